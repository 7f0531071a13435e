"""The cheap path of a held star: one whose links all stay closed and sticking this step.

Every held link of a rigid cohesive law is a stiff elastic joint (active_set.COMPLIANCE =
eps, in both directions while it has tensile strength left). On the piece where every link
of a star is closed and sticking, each reaction is then affine in the motion x (link
frame, rho_l the link's step stiffness, r_n its reaction of the step before):

    r_l = r0_l - (rho_l / eps) (tau_l + h (B x)_l),   tau_l = (g_n,N + dg_N, dg_T),  r0_l = (0, r_n,T)

and, the links carrying no springs, the star's momentum m x - h f - h B^T W r = 0 becomes,
with frames orthonormal (B^T W P B = L_g (x) I_d, L_g the graph Laplacian of the copies with
edge weights w_l rho_l),

    (M + h^2 / eps L_g) x_j = h f_j + h [B^T W (r0 - P tau / eps)]_j      in each direction j:

one symmetric positive definite n x n system per direction (n copies), the same at every
step, and the same in every direction where no copy of the star is prescribed. Its inverse is
stored (rigid_inverses: one block for the star then, one per direction otherwise), and the
path costs one product with it and one residual evaluation, against a dense LU solve of
q + L d unknowns per Newton iteration (measured: a 3D star of ~150 unknowns, ~30 us). The
residual then decides exactly, as for any Newton iterate: within rtol the star is solved;
where a link's reaction leaves its cone (tension past its strength, shear past the cone) or a
spring acts, it is not, and the star takes the full solve.

A prescribed component keeps its increment: in each direction the system is then that of
the copies free in it, the couplings to the prescribed ones on the right-hand side. A star
qualifies (rigid_inverses) if it has links and no frozen link; it tries the path where its
last piece was closed and sticking on every link and every link is cohesive (held_piece:
newton.solve_each, loop.keep_pieces).
"""
import numpy as np
from numba import njit

from dolfrag.solver.active_set import COMPLIANCE, CONTACT, STICK
from dolfrag.solver.stars.residual import evaluate, frame_jump

# The piece of a link that is closed and sticking (active_set.link_code).
HELD = CONTACT | STICK


@njit(cache=True, error_model="numpy")
def rigid_inverses(comp_off, link_off, slot_A, slot_B, weight, rho, fixed, frozen, mass, h, d):
    """Per star s, at inverse[off[s]:off[s + 1]], the inverse of M + h^2 / eps L_g (n x n, n
    its copies): one block where no copy of the star is prescribed, else d, one per direction
    j on the copies free in j (zero in the rows and columns of the prescribed ones). L_g is
    the star's graph Laplacian (edge weights weight * rho, Pa m or Pa: the records' Geometry
    fields), M the copies' masses (kg), h the step (s), eps = COMPLIANCE. An empty slice where
    the star does not qualify (no link, or a frozen link). One shared block is a third of the
    memory in 3D, and of what the path reads per step. Returns
    (off (n_stars + 1,) int, inverse)."""
    n_stars = len(comp_off) - 1
    off = np.zeros(n_stars + 1, dtype=np.int64)
    for s in range(n_stars):
        p0, p1, l0, l1 = comp_off[s], comp_off[s + 1], link_off[s], link_off[s + 1]
        n = (p1 - p0) // d
        blocks = 1 if not fixed[p0:p1].any() else d
        off[s + 1] = off[s] + (blocks * n * n if l1 > l0 and not frozen[l0:l1].any() else 0)
    inverse = np.zeros(off[n_stars])
    kappa = h * h / COMPLIANCE
    for s in range(n_stars):
        if off[s + 1] > off[s]:
            n, p0, l0, l1 = (comp_off[s + 1] - comp_off[s]) // d, comp_off[s], link_off[s], link_off[s + 1]
            blocks = inverse[off[s]:off[s + 1]].reshape((-1, n, n))
            for j in range(len(blocks)):
                _block(n, slot_A[l0:l1], slot_B[l0:l1], kappa * weight[l0:l1] * rho[l0:l1],
                       mass[p0 + j:p0 + n * d:d], fixed[p0 + j:p0 + n * d:d], blocks[j])
    return off, inverse


@njit(cache=True, error_model="numpy")
def _block(n, slot_A, slot_B, k, m, fixed, out):
    """One direction's block of rigid_inverses into out (n, n): the inverse of diag(m) + the
    graph Laplacian of edge weights k on the copies not ``fixed`` (n,) in that direction."""
    free = np.flatnonzero(~fixed)
    if len(free) == 0:
        return
    at = np.full(n, -1)
    at[free] = np.arange(len(free))
    A = np.diag(m[free].copy())
    for l in range(len(k)):
        a, b = at[slot_A[l]], at[slot_B[l]]
        if a >= 0:
            A[a, a] += k[l]
        if b >= 0:
            A[b, b] += k[l]
        if a >= 0 and b >= 0:
            A[a, b] -= k[l]
            A[b, a] -= k[l]
    A = np.linalg.inv(A)
    for i in range(len(free)):
        for k_ in range(len(free)):
            out[free[i], free[k_]] = A[i, k_]


@njit(cache=True, error_model="numpy")
def _laplace(d, n, Q, v, out):
    """out = Q[j] v on each direction j of the copies (v, out (n d,), copy-major; Q (1 or d,
    n, n): one block shared by the directions, or one each)."""
    if len(Q) == 1:  # every direction in one pass over the block
        for i in range(n):
            for j in range(d):
                out[i * d + j] = 0.0
            for k in range(n):
                Q_ik = Q[0, i, k]
                for j in range(d):
                    out[i * d + j] += Q_ik * v[k * d + j]
        return
    for j in range(d):
        for i in range(n):
            s = 0.0
            for k in range(n):
                s += Q[j, i, k] * v[k * d + j]
            out[i * d + j] = s


@njit(cache=True, error_model="numpy")
def rigid_solve(d, star, inverse, z, x, r, floor_m, floor_c, ev):
    """The motion x (q,) and reactions r (L, d) of ``star`` (records.Star) held, from its
    stored ``inverse`` (rigid_inverses' slice), into x and r; returns the scaled residuals
    (momentum, contact) there, as residual.evaluate (which leaves in ev what it leaves at
    any iterate). z (>= q,): a workspace for the right-hand side."""
    q, L, h = star.q, star.L, star.h
    n = q // d
    slot_A, slot_B, frame, w, rho, rhs = star.slot_A, star.slot_B, star.frame, star.w, star.rho, star.rhs
    g_n, dg, r_n, fixed, x_in = star.g_n, star.dg, star.r_n, star.fixed, star.x_in
    kappa = h * h / COMPLIANCE
    z = z[:q]
    z[:] = rhs
    for l in range(L):  # h B^T W (r0 - P tau / eps), and the couplings to prescribed copies
        a, b, k = slot_A[l], slot_B[l], kappa * w[l] * rho[l]
        stiff = rho[l] / COMPLIANCE
        for j in range(d):
            F = -frame[l, 0, j] * stiff * (g_n[l, 0] + dg[l, 0])
            for i in range(1, d):
                F += frame[l, i, j] * (r_n[l, i] - stiff * dg[l, i])
            A, B = a * d + j, b * d + j
            z[B] += h * w[l] * F + (k * x_in[A] if fixed[A] else 0.0)
            z[A] += -h * w[l] * F + (k * x_in[B] if fixed[B] else 0.0)
    _laplace(d, n, inverse.reshape((-1, n, n)), z, x)
    for c in range(q):
        if fixed[c]:
            x[c] = x_in[c]
    for l in range(L):
        a, b, stiff = slot_A[l], slot_B[l], rho[l] / COMPLIANCE
        r[l, 0] = -stiff * (g_n[l, 0] + dg[l, 0] + h * frame_jump(d, frame, l, 0, x, a, b))
        for i in range(1, d):
            r[l, i] = r_n[l, i] - stiff * (dg[l, i] + h * frame_jump(d, frame, l, i, x, a, b))
    return evaluate(d, star, x, r, floor_m, floor_c, ev)


@njit(cache=True, error_model="numpy")
def held_piece(code, shift):
    """Whether every link of a piece ``code`` is closed and sticking and a joint in both
    directions (shift > 0, Pa: a rigid cohesive link; active_set.normal_compliance)."""
    for l in range(len(code)):
        if code[l] != HELD or not shift[l] > 0:
            return False
    return True
