"""The linear-softening law's step (models.LinearSoftening.store), compiled: one loop over
the links.

The same arithmetic, operation for operation, as the numpy reference (LinearSoftening.store
and secant, which the tests hold it to, bit for bit): those cost ~25 numpy calls over every
link of the rank each step, 3.7 ms of a 19 ms step on a 3D bar of 9,555 tetrahedra whose
stars were held rigid (measured with cProfile).
"""
import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy", inline="always")
def _secant(state, sigma_c, delta_c):
    """S(delta_max) (Pa/m) of one link: LinearSoftening.secant."""
    if 0 < state < delta_c:
        return sigma_c * (1 / state - 1 / delta_c)
    return 0.0


@njit(cache=True, error_model="numpy")
def advance(links, opening, g_mid, shear, a_T, tolerance, sigma_c, delta_c, delta_open, delta_max, sprung, work,
            released, changed):
    """LinearSoftening.store on the links ``links`` (n,) at their mid-step jumps g_mid (n, d)
    (link frame, m), their opening read at ``opening`` (n, d) (m: g_mid less a rigid link's
    elastic joint), in place on the model's per-link arrays (sigma_c Pa, delta_c and
    delta_open m: read; delta_max m, sprung bool, work and released J/m^2: updated); shear
    = beta_ratio^2 / kappa^2 and a_T the law's weights of the tangential jump in the opening
    and in the energy; tolerance = OPENING_TOLERANCE. Writes into ``changed`` the positions
    (into links) whose state (delta_max, signed by sprung) changed and returns their count."""
    count = 0
    for i in range(len(links)):
        l = links[i]
        old, was = delta_max[l], sprung[l]
        sliding, opened = 0.0, 0.0
        for k in range(1, g_mid.shape[1]):
            sliding += g_mid[i, k] ** 2
            opened += opening[i, k] ** 2
        delta = np.sqrt(shear * opened + max(opening[i, 0], 0.0) ** 2)
        new = max(old, delta) if delta > tolerance * delta_c[l] else old
        now = was or new > delta_open[l]
        psi = max(g_mid[i, 0], 0.0) ** 2 + a_T * sliding
        S_new = _secant(new, sigma_c[l], delta_c[l])
        if now and not was:
            released[l] += work[l] - 0.5 * S_new * psi
            work[l] = 0.0
        else:
            released[l] += 0.5 * (_secant(old, sigma_c[l], delta_c[l]) - S_new) * psi * was
        delta_max[l], sprung[l] = new, now
        if (new if now else -new) != (old if was else -old):
            changed[count] = i
            count += 1
    return count


def warm():
    """Compile the loop into numba's cache (2D and 3D jumps, as the star solver passes them)."""
    for d in (2, 3):
        one = np.ones(1)
        advance(np.zeros(1, dtype=np.int64), np.ones((1, d)), np.ones((1, d)), 1.0, 1.0, 1e-9, one, one, one, np.zeros(1),
                np.zeros(1, dtype=np.bool_), np.zeros(1), np.zeros(1), np.zeros(1, dtype=np.int64))
