"""SIGINT and SIGTERM stop a run on every rank together: at the end of the current step, or
within a step that may take longer than a launcher waits after its SIGTERM, which is then
abandoned (runner/loop.py, solver/interrupt.py).

A handler only raises flags: ``signal`` for Python, ``flag`` for compiled loops. The time
loop reduces the flags of all ranks once a step (``Stop.requested``); inside a step, theta's
Newton once an iteration and the imex star solver once a step (``Stop.pending``), so a
signal that reaches one rank (mpirun, a batch scheduler) stops them all at the same point.
``DOLFRAG_SIGNAL_AT_STEP=N`` (or ``N:SIGKILL``, any signal name) makes rank 0 send itself SIGTERM (that signal) after step N, before its checkpoint: a stop at a
known step, for the tests of checkpoint and resume.
"""
import os
import signal
import threading

import numpy as np
from mpi4py import MPI

EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}  # 128 + the signal number, as shells report


class Stop:
    """Install with ``with Stop(comm) as stop:``; the old handlers come back on exit."""

    def __init__(self, comm):
        self.comm, self.signal = comm, None
        at, _, name = os.environ.get("DOLFRAG_SIGNAL_AT_STEP", "").partition(":")
        self._send_at = int(at) if at and comm.rank == 0 else None
        self._send = signal.Signals[name or "SIGTERM"]
        self._old = {}
        self.flag = np.zeros(1, dtype=np.int8)  # 1 once this rank got a signal

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():  # elsewhere Python cannot catch signals
            for sig in EXIT_CODES:
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc):
        for sig, handler in self._old.items():
            signal.signal(sig, handler)

    def _handle(self, signum, frame):
        self.signal = signal.Signals(signum)
        self.flag[0] = 1

    def pending(self):
        """Whether any rank got a signal. Collective."""
        return self._agree()[0]

    def requested(self, step, due, slow):
        """(stop, checkpoint, slow): whether any rank got a signal, whether any rank's
        ``due`` (a checkpoint's wall-time interval has passed) is set, and whether any
        rank's ``slow`` (its step took long) is. Collective."""
        if step == self._send_at:
            os.kill(os.getpid(), self._send)
        return self._agree(due, slow)

    def _agree(self, *flags):
        """(any rank's signal, then per flag whether any rank's is set), the signal kept on
        every rank. Collective."""
        flags = np.array([0 if self.signal is None else int(self.signal), *map(int, flags)])
        self.comm.Allreduce(MPI.IN_PLACE, flags, op=MPI.MAX)
        if flags[0] and self.signal is None:
            self.signal = signal.Signals(int(flags[0]))
        return tuple(bool(flag) for flag in flags)
