"""fragments.csv's table (post/fragment_table.py) from hand-made cuts: volumes, masses,
energies, largest dimensions, when each piece came free, its material group and whether a
support holds it."""
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI
from scipy.spatial.distance import pdist

from conftest import ROOT, rectangle
from dolfrag import bulk, mesh, space as spaces
from dolfrag.interface import links as link_table
from dolfrag.post.figures import round_length
from dolfrag.post.fragment_table import HULL_ABOVE, columns, fragment_table, largest_dimension, rows
from dolfrag.post.fragments import Fragments, fragments
from test_fragments import LENGTH, ROUNDOFF, WIDTH, band_fields, cut, plane_break_times

RHO = 2400.0  # kg/m^3
STEEL = SimpleNamespace(E=200e9, nu=0.3, rho=7850.0, hypothesis="plane_strain")
NO_SUPPORTS = SimpleNamespace(clamped=(), simple=(), rollers=())


def assemble(geometry, size, groups=None):
    """(domain, space, links, lumped mass) on one rank."""
    domain = mesh.build(geometry, size, MPI.COMM_SELF)
    space = spaces.create(domain)
    material = SimpleNamespace(E=30e9, nu=0.2, rho=RHO, hypothesis="plane_strain")
    ops = bulk.assemble(space, domain, SimpleNamespace(material=material, materials=groups or {}))
    return domain, space, link_table.build(space), ops.m.x.array.copy()


@pytest.fixture(scope="module")
def bar():
    return assemble(rectangle(LENGTH, WIDTH), 0.005)


def table_of(domain, space, links, mass, broken, supports=NO_SUPPORTS, break_time=None, velocity=None):
    velocity = np.zeros_like(mass) if velocity is None else velocity
    frags, of_cell = fragments(space, links, broken, mass, velocity, break_time=break_time, of_cells=True)
    return frags, fragment_table(space, domain, supports, mass, frags, of_cell)


def test_a_piece_came_free_when_its_last_neighbour_separated():
    # 0 - 1 - 2 in a chain, 3 alone: 1 came free when its later neighbour let go
    frags = Fragments(*(np.zeros(4) for _ in range(6)), neighbours=np.array([[0, 1], [1, 2]]),
                      separated_at=np.array([2e-6, 5e-6]))
    assert np.array_equal(frags.came_free(), [2e-6, 5e-6, 5e-6, np.nan], equal_nan=True)


def test_largest_dimension_is_the_diameter_of_the_points():
    assert largest_dimension(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])) == pytest.approx(np.sqrt(2))
    assert largest_dimension(np.array([[0.3, 0.2, 0.1]])) == 0.0
    points = np.random.default_rng(1).normal(size=(5 * HULL_ABOVE, 3))  # taken over the hull's vertices
    assert largest_dimension(points) == pytest.approx(pdist(points).max(), rel=1e-15)


def test_table_of_four_bands_gives_their_areas_masses_sizes_and_release_times(bar):
    domain, space, links, mass = bar
    planes = [LENGTH / 4, LENGTH / 2, 3 * LENGTH / 4]
    v, _ = band_fields(space, planes)  # v_x = +1, -1, +1, -1 m/s
    times = plane_break_times(space, links, planes, [3e-6, 1e-6, 2e-6], 0.5e-6)  # last links 0.5 us late
    frags, table = table_of(domain, space, links, mass, cut(space, links, planes), break_time=times, velocity=v)
    assert len(table) == 4
    # the cells tile the rectangle: areas and masses sum to the body's to round-off
    assert table.volume.sum() == pytest.approx(LENGTH * WIDTH, rel=ROUNDOFF)
    assert table.mass.sum() == pytest.approx(RHO * LENGTH * WIDTH, rel=ROUNDOFF)
    assert np.allclose(table.mass, RHO * table.volume, rtol=ROUNDOFF, atol=0)  # one material, lumped mass exact
    assert np.allclose(table.speed, 1.0, rtol=0, atol=ROUNDOFF)
    assert np.allclose(table.kinetic_energy, 0.5 * table.mass, rtol=ROUNDOFF, atol=0)  # J/m at 1 m/s
    # the diameter lies between the bbox's longest side and its diagonal (a jagged cut)
    extent = frags.bbox_max - frags.bbox_min
    assert np.all(table.size >= extent.max(axis=1) - 1e-15)
    assert np.all(table.size <= np.linalg.norm(extent, axis=1) + 1e-15)
    # band 0 let go of band 1 at 3.5 us; band 1 of band 2 at 1.5 us, band 2 of band 3 at 2.5 us
    assert table.came_free == pytest.approx([3.5e-6, 3.5e-6, 2.5e-6, 2.5e-6], rel=1e-15)
    assert table.group == ("concrete",) * 4 and not table.held.any()


def test_one_piece_when_nothing_broke_never_came_free_and_a_clamped_edge_holds_it(bar):
    domain, space, links, mass = bar
    _, table = table_of(domain, space, links, mass, np.zeros(len(links), bool),
                        SimpleNamespace(clamped=("left",), simple=(), rollers=()))
    assert len(table) == 1 and np.isnan(table.came_free[0]) and table.held[0]


def test_only_the_pieces_on_a_clamped_or_simple_face_are_held_rollers_let_go(bar):
    domain, space, links, mass = bar
    broken = cut(space, links, [LENGTH / 4, 3 * LENGTH / 4])
    _, table = table_of(domain, space, links, mass, broken, SimpleNamespace(clamped=("left",), simple=("right",),
                                                                            rollers=("bottom", "top")))
    assert np.array_equal(table.held, [True, False, True])


def test_the_group_is_the_one_holding_most_of_the_mass():
    geometry = SimpleNamespace(kind="file", tdim=2, file=str(ROOT / "meshes" / "bar-two-materials.geo"))
    domain, space, links, mass = assemble(geometry, 0.005, {"steel": STEEL})
    # concrete for x < 0.1 m, steel beyond: the middle piece (0.02 .. 0.13 m) is mostly concrete by
    # volume (0.08 m of 0.11) but steel by mass (7850 x 0.03 > 2400 x 0.08)
    _, table = table_of(domain, space, links, mass, cut(space, links, [0.02, 0.13]))
    assert table.group == ("concrete", "steel", "steel")
    assert table.volume[1] == pytest.approx(0.11 * 0.05, abs=0.005 * 0.05)  # within a cell of the planes
    assert table.mass.sum() == pytest.approx((RHO * 0.1 + 7850.0 * 0.2) * 0.05, rel=ROUNDOFF)


def test_rows_follow_the_columns_with_units_per_metre_in_2d(bar):
    domain, space, links, mass = bar
    _, table = table_of(domain, space, links, mass, cut(space, links, [LENGTH / 2]))
    header = columns(2)
    assert header[:3] == ["id", "mass_kg_per_m", "volume_m2"] and "kinetic_energy_J_per_m" in header
    assert columns(3)[:3] == ["id", "mass_kg", "volume_m3"] and "vz_m_s" in columns(3)
    table_rows = rows(table)
    assert len(table_rows) == 2 and all(len(row) == len(header) for row in table_rows)
    assert [row[header.index("group")] for row in table_rows] == ["concrete", "concrete"]


def test_the_scale_bar_of_fragments_png_is_a_round_length():
    assert [round_length(x) for x in (0.05, 0.049, 0.3, 7.0, 1.0)] == pytest.approx([0.05, 0.02, 0.2, 5.0, 1.0])
