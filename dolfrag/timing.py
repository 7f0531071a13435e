"""Wall time per phase of the time loop, on each rank: where a step's time goes.

``lap(phase)`` books the time since the previous lap to ``phase``; a lap costs about 0.1 µs,
so every step can afford a handful (benchmarks/scaling.py reads them, and summary.json
gets them as ``timings_s``).
"""
from collections import defaultdict
from time import perf_counter

import numpy as np
from mpi4py import MPI

# The phases of an imex step, in order; theta's coupled global solve is "implicit". The star
# solve is "interface", but for its second and third passes over the stars the first left
# unsolved (solver/semismooth.py): "hard_stars".
PHASES = ("bulk", "interface", "hard_stars", "communication", "update", "implicit", "diagnostics", "output")


class PhaseTimer:
    """Seconds spent in each phase since creation, on this rank."""

    def __init__(self):
        self.seconds = defaultdict(float)
        self._last = perf_counter()

    def start(self):
        """Open a new lap without booking the time since the last one."""
        self._last = perf_counter()

    def lap(self, phase):
        now = perf_counter()
        self.seconds[phase] += now - self._last
        self._last = now

    def summary(self, comm):
        """{phase: {"max": s, "mean": s}} over the ranks. Collective."""
        local = np.array([self.seconds.get(p, 0.0) for p in PHASES])
        largest, total = np.empty_like(local), np.empty_like(local)
        comm.Allreduce(local, largest, op=MPI.MAX)
        comm.Allreduce(local, total, op=MPI.SUM)
        return {p: {"max": largest[i], "mean": total[i] / comm.size} for i, p in enumerate(PHASES)}
