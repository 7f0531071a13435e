"""Run outputs: history.csv (a row every few steps, flushed, so a crash loses nothing
written so far), fields.pvd (VTK: keeps the DG field, crack openings included),
summary.json (written atomically)."""
import csv
import json
import os
from pathlib import Path

import numpy as np

from dolfrag import compat
from dolfrag.post.vtk import FieldsFile


def dof_damage(space, links, link_damage, out):
    """Fill the scalar DG-P1 Function ``out`` with, at each dof, the largest damage
    (1 - beta, 0 sound .. 1 broken) of the links at it: the cracks, drawn on the broken
    mesh. Collective: a dof's links all sit on its vertex's owner, which sends the value."""
    values = out.x.array
    values[:] = 0.0
    np.maximum.at(values, links.dof_A, link_damage)
    np.maximum.at(values, links.dof_B, link_damage)
    star = values.copy()
    compat.scatter_reverse_add(out)  # one contribution per dof: its star's owner's
    mine = star > 0
    values[mine] = star[mine]
    compat.scatter_forward(out)


def write_csv(path, columns, rows):
    """A CSV table at ``path``: the header ``columns``, then ``rows`` (lists of numbers and
    strings); floats with 10 significant digits, NaN as ``nan``. Call on one rank."""
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(columns)
        out.writerows([f"{x:.10g}" if isinstance(x, (float, np.floating)) else x for x in row] for row in rows)


class RunOutput:
    """Files of one run in ``out``; rank 0 writes CSV and JSON, VTK is collective."""

    def __init__(self, out, comm, columns, fields=True, resume_step=None):
        """resume_step: continue a run from its checkpoint after this step: history.csv
        keeps its rows up to it."""
        self.out, self.comm = Path(out), comm
        if comm.rank == 0:
            (self.out / "figures").mkdir(parents=True, exist_ok=True)
            if resume_step is None:
                self._csv_file = open(self.out / "history.csv", "w", newline="")
                csv.writer(self._csv_file).writerow(columns)
            else:
                self._csv_file = _history_up_to(self.out / "history.csv", resume_step)
            self._csv = csv.writer(self._csv_file)
            self._csv_file.flush()
        comm.barrier()
        # its snapshot times are checkpointed: a resumed run continues the series
        self.vtk = FieldsFile(comm, self.out / "fields.pvd") if fields else None

    def row(self, values):
        if self.comm.rank == 0:
            self._csv.writerow([f"{x:.10g}" for x in values])
            self._csv_file.flush()

    def fields(self, functions, t, vtk=None):
        """Write DG functions at time t (s) to fields.pvd (or the open VTK file ``vtk``).
        Collective; updates their ghost values."""
        for f in functions:
            compat.scatter_forward(f)
        (vtk or self.vtk).write_function(functions, t)

    def links(self, columns, rows):
        """links.csv: one row per link, gathered from every rank (rank 0 writes).
        Collective; rows (n_owned_links, len(columns)) floats. Returns the gathered rows
        on rank 0, None elsewhere."""
        everyone = self.comm.gather(np.asarray(rows, dtype=float), root=0)
        if self.comm.rank != 0:
            return None
        table = np.concatenate(everyone)
        np.savetxt(self.out / "links.csv", table, delimiter=",", header=",".join(columns), comments="", fmt="%.9g")
        return table

    def table(self, name, columns, rows):
        """``name`` (e.g. fragments.csv) in the run folder: write_csv on rank 0 only."""
        if self.comm.rank == 0:
            write_csv(self.out / name, columns, rows)

    def failure(self, write):
        """Call write(vtk) with failure.pvd open: the state where a run failed. Collective."""
        write(FieldsFile(self.comm, self.out / "failure.pvd"))

    def summary(self, data):
        if self.comm.rank == 0:
            tmp = self.out / "summary.json.tmp"
            tmp.write_text(json.dumps(data, indent=2) + "\n")
            os.replace(tmp, self.out / "summary.json")

    def close(self):
        if self.comm.rank == 0:
            self._csv_file.close()


def _history_up_to(path, step):
    """history.csv opened for appending, its rows after ``step`` (written after the last
    checkpoint) removed."""
    f = open(path, "r+", newline="")
    lines = f.readlines()
    keep = lines[:1] + [line for line in lines[1:] if int(float(line.split(",", 1)[0])) <= step]
    f.seek(0)
    f.writelines(keep)
    f.truncate()
    return f
