"""The rigid path of the star kernel (solver/stars/rigid.py): a star closed and sticking on
every link, solved from the stored inverse of its joints' system instead of Newton, gets the answer Newton gets,
motion and reactions, on random stars and on the recorded steps of cracking bars; where its
piece does not hold it takes Newton and the same answer; and a run uses it."""
import json

import numpy as np
import pytest
from conftest import copied_cache, mpirun
from mpi4py import MPI

from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.runner.driver import integrator
from dolfrag.solver import star_kernel
from dolfrag.solver.active_set import COMPLIANCE
from dolfrag.solver.star_kernel import DEFAULT, Cache, StepData
from dolfrag.solver.stars.records import star_at
from dolfrag.solver.stars.residual import evaluate, evaluation
from dolfrag.solver.stars.rigid import HELD, held_motion, held_residual

# The full solve stops within rtol of the star's scale: its motion is the rigid path's to a
# few rtol of its largest value (the momentum rows scaled by m, through a Jacobian of
# condition ~1e3 on these stars), and its reactions to what the joints make of the residual
# it stops at (ring, below).
AGREE = 1e3 * DEFAULT.rtol


def ring(*outputs):
    """How far (relative to the largest) a star's reactions may lie from the exact ones when
    its solve stops at a scaled residual e: around a ring of held links the reactions are
    fixed by the joints' compliance alone (active_set.COMPLIANCE, eps), so a residual e of
    the jumps around it moves them by ~e / eps; 10 e / eps bounds it."""
    return max(AGREE, 10 * max(out.residual.max() for out in outputs) / COMPLIANCE)


def _rigid_star(rng, d, k=6, L=12, fixed=()):
    """A random star of k copies joined by L links (a ring through every copy, then random
    chords: connected, with loops) whose links are intact and strong: closed (g_n = 0), a
    compatible predicted motion (dg = h B v for a random v), cohesion far above the forces,
    no springs (a rigid cohesive link has none), a random reaction of the step before; its
    prescribed components move with the star (x = c - v, c common)."""
    slot_A = np.concatenate([np.arange(k), rng.integers(0, k, L - k)])
    slot_B = np.concatenate([(np.arange(k) + 1) % k, (slot_A[k:] + rng.integers(1, k, L - k)) % k])
    frame = np.ascontiguousarray(np.linalg.qr(rng.normal(size=(L, d, d)))[0])
    q, h = k * d, 0.3
    v = rng.normal(size=(k, d))
    dg = h * np.einsum("lij,lj->li", frame, v[slot_B] - v[slot_A])
    is_fixed = np.zeros(q, bool)
    is_fixed[list(fixed)] = True
    return dict(q=q, L=L, d=d, slot_A=slot_A, slot_B=slot_B, frame=frame, w=rng.uniform(0.5, 2, L),
                rho=rng.uniform(0.5, 2, L), frozen=np.zeros(L, bool), m=np.repeat(rng.uniform(0.5, 2, k), d),
                fixed=is_fixed, rhs=rng.normal(size=q), x_in=np.where(is_fixed, (rng.normal(size=d) - v).ravel(), 0.0),
                g_n=np.zeros((L, d)), dg=dg, mu=rng.uniform(0, 0.6, L), shift=np.full(L, 1e3),
                cohesion_T=np.full(L, 1e3), k_N=np.zeros(L), k_T=np.zeros(L), h=h, r_n=rng.normal(size=(L, d)))


def _records(star):
    """The kernel's records of one star: Geometry, StepData, and an empty cache (a list)."""
    q, L, d = star["q"], star["L"], star["d"]
    comp_off, link_off = np.array([0, q]), np.array([0, L])
    geometry = star_kernel.star_geometry(comp_off, link_off, star["slot_A"], star["slot_B"], star["frame"], star["w"],
                                         star["rho"], star["frozen"], star["m"], star["fixed"], star["h"])
    data = StepData(star["rhs"], star["x_in"], *(star[k] for k in ("g_n", "dg", "mu", "shift", "cohesion_T", "k_N",
                                                                     "k_T", "h")), 0.0, 0.0, star["r_n"])
    return geometry, data, list(star_kernel.empty_cache(comp_off, link_off, d))


def _solve(geometry, data, cache, rigid, todo=None):
    """One kernel call with the rigid path on or off: its Outputs."""
    q, L = len(geometry.mass), len(geometry.slot_A)
    n = len(geometry.comp_off) - 1
    out = star_kernel.empty_outputs(n, q, L, geometry.frame.shape[1])
    star_kernel.solve_stars(geometry, data, Cache(*cache), out, DEFAULT._replace(rigid=rigid), todo)
    return out


def _held(cache):
    """The cache of stars last closed and sticking on every link: RIGID, no factors."""
    cache = copied_cache(cache)
    cache[4][:] = HELD
    cache[6][:] = star_kernel.RIGID
    return cache


def _close(a, b, scale):
    return np.abs(a - b).max() <= AGREE * max(np.abs(b).max(), scale)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("fixed", [(), (0,), (0, 1, 5)], ids=["free", "one held component", "three"])
def test_a_rigid_star_gets_newtons_motion_and_reactions(d, fixed):
    rng = np.random.default_rng(7)
    for _ in range(50):
        star = _rigid_star(rng, d, fixed=fixed)
        geometry, data, cache = _records(star)
        newton = _solve(geometry, data, cache, rigid=False)
        assert newton.status[0] == star_kernel.CONVERGED
        rigid = _solve(geometry, data, _held(cache), rigid=True)
        # solved by the rigid path: at iteration 1, no Newton
        assert rigid.status[0] == star_kernel.CONVERGED and rigid.counters[star_kernel.ITERATIONS] == 1
        assert _close(rigid.x, newton.x, 0.0)
        assert np.array_equal(rigid.x[star["fixed"]], star["x_in"][star["fixed"]])
        for field in ("r", "reaction"):  # the reactions, and on the prescribed components their sums
            a, b = getattr(rigid, field), getattr(newton, field)
            assert np.abs(a - b).max() <= ring(rigid, newton) * np.abs(b).max()


@pytest.mark.parametrize("d", [2, 3])
def test_a_star_pulled_past_a_links_strength_leaves_the_rigid_path_for_newton(d):
    """One link of the star has almost no strength left: held, it would pull, or shear past
    its friction; the residual refuses it, Newton opens it or lets it slide, and the answer
    is Newton's from zero."""
    rng = np.random.default_rng(3)
    opened = 0
    for _ in range(50):
        star = _rigid_star(rng, d)
        star["shift"][0] = star["cohesion_T"][0] = 1e-9
        geometry, data, cache = _records(star)
        newton = _solve(geometry, data, cache, rigid=False)
        rigid = _solve(geometry, data, _held(cache), rigid=True)
        assert rigid.status[0] == newton.status[0] == star_kernel.CONVERGED
        if rigid.counters[star_kernel.ITERATIONS] > 1:  # refused: Newton from zero, as without the path
            opened += 1
            assert np.array_equal(rigid.x, newton.x) and np.array_equal(rigid.r, newton.r)
            g_end = star["g_n"][0] + rigid.slip[0]
            assert g_end[0] > 0 or np.abs(g_end[1:]).max() > 0  # the link opened or slid
    assert opened > 10


def _held_residual_and_evaluate(geometry, data, s):
    """Star s of the records held (rigid.held_motion), and there the held pass's residual
    (rigid.held_residual, with the outputs it writes) and residual.evaluate's: (scaled,
    out, evaluate's scaled parts, its Evaluation)."""
    d = geometry.frame.shape[1]
    p0, p1, l0, l1 = geometry.comp_off[s], geometry.comp_off[s + 1], geometry.link_off[s], geometry.link_off[s + 1]
    out = star_kernel.empty_outputs(len(geometry.comp_off) - 1, len(geometry.mass), len(geometry.slot_A), d)
    q = p1 - p0
    held_motion(d, geometry, data, p0, p1, l0, l1, geometry.rigid[geometry.rigid_off[s]:geometry.rigid_off[s + 1]],
                np.empty(q), out.x, out.r)
    scaled = held_residual(d, geometry, data, p0, p1, l0, l1, np.empty(q), out)
    ev = evaluation(d, q, l1 - l0)
    parts = evaluate(d, star_at(geometry, data, s), out.x[p0:p1].copy(), out.r[l0:l1].copy(), data.floor_m,
                     data.floor_c, ev)
    return scaled, out, parts, ev


def _assert_held_residual_is_evaluates(geometry, data, s):
    """held_residual is evaluate on the held piece, term for term: where every link of star
    s reads closed and sticking at its held motion, the same scaled residual, springs' jumps,
    slips and reactions of prescribed components, bit for bit; elsewhere inf (Newton's).
    Returns whether the star read the held piece."""
    scaled, out, parts, ev = _held_residual_and_evaluate(geometry, data, s)
    p0, p1, l0, l1 = geometry.comp_off[s], geometry.comp_off[s + 1], geometry.link_off[s], geometry.link_off[s + 1]
    L = l1 - l0
    if not (ev.code[:L] == HELD).all():
        assert scaled == np.inf
        return False
    assert scaled == max(parts)
    assert np.array_equal(out.gbar[l0:l1], ev.gbar[:L]) and np.array_equal(out.slip[l0:l1], ev.slip[:L])
    assert np.array_equal(out.reaction[p0:p1], ev.reaction[:p1 - p0])
    return True


@pytest.mark.parametrize("d", [2, 3])
def test_the_held_pass_reads_the_residual_newton_reads(d):
    """On random held stars, strong or with a link near no strength, and with or without
    springs (a held link of linear softening has none, but the residual counts them), the
    held pass's residual at the held motion is evaluate's where the star reads the held
    piece and inf where it does not: it accepts exactly the stars Newton would accept at
    that iterate and piece."""
    rng = np.random.default_rng(11)
    read = refused = 0
    for k in range(80):
        star = _rigid_star(rng, d, fixed=(0,) if k % 3 == 0 else ())
        if k % 2:
            star["shift"][0] = star["cohesion_T"][0] = 1e-9
        if k % 4 >= 2:
            star["k_N"], star["k_T"] = rng.uniform(0, 1, star["L"]), rng.uniform(0, 1, star["L"])
        geometry, data, _ = _records(star)
        if _assert_held_residual_is_evaluates(geometry, data, 0):
            read += 1
        else:
            refused += 1
    assert read > 20 and refused > 20


def _recorded_calls(monkeypatch, dim, steps):
    """The kernel's inputs at each step of a sound bar of linear softening under its pulse,
    weak enough (0.4 MPa) to crack as the pulse reflects in tension: (geometry, data)."""
    shape = [] if dim == 2 else ["geometry.kind=box", "geometry.thickness=0.012", "mesh.size=0.006",
                                 'supports.rollers=["bottom","top","front","back"]']
    case = load_case("sound-bar", ["mesh.size=0.004", "interface.law=linear_softening", "interface.sigma_c=4e5",
                                   "interface.G_c=1", "interface.mu=0.3", "geometry.width=0.012", *shape])
    integ = integrator(Problem.build(case, MPI.COMM_SELF))
    calls = []
    solve = star_kernel.solve_stars

    def recorded(geometry, data, *args):
        calls.append((geometry, type(data)(*(f.copy() if isinstance(f, np.ndarray) else f for f in data))))
        solve(geometry, data, *args)

    monkeypatch.setattr(star_kernel, "solve_stars", recorded)
    for _ in range(steps):
        integ.step()
    return calls, integ


@pytest.mark.parametrize("dim", [2, 3])
def test_recorded_steps_of_a_cracking_bar_solve_alike_with_and_without_the_rigid_path(dim, monkeypatch):
    """Every star of recorded steps held rigid first. Where the rigid path takes it, Newton
    predicted from the factors of that piece (what the star would have stored) gets the same
    motion, and the same reactions up to what the joints make of the star's residual;
    where the path refuses it, the star is Newton's from zero, bit for bit; and the held
    pass's residual is evaluate's (_assert_held_residual_is_evaluates).

    A star is solved to rtol of its scales, or of the step's where its own are tiny (the
    floors of semismooth.FLOOR): its values agree to a few rtol of the step's largest. The
    reactions of a ring of held links are fixed by the joints' compliance eps
    (active_set.COMPLIANCE): where Newton stops at a residual e (within rtol), its reactions
    may differ from the exact ones by a self-equilibrated ring of size ~ e / eps of the
    step's largest reaction; the bound is 10 e / eps (see ring)."""
    calls, integ = _recorded_calls(monkeypatch, dim, 180)
    assert (integ.model.damage() > 0).sum() > 10  # the bar cracks: refused stars are among them
    taken = refused = read = 0
    for geometry, data in calls[30::30]:
        d = geometry.frame.shape[1]
        empty = list(star_kernel.empty_cache(geometry.comp_off, geometry.link_off, d))
        held = _held(empty)
        rigid = _solve(geometry, data, held, rigid=True)
        took = held[6] == star_kernel.RIGID
        # Newton from zero on the refused stars: the same call, bit for bit
        from_zero = _solve(geometry, data, empty, rigid=False, todo=~took)
        assert np.array_equal(rigid.status[~took], from_zero.status[~took])
        for s in np.flatnonzero(~took):
            p = slice(geometry.comp_off[s], geometry.comp_off[s + 1])
            l = slice(geometry.link_off[s], geometry.link_off[s + 1])
            assert np.array_equal(rigid.x[p], from_zero.x[p]) and np.array_equal(rigid.r[l], from_zero.r[l])
        # Newton predicted from the held piece's factors on the stars it took
        stored = list(star_kernel.empty_cache(geometry.comp_off, geometry.link_off, d))
        star_kernel.keep_pieces(np.flatnonzero(took), geometry, data, rigid.x, rigid.r, Cache(*stored),
                                DEFAULT._replace(rigid=False))
        assert (stored[6][took] == star_kernel.EXACT).all()
        newton = _solve(geometry, data, stored, rigid=False, todo=took)
        assert (newton.status[took] == star_kernel.CONVERGED).all()
        largest_x, largest_r = np.abs(newton.x).max(), np.abs(newton.r).max()
        for s in np.flatnonzero(took):
            p = slice(geometry.comp_off[s], geometry.comp_off[s + 1])
            l = slice(geometry.link_off[s], geometry.link_off[s + 1])
            assert np.abs(rigid.x[p] - newton.x[p]).max() <= AGREE * largest_x, s
            bound = max(AGREE, 10 * max(newton.residual[s], rigid.residual[s]) / COMPLIANCE)
            assert np.abs(rigid.r[l] - newton.r[l]).max() <= bound * largest_r, s
        taken, refused = taken + took.sum(), refused + (~took).sum()
        # and the held pass's residual is evaluate's there (every fifth star that qualifies)
        for s in np.flatnonzero(np.diff(geometry.rigid_off) > 0)[::5]:
            read += _assert_held_residual_is_evaluates(geometry, data, s)
    assert taken > 0 and refused > 0 and read > 0


def test_a_run_holds_its_intact_stars_rigid():
    """In a run of linear softening at rest and under a weak pulse, every star is held
    rigid after the first step: no factors stored, every star solved at iteration 1."""
    case = load_case("sound-bar", ["mesh.size=0.004", "interface.law=linear_softening", "interface.sigma_c=4e6",
                                   "interface.G_c=100"])
    integ = integrator(Problem.build(case, MPI.COMM_SELF))
    for _ in range(20):
        integ.step()
    lay = integ.interface.layout
    assert (lay.cached == star_kernel.RIGID).all()
    assert integ.interface.first == lay.n_stars and integ.interface.iterations == 1


WALL = ["wall-bending-clamped", "--set=mesh.size=0.04", "--set=output.fields=0", "--set=output.figures=false"]


def test_a_cracking_reinforced_wall_holds_most_of_its_stars_rigid():
    """The clamped wall (C30/37, linear softening, bars) once its first links have softened
    at ~30 ms: most of its stars still intact and held rigid."""
    case = load_case(WALL[0], [a.split("=", 1)[1] for a in WALL[1:]] + ["time.end=0.04"])
    integ = integrator(Problem.build(case, MPI.COMM_SELF))
    while integ.t < 0.035:
        integ.step()
    assert (integ.model.damage() > 0).any()
    assert np.mean(integ.interface.layout.cached == star_kernel.RIGID) > 0.5


@pytest.mark.mpi
def test_the_rigid_path_gives_the_same_run_on_one_and_two_ranks(tmp_path):
    """The same wall to 40 ms, as it cracks, on 1 and 2 ranks: each star's path depends on
    its own data alone, so the ranks agree as they do without it."""
    for ranks in (1, 2):
        mpirun(["-m", "dolfrag.cli", "run", *WALL, "--set=time.end=0.04", "--quiet", "--out",
                tmp_path / f"n{ranks}"], n=ranks)
    one, two = (json.loads((tmp_path / f"n{n}" / "summary.json").read_text()) for n in (1, 2))
    assert one["broken_links"] == two["broken_links"] > 0
    # the ranks sum energies in another order: round-off of the largest, the load's work
    for key, value in one["energies_J"].items():
        assert two["energies_J"][key] == pytest.approx(value, rel=1e-8, abs=1e-9 * one["energies_J"]["W_external_J"])
