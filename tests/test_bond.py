"""Bond-slip between bars and concrete (rebar/bond.py): the fib Model Code 2010 envelope and
its return map, the bars' own nodes against closed forms on fixed concrete (an elastic
oscillation, exact for central differences; a slide to rest on the envelope, from the
envelope's integral), the stable step with the nodes, and a run's energy balance on 1 and 2
ranks."""
import json
import math

import numpy as np
import pytest
from mpi4py import MPI
import scipy.sparse as sp
from scipy.optimize import brentq
from scipy.sparse.linalg import eigsh

from conftest import mpirun
from test_resume import dolfrag
from dolfrag.case import load_case
from dolfrag.concrete import bond_strength
from dolfrag.problem import Problem
from dolfrag.rebar.bond import BondLaw, bar_force, bond_stress, envelope, plastic_slip_work

LAW = BondLaw(tau_max=bond_strength(38e6), s3=0.01)  # C30/37: f_cm = 38 MPa; 10 mm clear rib spacing


def test_envelope_is_fib2010_on_each_branch_and_continuous():
    tau = LAW.tau_max
    assert tau == pytest.approx(2.5e6 * math.sqrt(38))  # Table 6.1-1, pull-out, good bond
    s = np.array([0.5e-3, 1.5e-3, 2e-3 + 0.5 * (0.01 - 2e-3), 0.02])
    expected = [tau * 0.5**0.4, tau, tau * (1 - 0.6 * 0.5), 0.4 * tau]
    # the same formulas evaluated two ways: round-off
    assert envelope(LAW, s) == pytest.approx(expected, rel=1e-14)
    assert envelope(LAW, -s) == pytest.approx(expected, rel=1e-14)  # symmetric in the slip's sign
    # both sides of each joint, 2e-12 of it apart: the slopes move the stress by ~1e-11 of
    # itself, a jump would by its own size
    for joint in (LAW.s1, LAW.s2, LAW.s3):
        assert envelope(LAW, joint * (1 - 1e-12)) == pytest.approx(envelope(LAW, joint * (1 + 1e-12)), rel=1e-9)
    # the elastic line meets the envelope at elastic_slip (k_0 is its secant there: round-off)
    # and lies under it before
    assert LAW.k_0 * LAW.elastic_slip == pytest.approx(envelope(LAW, LAW.elastic_slip), rel=1e-14)
    s_small = np.linspace(1e-8, LAW.elastic_slip, 50)
    assert np.all(LAW.k_0 * s_small <= envelope(LAW, s_small) * (1 + 1e-12))


def test_the_bond_strength_comes_from_the_grade_unless_given_and_says_where_from():
    case = load_case("wall-bending-simple", ["rebar.bond=fib2010"])
    assert case.rebar.bond_tau_max == pytest.approx(2.5e6 * math.sqrt(38))
    assert "C30/37" in case.sources["rebar.bond_tau_max"] and "6.1-1" in case.sources["rebar.bond_tau_max"]
    given = load_case("wall-bending-simple", ["rebar.bond=fib2010", "rebar.bond_tau_max=1e7"])
    assert given.rebar.bond_tau_max == 1e7 and "rebar.bond_tau_max" not in given.sources
    assert load_case("wall-bending-simple", []).rebar.bond_tau_max is None  # perfect bond: no such key


def walk(path):
    """Stresses (Pa, (n, d)), trapezoidal work and dissipated work (J/m^2) of the return map
    along a path of slip vectors (m, (n, d)) from rest."""
    d = path.shape[1]
    slip_p, slip_max, tau = np.zeros((1, d)), np.zeros(1), np.zeros((1, d))
    taus, work, dissipated = [tau[0]], 0.0, 0.0
    for s_a, s_b in zip(path[:-1], path[1:]):
        new, p, slip_max = bond_stress(LAW, s_b[None], slip_p, slip_max)
        work += 0.5 * (tau[0] + new[0]) @ (s_b - s_a)
        dissipated += plastic_slip_work(tau, new, slip_p, p)[0]
        slip_p, tau = p, new
        taus.append(tau[0])
    return np.array(taus), work, dissipated


def test_return_map_follows_the_envelope_unloads_elastically_and_dissipates_what_it_does_not_store():
    s = np.concatenate([np.linspace(0, 4e-3, 801), np.linspace(4e-3, -1e-3, 1001)[1:]])
    taus, work, dissipated = walk(s[:, None])
    taus = taus[:, 0]
    loading = (s >= LAW.elastic_slip) & (np.arange(len(s)) <= 800)
    # monotone slip beyond the elastic line: on the envelope (its slope there is below k_0),
    # the return map's clip giving the envelope's own value: round-off
    assert taus[loading] == pytest.approx(envelope(LAW, s[loading]), rel=1e-12)
    # first unloading steps from 4 mm: elastic, slope k_0
    assert (taus[801] - taus[800]) / (s[801] - s[800]) == pytest.approx(LAW.k_0, rel=1e-12)
    # reversed slip yields at minus the envelope of the largest slip reached (4 mm)
    assert taus[-1] == pytest.approx(-envelope(LAW, 4e-3), rel=1e-12)
    # energy: the trapezoidal work along the path is what is dissipated plus the elastic
    # energy left, exactly (the step's mean stress on the plastic slip), whatever the steps
    stored = 0.5 * taus[-1] ** 2 / LAW.k_0
    assert dissipated > 0
    assert work == pytest.approx(dissipated + stored, rel=1e-12)


def test_the_bond_is_the_same_across_the_bar_and_keeps_its_energy_identity_on_a_turning_slip():
    # a slip grown along y instead of x: the same stresses (the law is isotropic)
    s = np.linspace(0, 3e-3, 301)
    along, _, _ = walk(np.column_stack([s, 0 * s]))
    across, _, _ = walk(np.column_stack([0 * s, s]))
    assert across[:, 1] == pytest.approx(along[:, 0], rel=1e-14) and not across[:, 0].any()
    # grown to 1.5 mm, then turned at that size by half a turn: the stress stays on the
    # envelope (radially returned), turns with the slip and dissipates; the work identity holds
    angle = np.linspace(0, np.pi, 400)
    path = np.concatenate([np.column_stack([s[:151], 0 * s[:151]]), 1.5e-3 * np.column_stack([np.cos(angle),
                                                                                          np.sin(angle)])[1:]])
    taus, work, dissipated = walk(path)
    size = np.linalg.norm(taus[-1])
    assert size == pytest.approx(float(envelope(LAW, 1.5e-3)), rel=1e-3)  # the chord lag of a 0.45 degree step
    assert taus[-1][0] < 0  # it turned with the slip
    assert dissipated > 0.5 * LAW.tau_max * 1.5e-3 * np.pi  # most of the arc 1.5 mm x pi is slid
    assert work == pytest.approx(dissipated + 0.5 * size**2 / LAW.k_0, rel=1e-12)


def test_the_bars_between_nodes_yield_in_compression_as_in_tension_and_book_their_work_exactly():
    E_s, A, f_y, L = 2e11, 5e-4, 5e8, 0.01
    eps_y = f_y / E_s
    # out to twice the yield strain, back through zero into compressive yield, and back
    path = np.concatenate([np.linspace(0, 2 * eps_y, 41), np.linspace(2 * eps_y, -2 * eps_y, 81)[1:],
                           np.linspace(-2 * eps_y, 0.5 * eps_y, 51)[1:]])
    eps_p, N_a, work, plastic = 0.0, 0.0, 0.0, 0.0
    forces = []
    for e_a, e_b in zip(path[:-1], path[1:]):
        N_b, p = bar_force(np.array([e_b]), np.array([eps_p]), E_s, A, f_y)
        work += 0.5 * (N_a + N_b[0]) * (e_b - e_a) * L
        plastic += 0.5 * L * (N_a + N_b[0]) * (p[0] - eps_p)  # the step's mean force, as BondedBars
        eps_p, N_a = p[0], N_b[0]
        forces.append(N_a)
    assert max(forces) == pytest.approx(A * f_y) and min(forces) == pytest.approx(-A * f_y)
    # the trapezoidal work is the elastic energy left plus the plastic work, exactly
    assert work == pytest.approx(0.5 * L * N_a**2 / (E_s * A) + plastic, rel=1e-12)
    # plastic flow at the yield force over 1 eps_y in tension (eps_y to 2 eps_y), 2 eps_y in
    # compression (after 2 eps_y of elastic return: 0 to -2 eps_y) and 0.5 eps_y in tension
    # again (0 to 0.5 eps_y); the path's steps fall on those corners, so this is exact too
    assert plastic == pytest.approx(A * f_y * L * 3.5 * eps_y, rel=1e-9)


def bonded_wall(*sets):
    case = load_case("wall-bending-simple", ["rebar.bond=fib2010", "output.figures=false", *sets])
    return Problem.build(case, MPI.COMM_SELF)


def test_bars_on_fixed_concrete_oscillate_as_central_differences_say_and_keep_their_energy():
    problem = bonded_wall()
    bars, law = problem.rebars, problem.rebars.law
    u = np.zeros(problem.space.V.dofmap.index_map.size_local * 2)
    # a uniform slip along x, elastic: the cables stay unstretched, every node is a mass
    # m = rho_s A l on a spring k = k_0 p l, with p = 4 A / diameter, so omega^2 = 4 k_0 / (rho_s d)
    s0 = 0.5 * law.elastic_slip
    bars.u_s[:, 0] = s0
    omega = math.sqrt(4 * law.k_0 / (problem.case.rebar.rho * problem.case.rebar.diameter))
    h = 0.2 / omega
    theta = math.acos(1 - (h * omega) ** 2 / 2)
    n = np.arange(1, 201)
    # u_n = A cos(theta n) + B sin(theta n) with u_0 = s0 and v_{-1/2} = 0 (u_{-1} = u_0)
    expected = s0 * (np.cos(theta * n) - math.tan(theta / 2) * np.sin(theta * n))
    k = law.k_0 * bars.surface
    history, energy = [], []
    for _ in n:
        bars.explicit_step(u, h)
        history.append(bars.u_s[:, 0].copy())
        energy.append(bars.kinetic_energy + bars.stored_energy(u, u))
    history = np.array(history)
    # every node follows the recurrence's closed form to round-off
    assert np.abs(history - expected[:, None]).max() < 1e-9 * s0
    assert np.abs(bars.u_s[:, 1]).max() == 0.0
    # kinetic plus booked energy: the springs' initial 1/2 k s0^2, to round-off
    assert np.array(energy) == pytest.approx(0.5 * s0**2 * k.sum(), rel=1e-9)
    assert abs(bars.dissipated) < 1e-9 * 0.5 * s0**2 * k.sum()  # elastic: round-off in slip - tau / k_0


def slide_distance(law, energy_per_area):
    """The slip (m) at which the work of the bond, elastic line to elastic_slip and then
    the envelope, equals energy_per_area (J/m^2): the envelope's integral in closed form."""
    tau, s1, s2, s3, a = law.tau_max, law.s1, law.s2, law.s3, law.alpha
    s_e = law.elastic_slip

    def work(s):
        rising = tau * s1 / (1 + a) * (min(s, s1) / s1) ** (1 + a) - tau * s1 / (1 + a) * (s_e / s1) ** (1 + a)
        flat = tau * (min(max(s, s1), s2) - s1)
        falling = 0.0
        if s > s2:
            x = min(s, s3) - s2
            falling = tau * (x - (1 - law.residual) * x**2 / (2 * (s3 - s2))) + law.residual * tau * max(s - s3, 0)
        return 0.5 * law.k_0 * s_e**2 + rising + flat + falling

    return brentq(lambda s: work(s) - energy_per_area, s_e, 1.0)


def test_a_bar_thrown_along_fixed_concrete_slides_as_far_as_the_envelopes_work_allows():
    problem = bonded_wall()
    bars, law, rebar = problem.rebars, problem.rebars.law, problem.case.rebar
    u = np.zeros(problem.space.V.dofmap.index_map.size_local * 2)
    V0 = 80.0  # m/s: kinetic energy per bond area 1/2 rho_s A V0^2 / p = rho_s d V0^2 / 8 J/m^2
    bars.v_s[:, 0] = V0
    h = 0.02 / math.sqrt(4 * law.k_0 / (rebar.rho * rebar.diameter))
    largest = 0.0
    for _ in range(100000):
        bars.explicit_step(u, h)
        largest = max(largest, bars.u_s[:, 0].max())
        if bars.v_s[:, 0].max() < 0:
            break
    expected = slide_distance(law, rebar.rho * rebar.diameter * V0**2 / 8)
    assert 2 * law.s1 < expected < law.s3  # the slide crosses the plateau into the softening
    # central differences against the continuous slide: second order in h (measured 8.4e-5
    # of the 4.6 mm slide at this step, 2.3e-5 at half of it); an error in the envelope's
    # branches or the work would show at the first order
    assert largest == pytest.approx(expected, rel=5e-4)
    # what the bar had is now dissipated by slip, stored elastically or still kinetic
    kinetic0 = 0.5 * V0**2 * bars.m_s.sum()
    assert bars.kinetic_energy + bars.stored_energy(u, u) + bars.dissipated == pytest.approx(kinetic0, rel=1e-9)
    assert bars.bond_work > 0.9 * kinetic0


def whole_system_omega2(problem):
    """lambda_max(M^-1 K) over the concrete's components and the nodes', assembled here
    from the bars' geometry: the cells' blocks, a spring E_s A / L between consecutive nodes
    and a spring k_0 p l from each node to its point in its cell, on each axis."""
    bars, ops = problem.rebars, problem.bulk
    n_c, d = ops.K_cells.shape[0], bars.d
    node = n_c + np.arange(len(bars.X) * d).reshape(-1, d)
    rows, cols, vals, k = [], [], [], []
    for axis in range(d):
        for a, b, L, A in zip(bars.a, bars.b, bars.L, bars.area):
            rows += [len(k)] * 2
            cols += [node[a, axis], node[b, axis]]
            vals += [-1.0, 1.0]
            k.append(bars.E_s * A / L)
        for i, lam, comps in zip(bars.bonded, bars.lam, bars.comps):
            rows += [len(k)] * (d + 2)
            cols += [node[i, axis], *comps[:, axis]]
            vals += [1.0, *(-lam)]
            k.append(bars.law.k_0 * bars.surface[i])
    C = sp.csr_matrix((vals, (rows, cols)), shape=(len(k), n_c + node.size))
    K = sp.block_diag([ops.K_cells.tocsr(), sp.csr_matrix((node.size, node.size))]) + C.T @ sp.diags(k) @ C
    scale = sp.diags(1 / np.sqrt(np.concatenate([ops.m.x.array[:n_c], np.repeat(bars.m_s, d)])))
    A = scale @ K @ scale
    return eigsh(A, k=1, which="LA", v0=np.ones(A.shape[0]), tol=0, return_eigenvectors=False)[0]


@pytest.mark.parametrize("E_s", [2e11, 2e13])
def test_the_stable_step_is_the_whole_systems_with_the_bars_nodes(E_s):
    problem = bonded_wall(f"rebar.E={E_s}")
    # Lanczos to machine precision on the same operator assembled two ways: round-off
    assert problem.dt_crit == pytest.approx(2 / np.sqrt(whole_system_omega2(problem)), rel=1e-9)
    if E_s > 1e12:
        # steel 100 times stiffer: the nodes, not the cells, set the step (a rule that left
        # them out would give the bulk's)
        assert problem.dt_crit < 0.9 * problem.bulk.dt_bulk
    else:
        # measured: the bulk's own step; the bars do not shorten it on this mesh
        assert problem.dt_crit == pytest.approx(problem.bulk.dt_bulk, rel=1e-9)


# a 200 bar pulse rising in 0.3 ms: within 1 ms the wall cracks through (about 100 links)
# and the bars slip (28 mm at midspan); 390 steps. Without the rate effect: its strengths move
# in steps of 1 % (interface/rate.py), and a link whose rate sits at a step's edge takes it
# on one rank count and not on the other (measured here: 1e-5 apart after step 200)
VIOLENT = ["rebar.bond=fib2010", "load.peak=2e7", "load.rise=0.0003", "time.end=0.001", "output.figures=false",
           "output.fields=0", "interface.rate_effect=none"]


def test_a_bonded_run_balances_its_energy_and_gives_the_same_answer_on_1_and_2_ranks(tmp_path):
    sets = [arg for item in VIOLENT for arg in ("--set", item)]
    runs = {}
    for n in (1, 2):
        mpirun(["-m", "dolfrag.cli", "run", "wall-bending-simple", "--quiet", *sets, "--out", str(tmp_path / str(n))],
               n=n)
        runs[n] = json.loads((tmp_path / str(n) / "summary.json").read_text())
    one, two = runs[1], runs[2]
    assert two["ranks"] == 2
    for run in (one, two):
        # the bars' nodes, cables and bond booked like the bulk: the balance closes to round-off
        assert run["balance_error_relative"] < 1e-10
        # the bars slip: measured 3.0 kJ/m of the 600 kJ/m of work (the rest goes to the
        # motion of the broken wall); none if the bond did not yield
        assert run["rebar"]["bond_slip_work_J"] > 1e-3 * run["energies_J"]["W_external_J"]
        assert run["broken_links"] > 50
    assert two["dt_s"] == pytest.approx(one["dt_s"], rel=1e-12)
    assert two["broken_links"] == one["broken_links"]
    # the star solves are the same problems on either rank count and the bars' state is the
    # same on every rank: round-off only (the Newton tolerance, 1e-10 of the step's momentum,
    # bounds what a reordering can move)
    for key in ("bond_slip_work_J", "peak_force_N"):
        assert two["rebar"][key] == pytest.approx(one["rebar"][key], rel=1e-6)
    assert two["wall"]["midspan_deflection"]["peak_m"] == pytest.approx(one["wall"]["midspan_deflection"]["peak_m"],
                                                                        rel=1e-6)


def test_a_bonded_run_stopped_and_resumed_ends_as_the_uninterrupted_run(tmp_path):
    sets = [arg for item in VIOLENT for arg in ("--set", item)]
    whole = dolfrag(["run", "wall-bending-simple", "--quiet", *sets, "--out", tmp_path / "whole"], 1)
    assert whole.returncode == 0, whole.stderr
    out = tmp_path / "stopped"
    # stopped while the wall cracks and the bars slip
    stopped = dolfrag(["run", "wall-bending-simple", "--quiet", *sets, "--out", out], 1, stop_at=250)
    assert stopped.returncode == 143, stopped.stderr
    at_stop = json.loads((out / "summary.json").read_text())
    assert at_stop["steps_done"] == 250 and at_stop["broken_links"] > 0
    assert dolfrag(["run", "--resume", out, "--quiet"], 1).returncode == 0
    # the nodes' displacements, velocities, slips and booked work are in the checkpoint:
    # imex repeats the same operations on the same bits
    with open(tmp_path / "whole" / "history.csv") as f, open(out / "history.csv") as g:
        assert f.read() == g.read()
    got, expected = (json.loads((path / "summary.json").read_text()) for path in (out, tmp_path / "whole"))
    assert got["energies_J"] == expected["energies_J"] and got["rebar"] == expected["rebar"]
