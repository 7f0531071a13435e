"""Interface models: a law bound to its parameters and its per-link state.

The laws themselves (interface/laws.py) are pure functions; a model holds what a run
needs around one: parameters from the case, the state array (one entry per owned link),
the friction coefficient, the energies, and the rule for "broken".
"""
from typing import NamedTuple

import numpy as np

from dolfrag.interface import laws

# An RCCM link never reaches beta = 0 (the traction decays like w^2 / (C_N g^3)); it is
# counted broken past 10 u0 (beta = 1/100, traction sigma_c / 1000), the criterion of
# LMGC90's example scripts (PHYSICS.md §1).
BROKEN_BETA = 1e-2


class Cohesion(NamedTuple):
    """Cohesive traction (Pa), its link-frame tangent (Pa/m) and the trial state."""
    r_N: np.ndarray
    r_T: np.ndarray
    dr_N_dg_N: np.ndarray
    dr_T_dg_T: np.ndarray
    dr_N_dg_T: np.ndarray
    dr_T_dg_N: np.ndarray
    state: np.ndarray


class Elastic:
    """Linear springs C_N, C_T (Pa/m) in tension and compression; no state, never broken."""

    def __init__(self, n_links, C_N, C_T):
        self.C_N, self.C_T, self.n_links = C_N, C_T, n_links

    def stored_energy(self, g_N, g_T):
        return laws.elastic_energy(g_N, g_T, self.C_N, self.C_T)

    def dissipated(self):
        return np.zeros(self.n_links)

    def broken(self):
        return np.zeros(self.n_links, dtype=bool)

    def damage(self):
        return np.zeros(self.n_links)


class Rccm:
    """RCCM damage (Raous-Cangemi-Cocu / Monerie) with unilateral contact and Coulomb
    friction mu (1 - beta). State: beta (n_links,), 1 sound .. 0 broken.

    C_N, C_T Pa/m; w J/m^2 (peak traction sqrt(C_N w)); b J s/m^2 (0: rate-independent);
    mu -; h s (time step, for the viscous update).
    """

    def __init__(self, n_links, C_N, C_T, w, b=0.0, mu=0.0, h=None):
        self.C_N, self.C_T, self.w, self.b, self.mu, self.h = C_N, C_T, w, b, mu, h
        self.beta = np.ones(n_links)
        self.released = np.zeros(n_links)  # J/m^2 per link, see store

    def state_at(self, links):
        return self.beta[links]

    def friction(self, beta):
        return laws.rccm_friction_coefficient(beta, self.mu)

    def cohesion(self, g_N, g_T, beta_n):
        """Traction of the step, with the damage lagged by one step: r = beta_n^2 C g
        (normal part in opening only), its tangent beta_n^2 C, and the damage the law gives
        at these jumps (the state after the step).

        Why lagged: with beta implicit, a star whose softening stiffness exceeds its mass
        term (h^2/4 w |dr/dg| > m, always the case at C = 10-100 E/h) has several solutions,
        and which one Newton finds follows round-off: 1 and 2 ranks broke 70 and 56 links
        in the same run (measured). Lagged, each star problem is monotone (unique), and the
        energy the drop beta_n -> beta frees is booked exactly (store)."""
        secant = beta_n**2
        beta = laws.rccm(g_N, g_T, beta_n, self.C_N, self.C_T, self.w, self.b, self.h)[-1]
        m = g_T.shape[1]
        zeros = np.zeros((len(beta), m))
        return Cohesion(secant * self.C_N * np.maximum(g_N, 0.0), secant[:, None] * self.C_T * g_T,
                        secant * self.C_N * (g_N > 0), secant[:, None, None] * self.C_T * np.eye(m),
                        zeros, zeros, beta)

    def store(self, links, state, valid, g_N, g_T):
        """Accept the converged state of the links (n, L) where valid (n, L); g_N (n, L),
        g_T (n, L, d-1): the link-frame jumps (g_n + g_{n+1}) / 2 (m), where the
        energy of the step is stored (solver/imex.py).

        With damage lagged by one step the traction used beta_n, so the drop to beta frees
        the elastic energy 1/2 (beta_n^2 - beta^2)(C_N <g_N>+^2 + C_T |g_T|^2): that is the
        dissipation booked (it equals w (beta_n - beta) while the link follows the envelope,
        and exceeds it when a link fails within a step)."""
        idx = links[valid]
        Y = self.C_N * np.maximum(g_N[valid], 0.0) ** 2 + self.C_T * np.sum(g_T[valid] ** 2, axis=-1)
        self.released[idx] += 0.5 * (self.beta[idx] ** 2 - state[valid] ** 2) * Y
        self.beta[idx] = state[valid]

    def stored_energy(self, g_N, g_T):
        """Elastic energy density of every link (J/m^2), at link-frame jumps g_N, g_T."""
        return laws.rccm_energy(g_N, g_T, self.beta, self.C_N, self.C_T)

    def dissipated(self):
        """Energy density released by damage so far (J/m^2), per link."""
        return self.released

    def broken(self):
        return self.beta <= BROKEN_BETA

    def damage(self):
        """1 - beta per link: 0 sound, 1 broken."""
        return 1.0 - self.beta
