"""`dolfrag` (argv[2:]) with every residual evaluation of the theta Newton slowed by argv[1]
seconds: a test-only slow step (two or three evaluations an iteration, a few iterations a
step), as on a large 3D mesh where an iteration costs seconds, so that a stop request
arrives while a step is in progress."""
import sys
import time

from dolfrag import cli
from dolfrag.solver.theta import Theta

delay = float(sys.argv[1])
evaluate = Theta._evaluate


def slow_evaluate(self, step, x, r):
    time.sleep(delay)
    return evaluate(self, step, x, r)


Theta._evaluate = slow_evaluate
sys.exit(cli.main(sys.argv[2:]))
