"""validation/close_in.py's areas on a box of tetrahedra whose chosen cells are known: the
face areas exactly, the through-thickness (breach) area to its sampling."""
import sys

import numpy as np
import pytest
import pyvista as pv

from conftest import ROOT

sys.path.insert(0, str(ROOT / "validation"))
import close_in  # noqa: E402


def _box(length=0.4, width=0.3, thickness=0.15, n=(8, 6, 3)):
    """A box of n bricks, each cut into tetrahedra, corner at the origin."""
    grid = pv.ImageData(dimensions=[k + 1 for k in n]).triangulate()  # unit bricks: float32 points, exact
    grid.points = grid.points.astype(np.float64) * np.array([length / n[0], width / n[1], thickness / n[2]])
    (_, conn), = grid.cells_dict.items()
    return grid, conn, grid.points[conn].mean(axis=1)


def test_face_areas_are_the_chosen_cells_facets():
    grid, conn, centroid = _box()
    everything = np.ones(len(conn), dtype=bool)
    # areas summed from float64 facets whose corners are exact multiples of the brick: round-off
    for z in (0.0, 0.15):  # each face of the box once
        assert close_in.face_area(grid, conn, everything, z) == pytest.approx(0.4 * 0.3, rel=1e-12)
    # the bricks with x < 0.1 and y < 0.15: a quarter of the face's length, half its width
    corner = (centroid[:, 0] < 0.1) & (centroid[:, 1] < 0.15)
    assert close_in.face_area(grid, conn, corner, 0.0) == pytest.approx(0.1 * 0.15, rel=1e-12)
    assert close_in.face_area(grid, conn, corner, 0.075) == 0.0  # no face there


def test_the_breach_is_where_every_depth_is_chosen():
    grid, conn, centroid = _box()
    column = (centroid[:, 0] < 0.1) & (centroid[:, 1] < 0.15)  # through the whole thickness
    # lines 5 mm apart from 2.5 mm in: 20 x 30 of them fall in the 0.1 x 0.15 m column, none on
    # a brick's edge, so the count is exact and the area 600 x 25e-6 m^2 to round-off
    assert close_in.through_area(grid, column, 0.15) == pytest.approx(0.1 * 0.15, rel=1e-12)
    # the same column without its back layer of bricks: a spall-less crater, no breach
    crater = column & (centroid[:, 2] < 0.1)
    assert close_in.through_area(grid, crater, 0.15) == 0.0
    assert close_in.face_area(grid, conn, crater, 0.0) == pytest.approx(0.1 * 0.15, rel=1e-12)
    assert close_in.face_area(grid, conn, crater, 0.15) == 0.0
