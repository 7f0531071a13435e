"""The records the compiled star solve reads and writes, and the codes it writes in them.

Stars are stored flat: star s owns the components [comp_off[s], comp_off[s+1]) (q of them,
copy-major) and the links [link_off[s], link_off[s+1]) of the star-link arrays (L of them),
whose two copies are slot_A, slot_B (0 .. q/d - 1). A star's unknowns z are ordered (x (q),
r_N of every link, then each tangential component of every link), N = q + L d of them.

Each record is a ``collections.namedtuple`` of arrays and scalars, which numba passes to
compiled functions as they are (a tuple: no copy, each field typed on its own):

    Geometry  the layout, fixed for a run (solver/semismooth.StarLayout builds it)
    StepData  what a step gives its stars (gather_stars fills the jumps and forces)
    Cache     each star's stored Jacobian factors and what they are good for
    Outputs   what solve_stars writes
    Star      one star's slices of Geometry and StepData (star_at), what the per-star
              kernels read
"""
from collections import namedtuple

import numpy as np
from numba import njit

from dolfrag.solver.stars.blocks import empty_blocks

Geometry = namedtuple("Geometry", (
    "comp_off",     # (n_stars + 1,) int: each star's first component
    "link_off",     # (n_stars + 1,) int: each star's first link
    "slot_A",       # (n_links,) int: the copy (within its star) on side A of each link
    "slot_B",       # (n_links,) int: the copy on side B
    "frame",        # (n_links, d, d): link frames, normal first
    "weight",       # (n_links,): m (2D) or m^2 (3D)
    "rho",          # (n_links,) Pa/m: the step's stiffness, the augmentation of the projections
    "frozen",       # (n_links,) bool: both copies prescribed (see residual.FROZEN)
    "mass",         # (n_comps,) kg: lumped
    "fixed",        # (n_comps,) bool: prescribed
    "elimination",  # (n_comps + d n_links,) int: each star's unknown_order, at comp_off + d link_off
    "rigid_off",    # (n_stars + 1,) int: each star's rigid inverse (rigid.rigid_inverses; empty: none)
    "rigid",        # the rigid inverses, n^2 values a star of n copies (d n^2 if one is prescribed)
))

StepData = namedtuple("StepData", (
    "rhs",         # (n_comps,) N s: h f
    "x_in",        # (n_comps,) m/s: the prescribed increments
    "g_n",         # (n_links, d) m: the jump of u_n, link frame
    "dg",          # (n_links, d) m: h B v_-, link frame
    "mu",          # (n_links,): friction
    "shift",       # (n_links,) Pa: the normal cohesion the constraint's cone is shifted by
    "cohesion_T",  # (n_links,) Pa: the tangential cohesion
    "k_N",         # (n_links,) Pa/m: the springs' secants, fixed for the step
    "k_T",         # (n_links,) Pa/m
    "h",           # s: the step
    "floor_m",     # the scales below which a star's momentum and contact residuals are read
    "floor_c",     #   against the step's largest instead (semismooth.FLOOR)
    "r_n",         # (n_links, d) Pa: the reactions of the step before (the sticking links' elastic reference)
))

Cache = namedtuple("Cache", (
    "blocks",    # blocks.Blocks: where each star's factors are in ``factors`` (N^2 values)
    "piv_off",   # (n_stars + 1,) int: each star's index, 2 N + 1 values (factor_jacobian)
    "factors",   # the pool of blocks holding the LU factors of the stars' stored Jacobians
    "pivots",    # int: their index (the coupled unknowns, the unit ones, the pivots)
    "codes",     # (n_links,) int8: the piece the factors are of
    "slip_dir",  # (n_links, d): their 3D slip directions and projection scales (piece_branches)
    "cached",    # (n_stars,) int8: what the factors are (NONE, APPROXIMATE, EXACT, STALE)
    "factored",  # (n_links, 3): the (k_N, k_T, mu) they were formed with
))

Outputs = namedtuple("Outputs", (
    "x",             # (n_comps,) m/s: the velocity increments
    "r",             # (n_links, d) Pa: the reactions, link frame
    "reaction",      # (n_comps,) N: the reactions of prescribed components
    "gbar",          # (n_links, d) m: the jump the springs are read at
    "slip",          # (n_links, d) m: the step's jump increment h B (v_- + x)
    "status",        # (n_stars,) int8: CONVERGED, STALLED, UNCONVERGED
    "residual",      # (n_stars,): the final scaled residual
    "counters",      # (4,) int: ITERATIONS, N_UNCONVERGED, N_STALLED, N_FIRST
    "entry_codes",   # (n_links,) int8: an unconverged star's pieces at entry (star_replay)
    "entry_cached",  # (n_stars,) int8: what its factors were, if it started from them
))

Star = namedtuple("Star", "q L slot_A slot_B frame w rho frozen m fixed rhs x_in g_n dg mu shift cohesion_T k_N k_T h r_n")

# What each star's solve ended as (Outputs.status): below rtol; accepted above it (from
# StarOptions.fallback on, within stall or give_up); unconverged.
CONVERGED, STALLED, UNCONVERGED = 0, 1, 2

# What a star's stored factors are (Cache.cached): nothing usable; the Jacobian of the last
# step's piece with 3D slip directions held (solver/active_set.py: a start for Newton, never
# reused by it); the exact Jacobian of an affine piece (a prediction that solves the star if
# it stays on the piece, and Newton's matrix on it); the exact Jacobian of an affine piece
# for the springs and friction of an earlier step (STALE: the damage of a link has changed
# since; see StarOptions.chord), or of a 3D slipping piece at an earlier iterate
# (newton._keep_newton_factors). Measured on bunker-h2 at 8 ms (0.2 m, 2,050 stars): 430
# stars with a slipping link started from zero took 4.3 Newton iterations each, half the
# kernel's time.
# RIGID: no factors; the star's last piece was closed and sticking on every link, and it
# tries the rigid path (rigid.py) first.
NONE, APPROXIMATE, EXACT, STALE, RIGID = 0, 1, 2, 3, 4
# Newton factorises the exact Jacobians of a star with APPROXIMATE factors into workspaces
# and leaves those in place: they stay its next step's start where their prediction solves
# it; where Newton's last Jacobian is of a slipping piece, that one replaces them
# (_keep_newton_factors); else they are given up (NONE) and keep_pieces forms the converged
# piece's.

# Indices into Outputs.counters.
ITERATIONS, N_UNCONVERGED, N_STALLED, N_FIRST = 0, 1, 2, 3


@njit(cache=True, error_model="numpy")
def star_at(geometry, data, s):
    """Star s's slices of the layout and of the step's data."""
    p0, p1 = geometry.comp_off[s], geometry.comp_off[s + 1]
    l0, l1 = geometry.link_off[s], geometry.link_off[s + 1]
    return Star(p1 - p0, l1 - l0, geometry.slot_A[l0:l1], geometry.slot_B[l0:l1], geometry.frame[l0:l1],
                geometry.weight[l0:l1], geometry.rho[l0:l1], geometry.frozen[l0:l1], geometry.mass[p0:p1],
                geometry.fixed[p0:p1], data.rhs[p0:p1], data.x_in[p0:p1], data.g_n[l0:l1], data.dg[l0:l1],
                data.mu[l0:l1], data.shift[l0:l1], data.cohesion_T[l0:l1], data.k_N[l0:l1], data.k_T[l0:l1], data.h,
                data.r_n[l0:l1])


def empty_cache(comp_off, link_off, d):
    """A Cache with room for every star's factors and nothing stored (NONE)."""
    q, L = np.diff(comp_off), np.diff(link_off)
    N = q + L * d
    blocks, pool = empty_blocks(N)
    piv_off = np.concatenate([[0], np.cumsum(2 * N + 1)]).astype(np.int64)
    n_links = int(link_off[-1])
    return Cache(blocks, piv_off, np.zeros(pool), np.zeros(piv_off[-1], np.int64),
                 np.zeros(n_links, np.int8), np.zeros((n_links, d)), np.zeros(len(q), np.int8),
                 np.zeros((n_links, 3)))


def empty_outputs(n_stars, n_comps, n_links, d):
    """Outputs of zeros for n_stars stars of n_comps components and n_links links."""
    return Outputs(np.zeros(n_comps), np.zeros((n_links, d)), np.zeros(n_comps), np.zeros((n_links, d)),
                   np.zeros((n_links, d)), np.zeros(n_stars, np.int8), np.zeros(n_stars), np.zeros(4, np.int64),
                   np.zeros(n_links, np.int8), np.zeros(n_stars, np.int8))
