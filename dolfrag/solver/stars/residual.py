"""The residual of one star's problem (solver/semismooth.py states it) and the branches of
its projections, at an iterate."""
from collections import namedtuple

import numpy as np
from numba import njit

from dolfrag.solver.active_set import link_code, normal_compliance, tangential_compliance

# A link whose two copies are both prescribed (between supported copies, or in a patch
# test) has a known jump, so Newton cannot move it and its contact rows would be singular.
# Its reaction is the projection itself, taken with the augmentation FROZEN times larger
# (so a prescribed opening releases the constraint at once) and iterated as a fixed
# point: identity rows in the Jacobian. Part of the residual, not a tuning of Newton: the
# Jacobian and the tests read the same constant.
FROZEN = 1e6

# Columns of the per-link branch table of evaluate.
B_CONTACT, B_STICK, B_SLIP, B_PRESSED, B_SCALE = 0, 1, 2, 3, 4

# What evaluate leaves at an iterate (workspaces of L_max links, q_max components).
Evaluation = namedtuple("Evaluation", "Bx gbar slip branch e force R reaction code scratch")


@njit(cache=True, error_model="numpy")
def evaluation(d, q_max, L_max):
    """An Evaluation with room for stars of up to q_max components and L_max links."""
    return Evaluation(np.empty((L_max, d)), np.empty((L_max, d)), np.empty((L_max, d)), np.empty((L_max, 5)),
                 np.zeros((L_max, max(d - 1, 1))), np.empty(q_max), np.empty(q_max + L_max * d), np.empty(q_max),
                 np.empty(L_max, dtype=np.int8), np.empty(12 * d * d))


@njit(cache=True, error_model="numpy", inline="always")
def frame_jump(d, frame, l, i, v, a, b):
    """Component i, in link l's frame (frame (L, d, d)), of the jump v_b - v_a of a copy field
    v (copy-major, d per copy) between the link's copies a and b."""
    s = 0.0
    for j in range(d):
        s += frame[l, i, j] * (v[b * d + j] - v[a * d + j])
    return s


@njit(cache=True, error_model="numpy")
def scaled_ratio(a, scale):
    """a / scale, 0 where both vanish (a star at rest), inf where only the scale does."""
    if scale > 0:
        return a / scale
    return np.inf if a > 0 else 0.0


@njit(cache=True, error_model="numpy")
def evaluate(d, star, x, r, floor_m, floor_c, ev):
    """The residual ev.R (q + L d) of ``star`` (records.Star) at (x (q), r (L, d)), in the
    unknowns' order, and its scaled parts (momentum, contact), returned; the floors as in
    records.StepData. In ``ev`` (an Evaluation) it leaves per link B x in the link frame (Bx), the
    jump the springs are read at (gbar), the end-of-step slip h B (v_- + x) (slip), the
    branches of the projections (branch, e: slip direction) and the piece (code); per
    component the interface force h B^T w (t - r) (force) and the reactions of prescribed
    components (reaction, N). Frozen links take FROZEN rho.

        R_m = m x - h f + h B^T w (t(gbar) - r)       (0 on prescribed components)
        phi = Alart-Curnier of Signorini-Coulomb on the cone shifted by the cohesion,
              at g_end = g_n + dg + h B x, with the held links' joints
              (interface/contact.py; active_set.COMPLIANCE)
        gbar = g_n + h B x / 4, but 3 g_n,N / 4 - dg_N / 4 on closed links

    Closed links read their normal spring at the jump contact pins (where g_end,N = 0),
    which does not move with x: read at gbar(x), a spring acting in opening only sat on its
    kink at g_N = 0 at gaps exact to the contact tolerance (1e-13 m), and Newton and
    Gauss-Seidel, each on one side, did not meet (measured: see StarOptions.give_up).
    """
    q, L, h = star.q, star.L, star.h
    slot_A, slot_B, frame, w, rho, frozen = star.slot_A, star.slot_B, star.frame, star.w, star.rho, star.frozen
    m, fixed, rhs, g_n, dg, mu = star.m, star.fixed, star.rhs, star.g_n, star.dg, star.mu
    shift, cohesion_T, k_N, k_T, r_n = star.shift, star.cohesion_T, star.k_N, star.k_T, star.r_n
    Bx, gbar, slip, branch, e, force = ev.Bx, ev.gbar, ev.slip, ev.branch, ev.e, ev.force
    R, reaction, code, scratch = ev.R, ev.reaction, ev.code, ev.scratch
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
        y_N = r_shift - rho_l * (g_n[l, 0] + slip[l, 0]) - normal_compliance(frozen[l], shift[l]) * r[l, 0]
        contact = y_N >= 0
        phi = r_shift - max(0.0, y_N)
        R[q + l] = phi
        max_phi = max(max_phi, abs(phi))
        probe += phi
        pressed = r_shift > 0
        radius = mu[l] * (r_shift if pressed else 0.0) + cohesion_T[l]
        eps = tangential_compliance(frozen[l])
        norm = 0.0
        for i in range(1, d):
            y_i = r[l, i] - rho_l * slip[l, i] - eps * (r[l, i] - r_n[l, i])
            norm += y_i * y_i
        norm = np.sqrt(norm)
        stick = norm <= radius and radius > 0
        slipping = norm > radius and radius > 0
        scale = radius / norm if slipping else 0.0
        for i in range(1, d):
            y_i = r[l, i] - rho_l * slip[l, i] - eps * (r[l, i] - r_n[l, i])
            e[l, i - 1] = y_i / norm if slipping else 0.0
            phi = rho_l * slip[l, i] + eps * (r[l, i] - r_n[l, i]) if stick else r[l, i] - scale * y_i
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
    return scaled_ratio(max_m, max(scale_m, floor_m)), scaled_ratio(max_phi, max(scale_c, floor_c))

