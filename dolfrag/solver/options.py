"""Newton's tuning constants of the theta integrator, in one frozen object (each with the
measurement that set it). The star Newton of imex has its own (solver/stars/options.py:
StarOptions), whose cycle, regularisation and stall the theta Newton shares."""
from dataclasses import dataclass

from dolfrag.solver.stars.options import DEFAULT as STAR


@dataclass(frozen=True)
class NewtonOptions:
    """The theta step's global Newton (solver/theta/integrator.py)."""
    # cap and tolerance on the residual scaled by the step's largest momentum term; halvings of
    # a step Newton cannot finish
    max_iterations: int = 30
    rtol: float = 1e-10
    max_cuts: int = 4
    # doublings of MUMPS' workspace relaxation tried when a factorisation runs out of it
    mumps_relaxations: int = 6
    # A Newton correction from the factorisation in hand (an older Jacobian of the same step
    # length) is taken when it divides the scaled residual by 1 / stale_contraction at least;
    # else the Jacobian is assembled and factorised at the current iterate. That is tried only
    # while at most stale_states of the links and bars are in another state (open, stick, slip;
    # slack, taut, yielding) than where it was assembled: a semi-smooth Newton step with a stale
    # active set sends the iterates astray (measured on wall-bending-clamped from 20 ms: 228
    # iterations and a cut with any state changed, 162 with none, 180 without reuse; over 100
    # elastic steps, 19 factorisations at 0.002 and 74 at 0).
    stale_contraction: float = 0.1
    stale_states: float = 0.002
    # The regularisation of redundant contact rows in a sub-step (a step Newton could not
    # finish whole, or one started at the last step's halving), from its regularise_after-th
    # iteration on, while the scaled residual is above near: a sticking or closed link whose
    # constraint is redundant takes reactions of ~1/regularisation times its residual from a
    # Newton step; at 1e-6 Newton cycled between such reactions down to h/16 (measured twice at
    # 34-36 ms of wall-bending-clamped: both sub-steps converge from the 5th iteration at 1e-3,
    # one still fails from the 10th). Near the solution the active set has settled, and 1e-3
    # would only slow the last digits down (a full run stalled at 3e-8 after 30 iterations;
    # measured). Not in whole steps: there it slowed the cracking RCCM bar of tests/mpi_theta.py
    # from 7-11 to 12-58 iterations a step and made one rank cut a step the other did not.
    cycle_regularisation: float = 1e-3
    regularise_after: int = 5
    near: float = 1e-4
    # A sub-step that does not converge at the last halving gets last_resort times the
    # iterations once (stick-slip cycles of a few links: one needed 94 iterations at h/16, at
    # 37.7 ms of wall-bending-clamped; measured) before ConvergenceError.
    last_resort: int = 4
    # steps without a halving before the sub-steps are made twice as long again
    relax_after: int = 4
    # halvings of a Newton step tried by the line search on the residual norm
    backtracks: int = 4
    # shared with the star Newton: damped steps after `cycle` iterations (active-set cycles),
    # the regularisation of sticking links' redundant rows, and the scaled residual at which a
    # stalled Newton is accepted
    cycle: int = STAR.cycle
    regularisation: float = STAR.regularisation
    stall: float = STAR.stall
