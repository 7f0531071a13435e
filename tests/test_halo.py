"""benchmarks/halo.py: ghost layers of star partitions, counted by hand on structured meshes and
against DOLFINx's own distribution."""
import itertools
import sys

import numpy as np
import pytest

from conftest import ROOT, mpirun

sys.path.insert(0, str(ROOT / "benchmarks"))
import halo  # noqa: E402


def grid_triangles(n):
    """n x n unit squares, each cut by its (i, j)-(i+1, j+1) diagonal: (2 n^2, 3) vertices
    and (2 n^2, 2) centroids (in square widths)."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    v = lambda a, b: a + (n + 1) * b  # noqa: E731
    lower = np.column_stack([v(i, j), v(i + 1, j), v(i + 1, j + 1)])
    upper = np.column_stack([v(i, j), v(i + 1, j + 1), v(i, j + 1)])
    centre = np.column_stack([i + 0.5, j + 0.5])
    return np.concatenate([lower, upper]), np.concatenate([centre, centre])


def kuhn_tetrahedra(n):
    """n^3 unit cubes, each cut into the 6 tetrahedra around its main diagonal (Kuhn):
    (6 n^3, 4) vertices and the x index of each tetrahedron's cube."""
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(n)] * 3, indexing="ij"))
    v = lambda c: c[0] + (n + 1) * (c[1] + (n + 1) * c[2])  # noqa: E731
    tets = []
    for order in itertools.permutations(range(3)):
        corner, path = np.array([i, j, k]), []
        path.append(v(corner))
        for axis in order:
            corner = corner.copy()
            corner[axis] += 1
            path.append(v(corner))
        tets.append(np.column_stack(path))
    return np.concatenate(tets), np.tile(i, 6)


def test_quadrants_of_a_triangle_grid_ghost_4c_plus_their_corner_star():
    # Split at x = y = c: each quadrant ghosts the 2c triangles along each of its two cut
    # edges (both triangles of every square on the far side touch the cut line), plus the
    # triangles of the centre vertex's star in the diagonally opposite quadrant: 2 for the
    # lower-left / upper-right quadrants (the diagonal runs through the centre), 1 for the others.
    n, c = 8, 4
    c2v, centre = grid_triangles(n)
    owner = (centre[:, 0] > c).astype(int) + 2 * (centre[:, 1] > c)  # 0 LL, 1 LR, 2 UL, 3 UR
    h = halo.star_halo(c2v, owner, 4)
    assert list(h.owned) == [2 * c * c] * 4
    assert list(h.ghosts) == [4 * c + 2, 4 * c + 1, 4 * c + 1, 4 * c + 2]
    assert list(h.neighbours) == [3, 3, 3, 3]  # the corner makes the diagonal quadrant a neighbour
    assert h.sent.sum() == h.ghosts.sum()
    assert list(h.bytes_received(tdim=2, gdim=2)) == list(h.ghosts * 3 * 2 * 8)


def test_halves_of_a_kuhn_cube_grid_ghost_one_layer_of_6_n2_tetrahedra():
    # every Kuhn tetrahedron holds both ends of its cube's diagonal, so all 6 n^2 tetrahedra
    # of the cube layer on the other side of the cut plane touch it; no other does
    n = 6
    c2v, column = kuhn_tetrahedra(n)
    h = halo.star_halo(c2v, (column >= n // 2).astype(int), 2)
    assert list(h.owned) == [3 * n**3] * 2
    assert list(h.ghosts) == [6 * n * n] * 2
    assert list(h.sent) == [6 * n * n] * 2
    assert list(h.neighbours) == [1, 1]


def test_star_work_of_column_parts_is_the_vertex_degrees_they_own_over_3():
    # 6 x 6 grid in three column strips; a vertex goes to the lowest part around it, so part 0
    # owns vertex columns x = 0, 1, 2, part 1 x = 3, 4, part 2 x = 5, 6. Vertex degrees
    # (triangles around it): 6 inside, 3 on an edge, 2 / 1 at the corners on / off the
    # diagonal: a boundary column sums to 2 + 1 + 5 * 3 = 18, an inner one to 3 + 3 + 5 * 6 = 36.
    n = 6
    c2v, centre = grid_triangles(n)
    owner = (centre[:, 0] > 2).astype(int) + (centre[:, 0] > 4)
    x = np.arange((n + 1) ** 2) % (n + 1)
    h = halo.star_halo(c2v, owner, 3, vertex_owner=(x > 2).astype(int) + (x > 4))
    assert list(h.star_cells) == [(18 + 36 + 36) / 3, (36 + 36) / 3, (36 + 18) / 3]


def test_random_vertex_owners_own_a_cell_around_their_vertex():
    c2v, centre = grid_triangles(6)
    owner = (centre[:, 0] > 2).astype(int) + (centre[:, 1] > 3)
    PV, _ = halo.vertex_parts(halo.cell_vertex_incidence(c2v), owner, 3)
    vertex_owner = halo.random_vertex_owners(PV, seed=3)
    assert PV[vertex_owner, np.arange(PV.shape[1])].all()
    shared = np.diff(PV.tocsc().indptr) > 1
    assert len(np.unique(vertex_owner[shared])) == 3  # not always the same part


@pytest.mark.mpi
@pytest.mark.parametrize("dim,size", [("2d", 0.01), ("3d", 0.01)])
def test_halo_counts_are_dolfinx_ghost_layer_on_two_ranks(dim, size, tmp_path):
    out = tmp_path / "halo.npz"
    mpirun(["tests/mpi_halo.py", dim, size, out], n=2)
    r = np.load(out)
    for key in ("owned", "ghosts", "neighbours", "sent"):
        assert list(r[key]) == list(r[f"counted_{key}"]), key
    # a ghost cell's DG-P1 dofs are the ghost dofs: (tdim + 1) per ghost cell
    assert list(r["dof_ghosts"]) == list(r["ghosts"] * (int(r["tdim"]) + 1))
    assert r["vertex_owner_eligible"].all()
