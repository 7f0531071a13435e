"""The RCCM trial state of a step and its acceptance, compiled: one loop over the links each.

The same arithmetic, operation for operation, as models.threshold_trial_state with
laws.mohr_coulomb_shear and laws.rccm_damage (the pure numpy reference the tests hold it
to, bit for bit), and as the released energy of models.Rccm.store: those cost ~20 numpy
calls a step whatever the number of links, which on a rank's few hundred links is most
of their time.
"""
import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _opening_sliding(g_N, g_T, l):
    """<g_N>+ and |g_T|^2 of link l (m, m^2): what the driving energy Y' is made of."""
    sliding = 0.0
    for k in range(g_T.shape[1]):
        sliding += g_T[l, k] ** 2
    return max(g_N[l], 0.0), sliding


@njit(cache=True, error_model="numpy")
def trial_state(g_N, g_T, beta_n, r_N, C_N, C_T, w, b, h, mu_i, margin, beta):
    """beta[l]: the damage RCCM gives at the link-frame jumps g_N (n,) and g_T (n, d-1) (m)
    from beta_n (n,), with the shear that drives it reduced by mu_i r_N (r_N (n,) Pa, or
    empty for none). C_N, C_T Pa/m; w J/m^2; b J s/m^2 (0: rate-independent); h s; margin:
    the threshold test's (models.THRESHOLD_MARGIN)."""
    shear = len(r_N) > 0 and mu_i != 0.0
    for l in range(len(beta_n)):
        beta_l = beta_n[l]
        beta[l] = beta_l
        opening, sliding = _opening_sliding(g_N, g_T, l)
        threshold = w / beta_l if beta_l > 0 else np.inf
        if not C_N * opening**2 + C_T * sliding > (1 - margin) * threshold:
            continue
        if shear:  # the shear traction above mu_i r_N alone drives damage
            norm = np.sqrt(sliding)
            secant = beta_l**2
            resisted = mu_i * max(r_N[l], 0.0) / (secant * C_T) if secant > 0 else np.inf
            factor = max(norm - resisted, 0.0) / norm if norm > 0 else 0.0
            sliding = 0.0
            for k in range(g_T.shape[1]):
                sliding += (factor * g_T[l, k]) ** 2
        Y = C_N * opening**2 + C_T * sliding
        free = w / Y if Y > 0 else np.inf
        new = free if free < beta_l else beta_l
        if b > 0:  # the viscous law
            viscous = (h * w + b * beta_l) / (b + h * Y)
            new = viscous if w <= beta_l * Y and viscous <= beta_l else beta_l
        beta[l] = min(max(new, 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def store(links, state, g_N, g_T, C_N, C_T, beta, released):
    """Accept the damage ``state`` (n,) of the links ``links`` (n,) into beta (per link of
    the table), adding to ``released`` (J/m^2) the energy the drop frees at the
    link-frame jumps g_N (n,), g_T (n, d-1) (m): 1/2 (beta_n^2 - beta^2) Y'(g)."""
    for i in range(len(links)):
        k = links[i]
        if state[i] == beta[k]:
            continue
        opening, sliding = _opening_sliding(g_N, g_T, i)
        drive = C_N * opening**2 + C_T * sliding
        released[k] += 0.5 * (beta[k] ** 2 - state[i] ** 2) * drive
        beta[k] = state[i]


def warm():
    """Compile the loops into numba's cache (2D and 3D jumps, with and without r_N; the
    jumps of store as columns of the link-frame jump array, as the star solver passes them)."""
    for m in (1, 2):
        for r_N in (np.zeros(0), np.ones(1)):
            trial_state(np.ones(1), np.ones((1, m)), np.ones(1), r_N, 1.0, 1.0, 0.5, 1.0, 1.0, 0.3, 1e-9,
                        np.empty(1))
        g = np.ones((1, m + 1))
        store(np.zeros(1, dtype=np.int64), np.zeros(1), g[:, 0], g[:, 1:], 1.0, 1.0, np.ones(1), np.zeros(1))
