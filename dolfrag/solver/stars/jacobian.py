"""The generalised Jacobian of one star's problem, its LU factors with the identity rows set
apart, and the pieces the factors stand for."""
import numpy as np
from numba import njit

from dolfrag.solver.active_set import (CONTACT, NEGATIVE, PRESSED, SLIP, SPRING, STICK, normal_compliance,
                                      spring_normal_tangent, tangential_compliance)
from dolfrag.solver.stars.lu import lu_factor, record_size
from dolfrag.solver.stars.records import APPROXIMATE, EXACT
from dolfrag.solver.stars.residual import B_CONTACT, B_PRESSED, B_SCALE, B_SLIP, B_STICK, FROZEN


@njit(cache=True, error_model="numpy")
def _jacobian_into(d, star, code, ev, position, n_c, A, C, K, first, at, regularisation):
    """The generalised Jacobian of (R_m, phi) of ``star`` (records.Star) at the point evaluate
    last saw (ev's branch and e, and code), added into the rows of the unknowns with
    position (N,) below n_c: entry (i, j) into A[position[i], position[j]] (n_c, n_c) where position[j] < n_c, else into
    C[position[i], position[j] - n_c]; the rows of the other unknowns, identity rows, are not
    stored. A link whose reactions have positions from ``first`` on is condensed: its block's
    Schur complement goes into A and its record (_condense) into K. Frozen links have identity rows (see FROZEN); prescribed components identity
    rows and zero columns; sticking links get ``regularisation`` (StarOptions.regularisation)
    on the rows of their reaction diagonal that no joint's compliance holds (a closed link
    without tensile strength: its normal row), so that the Jacobian of a piece of stiff joints
    is exact and its stored factors predict the step exactly.
    Each link's block (its two copies and its reactions) is formed in ev.scratch (>= 12 d^2,)
    and then added where it goes (at (>= 3 d, int): its rows' and columns' positions): a
    helper call per entry, with its array arguments, cost six times the whole matrix
    (measured)."""
    q, L, h = star.q, star.L, star.h
    slot_A, slot_B, frame, w, rho, frozen = star.slot_A, star.slot_B, star.frame, star.w, star.rho, star.frozen
    m, fixed, mu, k_N, k_T = star.m, star.fixed, star.mu, star.k_N, star.k_T
    branch, e, scratch = ev.branch, ev.e, ev.scratch
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
        eps = tangential_compliance(frozen[l])
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
        block[2 * d, 2 * d] = normal_compliance(frozen[l], star.shift[l]) if contact else 1.0
        for i in range(1, d):
            block[2 * d + i, 2 * d] = -mu[l] * e[l, i - 1] if (slipping and pressed) else 0.0
            for k in range(1, d):
                block[2 * d + i, 2 * d + k] = 0.0 if stick else (1.0 if i == k else 0.0) - (1.0 - eps) * P[i - 1, k - 1]
        if stick:  # the joint's tangential compliance; the regularisation where a row has none
            for i in range(d):
                block[2 * d + i, 2 * d + i] += eps if i > 0 else 0.0
                if block[2 * d + i, 2 * d + i] == 0.0:
                    block[2 * d + i, 2 * d + i] = regularisation
        for c in range(3 * d):  # where the block's rows and columns go (-1: a prescribed component's)
            u = a * d + c if c < d else (b * d + c - d if c < 2 * d else q + (c - 2 * d) * L + l)
            at[c] = -1 if u < q and fixed[u] else position[u]
        if at[2 * d] >= first:
            _condense(d, block, at, n_c, A, K[(at[2 * d] - first) // d * record_size(d):])
            continue
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
def _condense(d, block, at, n_c, A, record):
    """Condense a held link's reactions out of its block (3 d x 3 d: copy a, copy b, its
    reactions; at (3 d,) their positions, -1 a prescribed component's): its reaction rows
    K_rx y_x + K_rr y_r = R_r involve only its own copies, and K_rr is diagonal (the joint's
    compliance, active_set.COMPLIANCE), so y_r = K_rr^-1 R_r - H y_x with H = K_rr^-1 K_rx,
    and the copies' rows get K_xx - K_xr H into A and G = K_xr K_rr^-1 into their
    right-hand side (lu.solve_star). Prescribed components' rows of G and columns of H are
    zero: their rows are the identity, their columns zero."""
    inverse = record[:d]
    G = record[d:d + 2 * d * d].reshape((2 * d, d))
    H = record[d + 2 * d * d:4 * d * d + d].reshape((d, 2 * d))
    for i in range(d):
        inverse[i] = 1.0 / block[2 * d + i, 2 * d + i]
    for r in range(2 * d):
        for i in range(d):
            G[r, i] = block[r, 2 * d + i] * inverse[i] if at[r] >= 0 else 0.0
            H[i, r] = inverse[i] * block[2 * d + i, r] if at[r] >= 0 else 0.0
    for r in range(2 * d):
        i = at[r]
        if i < 0 or i >= n_c:
            continue
        for c in range(2 * d):
            j = at[c]
            if j < 0:
                continue
            s = block[r, c]
            for k in range(d):
                s -= G[r, k] * block[2 * d + k, c]
            A[i, j] += s


@njit(cache=True, error_model="numpy", inline="always")
def _held_link(l, frozen, shift, branch):
    """Whether link l of a star is a closed, sticking joint (a rigid cohesive link, shift > 0
    Pa, not frozen): its reactions' rows are then local and their diagonal invertible."""
    return (not frozen[l] and shift[l] > 0 and branch[l, B_CONTACT] > 0 and branch[l, B_STICK] > 0
            and not branch[l, B_SLIP] > 0)


@njit(cache=True, error_model="numpy")
def jacobian(d, star, code, ev, J, regularisation):
    """The whole generalised Jacobian J (N, N), every row stored (_jacobian_into): the
    matrix the stored factors stand for, as the tests check it."""
    N = star.q + star.L * d
    J[:, :] = 0.0
    _jacobian_into(d, star, code, ev, np.arange(N), N, J, J[:, :0], J[0, :0], N, np.empty(3 * d, dtype=np.int64),
                   regularisation)
    return N


@njit(cache=True, error_model="numpy")
def factor_jacobian(d, star, code, ev, elimination, store, index, position, regularisation):
    """Factorise a star's Jacobian (_jacobian_into, arguments as there) with its unit rows set
    apart and its held links condensed. An unknown whose row is that of the identity (an open
    link's normal row, a tangential row neither sticking nor slipping, a frozen link, a
    prescribed component) is its own residual's, and leaves the others a system on the coupled
    unknowns only (an intact RCCM star in tension: its q momentum rows alone; a 2D star: LU of
    ~18 rows instead of 24 costs half). The reactions of a held link (_held_link: a closed,
    sticking joint) are eliminated link by link (_condense), which leaves the LU the copies and
    the other links' reactions: on a cracking 3D bar, 63 coupled unknowns instead of 137 on
    average (docs/method.md, "Held links condensed"). The coupled unknowns are eliminated in the star's ``elimination`` order (N,:
    unknown_order). Only their rows are formed, straight into store (>= N^2): the LU factors
    of the coupled block (n_c, n_c), its columns of the unit unknowns (n_c, n_u), then a record
    per condensed link (lu.record_size); index (>= 2 N + 1): n_c, the coupled unknowns, the unit
    ones, the condensed ones (as -1 - u, a link's d reactions together), the pivots, then each
    condensed link's two copies. Links are condensed only where the coupled block keeps at
    least lu.record_size(d) / d rows, so that everything lies in the first n_c N values of
    store. position (>= N + 3 d, int) workspace; ev (residual.Evaluation) gives the branches
    and e of the point, and its scratch. (Formed whole and then copied, a 3D star's Jacobian
    cost more than its LU: measured on the damaged 3D bar, 5 + 13 ms of a 101 ms kernel call,
    the LU 17 ms.)"""
    q, L, fixed, frozen, shift, branch = star.q, star.L, star.fixed, star.frozen, star.shift, ev.branch
    N = q + L * d
    order = index[1:1 + N]
    n_held, n_coupled = 0, 0
    for l in range(L):
        if _held_link(l, frozen, shift, branch):
            n_held += 1
    for u in range(N):
        if not _unit(u, q, L, fixed, frozen, branch):
            n_coupled += 1
    if n_coupled - d * n_held < record_size(d) // d:
        n_held = 0
    first = N - d * n_held
    n_c, n_t = 0, first
    for u in elimination:
        if u >= q and n_held > 0 and _held_link((u - q) % L, frozen, shift, branch):
            continue
        if _unit(u, q, L, fixed, frozen, branch):
            n_t -= 1
            order[n_t] = u
        else:
            order[n_c] = u
            n_c += 1
    index[0] = n_c
    for i in range(first):
        position[order[i]] = i
    copies = index[1 + N + n_c:]
    k = 0
    for l in range(L):
        if n_held > 0 and _held_link(l, frozen, shift, branch):
            for i in range(d):
                u = q + i * L + l
                order[first + d * k + i] = -1 - u
                position[u] = first + d * k + i
            copies[2 * k], copies[2 * k + 1] = star.slot_A[l], star.slot_B[l]
            k += 1
    n_u = first - n_c
    end = n_c * (n_c + n_u) + n_held * record_size(d)
    store[:n_c * N] = 0.0  # all its solves read (and a checkpoint keeps), the same each time
    A = store[:n_c * n_c].reshape((n_c, n_c))
    C = store[n_c * n_c:n_c * (n_c + n_u)].reshape((n_c, n_u))
    _jacobian_into(d, star, code, ev, position[:N], n_c, A, C, store[n_c * (n_c + n_u):end], first, position[N:],
                   regularisation)
    lu_factor(A, index[1 + N:1 + N + n_c])


@njit(cache=True, error_model="numpy", inline="always")
def _unit(u, q, L, fixed, frozen, branch):
    """Whether unknown u of a star has an identity row (factor_jacobian)."""
    if u < q:
        return fixed[u]
    l = (u - q) % L
    moves = branch[l, B_SLIP] > 0 if u >= q + L else branch[l, B_CONTACT] > 0  # tangential, normal
    return frozen[l] or not (moves or branch[l, B_STICK] > 0)


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
def factor_piece(d, star, code, slip_dir, elimination, store, index, position, ev, regularisation):
    """factor_jacobian of the piece ``code`` (L,) of one star with its slip directions
    slip_dir (L, d) held (piece_branches): what keep_pieces stores for the next step's
    prediction. Arguments as factor_jacobian; ev's branch and e are overwritten."""
    piece_branches(star.L, d, code, slip_dir, ev.branch, ev.e)
    factor_jacobian(d, star, code, ev, elimination, store, index, position, regularisation)


@njit(cache=True, error_model="numpy")
def kind_of(d, star, code):
    """What the factors of a star's piece are good for: APPROXIMATE with a 3D slipping link
    (smooth, not affine), else EXACT. A frozen link does not count: its rows are the
    identity on every piece (its reaction a fixed point, see FROZEN), and its copies'
    momentum rows are prescribed, so the factors are Newton's own matrix on the piece;
    its predicted reaction is exact where its jump vanishes (a clamped support), and the
    fixed point reuses the factors elsewhere. Measured on bunker-h2 (0.2 m, 8 ms): the
    133 stars of the clamped base, started from zero, took 3.1 Newton iterations each."""
    kind = EXACT
    frozen = star.frozen  # a local: a record field read in a loop costs an NRT incref/decref a pass
    for l in range(star.L):
        if d == 3 and (code[l] & SLIP) and not frozen[l]:
            kind = APPROXIMATE
    return kind


@njit(cache=True, error_model="numpy")
def flip_rows(d, star, l, old, new, U, V, regularisation):
    """The rows of U and V (each (2, N)) with J_new - J_old = U^T V for link l going from
    piece old to piece new (their CONTACT and SPRING bits differ only): its normal row (the
    contact row h rho n^T (x_B - x_A) against the open row r_N) and its spring's
    h^2/4 w k_N n n^T in the momentum block (as _jacobian_into forms them, with its
    ``regularisation``). Returns the rank (1, 2)."""
    q, h, slot_A, slot_B, frame, w, rho, fixed, k_N = star.q, star.h, star.slot_A, star.slot_B, star.frame, \
        star.w, star.rho, star.fixed, star.k_N
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
    closed = normal_compliance(star.frozen[l], star.shift[l])  # the normal row's diagonal in contact
    if (old & STICK) and closed == 0.0:  # (the pieces share their STICK bit)
        closed = regularisation
    V[0, q + l] = (closed if c_new else 1.0) - (closed if c_old else 1.0)
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
def note_factored(star, factored):
    """factored (L, 3) = the (k_N, k_T, mu) of a star's links its factors are formed with
    (what star_replay needs to form stale factors again)."""
    k_N, k_T, mu = star.k_N, star.k_T, star.mu  # locals (see kind_of)
    for l in range(star.L):
        factored[l, 0], factored[l, 1], factored[l, 2] = k_N[l], k_T[l], mu[l]
