"""A compiled call run by solver/interrupt.Responsive: the main thread takes a signal while
the call runs, and the call sees the flag its handler sets (as the star loop sees a stop
request, tests/test_star_kernel.py; the whole stop under mpirun: tests/test_resume.py)."""
import os
import signal
import threading

import numpy as np
from numba import njit

from dolfrag.solver.interrupt import Responsive

# iterations the spin would take without a stop: seconds, so that a signal after 0.2 s
# stops it well before (a loop that never read the flag again would run them all)
LIMIT = 10**10


@njit(nogil=True)
def _spin(flag, count, limit):
    """Count until ``flag`` is set or ``limit`` is reached; the store into ``count`` each
    turn keeps the compiler from reading ``flag`` once for the whole loop."""
    while count[0] < limit and not flag[0]:
        count[0] += 1


def test_a_signal_during_a_compiled_call_reaches_it_through_the_flag():
    flag, count = np.zeros(1, np.int8), np.zeros(1, np.int64)
    _spin(np.ones(1, np.int8), count, 1)  # compiled before the clock starts
    handled = []

    def handle(signum, frame):
        handled.append(threading.current_thread() is threading.main_thread())
        flag[0] = 1

    old = signal.signal(signal.SIGUSR1, handle)
    try:
        timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGUSR1))
        timer.start()
        Responsive()(_spin, flag, count, LIMIT)
        timer.join()
    finally:
        signal.signal(signal.SIGUSR1, old)
    assert handled == [True] and 0 < count[0] < LIMIT
