"""When each link broke, and the star solves' convergence, checked every step."""
import numpy as np
from mpi4py import MPI

from dolfrag.solver.semismooth import ConvergenceError
from dolfrag.runner.context import Observer


class BreakTimes(Observer):
    STATE = ("break_time",)

    def __init__(self, ctx):
        self.ctx = ctx
        self.break_time = ctx.break_time  # s, NaN while sound: shared with the context

    def observe(self, step):
        integ = self.ctx.integ
        if not self.ctx.problem.law.breakable:
            return
        self.break_time[integ.model.broken() & np.isnan(self.break_time)] = integ.t
        integ.timer.lap("diagnostics")
        _check_converged(integ, self.ctx.comm)
        integ.timer.lap("communication")


def _check_converged(integ, comm):
    """Raise ConvergenceError if a star's Newton failed this step (imex). Collective."""
    stars = comm.allreduce(integ.interface.unconverged)
    if stars:
        residual = comm.allreduce(integ.interface.residual, op=MPI.MAX)
        raise ConvergenceError(
            f"t = {integ.t:.6g} s (step {integ.n}): {stars} vertex star(s) did not converge in "
            f"{integ.interface.max_iterations * max(integ.interface.escalation, 1)} Newton iterations (worst "
            f"scaled residual {residual:.3g}, "
            f"tolerance {integ.interface.rtol:g}); the state is saved in failure.pvd, the stars in "
            f"failed_stars_rank<r>.npz (`dolfrag replay <file>` solves them again)")
