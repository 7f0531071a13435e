"""fields.pvd: displacement, velocity and damage at output.fields + 1 evenly spaced steps.

The series (post/vtk.FieldsFile) rewrites its index after every snapshot, so a killed run
leaves a readable fields.pvd; its list of snapshot times is checkpointed, so a resumed run
continues it from the checkpoint, each snapshot once.
"""
import numpy as np

from dolfrag import compat
from dolfrag.post.output import dof_damage
from dolfrag.runner.context import Observer


class FieldSnapshots(Observer):
    def __init__(self, ctx, output, resume_step=None):
        self.ctx, self.output, self.resume_step = ctx, output, resume_step
        fields, n_steps = ctx.case.output.fields, ctx.problem.n_steps
        self.steps = set(np.round(np.linspace(0, n_steps, fields + 1)).astype(int)) if fields else set()
        self.damage = compat.Function(compat.dg1_scalar_space(ctx.space.mesh))
        self.damage.name = "damage"

    def write(self, t, vtk=None):
        """Write the current fields at time t (s) into ``vtk`` (a failure's), else as the
        next snapshot of the series. Collective."""
        integ = self.ctx.integ
        dof_damage(self.ctx.space, self.ctx.links, integ.model.damage(), self.damage)
        self.output.fields([integ.u, integ.v, self.damage], t, vtk)

    def start(self):
        """The first snapshot; on resume, the index cut back to the checkpoint's snapshots."""
        if self.resume_step is not None:
            if self.output.vtk is not None:
                self.output.vtk.write_index()
        elif 0 in self.steps:
            self.write(0.0)

    def observe(self, step):
        if step.k in self.steps:
            self.write(self.ctx.integ.t)
