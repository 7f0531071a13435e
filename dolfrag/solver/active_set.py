"""The last active set of each vertex star, and the affine step it predicts (imex).

The star problem of solver/semismooth.py is piecewise linear in its unknowns z = (x, r)
(velocity increments and link reactions): with the damage lagged, on one *piece* - which
links are in contact, which stick or slip (and which way, in 2D), which are pressed, which
normal springs pull - its residual is affine,

    R(z) = J z + c,        c = R(0) evaluated with that piece's formulas,

with J the generalised Jacobian of the piece. From one step to the next most stars stay on
their piece (measured on sound-bar: 100-150 of 30k links change contact state per step as
a wave passes), so the step is predicted by one solve with the LU factors of the star's
last Jacobian, z = -J^-1 c, and the residual at z decides. The constant c for piece p, per
link (link frame, rho the augmentation, g_n the jump of u_n, dg the predicted jump
increment h B v_-, D the springs' tangent on the piece, w the link weight):

    momentum rows   -h f + h B^T (w D g_n)          (prescribed rows: 0)
    normal row      contact: rho (g_n,N + dg_N)      open: shift
    tangent rows    stick: rho dg_T    slip: -e (mu shift [pressed] + cohesion_T)    free: 0

with e the slip direction (slip_dir, per link). In 2D e = +-1 is part of the piece, and the
prediction is exact on it. A 3D slip is smooth, not affine: its direction turns with the
iterate, and the prediction holds e at the last step's direction (the tangent rows
r_T - radius(r_N) e, with their Jacobian: P = 0 in stars/jacobian.py), exact only if
the direction stays; it is then a start for Newton, not a solve (stars/records.APPROXIMATE).
Compiled (numba), one star at a time, called from the star kernel; no MPI: each rank
predicts its own stars.
"""
import numpy as np
from numba import njit

CONTACT, STICK, SLIP, PRESSED, NEGATIVE, SPRING = 1, 2, 4, 8, 16, 32

# A held link is a stiff elastic joint, not a rigid one: its compliance is COMPLIANCE / rho
# (m/Pa; rho = m / (h^2 w) the link's step stiffness, Pa/m, measured 4-14 E / h_mesh at the
# stable step: a joint 4,000-14,000 times stiffer than a cell of the bulk). A sticking link's tangential
# reaction moves from the step before's, r_n, with its slip as the spring rho / COMPLIANCE,
# and a closed link with tensile strength left (shift > 0: a rigid cohesive link) opens or
# closes by COMPLIANCE r_N / rho; broken links keep exact contact. Rigid, the reactions of a
# ring of sticking links around a vertex were determined only up to self-equilibrated rings:
# the Jacobian was singular there, and Newton stalled on such stars (the hard stars of
# the cracking 3D runs; measured before and after in docs/notes/performance-history.md).
COMPLIANCE = 1e-3


@njit(cache=True, error_model="numpy")
def link_code(contact, stick, slip, pressed, e_0, gbar_N):
    """One small integer naming a link's piece: the contact branches (bools; e_0 the first
    component of the slip direction) and whether the normal spring pulls (gbar_N > 0).
    Whether the link is pressed matters (to J and c) only where it slips; whether the
    spring pulls, only where the link is open: in contact g_end,N = 0 pins gbar_N =
    (3 g_n,N - dg_N) / 4 to round-off of a closed link, whose sign then flickers from step
    to step while both pieces give the same step to that round-off."""
    code = CONTACT * contact + STICK * stick + SLIP * slip + PRESSED * (slip and pressed)
    code += SPRING * (gbar_N > 0 and not contact) + NEGATIVE * (slip and e_0 < 0)
    return np.int8(code)


@njit(cache=True, error_model="numpy", inline="always")
def tangential_compliance(frozen):
    """A link's tangential compliance relative to its rho (see COMPLIANCE): none if frozen."""
    return 0.0 if frozen else COMPLIANCE


@njit(cache=True, error_model="numpy", inline="always")
def normal_compliance(frozen, shift):
    """A link's normal compliance relative to its rho while closed (see COMPLIANCE): only a
    rigid cohesive link's (shift > 0, Pa); broken links keep exact contact."""
    return COMPLIANCE if shift > 0 and not frozen else 0.0


@njit(cache=True, error_model="numpy")
def joint_jumps(g_n, slip, r_n, r, shift, rho, frozen, g_mid, opening, joint):
    """A step's jumps of the links (link frame, (n, d), m) from the jumps of u_n, g_n, and
    the step's increments ``slip``, with the reactions of the step before and of this one,
    r_n and r (Pa), into g_mid, opening and joint:

        g_mid   = g_n + slip / 2                      the mid-step jump
        joint   = -c (r - r_n)                        the joints' elastic jump increment
        opening = g_mid + c (r_n + r) / 2             g_mid less the joints' elastic jump

    with c = COMPLIANCE / rho (m/Pa) the joint of a law's rigid link (shift > 0, Pa; rho the
    links' step stiffness, Pa/m), 0 on the others: the joint's elastic jump, -c r, is the
    joint's, not the law's (see COMPLIANCE). One compiled pass: 0.27 ms of CPU on the 31,632
    links of bunker-h2 at 0.2 m, against 0.88 ms for numpy's temporaries."""
    n, d = g_n.shape
    for l in range(n):
        c = normal_compliance(frozen[l], shift[l]) / rho[l]
        for i in range(d):
            g_mid[l, i] = g_n[l, i] + 0.5 * slip[l, i]
            joint[l, i] = -c * (r[l, i] - r_n[l, i])
            opening[l, i] = g_mid[l, i] + 0.5 * c * (r_n[l, i] + r[l, i])


@njit(cache=True, error_model="numpy")
def spring_normal_tangent(code, k_N):
    """The springs' normal tangent (Pa/m) on a piece: k_N where the spring pulls on an open
    link, 0 in contact (the pinned normal jump does not move with x) and in closing."""
    return k_N if code & SPRING else 0.0


@njit(cache=True, error_model="numpy")
def affine_constant(d, star, code, slip_dir, c):
    """c (q + L d) of the pieces ``code`` (L,) of ``star`` into c: momentum rows, then the
    normal rows of every link, then each tangential component of every link. star
    (solver/stars/records.Star): slot_A, slot_B (L,) the copies each link joins; frame
    (L, d, d) link frames (normal first); w (L,) weights (m or m^2); rho (L,) augmentation
    (Pa/m); fixed (q,) prescribed components; rhs (q,) h f (N s); g_n, dg (L, d) m; mu (-),
    shift, cohesion_T (Pa), k_N, k_T (Pa/m) (L,) the friction, the constraint's cohesion and
    the springs' secants; h (s). slip_dir (L, d) the slip direction of slipping links (its
    first d - 1 columns)."""
    q, L, h = star.q, star.L, star.h
    slot_A, slot_B, frame, w, rho, fixed, rhs = star.slot_A, star.slot_B, star.frame, star.w, star.rho, star.fixed, \
        star.rhs
    g_n, dg, mu, shift, cohesion_T, k_N, k_T = star.g_n, star.dg, star.mu, star.shift, star.cohesion_T, star.k_N, \
        star.k_T
    for i in range(q):
        c[i] = -rhs[i]
    for l in range(L):
        cd = code[l]
        contact = (cd & CONTACT) > 0
        t0_N = spring_normal_tangent(cd, k_N[l]) * g_n[l, 0]
        if contact:  # the law's normal traction at the jump contact pins
            t0_N += k_N[l] * max(0.75 * g_n[l, 0] - 0.25 * dg[l, 0], 0.0)
        a, b = slot_A[l], slot_B[l]
        for j in range(d):
            F = frame[l, 0, j] * t0_N
            for i in range(1, d):
                F += frame[l, i, j] * k_T[l] * g_n[l, i]
            F *= h * w[l]
            c[b * d + j] += F
            c[a * d + j] -= F
        c[q + l] = rho[l] * (g_n[l, 0] + dg[l, 0]) if contact else shift[l]
        radius0 = mu[l] * shift[l] * ((cd & PRESSED) > 0) + cohesion_T[l]
        for i in range(1, d):
            if cd & STICK:
                c[q + i * L + l] = rho[l] * dg[l, i] - tangential_compliance(star.frozen[l]) * star.r_n[l, i]
            elif cd & SLIP:  # in 2D the direction is the piece's; in 3D the held one
                e = (-1.0 if cd & NEGATIVE else 1.0) if d == 2 else slip_dir[l, i - 1]
                c[q + i * L + l] = -e * radius0
            else:
                c[q + i * L + l] = 0.0
    for i in range(q):
        if fixed[i]:
            c[i] = 0.0


def warm():
    """Compile joint_jumps into numba's cache (2D and 3D)."""
    for d in (2, 3):
        g = np.zeros((1, d))
        joint_jumps(g, g, g, g, np.ones(1), np.ones(1), np.zeros(1, dtype=np.bool_), g.copy(), g.copy(), g.copy())
