"""fields.pvd: displacement, velocity and damage at output.fields + 1 evenly spaced steps.

The index fields.pvd is written here after every snapshot (the VTK writer writes its own
only when it is destroyed, so a killed run would leave none), from the list of snapshots
kept in the checkpoint: each run segment writes its pieces as a series of its own
(fields-from-step<k>-.pvd, k the step it started from), and fields.pvd lists those up to the
checkpoint a segment resumed from and that segment's own, each once.
"""
from pathlib import Path

import numpy as np

from dolfrag import compat
from dolfrag.post.output import dof_damage


class FieldSnapshots:
    STATE = ("entries",)  # what a checkpoint keeps

    def __init__(self, ctx, output, resume_step=None):
        self.ctx, self.output, self.resume_step = ctx, output, resume_step
        fields, n_steps = ctx.case.output.fields, ctx.problem.n_steps
        self.steps = set(np.round(np.linspace(0, n_steps, fields + 1)).astype(int)) if fields else set()
        self.damage = compat.Function(compat.dg1_scalar_space(ctx.space.mesh))
        self.damage.name = "damage"
        self.entries = []  # [time (s), piece file] of every snapshot of the run so far
        self._written = 0  # snapshots of this run segment

    def write(self, t, vtk=None):
        """Write the current fields at time t (s) into ``vtk`` (a failure's), else as the
        next snapshot of the series. Collective."""
        integ = self.ctx.integ
        dof_damage(self.ctx.space, self.ctx.links, integ.model.damage(), self.damage)
        self.output.fields([integ.u, integ.v, self.damage], t, vtk)
        if vtk is None:
            # the VTK writer's name of its n-th piece: <stem><n:06d>.pvtu
            self.entries.append([t, f"{Path(self.output.fields_name).stem}{self._written:06d}.pvtu"])
            self._written += 1
            self._index()

    def start(self):
        if 0 in self.steps and self.resume_step is None:
            self.write(0.0)

    def observe(self, step):
        if step.k in self.steps:
            self.write(self.ctx.integ.t)

    def close(self):
        """After the VTK writer closed (it writes its own index): fields.pvd lists the run's
        snapshots."""
        if self.steps:
            self._index()

    def _index(self):
        if self.ctx.comm.rank != 0:
            return
        out = Path(self.ctx.out)
        tmp = out / "fields.pvd.tmp"
        tmp.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0">\n  <Collection>\n'
                       + "".join(f'    <DataSet timestep="{t!r}" part="0" file="{name}" />\n'
                                 for t, name in self.entries) + "  </Collection>\n</VTKFile>\n")
        tmp.replace(out / "fields.pvd")
