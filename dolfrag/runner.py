"""`run(case, out)`: mesh, operators, time loop and outputs of one case.

Everything the user can get wrong is checked before ``out`` is created, so bad
input leaves no half-written directory behind.
"""
import dataclasses
import math
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from dolfrag import (__version__, analytic, bulk, compat, homogenise, loads, mesh, rebar, rebar_layout,
                     space as spaces, supports, viscosity)
from dolfrag.config import Case, CaseError, load_case
from dolfrag.interface import links as link_table, models
from dolfrag.interface.jumps import Jump
from dolfrag.interface.stars import Stars
from dolfrag.post import expanding, shpb, wall
from dolfrag.post.figures import broken_mesh_png, deflection_png, exploded, signal_png, wave_png
from dolfrag.post.fragments import breaks_by_time, fragments
from dolfrag.post.output import RunOutput, dof_damage
from dolfrag.progress import Progress
from dolfrag.solver.imex import ElasticSprings, Imex
from dolfrag.solver.semismooth import ConvergenceError, StarNewton, step_stiffness
from dolfrag.solver.theta import Theta, accuracy_time_step
from dolfrag.stretch import Stretch

ENERGY_COLUMNS = ["E_kinetic_J", "E_bulk_J", "E_interface_J", "E_rebar_J", "D_damage_J", "D_contact_J",
                  "D_numerical_J", "D_rebar_plastic_J", "D_viscous_J", "W_external_J", "balance_error_J"]
ENERGY_FIELDS = ["kinetic", "bulk", "interface", "rebar", "damage", "contact", "numerical", "plastic", "viscous",
                 "external_work", "balance_error"]
# velocity_x.png: each fragment moved off the body's centre by this share of its centroid
# offset, so that cracks a few micrometres wide show (the seed's Fig. 6)
EXPLODE = 0.1


def interface_model(interface, E, size, n, h, k_step=np.inf):
    """The model of ``interface`` (config.Interface) on n links; h (s) for viscous RCCM;
    k_step (Pa/m, per link) the step's own stiffness, where linear softening leaves its
    rigid constraint."""
    C_N, C_T = interface.stiffness(E, size)
    if interface.law == "elastic":
        return models.Elastic(n, C_N, C_T)
    if interface.law == "threshold":
        return models.Threshold(n, interface.R_c, interface.W_eth, interface.mu)
    if interface.law == "linear_softening":
        return models.LinearSoftening(n, interface.sigma_c, interface.G_c, interface.mu, k_open=k_step)
    if interface.law == "rccm_decoupled":
        return models.RccmDecoupled(n, C_N, C_T, interface.sigma_c, interface.G_c, interface.mu, interface.mu_i)
    return models.Rccm(n, C_N, C_T, interface.adhesion_energy(C_N), interface.b, interface.mu, h, interface.mu_i)


def interface_step(interface, E, size, stars, jump, m, h):
    """The model of ``interface`` (config.Interface) and its imex star step solver."""
    model = interface_model(interface, E, size, len(jump.links), h, step_stiffness(jump.links, m, h, stars.gdim))
    if interface.law == "elastic":
        return ElasticSprings(stars, jump, model, m, h)
    return StarNewton(stars, jump, model, m, h)


def setup(case, comm):
    """Mesh, space, operators and the integrator for ``case``: (domain, space, links,
    integrator, n_steps, dt_crit). Collective. A stretch is started (initial velocity,
    ends held), but the work of its ends is booked only by ``run``."""
    return _setup(case, comm)[:6]


def _setup(case, comm):
    """setup's tuple, plus the case's Stretch (None for a pressure load)."""
    domain = mesh.build(case.geometry, case.mesh.size, comm)
    named = ([("load.boundary", case.load.boundary)] if case.load.kind == "pressure" else []) + [
        (f"supports.{kind}", name) for kind in ("rollers", "clamped", "simple")
        for name in getattr(case.supports, kind)]
    for key, name in named:
        if name not in domain.boundaries:
            raise CaseError(f"{key} = {name!r}: not a boundary of the mesh; boundaries: "
                            f"{', '.join(sorted(domain.boundaries)) or 'none'}")
    space = spaces.create(domain)
    bulk_ops = bulk.assemble(space, domain, case)
    bars = None
    if case.rebar.faces:
        lines, areas = rebar_layout.layer_polylines(case.rebar, case.geometry, space.gdim)
        bars = rebar.Rebars(space, lines, areas, case.rebar.E, case.rebar.f_y, case.rebar.rho, case.mesh.size, comm,
                            eps_u=case.rebar.eps_u)
        bars.add_mass(bulk_ops.m.x.array)
        # omega_max^2 <= bulk's + bars' (Weyl); the bulk's, with the lighter concrete-only
        # mass, stays an upper bound
        bulk_ops.dt_crit = 2 / math.sqrt((2 / bulk_ops.dt_crit)**2 + bars.stiffness_bound(bulk_ops.m.x.array))
    links = link_table.build(space)
    held = supports.constrained_components(space, domain, case.supports)
    stretch = Stretch(space, domain, case.load.strain_rate) if case.load.kind == "stretch" else None
    if stretch is not None:  # its ends are supports whose velocity is prescribed
        held = np.union1d(held, stretch.held)
    stars = Stars(space, links, held)
    time = case.time
    viscous = viscosity.build(space, domain, case) if time.scheme == "imex" else None
    if viscous is not None:  # its linear term lowers the stable step
        bulk_ops.dt_crit *= viscosity.step_factor(viscous.options)
    if time.scheme == "theta":  # unconditionally stable: the step follows accuracy, not dt_crit
        h = time.dt or accuracy_time_step(case.load, time.end)
    else:
        h = time.cfl * bulk_ops.dt_crit
    n_steps = math.ceil(time.end / h)
    h = time.end / n_steps
    jump = Jump(space, links)
    if stretch is None:
        load = loads.unit_pressure_vector(space, domain, case.load.boundary, case.load.region)
        pressure = loads.signal(case.load)
    else:
        load, pressure = compat.Function(space.V), np.zeros_like  # no pressure: p(t) = 0
    if time.scheme == "theta":
        model = interface_model(case.interface, case.material.E, case.mesh.size, len(links), h)
        integrator = Theta(space, bulk_ops, jump, model, load, pressure, h, time.theta,
                           stars.constrained, rebars=bars)
    else:
        step = interface_step(case.interface, case.material.E, case.mesh.size, stars, jump, bulk_ops.m.x.array, h)
        integrator = Imex(space, bulk_ops, jump, step, load, pressure, h, rebars=bars, viscosity=viscous)
    if stretch is not None:
        stretch.start(integrator, stars.comps)
    return domain, space, links, integrator, n_steps, bulk_ops.dt_crit, stretch


def _probes(space, domain):
    """Owned flat components of every named boundary, for its mean velocity."""
    probes = {}
    for name, tag in sorted(domain.boundaries.items()):
        dofs = space.boundary_dofs(domain.facet_tags, tag)
        dofs = dofs[dofs < space.n_owned_dofs]
        for k, axis in enumerate("xyz"[:space.gdim]):
            probes[f"v{axis}_{name}_m_s"] = space.gdim * dofs + k
    return probes


def _check_converged(integ, comm):
    """Raise ConvergenceError if a star's Newton failed this step (imex). Collective."""
    stars = comm.allreduce(integ.interface.unconverged)
    if stars:
        residual = comm.allreduce(integ.interface.residual, op=MPI.MAX)
        raise ConvergenceError(
            f"t = {integ.t:.6g} s (step {integ.n}): {stars} vertex star(s) did not converge in "
            f"{integ.interface.max_iterations} Newton iterations (worst scaled residual {residual:.3g}, "
            f"tolerance {integ.interface.rtol:g}); the state is saved in failure.pvd")


def _free_end(case):
    """x (m) of the far end of a rectangle bar loaded on its left or right edge, else None:
    breaks are then reported from it, first to complete first."""
    if case.geometry.kind != "rectangle" or case.load.boundary not in ("left", "right"):
        return None
    return case.geometry.length if case.load.boundary == "left" else 0.0


def _free_end_probe(case, space, domain):
    """shpb.FreeEndProbe of the face opposite the loaded one of a bar (``_free_end``)."""
    face = "right" if case.load.boundary == "left" else "left"
    dofs = space.boundary_dofs(domain.facet_tags, domain.boundary_tag(face))
    return shpb.FreeEndProbe(space.gdim * dofs[dofs < space.n_owned_dofs], 1.0 if face == "right" else -1.0)


class WallSection(NamedTuple):
    """A wall section (2D) or slab (3D) that gets the ``wall`` block (post/wall.py): span (m;
    (L_x, L_y) for a slab), thickness H (m), free_face (m, its coordinate on thickness_axis),
    span_axis (0, or (0, 1) for a slab), thickness_axis (1 in 2D, 2 in 3D)."""
    span: object
    thickness: float
    free_face: float
    span_axis: object
    thickness_axis: int


def _wall_section(case):
    """The WallSection of a rectangle loaded on its bottom or top face (a wall section
    spanning x) or of a box loaded on its front or back face (a slab spanning x and y),
    else None."""
    g, face = case.geometry, case.load.boundary
    if g.kind == "rectangle" and face in ("bottom", "top"):
        return WallSection(g.length, g.width, g.width if face == "bottom" else 0.0, 0, 1)
    if g.kind == "box" and face in ("front", "back"):
        return WallSection((g.length, g.width), g.thickness, g.thickness if face == "front" else 0.0, (0, 1), 2)
    return None


def _wall_estimates(case, C_N, section):
    """post.wall.estimates (block, bending history) for a wall case: the 1D wave speed is the
    uniaxial-strain (P-wave) modulus in series with the interface springs, one per mesh size
    (analytic.py; the unstructured mesh is measured a few per cent softer still,
    docs/validation.md)."""
    mat = case.material
    M = analytic.series_interface_modulus(analytic.p_wave_modulus(mat.E, mat.nu, mat.hypothesis), C_N,
                                          case.mesh.size)
    sup = case.supports
    kind = "clamped" if sup.clamped else "simple" if sup.simple else None
    bends_in_plane_strain = np.ndim(section.span) or mat.hypothesis == "plane_strain"  # a slab: always nu
    return wall.estimates(loads.signal(case.load), case.time.end, analytic.wave_speed(M, mat.rho), mat.rho, mat.E,
                          shpb.tensile_strength(case.interface, C_N), section.thickness, section.span,
                          kind, mat.nu if bends_in_plane_strain else 0.0)


def _midspan(space, section, size):
    """Owned flat components along the thickness of the dofs on the centre line: within half
    a mesh size of x = L/2 in 2D; in 3D within one mesh size of (L_x/2, L_y/2) on both axes
    (an unstructured tetrahedral mesh may have no vertex within h/2 of a line)."""
    axes = np.atleast_1d(section.span_axis)
    half = size / 2 if len(axes) == 1 else size
    x = space.x[:space.n_owned_dofs][:, axes]
    dofs = np.flatnonzero(np.all(np.abs(x - np.asarray(section.span) / 2) < half, axis=1))
    return space.gdim * dofs + section.thickness_axis


def run(case, out, quiet=False, comm=None):
    """Run ``case`` (a config.Case, a case file path or a built-in name); write
    summary.json, history.csv, fields.pvd and figures/ into ``out``. Collective.
    Returns the summary dict."""
    comm = comm or MPI.COMM_WORLD
    if not isinstance(case, Case):
        case = load_case(case)
    wall_start = time.perf_counter()
    domain, space, links, integ, n_steps, dt_crit, stretch = _setup(case, comm)
    probes = _probes(space, domain)
    section = _wall_section(case)
    midspan = _midspan(space, section, case.mesh.size) if section else None
    deflection = ([], [])  # s, m: the midspan deflection (mean displacement across the thickness)
    wave = ([], [])  # this rank's midspan dofs: depth (m) and velocity across the thickness (m/s) at each row
    columns = ["step", "time_s", "load_Pa", *ENERGY_COLUMNS, "broken_links", "newton_iterations",
               "newton_unconverged", "newton_residual", *probes, *(["w_midspan_m"] if section else []),
               *(["rebar_force_max_N"] if integ.rebars else [])]
    snapshots = set(np.round(np.linspace(0, n_steps, case.output.fields + 1)).astype(int)) \
        if case.output.fields else set()
    output = RunOutput(out, comm, columns, fields=bool(snapshots))
    damage = compat.Function(compat.dg1_scalar_space(space.mesh))
    damage.name = "damage"

    def write_fields(t, vtk=None):
        dof_damage(space, links, integ.model.damage(), damage)
        output.fields([integ.u, integ.v, damage], t, vtk)

    progress = Progress(n_steps, quiet=quiet, rank=comm.rank)
    summary = {"case": case.to_dict(), "version": __version__, "ranks": comm.size,
               "cells": space.mesh.topology.index_map(space.mesh.topology.dim).size_global,
               "links": comm.allreduce(len(links)), "dofs": space.V.dofmap.index_map.size_global * space.gdim,
               "steps": n_steps, "dt_s": integ.h, "dt_crit_s": dt_crit,
               "interface_stiffness_Pa_m": {"C_N": integ.model.C_N, "C_T": integ.model.C_T},
               "status": "running"}
    max_error, max_work, energies = 0.0, 0.0, None
    break_time = np.full(len(links), np.nan)  # s, when each link broke
    free_end = _free_end(case)
    free_probe = None if free_end is None else _free_end_probe(case, space, domain)
    # s, times still to measure fragments at: the requested ones, and a bar's MEASURE_TIME
    bar_time = {shpb.MEASURE_TIME} if free_end is not None and case.time.end >= shpb.MEASURE_TIME else set()
    pending = sorted(set(case.output.fragments_at) | bar_time)
    measured = {}  # requested time (s): (time of the step nearest it (s), Fragments)

    def current_fragments(of_cells=False):
        return fragments(space, links, integ.model.broken(), integ.m, integ.v.x.array, integ.u.x.array,
                         break_time, of_cells)
    try:
        if 0 in snapshots:
            write_fields(0.0)
        for k in range(1, n_steps + 1):
            t_n = integ.t
            try:
                energies = integ.step(energies=k % case.output.every == 0 or k == n_steps)
                if stretch is not None:
                    stretch.book(integ)
                    if energies is not None:  # E_{-1/2} and the ends' work are supplied too
                        energies = dataclasses.replace(
                            energies, external_work=energies.external_work + stretch.supplied(comm))
                if integ.model.can_break:
                    break_time[integ.model.broken() & np.isnan(break_time)] = integ.t
                    integ.timer.lap("diagnostics")
                    _check_converged(integ, comm)
                    integ.timer.lap("communication")
            except ConvergenceError:
                output.failure(lambda vtk: write_fields(integ.t, vtk))  # the state, for a look
                raise
            if energies is not None:
                probe_sums = comm.allreduce(np.array([[integ.v.x.array[c].sum(), len(c)] for c in probes.values()]
                                                     + ([[integ.u.x.array[midspan].sum(), len(midspan)]]
                                                        if section else [])))
                newton = [comm.allreduce(integ.interface.iterations, op=MPI.MAX),
                          comm.allreduce(integ.interface.unconverged, op=MPI.SUM),
                          comm.allreduce(integ.interface.residual, op=MPI.MAX)]
                output.row([k, integ.energy_time, integ.pressure(t_n),
                            *(getattr(energies, a) for a in ENERGY_FIELDS), energies.broken_links, *newton,
                            *(probe_sums[:, 0] / np.maximum(probe_sums[:, 1], 1)),
                            *([comm.allreduce(integ.rebars.force_max, op=MPI.MAX)] if integ.rebars else [])])
                if section:
                    wave[0].append(space.x[midspan // space.gdim, section.thickness_axis])
                    wave[1].append(integ.v.x.array[midspan].copy())
                    deflection[0].append(integ.t)
                    deflection[1].append(probe_sums[-1, 0] / max(probe_sums[-1, 1], 1))
                max_error = max(max_error, abs(energies.balance_error))
                max_work = max(max_work, abs(energies.external_work))
            if free_probe is not None:
                free_probe.record(integ.energy_time, integ.v.x.array)
            if k in snapshots:
                write_fields(integ.t)
            while pending and integ.t >= pending[0] - integ.h / 2:  # the step nearest to it
                at = pending.pop(0)
                measured[at] = (integ.t, current_fragments())
                if at in case.output.fragments_at:
                    summary.setdefault("fragments_at", []).append(
                        {"requested_time_s": at, "time_s": integ.t, **measured[at][1].to_dict()})
            progress.update(k)
            integ.timer.lap("output")
        summary["timings_s"] = integ.timer.summary(comm)
        # star solves accepted at their best iterate within semismooth.GIVE_UP (imex)
        summary["stalled_star_solves"] = comm.allreduce(integ.interface.stalled)
        summary["status"] = "completed"
    except BaseException as err:
        summary["status"] = f"failed at t = {integ.t:.6g} s: {type(err).__name__}: {err}"
        raise
    finally:
        summary["steps_done"] = integ.n
        summary["wall_time_s"] = time.perf_counter() - wall_start
        if energies is not None:
            summary["energies_J"] = {c: getattr(energies, a) for c, a in zip(ENERGY_COLUMNS, ENERGY_FIELDS)}
            summary["broken_links"] = energies.broken_links
        summary["max_abs_balance_error_J"] = max_error
        summary["balance_error_relative"] = max_error / max_work if max_work else 0.0
        output.summary(summary)
        output.close()
    frags, fragment_of_cell = current_fragments(of_cells=True)
    axes = "xyz"[:space.gdim]
    table = output.links([*axes, *(f"n{a}" for a in axes), "weight", "damage", "broken", "break_time_s"],
                         np.column_stack([space.vertex_x[links.vertex][:, :space.gdim], links.normal, links.weight,
                                          integ.model.damage(), integ.model.broken(), break_time]))
    summary["fragments"] = frags.to_dict()
    if integ.rebars is not None:
        bars = integ.rebars
        summary["rebar"] = {"segments": bars.count,
                            "peak_force_N": comm.allreduce(bars.peak_force, op=MPI.MAX),
                            "plastic_work_J": comm.allreduce(bars.plastic_work),
                            "ruptured_segments": bars.ruptures,
                            "rupture_energy_J": comm.allreduce(bars.rupture_work),
                            "units": "N and J per metre of depth in 2D"}
    if section:
        # in the reference configuration: a bounding box then says where a piece came from
        reference = fragments(space, links, integ.model.broken(), integ.m, integ.v.x.array, None, break_time)
        peak_force = [summary["rebar"]["peak_force_N"]] if integ.rebars else None
        block = None
        if comm.rank == 0:
            d = space.gdim
            block = wall.wall_block(reference, table[:, :d], table[:, 2 * d], table[:, 2 * d + 1],
                                    table[:, 2 * d + 3], *deflection, peak_force, time.perf_counter() - wall_start,
                                    h=case.mesh.size, **section._asdict())
        summary["wall"] = comm.bcast(block, root=0)
        summary["wall"]["estimates"], bending = _wall_estimates(case, integ.model.C_N, section)
    if stretch is not None:
        reference = fragments(space, links, integ.model.broken(), integ.m, integ.v.x.array, None, break_time)
        summary["expanding_bar"] = expanding.block(reference, stretch.length, stretch.rate, case.material,
                                                   case.interface)
    if free_end is not None:
        summary["breaks"] = breaks_by_time(frags, free_end)
        measured_at, at_measure = measured.get(shpb.MEASURE_TIME, (integ.t, frags))  # shorter run: the end
        sigma_c, rho, E = shpb.tensile_strength(case.interface, integ.model.C_N), case.material.rho, case.material.E
        closed = None if sigma_c is None else analytic.bar_spall(
            loads.signal(case.load), analytic.wave_speed(E, rho), rho, sigma_c, case.geometry.length,
            loads.signal_end(case.load), at=measured_at)
        summary["shpb"] = shpb.shpb_block(frags, at_measure, measured_at, free_end, sigma_c, rho, E, case.name,
                                          closed_form=closed, free_end_velocity=free_probe.series(comm),
                                          E_eff=homogenise.bar_modulus(case))
    output.summary(summary)
    if case.output.figures:
        figures = Path(out) / "figures"
        v = integ.v.x.array.reshape(-1, space.gdim)
        broken_mesh_png(space, integ.u, np.linalg.norm(v, axis=1), figures / "velocity.png",
                        "velocity magnitude (m/s)")
        broken_mesh_png(space, integ.u, v[:, 0], figures / "velocity_x.png", "velocity v_x (m/s)", scale=1.0,
                        cell_offset=exploded(frags, fragment_of_cell, EXPLODE),
                        note=f"fragments moved apart by {EXPLODE:g} x their centroid offset; "
                             f"t = {integ.t * 1e6:.1f} us")
        dof_damage(space, links, integ.model.damage(), damage)
        broken_mesh_png(space, integ.u, damage.x.array, figures / "damage.png", "damage 1 - beta (-)")
        if stretch is None:
            signal_png(loads.signal(case.load), case.time.end, figures / "load.png", comm,
                       f"load on '{case.load.boundary}' ({case.name})")
        if section:
            across = "xyz"[section.thickness_axis]
            broken_mesh_png(space, integ.u, v[:, section.thickness_axis], figures / f"velocity_{across}.png",
                            f"velocity v_{across} (m/s)", scale=1.0,
                            cell_offset=exploded(frags, fragment_of_cell, EXPLODE),
                            note=f"fragments moved apart by {EXPLODE:g} x their centroid offset; "
                                 f"t = {integ.t * 1e3:.3g} ms")
            slab = bool(np.ndim(section.span))
            if slab:  # the half y < L_y / 2, seen from +y: the cut along the centre line shows the cracks inside
                centroid_y = space.x[space.cell_dofs[:space.n_owned_cells], 1].mean(axis=1)
                broken_mesh_png(space, integ.u, damage.x.array, figures / "slab.png", "damage 1 - beta (-)",
                                cells=centroid_y < section.span[1] / 2, view=(0.4, 1.0, 0.35),
                                note=f"half slab y < {section.span[1] / 2:g} m; t = {integ.t * 1e3:.3g} ms")
            deflection_png(deflection[0], deflection[1], bending, figures / "deflection.png", comm,
                           f"{'centre' if slab else 'midspan'} deflection ({case.name})",
                           summary["wall"]["first_through_crack_s"],
                           "thin plate, p(t) applied statically" if slab else "elastic SDOF (Biggs)")
            rows = comm.gather(wave, root=0)
            if rows is not None:
                depth = [np.concatenate(parts) for parts in zip(*(r[0] for r in rows))]
                v_across = [np.concatenate(parts) for parts in zip(*(r[1] for r in rows))]
                wave_png(deflection[0], depth, v_across, section.thickness, figures / "wave.png", comm,
                         f"v_{across} through the thickness at midspan ({case.name})")
    return summary
