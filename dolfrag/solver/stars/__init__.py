"""Compiled solves of the vertex stars of the nonsmooth imex step (solver/semismooth.py
states the problem): one loop over a rank's stars per step, each star's whole semi-smooth
Newton inside. A package of one idea per module, from the bottom up:

    records.py       the records the loop reads and writes (layout, step data, cache,
                     outputs, one star's slices) and the codes it writes in them
    options.py       StarOptions, the Newton's tuning, one record
    blocks.py        where each star's stored factors live: blocks of one pool
    lu.py            dense LU in place, the solves from a star's stored factors, Woodbury
    residual.py      a star's residual and the branches of its projections at an iterate
    jacobian.py      its generalised Jacobian, LU with the identity rows set apart, pieces
    ordering.py      the elimination order of each star's unknowns
    gauss_seidel.py  the projected Gauss-Seidel fallback
    rigid.py         a star closed and sticking on every link, its joints solved from a stored inverse
    newton.py        one star's Newton, and what it keeps of its factors
    loop.py          the loops over the stars: gather_stars, solve_stars, keep_pieces, warm

solver/star_kernel.py is the interface the rest of dolfrag calls.

The springs of every model are secants lagged by one step (interface/models.py): a link's
traction is k_N <gbar_N>+ and k_T gbar_T, with k_N, k_T (Pa/m) fixed for the step
(model.secants).
"""
