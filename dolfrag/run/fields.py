"""fields.pvd: displacement, velocity and damage at output.fields + 1 evenly spaced steps.

A resumed run writes its snapshots into a series of its own (fields-from-step<k>.pvd) and,
when it closes, makes fields.pvd the index of both: the snapshots up to the checkpoint,
then its own, each once.
"""
import re
from pathlib import Path

import numpy as np

from dolfrag import compat
from dolfrag.post.output import dof_damage

_DATASET = re.compile(r'<DataSet timestep="([^"]+)"[^>]*/>')


class FieldSnapshots:

    def __init__(self, ctx, output, resume_step=None):
        self.ctx, self.output, self.resume_step = ctx, output, resume_step
        fields, n_steps = ctx.case.output.fields, ctx.problem.n_steps
        self.steps = set(np.round(np.linspace(0, n_steps, fields + 1)).astype(int)) if fields else set()
        self.damage = compat.Function(compat.dg1_scalar_space(ctx.space.mesh))
        self.damage.name = "damage"

    def write(self, t, vtk=None):
        """Write the current fields at time t (s) (into ``vtk``, else fields.pvd). Collective."""
        integ = self.ctx.integ
        dof_damage(self.ctx.space, self.ctx.links, integ.model.damage(), self.damage)
        self.output.fields([integ.u, integ.v, self.damage], t, vtk)

    def start(self):
        if 0 in self.steps and self.resume_step is None:
            self.write(0.0)

    def observe(self, step):
        if step.k in self.steps:
            self.write(self.ctx.integ.t)

    def close(self, t_resumed):
        """After the output is closed: make fields.pvd the index of the snapshots up to
        t_resumed (s, the checkpoint this segment started from) and this segment's (rank 0)."""
        if self.resume_step is None or not self.steps or self.ctx.comm.rank != 0:
            return
        out = Path(self.ctx.out)
        own = out / self.output.fields_name
        earlier = [line for t, line in _datasets(out / "fields.pvd") if t <= t_resumed * (1 + 1e-12)]
        lines = earlier + [line for _, line in _datasets(own)]
        tmp = out / "fields.pvd.tmp"
        tmp.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0">\n  <Collection>\n'
                       + "".join(f"    {line}\n" for line in lines) + "  </Collection>\n</VTKFile>\n")
        tmp.replace(out / "fields.pvd")


def _datasets(pvd):
    """[(time s, DataSet line)] of a .pvd file; [] if there is none."""
    if not pvd.exists():
        return []
    return [(float(m.group(1)), m.group(0)) for m in _DATASET.finditer(pvd.read_text())]
