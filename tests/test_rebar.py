"""Rebars: the cable law, the strain operator on a mesh, and a cracked section held by bars."""
from types import SimpleNamespace

import numpy as np
import pytest

import dolfrag
from conftest import rectangle
from dolfrag import mesh, rebar, space as spaces
from dolfrag.config import load_case

E_S, AREA, F_Y = 200e9, 5.236e-4, 500e6


def test_cable_carries_no_compression_and_E_A_eps_in_tension():
    eps = np.array([-1e-3, 0.0, 1e-3, 4e-3])
    N, eps_p, k = rebar.cable_force(eps, np.zeros(4), E_S, AREA, F_Y)
    assert N[:2].tolist() == [0.0, 0.0]
    assert N[2] == pytest.approx(E_S * AREA * 1e-3, rel=1e-12)
    assert N[3] == pytest.approx(AREA * F_Y, rel=1e-12)  # 4e-3 > f_y / E_s = 2.5e-3: yields
    assert eps_p.tolist() == pytest.approx([0, 0, 0, 4e-3 - F_Y / E_S], abs=1e-15)
    assert k.tolist() == [0.0, 0.0, E_S * AREA, 0.0]


def test_yielded_cable_unloads_elastically_and_goes_slack():
    eps_p = np.array([1.5e-3])  # after yielding to eps = 4e-3
    N_unload = rebar.cable_force(np.array([3e-3]), eps_p, E_S, AREA, F_Y)[0]
    N_slack = rebar.cable_force(np.array([1e-3]), eps_p, E_S, AREA, F_Y)[0]
    assert N_unload[0] == pytest.approx(E_S * AREA * 1.5e-3, rel=1e-12)
    assert N_slack[0] == 0.0


@pytest.fixture(scope="module")
def wall_bars(comm):
    geometry = SimpleNamespace(**vars(rectangle(0.3, 0.1)), thickness=None)
    domain = mesh.build(geometry, 0.01, comm)
    space = spaces.create(domain)
    layers = SimpleNamespace(faces=("bottom", "top"), cover=0.03, diameter=0.01, spacing=0.15, direction="x")
    lines, areas = rebar.layer_polylines(layers, geometry, 2)
    return space, rebar.Rebars(space, lines, areas, E_S, None, 7850.0, 0.01, comm), lines, areas


def test_layers_sit_at_the_cover_with_the_area_per_metre_of_depth(wall_bars):
    _, _, lines, areas = wall_bars
    assert [line[:, 1].tolist() for line in lines] == [[0.03, 0.03], [0.07, 0.07]]
    assert areas == pytest.approx(np.pi * 0.01**2 / 4 / 0.15, rel=1e-12)


def test_strain_operator_reads_stretch_not_shear_or_translation(wall_bars):
    space, bars, _, _ = wall_bars
    x = space.x
    stretch, shear, shift = (np.zeros(x.size) for _ in range(3))
    stretch[0::2] = 1e-3 * x[:, 0]
    shear[1::2] = 1e-3 * x[:, 0]
    shift[0::2], shift[1::2] = 1e-3, -2e-3
    # P1 reproduces linear fields exactly: round-off only
    assert bars.B @ stretch == pytest.approx(np.full(bars.B.shape[0], 1e-3), rel=1e-9)
    assert np.abs(bars.B @ shear).max() < 1e-15
    assert np.abs(bars.B @ shift).max() < 1e-12


@pytest.mark.parametrize("layers", ["wall_bars", "box_bars"])  # 2D and 3D
def test_bar_mass_is_lumped_whole(layers, request, comm):
    space, bars, lines, areas = request.getfixturevalue(layers)
    m = np.zeros(space.x.size)
    bars.add_mass(m)
    d = space.gdim  # each component carries the mass
    owned = comm.allreduce(m[:space.n_owned_dofs * d].sum()) / d
    expected = 7850.0 * sum(a * np.linalg.norm(line[1] - line[0]) for line, a in zip(lines, areas))
    assert owned == pytest.approx(expected, rel=1e-12)


PULLED_BAR = """
[geometry]
kind = "rectangle"
length = 0.1
width = 0.01
structured = true
[mesh]
size = 0.005
[material]
E = 35e9
nu = 0.2
rho = 2350.0
[interface]
law = "rccm"
sigma_c = 1e6
[load]
boundary = "right"
signal = "table"
file = "pull.csv"
[supports]
clamped = ["left"]
[time]
end = 200e-6
[output]
fields = 0
figures = false
"""
BARS = """
[rebar]
faces = ["bottom", "top"]
cover = 0.0025
diameter = 0.005
spacing = 0.15
"""


def pulled_bar(tmp_path, bars):
    """A 0.1 m x 0.01 m bar, two rows of cells, clamped on the left and pulled on the right
    by 2 MPa (reached in 20 us, then held), twice its strength. Each bar runs through the
    middle of a row of the structured mesh, so it crosses every cell of its row."""
    (tmp_path / "pull.csv").write_text("t,p\n0,0\n20e-6,-2e6\n1,-2e6\n")
    name = "reinforced" if bars else "plain"
    path = tmp_path / f"{name}.toml"
    path.write_text(PULLED_BAR + (BARS if bars else ""))
    summary = dolfrag.run(load_case(path), tmp_path / name, quiet=True)
    history = np.genfromtxt(tmp_path / name / "history.csv", delimiter=",", names=True)
    return summary, history


def test_cracked_plain_section_separates_while_bars_hold_it(tmp_path):
    plain, h_plain = pulled_bar(tmp_path, bars=False)
    held, h_held = pulled_bar(tmp_path, bars=True)
    assert plain["broken_links"] > 0 and held["broken_links"] > 0
    assert plain["fragments"]["count"] >= 2
    # plain: the loose end accelerates for good (p H / m_piece); held: the bars stop it
    # (measured: 65 m/s against 0.5 m/s at 200 us)
    assert h_plain["vx_right_m_s"][-1] > 10.0
    assert abs(h_held["vx_right_m_s"][-1]) < 0.05 * h_plain["vx_right_m_s"][-1]
    # with the concrete cut, the two bars carry the whole pull, p H / 2 = 10 kN/m each; more
    # while the load is transferred dynamically (measured 2.4 x: a sudden transfer doubles
    # it, and the breaking concrete gives back its strain energy). Elastic bars (no f_y).
    assert held["rebar"]["peak_force_N"] >= 2e6 * 0.01 / 2
    # history.csv samples every 10th step (~4 us, a sixtieth of the bar-mass period): it
    # never exceeds the run's peak, and comes within 10 % of it
    sampled = h_held["rebar_force_max_N"].max()
    assert 0.9 * held["rebar"]["peak_force_N"] <= sampled <= held["rebar"]["peak_force_N"]


BOX = SimpleNamespace(kind="box", tdim=3, length=0.2, width=0.2, thickness=0.05)
AREA_3D = np.pi * 0.008**2 / 4  # m^2, one 8 mm bar


@pytest.fixture(scope="module")
def box_bars(comm):
    """3D: two crossing layers (x and y bars, 4 each way) near the z = 0 face of a small slab."""
    space = spaces.create(mesh.build(BOX, 0.02, comm))
    layers = SimpleNamespace(faces=("front",), cover=0.015, diameter=0.008, spacing=0.05, direction="xy")
    lines, areas = rebar.layer_polylines(layers, BOX, 3)
    return space, rebar.Rebars(space, lines, areas, E_S, None, 7850.0, 0.02, comm), lines, areas


def biaxial_stretch(space, eps):
    """u = eps (x, y, 0): a uniform stretch in the plane of the layers (P1 holds it exactly)."""
    u = np.zeros(space.x.size)
    u[0::3], u[1::3] = eps * space.x[:, 0], eps * space.x[:, 1]
    return u


def test_crossing_layers_in_a_box_read_the_in_plane_stretch(box_bars, comm):
    space, bars, lines, areas = box_bars
    assert len(lines) == 8  # 4 bars each way, 50 mm apart across 0.2 m
    assert {line[0, 2] for line in lines} == {0.015, 0.023}  # y bars one diameter further in
    assert areas == pytest.approx(AREA_3D, rel=1e-12)  # one bar each in 3D, not per metre
    assert comm.allreduce(int(bars.counted.sum())) > 0
    assert bars.B @ biaxial_stretch(space, 1e-3) == pytest.approx(np.full(bars.B.shape[0], 1e-3), rel=1e-9)


def test_a_3d_layer_carries_n_E_s_A_eps_across_any_section_and_nothing_in_compression(box_bars, comm):
    """The bars' forces on the cells left of a section x = X (cell centroids; DG dofs belong
    to one cell) are what the bars crossing it carry: 4 x-bars, each E_s A eps, whatever
    the cut (a bar zig-zagging across a jagged cut gives +N - N + N); the y-bars, along y
    exactly, add nothing along x."""
    space, bars, _, _ = box_bars
    if comm.size > 1:
        pytest.skip("sums the force on local cells: serial")
    eps = 1e-4  # elastic: no f_y here
    f, k = bars.forces(biaxial_stretch(space, eps), commit=True)
    # every segment reads eps exactly (P1): round-off only
    assert bars.force_max == pytest.approx(E_S * AREA_3D * eps, rel=1e-9)
    assert np.all(k == E_S * AREA_3D)
    centroid_x = space.x[space.cell_dofs[:space.n_owned_cells], 0].mean(axis=1)
    for X in (0.05, 0.1, 0.137):
        left = space.cell_dofs[:space.n_owned_cells][centroid_x < X].ravel()
        assert f[3 * left].sum() == pytest.approx(4 * E_S * AREA_3D * eps, rel=1e-9), X
        assert abs(f[3 * left + 2].sum()) < 1e-9 * E_S * AREA_3D * eps  # in-plane bars: no z force
    squeeze, k = bars.forces(biaxial_stretch(space, -eps), commit=False)
    assert np.all(squeeze == 0.0) and np.all(k == 0.0)  # tension only


def test_slab_layers_are_spacing_apart_centred_on_the_face():
    # the slab: 1 m wide, bars every 0.15 m -> 6 bars 0.15 apart, 0.125 m from the edges
    # (0.167 m apart if spread evenly: 10 % less steel per metre than asked)
    slab = SimpleNamespace(kind="box", tdim=3, length=1.0, width=1.0, thickness=0.1)
    layers = SimpleNamespace(faces=("front", "back"), cover=0.03, diameter=0.01, spacing=0.15, direction="xy")
    lines, _ = rebar.layer_polylines(layers, slab, 3)
    assert len(lines) == 24  # 6 bars, 2 directions, 2 faces
    x_bars = [line for line in lines if line[0, 0] != line[1, 0]]
    y_at = sorted({round(line[0, 1], 12) for line in x_bars})
    assert y_at == pytest.approx(0.125 + 0.15 * np.arange(6), abs=1e-12)
    assert sorted({round(line[0, 2], 12) for line in lines}) == [0.03, 0.04, 0.06, 0.07]
