"""Single-interface patch tests driven by imposed displacement: two triangles
share one facet (two links); cell A is held, cell B is moved rigidly, so the bulk carries
no stress and the reaction on B is the interface traction times the facet length.

Each law's traction is compared, step by step, with its closed form evaluated the way
the step evaluates it: the springs at the jump of the average (g_{n+1} + 2 g_n + g_{n-1})/4
with the state lagged by one step, the rigid constraint at the end-of-step gap. Those are
exact statements about the discrete step, so they hold to the Newton tolerance."""
import dataclasses

import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT
from dolfrag import compat
from dolfrag.case import load_case
from dolfrag.interface.stars import Stars
from dolfrag.problem import Problem
from dolfrag.solver.active_set import COMPLIANCE
from dolfrag.solver.imex import Imex
from dolfrag.solver.semismooth import step_stiffness

PATCH = ROOT / "tests" / "cases" / "patch.toml"
SIGMA_C = 5.0e6  # Pa
RTOL = 1e-8  # Newton stops at 1e-10 of the reaction scale; tractions here are O(sigma_c)


def two_cells(overrides, held=("A", "B")):
    """The patch integrator with the named cells' components prescribed (A held still,
    B moved by ``drive``), and the flat components of cell A and of cell B."""
    case = load_case(PATCH, overrides)
    problem = Problem.build(case, MPI.COMM_SELF)
    space, links = problem.space, problem.links
    d = space.gdim
    cell_of = {"A": np.flatnonzero((space.cell_dofs == links.dof_A[0]).any(axis=1))[0],
               "B": np.flatnonzero((space.cell_dofs == links.dof_B[0]).any(axis=1))[0]}
    comps = {k: (d * space.cell_dofs[c][:, None] + np.arange(d)).ravel() for k, c in cell_of.items()}
    stars = Stars(space, links, np.concatenate([comps[k] for k in held]))
    integ = Imex.from_problem(dataclasses.replace(problem, stars=stars), load=compat.Function(space.V))
    return case, integ, links, comps


def drive(integ, comps, direction, g):
    """Move cell B rigidly so that its jump is g[k] * direction at step k (m); returns the
    normal traction (Pa, tension > 0) measured from B's reactions, and the end-of-step
    normal gap, per step."""
    h, n = integ.h, integ.jump.links.normal[0]
    length = integ.jump.links.weight.sum()
    B = comps["B"]
    velocity = np.diff(g) / h
    k = {"now": 0}
    integ.impose(B, lambda t: np.tile(velocity[k["now"]] * direction, len(B) // len(direction)))
    traction, gap = [], []
    for k["now"] in range(len(velocity)):
        integ.step()
        # inertia of B's velocity change is not interface force: take it out
        R = integ.interface.reaction[B] - integ.m[B] * integ.dv.x.array[B] / h
        traction.append(R.reshape(-1, len(n)).sum(axis=0) @ n / length)
        gap.append(integ.jump.local(integ.jump(integ.u.x.array))[0][0])
    return np.array(traction), np.array(gap)


def averaged(g):
    """Jump the springs see at step k: (g_{k+1} + 2 g_k + g_{k-1}) / 4 (g_{-1} = g_0)."""
    before = np.concatenate([[g[0]], g[:-2]])
    return (g[1:] + 2 * g[:-1] + before) / 4


def opening_path(peak, steps, unload_to=None, reload_to=None):
    """Normal jump history: 0 -> peak, optionally back to unload_to and up to reload_to (m)."""
    g = list(np.linspace(0.0, peak, steps + 1))
    if unload_to is not None:
        g += list(np.linspace(peak, unload_to, steps + 1)[1:])
        g += list(np.linspace(unload_to, reload_to, steps + 1)[1:])
    return np.array(g)


def test_rccm_traction_follows_the_lagged_law_and_dissipates_w():
    case, integ, links, comps = two_cells(["interface.law=rccm", f"interface.sigma_c={SIGMA_C}"])
    C = integ.model.C_N
    w = integ.model.w
    g0 = np.sqrt(w / C)  # peak opening, traction sigma_c there
    g = opening_path(30 * g0, 600, unload_to=2 * g0, reload_to=40 * g0)
    traction, _ = drive(integ, comps, links.normal[0], g)
    gbar = averaged(g)
    beta, expected = 1.0, []
    for gk in gbar:  # the closed form, state lagged one step
        expected.append(beta**2 * C * max(gk, 0.0))
        beta = min(beta, w / (C * gk**2)) if gk > 0 else beta
    assert traction == pytest.approx(np.array(expected), rel=RTOL, abs=RTOL * SIGMA_C)
    # peak sqrt(C w) = sigma_c, overshot by the lag: at most one increment past g0
    assert SIGMA_C <= traction.max() <= SIGMA_C * (1 + (g[1] - g[0]) / g0) * (1 + RTOL)
    # damage is irreversible: unloading and reloading follow the secant beta_min^2 C
    n = 601
    assert np.all(np.diff(traction[n:n + 590]) <= 0) and np.all(np.diff(traction[n + 601:n + 1000]) >= 0)
    dissipated = integ.model.dissipated() @ links.weight / links.weight.sum()
    # work to separation w, less what beta = w/(C g^2) at 40 g0 keeps. Booking the drop
    # beta_n -> beta at the lagged secant (models.Rccm.store) overshoots, never undershoots,
    # and converges at first order: 1.37 dg/g0 measured on a monotone pull to 40 g0 with
    # 300 to 2,400 increments (the same sums in plain numpy); 1.5 dg/g0 bounds it.
    exact = w * (1 - 1 / 40**2)
    assert exact <= dissipated <= exact * (1 + 1.5 * np.diff(g).max() / g0)


def test_threshold_carries_R_c_until_W_eth_then_dissipates_R_c_W_eth():
    R_c, W_eth = 3.0e6, 2.0e-6
    case, integ, links, comps = two_cells(["interface.law=threshold", f"interface.R_c={R_c}",
                                           f"interface.W_eth={W_eth}"])
    g = opening_path(2 * W_eth, 400)
    traction, gap = drive(integ, comps, links.normal[0], g)
    g_mid = (g[1:] + g[:-1]) / 2
    held = g_mid <= W_eth
    assert traction[held & (g[1:] > 0)] == pytest.approx(R_c, rel=RTOL)
    assert np.all(np.abs(traction[~held][1:]) <= RTOL * R_c)  # broken for good
    step = g[1] - g[0]
    dissipated = integ.model.dissipated() @ links.weight / links.weight.sum()
    # lost at the step whose mid gap passes W_eth: R_c W_eth to within R_c times one increment
    assert abs(dissipated - R_c * W_eth) <= R_c * step


def test_linear_softening_follows_its_secant_and_dissipates_G_c():
    G_c = 50.0
    case, integ, links, comps = two_cells(["interface.law=linear_softening", f"interface.sigma_c={SIGMA_C}",
                                           f"interface.G_c={G_c}"])
    delta_c = 2 * G_c / SIGMA_C
    g = opening_path(0.6 * delta_c, 300, unload_to=0.1 * delta_c, reload_to=1.2 * delta_c)
    traction, _ = drive(integ, comps, links.normal[0], g)
    gbar, g_mid = averaged(g), (g[1:] + g[:-1]) / 2
    # rigid, at the softened strength, until the secant is down to the step's own stiffness
    k_step = step_stiffness(links, integ.m, integ.h, 2)
    delta_open = SIGMA_C / (k_step + SIGMA_C / delta_c)
    assert integ.model.delta_open() == pytest.approx(delta_open, rel=1e-12)  # same formula: round-off
    assert np.all((0.01 * delta_c < delta_open) & (delta_open < 0.1 * delta_c))  # a rigid phase of 5-50 steps
    delta_max, sprung, expected = 0.0, False, []
    for gb, gm in zip(gbar, g_mid):  # every quantity of the law lagged by one step
        S = SIGMA_C * (1 / delta_max - 1 / delta_c) if 0 < delta_max < delta_c else 0.0
        expected.append(S * max(gb, 0.0) if sprung else SIGMA_C * (1 - delta_max / delta_c) * (gm > 0))
        delta_max = max(delta_max, gm) if gm > 1e-9 * delta_c else delta_max
        sprung = sprung or delta_max > delta_open[0]
    assert traction == pytest.approx(np.array(expected), rel=RTOL, abs=RTOL * SIGMA_C)
    dissipated = integ.model.dissipated() @ links.weight / links.weight.sum()
    # The secant lagged one step lets the traction overshoot the softening envelope by
    # sigma_c dg / delta_k at the k-th step after opening (delta_k ~ k dg), so the extra
    # work sums like a harmonic series: at most 2 (ln(delta_c / dg) + 1) dg / delta_c of
    # G_c = sigma_c delta_c / 2, and never less than G_c.
    dg = np.diff(g).max()
    assert G_c <= dissipated <= G_c * (1 + 2 * (np.log(delta_c / dg) + 1) * dg / delta_c)
    assert integ.model.broken().all()


@pytest.mark.parametrize("law", [["interface.law=rccm", f"interface.sigma_c={SIGMA_C}"],
                                 ["interface.law=threshold", "interface.R_c=3e6", "interface.W_eth=2e-6"],
                                 ["interface.law=linear_softening", f"interface.sigma_c={SIGMA_C}",
                                  "interface.G_c=50"]], ids=["rccm", "threshold", "linear_softening"])
def test_a_cell_pushed_into_a_free_one_never_interpenetrates(law):
    """RCCM's intact link is exact contact in compression: the gap never closes past zero.
    An intact link of a rigid cohesive law (threshold, linear softening) is a stiff elastic
    joint (active_set.COMPLIANCE): pressed by r_N it closes by exactly COMPLIANCE r_N / rho,
    its elastic compression, and no further."""
    case, integ, links, comps = two_cells(law, held=("A",))
    n = links.normal[0]
    A = comps["A"]
    V = 1.0  # m/s, A driven towards B
    integ.impose(A, lambda t: np.tile(V * n, len(A) // len(n)))
    joint = 0.0 if "rccm" in law[0] else COMPLIANCE / step_stiffness(links, integ.m, integ.h, 2)  # m/Pa
    worst, pressed = 0.0, 0.0
    for _ in range(50):
        integ.step()
        g_N, r_N = integ.jump.local(integ.jump(integ.u.x.array))[0], integ.interface.r[:, 0]
        worst = min(worst, (g_N + joint * np.maximum(r_N, 0.0)).min())
        pressed = max(pressed, r_N.max())
    # B has been pushed along (its copies ring elastically about A's speed)
    B = comps["B"]
    assert np.mean(integ.v.x.array[B].reshape(-1, 2) @ n) > 0.5 * V
    assert pressed > 0
    # the gap is enforced to the Newton tolerance, ~1e-10 of r / rho (semismooth.py), far
    # below the 50 h V = 8e-5 m that A travelled
    assert worst >= -1e-12 * 50 * integ.h * V


def test_rccm_decoupled_dissipates_G_c_whatever_C_N():
    G_c = 50.0
    delta_c = 2 * G_c / SIGMA_C
    for ratio in (10.0, 100.0):
        excess = []
        for steps in (300, 1200):
            case, integ, links, comps = two_cells(["interface.law=rccm_decoupled", f"interface.sigma_c={SIGMA_C}",
                                                   f"interface.G_c={G_c}", f"interface.stiffness_ratio={ratio}"])
            g = opening_path(1.2 * delta_c, steps)
            traction, _ = drive(integ, comps, links.normal[0], g)
            # peak sigma_c, overshot by the lag: one increment of the elastic rise at most
            assert SIGMA_C <= traction.max() <= SIGMA_C + integ.model.C_N * np.diff(g).max()
            assert integ.model.broken().all()
            excess.append(integ.model.dissipated() @ links.weight / links.weight.sum() / G_c - 1)
        # the lagged secant overshoots (never undershoots) and the excess vanishes at about
        # first order in the increment (x dg log dg): 4 times finer, more than 3 times smaller
        assert 0 <= excess[1] < excess[0] / 3 and excess[0] < 0.1, excess


def test_friction_slips_at_the_coulomb_limit_sticks_below_it_and_dissipates_its_work():
    # An intact threshold link, closed (g_N = 0 imposed), presses with its cohesion: the
    # Coulomb cone is shifted by R_c, so the slip threshold is mu R_c with no normal load.
    R_c, mu = 3.0e6, 0.5
    case, integ, links, comps = two_cells(["interface.law=threshold", f"interface.R_c={R_c}",
                                           "interface.W_eth=1e-3", f"interface.mu={mu}"])
    t = links.tangents[0][0]
    s = 2e-6  # m: slide forward s, hold, slide back s / 2
    g = np.concatenate([np.linspace(0, s, 101), np.full(50, s), np.linspace(s, s / 2, 51)[1:]])
    n, length = links.normal[0], links.weight.sum()
    B, h = comps["B"], integ.h
    velocity = np.diff(g) / h
    shear, k = [], {"now": 0}
    integ.impose(B, lambda _: np.tile(velocity[k["now"]] * t, len(B) // len(t)))
    for k["now"] in range(len(velocity)):
        integ.step()
        R = integ.interface.reaction[B] - integ.m[B] * integ.dv.x.array[B] / h
        shear.append(R.reshape(-1, len(n)).sum(axis=0) @ t / length)
    shear = np.array(shear)
    forward, hold, back = velocity > 0, velocity == 0, velocity < 0
    # the support drives B against friction: +mu R_c forward, -mu R_c back (the Newton tolerance)
    assert shear[forward] == pytest.approx(mu * R_c, rel=RTOL)
    assert shear[back] == pytest.approx(-mu * R_c, rel=RTOL)
    assert np.all(np.abs(shear[hold]) <= mu * R_c * (1 + RTOL))  # stick: inside the cone
    # friction work mu R_c x slid distance x facet length, all of it dissipated by contact.
    # The discrete energy identity pairs a step's reaction with the centred difference
    # (g_{n+1} - g_{n-1}) / 2, so each start, stop or reversal of sliding shifts the sum by
    # half an increment: within one increment in all (measured: exactly one, -1/150)
    increment = mu * R_c * np.abs(np.diff(g)).max() * length
    assert abs(integ.interface.contact_dissipated - mu * R_c * 1.5 * s * length) <= increment * (1 + 1e-6)
    assert not integ.model.broken().any() and integ.model.dissipated().sum() == 0


def test_a_pressed_block_slips_at_the_coulomb_limit_until_it_moves_with_its_driver():
    # The belt problem: cell A is driven into the broken interface (normal acceleration a,
    # so the contact pushes free cell B with ~ m_B a) while sliding at V; friction drags B
    # at mu a until it moves with A (t_s = V / (mu a)), then holds it (stick).
    mu, a, V = 0.5, 1e4, 0.5  # -, m/s^2, m/s
    case, integ, links, comps = two_cells(["interface.law=rccm", f"interface.sigma_c={SIGMA_C}",
                                           f"interface.mu={mu}"], held=("A",))
    integ.model.beta[:] = 0.0  # broken: contact and full friction mu (1 - beta) only
    n, t = links.normal[0], links.tangents[0][0]
    A, B = comps["A"], comps["B"]
    integ.impose(A, lambda time: np.tile(a * time * n + V * t, len(A) // len(n)))
    m_B = integ.m[B].reshape(-1, len(n))[:, 0].sum()
    slipping, sticking = [], []
    for k in range(int(2 * V / (mu * a) / integ.h)):
        integ.step()
        r_N, r_T = integ.interface.r[:, 0], integ.interface.r[:, 1]
        v_B = np.mean(integ.v.x.array[B].reshape(-1, len(n)) @ t)
        pressed = r_N > 1e-6 * m_B * a / links.weight.sum()
        if v_B < 0.5 * V or v_B > 0.9 * V:  # clearly slipping, or caught up
            (slipping if v_B < 0.5 * V else sticking).append((r_N[pressed], r_T[pressed], v_B))
    assert len(slipping) > 10 and len(sticking) > 10  # both phases seen
    # slip: every pressed link sits on the Coulomb cone, r_T opposing B's slip relative to
    # A (backwards), i.e. pushing B forwards along t (Newton tolerance)
    for r_N, r_T, _ in slipping:
        assert np.allclose(r_T, mu * r_N, rtol=1e-8, atol=1e-8 * mu * r_N.max(initial=0.0))
    # stick: inside the cone (some links touch its edge as B rings; Newton's tolerance is
    # 1e-10 of the star's scale, which holds the gap terms rho |g|, so allow 1e-6 of the
    # reactions), and B moves with A (its copies ring elastically: within 2 %)
    for r_N, r_T, v_B in sticking[len(sticking) // 2:]:
        assert np.all(np.abs(r_T) <= mu * r_N + 1e-6 * mu * r_N.max(initial=0.0))
        assert v_B == pytest.approx(V, rel=0.02)
    # a rigid block dragged to the belt speed dissipates 1/2 m V^2 by friction; B is elastic
    # and bounces on A (normal impacts dissipate too): 0.6 % below it, measured
    assert integ.interface.contact_dissipated == pytest.approx(0.5 * m_B * V**2, rel=0.03)
