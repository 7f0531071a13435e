"""Bar layers behind the face groups of a user's 3D mesh file (dolfrag/rebar/faces.py)."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import mpirun
from dolfrag import mesh, space as spaces
from dolfrag.rebar import faces as rebar_faces
from dolfrag.case import load_case

# A 0.6 m x 0.4 m x 0.2 m slab with its two large faces named (z = 0 and z = 0.2).
SLAB_GEO = """SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.6, 0.4, 0.2};
e = 1e-6;
Physical Volume("concrete") = {1};
Physical Surface("under") = Surface In BoundingBox{-e, -e, -e, 0.6 + e, 0.4 + e, e};
Physical Surface("over") = Surface In BoundingBox{-e, -e, 0.2 - e, 0.6 + e, 0.4 + e, 0.2 + e};
"""
COVER, DIAMETER, SPACING = 0.03, 0.01, 0.15


def _slab_case(tmp_path, *sets):
    geo = tmp_path / "slab.geo"
    geo.write_text(SLAB_GEO)
    return load_case("bunker-two-rooms", [f"geometry.file='{geo}'", "mesh.size=0.1", "load.boundary='under'",
                                          "supports.clamped=[]", "supports.rollers=['over']",
                                          "rebar.faces=['under', 'over']", f"rebar.cover={COVER}",
                                          f"rebar.diameter={DIAMETER}", f"rebar.spacing={SPACING}", *sets])


def _rounded_set(lines):
    return {tuple(np.round(line.ravel(), 12)) for line in lines}


def test_layers_behind_a_slabs_faces_are_the_box_layers_less_the_cover_at_their_ends(tmp_path):
    """On a flat face the layers are those of a generated box (rebar_layout): bars along x
    at y = 0.2 -+ 0.075 m (two fit 0.15 m apart in 0.4 m), crossing bars along y at four x,
    the first layer at the cover, the second one diameter further in, each bar stopped a
    cover short of the slab's edges."""
    case = _slab_case(tmp_path)
    domain = mesh.build(case.geometry, case.mesh.size, MPI.COMM_SELF)
    lines, areas = rebar_faces.polylines(case.rebar, spaces.create(domain), domain, MPI.COMM_SELF)
    expected = []
    for z_face, inward in ((0.0, 1.0), (0.2, -1.0)):
        for y in 0.2 + np.array([-0.5, 0.5]) * SPACING:  # along x, first layer
            z = z_face + inward * COVER
            expected.append(np.array([[COVER, y, z], [0.6 - COVER, y, z]]))
        for x in 0.3 + np.array([-1.5, -0.5, 0.5, 1.5]) * SPACING:  # along y, one diameter further in
            z = z_face + inward * (COVER + DIAMETER)
            expected.append(np.array([[x, COVER, z], [x, 0.4 - COVER, z]]))
    # the same ends up to the order of each bar's two ends
    assert _rounded_set(lines) | _rounded_set(line[::-1] for line in lines) >= _rounded_set(expected)
    assert len(lines) == len(expected)
    assert np.allclose(areas, np.pi * DIAMETER**2 / 4)


def test_in_plane_axes_are_orthonormal_and_tangent():
    for normal in ([0.0, 0.0, -1.0], [0.6, 0.8, 0.0], [0.0, 0.6, 0.8], [1 / np.sqrt(3)] * 3):
        axes = rebar_faces.in_plane_axes(np.array(normal))
        assert np.allclose(axes @ axes.T, np.eye(2), atol=1e-14) and np.allclose(axes @ normal, 0, atol=1e-14)
    assert np.array_equal(rebar_faces.in_plane_axes(np.array([0.0, -1.0, 0.0])), np.eye(3)[[0, 2]])


@pytest.mark.mpi
def test_two_room_layers_are_the_same_on_1_and_2_ranks_and_avoid_the_openings(tmp_path):
    """The two-room bunker's bars behind its inner and outer faces: the same polylines on 2
    ranks (each rank sees part of the facets), every bar inside the concrete (its ends
    a cover from an opening's edge), none crossing the door or the doorway."""
    sets = ["mesh.size=0.25"]
    mpirun(["tests/mpi_rebar_faces.py", "bunker-two-rooms", tmp_path / "two.npz", *sets], n=2)
    case = load_case("bunker-two-rooms", sets)
    domain = mesh.build(case.geometry, case.mesh.size, MPI.COMM_SELF)
    lines, _ = rebar_faces.polylines(case.rebar, spaces.create(domain), domain, MPI.COMM_SELF)
    two = np.load(tmp_path / "two.npz")["lines"]
    assert np.array_equal(np.array(lines), two)
    t, L, H = 0.2, 2.0, 2.0
    for line in lines:
        points = line[0] + np.linspace(0, 1, 50)[:, None] * (line[1] - line[0])
        x, y, z = points.T
        in_room = ((x > t) & (x < t + L) | (x > 2 * t + L) & (x < 2 * t + 2 * L)) & (y > t) & (y < t + L) & (z < H)
        door = (x > t + (L - 0.9) / 2) & (x < t + (L + 0.9) / 2) & (y < t) & (z < H)
        doorway = (x > t + L) & (x < 2 * t + L) & (np.abs(y - (t + L / 2)) < 0.4) & (z < H)
        assert not np.any(in_room | door | doorway), line
