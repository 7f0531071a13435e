"""The compiled star solve of the nonsmooth imex step, as the rest of dolfrag calls it
(solver/semismooth.py, solver/star_replay.py; ``make install`` calls warm() to compile it
into numba's cache). The kernels and their records live in solver/stars/."""
from dolfrag.solver.stars.jacobian import factor_piece
from dolfrag.solver.stars.loop import gather_stars, keep_pieces, solve_stars, star_geometry, warm
from dolfrag.solver.stars.options import DEFAULT, StarOptions
from dolfrag.solver.stars.records import (APPROXIMATE, CONVERGED, EXACT, ITERATIONS, N_FIRST, N_STALLED,
                                          N_UNCONVERGED, NONE, RIGID, STALE, STALLED, UNCONVERGED, Cache, Geometry,
                                          Outputs, StepData, empty_cache, empty_outputs, star_at)
from dolfrag.solver.stars.residual import evaluation

__all__ = ["APPROXIMATE", "CONVERGED", "DEFAULT", "EXACT", "ITERATIONS", "N_FIRST", "N_STALLED", "N_UNCONVERGED",
           "NONE", "RIGID", "STALE", "STALLED", "UNCONVERGED", "Cache", "Geometry", "Outputs", "StarOptions", "StepData",
           "empty_cache", "empty_outputs", "evaluation", "factor_piece", "gather_stars", "keep_pieces", "solve_stars",
           "star_at", "star_geometry", "warm"]
