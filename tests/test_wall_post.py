"""The wall block of summary.json (post/wall.py) on hand-made fragments and link tables: a
1 m x 0.1 m section, span along x, thickness along y, mesh size 1 cm."""
import json

import numpy as np
import pytest

from dolfrag.post import wall
from dolfrag.post.fragments import Fragments

L, H, h = 1.0, 0.1, 0.01  # m: span, thickness, mesh size
RHO = 2350.0  # kg/m^3
WIDTH = wall.CRACK_LINK_CELLS * h
# bbox corners and velocities are given exactly; a difference or a mass-weighted mean of
# two keeps them to a few ulps of 1 m or 10 m/s
EXACT = 1e-14


def pieces(boxes, v_y):
    """Fragments made of the rectangles boxes[i] = (x_lo, x_hi, y_lo, y_hi) (m), moving at
    v_y[i] (m/s) along y; masses (kg/m) are the areas times RHO."""
    b = np.asarray(boxes, dtype=float)
    lo, hi = b[:, [0, 2]], b[:, [1, 3]]
    k = len(b)
    return Fragments(RHO * np.prod(hi - lo, axis=1), (lo + hi) / 2, np.column_stack([np.zeros(k), v_y]),
                     lo, hi, np.ones(k, dtype=np.int64), np.zeros((0, 2), dtype=np.int64), np.zeros(0))


def mirrored(frags):
    """The same section upside down (y -> H - y): the free face moves from y = H to y = 0."""
    flip, shift = np.array([1.0, -1.0]), np.array([0.0, H])
    a, b = shift + flip * frags.bbox_min, shift + flip * frags.bbox_max
    return Fragments(frags.mass, shift + flip * frags.centroid, flip * frags.velocity, np.minimum(a, b),
                     np.maximum(a, b), frags.cells, frags.neighbours, frags.separated_at)


# the wall with a 2 cm scab off the free face (y = H) at midspan, flying at 3 m/s, and a 2 cm
# chip off the loaded face (y = 0), pushed along at 5 m/s
BODY, SCAB, CHIP = (0.0, L, 0.0, H), (0.4, 0.6, 0.08, H), (0.45, 0.55, 0.0, 0.02)


def test_scab_off_the_free_face_is_found_with_its_depth_and_velocity_from_either_side():
    frags = pieces([BODY, SCAB, CHIP], [0.5, 3.0, 5.0])
    for f, free_face in ((frags, H), (mirrored(frags), 0.0)):
        s = wall.scab(f, free_face, axis=1, thickness=H, h=h)
        assert s["fragments"] == [1] and s["count"] == 1  # not the chip on the loaded face
        assert s["thickness_m"] == pytest.approx(0.02, abs=EXACT)
        assert s["velocity_m_s"] == pytest.approx(3.0, abs=EXACT)  # towards the free face: +y, or -y once mirrored
        assert s["mass_kg"] == pytest.approx(RHO * 0.2 * 0.02, rel=EXACT)
        assert s["span_extent_m"] == [0.4, 0.6]


def test_scab_of_two_pieces_is_as_deep_as_the_deeper_and_flies_at_their_momentum_over_mass():
    # 1 cm and 3 cm deep, equally wide: masses 1 : 3, velocities 2 and 6 m/s => 20 / 4 = 5 m/s
    frags = pieces([BODY, (0.2, 0.3, 0.09, H), (0.6, 0.7, 0.07, H)], [0.0, 2.0, 6.0])
    s = wall.scab(frags, H, axis=1, thickness=H, h=h)
    assert s["count"] == 2 and s["span_extent_m"] == [0.2, 0.7]
    assert s["thickness_m"] == pytest.approx(0.03, abs=EXACT)
    assert s["velocity_m_s"] == pytest.approx(5.0, abs=EXACT)


def test_a_panel_through_the_thickness_or_a_loaded_face_chip_is_no_scab():
    panel = pieces([(0.0, 0.3, 0.0, H), (0.3, 0.7, 0.0, H), (0.7, L, 0.0, H)], [0.0, 4.0, 0.0])
    assert wall.scab(panel, H, axis=1, thickness=H, h=h) is None
    assert wall.scab(pieces([BODY, CHIP], [0.0, 5.0]), H, axis=1, thickness=H, h=h) is None
    # the loaded face crushed into chips: the main body no longer reaches it, and is no scab
    crushed = pieces([(0.0, L, 0.02, H), (0.0, 0.5, 0.0, 0.02), (0.5, L, 0.0, 0.02)], [0.0, 1.0, 1.0])
    assert wall.scab(crushed, H, axis=1, thickness=H, h=h) is None
    # a piece one cell below the free face does not touch it (TOUCH_SHARE)
    assert wall.scab(pieces([BODY, (0.4, 0.6, 0.07, H - h)], [0.0, 3.0]), H, axis=1, thickness=H, h=h) is None


def test_a_wedge_off_a_clamped_corner_is_no_scab_a_layer_is():
    # corners of the free face cut off by inclined cracks next to the clamped ends: 32.5 mm
    # deep, 20 mm wide (a wedge is at most twice as wide as deep); and a layer 3 x as wide
    corners = pieces([(0.0, 0.02, H - 0.0325, H), (0.02, 0.98, 0.0, H), (0.98, L, H - 0.0325, H)], [-0.03, 0.0, -0.03])
    assert wall.scab(corners, H, axis=1, thickness=H, h=h) is None
    layer = pieces([BODY, (0.4, 0.4 + 3 * 0.0325, H - 0.0325, H)], [0.0, 2.0])
    assert wall.scab(layer, H, axis=1, thickness=H, h=h)["fragments"] == [1]
    narrow = pieces([BODY, (0.4, 0.4 + 2.9 * 0.0325, H - 0.0325, H)], [0.0, 2.0])
    assert wall.scab(narrow, H, axis=1, thickness=H, h=h) is None
    # in 3D every span axis must be 3 x the depth: a 20 mm deep strip 50 mm wide is no scab
    assert wall.scab(slab_pieces([SLAB, (0.2, 0.8, 0.3, 0.35, 0.08, H)], [0.0, 2.0]), H, axis=2, thickness=H,
                     h=h) is None


def line(x, y_from, y_to, broken=True, time=np.nan):
    """Links on the vertices (x, y) of a vertical line of facets from y_from to y_to,
    every h. Each inner vertex carries two links (the facets above and below), each of
    weight h/2. Returns x_link (n, 2), broken (n,), weight (n,), break_time (n,)."""
    y = np.arange(round(y_from / h), round(y_to / h) + 1) * h
    y = np.concatenate([y[:-1], y[1:]])  # each facet's two vertices
    n = len(y)
    return (np.column_stack([np.full(n, x), y]), np.full(n, broken), np.full(n, h / 2),
            np.broadcast_to(time, (n,)).astype(float))


def table(*lines):
    return [np.concatenate(column) for column in zip(*lines)]


def cracks(x_link, broken, weight):
    return wall.through_cracks(x_link, broken, weight, 0, 1, H, WIDTH)


def test_a_straight_line_of_broken_links_across_the_thickness_is_a_through_crack_there():
    x_link, broken, weight, _ = table(line(0.5, 0.0, H), line(0.2, 0.0, H, broken=False))
    found = cracks(x_link, broken, weight)
    assert found.position == pytest.approx([0.5], abs=EXACT)
    assert list(found.span_min) == [0.5] and list(found.span_max) == [0.5]


def test_a_line_over_half_the_thickness_or_short_of_a_face_by_one_cell_is_not_a_through_crack():
    assert not len(cracks(*table(line(0.5, 0.0, H / 2))[:3]).position)
    assert not len(cracks(*table(line(0.5, 0.0, H - h))[:3]).position)
    # from both faces, with 3 cells (> WIDTH) of sound concrete between
    assert not len(cracks(*table(line(0.5, 0.0, 0.04), line(0.5, 0.07, H))[:3]).position)
    # the same two halves 1 cm apart along the span still join (1 cm <= WIDTH)
    assert cracks(*table(line(0.5, 0.0, 0.05), line(0.51, 0.05, H))[:3]).position == pytest.approx(
        [0.505], abs=EXACT)


def test_an_inclined_shear_crack_at_a_support_is_a_through_crack():
    # 45 degrees from (0.05, 0) to (0.15, H), links every h along x and y
    s = np.arange(11) * h
    x_link = np.column_stack([0.05 + s, s])
    found = cracks(x_link, np.ones(11, dtype=bool), np.full(11, h / np.sqrt(2)))
    assert found.position == pytest.approx([0.1], abs=EXACT)
    assert found.span_min == pytest.approx([0.05], abs=EXACT) and found.span_max == pytest.approx([0.15], abs=EXACT)


def test_first_through_crack_forms_when_its_last_link_breaks():
    # at x = 0.3 links break from the free face down, the last at 2 ms; at x = 0.7 the crack
    # completes at 1 ms but its neighbourhood keeps breaking until 5 ms
    x1, b1, w1, t1 = line(0.3, 0.0, H)
    t1 = 2e-3 * (1 - x1[:, 1] / H) + 1e-4
    x2, b2, w2, _ = line(0.7, 0.0, H)
    t2 = np.full(len(x2), 1e-3)
    x3, b3, w3, t3 = line(0.8, 0.0, H, time=5e-3)
    x_link, _, _, break_time = table((x1, b1, w1, t1), (x2, b2, w2, t2), (x3, b3, w3, t3))
    assert wall.first_through_crack_time(x_link, break_time, 1, H, WIDTH) == 1e-3
    # without the x = 0.7 crack: the x = 0.3 one, when its link on y = 0 breaks
    first = wall.first_through_crack_time(*table((x1, b1, w1, t1), (x3, b3, w3, t3))[::3], 1, H, WIDTH)
    assert first == t1.max() == pytest.approx(2.1e-3, rel=EXACT)
    half = table(line(0.5, 0.0, H / 2, time=1e-3))
    assert wall.first_through_crack_time(half[0], half[3], 1, H, WIDTH) is None


def test_damage_sums_damage_times_weight_per_zone_and_names_the_zone_that_broke_first():
    x = np.array([0.05, 0.95, 0.5, 0.4, 0.25])  # supports, supports, midspan, midspan, neither
    x_link = np.column_stack([x, np.full(5, H / 2)])
    damage = np.array([0.5, 1.0, 1.0, 0.25, 1.0])
    weight = np.array([0.01, 0.02, 0.004, 0.008, 1.0])
    break_time = np.array([np.nan, 3e-3, 2e-3, np.nan, 1e-3])  # the first break is in neither zone
    zones = wall.damage_by_zone(x_link, damage, weight, break_time, L)
    assert zones["supports"]["damaged_length_m"] == pytest.approx(0.005 + 0.02, rel=EXACT)
    assert zones["midspan"]["damaged_length_m"] == pytest.approx(0.004 + 0.002, rel=EXACT)
    assert zones["supports"]["first_break_s"] == 3e-3 and zones["midspan"]["first_break_s"] == 2e-3
    assert zones["first"] == "midspan"
    break_time[0] = 1.5e-3
    assert wall.damage_by_zone(x_link, damage, weight, break_time, L)["first"] == "supports"
    break_time[0] = 2e-3
    assert wall.damage_by_zone(x_link, damage, weight, break_time, L)["first"] == "both"
    none = wall.damage_by_zone(x_link, damage, weight, np.full(5, np.nan), L)
    assert none["first"] is None and none["midspan"]["first_break_s"] is None


def test_central_panel_is_the_heaviest_piece_over_midspan_and_flies_towards_the_free_face():
    # support stubs, a lighter scab over midspan, and the panel between the stubs
    frags = pieces([(0.0, 0.3, 0.0, H), SCAB, (0.3, 0.7, 0.0, H), (0.7, L, 0.0, H)], [0.0, 9.0, 4.0, 0.0])
    panel = wall.central_panel(frags, L, 0, 1)
    assert panel["fragment"] == 2 and panel["velocity_m_s"] == 4.0 and panel["span_extent_m"] == [0.3, 0.7]
    assert panel["mass_kg"] == pytest.approx(RHO * 0.4 * H, rel=EXACT)
    flipped = mirrored(frags)
    assert wall.central_panel(flipped, L, 0, 1, wall.outward(flipped, 0.0, 1))["velocity_m_s"] == 4.0


def test_wall_block_interpolates_the_deflection_at_the_first_through_crack():
    frags = pieces([BODY, SCAB, CHIP], [0.5, 3.0, 5.0])
    x_link, _, weight, break_time = table(line(0.5, 0.0, H, time=1.5e-3), line(0.2, 0.0, H / 2, time=0.5e-3))
    damage = np.isfinite(break_time).astype(float)
    t = np.array([0.0, 1e-3, 2e-3, 3e-3])  # s
    w = np.array([0.0, 0.01, 0.03, 0.02])  # m, towards the free face
    block = wall.wall_block(frags, x_link, weight, damage, break_time, t, w, np.array([1e5, -2e5, 1.5e5]), 12.5,
                            span=L, thickness=H, free_face=H, h=h)
    json.dumps(block)
    assert block["first_through_crack_s"] == 1.5e-3
    assert [c["position_m"] for c in block["through_cracks"]] == pytest.approx([0.5], abs=EXACT)
    deflection = block["midspan_deflection"]
    assert deflection["peak_m"] == 0.03 and deflection["peak_time_s"] == 2e-3
    assert deflection["at_first_through_crack_m"] == pytest.approx(0.02, abs=EXACT)  # halfway 0.01 .. 0.03
    assert block["scab"]["fragments"] == [1] and block["central_panel"]["fragment"] == 0
    assert block["damage_by_zone"]["first"] == "midspan"
    assert block["rebar_peak_force_N"] == -2e5 and block["wall_time_s"] == 12.5
    # no crack: no deflection at it
    quiet = wall.wall_block(frags, x_link, weight, damage, np.full(len(weight), np.nan), t, w, None, 1.0,
                            span=L, thickness=H, free_face=H, h=h)
    assert quiet["first_through_crack_s"] is None and quiet["midspan_deflection"]["at_first_through_crack_m"] is None
    assert quiet["through_cracks"] == [] and quiet["rebar_peak_force_N"] is None


# A slab 1 m x 1 m x 0.1 m (3D): spans along x and y, thickness along z, free face z = H
SPANS = (L, L)


def slab_pieces(boxes, v_z):
    """Fragments made of the boxes[i] = (x_lo, x_hi, y_lo, y_hi, z_lo, z_hi) (m), moving at
    v_z[i] (m/s) along z; masses (kg) are the volumes times RHO."""
    b = np.asarray(boxes, dtype=float)
    lo, hi = b[:, 0::2], b[:, 1::2]
    k = len(b)
    return Fragments(RHO * np.prod(hi - lo, axis=1), (lo + hi) / 2, np.column_stack([np.zeros((k, 2)), v_z]),
                     lo, hi, np.ones(k, dtype=np.int64), np.zeros((0, 2), dtype=np.int64), np.zeros(0))


SLAB, SLAB_SCAB = (0.0, L, 0.0, L, 0.0, H), (0.4, 0.6, 0.3, 0.7, 0.08, H)


def test_slab_scab_reports_its_footprint_on_both_span_axes():
    s = wall.scab(slab_pieces([SLAB, SLAB_SCAB], [0.5, 3.0]), H, axis=2, thickness=H, h=h)
    assert s["fragments"] == [1] and s["thickness_m"] == pytest.approx(0.02, abs=EXACT)
    assert s["velocity_m_s"] == pytest.approx(3.0, abs=EXACT)
    assert s["mass_kg"] == pytest.approx(RHO * 0.2 * 0.4 * 0.02, rel=EXACT)
    assert s["span_extent_m"] == [[0.4, 0.6], [0.3, 0.7]]


def plane(x, broken=True, time=np.nan):
    """Links on a grid of vertices h apart over the plane x = const of the slab, through
    the whole thickness (z = 0 .. H, y = 0 .. L), each of weight h^2 / 3."""
    y, z = np.meshgrid(np.arange(round(L / h) + 1) * h, np.arange(round(H / h) + 1) * h, indexing="ij")
    n = y.size
    return (np.column_stack([np.full(n, x), y.ravel(), z.ravel()]), np.full(n, broken), np.full(n, h**2 / 3),
            np.full(n, time, dtype=float))


def test_slab_through_crack_is_a_plane_across_the_thickness_with_its_extent():
    x_link, broken, weight, _ = table(plane(0.05), plane(0.5, broken=False))
    found = wall.through_cracks(x_link, broken, weight, (0, 1), 2, H, WIDTH)
    assert found.position.shape == (1, 2) and found.position[0] == pytest.approx([0.05, 0.5], abs=EXACT)
    assert found.span_min.tolist() == [[0.05, 0.0]] and found.span_max[0] == pytest.approx([0.05, L], abs=EXACT)
    # the same plane short of the free face by one cell is no through-crack
    short = x_link[:, 2] < H - h / 2
    assert not len(wall.through_cracks(x_link[short], broken[short], weight[short], (0, 1), 2, H, WIDTH).position)


def test_slab_support_zones_are_the_edge_bands_and_midspan_the_central_square():
    # near the edge y = 0 at mid-x (supports); the centre (midspan); off-centre in y only (neither)
    x_link = np.array([[0.5, 0.05, H / 2], [0.5, 0.5, H / 2], [0.5, 0.3, H / 2]])
    zones = wall.damage_by_zone(x_link, np.ones(3), np.array([1e-4, 2e-4, 4e-4]), np.array([2e-3, 1e-3, 5e-4]),
                                SPANS, (0, 1))
    assert zones["supports"]["damaged_area_m2"] == pytest.approx(1e-4, rel=EXACT)
    assert zones["midspan"]["damaged_area_m2"] == pytest.approx(2e-4, rel=EXACT)
    assert zones["supports"]["first_break_s"] == 2e-3 and zones["first"] == "midspan"


def test_slab_central_panel_must_cover_the_centre_on_both_axes():
    # a strip over x = 0.5 but not over y = 0.5 is not the panel; the punched square is
    strip, square = (0.3, 0.7, 0.0, 0.2, 0.0, H), (0.3, 0.7, 0.3, 0.7, 0.0, H)
    frags = slab_pieces([strip, square], [9.0, 4.0])
    panel = wall.central_panel(frags, SPANS, (0, 1), 2)
    assert panel["fragment"] == 1 and panel["velocity_m_s"] == 4.0
    assert panel["span_extent_m"] == [[0.3, 0.7], [0.3, 0.7]]


def test_slab_wall_block_is_json_ready_with_per_axis_results():
    x_link, broken, weight, break_time = table(plane(0.05, time=1e-3), plane(0.5, broken=False))
    block = wall.wall_block(slab_pieces([SLAB, SLAB_SCAB], [0.5, 3.0]), x_link, weight,
                            np.isfinite(break_time).astype(float), break_time, np.array([0.0, 2e-3]),
                            np.array([0.0, 1e-3]), None, 1.0, span=SPANS, thickness=H, free_face=H, h=h,
                            span_axis=(0, 1), thickness_axis=2)
    assert json.loads(json.dumps(block))["through_cracks"] == [{"position_m": pytest.approx([0.05, 0.5]),
                                                               "span_extent_m": [[0.05, 0.05], [0.0, L]]}]
    assert block["first_through_crack_s"] == 1e-3 and block["damage_by_zone"]["first"] == "supports"
    assert block["midspan_deflection"]["at_first_through_crack_m"] == pytest.approx(0.5e-3, abs=1e-18)


@pytest.mark.slow
def test_the_full_scabbing_wall_reports_the_layer_not_the_clamped_corners(tmp_path):
    # wall-scabbing as written (docs/wall.md, 26 s): the spall crack cuts a layer over the whole
    # span; next to the clamped ends wedges 30 mm deep and 7-10 mm wide come off the corners
    # of the free face, which the rule (a layer >= SCAB_ASPECT x as wide as deep) leaves out
    from mpi4py import MPI

    import dolfrag
    from dolfrag.case import load_case
    summary = dolfrag.run(load_case("wall-scabbing", ["output.fields=0", "output.figures=false"]), tmp_path,
                          quiet=True, comm=MPI.COMM_SELF)
    s, estimates = summary["wall"]["scab"], summary["wall"]["estimates"]
    assert s["count"] == 1 and s["span_extent_m"] == pytest.approx([0.0, L], abs=h)
    # the 1D plane (20.4 mm) within one 5 mm cell; the layer flies towards the free face
    # (1.83 m/s measured, the 1D trapped momentum 2.67 m/s: the 1 us front is not resolved)
    assert s["thickness_m"] == pytest.approx(estimates["scab_thickness_m"], abs=summary["case"]["mesh"]["size"])
    assert 0.5 * estimates["scab_velocity_m_s"] < s["velocity_m_s"] < estimates["scab_velocity_m_s"]
    # the corner wedges exist, touch the free face and are thinner than the wall: without the
    # rule they would be counted (count 1 above: they are not)
    frags = summary["fragments"]
    lo, hi = np.array(frags["bbox_min"]), np.array(frags["bbox_max"])
    corners = (hi[:, 1] > H - 1e-6) & (hi[:, 1] - lo[:, 1] < H - h) & ((hi[:, 0] < 0.05) | (lo[:, 0] > L - 0.05))
    assert corners.sum() >= 1
