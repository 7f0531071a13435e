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
residual then decides exactly, as for any Newton iterate: where every link reads the held
piece and it is within rtol the star is solved; where a link's reaction leaves its cone
(tension past its strength, shear past the cone) or a spring acts, it is not, and the star
takes the full solve.

A prescribed component keeps its increment: in each direction the system is then that of
the copies free in it, the couplings to the prescribed ones on the right-hand side. A star
qualifies (rigid_inverses) if it has links and no frozen link; it tries the path where its
last piece was closed and sticking on every link and every link is cohesive (held_piece:
held_stars, a pass of its own before Newton's loop; newton.solve_each and loop.keep_pieces
send a star back to it).
"""
import numpy as np
from numba import njit

from dolfrag.solver.active_set import COMPLIANCE, CONTACT, STICK
from dolfrag.solver.stars.records import CONVERGED, ITERATIONS, N_FIRST, NONE, RIGID
from dolfrag.solver.stars.residual import frame_jump, scaled_ratio

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
def held_stars(d, geometry, data, cache, out, rtol, todo, rest, z, force):
    """The held path over a rank's stars, before Newton (newton.solve_each): each star s of
    ``todo`` whose stored piece is held on every link (held_piece; cache.cached not NONE)
    and that qualifies (rigid_inverses) gets its motion and reactions there (held_motion)
    and is solved if it reads the held piece there with its residual within ``rtol``
    (held_residual): its outputs, status and counters are then written as Newton's would be
    for a star solved at iteration 1. rest[s]: whether s of ``todo`` still takes Newton;
    a refused star stored no factors if it was RIGID (cached NONE: Newton starts from zero).
    z, force (>= the largest star's components): workspaces. Records as
    loop.solve_stars.

    The stars are read through the flat arrays and their offsets, not through a Star per
    star (records.star_at): numba increfs and decrefs every array of such a record it
    slices and passes on, ~0.26 us a star to build one and ~0.4 us more to pass it to a
    function (measured on 4,863 held 2D stars of the damaged bar of
    benchmarks/step_cost.py: the held path cost 1.33 us a star through the record, 0.64 us
    read flat)."""
    comp_off, link_off, rigid_off, rigid = geometry.comp_off, geometry.link_off, geometry.rigid_off, geometry.rigid
    codes, cached, shift = cache.codes, cache.cached, data.shift
    status, residual, counters = out.status, out.residual, out.counters
    for s in range(len(comp_off) - 1):
        rest[s] = todo[s]
        r0, r1, l0, l1 = rigid_off[s], rigid_off[s + 1], link_off[s], link_off[s + 1]
        if not todo[s] or r1 == r0 or cached[s] == NONE or not held_piece(codes[l0:l1], shift[l0:l1]):
            continue
        p0, p1 = comp_off[s], comp_off[s + 1]
        held_motion(d, geometry, data, p0, p1, l0, l1, rigid[r0:r1], z, out.x, out.r)
        scaled = held_residual(d, geometry, data, p0, p1, l0, l1, force, out)
        if scaled <= rtol:
            rest[s] = False
            status[s], residual[s] = CONVERGED, scaled
            counters[N_FIRST] += 1
            counters[ITERATIONS] = max(counters[ITERATIONS], 1)
        elif cached[s] == RIGID:  # no factors to predict with
            cached[s] = NONE


@njit(cache=True, error_model="numpy", inline="always")
def held_motion(d, geometry, data, p0, p1, l0, l1, inverse, z, x, r):
    """The motion x[p0:p1] and reactions r[l0:l1] (link frame) of the star of components
    [p0, p1) and links [l0, l1) held, from its stored ``inverse`` (rigid_inverses' slice);
    z: a workspace for the right-hand side."""
    slot_A, slot_B, frame, w, rho, fixed = geometry.slot_A, geometry.slot_B, geometry.frame, geometry.weight, \
        geometry.rho, geometry.fixed
    rhs, x_in, g_n, dg, r_n, h = data.rhs, data.x_in, data.g_n, data.dg, data.r_n, data.h
    q, first = p1 - p0, p0 // d  # the star's components, and its first copy
    n = q // d
    kappa = h * h / COMPLIANCE
    for c in range(q):
        z[c] = rhs[p0 + c]
    for l in range(l0, l1):  # h B^T W (r0 - P tau / eps), and the couplings to prescribed copies
        a, b, k = slot_A[l], slot_B[l], kappa * w[l] * rho[l]
        stiff = rho[l] / COMPLIANCE
        for j in range(d):
            F = -frame[l, 0, j] * stiff * (g_n[l, 0] + dg[l, 0])
            for i in range(1, d):
                F += frame[l, i, j] * (r_n[l, i] - stiff * dg[l, i])
            A, B = a * d + j, b * d + j
            z[B] += h * w[l] * F + (k * x_in[p0 + A] if fixed[p0 + A] else 0.0)
            z[A] += -h * w[l] * F + (k * x_in[p0 + B] if fixed[p0 + B] else 0.0)
    if len(inverse) == n * n:  # one block for every direction: a row's d sums side by side
        for i in range(n):
            s0, s1, s2 = 0.0, 0.0, 0.0
            for k in range(n):
                Q_ik = inverse[i * n + k]
                s0 += Q_ik * z[k * d]
                s1 += Q_ik * z[k * d + 1]
                if d == 3:
                    s2 += Q_ik * z[k * d + 2]
            x[p0 + i * d], x[p0 + i * d + 1] = s0, s1
            if d == 3:
                x[p0 + i * d + 2] = s2
    else:  # one block a direction, prescribed components zero in it
        for j in range(d):
            for i in range(n):
                s = 0.0
                for k in range(n):
                    s += inverse[j * n * n + i * n + k] * z[k * d + j]
                x[p0 + i * d + j] = s
    for c in range(p0, p1):
        if fixed[c]:
            x[c] = x_in[c]
    for l in range(l0, l1):
        a, b, stiff = first + slot_A[l], first + slot_B[l], rho[l] / COMPLIANCE
        r[l, 0] = -stiff * (g_n[l, 0] + dg[l, 0] + h * frame_jump(d, frame, l, 0, x, a, b))
        for i in range(1, d):
            r[l, i] = r_n[l, i] - stiff * (dg[l, i] + h * frame_jump(d, frame, l, i, x, a, b))


@njit(cache=True, error_model="numpy", inline="always")
def held_residual(d, geometry, data, p0, p1, l0, l1, force, out):
    """The scaled residual of the star of components [p0, p1) and links [l0, l1) at out.x,
    out.r, the larger of its momentum and contact parts, as residual.evaluate's on the held
    piece (the same terms in the same order); inf where a link does not read that piece
    (open, or slipping) or where it is NaN. Writes the springs' jumps, the slips and the
    prescribed components' reactions into out, as newton._write does; force: a workspace."""
    slot_A, slot_B, frame, w, rho, m, fixed = geometry.slot_A, geometry.slot_B, geometry.frame, geometry.weight, \
        geometry.rho, geometry.mass, geometry.fixed
    rhs, g_n, dg, mu, shift, cohesion_T, k_N, k_T, r_n, h = data.rhs, data.g_n, data.dg, data.mu, data.shift, \
        data.cohesion_T, data.k_N, data.k_T, data.r_n, data.h
    x, r, gbar, slip, reaction = out.x, out.r, out.gbar, out.slip, out.reaction
    q, first = p1 - p0, p0 // d
    for i in range(q):
        force[i] = 0.0
    max_phi, max_r, max_terms, probe = 0.0, 0.0, 0.0, 0.0
    for l in range(l0, l1):
        a, b = first + slot_A[l], first + slot_B[l]
        for i in range(d):
            s = frame_jump(d, frame, l, i, x, a, b)
            gbar[l, i] = g_n[l, i] + 0.25 * h * s
            slip[l, i] = dg[l, i] + h * s
            max_terms = max(max_terms, rho[l] * (abs(g_n[l, i]) + abs(dg[l, i]) + h * abs(s)))
            max_r = max(max_r, abs(r[l, i]))
        r_shift = r[l, 0] + shift[l]
        y_N = r_shift - rho[l] * (g_n[l, 0] + slip[l, 0]) - COMPLIANCE * r[l, 0]
        radius = mu[l] * (r_shift if r_shift > 0 else 0.0) + cohesion_T[l]
        norm = 0.0
        for i in range(1, d):
            y_i = r[l, i] - rho[l] * slip[l, i] - COMPLIANCE * (r[l, i] - r_n[l, i])
            norm += y_i * y_i
        if not (y_N >= 0 and np.sqrt(norm) <= radius and radius > 0):  # not closed and sticking
            return np.inf
        phi = r_shift - y_N
        max_phi = max(max_phi, abs(phi))
        probe += phi
        for i in range(1, d):
            phi = rho[l] * slip[l, i] + COMPLIANCE * (r[l, i] - r_n[l, i])
            max_phi = max(max_phi, abs(phi))
            probe += phi
        gbar[l, 0] = 0.75 * g_n[l, 0] - 0.25 * dg[l, 0]
        t_N = w[l] * (k_N[l] * max(gbar[l, 0], 0.0) - r[l, 0])
        for j in range(d):  # h B^T w (t(gbar) - r), the springs' t as evaluate reads them
            F = frame[l, 0, j] * t_N
            for i in range(1, d):
                F += frame[l, i, j] * (w[l] * (k_T[l] * gbar[l, i] - r[l, i]))
            force[(b - first) * d + j] += h * F
            force[(a - first) * d + j] -= h * F
    scale_m, max_m = 0.0, 0.0
    for i in range(q):
        mx = m[p0 + i] * x[p0 + i]
        scale_m = max(scale_m, abs(rhs[p0 + i]), abs(mx), abs(force[i]))
        R_i = mx - rhs[p0 + i] + force[i]
        reaction[p0 + i] = R_i / h if fixed[p0 + i] else 0.0
        R_i = 0.0 if fixed[p0 + i] else R_i
        max_m = max(max_m, abs(R_i))
        probe += R_i
    if probe != probe:  # NaN: never read as converged
        return np.inf
    scaled_c = scaled_ratio(max_phi, max(max_r + max_terms, data.floor_c))
    return max(scaled_ratio(max_m, max(scale_m, data.floor_m)), scaled_c)


@njit(cache=True, error_model="numpy")
def held_piece(code, shift):
    """Whether every link of a piece ``code`` is closed and sticking and a joint in both
    directions (shift > 0, Pa: a rigid cohesive link; active_set.normal_compliance)."""
    for l in range(len(code)):
        if code[l] != HELD or not shift[l] > 0:
            return False
    return True
