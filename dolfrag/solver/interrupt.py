"""Abandoning a step midway on a stop request.

A step of a cracking 3D structure may take longer than a launcher waits between its
SIGTERM and its SIGKILL (Open MPI: 1 s by default, Slurm: 30 s). An integrator whose
``interrupt`` is set asks it during the step and gives the step up with StepInterrupted;
the time loop then puts back the state it kept from before the step (runner/loop.py).

``interrupt`` is an object with ``flag``, a one-element int8 array that the signal handler
sets on its own rank and that compiled loops read, and ``pending()``, which tells every
rank whether any rank got a signal (collective). Python runs signal handlers only between
bytecodes of the main thread, never inside a compiled call: run_responsive runs such a
call in a worker thread while the main thread waits in short slices, so that the handler
runs at once and the call sees ``flag`` set.
"""
from concurrent.futures import ThreadPoolExecutor

# s: how long the main thread waits on the worker before taking a pending signal
SLICE = 0.05


class StepInterrupted(Exception):
    """A step abandoned because its integrator's ``interrupt`` said so: the integrator's
    state is partly advanced, and the caller restores the one it kept from before the step."""


class Responsive:
    """One worker thread, created at the first call and reused."""

    def __init__(self):
        self._worker = None

    def __call__(self, function, *args):
        """function(*args) in the worker thread; its result. The function must release the
        GIL (numba's nogil) for the worker to run while the main thread waits."""
        if self._worker is None:
            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dolfrag-kernel")
        future = self._worker.submit(function, *args)
        while True:
            try:
                return future.result(timeout=SLICE)
            except TimeoutError:  # a signal handler has run, if one was due
                continue
