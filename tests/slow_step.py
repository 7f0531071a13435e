"""`dolfrag` (argv[3:]) with a test-only slow step, so that a stop request arrives while a
step is in progress, as on a large cracking 3D mesh where a step costs seconds.

argv[1] = "theta": every residual evaluation of theta's Newton is slowed by argv[2] s (two or
three evaluations an iteration, a few iterations a step).
argv[1] = "imex": every call of the compiled star loop is preceded by argv[2] s of waiting
that, like the loop, gives up as soon as the stop request's flag is set (its last argument).
argv[1] = "imex-first": as "imex" in a run that starts, unslowed in a run that resumes
(`run --resume`), so that a batch job's later starts end far from their time limit.
"""
import sys
import time

from dolfrag import cli
from dolfrag.solver import star_kernel
from dolfrag.solver.theta import Theta

kind, delay = sys.argv[1], float(sys.argv[2])


def slowed_theta():
    evaluate = Theta._evaluate

    def slow_evaluate(self, step, x, r):
        time.sleep(delay)
        return evaluate(self, step, x, r)

    Theta._evaluate = slow_evaluate


def slowed_imex():
    solve_stars = star_kernel.solve_stars

    def slow_solve_stars(*args):
        abort, end = args[-1], time.monotonic() + delay
        while time.monotonic() < end and not abort[0]:
            time.sleep(0.01)
        return solve_stars(*args)

    star_kernel.solve_stars = slow_solve_stars


resumed = "--resume" in sys.argv[3:]
{"theta": slowed_theta, "imex": slowed_imex, "imex-first": (lambda: None) if resumed else slowed_imex}[kind]()
sys.exit(cli.main(sys.argv[3:]))
