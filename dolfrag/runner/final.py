"""What every completed run reports at its end: the fragments (summary.json, fragments.csv,
their mass distribution), links.csv, and the common figures (velocity, exploded velocity_x,
damage, load, fragment masses)."""
from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from dolfrag import compat
from dolfrag.post import fragment_sizes, fragment_table
from dolfrag.post.figures import (DAMAGE_RANGE, SIGNED, broken_mesh_png, charge_png, exploded, figure_title,
                                  fragment_masses_png, signal_png)
from dolfrag.post.output import dof_damage
from dolfrag.post.vtk import FieldsFile

# velocity_x.png: each fragment moved off the body's centre by this share of its centroid
# offset, so that cracks a few micrometres wide show (Fig. 6 of the paper *Study and
# simulation of fragmentation phenomena of concrete structures under stuffy explosion*)
EXPLODE = 0.1


class Final(NamedTuple):
    """fragments: post.fragments.Fragments at the end (displaced); fragment_of_cell: each
    owned cell's fragment; table: their post.fragment_table.FragmentTable (fragments.csv);
    links: links.csv's rows on rank 0 (None elsewhere); damage: the DG damage Function;
    wall_time: s since the run started; summary: the summary dict."""
    fragments: object
    fragment_of_cell: object
    table: object
    links: object
    damage: object
    wall_time: float
    summary: dict


def finish(ctx, output, damage, wall_time, summary):
    """The Final of a completed run; writes links.csv, fragments.csv, fragments.pvd and the
    summary's fragments with the fit of their masses (of the pieces no support holds).
    Collective."""
    space, links, model = ctx.space, ctx.links, ctx.integ.model
    frags, fragment_of_cell = ctx.fragments(of_cells=True)
    pieces = fragment_table.fragment_table(space, ctx.problem.domain, ctx.case.supports, ctx.integ.m, frags,
                                           fragment_of_cell)
    output.table("fragments.csv", fragment_table.columns(space.gdim), fragment_table.rows(pieces))
    _fragment_fields(ctx, output.out / "fragments.pvd", pieces, fragment_of_cell)
    axes = "xyz"[:space.gdim]
    table = output.links([*axes, *(f"n{a}" for a in axes), "weight", "damage", "broken", "break_time_s"],
                         np.column_stack([space.vertex_x[links.vertex][:, :space.gdim], links.normal, links.weight,
                                          model.damage(), model.broken(), ctx.break_time]))
    # the first link broken through, and the load's (mean) pressure then
    first = ctx.comm.allreduce(float(np.min(np.nan_to_num(ctx.break_time, nan=np.inf), initial=np.inf)),
                               op=MPI.MIN)
    summary["first_break"] = None if np.isinf(first) else {"time_s": first,
                                                          "load_Pa": float(ctx.problem.pressure(first))}
    free = pieces.mass[~pieces.held]
    summary["fragments"] = {**frags.to_dict(),
                            "size_distribution": fragment_sizes.block(free, "kg/m" if space.gdim == 2 else "kg")}
    dof_damage(space, links, model.damage(), damage)
    return Final(frags, fragment_of_cell, pieces, table, damage, wall_time, summary)


def _fragment_fields(ctx, path, pieces, fragment_of_cell):
    """fragments.pvd, one snapshot at the end: the displacement (m) and, on every cell, its
    fragment (the row of fragments.csv), whether a support holds that fragment (0/1) and its
    mean speed (m/s). Collective."""
    space, integ = ctx.space, ctx.integ
    owned = space.cell_dofs[:space.n_owned_cells]
    per_cell = {"fragment": fragment_of_cell, "held": pieces.held[fragment_of_cell],
                "fragment_speed": pieces.speed[fragment_of_cell]}
    V, functions = compat.dg1_scalar_space(space.mesh), [integ.u]
    for name, values in per_cell.items():
        f = compat.Function(V)
        f.name = name
        f.x.array[owned] = np.asarray(values, dtype=float)[:, None]
        functions.append(f)
    FieldsFile(ctx.comm, path).write_function(functions, integ.t)


def fragments_view(table):
    """fragments.png's camera direction in 3D (z up), isometric: from above, or from below
    when the pieces no support holds lie below the body's mass centre (e.g. crumbs of a
    slab's loaded underside); None in 2D."""
    if table.centroid.shape[1] == 2:
        return None
    free = ~table.held
    below = free.any() and table.mass[free] @ table.centroid[free, 2] / table.mass[free].sum() < \
        table.mass @ table.centroid[:, 2] / table.mass.sum()
    return (1.0, 1.0, -1.0 if below else 1.0)


def common_figures(ctx, folder, final):
    """velocity.png, velocity_x.png, damage.png, fragments.png, fragment_masses.png, and
    load.png for a pressure load. Collective."""
    space, integ, case = ctx.space, ctx.integ, ctx.case
    v = integ.v.x.array.reshape(-1, space.gdim)
    title = figure_title(case.name, integ.t)
    apart = exploded(final.fragments, final.fragment_of_cell, EXPLODE)
    broken_mesh_png(space, integ.u, np.linalg.norm(v, axis=1), folder / "velocity.png", "velocity magnitude (m/s)",
                    title)
    broken_mesh_png(space, integ.u, v[:, 0], folder / "velocity_x.png", "velocity v_x (m/s)", title, scale=1.0,
                    cell_offset=apart, clim=SIGNED,
                    note=f"fragments moved apart by {EXPLODE:g} x their centroid offset")
    broken_mesh_png(space, integ.u, final.damage.x.array, folder / "damage.png", "damage 1 - beta (-)", title,
                    clim=DAMAGE_RANGE,
                    rebars=ctx.problem.rebars if space.gdim == 3 else None)  # 2D: they lie in the mesh
    fragment_speed = np.zeros(len(space.x))
    fragment_speed[space.cell_dofs[:space.n_owned_cells]] = final.table.speed[final.fragment_of_cell][:, None]
    broken_mesh_png(space, integ.u, fragment_speed, folder / "fragments.png", "fragment speed (m/s)", title,
                    scale=1.0, cell_offset=apart, view=fragments_view(final.table),
                    note=f"each fragment coloured by its mean speed, moved apart by {EXPLODE:g} x its centroid offset")
    fragment_masses_png(final.table.mass[~final.table.held], final.summary["fragments"]["size_distribution"],
                        folder / "fragment_masses.png", ctx.comm, f"fragments no support holds ({title})")
    if case.load.signal == "charge":
        charge_png(ctx.problem.load, case.time.end, folder / "load.png", ctx.comm,
                   f"charge on '{case.load.boundary}' ({case.name})")
    elif case.load.kind == "pressure":
        signal_png(ctx.problem.pressure, case.time.end, folder / "load.png", ctx.comm,
                   f"load on '{case.load.boundary}' ({case.name})")
