"""The link table (interface/links.py conventions) in 2D and 3D, on 1 and 2 ranks."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import box, mpirun, rectangle
from dolfrag import compat, mesh, space as spaces
from dolfrag.interface import links as link_table
from dolfrag.space import facet_measures

CASES = {"2d": (rectangle(), 0.008), "3d": (box(), 0.02)}


@pytest.fixture(scope="module", params=sorted(CASES))
def built(request):
    geometry, size = CASES[request.param]
    domain = mesh.build(geometry, size, MPI.COMM_SELF)
    space = spaces.create(domain)
    return request.param, space, link_table.build(space)


def interior_facets(space):
    tdim = space.mesh.topology.dim
    f2c = space.mesh.topology.connectivity(tdim - 1, tdim)
    interior = np.flatnonzero(np.diff(f2c.offsets) == 2)
    verts = compat.adjacency_array(space.mesh.topology.connectivity(tdim - 1, 0), tdim)[interior]
    return interior, space.vertex_x[verts]


def test_one_link_per_vertex_of_every_interior_facet(built):
    _, space, links = built
    interior, _ = interior_facets(space)
    assert len(links) == space.gdim * len(interior)  # gdim vertices per facet
    pairs = np.unique(np.column_stack([links.facet, links.vertex]), axis=0)
    assert len(pairs) == len(links)


def test_both_copies_of_a_link_sit_at_the_same_point(built):
    _, space, links = built
    assert np.array_equal(space.x[links.dof_A], space.x[links.dof_B])
    assert np.all(links.dof_A != links.dof_B)


def test_unit_normals_point_from_A_to_B(built):
    _, space, links = built
    assert np.allclose(np.linalg.norm(links.normal, axis=1), 1.0, rtol=1e-14)
    cell_of = np.empty(len(space.dof_vertex), dtype=np.int64)
    cell_of[space.cell_dofs.ravel()] = np.repeat(np.arange(len(space.cell_dofs)), space.gdim + 1)
    centre = space.x[space.cell_dofs].mean(axis=1)
    to_B = centre[cell_of[links.dof_B]] - centre[cell_of[links.dof_A]]
    assert np.all(np.einsum("ij,ij->i", to_B, links.normal) > 0)
    tangents = links.tangents
    assert np.allclose(np.einsum("ikj,ij->ik", tangents, links.normal), 0.0, atol=1e-14)


def test_weights_sum_to_the_interior_facet_measure(built):
    _, space, links = built
    _, corners = interior_facets(space)
    assert links.weight.sum() == pytest.approx(facet_measures(corners).sum(), rel=1e-13)


@pytest.mark.mpi
@pytest.mark.parametrize("dim", sorted(CASES))
def test_same_links_and_whole_stars_on_one_and_two_ranks(dim, tmp_path):
    size = str(CASES[dim][1])
    serial, parallel = tmp_path / "one.npz", tmp_path / "two.npz"
    mpirun(["tests/mpi_links.py", dim, size, serial], n=1)
    mpirun(["tests/mpi_links.py", dim, size, parallel], n=2)
    one, two = np.load(serial), np.load(parallel)
    # every cell corner is in exactly one owned star: stars are whole and owned once
    for result in (one, two):
        assert result["star_copies"] == result["n_cells"] * (int(dim[0]) + 1)
    a, b = (np.round(r["table"], 12) for r in (one, two))
    assert len(a) == len(b)
    assert np.array_equal(a[np.lexsort(a.T)], b[np.lexsort(b.T)])
