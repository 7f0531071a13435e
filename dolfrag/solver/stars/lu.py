"""Dense LU in place for the stars' small systems, and the solves from a star's stored
factors (factor_jacobian's layout), with a Woodbury correction for links that flipped
(StarOptions.flips)."""
from numba import njit


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


@njit(cache=True, error_model="numpy", inline="always")
def record_size(d):
    """The values a condensed link keeps (jacobian._condense): K_rr^-1 (d), G (2 d x d), H (d x 2 d)."""
    return 4 * d * d + d


@njit(cache=True, error_model="numpy")
def solve_star(d, store, index, R, work, nonzero):
    """Solve J y = R in place (R (N,)) from factor_jacobian's store and index (jacobian.factor_jacobian); work (>= N,),
    nonzero (>= N, int) workspaces. A condensed link's reactions r (jacobian._condense) leave
    the copies' residuals R_x - G R_r before the coupled solve and come back after it, as
    K_rr^-1 R_r - H y_x."""
    N = len(R)
    n_c = index[0]
    order = index[1:1 + N]
    n_u = N - n_c
    while n_u > 0 and order[n_c + n_u - 1] < 0:  # the condensed unknowns, marked, at the end
        n_u -= 1
    A = store[:n_c * n_c].reshape((n_c, n_c))
    C = store[n_c * n_c:n_c * (n_c + n_u)].reshape((n_c, n_u))
    condensed = store[n_c * (n_c + n_u):]
    copies = index[1 + N + n_c:]
    first, size = n_c + n_u, record_size(d)
    for k in range((N - first) // d):
        G = condensed[k * size + d:k * size + d + 2 * d * d]
        for c in range(2 * d):
            u = copies[2 * k + c // d] * d + c % d
            s = R[u]
            for i in range(d):
                s -= G[c * d + i] * R[-1 - order[first + d * k + i]]
            R[u] = s
    # the unit unknowns' residuals are mostly zero (an open link's normal row without
    # shift, a frictionless tangential row): their columns are skipped, in the same order
    n_nz = 0
    for k in range(n_u):
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
    for k in range((N - first) // d):
        inverse = condensed[k * size:k * size + d]
        H = condensed[k * size + d + 2 * d * d:(k + 1) * size]
        for i in range(d):
            u = -1 - order[first + d * k + i]
            s = inverse[i] * R[u]
            for c in range(2 * d):
                s -= H[i * 2 * d + c] * R[copies[2 * k + c // d] * d + c % d]
            R[u] = s


@njit(cache=True, error_model="numpy")
def woodbury_factor(d, store, index, U, V, Z, cap, cap_piv, work, nonzero):
    """Z = J^-1 U^T (rows, from the stored factors) and the LU of the capacitance
    I + V Z^T, for woodbury_solve; U, V, Z (n_u, N), cap (>= n_u^2)."""
    n_u = U.shape[0]
    for i in range(n_u):
        Z[i] = U[i]
        solve_star(d, store, index, Z[i], work, nonzero)
    C = cap[:n_u * n_u].reshape((n_u, n_u))
    for i in range(n_u):
        for j in range(n_u):
            s = 1.0 if i == j else 0.0
            for m in range(len(Z[j])):
                s += V[i, m] * Z[j, m]
            C[i, j] = s
    lu_factor(C, cap_piv[:n_u])


@njit(cache=True, error_model="numpy")
def woodbury_solve(d, store, index, V, Z, cap, cap_piv, R, t, work, nonzero):
    """Solve (J + U^T V) y = R in place, J from the stored factors, Z and the capacitance
    from woodbury_factor; t (>= n_u,) workspace."""
    n_u = V.shape[0]
    solve_star(d, store, index, R, work, nonzero)
    for i in range(n_u):
        s = 0.0
        for m in range(len(R)):
            s += V[i, m] * R[m]
        t[i] = s
    lu_solve(cap[:n_u * n_u].reshape((n_u, n_u)), cap_piv[:n_u], t[:n_u])
    for i in range(n_u):
        for m in range(len(R)):
            R[m] -= t[i] * Z[i, m]
