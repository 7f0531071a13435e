"""The cheap path of a rigid star: one whose links all stay closed and sticking this step.

On that piece a star's motion is known without Newton. Every link holds its jump: the
normal gap closes (g_n,N + dg_N + h (B x)_N = 0) and the tangential jump does not move
(dg_T + h (B x)_T = 0), so the copies move as one body. With frames orthonormal,
B^T W P B = L_g (x) I_d, L_g the star's graph Laplacian over its copies with edge weights
w_l rho_l (W the links' weights, m or m^2; P their augmentations rho, Pa/m), and

    x = L_g^+ B^T W P tau + c,      tau_l = -(g_n,N + dg_N, dg_T) / h   (link frame)

with c the common velocity that conserves the star's momentum, sum m x = sum h f (the
interface forces are internal and cancel). The reactions then balance the momentum
residual at r = 0, h B^T W r = R_m(x, 0). Around a vertex the links close on themselves,
so that balance leaves the reactions undetermined up to self-equilibrated rings; the full
solve fixes them by its regularisation of the sticking rows (StarOptions.regularisation),
whose iterates stay in the range of P B (the Delassus matrix's), and tend to its only
solution there, r = P B lambda:

    lambda = L_g^+ R_m(x, 0) / h,      r_l = rho_l frame_l (lambda_B - lambda_A).

The same answer the full solve converges to, in the motion and in the reactions, at the
cost of two products with the star's stored (L_g + a J / n)^-1 (n copies, J = 1 1^T,
a = trace / n: on zero-sum right-hand sides it acts as L_g^+) and two residual evaluations,
against a dense LU solve of q + L d unknowns per Newton iteration (measured: a 3D star of
~150 unknowns, 2 iterations, ~30 us). The residual at (x, r) then decides exactly, as for
any Newton iterate: where it is within rtol the star is solved; where a link's reaction
leaves its cone (tension past the shift, shear past the cone) or springs break the
balance, it is not, and the star takes the full solve.

A prescribed component keeps its increment, and in each direction the Laplacian is then that
of the copies free in it (no longer singular where a copy is held, and no common velocity to
find). A star qualifies (rigid_inverses) if it has links, no frozen link, and its copies
are connected by its links; it tries the path where its last piece was closed and sticking
on every link (newton.solve_each, loop.keep_pieces).
"""
from collections import namedtuple

import numpy as np
from numba import njit

from dolfrag.solver.active_set import CONTACT, STICK
from dolfrag.solver.stars.residual import evaluate, frame_jump

# The piece of a link that is closed and sticking (active_set.link_code).
HELD = CONTACT | STICK

# Workspaces of rigid_solve for stars of up to q_max components: B^T W P tau, then lambda.
RigidSpace = namedtuple("RigidSpace", "z lam")


@njit(cache=True, error_model="numpy")
def rigid_space(q_max):
    """A RigidSpace for stars of up to q_max components."""
    return RigidSpace(np.empty(q_max), np.empty(q_max))


@njit(cache=True, error_model="numpy")
def _connected(n, slot_A, slot_B):
    """Whether the n copies of a star are connected by its links (union-find)."""
    root = np.arange(n)
    for l in range(len(slot_A)):
        a, b = slot_A[l], slot_B[l]
        while root[a] != a:
            a = root[a]
        while root[b] != b:
            b = root[b]
        root[max(a, b)] = min(a, b)
    for i in range(n):
        a = i
        while root[a] != a:
            a = root[a]
        if a != 0:
            return False
    return True


@njit(cache=True, error_model="numpy")
def rigid_inverses(comp_off, link_off, slot_A, slot_B, weight, rho, fixed, frozen, d):
    """Per star s, d blocks of n x n (n its copies) at inverse[off[s]:off[s + 1]], one per
    direction j: with L_g the star's graph Laplacian (edge weights weight * rho, Pa m or Pa:
    the records' Geometry fields), (L_g + a J / n)^-1 (a = trace(L_g) / n, J = 1 1^T) where
    no copy is prescribed in j, else the inverse of L_g on the copies free in j, zero in the
    rows and columns of the others. An empty slice where the star does not qualify (no
    link, a frozen link, copies not connected). Returns (off (n_stars + 1,) int, inverse)."""
    n_stars = len(comp_off) - 1
    off = np.zeros(n_stars + 1, dtype=np.int64)
    for s in range(n_stars):
        l0, l1 = link_off[s], link_off[s + 1]
        n = (comp_off[s + 1] - comp_off[s]) // d
        qualifies = l1 > l0 and not frozen[l0:l1].any() and _connected(n, slot_A[l0:l1], slot_B[l0:l1])
        off[s + 1] = off[s] + (d * n * n if qualifies else 0)
    inverse = np.zeros(off[n_stars])
    for s in range(n_stars):
        if off[s + 1] > off[s]:
            n, p0, l0, l1 = (comp_off[s + 1] - comp_off[s]) // d, comp_off[s], link_off[s], link_off[s + 1]
            blocks = inverse[off[s]:off[s + 1]].reshape((d, n, n))
            for j in range(d):
                _block(n, slot_A[l0:l1], slot_B[l0:l1], weight[l0:l1] * rho[l0:l1], fixed[p0 + j:p0 + n * d:d],
                       blocks[j])
    return off, inverse


@njit(cache=True, error_model="numpy")
def _block(n, slot_A, slot_B, k, fixed, out):
    """One direction's block of rigid_inverses into out (n, n): k the edge weights, fixed
    (n,) which copies are prescribed in that direction."""
    G = np.zeros((n, n))
    for l in range(len(k)):
        a, b = slot_A[l], slot_B[l]
        G[a, a] += k[l]
        G[b, b] += k[l]
        G[a, b] -= k[l]
        G[b, a] -= k[l]
    if not fixed.any():
        out[:, :] = np.linalg.inv(G + np.trace(G) / (n * n))
        return
    free = np.flatnonzero(~fixed)
    if len(free) == 0:
        return
    G_F = np.empty((len(free), len(free)))
    for i in range(len(free)):
        for k_ in range(len(free)):
            G_F[i, k_] = G[free[i], free[k_]]
    G_F = np.linalg.inv(G_F)
    for i in range(len(free)):
        for k_ in range(len(free)):
            out[free[i], free[k_]] = G_F[i, k_]


@njit(cache=True, error_model="numpy")
def _laplace(d, n, Q, v, out):
    """out = Q[j] v on each direction j of the copies (v, out (n d,), copy-major)."""
    for j in range(d):
        for i in range(n):
            s = 0.0
            for k in range(n):
                s += Q[j, i, k] * v[k * d + j]
            out[i * d + j] = s


@njit(cache=True, error_model="numpy")
def rigid_solve(d, star, inverse, x, r, floor_m, floor_c, ev, rw):
    """The motion x (q,) and reactions r (L, d) of ``star`` (records.Star) held rigid, from
    its stored ``inverse`` (rigid_inverses' slice), into x and r; returns the scaled
    residuals (momentum, contact) there, as residual.evaluate (which leaves in ev what it
    leaves at any iterate). A prescribed component takes its increment x_in, and the
    Laplacian of those increments moves to the right-hand side; a direction with none takes
    the common velocity that conserves the star's momentum. rw: a RigidSpace."""
    q, L, h = star.q, star.L, star.h
    n = q // d
    Q = inverse.reshape((d, n, n))
    slot_A, slot_B, frame, w, rho, m, rhs = star.slot_A, star.slot_B, star.frame, star.w, star.rho, star.m, star.rhs
    g_n, dg, fixed, x_in = star.g_n, star.dg, star.fixed, star.x_in
    z, lam = rw.z[:q], rw.lam[:q]
    z[:] = 0.0
    for l in range(L):  # B^T W P tau, less L_g of the prescribed increments
        a, b, k = slot_A[l], slot_B[l], w[l] * rho[l]
        for j in range(d):
            delta = -frame[l, 0, j] * (g_n[l, 0] + dg[l, 0])
            for i in range(1, d):
                delta -= frame[l, i, j] * dg[l, i]
            delta /= h
            A, B = a * d + j, b * d + j
            delta -= (x_in[B] if fixed[B] else 0.0) - (x_in[A] if fixed[A] else 0.0)
            z[B] += k * delta
            z[A] -= k * delta
    _laplace(d, n, Q, z, x)
    for j in range(d):  # the common velocity where no copy is held: the star's momentum conserved
        mass, momentum, held_j = 0.0, 0.0, False
        for i in range(n):
            held_j = held_j or fixed[i * d + j]
            mass += m[i * d + j]
            momentum += rhs[i * d + j] - m[i * d + j] * x[i * d + j]
        for i in range(n):
            c = i * d + j
            x[c] = x_in[c] if fixed[c] else x[c] + (0.0 if held_j else momentum / mass)
    r[:L, :] = 0.0
    evaluate(d, star, x, r, floor_m, floor_c, ev)
    _laplace(d, n, Q, ev.R[:q], lam)
    for l in range(L):
        a, b = slot_A[l], slot_B[l]
        for i in range(d):
            r[l, i] = rho[l] * frame_jump(d, frame, l, i, lam, a, b) / h
    return evaluate(d, star, x, r, floor_m, floor_c, ev)


@njit(cache=True, error_model="numpy")
def all_held(code):
    """Whether every link of a piece ``code`` is closed and sticking."""
    for c in code:
        if c != HELD:
            return False
    return True
