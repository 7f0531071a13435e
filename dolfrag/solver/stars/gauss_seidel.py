"""Projected Gauss-Seidel over one star's links: the fallback of a star whose Newton wanders
(StarOptions.fallback)."""
from collections import namedtuple

import numpy as np
from numba import njit

from dolfrag.solver.active_set import CONTACT, normal_compliance, spring_normal_tangent, tangential_compliance
from dolfrag.solver.stars.lu import lu_factor, lu_solve
from dolfrag.solver.stars.residual import frame_jump

# gauss_seidel's workspaces, flat (sized for the largest star of a call, n = L d unknowns of
# reactions): the momentum matrix A (q, q), B^T W (q, n), the springs' constants (n,), the
# right-hand side (q,), the pivots (q,), x = x0 + X r (q,), (q, n), a column (q,), the jumps
# c + G r (n,), (n, n), per link its augmentation (L,), two vectors of a link (d,), and per
# link the links its rows of G couple it to (L, L) and how many (L,).
SweepSpace = namedtuple("SweepSpace", "A P spring b0 piv x0 X column c G rho y z coupled n_coupled")


@njit(cache=True, error_model="numpy")
def sweep_space(d, q_max, L_max):
    """A SweepSpace for stars of up to q_max components and L_max links."""
    n = L_max * d
    return SweepSpace(np.empty(q_max * q_max), np.empty(q_max * n), np.empty(n), np.empty(q_max),
                      np.empty(q_max, dtype=np.int64), np.empty(q_max), np.empty(q_max * n), np.empty(q_max),
                      np.empty(n), np.empty(n * n), np.empty(L_max), np.empty(d), np.empty(d),
                      np.empty(L_max * L_max, dtype=np.int64), np.empty(L_max, dtype=np.int64))


@njit(cache=True, error_model="numpy")
def gauss_seidel(d, star, x, r, gbar, code, floor_c, sweeps, tol, ws):
    """Projected Gauss-Seidel over the star's links (the nonsmooth Gauss-Seidel of LMGC90):
    with the springs' affine model of the current iterate held (traction t0 + D h B x / 4,
    read as in _evaluate: gbar and code from it), x is linear in r, x = x0 + X r, so the
    end-of-step jumps are c + G r; each link in turn projects r_l - rho_l (its gap, its
    slip) onto the shifted Signorini-Coulomb set, rho_l = 1 / max diag G_ll, for ``sweeps``
    sweeps or until none changes a reaction by more than tol of the largest. Overwrites
    x (q,) and r (L, d); ``star`` a records.Star, gbar and code as evaluate left them,
    ws a SweepSpace (a Newton step's workspaces: a star can take thousands of calls)."""
    q, L, h = star.q, star.L, star.h
    slot_A, slot_B, frame, w, m, fixed, rhs = star.slot_A, star.slot_B, star.frame, star.w, star.m, star.fixed, star.rhs
    g_n, dg, mu, shift, cohesion_T, k_N, k_T = star.g_n, star.dg, star.mu, star.shift, star.cohesion_T, star.k_N, \
        star.k_T
    frozen, rho_link, r_n = star.frozen, star.rho, star.r_n
    n = L * d
    A = ws.A[:q * q].reshape((q, q))
    P = ws.P[:q * n].reshape((q, n))  # B^T W
    A[:, :] = 0.0
    P[:, :] = 0.0
    spring = ws.spring[:n]
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
    b0 = ws.b0[:q]
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
    piv = ws.piv[:q]
    lu_factor(A, piv)
    x0 = ws.x0[:q]
    for i in range(q):
        x0[i] = x[i] if fixed[i] else b0[i]
    lu_solve(A, piv, x0)
    X = ws.X[:q * n].reshape((q, n))
    column = ws.column[:q]
    for k in range(n):
        for i in range(q):
            column[i] = h * P[i, k]
        lu_solve(A, piv, column)
        X[:, k] = column
    # B as (n, q): link-frame jumps of the components
    c = ws.c[:n]
    G = ws.G[:n * n].reshape((n, n))  # every entry written
    for l in range(L):
        a, b = slot_A[l], slot_B[l]
        for i in range(d):
            c[l * d + i] = g_n[l, i] + dg[l, i] + h * frame_jump(d, frame, l, i, x0, a, b)
            for k in range(n):
                s = 0.0
                for j in range(d):
                    s += frame[l, i, j] * (X[b * d + j, k] - X[a * d + j, k])
                G[l * d + i, k] = h * s
    rho = ws.rho[:L]
    for l in range(L):
        big = G[l * d, l * d]
        for i in range(1, d):
            big = max(big, G[l * d + i, l * d + i])
        rho[l] = 1.0 / big if big > 0 else 0.0
    coupled = ws.coupled[:L * L].reshape((L, L))
    n_coupled = ws.n_coupled[:L]
    _couplings(d, L, G, coupled, n_coupled)
    y, z = ws.y, ws.z
    for _ in range(sweeps):
        change, largest = 0.0, 0.0
        for l in range(L):
            if rho[l] <= 0:
                continue
            for i in range(d):
                s = c[l * d + i]
                for m in range(n_coupled[l]):
                    k = coupled[l, m]
                    for j in range(d):
                        s += G[l * d + i, k * d + j] * r[k, j]
                y[i] = s
            # the joint's compliances (active_set.COMPLIANCE), m/Pa
            soft_N = normal_compliance(frozen[l], shift[l]) / rho_link[l]
            soft_T = tangential_compliance(frozen[l]) / rho_link[l]
            r_N = max(-shift[l], r[l, 0] - rho[l] * (y[0] + soft_N * r[l, 0]))
            norm = 0.0
            for i in range(1, d):
                z[i] = r[l, i] - rho[l] * (y[i] - g_n[l, i] + soft_T * (r[l, i] - r_n[l, i]))
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
        if change <= tol * (largest + floor_c):
            break
    for i in range(q):
        s = x0[i]
        for l in range(L):
            for j in range(d):
                s += X[i, l * d + j] * r[l, j]
        x[i] = s



@njit(cache=True, error_model="numpy")
def _couplings(d, L, G, coupled, n_coupled):
    """Per link l, the links k whose block G[l, k] is not all zero, in increasing order
    (coupled[l, :n_coupled[l]]). A sweep sums only over them: the same sums as over every
    link, less exact zeros. Without springs A is the diagonal mass, and two links are
    coupled only through a shared copy: in 3D a copy has three facets at the vertex, so a
    link meets about 6 of the star's 20-50 links (measured on the cracking bunker-wall-panel,
    linear softening, where Gauss-Seidel takes most of a stalled star's time)."""
    for l in range(L):
        n = 0
        for k in range(L):
            nonzero = False
            for i in range(d):
                for j in range(d):
                    nonzero = nonzero or G[l * d + i, k * d + j] != 0.0
            if nonzero:
                coupled[l, n] = k
                n += 1
        n_coupled[l] = n
