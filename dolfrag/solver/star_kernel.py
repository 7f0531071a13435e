"""Compiled solves of the vertex stars of the nonsmooth imex step: one loop over a rank's
stars per step, each star's whole semi-smooth Newton inside (solver/semismooth.py states
the problem).

Stars are stored flat: star s owns the components comps[comp_off[s]:comp_off[s+1]] (q of
them, copy-major) and the links [link_off[s], link_off[s+1]) of the star-link arrays
(L of them), whose two copies are slot_A, slot_B (0 .. q/d - 1). A star's unknowns z are
ordered (x (q), r_N of every link, then each tangential component of every link), N =
q + L d of them; its Jacobian's LU factors (partial pivoting, a third of the work of an
explicit inverse; factor_jacobian sets the identity rows apart) are kept in
``factors`` at fac_off[s] (N^2 values) with their index at piv_off[s] (2 N + 1), for the
next step's prediction (solver/active_set.py).

The springs of every model are secants lagged by one step (interface/models.py): a link's
traction is k_N <gbar_N>+ and k_T gbar_T, with k_N, k_T (Pa/m) fixed for the step
(model.secants). ``warm()`` compiles the kernels into numba's cache
(``make install`` calls it).
"""

import numpy as np
from numba import njit

from dolfrag.solver.active_set import (CONTACT, NEGATIVE, PRESSED, SLIP, SPRING, STICK, affine_constant, link_code,
                                      spring_normal_tangent)

# A link whose two copies are both prescribed (between supported copies, or in a patch
# test) has a known jump, so Newton cannot move it and its contact rows would be singular.
# Its reaction is the projection itself, taken with the augmentation FROZEN times larger
# (so a prescribed opening releases the constraint at once) and iterated as a fixed
# point: identity rows in the Jacobian.
FROZEN = 1e6

# Rigid constraints around a vertex are redundant: the jumps of an interior star sum to zero
# around the vertex, so when every link sticks (a rigid threshold or linear-softening star,
# or a frictional contact ring) the constraint rows lose rank and the exact Jacobian is
# singular. The Newton matrix gets REGULARISATION on the reaction diagonal (d phi / d r) of
# sticking links only (elsewhere Newton stays exact: on a piecewise-linear piece it lands in
# one step, which a cold start needs):
# the residual stays exact, so the solution does too; Newton converges at a rate of about
# REGULARISATION per iteration instead of exactly, and picks one of the equivalent
# reactions in the redundant directions (they do no work: same motion, same energies).
REGULARISATION = 1e-6

# A star has converged once its residual is below RTOL of its largest term (scaled as in
# _evaluate): ~1e6 times round-off, where the quadratic phase of Newton has ended.
RTOL = 1e-10

# Full Newton steps for this many iterations, then backtracking on the scaled residual:
# a semi-smooth Newton can cycle between active sets of contact and friction (measured on
# the rigid laws, and on linear softening with friction: period-4 cycles of a star whose
# sprung link toggles between open and slipping); halving the step (at most SHORTEST
# times) from the last point that lowered the residual breaks the cycle.
CYCLE = 20
SHORTEST = 6

# A star started from its prediction and not solved after RESTART iterations starts again
# from zero (x = 0, r = 0), the start that the solver had before predictions: measured on
# expanding-bar (linear softening, 3 mm, normalised rate 0.1, benchmarks/robustness.py), an
# interior ring of six rigid links wandered from its prediction through 1,000 iterations,
# Gauss-Seidel included, and converges from zero in 6. The restart keeps the schedule of a
# start from zero (CYCLE, FALLBACK counted from it): counted from the first iteration, a
# random 3D slipping star that needs Gauss-Seidel (36 iterations from zero) met it 20
# iterations early and did not converge in 100 (tests/test_star_kernel.py).
RESTART = 10

# Where the semi-smooth Newton stalls (a link sitting on the kink between stick and slip,
# measured on the rigid laws with friction: residuals stuck at 1e-10 .. 2e-9 of the star's
# reactions), a star within STALL is accepted from FALLBACK iterations on.
STALL = 1e-8

# From FALLBACK on, a star whose contact and friction are within STALL and whose momentum
# is within GIVE_UP is accepted; so is, after max_iterations, the best iterate it reached
# if within GIVE_UP overall (both counted as stalled). Measured on wall-bending-clamped
# under imex at 51 ms: a closed star of 6 links (4 broken and in contact, 1 partly damaged
# and sticking, 1 intact), whose normal springs (opening only) sit on their kink at
# g_N = 0: Gauss-Seidel solves its contact and friction to 1e-10, and leaves the momentum
# at 6.3e-7 (the springs' side of the kink read at a gap exact only to the contact
# tolerance, 1e-13 m); each Newton polish from there sent it astray. Reading closed links'
# springs at the jump contact pins (see _evaluate) removed that case; GIVE_UP stays the
# last net. 1e-6 of the star's momentum is far below any error of the discretisation; a
# star above it still stops the run.
GIVE_UP = 1e-6

# Newton iterations after which a star still unconverged alternates projected Gauss-Seidel
# sweeps (_gauss_seidel, see SWEEPS) with full Newton steps from their result (which
# finish the job once Gauss-Seidel has found the active set).
FALLBACK = 30

# Projected Gauss-Seidel sweeps in the first fallback call, doubled at each call up to
# MAX_SWEEPS: Newton usually finishes after a few hundred, but with friction mu = 0.6 the
# sweeps crawl (measured: up to 14,455 before the reactions settle, sound-bar with linear
# softening), and a fixed budget of 300 let each Newton polish undo them.
SWEEPS = 300
MAX_SWEEPS = 20000

# What each star's solve ended as (``status``): below rtol; accepted above it (from
# FALLBACK on, within STALL or GIVE_UP); unconverged.
CONVERGED, STALLED, UNCONVERGED = 0, 1, 2

# What a star's stored factors are (``cached``): nothing usable; the Jacobian of the last
# step's piece with 3D slip directions held (solver/active_set.py: a start for Newton, never
# reused by it); the exact Jacobian of an affine piece (a prediction that solves the star if
# it stays on the piece, and Newton's matrix on it); the exact Jacobian of an affine piece
# for the springs and friction of an earlier step (STALE: the damage of a link has changed
# since; see CHORD), or of a 3D slipping piece at an earlier iterate (_keep_newton_factors).
# Measured on bunker-h2 at 8 ms (0.2 m, 2,050 stars): 430 stars with a slipping link started
# from zero took 4.3 Newton iterations each, half the kernel's time.
NONE, APPROXIMATE, EXACT, STALE = 0, 1, 2, 3
# Newton factorises the exact Jacobians of a star with APPROXIMATE factors into workspaces
# and leaves those in place: they stay its next step's start where their prediction solves
# it; where Newton's last Jacobian is of a slipping piece, that one replaces them
# (_keep_newton_factors); else they are given up (NONE) and keep_pieces forms the converged
# piece's.

# Stale factors (the piece's Jacobian for an earlier damage) stay Newton's matrix on their
# piece - a chord iteration, which converges to the same solution as the exact matrix - as
# long as each chord step divides the scaled residual by 1 / CHORD at least; below that a
# fresh Jacobian is cheaper. Damage goes on changing every step in links already broken
# (an RCCM link's beta keeps falling as w / Y' while it opens): measured on
# wall-bending-clamped at 50 ms, 469 of 1,708 links changed their damage in a step and
# 197 of its 359 stars were factorised again for them alone.
CHORD = 1e-2

# A star whose iterate reads another piece than its stored factors' only by links flipping
# between contact and open (an intact link crossing g_N = 0: its normal row and its spring's
# n n^T in the momentum block change, rank 2 each) solves with those factors and a Woodbury
# correction instead of a new Jacobian and LU, for up to FLIPS such links, and keeps them as
# its reference piece for the next step. From WOODBURY coupled unknowns on: measured on the
# damaged 3D bar (150 unknowns, 73 coupled), a new Jacobian and LU cost 36 us, a solve in
# cache ~2 us; in 2D the LU (1.5 us) is as cheap as the correction. Up to 4 links rather
# than 2: the damaged 3D step 15,545-15,593 -> 13,271-13,450 ns per element-step (a third
# of its flips change 3 links or more).
FLIPS = 4
WOODBURY = 32

# Indices into the counters the kernel returns.
ITERATIONS, N_UNCONVERGED, N_STALLED, N_FIRST = 0, 1, 2, 3

# Columns of the per-link branch table of _evaluate.
B_CONTACT, B_STICK, B_SLIP, B_PRESSED, B_SCALE = 0, 1, 2, 3, 4


# ---------------------------------------------------------------- dense LU, in place

@njit(cache=True, error_model="numpy")
def _swap_in_pivot(A, k, piv):
    """Partial pivoting at column k: the row (>= k) of the largest |A[., k]| swapped into row
    k, its index in piv[k]."""
    n = A.shape[0]
    p, big = k, abs(A[k, k])
    for i in range(k + 1, n):
        if abs(A[i, k]) > big:
            p, big = i, abs(A[i, k])
    piv[k] = p
    if p != k:
        for j in range(n):
            A[k, j], A[p, j] = A[p, j], A[k, j]


@njit(cache=True, error_model="numpy")
def lu_factor(A, piv):
    """LU factors of the square A (n, n) in place, partial pivoting; piv (n,) the row swaps.

    Right-looking, two pivots per sweep: each trailing row is updated by pivot rows k and
    k + 1 in one pass, A_ij <- (A_ij - l_ik A_kj) - l_i,k+1 A_k+1,j, which reads and writes
    it once instead of twice (measured: 1.7x faster at n = 44, 1.45x at 83) in the order of
    operations of one pivot at a time, so the factors are bit-identical to the textbook
    loop (tests/test_star_kernel.py). A zero pivot eliminates nothing, as there."""
    n = A.shape[0]
    k = 0
    while k < n:
        _swap_in_pivot(A, k, piv)
        if k + 1 == n or A[k, k] == 0.0:  # one pivot alone
            if A[k, k] != 0.0:
                inverse = 1.0 / A[k, k]
                for i in range(k + 1, n):
                    factor = A[i, k] * inverse
                    A[i, k] = factor
                    if factor != 0.0:
                        for j in range(k + 1, n):
                            A[i, j] -= factor * A[k, j]
            k += 1
            continue
        # column k's multipliers, column k + 1 and row k + 1 updated by row k: what the
        # second pivot's choice and row need
        inverse = 1.0 / A[k, k]
        for i in range(k + 1, n):
            factor = A[i, k] * inverse
            A[i, k] = factor
            if factor != 0.0:
                A[i, k + 1] -= factor * A[k, k + 1]
        _update_row(A, k + 1, k)
        p, big = k + 1, abs(A[k + 1, k + 1])
        for i in range(k + 2, n):
            if abs(A[i, k + 1]) > big:
                p, big = i, abs(A[i, k + 1])
        piv[k + 1] = p
        done = -1  # the row, below k + 1, already updated by row k
        if p != k + 1:
            _update_row(A, p, k)
            for j in range(n):
                A[k + 1, j], A[p, j] = A[p, j], A[k + 1, j]
            done = p
        second = A[k + 1, k + 1] != 0.0
        inverse = 1.0 / A[k + 1, k + 1] if second else 0.0
        for i in range(k + 2, n):
            f1 = 0.0 if i == done else A[i, k]
            f2 = A[i, k + 1] * inverse
            if second:
                A[i, k + 1] = f2
            if f1 != 0.0 and f2 != 0.0:
                for j in range(k + 2, n):
                    A[i, j] = (A[i, j] - f1 * A[k, j]) - f2 * A[k + 1, j]
            elif f1 != 0.0:
                for j in range(k + 2, n):
                    A[i, j] -= f1 * A[k, j]
            elif f2 != 0.0:
                for j in range(k + 2, n):
                    A[i, j] -= f2 * A[k + 1, j]
        k += 2


@njit(cache=True, error_model="numpy")
def _update_row(A, i, k):
    """Row i, beyond column k + 1, updated by pivot row k (its multiplier in A[i, k])."""
    factor = A[i, k]
    if factor != 0.0:
        for j in range(k + 2, A.shape[0]):
            A[i, j] -= factor * A[k, j]


@njit(cache=True, error_model="numpy")
def lu_solve(LU, piv, b):
    """Solve A y = b in place (b (n,)), from lu_factor's LU and piv.

    Four rows at a time: a row's sum is a chain of dependent subtractions, so one row at a
    time waits on each; four rows share each b_j and run four chains side by side (measured:
    n = 24, 0.64 -> 0.33 us; 44, 1.8 -> 0.8). Forward, each row is summed in the order of
    one row at a time; backward, from the last column down (the order the blocks need)."""
    n = LU.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    i = 0
    while i + 4 <= n:
        s0, s1, s2, s3 = b[i], b[i + 1], b[i + 2], b[i + 3]
        for j in range(i):
            b_j = b[j]
            s0 -= LU[i, j] * b_j
            s1 -= LU[i + 1, j] * b_j
            s2 -= LU[i + 2, j] * b_j
            s3 -= LU[i + 3, j] * b_j
        s1 -= LU[i + 1, i] * s0
        s2 -= LU[i + 2, i] * s0
        s2 -= LU[i + 2, i + 1] * s1
        s3 -= LU[i + 3, i] * s0
        s3 -= LU[i + 3, i + 1] * s1
        s3 -= LU[i + 3, i + 2] * s2
        b[i], b[i + 1], b[i + 2], b[i + 3] = s0, s1, s2, s3
        i += 4
    for i in range(i, n):
        s = b[i]
        for j in range(i):
            s -= LU[i, j] * b[j]
        b[i] = s
    i = n - 1
    while i >= 3:
        s0, s1, s2, s3 = b[i], b[i - 1], b[i - 2], b[i - 3]
        for j in range(n - 1, i, -1):
            b_j = b[j]
            s0 -= LU[i, j] * b_j
            s1 -= LU[i - 1, j] * b_j
            s2 -= LU[i - 2, j] * b_j
            s3 -= LU[i - 3, j] * b_j
        s0 /= LU[i, i]
        s1 = (s1 - LU[i - 1, i] * s0) / LU[i - 1, i - 1]
        s2 = ((s2 - LU[i - 2, i] * s0) - LU[i - 2, i - 1] * s1) / LU[i - 2, i - 2]
        s3 = (((s3 - LU[i - 3, i] * s0) - LU[i - 3, i - 1] * s1) - LU[i - 3, i - 2] * s2) / LU[i - 3, i - 3]
        b[i], b[i - 1], b[i - 2], b[i - 3] = s0, s1, s2, s3
        i -= 4
    for i in range(i, -1, -1):
        s = b[i]
        for j in range(n - 1, i, -1):
            s -= LU[i, j] * b[j]
        b[i] = s / LU[i, i]


# ---------------------------------------------------------------- one star

@njit(cache=True, error_model="numpy")
def _ratio(a, scale):
    """a / scale, 0 where both vanish (a star at rest), inf where only the scale does."""
    if scale > 0:
        return a / scale
    return np.inf if a > 0 else 0.0


@njit(cache=True, error_model="numpy")
def _evaluate(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, rhs, g_n, dg, mu, shift, cohesion_T, k_N,
              k_T, h, x, r, floor_m, floor_c, Bx, gbar, slip, branch, e, force, R, reaction, code, scratch):
    """The star's residual R (q + L d) at (x (q), r (L, d)), in the unknowns' order, and its
    scaled parts (momentum, contact), returned. Per link it leaves B x in the link frame
    (Bx), the jump the springs are read at (gbar), the end-of-step slip h B (v_- + x)
    (slip), the branches of the projections (branch, e: slip direction) and the piece
    (code); per component the interface force h B^T w (t - r) (force) and the reactions
    of prescribed components (reaction, N). Frozen links take FROZEN rho;
    scratch (>= 2 d,) workspace.

        R_m = m x - h f + h B^T w (t(gbar) - r)       (0 on prescribed components)
        phi = Alart-Curnier of Signorini-Coulomb on the cone shifted by the cohesion,
              at g_end = g_n + dg + h B x            (interface/contact.py)
        gbar = g_n + h B x / 4, but 3 g_n,N / 4 - dg_N / 4 on closed links

    Closed links read their normal spring at the jump contact pins (where g_end,N = 0),
    which does not move with x: read at gbar(x), a spring acting in opening only sat on its
    kink at g_N = 0 at gaps exact to the contact tolerance (1e-13 m), and Newton and
    Gauss-Seidel, each on one side, did not meet (measured: see GIVE_UP).
    """
    for i in range(q):
        force[i] = 0.0
    max_phi, max_r, max_terms = 0.0, 0.0, 0.0
    probe = 0.0  # the sum of the residual: NaN if any entry is (max() drops a NaN)
    jump, t = scratch[:d], scratch[d:2 * d]
    for l in range(L):
        a, b = slot_A[l], slot_B[l]
        for j in range(d):
            jump[j] = x[b * d + j] - x[a * d + j]
        for i in range(d):
            s = 0.0
            for j in range(d):
                s += frame[l, i, j] * jump[j]
            Bx[l, i] = s
            gbar[l, i] = g_n[l, i] + 0.25 * h * s
            slip[l, i] = dg[l, i] + h * s
            max_terms = max(max_terms, rho[l] * (abs(g_n[l, i]) + abs(dg[l, i]) + h * abs(s)))
            max_r = max(max_r, abs(r[l, i]))
        rho_l = FROZEN * rho[l] if frozen[l] else rho[l]
        # shifted Signorini on r~_N = r_N + shift, Coulomb on the shifted cone
        r_shift = r[l, 0] + shift[l]
        y_N = r_shift - rho_l * (g_n[l, 0] + slip[l, 0])
        contact = y_N >= 0
        phi = r_shift - max(0.0, y_N)
        R[q + l] = phi
        max_phi = max(max_phi, abs(phi))
        probe += phi
        pressed = r_shift > 0
        radius = mu[l] * (r_shift if pressed else 0.0) + cohesion_T[l]
        norm = 0.0
        for i in range(1, d):
            y_i = r[l, i] - rho_l * slip[l, i]
            norm += y_i * y_i
        norm = np.sqrt(norm)
        stick = norm <= radius and radius > 0
        slipping = norm > radius and radius > 0
        scale = radius / norm if slipping else 0.0
        for i in range(1, d):
            y_i = r[l, i] - rho_l * slip[l, i]
            e[l, i - 1] = y_i / norm if slipping else 0.0
            phi = rho_l * slip[l, i] if stick else r[l, i] - scale * y_i
            R[q + i * L + l] = phi
            max_phi = max(max_phi, abs(phi))
            probe += phi
        branch[l, B_CONTACT] = 1.0 if contact else 0.0
        branch[l, B_STICK] = 1.0 if stick else 0.0
        branch[l, B_SLIP] = 1.0 if slipping else 0.0
        branch[l, B_PRESSED] = 1.0 if pressed else 0.0
        branch[l, B_SCALE] = scale
        if contact:
            gbar[l, 0] = 0.75 * g_n[l, 0] - 0.25 * dg[l, 0]
        code[l] = link_code(contact, stick, slipping, pressed, e[l, 0] if d > 1 else 0.0, gbar[l, 0])
        t[0] = w[l] * (k_N[l] * max(gbar[l, 0], 0.0) - r[l, 0])
        for i in range(1, d):
            t[i] = w[l] * (k_T[l] * gbar[l, i] - r[l, i])
        for j in range(d):
            F = 0.0
            for i in range(d):
                F += frame[l, i, j] * t[i]
            force[b * d + j] += h * F
            force[a * d + j] -= h * F
    scale_m, max_m = 0.0, 0.0
    for i in range(q):
        mx = m[i] * x[i]
        scale_m = max(scale_m, abs(rhs[i]), abs(mx), abs(force[i]))
        R_i = mx - rhs[i] + force[i]
        reaction[i] = R_i / h if fixed[i] else 0.0
        R[i] = 0.0 if fixed[i] else R_i
        max_m = max(max_m, abs(R[i]))
        probe += R[i]
    if probe != probe:  # an iterate gone NaN is never read as converged
        return np.inf, np.inf
    scale_c = max_r + max_terms
    return _ratio(max_m, max(scale_m, floor_m)), _ratio(max_phi, max(scale_c, floor_c))


@njit(cache=True, error_model="numpy")
def _jacobian_into(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, mu, k_N, k_T, h, code, branch, e,
                   position, n_c, A, C, scratch, at, regularisation):
    """The generalised Jacobian of (R_m, phi) at the point _evaluate last saw (its branch, e
    and code), added into the rows of the unknowns with position (N,) below n_c: entry
    (i, j) into A[position[i], position[j]] (n_c, n_c) where position[j] < n_c, else into
    C[position[i], position[j] - n_c]; the rows of the other unknowns, identity rows, are not
    stored. Frozen links have identity rows (see FROZEN); prescribed components identity
    rows and zero columns; sticking links get ``regularisation`` (REGULARISATION, or more in
    a step's second pass) on their reaction diagonal.
    Each link's block (its two copies and its reactions) is formed in scratch (>= 12 d^2,)
    and then added where it goes (at (>= 3 d, int): its rows' and columns' positions): a
    helper call per entry, with its array arguments, cost six times the whole matrix
    (measured)."""
    for i in range(q):
        if not fixed[i] and position[i] < n_c:
            A[position[i], position[i]] += m[i]
    RtDR = scratch[:d * d].reshape((d, d))
    JgR = scratch[d * d:2 * d * d].reshape((d, d))
    P = scratch[2 * d * d:3 * d * d].reshape((d, d))
    block = scratch[3 * d * d:12 * d * d].reshape((3 * d, 3 * d))  # rows and columns: copy a, copy b, reactions
    for l in range(L):
        a, b = slot_A[l], slot_B[l]
        R = frame[l]
        contact, stick = branch[l, B_CONTACT] > 0, branch[l, B_STICK] > 0
        slipping, pressed, scale = branch[l, B_SLIP] > 0, branch[l, B_PRESSED] > 0, branch[l, B_SCALE]
        rho_l = FROZEN * rho[l] if frozen[l] else rho[l]
        # springs: h^2/4 w R^T D R, D = diag(dN, k_T ...)
        dN = spring_normal_tangent(code[l], k_N[l])
        for i in range(d):
            for j in range(d):
                s = dN * R[0, i] * R[0, j]
                for k in range(1, d):
                    s += k_T[l] * R[k, i] * R[k, j]
                RtDR[i, j] = 0.25 * h * h * w[l] * s
        # tangential projection: P = scale (I - e e^T) where slipping
        for i in range(d - 1):
            for j in range(d - 1):
                P[i, j] = scale * ((1.0 if i == j else 0.0) - e[l, i] * e[l, j])
        # d phi / d x = h Jg R, Jg = diag(rho [contact], rho (I [stick] or P))
        for j in range(d):
            JgR[0, j] = (rho_l * R[0, j]) if contact else 0.0
            for i in range(1, d):
                s = 0.0
                for k in range(1, d):
                    s += (rho_l * (1.0 if i == k else 0.0) if stick else rho_l * P[i - 1, k - 1]) * R[k, j]
                JgR[i, j] = s
        for i in range(d):
            for j in range(d):
                block[i, j] = block[d + i, d + j] = RtDR[i, j]
                block[d + i, j] = block[i, d + j] = -RtDR[i, j]
                block[d + j, 2 * d + i] = -h * w[l] * R[i, j]  # reactions in the momentum rows: -h w B^T
                block[j, 2 * d + i] = h * w[l] * R[i, j]
                block[2 * d + i, d + j] = h * JgR[i, j]
                block[2 * d + i, j] = -h * JgR[i, j]
        # d phi / d r
        block[2 * d, 2 * d:] = 0.0
        block[2 * d, 2 * d] = 0.0 if contact else 1.0
        for i in range(1, d):
            block[2 * d + i, 2 * d] = -mu[l] * e[l, i - 1] if (slipping and pressed) else 0.0
            for k in range(1, d):
                block[2 * d + i, 2 * d + k] = 0.0 if stick else (1.0 if i == k else 0.0) - P[i - 1, k - 1]
        if stick:
            for i in range(d):
                block[2 * d + i, 2 * d + i] += regularisation
        for c in range(3 * d):  # where the block's rows and columns go (-1: a prescribed component's)
            u = a * d + c if c < d else (b * d + c - d if c < 2 * d else q + (c - 2 * d) * L + l)
            at[c] = -1 if u < q and fixed[u] else position[u]
        for r in range(3 * d):
            i = at[r]
            if i < 0 or i >= n_c:
                continue
            if r >= 2 * d and frozen[l]:  # identity rows
                A[i, i] += 1.0
                continue
            for c in range(3 * d):
                j = at[c]
                if j < 0:
                    continue
                if j < n_c:
                    A[i, j] += block[r, c]
                else:
                    C[i, j - n_c] += block[r, c]
    for i in range(q):
        if fixed[i] and position[i] < n_c:
            A[position[i], position[i]] += 1.0


@njit(cache=True, error_model="numpy")
def _jacobian(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, mu, k_N, k_T, h, code, branch, e, J, scratch):
    """The whole generalised Jacobian J (N, N), every row stored (_jacobian_into): the
    matrix the stored factors stand for, as the tests check it."""
    N = q + L * d
    J[:, :] = 0.0
    _jacobian_into(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, mu, k_N, k_T, h, code, branch, e,
                   np.arange(N), N, J, J[:, :0], scratch, np.empty(3 * d, dtype=np.int64), REGULARISATION)
    return N


@njit(cache=True, error_model="numpy")
def _gauss_seidel(q, L, d, slot_A, slot_B, frame, w, m, fixed, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, rhs,
                  x, r, gbar, code, floor_c, sweeps):
    """Projected Gauss-Seidel over the star's links (the nonsmooth Gauss-Seidel of LMGC90):
    with the springs' affine model of the current iterate held (traction t0 + D h B x / 4,
    read as in _evaluate: gbar and code from it), x is linear in r, x = x0 + X r, so the
    end-of-step jumps are c + G r; each link in turn projects r_l - rho_l (its gap, its
    slip) onto the shifted Signorini-Coulomb set, rho_l = 1 / max diag G_ll. Overwrites
    x (q,) and r (L, d)."""
    n = L * d
    A = np.zeros((q, q))
    P = np.zeros((q, n))  # B^T W
    spring = np.zeros(n)
    for i in range(q):
        A[i, i] = m[i]
    for l in range(L):
        a, b = slot_A[l], slot_B[l]
        R = frame[l]
        dN = spring_normal_tangent(code[l], k_N[l])
        spring[l * d] = dN * g_n[l, 0] + (k_N[l] * max(gbar[l, 0], 0.0) if code[l] & CONTACT else 0.0)
        for i in range(1, d):
            spring[l * d + i] = k_T[l] * g_n[l, i]
        for i in range(d):
            for j in range(d):
                s = dN * R[0, i] * R[0, j]
                for k in range(1, d):
                    s += k_T[l] * R[k, i] * R[k, j]
                s *= 0.25 * h * h * w[l]
                A[b * d + i, b * d + j] += s
                A[a * d + i, a * d + j] += s
                A[b * d + i, a * d + j] -= s
                A[a * d + i, b * d + j] -= s
            for j in range(d):
                P[b * d + j, l * d + i] = w[l] * R[i, j]
                P[a * d + j, l * d + i] = -w[l] * R[i, j]
    b0 = np.empty(q)
    for i in range(q):
        s = rhs[i]
        for k in range(n):
            s -= h * P[i, k] * spring[k]
        for j in range(q):
            if fixed[j]:
                s -= A[i, j] * x[j]
        b0[i] = s
    for i in range(q):
        if fixed[i]:
            A[i, :] = 0.0
            A[:, i] = 0.0
            A[i, i] = 1.0
            P[i, :] = 0.0
    piv = np.empty(q, dtype=np.int64)
    lu_factor(A, piv)
    x0 = np.empty(q)
    for i in range(q):
        x0[i] = x[i] if fixed[i] else b0[i]
    lu_solve(A, piv, x0)
    X = np.empty((q, n))
    column = np.empty(q)
    for k in range(n):
        for i in range(q):
            column[i] = h * P[i, k]
        lu_solve(A, piv, column)
        X[:, k] = column
    # B as (n, q): link-frame jumps of the components
    c = np.empty(n)
    G = np.zeros((n, n))
    for l in range(L):
        a, b = slot_A[l], slot_B[l]
        for i in range(d):
            s = 0.0
            for j in range(d):
                s += frame[l, i, j] * (x0[b * d + j] - x0[a * d + j])
            c[l * d + i] = g_n[l, i] + dg[l, i] + h * s
            for k in range(n):
                s = 0.0
                for j in range(d):
                    s += frame[l, i, j] * (X[b * d + j, k] - X[a * d + j, k])
                G[l * d + i, k] = h * s
    rho = np.empty(L)
    for l in range(L):
        big = G[l * d, l * d]
        for i in range(1, d):
            big = max(big, G[l * d + i, l * d + i])
        rho[l] = 1.0 / big if big > 0 else 0.0
    y = np.empty(d)
    z = np.empty(d)
    for _ in range(sweeps):
        change, largest = 0.0, 0.0
        for l in range(L):
            if rho[l] <= 0:
                continue
            for i in range(d):
                s = c[l * d + i]
                for k in range(L):
                    for j in range(d):
                        s += G[l * d + i, k * d + j] * r[k, j]
                y[i] = s
            r_N = max(-shift[l], r[l, 0] - rho[l] * y[0])
            norm = 0.0
            for i in range(1, d):
                z[i] = r[l, i] - rho[l] * (y[i] - g_n[l, i])
                norm += z[i] * z[i]
            norm = np.sqrt(norm)
            radius = mu[l] * max(r_N + shift[l], 0.0) + cohesion_T[l]
            cut = min(1.0, radius / norm) if norm > 0 else 1.0
            change = max(change, abs(r_N - r[l, 0]))
            r[l, 0] = r_N
            for i in range(1, d):
                change = max(change, abs(cut * z[i] - r[l, i]))
                r[l, i] = cut * z[i]
        for l in range(L):
            for i in range(d):
                largest = max(largest, abs(r[l, i]))
        if change <= 1e-14 * (largest + floor_c):
            break
    for i in range(q):
        s = x0[i]
        for l in range(L):
            for j in range(d):
                s += X[i, l * d + j] * r[l, j]
        x[i] = s


@njit(cache=True, error_model="numpy")
def unknown_order(q, L, d, slot_A, slot_B, out):
    """A fill-reducing elimination order of one star's unknowns into out (q + L d,):
    minimum degree on the graph of its copies and links (a link joins its two copies, and
    its reactions each of them), each node's d unknowns together, ties to the lowest node.
    The copies of a 3D star form a ring of tetrahedra around the vertex, so in the order
    of the unknowns (copies, then reactions) their LU fills in; measured on the damaged 3D
    bar (9,555 tetrahedra, 2,227 stars, 59 coupled unknowns on average): 45 % of the LU
    factors nonzero in that order, 27 % in this one, and the LU 33.5 -> 18.5 us a star.
    2D stars keep the order of their unknowns: their LU (~16 coupled unknowns) is as fast in
    either order (0.54 against 0.55 us), and where a Jacobian is singular (random stars with
    two links between the same copies) minimum degree met exact zero pivots more often
    (NaN iterates in 159 of 1,500 random stars solved from zero, against 4)."""
    if d == 2:
        for i in range(q + L * d):
            out[i] = i
        return
    n_copies = q // d
    n = n_copies + L
    G = np.zeros((n, n), dtype=np.bool_)
    for l in range(L):
        a, b, c = slot_A[l], slot_B[l], n_copies + l
        G[a, b] = G[b, a] = G[a, c] = G[c, a] = G[b, c] = G[c, b] = True
    degree = np.zeros(n, dtype=np.int64)
    for i in range(n):
        G[i, i] = False
        for j in range(n):
            degree[i] += G[i, j]
    alive = np.ones(n, dtype=np.bool_)
    neighbours = np.empty(n, dtype=np.int64)
    k = 0
    for _ in range(n):
        v, least = -1, n + 1
        for i in range(n):
            if alive[i] and degree[i] < least:
                v, least = i, degree[i]
        alive[v] = False
        m = 0
        for i in range(n):
            if alive[i] and G[v, i]:
                neighbours[m] = i
                m += 1
                degree[i] -= 1
        for i in range(m):  # eliminating v joins its neighbours
            for j in range(i + 1, m):
                a, b = neighbours[i], neighbours[j]
                if not G[a, b]:
                    G[a, b] = G[b, a] = True
                    degree[a] += 1
                    degree[b] += 1
        for i in range(d):
            out[k + i] = v * d + i if v < n_copies else q + i * L + (v - n_copies)
        k += d


@njit(cache=True, error_model="numpy")
def unknown_orders(comp_off, link_off, slot_A, slot_B, d):
    """unknown_order of every star, flat: star s at comp_off[s] + d link_off[s]."""
    n_stars = len(comp_off) - 1
    out = np.empty(comp_off[n_stars] + d * link_off[n_stars], dtype=np.int64)
    for s in range(n_stars):
        p0, l0 = comp_off[s], link_off[s]
        q, L = comp_off[s + 1] - p0, link_off[s + 1] - l0
        at = p0 + d * l0
        unknown_order(q, L, d, slot_A[l0:l0 + L], slot_B[l0:l0 + L], out[at:at + q + L * d])
    return out


@njit(cache=True, error_model="numpy")
def factor_jacobian(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, mu, k_N, k_T, h, code, branch, e,
                    elimination, store, index, position, scratch, regularisation=REGULARISATION):
    """Factorise a star's Jacobian (_jacobian_into, arguments as there) with its unit rows set
    apart: an unknown whose row is that of the identity (an open link's normal row, a
    tangential row neither sticking nor slipping, a frozen link, a prescribed component) is
    its own residual's, and leaves the others a system on the coupled unknowns only (an
    intact RCCM star in tension: its q momentum rows alone; a 2D star: LU of ~18 rows
    instead of 24 costs half). The coupled unknowns are eliminated in the star's
    ``elimination`` order (N,: unknown_order). Only their rows are formed, straight into
    store (>= N^2): the LU factors of the coupled block (n_c, n_c), then its columns of the
    unit unknowns (n_c, N - n_c); index (>= 2 N + 1): n_c, the coupled unknowns then the unit
    ones, the pivots. position (>= N + 3 d, int) workspace. (Formed whole and then copied, a 3D
    star's Jacobian cost more than its LU: measured on the damaged 3D bar, 5 + 13 ms of a
    101 ms kernel call, the LU 17 ms.)"""
    N = q + L * d
    order = index[1:1 + N]
    n_c, n_t = 0, N
    for u in elimination:
        if u < q:
            unit = fixed[u]
        else:
            l = (u - q) % L
            moves = branch[l, B_SLIP] > 0 if u >= q + L else branch[l, B_CONTACT] > 0  # tangential, normal
            unit = frozen[l] or not (moves or branch[l, B_STICK] > 0)
        if unit:
            n_t -= 1
            order[n_t] = u
        else:
            order[n_c] = u
            n_c += 1
    index[0] = n_c
    for i in range(N):
        position[order[i]] = i
    store[:n_c * N] = 0.0
    A = store[:n_c * n_c].reshape((n_c, n_c))
    C = store[n_c * n_c:n_c * N].reshape((n_c, N - n_c))
    _jacobian_into(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, mu, k_N, k_T, h, code, branch, e,
                   position[:N], n_c, A, C, scratch, position[N:], regularisation)
    lu_factor(A, index[1 + N:1 + N + n_c])


@njit(cache=True, error_model="numpy")
def solve_star(store, index, R, work, nonzero):
    """Solve J y = R in place (R (N,)) from factor_jacobian's store and index; work (>= N,),
    nonzero (>= N, int) workspaces."""
    N = len(R)
    n_c = index[0]
    order = index[1:1 + N]
    A = store[:n_c * n_c].reshape((n_c, n_c))
    C = store[n_c * n_c:n_c * N].reshape((n_c, N - n_c))
    # the unit unknowns' residuals are mostly zero (an open link's normal row without
    # shift, a frictionless tangential row): their columns are skipped, in the same order
    n_nz = 0
    for k in range(N - n_c):
        if R[order[n_c + k]] != 0.0:
            nonzero[n_nz] = k
            n_nz += 1
    for a in range(n_c):
        s = R[order[a]]
        for j in range(n_nz):
            k = nonzero[j]
            s -= C[a, k] * R[order[n_c + k]]
        work[a] = s
    lu_solve(A, index[1 + N:1 + N + n_c], work[:n_c])
    for a in range(n_c):
        R[order[a]] = work[a]


@njit(cache=True, error_model="numpy")
def piece_branches(L, d, code, slip_dir, branch, e):
    """The branches (branch (>= L, 5), e (>= L, d - 1)) of the piece ``code`` (L,) of one star
    with its slip directions slip_dir (L, d: the direction, then the scale of the tangential
    projection P = scale (I - e e^T)) held. keep_pieces holds directions with scale 0 (the
    projection left out, solver/active_set.py); Newton's kept factors (_keep_newton_factors) the
    direction and scale they were formed at. In 2D P = scale (1 - e^2) vanishes anyway."""
    for l in range(L):
        c = code[l]
        branch[l, B_CONTACT] = 1.0 if c & CONTACT else 0.0
        branch[l, B_STICK] = 1.0 if c & STICK else 0.0
        branch[l, B_SLIP] = 1.0 if c & SLIP else 0.0
        branch[l, B_PRESSED] = 1.0 if c & PRESSED else 0.0
        branch[l, B_SCALE] = 0.0
        e[l, :] = 0.0
        if c & SLIP:  # in 2D the direction is the piece's; in 3D the held one
            if d == 2:
                e[l, 0] = -1.0 if c & NEGATIVE else 1.0
            else:
                e[l, :d - 1] = slip_dir[l, :d - 1]
                branch[l, B_SCALE] = slip_dir[l, d - 1]


@njit(cache=True, error_model="numpy")
def factor_piece(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, elimination, mu, k_N, k_T, h, code, slip_dir,
                 store, index, position, branch, e, scratch):
    """factor_jacobian of the piece ``code`` (L,) of one star with its slip directions
    slip_dir (L, d) held (piece_branches): what keep_pieces stores for the next step's
    prediction. Arguments as factor_jacobian; branch (>= L, 5), e (>= L, d - 1) workspaces."""
    piece_branches(L, d, code, slip_dir, branch, e)
    factor_jacobian(q, L, d, slot_A, slot_B, frame, w, rho, frozen, m, fixed, mu, k_N, k_T, h, code, branch, e,
                    elimination, store, index, position, scratch)


@njit(cache=True, error_model="numpy")
def _kind(L, d, frozen, code):
    """What the factors of a star's piece are good for: APPROXIMATE with a 3D slipping link
    (smooth, not affine), else EXACT. A frozen link does not count: its rows are the
    identity on every piece (its reaction a fixed point, see FROZEN), and its copies'
    momentum rows are prescribed, so the factors are Newton's own matrix on the piece;
    its predicted reaction is exact where its jump vanishes (a clamped support), and the
    fixed point reuses the factors elsewhere. Measured on bunker-h2 (0.2 m, 8 ms): the
    133 stars of the clamped base, started from zero, took 3.1 Newton iterations each."""
    kind = EXACT
    for l in range(L):
        if d == 3 and (code[l] & SLIP) and not frozen[l]:
            kind = APPROXIMATE
    return kind


@njit(cache=True, error_model="numpy")
def _note_factored(L, k_N, k_T, mu, factored):
    """factored (L, 3) = the (k_N, k_T, mu) of a star's links its factors are formed with
    (what star_replay needs to form stale factors again)."""
    for l in range(L):
        factored[l, 0], factored[l, 1], factored[l, 2] = k_N[l], k_T[l], mu[l]


@njit(cache=True, error_model="numpy")
def _flips(L, frozen, scode, code, flipped):
    """How many links read another piece than scode, their indices into flipped; -1 if more
    than len(flipped), or if any is frozen or differs otherwise than in CONTACT and SPRING."""
    n = 0
    for l in range(L):
        if code[l] != scode[l]:
            if frozen[l] or ((code[l] ^ scode[l]) & ~(CONTACT | SPRING)) != 0 or n == len(flipped):
                return -1
            flipped[n] = l
            n += 1
    return n


@njit(cache=True, error_model="numpy")
def _flip_rows(q, L, d, slot_A, slot_B, frame, w, rho, fixed, k_N, h, l, old, new, U, V):
    """The rows of U and V (each (2, N)) with J_new - J_old = U^T V for link l going from
    piece old to piece new (their CONTACT and SPRING bits differ only): its normal row (the
    contact row h rho n^T (x_B - x_A) against the open row r_N) and its spring's
    h^2/4 w k_N n n^T in the momentum block (as _jacobian forms them). Returns the rank (1, 2)."""
    a, b = slot_A[l], slot_B[l]
    c_old, c_new = (old & CONTACT) != 0, (new & CONTACT) != 0
    U[0, :] = 0.0
    V[0, :] = 0.0
    U[0, q + l] = 1.0
    sign = (1.0 if c_new else 0.0) - (1.0 if c_old else 0.0)  # the contact row comes (+) or goes (-)
    for j in range(d):
        x = sign * h * rho[l] * frame[l, 0, j]
        V[0, b * d + j] = 0.0 if fixed[b * d + j] else x
        V[0, a * d + j] = 0.0 if fixed[a * d + j] else -x
    V[0, q + l] = (0.0 if c_new else 1.0) - (0.0 if c_old else 1.0)
    dN_old, dN_new = spring_normal_tangent(old, k_N[l]), spring_normal_tangent(new, k_N[l])
    if dN_new == dN_old:
        return 1
    c = 0.25 * h * h * w[l] * (dN_new - dN_old)
    U[1, :] = 0.0
    V[1, :] = 0.0
    for j in range(d):
        n_j = frame[l, 0, j]
        V[1, b * d + j] = 0.0 if fixed[b * d + j] else n_j
        V[1, a * d + j] = 0.0 if fixed[a * d + j] else -n_j
        U[1, b * d + j] = c * V[1, b * d + j]
        U[1, a * d + j] = c * V[1, a * d + j]
    return 2


@njit(cache=True, error_model="numpy")
def _woodbury_factor(store, index, U, V, Z, cap, cap_piv, work, nonzero):
    """Z = J^-1 U^T (rows, from the stored factors) and the LU of the capacitance
    I + V Z^T, for _woodbury_solve; U, V, Z (n_u, N), cap (>= n_u^2)."""
    n_u = U.shape[0]
    for i in range(n_u):
        Z[i] = U[i]
        solve_star(store, index, Z[i], work, nonzero)
    C = cap[:n_u * n_u].reshape((n_u, n_u))
    for i in range(n_u):
        for j in range(n_u):
            s = 1.0 if i == j else 0.0
            for m in range(len(Z[j])):
                s += V[i, m] * Z[j, m]
            C[i, j] = s
    lu_factor(C, cap_piv[:n_u])


@njit(cache=True, error_model="numpy")
def _woodbury_solve(store, index, V, Z, cap, cap_piv, R, t, work, nonzero):
    """Solve (J + U^T V) y = R in place, J from the stored factors, Z and the capacitance
    from _woodbury_factor; t (>= n_u,) workspace."""
    n_u = V.shape[0]
    solve_star(store, index, R, work, nonzero)
    for i in range(n_u):
        s = 0.0
        for m in range(len(R)):
            s += V[i, m] * R[m]
        t[i] = s
    lu_solve(cap[:n_u * n_u].reshape((n_u, n_u)), cap_piv[:n_u], t[:n_u])
    for i in range(n_u):
        for m in range(len(R)):
            R[m] -= t[i] * Z[i, m]


# ---------------------------------------------------------------- the loop over stars

@njit(cache=True, error_model="numpy")
def gather_stars(comps, comp_off, link_off, slot_A, slot_B, frame, u, v, f, prescribed, h, g_out, dg_out, rhs_out,
                 x_out):
    """What solve_stars reads of the flat fields (over local components): per star link,
    g_out (L_total, d) = frame (u_B - u_A) (m) and dg_out = h frame (v_B - v_A) (m), the
    jumps of u and h v in its link frame (normal first); per star component (comps),
    rhs_out = h f (N s) and x_out = prescribed (m/s: the prescribed increments). comps,
    comp_off, link_off, slot_A, slot_B as solve_stars; h (s)."""
    d = frame.shape[1]
    for i in range(len(comps)):
        rhs_out[i] = h * f[comps[i]]
        x_out[i] = prescribed[comps[i]]
    du, dv = np.empty(d), np.empty(d)
    for s in range(len(comp_off) - 1):
        p0 = comp_off[s]
        for l in range(link_off[s], link_off[s + 1]):
            a, b = p0 + slot_A[l] * d, p0 + slot_B[l] * d
            for j in range(d):  # gathered once, not once per frame row
                A, B = comps[a + j], comps[b + j]
                du[j], dv[j] = u[B] - u[A], v[B] - v[A]
            for i in range(d):
                g, dg = 0.0, 0.0
                for j in range(d):
                    g += frame[l, i, j] * du[j]
                    dg += frame[l, i, j] * dv[j]
                g_out[l, i] = g
                dg_out[l, i] = h * dg


@njit(cache=True, error_model="numpy", nogil=True)
def solve_stars(comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                rhs, x_in, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, rtol, max_iterations, predict,
                floor_m, floor_c, fac_off, piv_off, factors, pivots, codes, slip_dir, cached, factored,
                x_out, r_out, reaction, gbar_out, slip_out, status, residual, counters, entry_codes, entry_cached,
                regularisation=REGULARISATION, todo=None, abort=None):
    """Solve every star of the rank for this step (with ``todo``, a per-star bool array, only
    those where it is True: the others' outputs are left as they are).

    Per star component (flat over the stars, comp_off): mass (kg), fixed, rhs = h f (N s),
    x_in (m/s: the prescribed increments); per star link (link_off): slot_A, slot_B,
    frame (d, d), weight (m or m^2), rho (Pa/m: the step's stiffness), frozen, g_n, dg
    (link frame, m: the jump of u_n and h B v_-), mu, shift, cohesion_T (Pa), k_N, k_T
    (Pa/m); per star unknown, the stars' elimination orders (unknown_orders). The cache
    (fac_off, piv_off, factors, pivots, codes, slip_dir, cached, factored) holds each star's
    last Jacobian, piece and slip directions, what they are good for (NONE, APPROXIMATE,
    EXACT, STALE), and per link the (k_N, k_T, mu) they were formed with; Newton's Jacobians
    replace them (not APPROXIMATE ones: Newton then works in workspaces), and ``cached``
    stays EXACT or STALE only where the star converged on the piece of its stored factors,
    APPROXIMATE where their prediction solved it, EXACT where an exact prediction solved it
    or where they are a large star's reference piece (FLIPS), becomes STALE where Newton's
    last Jacobian was of a 3D slip (_keep_newton_factors; slip_dir then holds the directions
    and scales it was formed at), else NONE.

    Writes x_out, reaction (N) per component; r_out (Pa), gbar_out, slip_out (the springs'
    jump and the step's jump increment g_{n+1} - g_n = h B (v_- + x), m) per link; per star
    status (CONVERGED, STALLED, UNCONVERGED) and its final scaled residual; counters: the
    most iterations, the unconverged and stalled stars, the stars solved at iteration 1. For
    an unconverged star only, what star_replay needs to start it as this call did: the pieces
    of its stored factors (entry_codes, per link) and what they were if it started from their
    prediction (entry_cached; NONE if it started from zero), and in ``factored`` the data
    they were formed with. ``regularisation``: on sticking links' reaction diagonals
    (REGULARISATION; a step's second pass takes more, solver/semismooth.py). ``abort``: a
    one-element int8 array another thread may set (a stop request, solver/interrupt.py):
    the call then returns within one Newton iteration, its outputs unfinished. It releases
    the GIL, so that such a thread can run.
    """
    if todo is None:
        todo = np.ones(len(comp_off) - 1, dtype=np.bool_)
    if abort is None:
        abort = np.zeros(1, dtype=np.int8)
    if frame.shape[1] == 2:  # the dimension a compile-time constant: see _solve_stars
        _solve_stars(2, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                     rhs, x_in, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, rtol, max_iterations, predict,
                     floor_m, floor_c, fac_off, piv_off, factors, pivots, codes, slip_dir, cached, factored,
                     x_out, r_out, reaction, gbar_out, slip_out, status, residual, counters, entry_codes, entry_cached,
                     regularisation, todo, abort)
    else:
        _solve_stars(3, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                     rhs, x_in, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, rtol, max_iterations, predict,
                     floor_m, floor_c, fac_off, piv_off, factors, pivots, codes, slip_dir, cached, factored,
                     x_out, r_out, reaction, gbar_out, slip_out, status, residual, counters, entry_codes, entry_cached,
                     regularisation, todo, abort)


@njit(cache=True, error_model="numpy")
def _keep_newton_factors(L, N, d, l0, held, held_store, held_index, held_code, formed_at, store, index, codes,
                         slip_dir):
    """A 3D star that converged after Newton's last Jacobian was formed at a slip keeps that
    Jacobian as its STALE factors: the next step predicts with them, and Newton uses them as
    a chord while they contract (CHORD), instead of starting from held-direction factors
    (APPROXIMATE) that keep_pieces forms again and that contract poorly. They are copied
    from the workspaces where its start was held, else already in place; its slipping
    links' slip_dir get the direction and scale they were formed at, from which
    factor_piece forms them again. Measured on slab-3d-bending resumed at 0.1 s on 2 ranks,
    150 steps, before, after, after, before: solve_stars 16.5-17.5 -> 15.1-16.7 ms,
    keep_pieces 6.8-7.2 -> 0.9 ms a step; the same broken links and fragments."""
    if held:
        n_c = held_index[0]
        for i in range(n_c * N):
            store[i] = held_store[i]
        for i in range(1 + N + n_c):
            index[i] = held_index[i]
        for l in range(L):
            codes[l0 + l] = held_code[l]
    for l in range(L):
        if codes[l0 + l] & SLIP:
            for i in range(d):
                slip_dir[l0 + l, i] = formed_at[l, i]


@njit(cache=True, error_model="numpy")
def _solve_stars(d, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                 rhs, x_in, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, rtol, max_iterations, predict,
                 floor_m, floor_c, fac_off, piv_off, factors, pivots, codes, slip_dir, cached, factored,
                 x_out, r_out, reaction, gbar_out, slip_out, status, residual, counters, entry_codes, entry_cached,
                 regularisation, todo, abort):
    """solve_stars in d dimensions, d a compile-time constant: the loops over the
    components of a link are then unrolled (measured on captured steps of the damaged bars:
    a 2D call 21.5 -> 18.4 ms, 3D 91.4 -> 87.5 ms)."""
    n_stars = len(comp_off) - 1
    q_max, L_max = 0, 0
    for s in range(n_stars):
        q_max = max(q_max, comp_off[s + 1] - comp_off[s])
        L_max = max(L_max, link_off[s + 1] - link_off[s])
    N_max = q_max + L_max * d
    # workspaces, once per call
    x, force, react = np.empty(q_max), np.empty(q_max), np.empty(q_max)
    r = np.empty((L_max, d))
    Bx, gbar, slip = np.empty((L_max, d)), np.empty((L_max, d)), np.empty((L_max, d))
    branch, e = np.empty((L_max, 5)), np.zeros((L_max, max(d - 1, 1)))
    code, code_in = np.empty(L_max, dtype=np.int8), np.empty(L_max, dtype=np.int8)
    factored_in = np.empty((L_max, 3))
    R, delta, direction = np.empty(N_max), np.empty(N_max), np.empty(N_max)
    best_x, best_r = np.empty(q_max), np.empty((L_max, d))
    base_x, base_r = np.empty(q_max), np.empty((L_max, d))
    scratch = np.empty(12 * d * d)
    work, position = np.empty(N_max), np.empty(N_max + 3 * d, dtype=np.int64)
    nonzero = np.empty(N_max, dtype=np.int64)
    U_w, V_w, Z_w = np.empty((2 * FLIPS, N_max)), np.empty((2 * FLIPS, N_max)), np.empty((2 * FLIPS, N_max))
    cap, cap_piv, t_w = np.empty(4 * FLIPS * FLIPS), np.empty(2 * FLIPS, np.int64), np.empty(2 * FLIPS)
    flipped, built = np.empty(FLIPS, np.int64), np.empty((FLIPS, 2), np.int64)  # built: (link, its piece)
    held_store, held_index = np.empty(N_max * N_max), np.empty(2 * N_max + 1, np.int64)  # see APPROXIMATE
    held_code = np.empty(L_max, np.int8)
    formed_at = np.empty((L_max, d))  # per link, the slip direction and scale of Newton's last factors
    for s in range(n_stars):
        if abort[0]:
            return
        if not todo[s]:
            continue
        p0, p1, l0, l1 = comp_off[s], comp_off[s + 1], link_off[s], link_off[s + 1]
        q, L = p1 - p0, l1 - l0
        N = q + L * d
        sA, sB, fr, w, rh, fz = slot_A[l0:l1], slot_B[l0:l1], frame[l0:l1], weight[l0:l1], rho[l0:l1], frozen[l0:l1]
        m, fx, b_, xi = mass[p0:p1], fixed[p0:p1], rhs[p0:p1], x_in[p0:p1]
        gn, dgs, mus, shs, chs, kNs, kTs = g_n[l0:l1], dg[l0:l1], mu[l0:l1], shift[l0:l1], cohesion_T[l0:l1], \
            k_N[l0:l1], k_T[l0:l1]
        store, index = factors[fac_off[s]:fac_off[s] + N * N], pivots[piv_off[s]:piv_off[s] + 2 * N + 1]
        order = elimination[p0 + d * l0:p0 + d * l0 + N]
        scode = codes[l0:l1]
        xs, rs = x[:q], r[:L]
        if L == 0:  # lone copies (a corner of a single cell): no interface, explicit
            for i in range(q):
                x_out[p0 + i] = xi[i] if fx[i] else b_[i] / m[i]
                reaction[p0 + i] = (m[i] * xi[i] - b_[i]) / h if fx[i] else 0.0
            status[s], residual[s] = CONVERGED, 0.0
            continue
        imposed = False
        for i in range(q):
            xs[i] = xi[i] if fx[i] else 0.0
            imposed = imposed or (fx[i] and xi[i] != 0.0)
        # reactions start from zero (or from this step's prediction), never from the last
        # step: around a rigid star they are determined only up to self-equilibrated rings
        # (see REGULARISATION), which a warm start carried from step to step until they
        # choked the friction cones (measured: threshold and linear-softening runs then
        # failed to converge; cold, they complete)
        for l in range(L):  # with the piece and data the star starts from, element by element
            for i in range(d):  # (slice assignments cost more per star: measured)
                rs[l, i] = 0.0
            code_in[l] = scode[l]
            for i in range(3):
                factored_in[l, i] = factored[l0 + l, i]
        predicted = cached[s] != NONE and predict and not imposed  # imposed motion: not cached
        start = cached[s] if predicted else NONE
        if predicted:
            affine_constant(q, L, d, sA, sB, fr, w, rh, m, fx, b_, gn, dgs, mus, shs, chs, kNs, kTs, h, scode,
                            slip_dir[l0:l1], delta)
            solve_star(store, index, delta[:N], work, nonzero)
            for i in range(q):
                xs[i] = -delta[i]
            for l in range(L):
                for i in range(d):
                    rs[l, i] = -delta[q + i * L + l]
        # Newton's matrix: its factors, its piece and what it is (the stored ones, except
        # for held-direction factors, which Newton leaves in place: see APPROXIMATE)
        held = cached[s] == APPROXIMATE
        kind = cached[s]
        if held:
            store, index = held_store[:N * N], held_index[:2 * N + 1]
            scode = held_code[:L]
            scode[:] = code_in[:L]
            kind = NONE
        n_built, n_u = -1, 0  # how many flipped links the Woodbury correction was built for (-1: none)
        smooth = False  # store holds an exact Jacobian formed in this call at a 3D slip (_keep_newton_factors)
        has_best = False
        best_scaled, base_scaled, halvings = np.inf, np.inf, 0
        chord_from = np.inf  # the residual the last chord step started from (none yet: inf)
        since = 0  # the iteration this start began after: the schedule (CYCLE, FALLBACK) counts from it
        for iteration in range(1, max_iterations + 2):
            if abort[0]:  # a star may take seconds (ESCALATION)
                return
            k = iteration - since
            scaled_m, scaled_c = _evaluate(q, L, d, sA, sB, fr, w, rh, fz, m, fx, b_, gn, dgs, mus, shs, chs, kNs, kTs,
                                           h, xs, rs, floor_m, floor_c, Bx, gbar, slip, branch, e, force, R,
                                           react, code, scratch)
            scaled = max(scaled_m, scaled_c)
            last = iteration > max_iterations  # the best iterate, evaluated once more
            if k < FALLBACK:
                done = scaled <= rtol
                stalled = False
            else:  # stalled: accepted (see STALL, GIVE_UP)
                done = scaled <= (GIVE_UP if last else STALL) or (scaled_c <= STALL and scaled_m <= GIVE_UP)
                stalled = done and scaled > STALL
            same = True
            for l in range(L):
                same = same and code[l] == scode[l]
            if iteration == 1 and done:
                counters[N_FIRST] += 1
            counters[ITERATIONS] = max(counters[ITERATIONS], iteration)
            if done or last:
                # a star's stored factors stay valid if they are the Jacobian of the piece
                # it converged on (then only damage can change them), or if they solved it
                # by its prediction: the iterate then sits on the kink between that piece
                # and the one it reads (an intact link at g_N = 0, open or closed), where both
                # solve the star to rtol (measured on the 3D bar: 114-207 stars a step, each
                # factorised again for the next step's prediction, 6 % of the step)
                kept = done and iteration == 1 and predicted and kind == EXACT
                # a reference piece (see FLIPS): exact for this step, whatever piece the star ended on
                kept = kept or (done and kind == EXACT and index[0] >= WOODBURY)
                if done and smooth:  # Newton's last Jacobian, the next step's chord (_keep_newton_factors)
                    _keep_newton_factors(L, N, d, l0, held, held_store, held_index, held_code, formed_at,
                                         factors[fac_off[s]:fac_off[s] + N * N],
                                         pivots[piv_off[s]:piv_off[s] + 2 * N + 1], codes, slip_dir)
                    if held:
                        _note_factored(L, kNs, kTs, mus, factored[l0:l1])
                    cached[s] = STALE
                elif held:  # the held-direction factors, where their prediction solved the star
                    cached[s] = APPROXIMATE if done and iteration == 1 else NONE
                elif not (kept or ((kind == EXACT or kind == STALE) and same and done)):
                    cached[s] = NONE
                else:
                    cached[s] = kind
                if done:
                    status[s] = CONVERGED if scaled <= rtol else STALLED
                    if stalled:
                        counters[N_STALLED] += 1
                else:  # above GIVE_UP even at its best: the run stops (ConvergenceError)
                    status[s] = UNCONVERGED
                    counters[N_UNCONVERGED] += 1
                    entry_codes[l0:l1] = code_in[:L]
                    factored[l0:l1] = factored_in[:L]
                    entry_cached[s] = start
                residual[s] = scaled
                for i in range(q):
                    x_out[p0 + i] = xs[i]
                    reaction[p0 + i] = react[i]
                for l in range(L):
                    for i in range(d):
                        r_out[l0 + l, i] = rs[l, i]
                        gbar_out[l0 + l, i] = gbar[l, i]
                        slip_out[l0 + l, i] = slip[l, i]
                break
            if predicted and iteration == RESTART:  # from zero, with the schedule of a start from zero
                for i in range(q):
                    xs[i] = xi[i] if fx[i] else 0.0
                rs[:, :] = 0.0
                since = RESTART
                continue
            if k >= FALLBACK:
                if not has_best:
                    best_x[:q], best_r[:L], has_best = xs, rs, True
                if scaled < best_scaled:
                    best_x[:q], best_r[:L], best_scaled = xs, rs, scaled
            if iteration == max_iterations and has_best:
                xs[:], rs[:, :] = best_x[:q], best_r[:L]
                continue
            if k >= FALLBACK and (k - FALLBACK) % 2 == 0:  # Newton wanders: Gauss-Seidel, then polish
                _gauss_seidel(q, L, d, sA, sB, fr, w, m, fx, gn, dgs, mus, shs, chs, kNs, kTs, h, b_, xs, rs, gbar,
                              code, floor_c, min(SWEEPS * 2 ** ((k - FALLBACK) // 2), MAX_SWEEPS))
                continue
            newton = True
            if CYCLE < k < FALLBACK:  # a shorter step along the last direction
                if k == CYCLE + 1:
                    base_x[:q], base_r[:L], base_scaled, halvings = xs, rs, np.inf, 0
                    direction[:N] = 0.0
                if scaled >= base_scaled and halvings < SHORTEST:
                    newton = False
                    halvings += 1
                    alpha = 0.5 ** halvings
                    for i in range(q):
                        xs[i] = base_x[i] + alpha * direction[i]
                    for l in range(L):
                        for i in range(d):
                            rs[l, i] = base_r[l, i] + alpha * direction[q + i * L + l]
                else:
                    base_x[:q], base_r[:L], base_scaled, halvings = xs, rs, scaled, 0
            if not newton:
                continue
            # on the piece of its stored factors (an affine piece, whose Jacobian the piece
            # and the step's data determine) a star reuses them - a prediction only short
            # of REGULARISATION is finished by them; stale ones while they contract (CHORD);
            # elsewhere a fresh Jacobian replaces them
            chord = kind == STALE and k < CYCLE and scaled <= CHORD * chord_from
            n_f = -1
            if kind == EXACT and not same and index[0] >= WOODBURY:
                n_f = _flips(L, fz, scode, code, flipped)
            if same and chord:
                chord_from = scaled
            elif n_f > 0:  # the stored factors and a Woodbury correction for the flipped links
                fresh = n_f != n_built
                for i in range(n_f):
                    fresh = fresh or flipped[i] != built[i, 0] or code[flipped[i]] != built[i, 1]
                if fresh:
                    n_u = 0
                    for i in range(n_f):
                        l = flipped[i]
                        n_u += _flip_rows(q, L, d, sA, sB, fr, w, rh, fx, kNs, h, l, scode[l], code[l],
                                          U_w[n_u:n_u + 2, :N], V_w[n_u:n_u + 2, :N])
                        built[i, 0], built[i, 1] = l, code[l]
                    n_built = n_f
                    _woodbury_factor(store, index, U_w[:n_u, :N], V_w[:n_u, :N], Z_w[:n_u, :N], cap, cap_piv,
                                     work, nonzero)
            elif not (kind == EXACT and same):
                factor_jacobian(q, L, d, sA, sB, fr, w, rh, fz, m, fx, mus, kNs, kTs, h, code, branch, e, order, store,
                                index, position, scratch, regularisation)
                scode[:] = code[:L]
                if not held:
                    _note_factored(L, kNs, kTs, mus, factored[l0:l1])
                kind = EXACT if _kind(L, d, fz, code) == EXACT else NONE  # the exact Jacobian at the iterate
                smooth = kind == NONE
                if smooth:
                    for l in range(L):
                        for i in range(d - 1):
                            formed_at[l, i] = e[l, i]
                        formed_at[l, d - 1] = branch[l, B_SCALE]
                n_built = -1
            delta[:N] = R[:N]
            if n_f > 0:
                _woodbury_solve(store, index, V_w[:n_u, :N], Z_w[:n_u, :N], cap, cap_piv, delta[:N], t_w, work,
                                nonzero)
            else:
                solve_star(store, index, delta[:N], work, nonzero)
            if CYCLE < k < FALLBACK:
                direction[:N] = -delta[:N]
            for i in range(q):
                xs[i] -= delta[i]
            for l in range(L):
                for i in range(d):
                    rs[l, i] -= delta[q + i * L + l]


@njit(cache=True, error_model="numpy")
def keep_pieces(stars, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                rhs, x, r, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, fac_off, piv_off, factors, pivots, codes,
                slip_dir, cached, factored):
    """Store, for the next step's prediction, the LU factors of the Jacobian of the piece
    each of ``stars`` converged on (x per component, r per link), its slip directions held
    (factor_piece), with the friction, cohesion and springs (mu .. k_T per link) after the
    step; ``cached`` says what they are (_kind). Arguments as solve_stars."""
    if frame.shape[1] == 2:  # the dimension a compile-time constant, as in solve_stars
        _keep_pieces(2, stars, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                     rhs, x, r, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, fac_off, piv_off, factors, pivots, codes,
                     slip_dir, cached, factored)
    else:
        _keep_pieces(3, stars, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                     rhs, x, r, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, fac_off, piv_off, factors, pivots, codes,
                     slip_dir, cached, factored)


@njit(cache=True, error_model="numpy")
def _keep_pieces(d, stars, comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, elimination,
                 rhs, x, r, g_n, dg, mu, shift, cohesion_T, k_N, k_T, h, fac_off, piv_off, factors, pivots, codes,
                 slip_dir, cached, factored):
    """keep_pieces in d dimensions, d a compile-time constant (see _solve_stars)."""
    q_max, L_max = 0, 0
    for s in stars:
        q_max = max(q_max, comp_off[s + 1] - comp_off[s])
        L_max = max(L_max, link_off[s + 1] - link_off[s])
    N_max = q_max + L_max * d
    force, react = np.empty(q_max), np.empty(q_max)
    Bx, gbar, slip = np.empty((L_max, d)), np.empty((L_max, d)), np.empty((L_max, d))
    branch, e = np.empty((L_max, 5)), np.zeros((L_max, max(d - 1, 1)))
    code = np.empty(L_max, dtype=np.int8)
    R = np.empty(N_max)
    scratch = np.empty(12 * d * d)
    position = np.empty(N_max + 3 * d, dtype=np.int64)
    for s in stars:
        p0, p1, l0, l1 = comp_off[s], comp_off[s + 1], link_off[s], link_off[s + 1]
        q, L = p1 - p0, l1 - l0
        N = q + L * d
        sA, sB, fr, w, rh, fz = slot_A[l0:l1], slot_B[l0:l1], frame[l0:l1], weight[l0:l1], rho[l0:l1], frozen[l0:l1]
        if L == 0:  # no interface, no factors
            cached[s] = NONE
            continue
        m, fx = mass[p0:p1], fixed[p0:p1]
        mus, kNs, kTs = mu[l0:l1], k_N[l0:l1], k_T[l0:l1]
        _evaluate(q, L, d, sA, sB, fr, w, rh, fz, m, fx, rhs[p0:p1], g_n[l0:l1], dg[l0:l1], mus, shift[l0:l1],
                  cohesion_T[l0:l1], kNs, kTs, h, x[p0:p1], r[l0:l1], 0.0, 0.0, Bx, gbar, slip, branch, e,
                  force, R, react, code, scratch)
        for l in range(L):
            if code[l] & SLIP:
                slip_dir[l0 + l, :d - 1] = e[l, :d - 1]
                slip_dir[l0 + l, d - 1] = 0.0
        factor_piece(q, L, d, sA, sB, fr, w, rh, fz, m, fx, elimination[p0 + d * l0:p0 + d * l0 + N], mus, kNs, kTs,
                     h, code[:L], slip_dir[l0:l1],
                     factors[fac_off[s]:fac_off[s] + N * N], pivots[piv_off[s]:piv_off[s] + 2 * N + 1],
                     position, branch, e, scratch)
        codes[l0:l1] = code[:L]
        _note_factored(L, kNs, kTs, mus, factored[l0:l1])
        cached[s] = _kind(L, d, fz, code)


def warm():
    """Compile the kernels (2D and 3D) into numba's cache on a tiny star of each."""
    for d in (2, 3):
        q, L = 2 * d, 1
        frame = np.eye(d)[None].copy()
        args = dict(comp_off=np.array([0, q]), link_off=np.array([0, L]), slot_A=np.array([0]), slot_B=np.array([1]),
                    frame=frame, weight=np.ones(L), rho=np.ones(L), frozen=np.zeros(L, bool), mass=np.ones(q),
                    fixed=np.zeros(q, bool))
        args["elimination"] = unknown_orders(args["comp_off"], args["link_off"], args["slot_A"], args["slot_B"], d)
        link = dict(g_n=np.zeros((L, d)), dg=np.zeros((L, d)), mu=np.zeros(L), shift=np.zeros(L),
                    cohesion_T=np.zeros(L), k_N=np.ones(L), k_T=np.ones(L))
        N = q + L * d
        cache = dict(fac_off=np.array([0, N * N]), piv_off=np.array([0, 2 * N + 1]), factors=np.zeros(N * N),
                     pivots=np.zeros(2 * N + 1, np.int64), codes=np.zeros(L, np.int8),
                     slip_dir=np.zeros((L, d)), cached=np.zeros(1, np.int8), factored=np.zeros((L, 3)))
        solve_stars(**args, rhs=np.ones(q), x_in=np.zeros(q), **link, h=1.0, rtol=RTOL, max_iterations=100,
                    predict=True, floor_m=0.0, floor_c=0.0, **cache, x_out=np.zeros(q), r_out=np.zeros((L, d)),
                    reaction=np.zeros(q), gbar_out=np.zeros((L, d)), slip_out=np.zeros((L, d)),
                    status=np.zeros(1, np.int8), residual=np.zeros(1), counters=np.zeros(4, np.int64),
                    entry_codes=np.zeros(L, np.int8), entry_cached=np.zeros(1, np.int8))
        keep_pieces(np.array([0]), **args, rhs=np.ones(q), x=np.zeros(q), r=np.zeros((L, d)), **link, h=1.0, **cache)
        gather_stars(np.arange(q), args["comp_off"], args["link_off"], args["slot_A"], args["slot_B"], frame,
                     *(np.zeros(q) for _ in range(4)), 1.0, np.zeros((L, d)), np.zeros((L, d)), np.zeros(q),
                     np.zeros(q))
