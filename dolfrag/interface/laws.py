"""Interface laws, vectorised over links. Pure numpy: no PETSc, no dolfinx, no MPI.

Sign convention (interface/links.py): g = u_B - u_A, g_N = g . n > 0 in opening,
tractions positive in tension, acting on B (their opposite on A).

The cohesive laws here return the cohesive traction, its consistent tangent and the new
state for a trial jump; they never modify their inputs. Non-penetration and friction are
not penalties: they are complementarity conditions, whose Alart-Curnier projections live in
interface/contact.py. In closing (g_N < 0) every cohesive law carries no normal traction.

Shapes: n links, m = d - 1 tangential components (1 in 2D, 2 in 3D); g_T is (n, m) in
both. Material parameters are scalars or (n,) arrays. Every tangent is returned as
    dr_N_dg_N (n,), dr_T_dg_T (n, m, m), dr_N_dg_T (n, m), dr_T_dg_N (n, m)   Pa/m,
with dr_T_dg_T[i, a, b] = d r_T[i, a] / d g_T[i, b]; at g_N = 0 the one-sided derivative
of the closing side is used.
"""
import numpy as np


def elastic(g_N, g_T, C_N, C_T):
    """Linear interface springs (the reference paper's interface elasticity, C = 10 E / h by default).

    g_N (n,) m: normal jump.            C_N Pa/m: normal stiffness.
    g_T (n, d-1) m: tangential jump.    C_T Pa/m: tangential stiffness.

    r_N = C_N g_N,  r_T = C_T g_T;  stored energy density psi = (C_N g_N^2 + C_T |g_T|^2) / 2.

    Returns r_N (n,) Pa, r_T (n, d-1) Pa, and the tangent stiffnesses dr_N/dg_N, dr_T/dg_T
    (Pa/m, broadcastable to (n,)).
    """
    return C_N * g_N, C_T * g_T, C_N, C_T


def elastic_energy(g_N, g_T, C_N, C_T):
    """Stored energy per unit interface area (J/m^2), (n,)."""
    return 0.5 * (C_N * g_N**2 + C_T * np.sum(g_T**2, axis=-1))


def _col(x):
    """A scalar or (n,) parameter as a column broadcasting against (n, m)."""
    return np.asarray(x, dtype=float)[..., None]


def _secant(g_N, g_T, a_N, a_T, s, ds_dg_N, ds_dg_T):
    """r_N = a_N s <g_N>+, r_T = a_T s g_T and their exact derivatives, for a secant
    factor s (n,) with gradient ds_dg_N (n,), ds_dg_T (n, m); a_N, a_T Pa/m or 1/m."""
    p = np.maximum(g_N, 0.0)
    H = (g_N > 0).astype(float)
    a_N = np.asarray(a_N, dtype=float)
    a_T = _col(a_T)
    eye = np.eye(g_T.shape[-1])
    return (a_N * s * p, a_T * s[:, None] * g_T,
            a_N * (s * H + p * ds_dg_N),
            a_T[..., None] * (s[:, None, None] * eye + g_T[:, :, None] * ds_dg_T[:, None, :]),
            _col(a_N * p) * ds_dg_T,
            a_T * g_T * ds_dg_N[:, None])


def _driving_energy(g_N, g_T, C_N, C_T):
    """Y' = C_N <g_N>+^2 + C_T |g_T|^2 (J/m^2) and its gradient (J/m^3)."""
    p = np.maximum(g_N, 0.0)
    return (C_N * p**2 + C_T * np.sum(g_T**2, axis=-1), 2 * C_N * p, 2 * _col(C_T) * g_T)


def rccm_damage(Y, beta_n, w, b=0.0, h=None):
    """The RCCM damage step alone (rccm states the law): beta (n,) at driving energies
    Y' (J/m^2, (n,)) from beta_n, and dbeta/dY' (m^2/J) where damage grows (0 elsewhere);
    w, b, h as rccm. What the state update needs, without the traction and its tangent."""
    Y = np.asarray(Y, dtype=float)
    beta_n = np.broadcast_to(np.asarray(beta_n, dtype=float), Y.shape)
    w = np.broadcast_to(np.asarray(w, dtype=float), Y.shape)
    b = np.broadcast_to(np.asarray(b, dtype=float), Y.shape)
    free = np.divide(w, Y, out=np.full(Y.shape, np.inf), where=Y > 0)
    grow = free < beta_n
    beta = np.where(grow, free, beta_n)
    slope = -np.divide(free, Y, out=np.zeros(Y.shape), where=grow)
    viscous = b > 0
    if viscous.any():
        if h is None:
            raise ValueError("rccm: the viscous law (b > 0) needs the time step h (s)")
        denom = b + h * Y
        beta_visc = np.divide(h * w + b * beta_n, denom, out=beta_n.copy(), where=viscous)
        grow_visc = viscous & (w <= beta_n * Y) & (beta_visc <= beta_n)
        slope_visc = -np.divide(h * beta_visc, denom, out=np.zeros(Y.shape), where=grow_visc)
        grow = np.where(viscous, grow_visc, grow)
        beta = np.where(viscous, np.where(grow_visc, beta_visc, beta_n), beta)
        slope = np.where(viscous, slope_visc, slope)
    clipped = np.clip(beta, 0.0, 1.0)
    dbeta_dY = np.where(grow & (clipped == beta), slope, 0.0)
    return clipped, dbeta_dY


def rccm(g_N, g_T, beta_n, C_N, C_T, w, b=0.0, h=None):
    """RCCM adhesion (Raous-Cangemi-Cocu 1999 / Monerie; LMGC90 MAC_CZM; docs/method.md).

    symbol  meaning                                      unit      shape
    g_N     normal jump, > 0 in opening                  m         (n,)
    g_T     tangential jump                              m         (n, d-1)
    beta_n  adhesion intensity at the previous step      -         (n,), 1 sound .. 0 broken
    C_N     normal stiffness                             Pa/m      scalar or (n,)
    C_T     tangential stiffness                         Pa/m      scalar or (n,)
    w       adhesion energy (= work to separation)       J/m^2     scalar or (n,)
    b       damage viscosity, 0 = rate-independent       J s/m^2   scalar or (n,)
    h       time step, needed where b > 0                s         scalar

    Y' = C_N <g_N>+^2 + C_T |g_T|^2
    b == 0: beta = min(beta_n, w / Y')   (beta = beta_n where Y' = 0)
    b > 0:  beta = (h w + b beta_n) / (b + h Y'), LMGC90's implicit step of
            b dbeta/dt = -[w - beta Y']^-, kept only where w <= beta_n Y' (which is the
            same as beta <= beta_n), else beta = beta_n; clipped to [0, 1].
    r_N = beta^2 C_N <g_N>+    (zero in closing: contact takes over)
    r_T = beta^2 C_T g_T
    Peak sqrt(C_N w) at g_N = sqrt(w / C_N) (mode I), sqrt(C_T w) in mode II; work to
    separation w. The tangent includes dbeta/dg where damage grows:
    dbeta/dg = -(w / Y'^2) dY'/dg (b == 0), -(h beta / (b + h Y')) dY'/dg (b > 0).
    Damage is driven by <g_N>+ and g_T only: compression does not damage. With b > 0
    damage lags the jump: it keeps growing after the opening peaks, while beta Y' > w.

    Sign convention: g = u_B - u_A, n from A to B, tractions positive in tension.
    Returns r_N (n,), r_T (n, d-1) Pa, dr_N_dg_N, dr_T_dg_T, dr_N_dg_T, dr_T_dg_N (Pa/m,
    see the module docstring) and beta (n,).
    """
    g_N, g_T, beta_n = (np.asarray(a, dtype=float) for a in (g_N, g_T, beta_n))
    Y, dY_dg_N, dY_dg_T = _driving_energy(g_N, g_T, C_N, C_T)
    beta, dbeta_dY = rccm_damage(Y, beta_n, w, b, h)
    ds_dY = 2 * beta * dbeta_dY
    return (*_secant(g_N, g_T, C_N, C_T, beta**2, ds_dY * dY_dg_N, ds_dY[:, None] * dY_dg_T),
            beta)


def mohr_coulomb_shear(g_T, r_N, secant, C_T, mu_i):
    """The shear jump that drives RCCM damage under compression (Mohr-Coulomb type).

    symbol  meaning                                          unit    shape
    g_T     tangential jump                                  m       (n, d-1)
    r_N     contact pressure, >= 0 in compression            Pa      (n,)
    secant  the springs' factor beta_n^2                     -       (n,)
    C_T     tangential stiffness                             Pa/m    scalar or (n,)
    mu_i    internal friction of the intact material         -       scalar

    RCCM drives damage with C_T |g_T|^2 even under compression, so a pressed inclined facet
    fails in shear at sqrt(C_T w), however hard it is pressed (docs/hopkinson.md). Here only the
    shear traction above mu_i r_N counts: g_T is scaled to the length
    max(|g_T| - mu_i r_N / (secant C_T), 0). In tension (r_N = 0) and for mu_i = 0 it is g_T.
    Returns (n, d-1) m.
    """
    g_T = np.asarray(g_T, dtype=float)
    norm = np.linalg.norm(g_T, axis=-1)
    resisted = np.divide(mu_i * np.maximum(r_N, 0.0), secant * np.asarray(C_T, dtype=float),
                         out=np.full(norm.shape, np.inf), where=secant > 0)
    factor = np.divide(np.maximum(norm - resisted, 0.0), norm, out=np.zeros_like(norm), where=norm > 0)
    return factor[:, None] * g_T


def rccm_energy(g_N, g_T, beta, C_N, C_T):
    """Stored elastic energy of the RCCM springs (docs/method.md), J/m^2, (n,).

    psi_e = beta^2 / 2 (C_N <g_N>+^2 + C_T |g_T|^2); g_N (n,) m, g_T (n, d-1) m,
    beta (n,) -, C_N, C_T Pa/m. Valid for rccm and rccm_decoupled.
    """
    return 0.5 * np.asarray(beta) ** 2 * _driving_energy(g_N, g_T, C_N, C_T)[0]


def rccm_dissipation(beta, w):
    """Adhesion energy released by RCCM damage (docs/method.md), J/m^2, (n,).

    D = w (1 - beta); beta (n,) -, w J/m^2. In the rate-independent law the work done on a
    link is rccm_energy + D exactly; the viscous law (b > 0) dissipates the path-dependent
    integral of (beta Y' - w)(-dbeta/dt) dt on top.
    """
    return w * (1.0 - np.asarray(beta))


def rccm_friction_coefficient(beta, mu):
    """Friction coefficient of a damaged RCCM link, LMGC90 power p = 1 (docs/method.md).

    mu_beta = mu (1 - beta); beta (n,) -, mu (-) scalar or (n,). Returns (n,) -.
    """
    return mu * (1.0 - np.asarray(beta))


def rccm_parameters(sigma_c, C_N):
    """Adhesion energy w (J/m^2) giving RCCM the peak sigma_c (docs/method.md: the reference paper's coupling).

    w = sigma_c^2 / C_N; sigma_c Pa, C_N Pa/m. Strength, stiffness and toughness are then
    coupled: the work to separation is w itself (and w ~ h when C_N = 10 E / h).
    """
    return np.asarray(sigma_c, dtype=float) ** 2 / C_N


def decoupled_parameters(sigma_c, G_c):
    """Effective opening at full separation of rccm_decoupled (docs/method.md), m.

    delta_c = 2 G_c / sigma_c; sigma_c Pa, G_c J/m^2. The law also needs
    C_N > sigma_c^2 / (2 G_c), i.e. the elastic opening sigma_c / C_N below delta_c.
    """
    sigma_c = np.asarray(sigma_c, dtype=float)
    if np.any(sigma_c <= 0) or np.any(np.asarray(G_c) <= 0):
        raise ValueError("decoupled_parameters: sigma_c and G_c must be > 0")
    return 2 * np.asarray(G_c, dtype=float) / sigma_c


def rccm_decoupled(g_N, g_T, beta_n, C_N, C_T, sigma_c, G_c):
    """RCCM springs with a bilinear envelope (LMGC90 MP3_CZM in spirit; docs/method.md).

    symbol   meaning                                     unit     shape
    g_N      normal jump, > 0 in opening                 m        (n,)
    g_T      tangential jump                             m        (n, d-1)
    beta_n   adhesion intensity at the previous step     -        (n,), 1 sound .. 0 broken
    C_N,C_T  stiffnesses                                 Pa/m     scalar or (n,)
    sigma_c  peak effective traction                     Pa       scalar or (n,)
    G_c      work to separation                          J/m^2    scalar or (n,)

    Same springs, beta and friction as rccm, but sigma_c, G_c and C_N are independent:
    delta = sqrt(Y' / C_N) = sqrt(<g_N>+^2 + C_T/C_N |g_T|^2)   (effective opening)
    delta_0 = sigma_c / C_N,  delta_c = 2 G_c / sigma_c  (requires delta_0 < delta_c)
    envelope: beta^2 C_N delta = sigma_c (delta_c - delta) / (delta_c - delta_0)
    beta = min(beta_n, beta_env(delta)), beta_env = 1 below delta_0, 0 beyond delta_c.
    r_N = beta^2 C_N <g_N>+,  r_T = beta^2 C_T g_T  (damaged secant to the origin).
    The effective traction beta^2 C_N delta rises linearly to sigma_c at delta_0, then falls
    linearly to 0 at delta_c. Since r . dg = beta^2 C_N delta d(delta), the work to
    separation is sigma_c delta_c / 2 = G_c along any proportional path; the mode I peak is
    sigma_c, the mode II peak sqrt(C_T / C_N) sigma_c.

    Sign convention: g = u_B - u_A, n from A to B, tractions positive in tension.
    Returns r_N, r_T, dr_N_dg_N, dr_T_dg_T, dr_N_dg_T, dr_T_dg_N, beta as rccm.
    """
    g_N, g_T, beta_n = (np.asarray(a, dtype=float) for a in (g_N, g_T, beta_n))
    delta_c = decoupled_parameters(sigma_c, G_c)
    delta_0 = np.asarray(sigma_c, dtype=float) / C_N
    if np.any(delta_0 >= delta_c):
        raise ValueError("rccm_decoupled: needs C_N > sigma_c^2 / (2 G_c)")
    Y, dY_dg_N, dY_dg_T = _driving_energy(g_N, g_T, C_N, C_T)
    delta = np.sqrt(Y / C_N)
    A = sigma_c / (C_N * (delta_c - delta_0))
    s_env = np.divide(A * (delta_c - delta), delta, out=np.full(Y.shape, np.inf), where=delta > 0)
    s_env = np.where(delta >= delta_c, 0.0, s_env)
    grow = s_env < beta_n**2
    s = np.where(grow, s_env, beta_n**2)
    # ds/dY' = ds/ddelta / (2 C_N delta), ds/ddelta = -A delta_c / delta^2 on the softening line
    ds_dY = -np.divide(A * delta_c, 2 * C_N * delta**3, out=np.zeros(Y.shape),
                       where=grow & (delta < delta_c))
    return (*_secant(g_N, g_T, C_N, C_T, s, ds_dY * dY_dg_N, ds_dY[:, None] * dY_dg_T),
            np.sqrt(s))


def rccm_decoupled_dissipation(beta, C_N, sigma_c, G_c):
    """Energy dissipated by rccm_decoupled so far (docs/method.md), J/m^2, (n,).

    beta (n,) -; C_N Pa/m; sigma_c Pa; G_c J/m^2. With A = sigma_c / (C_N (delta_c -
    delta_0)), the reached effective opening is delta = A delta_c / (beta^2 + A) and
    D = sigma_c delta (1 - beta^2) / 2: area under the envelope minus the stored triangle;
    0 while sound, G_c when broken.
    """
    s = np.asarray(beta, dtype=float) ** 2
    delta_c = decoupled_parameters(sigma_c, G_c)
    A = sigma_c / (C_N * (delta_c - np.asarray(sigma_c) / C_N))
    return 0.5 * sigma_c * (1 - s) * A * delta_c / (s + A)


def linear_softening(g_N, g_T, delta_max_n, sigma_c, G_c, beta_ratio=1.0, kappa=1.0):
    """Linear softening, Camacho-Ortiz / Snozzi-Molinari as in Akantu (docs/method.md).

    symbol       meaning                                  unit    shape
    g_N          normal jump, > 0 in opening              m       (n,)
    g_T          tangential jump                          m       (n, d-1)
    delta_max_n  largest effective opening so far         m       (n,), 0 = not yet opened
    sigma_c      peak effective traction                  Pa      scalar or (n,)
    G_c          mode I work to separation                J/m^2   scalar or (n,)
    beta_ratio   shear weight (Akantu's beta)             -       scalar or (n,)
    kappa        G_cII / G_cI                             -       scalar or (n,)

    delta = sqrt(beta_ratio^2 |g_T|^2 / kappa^2 + <g_N>+^2),  delta_c = 2 G_c / sigma_c
    T = (beta_ratio^2 / kappa g_T t + <g_N>+ n) S,  with the secant factor
    S = sigma_c (1/delta - 1/delta_c)            on the envelope (delta >= delta_max_n),
    S = sigma_c (1/delta_max_n - 1/delta_c)      unloading to the origin (delta < delta_max_n),
    S = 0                                        once delta_max >= delta_c.
    The envelope starts at sigma_c for delta -> 0+ (extrinsic-like, no initial compliance):
    a link with delta_max == 0 and delta == 0 is "not yet opened" and gets zero traction and
    tangent here; the step solver keeps it rigid as a constraint (like contact) until its
    traction reaches sigma_c. Closing carries no cohesive normal traction.

    Sign convention: g = u_B - u_A, n from A to B, tractions positive in tension.
    Returns r_N (n,), r_T (n, d-1) Pa, dr_N_dg_N, dr_T_dg_T, dr_N_dg_T, dr_T_dg_N (Pa/m)
    and delta_max (n,) m.
    """
    g_N, g_T, delta_max_n = (np.asarray(a, dtype=float) for a in (g_N, g_T, delta_max_n))
    shear = np.asarray(beta_ratio, dtype=float) ** 2 / np.asarray(kappa, dtype=float) ** 2
    p = np.maximum(g_N, 0.0)
    delta = np.sqrt(shear * np.sum(g_T**2, axis=-1) + p**2)
    delta_c = 2 * np.asarray(G_c, dtype=float) / sigma_c
    delta_max = np.maximum(delta_max_n, delta)
    on_envelope = (delta >= delta_max_n) & (delta > 0) & (delta < delta_c)
    S = sigma_c * (np.divide(1.0, delta_max, out=np.zeros(delta.shape), where=delta_max > 0)
                   - 1.0 / delta_c)
    S = np.where((delta_max > 0) & (delta_max < delta_c), S, 0.0)
    # dS/ddelta = -sigma_c / delta^2 on the envelope; ddelta/dg_N = p/delta,
    # ddelta/dg_T = shear g_T / delta
    dS = -np.divide(sigma_c, delta**3, out=np.zeros(delta.shape), where=on_envelope)
    return (*_secant(g_N, g_T, 1.0, np.asarray(beta_ratio) ** 2 / kappa, S, dS * p,
                     _col(dS * shear) * g_T), delta_max)


def linear_softening_dissipation(delta_max, sigma_c, G_c):
    """Energy dissipated by linear_softening so far (docs/method.md), J/m^2, (n,).

    delta_max (n,) m; sigma_c Pa; G_c J/m^2. Area under the envelope up to delta_max,
    sigma_c delta_max (1 - delta_max / (2 delta_c)), minus the recoverable triangle
    sigma_c delta_max (1 - delta_max / delta_c) / 2:
    D = sigma_c min(delta_max, delta_c) / 2   (= G_c once broken).
    Exact for mode I and for kappa = 1; a pure mode II path dissipates kappa times this.
    """
    delta_c = 2 * np.asarray(G_c, dtype=float) / sigma_c
    return 0.5 * sigma_c * np.minimum(delta_max, delta_c)


def threshold(g_N, broken_n, R_c, W_eth):
    """Rigid threshold law, the reference paper's (R_c, W_eth) = LMGC90 xQS_WET_DS_CLB (docs/method.md).

    symbol    meaning                                     unit   shape
    g_N       normal gap, > 0 in opening                  m      (n,)
    broken_n  link broken before this call                -      (n,) bool
    R_c       cohesive tension                            Pa     scalar or (n,)
    W_eth     gap at which cohesion is lost for good      m      scalar or (n,)

    broken = broken_n or g_N > W_eth   (never heals: the xQS variant)
    cohesion = R_c where not broken, 0 where broken.
    There is no spring: the solver enforces shifted Signorini-Coulomb with shift = cohesion,
    r_N + cohesion >= 0, g_N >= 0, (r_N + cohesion) g_N = 0, |r_T| <= mu (r_N + cohesion)
    (interface/contact.py). The traction-gap curve is thus rectangular: tension R_c for
    0 < g_N <= W_eth, stored energy R_c g_N, lost at failure: R_c W_eth per unit area.
    LMGC90 tests the gap at the start of the step; pass that gap to reproduce it.

    Sign convention: g = u_B - u_A, n from A to B; compressive reactions r_N >= 0.
    Returns cohesion (n,) Pa, broken (n,) bool.
    """
    broken = np.asarray(broken_n, dtype=bool) | (np.asarray(g_N) > W_eth)
    return np.where(broken, 0.0, np.broadcast_to(R_c, broken.shape)).astype(float), broken


def threshold_dissipation(broken, R_c, W_eth):
    """Energy lost by the threshold law (docs/method.md), J/m^2, (n,): R_c W_eth where broken.

    broken (n,) bool; R_c Pa; W_eth m.
    """
    return np.where(broken, np.asarray(R_c, dtype=float) * W_eth, 0.0)


def drive(law_step, g_N, g_T, state, *per_step):
    """0D driver: impose a jump history on n links, no mesh: the laws checked alone.

    law_step(g_N (n,), g_T (n, d-1), state (n,), *extra) -> tuple whose first two entries
    are r_N (n,), r_T (n, d-1) and whose last entry is the new state (n,), e.g.
    ``lambda gN, gT, beta: rccm(gN, gT, beta, C_N, C_T, w)``.
    g_N (n_steps, n) m, g_T (n_steps, n, d-1) m, state (n,) initial state; per_step are
    optional (n_steps, ...) histories whose k-th entries are passed as extra (e.g. the
    time step h of the viscous rccm).
    Returns r_N (n_steps, n), r_T (n_steps, n, d-1) Pa, state (n_steps, n) after each step.
    """
    r_N, r_T, states = [], [], []
    for k, (gn, gt) in enumerate(zip(np.asarray(g_N, dtype=float), np.asarray(g_T, dtype=float))):
        out = law_step(gn, gt, state, *(extra[k] for extra in per_step))
        state = out[-1]
        r_N.append(out[0])
        r_T.append(out[1])
        states.append(state)
    return np.array(r_N), np.array(r_T), np.array(states)
