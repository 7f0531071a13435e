"""Fragments (post/fragments.py) from hand-made link states on a 0.1 x 0.02 m rectangle."""
import json
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from conftest import mpirun, rectangle
from dolfrag import bulk, compat, mesh, space as spaces
from dolfrag.interface import links as link_table
from dolfrag.post.fragments import breaks_along, fragments

LENGTH, WIDTH, H = 0.1, 0.02, 0.005  # m
# Sums of ~10^3 positive terms in a different order differ by ~1e-14 relative.
ROUNDOFF = 1e-12


def assemble(comm):
    """Space, links and the lumped mass (rho = 2400 kg/m^3) of the rectangle."""
    domain = mesh.build(rectangle(LENGTH, WIDTH), H, comm)
    space = spaces.create(domain)
    material = SimpleNamespace(E=30e9, nu=0.2, rho=2400.0, hypothesis="plane_strain")
    ops = bulk.assemble(space, domain, SimpleNamespace(material=material, materials={}))
    return space, link_table.build(space), ops.m.x.array.copy()


def bands(space, planes):
    """Band of every local cell (0 left of planes[0], ...) by its centroid x."""
    return np.searchsorted(planes, space.x[space.cell_dofs].mean(axis=1)[:, 0])


def cell_of_dof(space):
    cell = np.empty(len(space.dof_vertex), dtype=np.int64)
    cell[space.cell_dofs.ravel()] = np.repeat(np.arange(len(space.cell_dofs)), space.gdim + 1)
    return cell


def cut(space, links, planes):
    """Broken mask breaking every link whose two cells lie on either side of a plane x = c."""
    band, cell = bands(space, planes), cell_of_dof(space)
    return band[cell[links.dof_A]] != band[cell[links.dof_B]]


def hold_one_link(space, links, broken):
    """``broken`` with, on every cut facet, the link at its upper vertex (larger y) holding:
    a rule from geometry, so the same links hold whichever rank keeps them."""
    tdim = space.mesh.topology.dim
    verts = compat.adjacency_array(space.mesh.topology.connectivity(tdim - 1, 0), tdim)
    y = space.vertex_x[:, 1]
    return broken & (y[links.vertex] < y[verts[links.facet]].max(axis=1))


def band_fields(space, planes):
    """Velocity v_x = (-1)^band m/s and displacement u_x = 1e-3 band m of each dof."""
    band = bands(space, planes)[cell_of_dof(space)]
    v, u = np.zeros((len(band), space.gdim)), np.zeros((len(band), space.gdim))
    v[:, 0], u[:, 0] = (-1.0) ** band, 1e-3 * band
    return v.ravel(), u.ravel()


@pytest.fixture(scope="module")
def setup():
    return assemble(MPI.COMM_SELF)


def cell_masses(space, mass):
    return mass.reshape(-1, space.gdim)[space.cell_dofs, 0].sum(axis=1)


def test_nothing_broken_is_one_fragment_with_total_mass_at_the_centre(setup):
    space, links, mass = setup
    v, _ = band_fields(space, [LENGTH / 2])
    frags = fragments(space, links, np.zeros(len(links), bool), mass, v)
    assert len(frags) == 1 and frags.cells[0] == len(space.cell_dofs)
    m, left = cell_masses(space, mass), bands(space, [LENGTH / 2]) == 0
    # mean velocity is momentum / mass: (m_left - m_right) / m in x for v_x = +1 / -1
    v_x = (m[left].sum() - m[~left].sum()) / m.sum()
    assert np.allclose(frags.velocity[0], [v_x, 0.0], rtol=0, atol=ROUNDOFF)
    assert frags.mass[0] == pytest.approx(mass[::2].sum(), rel=ROUNDOFF)
    assert frags.mass[0] == pytest.approx(2400.0 * LENGTH * WIDTH, rel=ROUNDOFF)
    # vertex quadrature integrates x exactly on P1 cells: the lumped-mass centroid is exact
    assert np.allclose(frags.centroid[0], [LENGTH / 2, WIDTH / 2], rtol=0, atol=ROUNDOFF * LENGTH)
    assert np.allclose(frags.bbox_min[0], 0.0) and np.allclose(frags.bbox_max[0], [LENGTH, WIDTH])
    assert breaks_along(frags).distance.shape == (0,)


def test_cut_at_mid_length_gives_two_halves_with_their_masses_and_velocities(setup):
    space, links, mass = setup
    planes = [LENGTH / 2]
    v, _ = band_fields(space, planes)
    frags = fragments(space, links, cut(space, links, planes), mass, v)
    left = bands(space, planes) == 0
    m = cell_masses(space, mass)
    assert len(frags) == 2
    assert np.allclose(frags.mass, [m[left].sum(), m[~left].sum()], rtol=ROUNDOFF, atol=0)
    assert np.array_equal(frags.cells, [left.sum(), (~left).sum()])
    assert np.allclose(frags.velocity, [[1.0, 0.0], [-1.0, 0.0]], rtol=0, atol=ROUNDOFF)
    gap = breaks_along(frags).distance
    assert gap.shape == (1,) and abs(gap[0] - LENGTH / 2) < H  # a jagged cut, within a cell
    assert breaks_along(frags, free_end=LENGTH).distance == pytest.approx(LENGTH - gap)


def test_each_cell_knows_its_fragment(setup):
    space, links, mass = setup
    planes = [LENGTH / 4, LENGTH / 2, 3 * LENGTH / 4]
    frags, of_cell = fragments(space, links, cut(space, links, planes), mass, np.zeros_like(mass),
                               of_cells=True)
    # the fragments are ordered by centroid x: fragment i is the band i
    assert np.array_equal(of_cell, bands(space, planes)[:space.n_owned_cells])
    assert np.array_equal(np.bincount(of_cell), frags.cells)


def test_displacement_moves_centroid_and_bbox_of_the_displaced_fragment(setup):
    space, links, mass = setup
    planes = [LENGTH / 2]
    v, u = band_fields(space, planes)
    still = fragments(space, links, cut(space, links, planes), mass, v)
    moved = fragments(space, links, cut(space, links, planes), mass, v, displacement=u)
    shift = np.array([[0.0, 0.0], [1e-3, 0.0]])  # m, u_x = 1e-3 on the right half
    for name in ("centroid", "bbox_min", "bbox_max"):
        assert np.allclose(getattr(moved, name), getattr(still, name) + shift, rtol=0, atol=1e-15)


def test_three_cuts_give_four_fragments_in_order_along_the_bar(setup):
    space, links, mass = setup
    planes = [LENGTH / 4, LENGTH / 2, 3 * LENGTH / 4]
    v, _ = band_fields(space, planes)
    frags = fragments(space, links, cut(space, links, planes), mass, v)
    band, m = bands(space, planes), cell_masses(space, mass)
    assert len(frags) == 4
    expected = np.bincount(band, weights=m)
    assert np.allclose(frags.mass, expected, rtol=ROUNDOFF, atol=0)
    assert np.allclose(frags.velocity[:, 0], [1.0, -1.0, 1.0, -1.0], rtol=0, atol=ROUNDOFF)
    assert np.all(np.diff(frags.centroid[:, 0]) > 0)
    along = breaks_along(frags)
    assert np.all(np.abs(along.distance - planes) < H) and np.all(np.isnan(along.time))
    from_right = breaks_along(frags, free_end=LENGTH).distance
    assert np.allclose(from_right, LENGTH - along.distance[::-1])


def plane_break_times(space, links, planes, times, last_link_late=0.0):
    """Break time of every link cut by planes[i]: times[i] (NaN for intact links); the
    link at each cut facet's upper vertex ``last_link_late`` later."""
    band, cell = bands(space, planes), cell_of_dof(space)
    a, b = band[cell[links.dof_A]], band[cell[links.dof_B]]
    t = np.where(a != b, np.append(times, np.nan)[np.minimum(a, b)], np.nan)
    late = ~hold_one_link(space, links, np.ones(len(links), bool))
    return t + last_link_late * late


def test_a_break_completes_when_the_last_link_between_two_fragments_breaks(setup):
    space, links, mass = setup
    planes, times = [LENGTH / 4, LENGTH / 2, 3 * LENGTH / 4], [3e-6, 1e-6, 2e-6]
    broken = cut(space, links, planes)
    frags = fragments(space, links, broken, mass, np.zeros_like(mass),
                      break_time=plane_break_times(space, links, planes, times, 0.5e-6))
    assert len(frags.neighbours) == 3 and np.array_equal(frags.neighbours, [[0, 1], [1, 2], [2, 3]])
    # every plane completes when its late links break; read from the free end x = LENGTH
    assert breaks_along(frags, free_end=LENGTH).time == pytest.approx([2.5e-6, 1.5e-6, 3.5e-6], rel=1e-15)


def test_everything_broken_gives_one_fragment_per_cell(setup):
    space, links, mass = setup
    frags = fragments(space, links, np.ones(len(links), bool), mass, np.zeros_like(mass))
    m = cell_masses(space, mass)
    assert len(frags) == len(space.cell_dofs) and np.all(frags.cells == 1)
    assert np.allclose(np.sort(frags.mass), np.sort(m), rtol=ROUNDOFF, atol=0)
    centres = space.x[space.cell_dofs].mean(axis=1)  # uniform lumped mass: vertex mean
    # symmetric cells share a centroid x up to round-off: order by x, then y, equal x
    # meaning equal to 1e-9 of the body size (fragments.ORDER_DIGITS)
    key = np.round(centres / LENGTH, 9)
    expected = centres[np.lexsort(key.T[::-1])]
    assert np.allclose(frags.centroid, expected, rtol=0, atol=ROUNDOFF * LENGTH)


def test_a_facet_with_one_link_holding_stays_connected(setup):
    space, links, mass = setup
    cut_all = cut(space, links, [LENGTH / 2])
    broken = hold_one_link(space, links, cut_all)
    assert np.count_nonzero(broken) == len(np.unique(links.facet[cut_all]))  # one of two links
    frags = fragments(space, links, broken, mass, np.zeros_like(mass))
    assert len(frags) == 1


def test_to_dict_is_json_ready_and_broken_is_checked(setup):
    space, links, mass = setup
    frags = fragments(space, links, cut(space, links, [LENGTH / 2]), mass, np.zeros_like(mass))
    data = json.loads(json.dumps(frags.to_dict()))
    assert data["count"] == 2 and len(data["centroid"][0]) == 2
    with pytest.raises(ValueError, match="one flag per owned link"):
        fragments(space, links, np.zeros(len(links) + 1, bool), mass, np.zeros_like(mass))


@pytest.mark.mpi
def test_same_fragments_on_one_and_two_ranks(tmp_path):
    serial, parallel = tmp_path / "one.npz", tmp_path / "two.npz"
    mpirun(["tests/mpi_fragments.py", serial], n=1)
    mpirun(["tests/mpi_fragments.py", parallel], n=2)
    one, two = np.load(serial), np.load(parallel)
    assert sorted(one.files) == sorted(two.files)
    for name in set(one.files) - {"n_shared", "shared_one", "shared_both"}:
        if name.endswith(("cells", "count")):
            assert np.array_equal(one[name], two[name]), name
        else:
            assert np.allclose(one[name], two[name], rtol=ROUNDOFF, atol=ROUNDOFF * LENGTH), name
    assert len(one["chain_mass"]) == 4 and len(one["half_mass"]) == 2 and one["held_count"] == 1
    # 2 ranks: a facet holding by one link, kept by one rank, joins its cells as if both held
    n_cells = one["half_cells"].sum()
    assert two["n_shared"] >= 1 and two["shared_one"] == two["shared_both"] < n_cells
