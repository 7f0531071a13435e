"""Interface laws in 0D: closed-form peaks and works, irreversibility, consistent tangents,
and the Alart-Curnier projections (docs/method.md, "Interface laws"). No mesh, no MPI."""
import numpy as np
import pytest

from dolfrag.interface import contact, laws

EPS = np.finfo(float).eps
SIGMA_C = 4e6          # Pa
C_N = 7e13             # Pa/m, 10 E / h with E = 35 GPa, h = 5 mm
C_T = 3e13             # Pa/m, != C_N so that a swapped stiffness shows
W = SIGMA_C**2 / C_N   # J/m^2, the reference paper's coupling
U0 = np.sqrt(W / C_N)  # m, opening at the RCCM peak
G_C = 100.0            # J/m^2


def rccm_step(C_N=C_N, C_T=C_T, w=W, b=0.0):
    return lambda g_N, g_T, beta, h=None: laws.rccm(g_N, g_T, beta, C_N, C_T, w, b=b, h=h)


def mode_I(g, n=1, m=1):
    """Histories (n_steps, n) and (n_steps, n, m) of a pure opening g (n_steps,) or (n_steps, n)."""
    g_N = np.broadcast_to(np.asarray(g, dtype=float).reshape(len(g), -1), (len(g), n))
    return g_N, np.zeros((len(g), n, m))


def work(r, g):
    """Trapezoidal work of the traction history r (n_steps, n) along g (n_steps[, n])."""
    g = np.asarray(g).reshape(len(g), -1)
    return np.sum(0.5 * (r[1:] + r[:-1]) * np.diff(g, axis=0), axis=0)


# ---------------------------------------------------------------- RCCM, rate-independent

def test_rccm_peak_traction_is_sqrt_CN_w():
    C_N_ = np.array([7e13, 1e12, 3e14])
    sigma_c = np.array([4e6, 21e6, 1e6])
    w = laws.rccm_parameters(sigma_c, C_N_)
    u0 = np.sqrt(w / C_N_)
    k = np.arange(3001) / 1000  # k[1000] == 1.0 exactly, so u0 is sampled
    g_N, g_T = mode_I(k[:, None] * u0, n=3)
    r_N, r_T, beta = laws.drive(rccm_step(C_N=C_N_, w=w), g_N, g_T, np.ones(3))
    # the sample at u0 is C_N u0 up to a few roundings of sqrt and products
    assert np.allclose(r_N.max(axis=0), np.sqrt(C_N_ * w), rtol=1e-12, atol=0)
    assert np.allclose(r_N.max(axis=0), sigma_c, rtol=1e-12, atol=0)
    assert np.all(np.argmax(r_N, axis=0) == 1000)
    assert np.all(r_T == 0) and np.all(np.diff(beta, axis=0) <= 0)


@pytest.mark.parametrize("m", [1, 2])
def test_rccm_mode_II_peak_traction_is_sqrt_CT_w(m):
    direction = np.array([1.0]) if m == 1 else np.array([0.6, -0.8])
    s = np.sqrt(W / C_T) * np.arange(3001) / 1000  # s[1000] is the mode II peak opening
    g_T = s[:, None, None] * direction
    g_N = np.zeros((len(s), 1))
    r_N, r_T, _ = laws.drive(rccm_step(), g_N, g_T, np.ones(1))
    tau = np.linalg.norm(r_T, axis=-1)[:, 0]
    assert np.all(r_N == 0)
    assert tau.max() == pytest.approx(np.sqrt(C_T * W), rel=1e-12)  # roundings only
    assert np.argmax(tau) == 1000


def test_rccm_work_to_separation_is_w():
    works = []
    for n_soft in (5000, 10000):
        g = U0 * np.concatenate([np.linspace(0, 1, 101), np.geomspace(1, 1000, n_soft)[1:]])
        r_N, _, beta = laws.drive(rccm_step(), *mode_I(g), np.ones(1))
        works.append(work(r_N, g)[0])
    # beyond 1000 u0 the traction w^2 / (C_N g^3) still does w^2 / (2 C_N g^2) = w/2 * 1e-6
    expected = W - 0.5 * W * (U0 / g[-1]) ** 2
    # trapezoid: exact on the linear branch; on w^2/(C_N g^3) with grid ratio q it
    # overestimates by ~(q - 1)^2 w / 2 (2.4e-7 w for 10^4 points): Richardson removes
    # it, leaving O((q - 1)^4) ~ 1e-13 w, far below the 5e-7 w tail
    assert (4 * works[1] - works[0]) / 3 == pytest.approx(expected, rel=1e-9)
    # along the whole path, work = stored + w (1 - beta), to the 2.4e-7 w trapezoid error
    so_far = np.concatenate([[0.0], np.cumsum(0.5 * (r_N[1:, 0] + r_N[:-1, 0]) * np.diff(g))])
    stored = laws.rccm_energy(g, np.zeros((len(g), 1)), beta[:, 0], C_N, C_T)
    assert np.allclose(so_far, stored + laws.rccm_dissipation(beta[:, 0], W), rtol=0,
                       atol=1e-6 * W)


def test_rccm_unloading_and_reloading_follow_the_damaged_secant():
    g = U0 * np.concatenate([np.linspace(0, 2, 201), np.linspace(2, -1, 301)[1:],
                             np.linspace(-1, 3, 401)[1:]])
    r_N, _, beta = laws.drive(rccm_step(), *mode_I(g), np.ones(1))
    r_N, beta = r_N[:, 0], beta[:, 0]
    peak = 200
    beta_2 = W / (C_N * (2 * U0) ** 2)  # = 1/4 on the envelope at 2 u0
    assert beta[peak] == pytest.approx(beta_2, rel=1e-12)
    inside = np.arange(peak, 800)  # g[800] = 2 u0 on reloading, up to rounding
    assert np.all(beta[inside] == beta[peak])  # irreversible: frozen until 2 u0 again
    assert np.allclose(r_N[inside], beta[peak] ** 2 * C_N * np.maximum(g[inside], 0),
                       rtol=1e-12, atol=1e-12 * SIGMA_C)
    beyond = g > 2 * U0 * (1 + 1e-9)
    assert np.allclose(r_N[beyond], W**2 / (C_N * g[beyond] ** 3), rtol=1e-12, atol=0)


def test_rccm_compression_carries_no_cohesive_normal_traction():
    g_N = -U0 * np.array([0.5, 10.0, 1e3])
    g_T = 0.5 * np.sqrt(W / C_T) * np.ones((3, 1))  # C_T |g_T|^2 = w / 4: no damage
    r_N, r_T, dN_dN, _, dN_dT, _, beta = laws.rccm(g_N, g_T, np.ones(3), C_N, C_T, W)
    assert np.all(r_N == 0) and np.all(dN_dN == 0) and np.all(dN_dT == 0)
    assert np.all(beta == 1)  # compression never damages
    assert np.allclose(r_T, C_T * g_T, rtol=1e-15)


# ---------------------------------------------------------------- RCCM, viscous

def viscous_peak_and_work(kappa, du):
    """Peak / sqrt(C_N w) and work / w at a constant opening rate, for each kappa."""
    rate = 1.0  # m/s; only kappa = b rate sqrt(C_N) / w^1.5 matters
    b = np.asarray(kappa) * W**1.5 / (rate * np.sqrt(C_N))
    n_soft = int(round(10 / du))
    g = U0 * np.concatenate([np.arange(0, 20 + du / 2, du), np.geomspace(20, 2e4, n_soft)[1:]])
    h = np.diff(g / rate, prepend=0.0)
    r_N, _, _ = laws.drive(rccm_step(b=b), *mode_I(g, n=len(b)), np.ones(len(b)), h)
    return r_N.max(axis=0) / np.sqrt(C_N * W), work(r_N, g[:, None]) / W


def test_rccm_viscous_peak_and_work_follow_the_kappa_table():
    """docs/method.md, "Interface laws": kappa = b u' sqrt(C_N) / w^1.5 -> (peak ratio, work ratio)."""
    kappa = np.array([0.0, 0.1, 1.0, 10.0])
    table_peak = np.array([1.0, 1.01, 1.11, 1.55])
    table_work = np.array([1.0, 1.07, 1.51, 3.7])
    coarse = viscous_peak_and_work(kappa, 0.005)
    fine = viscous_peak_and_work(kappa, 0.0025)
    # LMGC90's implicit beta update is first order in h: Richardson-extrapolate; the change
    # fine - coarse (< 2e-3 here) bounds the remaining step error. Extrapolated values:
    # peaks 1.013, 1.108, 1.549 and works 1.073, 1.515, 3.717 for kappa = 0.1, 1, 10
    peak, work_ = (2 * f - c for f, c in zip(fine, coarse))
    assert np.all(np.abs(fine[0] - coarse[0]) < 2e-3)
    # table values are rounded to 2 decimals (0.005), the last work entry to 0.05
    assert np.allclose(peak, table_peak, rtol=0, atol=0.005 + 1e-3)
    assert np.allclose(work_, table_work, rtol=0, atol=np.array([1e-3, 6e-3, 6e-3, 0.05]))
    assert np.all(np.diff(peak) > 0) and np.all(np.diff(work_) > 0)  # rate strengthening


def test_rccm_viscous_damage_is_irreversible_on_unloading():
    g = U0 * np.concatenate([np.linspace(0, 3, 301), np.linspace(3, 0, 301)[1:]])
    h = np.abs(np.diff(g, prepend=0.0))  # |opening rate| 1 m/s, kappa = 1
    _, _, beta = laws.drive(rccm_step(b=W**1.5 / np.sqrt(C_N)), *mode_I(g), np.ones(1), h)
    beta = beta[:, 0]
    assert np.all(np.diff(beta) <= 0)  # never heals
    # damage lags the opening: it keeps growing after the largest opening while
    # beta Y' > w, and freezes exactly once the driving force has dropped below w
    assert beta[-1] < beta[300] < 1
    frozen = beta[:-1] * C_N * g[1:] ** 2 < W
    assert frozen[300:].any() and np.all(beta[1:][frozen] == beta[:-1][frozen])


# ---------------------------------------------------------------- consistent tangents

def _scaled_jumps(rng, n, m, target, energy):
    """Random jumps (half opening, half closing) scaled so that energy(g_N, g_T) = target."""
    g_N = rng.uniform(0.3, 1.0, n) * np.where(np.arange(n) % 2, 1.0, -1.0)
    g_T = rng.uniform(-1.0, 1.0, (n, m))
    scale = np.sqrt(target / energy(g_N, g_T))
    return g_N * scale, g_T * scale[:, None]


def _rccm_case(rng, n, m, regime, viscous=False):
    Y = lambda g_N, g_T: C_N * np.maximum(g_N, 0) ** 2 + C_T * np.sum(g_T**2, -1)
    beta_n = {"elastic": np.ones(n), "damaging": rng.uniform(0.5, 1.0, n),
              "unloading": rng.uniform(0.2, 0.8, n)}[regime]
    ratio = {"elastic": (0.2, 0.8), "damaging": (1.5, 5.0), "unloading": (0.2, 0.7)}[regime]
    g_N, g_T = _scaled_jumps(rng, n, m, rng.uniform(*ratio, n) * W / beta_n, Y)
    if viscous:  # kappa ~ 1 at an opening rate of 1 m/s, step 1e-3 u0 / (1 m/s)
        return g_N, g_T, lambda gN, gT: laws.rccm(gN, gT, beta_n, C_N, C_T, W,
                                                  b=W**1.5 / np.sqrt(C_N), h=1e-3 * U0)
    return g_N, g_T, lambda gN, gT: laws.rccm(gN, gT, beta_n, C_N, C_T, W)


def _decoupled_case(rng, n, m, regime):
    d0, dc = SIGMA_C / C_N, 2 * G_C / SIGMA_C
    Y = lambda g_N, g_T: C_N * np.maximum(g_N, 0) ** 2 + C_T * np.sum(g_T**2, -1)
    beta_n = np.ones(n)
    delta = {"elastic": rng.uniform(0.1, 0.8, n) * d0,
             "damaging": rng.uniform(1.2 * d0, 0.9 * dc, n),
             "unloading": rng.uniform(0.2, 0.8, n) * 0.5 * dc}[regime]
    if regime == "unloading":  # damaged at 0.5 delta_c, now below it
        beta_n = laws.rccm_decoupled(np.full(n, 0.5 * dc), np.zeros((n, m)), beta_n,
                                     C_N, C_T, SIGMA_C, G_C)[-1]
    g_N, g_T = _scaled_jumps(rng, n, m, C_N * delta**2, Y)
    return g_N, g_T, lambda gN, gT: laws.rccm_decoupled(gN, gT, beta_n, C_N, C_T, SIGMA_C, G_C)


def _softening_case(rng, n, m, regime):
    beta_ratio, kappa = 1.3, 2.0
    dc = 2 * G_C / SIGMA_C
    delta_fn = lambda g_N, g_T: (np.maximum(g_N, 0) ** 2
                                 + (beta_ratio / kappa) ** 2 * np.sum(g_T**2, -1))
    delta = {"elastic": rng.uniform(1.05, 2.0, n) * dc,  # broken: no traction
             "damaging": rng.uniform(0.1, 0.9, n) * dc,
             "unloading": rng.uniform(0.1, 0.8, n) * 0.9 * dc}[regime]
    delta_max = {"elastic": 1.1 * dc * np.ones(n), "damaging": 0.5 * delta,
                 "unloading": 0.9 * dc * np.ones(n)}[regime]
    g_N, g_T = _scaled_jumps(rng, n, m, delta**2, delta_fn)
    return g_N, g_T, lambda gN, gT: laws.linear_softening(gN, gT, delta_max, SIGMA_C, G_C,
                                                          beta_ratio, kappa)


def _jacobian(out):
    """(n, d, d) d(r_N, r_T)/d(g_N, g_T) from a law's tangent tuple."""
    _, _, dN_dN, dT_dT, dN_dT, dT_dN = out[:6]
    top = np.concatenate([dN_dN[:, None], dN_dT], axis=1)[:, None, :]
    bottom = np.concatenate([dT_dN[:, :, None], dT_dT], axis=2)
    return np.concatenate([top, bottom], axis=1)


CASES = {"rccm": _rccm_case, "rccm_viscous": lambda *a: _rccm_case(*a, viscous=True),
         "rccm_decoupled": _decoupled_case, "linear_softening": _softening_case}


@pytest.mark.parametrize("law", list(CASES))
@pytest.mark.parametrize("regime", ["elastic", "damaging", "unloading"])
@pytest.mark.parametrize("d", [2, 3])
def test_tangent_is_the_central_difference_of_the_traction(law, regime, d):
    rng = np.random.default_rng(17 * d + len(regime) + len(law))
    n, m = 40, d - 1
    g_N, g_T, law_at = CASES[law](rng, n, m, regime)
    J = _jacobian(law_at(g_N, g_T))
    g = np.concatenate([g_N[:, None], g_T], axis=1)
    step = 1e-6 * np.linalg.norm(g, axis=1)  # regimes have >= 10 % margins, far beyond
    J_fd = np.empty_like(J)
    for j in range(d):
        jumps = []
        for sign in (1, -1):
            gp = g.copy()
            gp[:, j] += sign * step
            r_N, r_T = law_at(gp[:, 0], gp[:, 1:])[:2]
            jumps.append(np.concatenate([r_N[:, None], r_T], axis=1))
        J_fd[:, :, j] = (jumps[0] - jumps[1]) / (2 * step[:, None])
    # central differences: truncation ~ step^2 = 1e-12, roundoff ~ eps / 1e-6 = 2e-10 of
    # |r| / |g| ~ |J|; relative 1e-6 leaves a wide margin yet catches any missing term
    scale = np.maximum(np.abs(J).max(axis=(1, 2)), 1e-300)
    assert np.all(np.abs(J_fd - J).max(axis=(1, 2)) <= 1e-6 * scale)
    if regime == "damaging" and law != "rccm_viscous":
        assert np.all(np.linalg.eigvalsh(0.5 * (J + J.transpose(0, 2, 1)))[g_N > 0, 0] < 0)


# ---------------------------------------------------------------- decoupled RCCM

@pytest.mark.parametrize("C_N_", [7e13, 7e11])
def test_rccm_decoupled_peak_is_sigma_c_and_work_is_G_c_whatever_C_N(C_N_):
    d0, dc = SIGMA_C / C_N_, laws.decoupled_parameters(SIGMA_C, G_C)
    # nodes at delta_0 and delta_c: the traction is linear between them, so the
    # trapezoid is exact up to roundoff
    g = np.concatenate([np.linspace(0, d0, 101), np.linspace(d0, dc, 1001)[1:],
                        np.linspace(dc, 1.5 * dc, 11)[1:]])
    step = lambda g_N, g_T, beta: laws.rccm_decoupled(g_N, g_T, beta, C_N_, C_T, SIGMA_C, G_C)
    r_N, _, beta = laws.drive(step, *mode_I(g), np.ones(1))
    assert r_N.max() == pytest.approx(SIGMA_C, rel=1e-12)
    assert np.argmax(r_N[:, 0]) == 100
    assert work(r_N, g)[0] == pytest.approx(G_C, rel=1e-10)
    assert beta[-1, 0] == 0
    mid = 600  # halfway down the softening branch: work = stored + dissipated
    stored = laws.rccm_energy(g[mid:mid + 1], np.zeros((1, 1)), beta[mid], C_N_, C_T)
    dissipated = laws.rccm_decoupled_dissipation(beta[mid], C_N_, SIGMA_C, G_C)
    assert (stored + dissipated)[0] == pytest.approx(work(r_N[:mid + 1], g[:mid + 1])[0],
                                                     rel=1e-10)
    tau_peak = np.sqrt(C_T / C_N_) * SIGMA_C  # mode II: delta = sqrt(C_T / C_N) |g_T|
    s = np.sqrt(C_N_ / C_T) * d0 * np.arange(201) / 100
    _, r_T, _ = laws.drive(step, np.zeros((201, 1)), s[:, None, None], np.ones(1))
    assert np.abs(r_T).max() == pytest.approx(tau_peak, rel=1e-12)


def test_rccm_decoupled_rejects_C_N_below_sigma_c_squared_over_2_G_c():
    with pytest.raises(ValueError):
        laws.rccm_decoupled(np.ones(1), np.zeros((1, 1)), np.ones(1),
                            0.5 * SIGMA_C**2 / (2 * G_C), C_T, SIGMA_C, G_C)


# ---------------------------------------------------------------- linear softening

def softening_step(beta_ratio=1.0, kappa=1.0):
    return lambda g_N, g_T, dmax: laws.linear_softening(g_N, g_T, dmax, SIGMA_C, G_C,
                                                        beta_ratio, kappa)


def midpoint_work(step, g_N, g_T):
    """Exact work along a path on which the law is linear between nodes: drive the nodes,
    evaluate the traction at each midpoint with the state reached at the segment start."""
    _, _, dmax = laws.drive(step, g_N, g_T, np.zeros(g_N.shape[1]))
    state = dmax[:-1]
    mN, mT = 0.5 * (g_N[1:] + g_N[:-1]), 0.5 * (g_T[1:] + g_T[:-1])
    r_N, r_T = step(mN.ravel(), mT.reshape(-1, mT.shape[-1]), state.ravel())[:2]
    return (np.sum(r_N * np.diff(g_N, axis=0).ravel())
            + np.sum(r_T * np.diff(g_T, axis=0).reshape(r_T.shape)))


def test_linear_softening_peak_is_sigma_c():
    dc = 2 * G_C / SIGMA_C
    g = dc * np.arange(1, 1001) / 1000
    r_N, _, _ = laws.drive(softening_step(), *mode_I(g), np.zeros(1))
    # envelope sigma_c (1 - delta / delta_c), first sample at delta_c / 1000
    assert r_N.max() == pytest.approx(SIGMA_C * (1 - 1e-3), rel=1e-12)
    assert r_N[-1, 0] == 0


@pytest.mark.parametrize("kappa", [1.0, 2.5])
def test_linear_softening_work_to_separation_is_G_c_in_mode_I_and_kappa_G_c_in_mode_II(kappa):
    dc = 2 * G_C / SIGMA_C
    g = dc * np.linspace(0, 1.2, 1201)
    assert midpoint_work(softening_step(), *mode_I(g)) == pytest.approx(G_C, rel=1e-12)
    beta_ratio = 1.7
    s = kappa / beta_ratio * g  # delta = beta_ratio |g_T| / kappa
    wII = midpoint_work(softening_step(beta_ratio, kappa), np.zeros((len(s), 1)),
                        s[:, None, None])
    assert wII == pytest.approx(kappa * G_C, rel=1e-12)  # kappa = G_cII / G_cI


def test_linear_softening_dissipation_is_the_path_work_after_unloading():
    dc = 2 * G_C / SIGMA_C
    g = dc * np.concatenate([np.linspace(0, 0.4, 401), np.linspace(0.4, 0, 401)[1:]])
    wk = midpoint_work(softening_step(), *mode_I(g))
    # the path is piecewise linear in g between nodes: the midpoint sum is exact
    assert wk == pytest.approx(laws.linear_softening_dissipation(0.4 * dc, SIGMA_C, G_C),
                               rel=1e-12)
    assert wk == pytest.approx(SIGMA_C * 0.4 * dc / 2, rel=1e-12)
    assert laws.linear_softening_dissipation(2 * dc, SIGMA_C, G_C) == pytest.approx(G_C)


def test_linear_softening_unloads_linearly_to_the_origin_and_stays_broken():
    dc = 2 * G_C / SIGMA_C
    g = dc * np.concatenate([np.linspace(0, 0.4, 41)[1:], np.linspace(0.4, -0.2, 61)[1:],
                             np.linspace(-0.2, 1.1, 131)[1:], np.linspace(1.1, 0.3, 9)[1:]])
    r_N, _, dmax = laws.drive(softening_step(), *mode_I(g), np.zeros(1))
    r_N, dmax = r_N[:, 0], dmax[:, 0]
    back = slice(40, 40 + 60 + 60)  # unloading, closing and reloading up to 0.4 delta_c
    secant = SIGMA_C * (1 - 0.4) / (0.4 * dc)
    assert np.allclose(r_N[back], secant * np.maximum(g[back], 0), rtol=1e-12,
                       atol=1e-12 * SIGMA_C)
    assert np.all(r_N[g < 0] == 0)
    assert np.all(r_N[g >= dc] == 0) and np.all(r_N[-8:] == 0)  # closing after failure
    assert dmax[-1] == pytest.approx(1.1 * dc)


# ---------------------------------------------------------------- threshold

def test_threshold_breaks_once_g_N_exceeds_W_eth_and_never_heals():
    R_c, W_eth = 2e6, 1e-5
    g = np.array([-1e-3, 0.0, 0.5 * W_eth, W_eth, np.nextafter(W_eth, 1.0), 1.0])
    cohesion, broken = laws.threshold(g, np.zeros(6, bool), R_c, W_eth)
    assert broken.tolist() == [False, False, False, False, True, True]
    assert np.array_equal(cohesion, np.where(broken, 0.0, R_c))
    cohesion, broken_again = laws.threshold(np.full(6, -1e-3), broken, R_c, W_eth)
    assert np.array_equal(broken_again, broken) and np.all(cohesion[broken] == 0)


def test_threshold_dissipates_R_c_W_eth():
    R_c, W_eth = 2e6, 1e-5

    def step(g_N, g_T, broken):
        # an opening intact link sits on the open branch of the shifted Signorini,
        # r_N = -cohesion: its tension is the cohesion (rectangular curve)
        cohesion, broken = laws.threshold(g_N, broken, R_c, W_eth)
        return cohesion * (g_N > 0), np.zeros_like(g_T), broken

    g = W_eth * np.linspace(0, 2, 201)  # node 100 is W_eth
    g_N, g_T = mode_I(g)
    _, _, broken = laws.drive(step, g_N, g_T, np.zeros(1, bool))
    mid = 0.5 * (g[1:] + g[:-1])
    r_mid = step(mid, np.zeros((len(mid), 1)), broken[:-1, 0])[0]  # state at segment start
    assert np.sum(r_mid * np.diff(g)) == pytest.approx(R_c * W_eth, rel=1e-12)
    assert laws.threshold_dissipation(broken[-1], R_c, W_eth)[0] == R_c * W_eth
    assert laws.threshold_dissipation(broken[50], R_c, W_eth)[0] == 0


# ---------------------------------------------------------------- contact projections

def _complementary_states(rng, n, m):
    """n states per kind (open, stick, slip) satisfying shifted Signorini-Coulomb."""
    shift = np.where(rng.random(3 * n) < 0.5, 2e6, 0.0)
    mu = rng.uniform(0.2, 0.8, 3 * n)
    direction = rng.normal(size=(3 * n, m))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    press = rng.uniform(0.1, 10.0, 3 * n) * 1e6  # r_N + shift > 0 in contact
    o, k, s = slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n)
    r_N = press - shift
    r_N[o] = -shift[o]
    g_N = np.zeros(3 * n)
    g_N[o] = rng.uniform(1e-9, 1e-5, n)
    v = rng.uniform(1e-9, 1e-5, (3 * n, 1)) * direction
    v[k] = 0.0
    r_T = np.zeros((3 * n, m))
    r_T[k] = (rng.uniform(0, 0.99, n) * mu[k] * press[k])[:, None] * direction[k]
    r_T[s] = -(mu[s] * press[s])[:, None] * direction[s]  # opposes the slip, on the cone
    return r_N, r_T, g_N, v, mu, shift


@pytest.mark.parametrize("d", [2, 3])
def test_projection_residuals_vanish_exactly_on_complementarity_states(d):
    rng = np.random.default_rng(d)
    n = 50
    r_N, r_T, g_N, v, mu, shift = _complementary_states(rng, n, d - 1)
    phi_N, phi_T, _, status = contact.contact_friction_projection(
        r_N, r_T, g_N, v, 7e13, 3e13, mu, shift)
    assert np.all(phi_N == 0)
    assert np.all(phi_T[:2 * n] == 0)
    # on the cone boundary r_T - radius y / |y| rounds: a few ulps of the radius
    assert np.all(np.abs(phi_T[2 * n:]) <= 8 * EPS * (mu * (r_N + shift))[2 * n:, None])
    assert status.tolist() == [contact.OPEN] * n + [contact.STICK] * n + [contact.SLIP] * n


@pytest.mark.parametrize("d", [2, 3])
def test_projection_residuals_are_nonzero_off_complementarity(d):
    rng = np.random.default_rng(10 + d)
    n = 50
    r_N, r_T, g_N, v, mu, shift = _complementary_states(rng, n, d - 1)
    kinds = {"open": slice(0, n), "stick": slice(n, 2 * n), "slip": slice(2 * n, 3 * n)}

    def residual(kind, r_N=r_N, r_T=r_T, g_N=g_N, v=v):
        k = kinds[kind]
        phi_N, phi_T = contact.contact_friction_projection(
            r_N[k], r_T[k], g_N[k], v[k], 7e13, 3e13, mu[k], shift[k])[:2]
        return np.abs(phi_N) + np.abs(phi_T).sum(axis=1)

    direction = rng.normal(size=r_T.shape)
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    cone = (mu * (r_N + shift))[:, None] * direction
    off = {"compression across an open gap": residual("open", r_N=r_N + 1e5),
           "shear on an open link": residual("open", r_T=r_T + 1e3),
           "penetration": residual("stick", g_N=g_N - 1e-7),
           "tension beyond the shift": residual("stick", r_N=-shift - 1e4),
           "friction outside the cone": residual("stick", r_T=1.05 * cone),
           "slip while sticking": residual("stick", v=v + 1e-7),
           "friction aiding the slip": residual("slip", r_T=-r_T)}
    assert [name for name, size in off.items() if not np.all(size > 0)] == []


def test_projection_of_an_open_link_without_slip_leaves_r_T_free():
    # r~_N = 0 gives a zero-radius disc, so phi_T = r_T even where y = r_T - rho_T v = 0:
    # the Jacobian must be the identity in r_T, not the (singular) stick branch
    phi_N, phi_T, jac, status = contact.contact_friction_projection(
        np.zeros(2), np.zeros((2, 2)), np.full(2, 1e-6), np.zeros((2, 2)), 7e13, 3e13, 0.5,
        0.0)
    assert np.all(phi_N == 0) and np.all(phi_T == 0) and np.all(status == contact.OPEN)
    assert np.array_equal(jac.dT_drT, np.broadcast_to(np.eye(2), (2, 2, 2)))
    assert np.all(jac.dT_dgT == 0) and np.all(jac.dN_drN == 1)


@pytest.mark.parametrize("d", [2, 3])
def test_projection_jacobian_is_the_central_difference_away_from_kinks(d):
    rng = np.random.default_rng(20 + d)
    n, m, rho_N, rho_T = 4000, d - 1, 7e13, 3e13
    scale = 1e6  # Pa
    r_N = rng.uniform(-1, 3, n) * scale
    r_T = rng.uniform(-1, 1, (n, m)) * scale
    g_N = rng.uniform(-1, 1, n) * scale / rho_N
    v = rng.uniform(-1, 1, (n, m)) * scale / rho_T
    mu = rng.uniform(0.2, 0.8, n)
    shift = np.where(rng.random(n) < 0.5, 1e6, 0.0)
    r_shift = r_N + shift
    y = np.linalg.norm(r_T - rho_T * v, axis=1)
    margin = 1e-3 * scale  # kinks: r~_N = rho_N g_N, r~_N = 0, |y| = radius, |y| = 0
    away = ((np.abs(r_shift - rho_N * g_N) > margin) & (np.abs(r_shift) > margin)
            & (np.abs(y - mu * np.maximum(r_shift, 0)) > margin) & (y > margin))
    r_N, r_T, g_N, v, mu, shift = (a[away] for a in (r_N, r_T, g_N, v, mu, shift))
    args = [r_N, r_T, g_N, v]
    _, _, jac, status = contact.contact_friction_projection(*args, rho_N, rho_T, mu, shift)
    assert set(status.tolist()) == {contact.OPEN, contact.STICK, contact.SLIP}
    # the step 1e-7 of the scale stays 1e4 times inside the 1e-3 margin; central
    # differences of piecewise smooth phi: truncation ~ (1e-7)^2, roundoff ~ eps / 1e-7
    steps = [1e-7 * scale, 1e-7 * scale, 1e-7 * scale / rho_N, 1e-7 * scale / rho_T]
    blocks = {0: ("dN_drN", "dT_drN"), 1: ("dN_drT", "dT_drT"), 2: ("dN_dgN", "dT_dgN"),
              3: ("dN_dgT", "dT_dgT")}
    for i, (arg, h) in enumerate(zip(args, steps)):
        cols = 1 if arg.ndim == 1 else m
        for j in range(cols):
            phis = []
            for sign in (1, -1):
                moved = [a.copy() for a in args]
                if arg.ndim == 1:
                    moved[i] += sign * h
                else:
                    moved[i][:, j] += sign * h
                phi_N, phi_T = contact.contact_friction_projection(
                    *moved, rho_N, rho_T, mu, shift)[:2]
                phis.append((phi_N, phi_T))
            fd_N = (phis[0][0] - phis[1][0]) / (2 * h)
            fd_T = (phis[0][1] - phis[1][1]) / (2 * h)
            jN, jT = (getattr(jac, name) for name in blocks[i])
            an_N = jN if arg.ndim == 1 else jN[:, j]
            an_T = jT if arg.ndim == 1 else jT[:, :, j]
            unit = 1.0 if i < 2 else (rho_N if i == 2 else rho_T)  # Jacobian entries ~ 1 or rho
            assert np.allclose(fd_N, an_N, rtol=0, atol=1e-6 * unit), (blocks[i][0], j)
            assert np.allclose(fd_T, an_T, rtol=0, atol=1e-6 * unit), (blocks[i][1], j)


# ---------------------------------------------------------------- purity

def test_laws_do_not_modify_their_inputs():
    rng = np.random.default_rng(0)
    n = 6
    arrays = dict(g_N=rng.normal(size=n) * U0, g_T=rng.normal(size=(n, 2)) * U0,
                  beta=rng.uniform(0.3, 1, n), dmax=rng.uniform(0, 1e-5, n),
                  broken=rng.random(n) < 0.5, r_N=rng.normal(size=n) * 1e6,
                  r_T=rng.normal(size=(n, 2)) * 1e6, mu=np.full(n, 0.5), shift=np.zeros(n))
    for a in arrays.values():
        a.flags.writeable = False  # any in-place write raises
    a = arrays
    laws.rccm(a["g_N"], a["g_T"], a["beta"], C_N, C_T, W)
    laws.rccm(a["g_N"], a["g_T"], a["beta"], C_N, C_T, W, b=1.0, h=1e-7)
    laws.rccm_decoupled(a["g_N"], a["g_T"], a["beta"], C_N, C_T, SIGMA_C, G_C)
    laws.linear_softening(a["g_N"], a["g_T"], a["dmax"], SIGMA_C, G_C, 1.2, 1.5)
    laws.threshold(a["g_N"], a["broken"], 1e6, 1e-6)
    contact.contact_friction_projection(a["r_N"], a["r_T"], a["g_N"], a["g_T"], 7e13, 3e13,
                                        a["mu"], a["shift"])


def test_mohr_coulomb_shear_needs_the_shear_traction_above_mu_i_times_the_pressure():
    C, w, beta_n, mu_i = 1e13, 10.0, np.ones(4), 0.6
    p = np.array([0.0, 5e6, 5e6, 5e6])  # Pa: tension, then pressed links
    tau = np.array([2e6, 2e6, 3.1e6, 8e6])  # Pa: shear tractions C_T |g_T|
    g_T = (tau / C)[:, None] * np.array([[0.6, 0.8]])  # 3D: two tangential components
    drive = laws.mohr_coulomb_shear(g_T, p, beta_n**2, C, mu_i)
    # the excess shear mu_i p = 3 MPa: none below it, the excess above it, the direction kept
    excess = np.array([2e6, 0.0, 0.1e6, 5e6])
    # closed-form arithmetic: round-off only (1e-12 relative; 1 mPa absolute for the zero)
    assert np.linalg.norm(drive, axis=1) * C == pytest.approx(excess, rel=1e-12, abs=1e-3)
    assert drive[3] / np.linalg.norm(drive[3]) == pytest.approx([0.6, 0.8])
    # RCCM damage then starts at sqrt(C_T w) + mu_i p in shear, not at sqrt(C_T w)
    peak = np.sqrt(C * w)  # 10 MPa
    pressed = np.full(2, 5e6)
    shear = np.array([[peak + mu_i * 5e6 - 1e3], [peak + mu_i * 5e6 + 1e5]]) / C
    beta = laws.rccm(np.zeros(2), laws.mohr_coulomb_shear(shear, pressed, np.ones(2), C, mu_i),
                     np.ones(2), C, C, w)[-1]
    assert beta[0] == 1.0 and beta[1] < 1.0
    # mu_i = 0 is the reference paper's law: g_T unchanged to round-off
    assert laws.mohr_coulomb_shear(g_T, p, beta_n**2, C, 0.0) == pytest.approx(g_T, rel=1e-15)
