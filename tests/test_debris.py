"""Debris throw (post/debris.py): flights against closed forms, the hazard distance of
hand-made landings, and debris.csv of a reduced 3D run."""
import json
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import dolfrag_cli
from dolfrag.case import load_case
from dolfrag.post import debris
from dolfrag.rebar.layout import layer_polylines
from test_slab import REDUCED
from test_vtk_output import cell_means, fragments_grid

G = debris.G
RHO_AIR = 1.225  # kg/m^3


def test_drag_free_flight_lands_at_the_parabolas_range():
    x0, v0, h = np.array([1.0, -2.0, 3.0]), np.array([12.0, -5.0, 8.0]), 3.0  # m, m/s; ground at z = 0
    landing = debris.fly(x0, v0, debris.drag_factor(2.0, 1e-3, 1.0, 0.0), 0.0)  # no air: no drag
    t = (v0[2] + np.sqrt(v0[2] ** 2 + 2 * G * h)) / G
    assert landing.time == pytest.approx(t, rel=1e-6)
    expected = x0[:2] + v0[:2] * t
    error = np.linalg.norm(landing.point[:2] - expected) / np.linalg.norm(v0[:2] * t)
    # measured 2e-15: DOP853 at 1e-10 (exact on a parabola), the event at machine precision
    assert error < 1e-6, error
    assert landing.point[2] == 0.0
    # energy: |v|^2 = |v0|^2 + 2 g h at the ground
    assert np.linalg.norm(landing.velocity) == pytest.approx(np.sqrt(v0 @ v0 + 2 * G * h), rel=1e-8)


def test_a_launch_at_the_ground_lands_where_it_is():
    landing = debris.fly([0.5, 0.5, 0.0], [1.0, 0.0, -1.0], 0.1, 0.0)
    assert landing.time == 0.0 and np.array_equal(landing.point, [0.5, 0.5, 0.0])


def test_a_dropped_fragment_reaches_the_terminal_speed():
    mass, volume, C_D = 1.0, 1.0 / 2350.0, 1.0  # a 1 kg concrete chunk
    area = np.pi * (3 * volume / (4 * np.pi)) ** (2 / 3)
    terminal = np.sqrt(2 * mass * G / (RHO_AIR * C_D * area))  # 48 m/s
    drag = debris.drag_factor(mass, volume, C_D, RHO_AIR)
    assert drag == pytest.approx(G / terminal**2, rel=1e-14)
    # dropped from rest, v(d)^2 = v_t^2 (1 - exp(-2 g d / v_t^2)) after a fall d
    for height in (20.0, 2000.0):
        speed = np.linalg.norm(debris.fly([0.0, 0.0, height], [0.0, 0.0, 0.0], drag, 0.0).velocity)
        assert speed == pytest.approx(terminal * np.sqrt(1 - np.exp(-2 * G * height / terminal**2)), rel=1e-6)
    # 2000 m is 16.8 times v_t^2 / (2 g): exp(-16.8) / 2 = 2.5e-8 below v_t
    assert speed == pytest.approx(terminal, rel=1e-3)


def test_a_fragment_launched_sideways_with_drag_falls_short_of_the_parabola():
    drag = debris.drag_factor(0.05, 0.05 / 2350.0, 1.0, RHO_AIR)
    free = debris.fly([0.0, 0.0, 2.0], [20.0, 0.0, 5.0], 0.0, 0.0)
    slowed = debris.fly([0.0, 0.0, 2.0], [20.0, 0.0, 5.0], drag, 0.0)
    assert 0 < slowed.point[0] < free.point[0]
    assert np.linalg.norm(slowed.velocity) < np.linalg.norm(free.velocity)  # drag takes energy


# Hand-made landings, rings 1 m wide, the limit 1 hazardous fragment per 55.7 m^2. Ring k holds
# [k, k + 1) m, area pi (2 k + 1) m^2, and is dense with n >= pi (2 k + 1) / 55.7 fragments:
# one is enough in rings 0 to 8 (ring 8: 17 pi / 55.7 = 0.96), ring 9 needs 2 (19 pi / 55.7 =
# 1.07), ring 12 needs 2 (1.41), ring 20 needs 3 (2.31), ring 30 needs 4 (3.44).
LANDINGS = [  # (range m, impact energy J)
    (0.4, 500.0),                # ring 0: dense
    (8.5, 100.0),                # ring 8: dense
    (9.5, 100.0),                # ring 9: 1 < 1.07
    (12.2, 79.0), (12.7, 200.0),  # ring 12: 2 >= 1.41, 79 J is hazardous
    (20.5, 1e4),                 # ring 20: 1 < 2.31
    *[(30.1 + 0.1 * i, 78.9) for i in range(5)],  # ring 30: 5 >= 3.44, but below 79 J
]


def test_hazard_distance_of_hand_made_landings_is_the_outer_edge_of_the_last_dense_ring():
    ranges, energies = np.array(LANDINGS).T
    assert debris.hazard_distance(ranges, energies, 79.0, 55.7, 1.0) == 13.0
    # the same energies at 78.9 J count: ring 30 then is the farthest dense ring
    assert debris.hazard_distance(ranges, energies, 78.9, 55.7, 1.0) == 31.0
    assert debris.hazard_distance(ranges, energies, 1e5, 55.7, 1.0) == 0.0  # none hazardous


@pytest.mark.parametrize("distance, expected", [(13.0, 14.0), (14.5, 0.0)])
def test_hazard_distance_of_three_fragments_at_one_range(distance, expected):
    # 3 fragments in ring k of width 2 m are dense enough if 3 x 55.7 >= 4 pi (2 k + 1), i.e.
    # k <= 6: ring 6 = [12, 14) m gives 14 m; at 14.5 m (ring 7) they are too sparse
    assert debris.hazard_distance(np.full(3, distance), np.full(3, 100.0), 79.0, 55.7, 2.0) == expected


def test_throw_leaves_held_pieces_and_measures_ranges_from_the_centre():
    table = SimpleNamespace(mass=np.array([1.0, 2.0, 3.0]), volume=np.array([1.0, 2.0, 3.0]) / 2350.0,
                            centroid=np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0], [2.0, 0.0, 0.5]]),
                            velocity=np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 3.0, 4.0]]),
                            held=np.array([False, True, False]))
    thrown = debris.throw(table, np.array([1.0, 0.0]), 0.0, 1.0, 0.0)
    assert np.array_equal(thrown.ids, [0, 2])
    t0 = np.sqrt(2 / G)
    assert thrown.landing[0] == pytest.approx([t0, 0.0, 0.0], rel=1e-8)
    assert thrown.range == pytest.approx([abs(t0 - 1.0), np.hypot(1.0, 3.0 * (4 + np.sqrt(16 + G)) / G)], rel=1e-8)
    # no drag: the impact energy is the launch energy plus m g h
    assert thrown.impact_energy == pytest.approx([0.5 * 1 + 1 * G * 1.0, 0.5 * 3 * 25 + 3 * G * 0.5], rel=1e-8)


@pytest.fixture(scope="module")
def slab(tmp_path_factory):
    """The reduced slab of tests/test_slab.py with its figures, serially."""
    out = tmp_path_factory.mktemp("debris-slab")
    sets = [item for item in REDUCED if item != "output.figures=false"]
    result = dolfrag_cli("run", "slab-3d-scabbing", "--quiet", "--out", out, *(a for s in sets for a in ("--set", s)))
    assert result.returncode == 0, result.stderr
    read = lambda name: np.genfromtxt(out / name, delimiter=",", names=True, dtype=None, encoding=None)  # noqa: E731
    return (load_case("slab-3d-scabbing", sets), json.loads((out / "summary.json").read_text()),
            read("fragments.csv"), read("debris.csv"), out)


@pytest.mark.slow
def test_fragments_csv_of_the_reduced_slab_sums_to_its_concrete_and_steel(slab):
    case, summary, frags, _, _ = slab
    g, bars = case.geometry, case.rebar
    lines, areas = layer_polylines(bars, g, 3)
    steel = bars.rho * sum(a * np.linalg.norm(line[1] - line[0]) for line, a in zip(lines, areas))
    volume = g.length * g.width * g.thickness
    assert len(frags) == summary["fragments"]["count"] > 5
    # 10 printed digits per row (output.write_csv)
    assert frags["volume_m3"].sum() == pytest.approx(volume, rel=1e-9)
    assert frags["mass_kg"].sum() == pytest.approx(case.material.rho * volume + steel, rel=1e-9)
    assert np.allclose(frags["kinetic_energy_J"], 0.5 * frags["mass_kg"] * frags["speed_m_s"] ** 2, rtol=1e-9)
    speed = np.linalg.norm([frags[f"v{a}_m_s"] for a in "xyz"], axis=0)
    assert np.allclose(frags["speed_m_s"], speed, rtol=1e-9)
    assert set(frags["group"]) == {"concrete"}
    # the crumbs left the slab before the end; the slab, held by its clamped edges, too
    assert np.all(frags["came_free_s"] <= case.time.end) and np.any(frags["held"] == 1)


@pytest.mark.slow
def test_fragments_pvd_gives_each_cell_its_row_of_fragments_csv(slab):
    case, summary, frags, _, out = slab
    grid, t = fragments_grid(out)
    # the snapshot's time is the run's last t, n_steps dt: time.end to the round-off of that product
    assert t == pytest.approx(case.time.end, rel=1e-12) and grid.n_cells == summary["cells"]
    (_, conn), = grid.cells_dict.items()
    for name in ("fragment", "held", "fragment_speed"):  # one value per cell, on each of its vertex copies
        values = grid.point_data[name][conn]
        assert np.array_equal(values, np.repeat(values[:, :1], values.shape[1], axis=1)), name
    fragment = grid.point_data["fragment"][conn[:, 0]].astype(int)
    assert np.array_equal(np.unique(fragment), frags["id"])
    volume = np.abs(grid.compute_cell_sizes(length=False, area=False).cell_data["Volume"])
    # each piece's cells make up its volume (fragments.csv: 10 printed digits)
    np.testing.assert_allclose(np.bincount(fragment, weights=volume), frags["volume_m3"], rtol=1e-9)
    assert np.array_equal(grid.point_data["held"][conn[:, 0]], frags["held"][fragment])
    np.testing.assert_allclose(grid.point_data["fragment_speed"][conn[:, 0]], frags["speed_m_s"][fragment],
                               rtol=1e-9)
    _, u = cell_means(grid, "displacement")
    assert np.abs(u).max() > 0  # the end state, not the reference


def test_debris_csv_of_the_reduced_slab_follows_from_fragments_csv(slab):
    case, summary, frags, thrown, out = slab
    block = summary["debris"]
    free = frags[frags["held"] == 0]
    assert np.array_equal(thrown["id"], free["id"]) and block["thrown"] == len(thrown) > 5
    assert block["held"] == np.count_nonzero(frags["held"])
    for axis in "xyz":
        assert np.array_equal(thrown[f"launch_{axis}_m"], free[f"{axis}_m"])
        assert np.array_equal(thrown[f"launch_v{axis}_m_s"], free[f"v{axis}_m_s"])
    assert block["ground_z_m"] == 0.0  # the slab's lowest point
    assert block["centre_m"] == pytest.approx([case.geometry.length / 2, case.geometry.width / 2], rel=1e-12)
    plan = np.column_stack([thrown["landing_x_m"], thrown["landing_y_m"]])
    assert np.allclose(thrown["range_m"], np.linalg.norm(plan - block["centre_m"], axis=1), rtol=1e-9)
    assert np.allclose(thrown["impact_energy_J"], 0.5 * thrown["mass_kg"] * thrown["impact_speed_m_s"] ** 2,
                       rtol=1e-9)
    # drag only takes energy: the impact energy is at most the launch energy plus m g (z0 -
    # ground), and drag's power m k |v|^3 takes at most m k v_max^3 T over the flight time T,
    # v_max = sqrt(2 E / m) the speed of all of it (measured: 1e-4 to 1.3e-3 of it taken)
    m = free["mass_kg"]
    launch = 0.5 * m * free["speed_m_s"] ** 2 + m * G * free["z_m"]
    k = debris.drag_factor(m, free["volume_m3"], case.debris.C_D, case.debris.air_density)
    assert np.all(thrown["impact_energy_J"] <= launch * (1 + 1e-9))
    taken = launch - thrown["impact_energy_J"]
    assert np.all(taken <= m * k * np.sqrt(2 * launch / m) ** 3 * thrown["flight_time_s"])
    assert np.all(thrown["flight_time_s"] > 0)
    assert block["hazardous"] == np.count_nonzero(thrown["hazardous"]) == 0  # mJ, far below 79 J
    assert block["hazard_distance_m"] == 0.0
    assert block["largest_range_m"] == pytest.approx(thrown["range_m"].max(), rel=1e-9)
    for name in ("debris_map.png", "fragment_masses.png", "fragments.png"):
        assert (out / "figures" / name).stat().st_size > 10_000, name


def test_a_2d_run_has_fragments_csv_and_no_debris(tmp_path):
    result = dolfrag_cli("run", "spall-bar", "--quiet", "--out", tmp_path, "--set", "mesh.size=0.01",
                         "--set", "time.end=2e-6", "--set", "output.fields=0", "--set", "output.figures=false")
    assert result.returncode == 0, result.stderr
    header = (tmp_path / "fragments.csv").read_text().splitlines()[0].split(",")
    assert header[1] == "mass_kg_per_m" and "z_m" not in header
    assert not (tmp_path / "debris.csv").exists()
    assert "debris" not in json.loads((tmp_path / "summary.json").read_text())


def test_debris_defaults_are_the_ddesb_criterion_and_still_air():
    options = load_case("slab-3d-scabbing").debris
    assert (options.enabled, options.C_D, options.air_density, options.ground_z) == (True, 1.0, 1.225, None)
    # 79 J and 1 per 600 ft^2 = 55.74 m^2 (DDESB Technical Paper 13)
    assert options.hazard_energy == 79.0 and options.hazard_area == pytest.approx(600 * 0.3048**2, abs=0.05)
    assert load_case("slab-3d-scabbing", ["debris.ground_z=-5"]).debris.ground_z == -5.0
