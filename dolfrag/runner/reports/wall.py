"""A wall section (2D) or slab (3D) loaded on a face: the midspan deflection (a history
column), the velocity through the thickness at midspan, the ``wall`` block (post/wall.py)
and its figures."""
from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from dolfrag import guards
from dolfrag.reference import analytic
from dolfrag.post import wall
from dolfrag.post.figures import (DAMAGE_RANGE, SIGNED, broken_mesh_png, deflection_png, exploded, figure_title,
                                  wave_png)
from dolfrag.runner.final import EXPLODE
from dolfrag.runner.context import Observer


class WallSection(NamedTuple):
    """span (m; (L_x, L_y) for a slab), thickness H (m), free_face (m, its coordinate on
    thickness_axis), span_axis (0, or (0, 1) for a slab), thickness_axis (1 in 2D, 2 in 3D)."""
    span: object
    thickness: float
    free_face: float
    span_axis: object
    thickness_axis: int


def wall_section(case):
    """The WallSection of a rectangle loaded on its bottom or top face (a wall section
    spanning x) or of a box loaded on its front or back face (a slab spanning x and y),
    else None."""
    g, face = case.geometry, case.load.boundary
    if g.kind == "rectangle" and face in ("bottom", "top"):
        return WallSection(g.length, g.width, g.width if face == "bottom" else 0.0, 0, 1)
    if g.kind == "box" and face in ("front", "back"):
        return WallSection((g.length, g.width), g.thickness, g.thickness if face == "front" else 0.0, (0, 1), 2)
    return None


def turning_warning(rebar, peak_deflection, span):
    """The one-line warning (or None) when a run's exact, yielding bars (case.Rebar) turned
    far enough for the linear bulk's rotation theta to read as their yield, theta^2 / 2 =
    f_y / E_s (rebar/cables.py), theta taken as a mid-span hinge's 2 |w| / L over the
    shortest span (m; a number, or one per axis), w the peak deflection (m)."""
    if not rebar.faces or rebar.kinematics != "exact" or rebar.f_y is None:
        return None
    theta, at_yield = 2 * abs(peak_deflection) / min(np.atleast_1d(span)), np.sqrt(2 * rebar.f_y / rebar.E)
    if theta <= at_yield:
        return None
    return (f"dolfrag: warning: the span turned by about {theta:.2g} rad (2 w / L), past the {at_yield:.2g} rad "
            "where exact bars read the linear bulk's rotation as a stretch of their yield strain and stiffen it; "
            "rebar.kinematics = 'small_strain' does not (docs/wall.md, Rebars)")


def midspan(space, section, size):
    """Owned flat components along the thickness of the dofs on the centre line: within half
    a mesh size of x = L/2 in 2D; in 3D within one mesh size of (L_x/2, L_y/2) on both axes
    (an unstructured tetrahedral mesh may have no vertex within h/2 of a line)."""
    axes = np.atleast_1d(section.span_axis)
    half = size / 2 if len(axes) == 1 else size
    x = space.x[:space.n_owned_dofs][:, axes]
    dofs = np.flatnonzero(np.all(np.abs(x - np.asarray(section.span) / 2) < half, axis=1))
    return space.gdim * dofs + section.thickness_axis


def estimates(case, pressure, C_N, tensile_strength, section):
    """post.wall.estimates (block, bending history) for a wall case under ``pressure`` p(t)
    (Pa; problem.Problem.pressure: a charge's mean over the face): the 1D wave speed is the
    uniaxial-strain (P-wave) modulus in series with the interface springs, one per mesh size
    (analytic.py; the unstructured mesh is measured a few per cent softer still,
    docs/validation.md)."""
    mat = case.material
    M = analytic.series_interface_modulus(analytic.p_wave_modulus(mat.E, mat.nu, mat.hypothesis), C_N,
                                          case.mesh.size)
    sup = case.supports
    kind = "clamped" if sup.clamped else "simple" if sup.simple else None
    bends_in_plane_strain = np.ndim(section.span) or mat.hypothesis == "plane_strain"  # a slab: always nu
    return wall.estimates(pressure, case.time.end, analytic.wave_speed(M, mat.rho), mat.rho, mat.E,
                          tensile_strength, section.thickness, section.span,
                          kind, mat.nu if bends_in_plane_strain else 0.0)


class WallReport(Observer):
    columns = ["w_midspan_m"]
    # deflection: s, m (the midspan deflection, mean displacement across the thickness);
    # wave: this rank's midspan dofs, depth (m) and velocity across the thickness (m/s) at each row
    STATE = ("deflection", "wave")

    @staticmethod
    def applies(case):
        return wall_section(case) is not None

    def __init__(self, ctx):
        self.ctx = ctx
        self.section = wall_section(ctx.case)
        self.midspan = midspan(ctx.space, self.section, ctx.case.mesh.size)
        self.deflection, self.wave = ([], []), ([], [])
        self._bending = None

    def values(self, step):
        integ, space, dofs = self.ctx.integ, self.ctx.space, self.midspan
        total, count = self.ctx.comm.allreduce(np.array([integ.u.x.array[dofs].sum(), len(dofs)]))
        w = total / max(count, 1)
        self.wave[0].append(space.x[dofs // space.gdim, self.section.thickness_axis])
        self.wave[1].append(integ.v.x.array[dofs].copy())
        self.deflection[0].append(integ.t)
        self.deflection[1].append(w)
        return [w]

    def summarise(self, summary, final):
        ctx, section = self.ctx, self.section
        integ, comm, d = ctx.integ, ctx.comm, ctx.space.gdim
        # in the reference configuration: a bounding box then says where a piece came from
        reference = ctx.fragments(displaced=False)
        peak_force = [comm.allreduce(integ.rebars.peak_force, op=MPI.MAX)] if integ.rebars else None
        block = None
        if comm.rank == 0:
            table = final.links
            block = wall.wall_block(reference, table[:, :d], table[:, 2 * d], table[:, 2 * d + 1],
                                    table[:, 2 * d + 3], *self.deflection, peak_force, final.wall_time,
                                    h=ctx.case.mesh.size, **section._asdict())
        summary["wall"] = comm.bcast(block, root=0)
        peak = summary["wall"]["midspan_deflection"]["peak_m"]
        guards.warn(turning_warning(ctx.case.rebar, peak, section.span), comm)
        strength = ctx.problem.law.tensile_strength(ctx.case.interface, integ.model.C_N)
        summary["wall"]["estimates"], self._bending = estimates(ctx.case, ctx.problem.pressure, integ.model.C_N,
                                                                strength, section)

    def figures(self, folder, final):
        ctx, section = self.ctx, self.section
        space, integ, comm, name = ctx.space, ctx.integ, ctx.comm, ctx.case.name
        v = integ.v.x.array.reshape(-1, space.gdim)
        across = "xyz"[section.thickness_axis]
        broken_mesh_png(space, integ.u, v[:, section.thickness_axis], folder / f"velocity_{across}.png",
                        f"velocity v_{across} (m/s)", figure_title(name, integ.t), scale=1.0,
                        cell_offset=exploded(final.fragments, final.fragment_of_cell, EXPLODE), clim=SIGNED,
                        note=f"fragments moved apart by {EXPLODE:g} x their centroid offset")
        slab = bool(np.ndim(section.span))
        if slab:  # the half y < L_y / 2, seen from +y: the cut along the centre line shows the cracks inside
            centroid_y = space.x[space.cell_dofs[:space.n_owned_cells], 1].mean(axis=1)
            broken_mesh_png(space, integ.u, final.damage.x.array, folder / "slab.png", "damage 1 - beta (-)",
                            figure_title(name, integ.t), cells=centroid_y < section.span[1] / 2,
                            view=(0.4, 1.0, 0.35), clim=DAMAGE_RANGE, note=f"half slab y < {section.span[1] / 2:g} m")
        deflection_png(self.deflection[0], self.deflection[1], self._bending, folder / "deflection.png", comm,
                       f"{'centre' if slab else 'midspan'} deflection ({name})",
                       final.summary["wall"]["first_through_crack_s"],
                       "thin plate, p(t) applied statically" if slab else "elastic SDOF (Biggs)")
        rows = comm.gather(self.wave, root=0)
        if rows is not None:
            depth = [np.concatenate(parts) for parts in zip(*(r[0] for r in rows))]
            v_across = [np.concatenate(parts) for parts in zip(*(r[1] for r in rows))]
            wave_png(self.deflection[0], depth, v_across, section.thickness, folder / "wave.png", comm,
                     f"v_{across} through the thickness at midspan ({name})")
