"""The last active set of each vertex star, and the affine step it predicts (imex).

The star problem of solver/semismooth.py is piecewise linear in its unknowns z = (x, r)
(velocity increments and link reactions): with the damage lagged, on one *piece* - which
links are in contact, which stick or slip (and which way, in 2D), which are pressed, which
normal springs pull - its residual is affine,

    R(z) = J z + c,        c = R(0) evaluated with that piece's formulas,

with J the generalised Jacobian of the piece. From one step to the next most stars stay on
their piece (measured on sound-bar: 100-150 of 30k links change contact state per step as
a wave passes), so the step is predicted by one solve with the inverse of the star's last
Jacobian, z = -J^-1 c, and the residual at z (solver/semismooth.py) decides. The constant c
for piece p, per link (link frame, rho the augmentation, g_n the jump of u_n, dg the
predicted jump increment h B v_-, D the springs' tangent on the piece, w the link weight):

    momentum rows   -h f + h B^T (w D g_n)          (prescribed rows: 0)
    normal row      contact: rho (g_n,N + dg_N)      open: shift
    tangent rows    stick: rho dg_T    slip: -e (mu shift [pressed] + cohesion_T)    free: 0

(2D only for slip, where its direction e = +-1 is part of the piece; a 3D slip is smooth,
not affine, and leaves the star to Newton.) Pure numpy, no MPI: each rank predicts its own
stars.
"""
import numpy as np

CONTACT, STICK, SLIP, PRESSED, NEGATIVE, SPRING = 1, 2, 4, 8, 16, 32


def pattern_code(branches, gbar_N):
    """One small integer per link naming its piece: the contact.Branches flags (arrays
    (n, L) or (n, L, m) for e) and whether the normal spring pulls (gbar_N > 0). Whether
    the link is pressed matters (to J and c) only where it slips; whether the spring pulls,
    only where the link is open: in contact g_end,N = 0 pins gbar_N = (3 g_n,N - dg_N) / 4
    to round-off of a closed link, whose sign then flickers from step to step while both
    pieces give the same step to that round-off."""
    slip, contact = branches.slip, branches.contact
    code = (CONTACT * contact + STICK * branches.stick + SLIP * slip
            + PRESSED * (slip & branches.pressed) + SPRING * ((gbar_N > 0) & ~contact))
    return (code + NEGATIVE * (slip & (branches.e[..., 0] < 0))).astype(np.int8)


def affine_constant(code, D, BR, w, rho, rhs, fixed, g_n, dg, mu, shift, cohesion_T, h, t_pinned):
    """c of the pieces ``code`` (n, L) for the stars' data: D (n, L, d, d) springs' tangent
    (Pa/m, without the normal column of links in contact: semismooth._spring_affine);
    BR (n, L d, q) link-frame jump operator; w (n, L) link weights (m or m^2); rho (n, L)
    augmentation (Pa/m); rhs (n, q) h f (N s); fixed (n, q) prescribed components; g_n, dg
    (n, L, d) m; mu (-), shift, cohesion_T (Pa) (n, L); h (s); t_pinned (n, L) the springs'
    normal traction (Pa) at the jump contact pins (semismooth.spring_jump). Returns
    (n, q + L d): momentum rows, then the normal rows of every link, then each tangential
    component of every link."""
    n, q = rhs.shape
    contact = (code & CONTACT) > 0
    t0 = np.einsum("slij,slj->sli", D, g_n)
    t0[..., 0] += np.where(contact, t_pinned, 0.0)
    t0 *= w[..., None]
    c_m = h * np.einsum("spq,sp->sq", BR, t0.reshape(n, -1)) - rhs
    c_m[fixed] = 0.0
    c_N = np.where(contact, rho * (g_n[..., 0] + dg[..., 0]), shift)
    stick, slip = (code & STICK) > 0, (code & SLIP) > 0
    radius0 = mu * shift * ((code & PRESSED) > 0) + cohesion_T
    e = np.where((code & NEGATIVE) > 0, -1.0, 1.0)
    c_T = np.where(stick[..., None], rho[..., None] * dg[..., 1:],
                   np.where(slip[..., None], -(e * radius0)[..., None], 0.0))
    # reactions component-major, as the unknowns of semismooth._jacobian
    return np.concatenate([c_m, c_N, c_T.transpose(0, 2, 1).reshape(n, -1)], axis=1)


class ActiveSets:
    """Per star of one group: the inverse of its last Jacobian (n_s, N, N), the piece it
    belongs to (code (n_s, L)), the springs' tangent D (n_s, L, d, d) on it, and whether
    it may predict (``valid``: set where the three describe the star's current state)."""

    def __init__(self, n_s, L, d, N):
        self.inverse = np.zeros((n_s, N, N))
        self.code = np.zeros((n_s, L), dtype=np.int8)
        self.D = np.zeros((n_s, L, d, d))
        self.valid = np.zeros(n_s, dtype=bool)

    def keep(self, stars, inverse, code, D, cacheable=True):
        """Store the Jacobian inverse of ``stars`` on the pieces ``code``, springs' tangent D;
        valid where ``cacheable`` (bool, scalar or per star)."""
        self.inverse[stars], self.code[stars], self.D[stars] = inverse, code, D
        self.valid[stars] = cacheable

    def predict(self, BR, w, rho, rhs, fixed, g_n, dg, mu, shift, cohesion_T, h, t_pinned):
        """z = -J^-1 c (n_s, N) for every star of the group (data as in affine_constant);
        meaningful where ``valid``."""
        c = affine_constant(self.code, self.D, BR, w, rho, rhs, fixed, g_n, dg, mu, shift, cohesion_T, h, t_pinned)
        return -np.einsum("sij,sj->si", self.inverse, c)
