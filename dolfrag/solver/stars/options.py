"""The star Newton's tuning, one record (each value with the measurement that set it).

StarOptions is a namedtuple, so that the compiled loop takes it as an argument: a case or a
step (semismooth's second pass) changes it without recompiling. Read as runtime values the
fields cost nothing measurable against compile-time constants (benchmarks/step_cost.py,
before and after the change: see the commit that introduced this record).
"""
from typing import NamedTuple

from numba import njit


class StarOptions(NamedTuple):
    """The star Newton's tuning (solver/stars/newton.py)."""
    # A star has converged once its residual is below rtol of its largest term (scaled as in
    # residual.evaluate): ~1e6 times round-off, where the quadratic phase of Newton has ended.
    rtol: float = 1e-10
    # The first pass's iterations (a step's second pass: semismooth.ESCALATION times these).
    # 100 before Gauss-Seidel stopped at sweep_tol: now the hard stars' last 50 iterations of
    # the first pass mostly ran Gauss-Seidel on stars the second pass solves anyway (captured
    # call of the cracking panel, both passes: 3.1 s at 100, 2.0-2.4 s at 50; bunker-h2 at
    # 0.1 m on 2 ranks, 300 s resumed: 94 and 96 steps).
    max_iterations: int = 50
    # Start each star from the affine prediction of its stored piece (solver/active_set.py);
    # False: every star from zero.
    predict: bool = True
    # A star whose last piece was closed and sticking on every link, each a stiff joint,
    # first tries that piece held (rigid.py): its motion and reactions from the stored inverse
    # of its joints' system instead of Newton on q + L d unknowns, accepted where its
    # residual is within rtol. False: every star takes Newton.
    rigid: bool = True
    # Rigid constraints around a vertex were redundant: the jumps of an interior star sum to
    # zero around the vertex, so when every link stuck the constraint rows lost rank and the
    # exact Jacobian was singular. Held links are stiff joints now (active_set.COMPLIANCE), so
    # it is regular there; the Newton matrix gets ``regularisation`` on the reaction diagonal
    # (d phi / d r) of sticking links only where no joint holds the row: the normal row of a
    # closed link without tensile strength (stars/jacobian.py). The residual stays exact, so
    # the solution does. On every sticking row, as it was, the stored factors of a piece of
    # joints were 1e-6 / 1e-3 off its Jacobian, so that no prediction solved a star that
    # took Newton at iteration 1: measured on bunker-wall-panel at 0.0667 m, the 659 stars a
    # step of its clamped edges (frozen links, no rigid path) took 2 iterations each before
    # it cracked, and 1 since; cracking, 32-40 % fewer iterations. A step's second pass takes
    # more (semismooth.SECOND_REGULARISATION).
    regularisation: float = 1e-6
    # Full Newton steps for ``cycle`` iterations, then backtracking on the scaled residual: a
    # semi-smooth Newton can cycle between active sets of contact and friction (measured on
    # the rigid laws, and on linear softening with friction: period-4 cycles of a star whose
    # sprung link toggles between open and slipping); halving the step (at most ``shortest``
    # times) from the last point that lowered the residual breaks the cycle.
    cycle: int = 20
    shortest: int = 6
    # A star started from its prediction and not solved after ``restart`` iterations starts
    # again from zero (x = 0, r = 0), the start that the solver had before predictions:
    # measured on expanding-bar (linear softening, 3 mm, normalised rate 0.1,
    # benchmarks/robustness.py), an interior ring of six rigid links wandered from its
    # prediction through 1,000 iterations, Gauss-Seidel included, and converges from zero in 6.
    # The restart keeps the schedule of a start from zero (cycle, fallback counted from it):
    # counted from the first iteration, a random 3D slipping star that needs Gauss-Seidel (36
    # iterations from zero) met it 20 iterations early and did not converge in 100
    # (tests/test_star_kernel.py).
    restart: int = 10
    # Newton iterations after which a star still unconverged alternates projected
    # Gauss-Seidel sweeps (gauss_seidel.py, see sweeps) with full Newton steps from their
    # result (which finish the job once Gauss-Seidel has found the active set).
    fallback: int = 30
    # Where the semi-smooth Newton stalls (a link sitting on the kink between stick and slip,
    # measured on the rigid laws with friction: residuals stuck at 1e-10 .. 2e-9 of the star's
    # reactions), a star within ``stall`` is accepted from ``fallback`` iterations on.
    stall: float = 1e-8
    # From ``fallback`` on, a star whose contact and friction are within ``stall`` and whose
    # momentum is within ``give_up`` is accepted; so is, after max_iterations, the best
    # iterate it reached if within ``give_up`` overall (both counted as stalled). Measured on
    # wall-bending-clamped under imex at 51 ms: a closed star of 6 links (4 broken and in
    # contact, 1 partly damaged and sticking, 1 intact), whose normal springs (opening only)
    # sit on their kink at g_N = 0: Gauss-Seidel solves its contact and friction to 1e-10, and
    # leaves the momentum at 6.3e-7 (the springs' side of the kink read at a gap exact only to
    # the contact tolerance, 1e-13 m); each Newton polish from there sent it astray. Reading
    # closed links' springs at the jump contact pins (see residual.evaluate) removed that
    # case; ``give_up`` stays the last net. 1e-6 of the star's momentum is far below any
    # error of the discretisation; a star above it still stops the run.
    give_up: float = 1e-6
    # A star whose best iterate is within give_up and has not fallen tenfold in ``plateau``
    # iterations (from fallback on, and since it came within give_up) ends there, accepted
    # at that best as after max_iterations. Only a second pass runs that long: there the
    # rigid 3D stars with friction, once within give_up, crawl on to 1e-8 through the
    # kinks of their pieces. Measured on the 26 second-pass calls of a cracking 3D box
    # (benchmarks/hard_stars.py): 20 of them ran to 1,000 iterations, ending at 1e-9 to
    # 9e-7; solved again alone, 26.3 s of CPU without the stop, 6.2 s at 100 (11.3 s at
    # 200, 5.1 s at 50), every star accepted within give_up.
    plateau: int = 100
    # Projected Gauss-Seidel sweeps in the first fallback call, doubled at each call up to
    # ``max_sweeps``: Newton usually finishes after a few hundred, but with friction mu = 0.6
    # the sweeps crawl (measured: up to 14,455 before the reactions settle, sound-bar with
    # linear softening), and a fixed budget of 300 let each Newton polish undo them.
    sweeps: int = 300
    max_sweeps: int = 20000
    # Newton steps from a Gauss-Seidel call's result before the next call: the first pass's
    # (a step's second pass takes semismooth.SECOND_POLISH).
    polish: int = 1
    # Gauss-Seidel stops earlier once no reaction changes in a sweep by more than
    # ``sweep_tol`` of the largest: it is there to find the star's piece, which Newton then
    # solves exactly; the star's answer is still held to rtol. Measured on a captured call
    # of the cracking 3D panel (bunker-wall-panel, linear softening, 0.1 m, 13.35 ms, 2,012
    # stars): at 1e-14 (round-off, as it was) every Gauss-Seidel call ran its whole budget,
    # 4.1 s for the first pass and 2.8 s for the second; at 1e-4, 1.5 s and 1.4 s, every
    # star solved. At 1e-3 one star was left unsolved after the second pass. A few stars need
    # the sweeps to round-off (bunker-h2 at 0.1 m, 8.49 ms): a step's third pass gives them
    # that (semismooth.LAST_SWEEP_TOL). 2D stars sweep to sweep_tol_2d, round-off: their
    # sweeps cost little, and stopped at 1e-4 they gave more star solves accepted at their
    # best iterate (benchmarks/robustness.py, linear softening at 3 mm and rate 0.1: 4 against
    # 1) and 1- and 2-rank runs that part ways (expanding-bar at 4 mm with fib2010: 1,502
    # against 1,503-1,504 broken links, tests/test_rate_effect.py).
    sweep_tol: float = 1e-4
    sweep_tol_2d: float = 1e-14
    # Stale factors (the piece's Jacobian for an earlier damage) stay Newton's matrix on their
    # piece - a chord iteration, which converges to the same solution as the exact matrix - as
    # long as each chord step divides the scaled residual by 1 / ``chord`` at least; below
    # that a fresh Jacobian is cheaper. Damage goes on changing every step in links already
    # broken (an RCCM link's beta keeps falling as w / Y' while it opens): measured on
    # wall-bending-clamped at 50 ms, 469 of 1,708 links changed their damage in a step and
    # 197 of its 359 stars were factorised again for them alone. 1e-2 until a 3D star's fresh
    # Jacobian and LU (~36 us) were measured against its chord steps (~5 us each): on captured
    # calls of the cracking bunker-h2 (0.2 m, at steps 1,500, 2,500 and 3,100), its stars off
    # the held path took 14.79, 19.51, 22.60 ms at 1e-2, 14.43, 18.53, 21.56 at 0.03, 13.73,
    # 16.61, 20.42 at 0.1 and 14.22, 16.29, 20.20 at 0.3; on the 2D captured calls (the
    # damaged bars of RCCM and linear softening, the expanding bar) within the noise.
    chord: float = 0.1
    # A star whose iterate reads another piece than its stored factors' only by links
    # flipping between contact and open (an intact link crossing g_N = 0: its normal row and
    # its spring's n n^T in the momentum block change, rank 2 each) solves with those factors
    # and a Woodbury correction instead of a new Jacobian and LU, for up to ``flips`` such
    # links, and keeps them as its reference piece for the next step. From ``woodbury``
    # coupled unknowns on: measured on the damaged 3D bar (150 unknowns, 73 coupled), a new
    # Jacobian and LU cost 36 us, a solve in cache ~2 us; in 2D the LU (1.5 us) is as cheap as
    # the correction. Up to 4 links rather than 2: the damaged 3D step 15,545-15,593 ->
    # 13,271-13,450 ns per element-step (a third of its flips change 3 links or more).
    flips: int = 4
    woodbury: int = 32


DEFAULT = StarOptions()


@njit(cache=True)
def sweep_tolerance(options, d):
    """Where Gauss-Seidel stops for a star in ``d`` dimensions (see StarOptions.sweep_tol)."""
    return options.sweep_tol if d == 3 else options.sweep_tol_2d
