"""Where each star's stored factors live: a block of N^2 values (N = q + L d, the star's
unknowns) in one pool, taken when a star first keeps factors and given back when it keeps
none (RIGID: records.Cache).

In a structure most stars are held most of the time (stars/rigid.py) and keep no factors,
but every star solves Newton once at the first step, or after a restart or a rewind. Fixed
blocks, one per star, were each touched then and stayed in memory for the whole run:
measured on the 0.05 m bunker (210,197 tetrahedra, 2 ranks), 3.4 of the 6.2 GB a rank held
from its first step on. From the pool, only the stars that hold factors hold a block;
Newton works in its own workspace until its star keeps what it formed
(newton.solve_each).

The pool is one array of room for every star's block at once (its size in N^2 values,
memory the system gives on first touch only); a block is taken from the free blocks of its
star's size N, else from the untouched end (``top``), so that what a run touches is the
most blocks it held at once.
"""
from collections import namedtuple

import numpy as np
from numba import njit

Blocks = namedtuple("Blocks", (
    "at",        # (n_stars,) int: each star's block in the pool (its first value), -1 for none
    "size",      # (n_stars,) int: each star's N, the side of its block
    "free_off",  # (N_max + 2,) int: the free blocks of side N at free[free_off[N]:free_off[N + 1]]
    "free_n",    # (N_max + 1,) int: how many there are
    "free",      # (n_stars,) int: their places in the pool
    "top",       # (1,) int: the untouched end of the pool
))


def empty_blocks(N):
    """Blocks for stars of N unknowns each (N, int array), none taken, and the pool's size
    (values): room for every star's block."""
    N = np.asarray(N, dtype=np.int64)
    counts = np.bincount(N, minlength=1)
    free_off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    blocks = Blocks(np.full(len(N), -1, np.int64), N, free_off, np.zeros(len(counts), np.int64),
                    np.zeros(len(N), np.int64), np.zeros(1, np.int64))
    return blocks, int((N * N).sum())


@njit(cache=True, error_model="numpy")
def take(blocks, s):
    """Star s's block (its first value in the pool), taken if it has none."""
    if blocks.at[s] < 0:
        N = blocks.size[s]
        if blocks.free_n[N] > 0:
            blocks.free_n[N] -= 1
            blocks.at[s] = blocks.free[blocks.free_off[N] + blocks.free_n[N]]
        else:
            blocks.at[s] = blocks.top[0]
            blocks.top[0] += N * N
    return blocks.at[s]


@njit(cache=True, error_model="numpy")
def give_back(blocks, s):
    """Star s's block, if it has one, back among the free blocks of its size."""
    if blocks.at[s] >= 0:
        N = blocks.size[s]
        blocks.free[blocks.free_off[N] + blocks.free_n[N]] = blocks.at[s]
        blocks.free_n[N] += 1
        blocks.at[s] = -1


def give_back_all(blocks):
    """Every block back, the pool as before the first step: no star keeps factors."""
    blocks.at[:] = -1
    blocks.free_n[:] = 0
    blocks.top[0] = 0


@njit(cache=True, error_model="numpy")
def gather(blocks, factors, used, out):
    """The used values of the stars' blocks (used[s] of them, from each block's start; 0
    for a star without a block) one star after the other into out."""
    k = 0
    for s in range(len(used)):
        at = blocks.at[s]
        for i in range(used[s]):
            out[k + i] = factors[at + i]
        k += used[s]


@njit(cache=True, error_model="numpy")
def scatter(blocks, factors, values, holds, used, stride):
    """The inverse of gather: for each star that ``holds`` (bool), a block taken and its
    first used[s] values from values, where the stars' values follow one another, stride[s]
    of them each (stride = used: gather's layout)."""
    k = 0
    for s in range(len(holds)):
        if holds[s]:
            at = take(blocks, s)
            for i in range(used[s]):
                factors[at + i] = values[k + i]
        k += stride[s]
