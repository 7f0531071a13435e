"""Run outputs: history.csv (a row every few steps, flushed, so a crash loses nothing
written so far), fields.pvd (VTK: keeps the DG field, crack openings included),
summary.json (written atomically)."""
import csv
import json
import os
from pathlib import Path

from dolfrag import compat


class RunOutput:
    """Files of one run in ``out``; rank 0 writes CSV and JSON, VTK is collective."""

    def __init__(self, out, comm, columns, fields=True):
        self.out, self.comm = Path(out), comm
        if comm.rank == 0:
            (self.out / "figures").mkdir(parents=True, exist_ok=True)
            self._csv_file = open(self.out / "history.csv", "w", newline="")
            self._csv = csv.writer(self._csv_file)
            self._csv.writerow(columns)
            self._csv_file.flush()
        comm.barrier()
        self._vtk = compat.vtk_file(comm, self.out / "fields.pvd") if fields else None

    def row(self, values):
        if self.comm.rank == 0:
            self._csv.writerow([f"{x:.10g}" for x in values])
            self._csv_file.flush()

    def fields(self, functions, t):
        """Write DG functions at time t (s). Collective; updates their ghost values."""
        for f in functions:
            compat.scatter_forward(f)
        self._vtk.write_function(functions, t)

    def summary(self, data):
        if self.comm.rank == 0:
            tmp = self.out / "summary.json.tmp"
            tmp.write_text(json.dumps(data, indent=2) + "\n")
            os.replace(tmp, self.out / "summary.json")

    def close(self):
        if self._vtk is not None:
            self._vtk.close()
        if self.comm.rank == 0:
            self._csv_file.close()
