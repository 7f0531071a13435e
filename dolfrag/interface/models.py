"""Interface models: a law bound to its parameters and its per-link state.

The laws themselves (interface/laws.py) are pure functions; a model holds what a run
needs around one: parameters from the case, the state array (one entry per owned link),
the friction coefficient, the energies, and the rule for "broken".
"""
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from dolfrag.interface import laws, rccm_kernel, softening_kernel

# Relative margin of the damage-threshold test of the RCCM trial states: links this close to
# their threshold go to the envelope, which decides exactly (round-off of w / beta_n
# against the law's own test w / Y' < beta_n is ~1e-16).
THRESHOLD_MARGIN = 1e-9

# An RCCM link never reaches beta = 0 (the traction decays like w^2 / (C_N g^3)); it is
# counted broken past 10 u0 (beta = 1/100, traction sigma_c / 1000), the criterion of
# LMGC90's example scripts.
BROKEN_BETA = 1e-2

_NO_PRESSURE = np.zeros(0)  # r_N not given: the whole shear drives damage


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

    STATE = ()  # what a checkpoint keeps

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


class _Model:
    """What every breakable model offers the star solvers: ``friction``, ``shift``,
    ``shear_cohesion`` and ``secants`` of link states (with the indices ``links`` of the
    links they belong to, which a model with per-link parameters reads; the others ignore
    them), ``springs`` (the traction and tangent of the secants), ``trial_state`` (the
    state the law gives at the step's jumps: the one ``store`` accepts), and the last two
    together in ``cohesion``."""

    def springs(self, g_N, g_T, state_n):
        """Traction of the step (Pa) at the link-frame jumps g_N (n,), g_T (n, d-1) (m),
        the state lagged at state_n: k_N <g_N>+ and k_T g_T with the ``secants`` (k_N, k_T)
        of state_n, their tangent, and the state state_n."""
        k_N, k_T = self.secants(state_n)
        m = g_T.shape[1]
        zeros = np.zeros((len(k_N), m))
        return Cohesion(k_N * np.maximum(g_N, 0.0), k_T[:, None] * g_T, k_N * (g_N > 0),
                        k_T[:, None, None] * np.eye(m), zeros, zeros, state_n)

    def trial_state(self, g_N, g_T, state_n, r_N=None):
        """The state after the step: unchanged by default (the rigid laws' state follows from
        the converged gap, in ``store``)."""
        return state_n

    def cohesion(self, g_N, g_T, state_n, r_N=None):
        """``springs`` with the trial state in place of state_n."""
        return self.springs(g_N, g_T, state_n)._replace(state=self.trial_state(g_N, g_T, state_n, r_N))

    def advance(self, links, gbar, g_mid, r_N, opening=None):
        """Take a step on the links ``links`` (n,): the trial state at the springs' jumps
        gbar (n, d), with the contact pressure r_N (n,) (Pa), accepted by ``store`` with the
        jumps g_mid (n, d) (link frame, m), or with ``opening`` (n, d) where the law's opening
        differs from them (g_mid less a rigid link's elastic joint: solver/active_set.py's
        COMPLIANCE). Returns the positions (into links) whose state changed."""
        before = self.state_at(links)
        self.store(links, self.trial_state(gbar[:, 0], gbar[:, 1:], before, r_N), g_mid[:, 0], g_mid[:, 1:], opening)
        return np.flatnonzero(self.state_at(links) != before)


class Rccm(_Model):
    """RCCM damage (Raous-Cangemi-Cocu / Monerie) with unilateral contact and Coulomb
    friction mu (1 - beta). State: beta (n_links,), 1 sound .. 0 broken.

    C_N, C_T Pa/m; w J/m^2 (peak traction sqrt(C_N w)); b J s/m^2 (0: rate-independent);
    mu -; h s (time step, for the viscous update); mu_i - (internal friction: the shear
    that drives damage is reduced by mu_i times the contact pressure,
    laws.mohr_coulomb_shear; 0 is the law of *Study and simulation of fragmentation
    phenomena of concrete structures under stuffy explosion*).
    """

    STATE = ("beta", "released")  # what a checkpoint keeps

    def __init__(self, n_links, C_N, C_T, w, b=0.0, mu=0.0, h=None, mu_i=0.0):
        if b > 0:  # the viscous update's own check (laws.rccm_damage), once, not every step
            laws.rccm_damage(np.zeros(1), 1.0, w, b, h)
        self.C_N, self.C_T, self.w, self.b, self.mu, self.h = C_N, C_T, w, b, mu, h
        self.mu_i = mu_i
        self.beta = np.ones(n_links)
        self.released = np.zeros(n_links)  # J/m^2 per link, see store

    def state_at(self, links):
        return self.beta[links]

    def friction(self, beta, links=None):
        return laws.rccm_friction_coefficient(beta, self.mu)

    def shift(self, beta, links=None):
        """Tension (Pa) the contact constraint itself may carry: none, the springs do."""
        return np.zeros_like(beta)

    shear_cohesion = shift

    def absorb(self, work):
        """Cohesive work of the constraint: none (no shift)."""

    def secants(self, beta_n, links=None):
        """The springs (k_N, k_T) = beta_n^2 (C_N, C_T) (Pa/m) of a step, the damage lagged
        by one step: r = beta_n^2 C g (normal part in opening only).

        Why lagged: with beta implicit, a star whose softening stiffness exceeds its mass
        term (h^2/4 w |dr/dg| > m, always the case at C = 10-100 E/h) has several solutions,
        and which one Newton finds follows round-off: 1 and 2 ranks broke 70 and 56 links
        in the same run (measured). Lagged, each star problem is monotone (unique), and the
        energy the drop beta_n -> beta frees is booked exactly (store)."""
        secant = beta_n**2
        return secant * self.C_N, secant * self.C_T

    def trial_state(self, g_N, g_T, beta_n, r_N=None):
        """The damage the law gives at these jumps (the state after the step); r_N (Pa,
        >= 0 in compression, or None): the contact pressure of the same iterate, for mu_i.
        Compiled (interface/rccm_kernel.py); threshold_trial_state is its reference."""
        flat = [np.ascontiguousarray(a, dtype=float) for a in (g_N, g_T, beta_n, _NO_PRESSURE if r_N is None else r_N)]
        beta = np.empty(len(flat[2]))
        rccm_kernel.trial_state(*flat, float(self.C_N), float(self.C_T), float(self.w), float(self.b),
                                float(self.h or 0.0), float(self.mu_i), THRESHOLD_MARGIN, beta)
        return beta

    def envelope(self, g_N, g_T, beta_n):
        """The damage the law gives at the jumps g_N, g_T from beta_n."""
        return laws.rccm_damage(self.driving_energy(g_N, g_T), beta_n, self.w, self.b, self.h)[0]

    def driving_energy(self, g_N, g_T):
        """Y' = C_N <g_N>+^2 + C_T |g_T|^2 (J/m^2) at link-frame jumps g_N (n...), g_T (n..., d-1)."""
        return self.C_N * np.maximum(g_N, 0.0) ** 2 + self.C_T * np.sum(g_T**2, axis=-1)

    def damage_threshold(self, beta_n):
        """The driving energy Y' (J/m^2) above which beta falls below beta_n: w / beta_n
        (the rate-independent envelope beta = w / Y', and the viscous law's growth
        condition beta_n Y' > w alike); inf for a broken link."""
        return np.divide(self.w, beta_n, out=np.full(np.shape(beta_n), np.inf), where=beta_n > 0)

    def store(self, links, state, g_N, g_T, opening=None):
        """Accept the converged state of the links (n,); g_N (n,), g_T (n, d-1): the
        link-frame jumps (g_n + g_{n+1}) / 2 (m), where the energy of the step is stored
        (solver/imex.py); no link of RCCM is rigid, so ``opening`` is not read.

        With damage lagged by one step the traction used beta_n, so the drop to beta frees
        the elastic energy 1/2 (beta_n^2 - beta^2)(C_N <g_N>+^2 + C_T |g_T|^2): that is the
        dissipation booked (it equals w (beta_n - beta) while the link follows the envelope,
        and exceeds it when a link fails within a step). Compiled (rccm_kernel.store)."""
        rccm_kernel.store(links, state, g_N, g_T, float(self.C_N), float(self.C_T), self.beta, self.released)

    def advance(self, links, gbar, g_mid, r_N, opening=None):
        """_Model.advance in one compiled pass (rccm_kernel.advance: trial_state and store's
        arithmetic); no link of RCCM is rigid, so ``opening`` is g_mid."""
        changed = np.empty(len(links), dtype=np.int64)
        count = rccm_kernel.advance(links, gbar, g_mid, r_N, float(self.C_N), float(self.C_T), float(self.w),
                                    float(self.b), float(self.h or 0.0), float(self.mu_i), THRESHOLD_MARGIN,
                                    self.beta, self.released, changed)
        return changed[:count]

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


def threshold_trial_state(model, g_N, g_T, beta_n, r_N=None):
    """An RCCM-type model's trial state in numpy: the damage its envelope gives at these
    jumps, as Rccm.trial_state. Only links whose driving energy Y' passes the damage
    threshold of their beta_n can damage (mu_i only lowers Y'); the envelope is evaluated
    on those alone, and decides (THRESHOLD_MARGIN keeps the test from missing one by
    round-off)."""
    may = model.driving_energy(g_N, g_T) > (1 - THRESHOLD_MARGIN) * model.damage_threshold(beta_n)
    beta = beta_n.copy()
    if may.any():
        g_N, g_T, beta_n = g_N[may], g_T[may], beta_n[may]
        drive = g_T if r_N is None or model.mu_i == 0 else laws.mohr_coulomb_shear(
            g_T, r_N[may], beta_n**2, model.C_T, model.mu_i)
        beta[may] = model.envelope(g_N, drive, beta_n)
    return beta


class RccmDecoupled(Rccm):
    """RCCM springs whose strength sigma_c (Pa) and toughness G_c (J/m^2) are independent
    of C_N (laws.rccm_decoupled, in the spirit of LMGC90's MP3_CZM): the effective traction
    rises to sigma_c, then falls linearly to zero at 2 G_c / sigma_c. Everything else
    (lagged secant, contact, friction mu (1 - beta), energy booking) is Rccm's."""

    def __init__(self, n_links, C_N, C_T, sigma_c, G_c, mu=0.0, mu_i=0.0):
        super().__init__(n_links, C_N, C_T, w=G_c, mu=mu, mu_i=mu_i)
        self.sigma_c, self.G_c = sigma_c, G_c

    def trial_state(self, g_N, g_T, beta_n, r_N=None):
        return threshold_trial_state(self, g_N, g_T, beta_n, r_N)

    advance = _Model.advance  # Rccm's compiled one is Rccm's envelope

    def envelope(self, g_N, g_T, beta_n):
        return laws.rccm_decoupled(g_N, g_T, beta_n, self.C_N, self.C_T, self.sigma_c, self.G_c)[-1]

    def damage_threshold(self, beta_n):
        """Y' = C_N delta^2 (J/m^2) where the envelope's beta equals beta_n:
        beta_n^2 C_N delta = sigma_c (delta_c - delta) / (delta_c - delta_0), laws.rccm_decoupled."""
        delta_c = laws.decoupled_parameters(self.sigma_c, self.G_c)
        delta_0 = self.sigma_c / self.C_N
        delta = self.sigma_c * delta_c / (beta_n**2 * self.C_N * (delta_c - delta_0) + self.sigma_c)
        return self.C_N * delta**2

    def broken(self):
        return self.beta <= 0.0


# A rigid link counts as opened once its mid-step jump exceeds this fraction of the law's
# length scale (W_eth, delta_c): far above the gaps the contact solve leaves (~1e-20 m,
# solver/semismooth.py) and far below any physical opening.
OPENING_TOLERANCE = 1e-9


class _Rigid(_Model):
    """Bookkeeping shared by the laws that keep a link rigid, as a constraint, until it
    opens: the star solve enforces Signorini-Coulomb shifted by the cohesion
    (interface/contact.py, ``shift`` and ``shear_cohesion``), and reports the work the
    cohesive part of the reactions did on each link (``absorb``). That work is the energy
    stored in a rigid link, released when the link opens or breaks."""

    C_N = C_T = None  # no springs while rigid

    def __init__(self, n_links, mu):
        self.mu = mu
        self.work = np.zeros(n_links)  # J/m^2: cohesive work on each rigid link
        self.released = np.zeros(n_links)

    def friction(self, state, links=None):
        return np.full(np.shape(state), float(self.mu))

    def absorb(self, work):
        """Add the work (J/m^2, per owned link) the cohesive reactions did this step: stored
        in links still rigid, released in those that opened or broke during the step (their
        state is already updated: store runs inside the step, absorb after it)."""
        rigid = self.rigid()
        self.work += np.where(rigid, work, 0.0)
        self.released += np.where(rigid, 0.0, work)

    def dissipated(self):
        return self.released


class Threshold(_Rigid):
    """The rigid threshold law of *Study and simulation of fragmentation phenomena of
    concrete structures under stuffy explosion* (laws.threshold): tension up to R_c (Pa) while the
    gap stays below W_eth (m), then broken for good; Coulomb friction mu on the cone
    shifted by R_c while cohesive, plain Coulomb after. State: 1.0 where broken, else 0.

    The cohesive work R_c g_N is stored while the link holds and lost when it breaks:
    R_c g_mid at the step the mid-step gap passes W_eth (R_c W_eth to within one step's
    opening)."""

    STATE = ("work", "released", "lost")  # what a checkpoint keeps

    def __init__(self, n_links, R_c, W_eth, mu=0.0):
        super().__init__(n_links, mu)
        self.R_c, self.W_eth = R_c, W_eth
        self.lost = np.zeros(n_links)

    def state_at(self, links):
        return self.lost[links]

    def shift(self, lost, links=None):
        return np.where(lost > 0, 0.0, self.R_c)

    def shear_cohesion(self, lost, links=None):
        return np.zeros_like(lost)

    def secants(self, lost_n, links=None):
        """No springs: the whole law is in the shifted contact constraint."""
        return np.zeros(len(lost_n)), np.zeros(len(lost_n))

    def store(self, links, state, g_N, g_T, opening=None):
        """Break the links (n,) whose mid-step gap g_N (n,), or opening[:, 0] where given
        (_Model.advance), passed W_eth (the trial ``state`` is not used: this law's state
        follows from the converged gap)."""
        gap = g_N if opening is None else opening[:, 0]
        broken = laws.threshold(gap, self.lost[links] > 0, self.R_c, self.W_eth)[1]
        newly = links[broken & (self.lost[links] == 0)]
        self.released[newly] += self.work[newly]
        self.work[newly] = 0.0
        self.lost[links] = broken

    def rigid(self):
        return self.lost == 0

    def stored_energy(self, g_N, g_T):
        return np.where(self.lost > 0, 0.0, self.work)

    def broken(self):
        return self.lost > 0

    def damage(self):
        return self.lost


def intact_friction(mu, mu_i):
    """The internal friction (-) of linear softening's intact links: mu_i, or the sliding
    friction mu where it is not given (Camacho-Ortiz's cone)."""
    return mu if mu_i is None else mu_i


class LinearSoftening(_Rigid):
    """Linear softening (laws.linear_softening, Camacho-Ortiz / Akantu): rigid until the
    link opens, with tension up to sigma_c (Pa) and shear up to a Mohr-Coulomb cone (the
    shifted cone of interface/contact.py); then secant springs S(delta_max) that
    soften linearly to zero at delta_c = 2 G_c / sigma_c (G_c J/m^2) and unload to the
    origin; Coulomb friction mu.

    The intact link's cone: |r_T| <= mu_i r_N + tau_c under the contact pressure r_N (Pa),
    mu_i (-) its internal friction and tau_c (Pa) its shear strength at zero pressure, both
    softened with the tensile strength. Without mu_i and tau_c it is Camacho-Ortiz's cone
    mu (r_N + sigma_c) + sigma_c / beta_ratio, whose uniaxial compressive strength is only a
    few sigma_c (docs/method.md, "The intact link under compression"). The cone's radius at
    the tension cut-off r_N = -sigma_c, tau_c - mu_i sigma_c, must not be negative.

    An opened link keeps its rigid constraint, with the strength softened along the law,
    sigma_c (1 - delta_max / delta_c), until its secant drops to k_open (Pa/m, scalar or
    per link; default: at once): the runner passes the step's own stiffness m / (h^2 w)
    of each link (solver/semismooth.step_stiffness), so that no spring is stiffer than the
    star problem it sits in. Measured on sound-bar with friction: links opened by 1e-10
    delta_c got shear springs 2,000 times the step's stiffness, and star Newton cycled.
    The switch opening delta_open = sigma_c / (k_open + sigma_c / delta_c) is about 4e-3
    delta_c for concrete (sigma_c = 4 MPa, G_c = 100 J/m^2, 2.5 mm cells, measured); the
    traction follows the envelope through it,
    only unloading differs (the rigid link closes at its strength instead of along the
    secant), which dissipates nothing extra once the link springs.

    The strength is per link (``sigma_c``, (n_links,)): ``set_strength`` changes it on the
    links that have not opened yet (a rate effect, interface/rate.py); an opened link keeps
    the strength it opened at, so that it dissipates G_c whatever the rate did after.
    Methods taking link states take the links they belong to (``links``: indices into the
    model's arrays, default all).

    State per link (``state_at``): delta_max (m) once on its spring, -delta_max while still
    rigid. As for RCCM the secant and the strength are lagged by one step (each star
    problem stays monotone) and the drop S_n -> S at the mid jump is booked as released
    energy; at the switch, the cohesive work done while rigid less the energy of the new
    secant is released."""

    # what a checkpoint keeps (the strengths with what follows from them)
    STATE = ("work", "released", "delta_max", "sprung", "sigma_c", "_delta_c", "_delta_open")

    def __init__(self, n_links, sigma_c, G_c, mu=0.0, beta_ratio=1.0, kappa=1.0, k_open=np.inf, mu_i=None,
                 tau_c=None):
        super().__init__(n_links, mu)
        self.G_c, self.beta_ratio, self.kappa = G_c, beta_ratio, kappa
        # the intact cone mu_i (r_N + shift) + c shift, shift = sigma_c x softening: c = tau_c / sigma_c - mu_i
        self.mu_i = intact_friction(mu, mu_i)
        self.cohesion_ratio = 1 / beta_ratio if tau_c is None else tau_c / sigma_c - self.mu_i
        self.k_open = np.broadcast_to(np.asarray(k_open, dtype=float), (n_links,))
        self.a_T = beta_ratio**2 / kappa  # the law's shear weight on the traction
        self.delta_max = np.zeros(n_links)
        self.sprung = np.zeros(n_links, dtype=bool)
        self.sigma_c = np.full(n_links, float(sigma_c))
        self._delta_c, self._delta_open = np.empty(n_links), np.empty(n_links)
        self._derive(slice(None))

    def _derive(self, links):
        """delta_c and delta_open of the links from their strengths (kept per link: the
        step reads them on every link it refreshes)."""
        sigma_c = self.sigma_c[links]
        self._delta_c[links] = delta_c = 2 * self.G_c / sigma_c
        self._delta_open[links] = np.maximum(OPENING_TOLERANCE * delta_c,
                                             sigma_c / (self.k_open[links] + sigma_c / delta_c))

    def delta_c(self, links=slice(None)):
        """Opening at full separation 2 G_c / sigma_c (m) of the links."""
        return self._delta_c[links]

    def delta_open(self, links=slice(None)):
        """Opening (m) past which the links leave their rigid constraint for their springs."""
        return self._delta_open[links]

    def set_strength(self, sigma_c, step=0.0):
        """Give the links that have not opened the strengths sigma_c (Pa, (n_links,)) where
        they differ from their current ones by more than the relative ``step``; returns the
        indices of the links whose strength changed."""
        changed = np.flatnonzero((self.delta_max == 0) & (np.abs(sigma_c - self.sigma_c) > step * self.sigma_c))
        self.sigma_c[changed] = sigma_c[changed]
        self._derive(changed)
        return changed

    def state_at(self, links):
        return np.where(self.sprung[links], self.delta_max[links], -self.delta_max[links])

    def shift(self, state, links=slice(None)):
        """The rigid links' tensile strength (Pa), softened along the law: 0 once sprung."""
        return np.where(state > 0, 0.0, self.sigma_c[links] * np.maximum(1 + state / self.delta_c(links), 0.0))

    def shear_cohesion(self, state, links=slice(None)):
        return self.shift(state, links) * self.cohesion_ratio

    def friction(self, state, links=None):
        """mu_i on the links still rigid (state <= 0), mu on those on their springs."""
        return np.where(np.asarray(state) > 0, float(self.mu), float(self.mu_i))

    def secant(self, state, links=slice(None)):
        """S(delta_max) (Pa/m): the traction factor of the law, 0 while rigid or broken."""
        delta_c = self.delta_c(links)
        inside = (state > 0) & (state < delta_c)
        return np.where(inside, self.sigma_c[links] * (1 / np.where(inside, state, 1.0) - 1 / delta_c), 0.0)

    def secants(self, state_n, links=slice(None)):
        """Secant springs (S, a_T S) (Pa/m) at the lagged state_n (none on rigid links:
        the constraint carries them)."""
        S = self.secant(state_n, links)
        return S, self.a_T * S

    def _delta(self, g_N, g_T):
        shear = self.beta_ratio**2 / self.kappa**2
        return np.sqrt(shear * np.sum(g_T**2, axis=-1) + np.maximum(g_N, 0.0) ** 2)

    def _psi(self, g_N, g_T):
        return np.maximum(g_N, 0.0) ** 2 + self.a_T * np.sum(g_T**2, axis=-1)

    def store(self, links, state, g_N, g_T, opening=None):
        """delta_max of the links (n,) from the mid-step jumps g_N (n,), g_T (n, d-1), or
        from ``opening`` (n, d) where given (_Model.advance); switch the links past
        delta_open to their springs; book the released energy at g_N, g_T (the trial
        ``state`` is not used)."""
        old, was = self.delta_max[links], self.sprung[links]
        delta = self._delta(g_N, g_T) if opening is None else self._delta(opening[:, 0], opening[:, 1:])
        new = np.where(delta > OPENING_TOLERANCE * self.delta_c(links), np.maximum(old, delta), old)
        now = was | (new > self.delta_open(links))
        switching = now & ~was
        psi = self._psi(g_N, g_T)
        S_new = self.secant(new, links)
        self.released[links] += np.where(switching, self.work[links] - 0.5 * S_new * psi,
                                         0.5 * (self.secant(old, links) - S_new) * psi * was)
        self.work[links[switching]] = 0.0
        self.delta_max[links] = new
        self.sprung[links] = now

    def advance(self, links, gbar, g_mid, r_N, opening=None):
        """_Model.advance in one compiled pass (softening_kernel.advance: store's arithmetic;
        the trial state is the state before, which store does not read)."""
        changed = np.empty(len(links), dtype=np.int64)
        count = softening_kernel.advance(links, g_mid if opening is None else opening, g_mid,
                                         self.beta_ratio**2 / self.kappa**2, float(self.a_T),
                                         OPENING_TOLERANCE, self.sigma_c, self._delta_c, self._delta_open,
                                         self.delta_max, self.sprung, self.work, self.released, changed)
        return changed[:count]

    def rigid(self):
        return ~self.sprung

    def stored_energy(self, g_N, g_T):
        return np.where(self.rigid(), self.work, 0.5 * self.secant(self.delta_max) * self._psi(g_N, g_T))

    def broken(self):
        return self.delta_max >= self.delta_c()

    def damage(self):
        """delta_max / delta_c, clipped to 1: 0 intact, 1 broken."""
        return np.minimum(self.delta_max / self.delta_c(), 1.0)


def _no_rules(interface, C_N):
    """A law whose keys need no rule between them."""
    return None


def _rccm_rules(interface, C_N):
    """RCCM's peak: sigma_c (then w = sigma_c^2 / C_N) or w, exactly one."""
    if (interface.sigma_c is None) == (interface.w is None):
        return (f"interface.sigma_c = {interface.sigma_c!r}, interface.w = {interface.w!r}: "
                "rccm needs exactly one of them (Pa, J/m^2)")
    return None


def _strength_rule(interface, C_N):
    """A law that takes its strength sigma_c (Pa) as given needs it."""
    if interface.sigma_c is None:
        return f"interface.sigma_c: missing (required when interface.law is {interface.law!r}), Pa"
    return None


def _softening_rules(interface, C_N):
    """linear_softening's sigma_c, and an intact cone whose radius at the tension cut-off,
    tau_c - mu_i sigma_c, is not negative."""
    missing = _strength_rule(interface, C_N)
    if missing or interface.tau_c is None:
        return missing
    mu_i = intact_friction(interface.mu, interface.mu_i)
    if interface.tau_c >= mu_i * interface.sigma_c:
        return None
    return (f"interface.tau_c = {interface.tau_c!r}: linear_softening needs tau_c >= mu_i sigma_c = "
            f"{mu_i * interface.sigma_c:.6g} Pa (mu_i = {mu_i!r}, sigma_c = {interface.sigma_c!r} Pa), "
            "so that the intact shear cone keeps a radius at the tension cut-off")


def _decoupled_rules(interface, C_N):
    """rccm_decoupled's sigma_c, and springs C_N (Pa/m) stiff enough that the elastic energy at
    the peak, sigma_c^2 / (2 C_N), stays below G_c (J/m^2): the softening branch needs the rest."""
    missing = _strength_rule(interface, C_N)
    if missing or C_N > interface.sigma_c**2 / (2 * interface.G_c):
        return missing
    return (f"interface.G_c = {interface.G_c!r}: rccm_decoupled needs C_N > sigma_c^2 / "
            f"(2 G_c), i.e. G_c > {interface.sigma_c**2 / (2 * C_N):.3g} J/m^2 with C_N = "
            f"{C_N:.3g} Pa/m (or raise interface.C_N / stiffness_ratio)")


@dataclass(frozen=True, kw_only=True)
class Law:
    """One interface law of the case's ``interface.law``: how to build its model, the
    [interface] keys it reads, the rules between them, and what the rest of the code may
    ask of it. Adding a law is adding its entry to LAWS.

    build(interface, n_links, C_N, C_T, h, k_step): the model (interface: case.Interface;
    C_N, C_T Pa/m from the stiffness rule; h s the time step; k_step Pa/m per link, the
    step's own stiffness, solver/semismooth.step_stiffness). keys: the law's own
    [interface] keys (beyond law and the stiffness keys every law has), allowed only with
    it. rules(interface, C_N): what is wrong with the keys as given (one line naming them),
    or None; C_N (Pa/m) the normal stiffness of the stiffness rule. Flags: breakable: links
    can break; rigid: links are constraints until they open (no springs, C_N and C_T
    unused); springs: linear springs everywhere, no contact, stepped by star blocks
    inverted once (imex cannot prescribe velocities through them); theta: available with
    the theta scheme.
    """
    build: Callable
    keys: tuple = ()
    rules: Callable = _no_rules
    breakable: bool
    rigid: bool = False
    springs: bool = False
    theta: bool

    def tensile_strength(self, interface, C_N):
        """Peak tensile traction (Pa) of this law with normal stiffness C_N (Pa/m): R_c of a
        threshold, sigma_c, or sqrt(C_N w) for RCCM given w; None without one (elastic)."""
        if self.springs:
            return None
        if interface.R_c is not None:
            return interface.R_c
        if interface.sigma_c is None:
            return float(np.sqrt(C_N * interface.w))
        return interface.sigma_c


LAWS = {
    "elastic": Law(build=lambda i, n, C_N, C_T, h, k: Elastic(n, C_N, C_T),
                   breakable=False, springs=True, theta=True),
    "rccm": Law(build=lambda i, n, C_N, C_T, h, k: Rccm(n, C_N, C_T, i.adhesion_energy(C_N), i.b, i.mu, h,
                                                        i.mu_i or 0.0),
                keys=("sigma_c", "w", "b", "mu", "mu_i"), rules=_rccm_rules, breakable=True, theta=True),
    "rccm_decoupled": Law(build=lambda i, n, C_N, C_T, h, k: RccmDecoupled(n, C_N, C_T, i.sigma_c, i.G_c, i.mu,
                                                                           i.mu_i or 0.0),
                          keys=("sigma_c", "G_c", "mu", "mu_i"), rules=_decoupled_rules, breakable=True, theta=True),
    "threshold": Law(build=lambda i, n, C_N, C_T, h, k: Threshold(n, i.R_c, i.W_eth, i.mu),
                     keys=("R_c", "W_eth", "mu"), breakable=True, rigid=True, theta=False),
    "linear_softening": Law(build=lambda i, n, C_N, C_T, h, k: LinearSoftening(n, i.sigma_c, i.G_c, i.mu, k_open=k,
                                                                               mu_i=i.mu_i, tau_c=i.tau_c),
                            keys=("sigma_c", "G_c", "mu", "mu_i", "tau_c", "rate_effect"), rules=_softening_rules,
                            breakable=True, rigid=True, theta=False),
}


def owning(key):
    """("law", names...): the `when` condition of the [interface] ``key``, the laws of LAWS
    whose keys hold it, in LAWS' order; asked when a case is read, so that a law added to
    LAWS brings its keys."""
    return ("law", *(name for name, entry in LAWS.items() if key in entry.keys))


def law(interface):
    """The Law of ``interface`` (case.Interface)."""
    return LAWS[interface.law]


def build(interface, E, size, n_links, h, k_step=np.inf):
    """The model of ``interface`` (case.Interface) on n_links links, its springs by the
    stiffness rule of E (Pa) and the mesh size (m); h (s) the time step (viscous RCCM);
    k_step (Pa/m, per link) the step's own stiffness, where linear softening leaves its
    rigid constraint."""
    C_N, C_T = interface.stiffness(E, size)
    return law(interface).build(interface, n_links, C_N, C_T, h, k_step)
