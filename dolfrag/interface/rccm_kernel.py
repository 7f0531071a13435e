"""The RCCM trial state of a step and its acceptance, compiled: one loop over the links each.

The same arithmetic, operation for operation, as models.threshold_trial_state with
laws.mohr_coulomb_shear and laws.rccm_damage (the pure numpy reference the tests hold it
to, bit for bit), and as the released energy of models.Rccm.store: those cost ~20 numpy
calls a step whatever the number of links, which on a rank's few hundred links is most
of their time.
"""
import numpy as np
from numba import njit


# The per-link helpers are inlined into the loops (numba's inline="always"): called, each
# call with array arguments cost about what the link's arithmetic does (measured on 1,708
# links: advance 21.8 -> 11.9 us, the same results bit for bit).
@njit(cache=True, error_model="numpy", inline="always")
def _opening_sliding(g_N, g_T):
    """<g_N>+ and |g_T|^2 of one link (m, m^2; g_T (d-1,)): what the driving energy Y' is made of."""
    sliding = 0.0
    for k in range(len(g_T)):
        sliding += g_T[k] ** 2
    return max(g_N, 0.0), sliding


@njit(cache=True, error_model="numpy", inline="always")
def _damage(g_N, g_T, beta_n, r_N, shear, C_N, C_T, w, b, h, mu_i, margin):
    """The damage of one link (trial_state's, for its g_N, g_T (d-1,), beta_n, r_N; shear:
    whether mu_i r_N reduces the shear)."""
    opening, sliding = _opening_sliding(g_N, g_T)
    threshold = w / beta_n if beta_n > 0 else np.inf
    if not C_N * opening**2 + C_T * sliding > (1 - margin) * threshold:
        return beta_n
    if shear:  # the shear traction above mu_i r_N alone drives damage
        norm = np.sqrt(sliding)
        secant = beta_n**2
        resisted = mu_i * max(r_N, 0.0) / (secant * C_T) if secant > 0 else np.inf
        factor = max(norm - resisted, 0.0) / norm if norm > 0 else 0.0
        sliding = 0.0
        for k in range(len(g_T)):
            sliding += (factor * g_T[k]) ** 2
    Y = C_N * opening**2 + C_T * sliding
    free = w / Y if Y > 0 else np.inf
    new = free if free < beta_n else beta_n
    if b > 0:  # the viscous law
        viscous = (h * w + b * beta_n) / (b + h * Y)
        new = viscous if w <= beta_n * Y and viscous <= beta_n else beta_n
    return min(max(new, 0.0), 1.0)


@njit(cache=True, error_model="numpy", inline="always")
def _release(beta_n, beta, g_N, g_T, C_N, C_T):
    """The energy (J/m^2) a link's drop beta_n -> beta frees at the jumps g_N, g_T (d-1,):
    1/2 (beta_n^2 - beta^2) Y'(g)."""
    opening, sliding = _opening_sliding(g_N, g_T)
    return 0.5 * (beta_n**2 - beta**2) * (C_N * opening**2 + C_T * sliding)


@njit(cache=True, error_model="numpy")
def trial_state(g_N, g_T, beta_n, r_N, C_N, C_T, w, b, h, mu_i, margin, beta):
    """beta[l]: the damage RCCM gives at the link-frame jumps g_N (n,) and g_T (n, d-1) (m)
    from beta_n (n,), with the shear that drives it reduced by mu_i r_N (r_N (n,) Pa, or
    empty for none). C_N, C_T Pa/m; w J/m^2; b J s/m^2 (0: rate-independent); h s; margin:
    the threshold test's (models.THRESHOLD_MARGIN)."""
    shear = len(r_N) > 0 and mu_i != 0.0
    for l in range(len(beta_n)):
        beta[l] = _damage(g_N[l], g_T[l], beta_n[l], r_N[l] if shear else 0.0, shear, C_N, C_T, w, b, h, mu_i,
                          margin)


@njit(cache=True, error_model="numpy")
def store(links, state, g_N, g_T, C_N, C_T, beta, released):
    """Accept the damage ``state`` (n,) of the links ``links`` (n,) into beta (per link of
    the table), adding to ``released`` (J/m^2) the energy the drop frees at the
    link-frame jumps g_N (n,), g_T (n, d-1) (m): 1/2 (beta_n^2 - beta^2) Y'(g)."""
    for i in range(len(links)):
        k = links[i]
        if state[i] != beta[k]:
            released[k] += _release(beta[k], state[i], g_N[i], g_T[i], C_N, C_T)
            beta[k] = state[i]


@njit(cache=True, error_model="numpy")
def advance(links, gbar, g_mid, r_N, C_N, C_T, w, b, h, mu_i, margin, beta, released, changed):
    """trial_state at the springs' jumps gbar (n, d) (link frame, normal first, m) of the
    links ``links`` (n,), with their contact pressure r_N (n,) (Pa), accepted as store
    does with the energy at the jumps g_mid (n, d): one pass. The positions i (into links)
    whose damage changed go to changed[:count]; count is returned."""
    shear = mu_i != 0.0
    count = 0
    for i in range(len(links)):
        k = links[i]
        new = _damage(gbar[i, 0], gbar[i, 1:], beta[k], r_N[i], shear, C_N, C_T, w, b, h, mu_i, margin)
        if new != beta[k]:
            released[k] += _release(beta[k], new, g_mid[i, 0], g_mid[i, 1:], C_N, C_T)
            beta[k] = new
            changed[count] = i
            count += 1
    return count


def warm():
    """Compile the loops into numba's cache (2D and 3D jumps, with and without r_N; the
    jumps of store as columns of the link-frame jump array, as the star solver passes them)."""
    for m in (1, 2):
        for r_N in (np.zeros(0), np.ones(1)):
            trial_state(np.ones(1), np.ones((1, m)), np.ones(1), r_N, 1.0, 1.0, 0.5, 1.0, 1.0, 0.3, 1e-9,
                        np.empty(1))
        g = np.ones((1, m + 1))
        store(np.zeros(1, dtype=np.int64), np.zeros(1), g[:, 0], g[:, 1:], 1.0, 1.0, np.ones(1), np.zeros(1))
        advance(np.zeros(1, dtype=np.int64), g, g, g[:, 0], 1.0, 1.0, 0.5, 1.0, 1.0, 0.3, 1e-9, np.ones(1),
                np.zeros(1), np.zeros(1, dtype=np.int64))
