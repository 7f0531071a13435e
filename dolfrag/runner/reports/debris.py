"""A 3D run (z up) with [debris] enabled: where its fragments land (post/debris.py):
debris.csv, the ``debris`` block of summary.json and figures/debris_map.png. Each fragment
is thrown from its centroid with its mean velocity at the end of the run."""
import numpy as np
from mpi4py import MPI
from scipy.spatial import ConvexHull

from dolfrag.post import debris
from dolfrag.post.figures import debris_map_png, milliseconds
from dolfrag.post.output import write_csv
from dolfrag.runner.context import Observer


def footprint(space, comm):
    """(k, 2) m: the corners of the convex hull of the body's undeformed vertices in plan
    (x, y), anticlockwise, on every rank. Collective."""
    plan = space.x[:space.n_owned_dofs, :2]
    corners = comm.allgather(plan[ConvexHull(plan).vertices])
    everyone = np.concatenate(corners)
    return everyone[ConvexHull(everyone).vertices]


def plan_centre(space, mass, comm):
    """(2,) m: the body's mass centre in plan (x, y), undeformed; mass: flat lumped mass of
    every local dof component (kg). Collective."""
    m = np.asarray(mass).reshape(-1, space.gdim)[:space.n_owned_dofs, 0]
    totals = comm.allreduce(np.append(m @ space.x[:space.n_owned_dofs, :2], m.sum()))
    return totals[:2] / totals[2]


class DebrisReport(Observer):
    """The plan-view footprint, centre and (by default) ground level of the undeformed body,
    taken when the run starts; the throw at its end."""

    @staticmethod
    def applies(case):
        return case.geometry.tdim == 3 and case.debris.enabled

    def __init__(self, ctx):
        self.ctx, self.options = ctx, ctx.case.debris
        space, comm = ctx.space, ctx.comm
        self.footprint = footprint(space, comm)
        self.centre = plan_centre(space, ctx.integ.m, comm)
        lowest = comm.allreduce(space.x[:space.n_owned_dofs, 2].min(), op=MPI.MIN)
        self.ground_z = lowest if self.options.ground_z is None else self.options.ground_z
        self.thrown = None  # the post.debris.Throw, on rank 0

    def summarise(self, summary, final):
        comm, table, options = self.ctx.comm, final.table, self.options
        block = None
        if comm.rank == 0:  # every rank holds the table: one throws, for all
            self.thrown = debris.throw(table, self.centre, self.ground_z, options.C_D, options.air_density)
            block = debris.block(self.thrown, options, self.centre, self.ground_z, table.held.sum())
            write_csv(self.ctx.out / "debris.csv", debris.columns(), debris.rows(self.thrown, options.hazard_energy))
        summary["debris"] = comm.bcast(block, root=0)

    def figures(self, folder, final):
        ctx = self.ctx
        debris_map_png(self.thrown, self.footprint, final.summary["debris"], folder / "debris_map.png", ctx.comm,
                       f"where the fragments land ({ctx.case.name}, thrown at t = {milliseconds(ctx.integ.t)})")
