"""The ``wall`` block of summary.json: a reinforced concrete wall section in plane strain, or
a slab in 3D (docs/wall.md). The span runs along ``span_axis`` from 0 to L, with supports at
x = 0 and x = L; a slab spans two axes (``span_axis`` a tuple, ``span`` one length per axis,
supported on its four edges). The thickness runs along ``thickness_axis`` from 0 to H. The
pressure acts on the loaded face; the free face is the opposite one.

Spatial results come per span axis: a number (or a [min, max] pair) when ``span_axis`` is
one axis, a list of them, one per axis, when it is a tuple. "Midspan" is the centre of the
span: the centre line of a slab.

These are pure functions of Fragments (post/fragments.py), of the gathered link table (the
columns of links.csv, output.links) and of the histories the integrator records. They use
no MPI and no dolfinx. The runner calls them with global arrays. They are deterministic, so
any rank that holds the same arrays gets the same answer.

Conventions:

* Piece velocities are positive towards the free face, along its outward normal: the
  direction in which scabs and the central panel fly. ``outward`` gives the sign.
* Link coordinates are the reference vertex coordinates (as in links.csv). Fragments are
  best built in the reference configuration (``fragments(..., displacement=None)``); the
  velocities are the same either way. A bounding box then shows where a piece came from,
  whatever the deflection. In the deformed configuration, a piece from the loaded face at
  midspan whose thickness exceeds H - w (w the deflection there) reaches the free face and
  is taken for a scab.
* 2D: masses (kg) and forces (N) are per metre of wall depth; link weights and damaged
  lengths are m per metre of depth. 3D: kg, N; link weights and damaged areas in m^2.
"""
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from dolfrag.reference import analytic

# A piece touches a face if its bbox comes within TOUCH_SHARE * h of it (h the mesh size, m).
# In the reference configuration a touching piece lies on the face up to round-off. A piece
# that does not touch it has at least one cell (of height ~h/2 or more) between it and the face.
TOUCH_SHARE = 0.25
# Through-cracks: broken links closer than CRACK_LINK_CELLS * h belong to one crack. Consecutive
# links of a crack are at most one facet apart, i.e. one edge (<= ~1.5 h on these meshes).
CRACK_LINK_CELLS = 2.0
# A crack reaches a face when it has a broken link on the face itself: face vertices lie on it
# up to round-off (and links.csv's 9 digits), and the next vertex inwards is a cell away.
FACE_TOL = 1e-6  # relative to H
# A scab is cut off the free face by a crack parallel to it: a layer at least SCAB_ASPECT times
# as wide (along every span axis) as it is deep. A wedge cut by cracks inclined at 45 degrees to
# the face is at most twice as wide as deep; 3 admits cracks within 34 degrees of the face.
SCAB_ASPECT = 3.0
SUPPORT_SHARE = 0.15  # support zones: x < 0.15 L and x > 0.85 L (on any span axis)
MIDSPAN_SHARE = 0.3  # midspan zone: |x - L/2| < 0.15 L (on every span axis)


def _span_axes(span_axis):
    """The span axes as a tuple, and whether results come as one value (a single int axis)."""
    axes = tuple(int(a) for a in np.atleast_1d(span_axis))
    return axes, np.ndim(span_axis) == 0


def _per_axis(values, single):
    """Per-span-axis results (JSON lists): the first alone when ``single``."""
    values = [np.asarray(v).tolist() for v in values]
    return values[0] if single else values


def main_body(frags):
    """Index of the heaviest fragment: the wall that is left."""
    return int(np.argmax(frags.mass))


def outward(frags, free_face, axis, main=None):
    """+1 if the free face (coordinate ``free_face`` on ``axis``, m) lies on the positive side
    of the main body's centroid, else -1: the sign of the free face's outward normal along
    ``axis``."""
    main = main_body(frags) if main is None else main
    return 1.0 if free_face > frags.centroid[main, axis] else -1.0


def scab(frags, free_face, axis, thickness, h, main=None):
    """The scab: the pieces cut off the free face by a crack parallel to it, or None if there
    are none.

    A scab piece is a fragment that is not the main body (``main``, by default the heaviest
    fragment). Its bbox reaches the free face (coordinate ``free_face`` on ``axis``, m), to
    within TOUCH_SHARE * h (h the mesh size, m); the test is one-sided, so pieces that have
    already flown off still count. The piece must also be thinner than the wall
    (``thickness`` H, m) by more than that tolerance: pieces through the whole thickness, like
    a central panel torn loose at its supports, are panels, not scabs. And it must be a layer,
    at least SCAB_ASPECT times as wide along every span axis as it is deep: a wedge cut off a
    corner by inclined cracks (at a clamped end, say) is no scab.

    Returns a dict:
    thickness_m: the bbox extent along ``axis`` of the thickest piece, i.e. the deepest
    concrete lost from the free face. It is not a mean: for a mean, take mass_kg /
    (rho * span length).
    mass_kg (kg per m of depth in 2D); velocity_m_s: momentum / mass along the outward normal
    of the free face; count: number of pieces; span_extent_m: [min, max] of their bboxes along
    the other axis (the span in 2D; in 3D one pair per other axis, x first); fragments: their
    indices in ``frags``.
    """
    main = main_body(frags) if main is None else main
    sign = outward(frags, free_face, axis, main)
    tol = TOUCH_SHARE * h
    outer = np.where(sign > 0, frags.bbox_max[:, axis], -frags.bbox_min[:, axis])
    extent = frags.bbox_max[:, axis] - frags.bbox_min[:, axis]
    span_axes = [a for a in range(frags.bbox_min.shape[1]) if a != axis]
    footprint = np.min(frags.bbox_max[:, span_axes] - frags.bbox_min[:, span_axes], axis=1)
    is_scab = (outer >= sign * free_face - tol) & (extent < thickness - tol) & (footprint >= SCAB_ASPECT * extent)
    is_scab[main] = False
    pieces = np.flatnonzero(is_scab)
    if not pieces.size:
        return None
    mass = frags.mass[pieces].sum()
    return {"thickness_m": float(extent[pieces].max()),
            "mass_kg": float(mass),
            "velocity_m_s": float(sign * frags.mass[pieces] @ frags.velocity[pieces, axis] / mass),
            "count": len(pieces),
            "span_extent_m": _per_axis([[frags.bbox_min[pieces, a].min(), frags.bbox_max[pieces, a].max()]
                                        for a in span_axes], len(span_axes) == 1),
            "fragments": pieces.tolist()}


class Cracks(NamedTuple):
    """Through-cracks ordered along the (first) span axis. position m: the mean span
    coordinate of their broken links, weighted by link weight. span_min, span_max m: their
    extent. Each (k,) for one span axis, (k, n_axes) for a tuple of them."""
    position: np.ndarray
    span_min: np.ndarray
    span_max: np.ndarray


def _through_clusters(points, depth, thickness, width):
    """Clusters of the points (n, gdim) (m) joined by distances <= width (m). depth (n,) m:
    their coordinate across the thickness. Returns the cluster of each point (n,) and
    whether each cluster reaches both faces depth = 0 and depth = thickness (k,) bool."""
    if not len(points):
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool)
    pairs = cKDTree(points).query_pairs(width, output_type="ndarray")
    n = len(points)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    k, labels = connected_components(graph, directed=False)
    reach = FACE_TOL * thickness
    at_zero = np.bincount(labels, weights=depth <= reach, minlength=k) > 0
    at_thickness = np.bincount(labels, weights=depth >= thickness - reach, minlength=k) > 0
    return labels, at_zero & at_thickness


def through_cracks(x_link, broken, weight, span_axis, thickness_axis, thickness, width):
    """Cracks across the whole thickness of the wall.

    x_link (n, gdim) m: reference coordinates of the links (vertices). broken (n,) bool.
    weight (n,) m per m depth (m^2 in 3D). span_axis: an axis or a tuple of them (a slab).
    thickness (m): the faces are at 0 and H on ``thickness_axis``. width (m): the largest
    gap in a crack, e.g. CRACK_LINK_CELLS mesh sizes.

    Rule: two broken links closer than ``width`` (in the plane of the section; in space,
    in 3D) belong to the same crack. A crack is a through-crack if it has a broken link on both faces
    (FACE_TOL). The rule holds for any crack path: straight flexural cracks at midspan
    and inclined shear cracks at the supports alike. A band of broken links spaced less
    than ``width`` apart also counts: the section there is cut. A through-crack whose
    facets are all cut also splits the fragments, but the detector does not need all
    links of a facet to be broken.

    In 3D a crack is a surface: a ring of yield lines along the four edges of a slab has its
    mean at the centre, so read its extent too.

    Takes the global arrays (gathered from every rank, as output.links does). A crack can
    cross rank boundaries, so it cannot be found per rank.
    """
    axes, single = _span_axes(span_axis)
    x_link, broken = np.asarray(x_link), np.asarray(broken, dtype=bool)
    labels, through = _through_clusters(x_link[broken], x_link[broken, thickness_axis], thickness, width)
    crack = through[labels]
    labels, x, w = labels[crack], x_link[broken][crack][:, axes], np.asarray(weight)[broken][crack]
    ids, index = np.unique(labels, return_inverse=True)
    k = len(ids)
    total = np.bincount(index, weights=w, minlength=k)
    position = np.column_stack([np.bincount(index, weights=w * x[:, j], minlength=k) / total
                                for j in range(len(axes))]).reshape(k, len(axes))
    span_min, span_max = np.full((k, len(axes)), np.inf), np.full((k, len(axes)), -np.inf)
    np.minimum.at(span_min, index, x)
    np.maximum.at(span_max, index, x)
    order = np.argsort(position[:, 0], kind="stable")
    pick = (lambda a: a[order, 0]) if single else (lambda a: a[order])
    return Cracks(pick(position), pick(span_min), pick(span_max))


def first_through_crack_time(x_link, break_time, thickness_axis, thickness, width):
    """Time (s) the first through-crack (``through_cracks``) formed: the earliest break time
    t at which the links broken by then (break_time <= t) form one. Returns None if none
    ever forms. break_time (n,) s, NaN for links not broken.

    Links never heal, and breaking another link can only join clusters, so "a through-crack
    exists" does not change back once true. Bisection over the sorted break times therefore
    finds the first one, in log2(n) calls.
    """
    break_time = np.asarray(break_time, dtype=float)
    x_link = np.asarray(x_link)
    times = np.unique(break_time[np.isfinite(break_time)])

    def exists(t):
        broken = break_time <= t
        return _through_clusters(x_link[broken], x_link[broken, thickness_axis], thickness, width)[1].any()

    if not times.size or not exists(times[-1]):
        return None
    before, at = -1, len(times) - 1  # no crack before times[0]; one by times[at]
    while at - before > 1:
        mid = (before + at) // 2
        before, at = (before, mid) if exists(times[mid]) else (mid, at)
    return float(times[at])


def damage_by_zone(x_link, damage, weight, break_time, span, span_axis=0, support_share=SUPPORT_SHARE,
                   midspan_share=MIDSPAN_SHARE):
    """Where the damage is: support zones (x < s L or x > (1 - s) L, s = support_share) and
    midspan zone (|x - L/2| < m L / 2, m = midspan_share). x is the span coordinate of the
    links; on a slab (tuple ``span_axis``, one L per axis in ``span``) the support zones are
    the bands along the four edges (near an edge on any axis) and the midspan zone is the
    central square (near the centre on every axis).

    x_link (n, gdim) m; damage (n,) 0 sound .. 1 broken; weight (n,) m per m depth (m^2 in
    3D); break_time (n,) s, NaN for links not broken; span L (m).
    Returns, per zone ("supports", "midspan"): damaged_length_m = sum(damage * weight) (m of
    facet per m depth, a fully broken facet counting its full length; damaged_area_m2 in 3D)
    and first_break_s (the earliest break time in the zone, None if none). Also "first": the
    zone that broke first, "both" if they broke in the same step, None if neither broke.
    Also the zone shares.
    """
    axes, _ = _span_axes(span_axis)
    x = np.asarray(x_link)[:, axes]
    span = np.broadcast_to(np.asarray(span, dtype=float), (len(axes),))
    damage, weight, break_time = (np.asarray(a, dtype=float) for a in (damage, weight, break_time))
    zones = {"supports": np.any((x < support_share * span) | (x > (1 - support_share) * span), axis=1),
             "midspan": np.all(np.abs(x - span / 2) < midspan_share * span / 2, axis=1)}
    first = {name: np.nanmin(break_time[z], initial=np.inf) for name, z in zones.items()}
    measure = "damaged_length_m" if np.shape(x_link)[1] == 2 else "damaged_area_m2"
    out = {name: {measure: float(damage[z] @ weight[z]),
                  "first_break_s": None if np.isinf(first[name]) else float(first[name])}
           for name, z in zones.items()}
    if np.isinf(min(first.values())):
        out["first"] = None
    elif first["supports"] == first["midspan"]:
        out["first"] = "both"
    else:
        out["first"] = min(first, key=first.get)
    return {**out, "support_share": support_share, "midspan_share": midspan_share}


def central_panel(frags, span, span_axis, normal_axis, sign=1.0):
    """The central panel: the heaviest fragment whose bbox contains the midspan x = L/2 (at
    any depth; on a slab the centre line), or None if no bbox does.

    span L (m, one per axis of a tuple ``span_axis``). sign: the outward sign of the free
    face along ``normal_axis`` (``outward``). Returns a dict: fragment (its index), mass_kg
    (per m depth in 2D), velocity_m_s (mean velocity along normal_axis, positive towards the
    free face), span_extent_m [min, max] (per span axis). The panel is ejected only if its
    extent lies inside (0, L): otherwise it is still held by a support.
    """
    axes, single = _span_axes(span_axis)
    lo, hi = frags.bbox_min[:, axes], frags.bbox_max[:, axes]
    centre = np.asarray(span, dtype=float) / 2
    over = np.flatnonzero(np.all((lo <= centre) & (hi >= centre), axis=1))
    if not over.size:
        return None
    i = int(over[np.argmax(frags.mass[over])])
    return {"fragment": i, "mass_kg": float(frags.mass[i]),
            "velocity_m_s": float(sign * frags.velocity[i, normal_axis]),
            "span_extent_m": _per_axis(np.column_stack([lo[i], hi[i]]), single)}


def peak(values):
    """The signed value of largest magnitude and its index."""
    i = int(np.argmax(np.abs(values)))
    return float(values[i]), i


def wall_block(frags, x_link, weight, damage, break_time, t, w, rebar_force, wall_time, *, span, thickness,
               free_face, h, span_axis=0, thickness_axis=1):
    """The ``wall`` dict of summary.json (JSON-ready).

    frags: Fragments at the end of the run (reference configuration preferred: module
    docstring). x_link (n, gdim) m, weight (n,) m per m depth, damage (n,), break_time (n,)
    s (NaN: not broken): the global link table, as in links.csv. A link is broken when it
    has a break time.
    t (n_t,) s, w (n_t,) m: midspan deflection history. rebar_force (any shape) N per m
    depth (N in 3D): the rebar axial forces over the run, tension > 0; None if there is no
    rebar. wall_time (s): the run's wall-clock time.
    span L (one per axis of a tuple span_axis), thickness H, free_face (coordinate of the
    free face on thickness_axis), h (mesh size): m.

    Peaks are the signed values of largest magnitude. The deflection at the first
    through-crack is interpolated in the history; it is None without a crack, or if the
    crack formed outside the history.
    """
    width = CRACK_LINK_CELLS * h
    x_link, break_time = np.asarray(x_link), np.asarray(break_time, dtype=float)
    t, w = np.asarray(t, dtype=float), np.asarray(w, dtype=float)
    cracks = through_cracks(x_link, np.isfinite(break_time), weight, span_axis, thickness_axis, thickness, width)
    cracked_at = first_through_crack_time(x_link, break_time, thickness_axis, thickness, width)
    w_peak, i_peak = peak(w)
    on_record = cracked_at is not None and t[0] <= cracked_at <= t[-1]
    main = main_body(frags)
    return {
        "span_m": span, "thickness_m": thickness, "free_face_m": free_face, "crack_link_distance_m": width,
        "scab": scab(frags, free_face, thickness_axis, thickness, h, main),
        "through_cracks": [{"position_m": np.asarray(p).tolist(),
                            "span_extent_m": np.column_stack([a, b]).squeeze().tolist()}
                           for p, a, b in zip(*cracks)],
        "first_through_crack_s": cracked_at,
        "midspan_deflection": {"peak_m": w_peak, "peak_time_s": float(t[i_peak]),
                               "at_first_through_crack_m": float(np.interp(cracked_at, t, w)) if on_record else None},
        "central_panel": central_panel(frags, span, span_axis, thickness_axis,
                                       outward(frags, free_face, thickness_axis, main)),
        "damage_by_zone": damage_by_zone(x_link, damage, weight, break_time, span, span_axis),
        "rebar_peak_force_N": None if rebar_force is None else peak(np.ravel(rebar_force))[0],
        "wall_time_s": float(wall_time),
    }


def estimates(pressure, end, c, rho, E, sigma_c, thickness, span, supports, nu):
    """The closed-form checks of a wall run (docs/hopkinson.md, docs/wall.md), JSON-ready.

    pressure: p(t) (Pa) on the loaded face, over [0, end] (s); c (m/s) the P-wave speed of
    the estimate; rho (kg/m^3), E (Pa), nu (-) the concrete's; sigma_c (Pa) its tensile
    strength (None for unbreakable interfaces: no scab, no ejection); thickness H and span L
    (m; a pair (L_x, L_y) for a slab); supports "clamped",
    "simple" or None (no bending estimate).
    Scab: the 1D spall plane of the pulse reflected at the free face and the momentum it
    traps (None if the tension never reaches sigma_c within H); ejection: the velocity
    jump sigma_c / sqrt(rho E) a crack sends out. Bending: for a wall section, the elastic
    Biggs SDOF peak deflection (``sdof_elastic``); for a slab, the thin-plate centre
    deflection under p(t) applied statically (``plate_quasi_static``: analytic.plate_deflection,
    a load slow against the plate's first period), w = w_1 p(t), w_1 the deflection per Pa.
    Returns the dict and the bending history (t (s), w (m)), or None without supports.
    """
    delta = None if sigma_c is None else analytic.spall_distance(pressure, c, sigma_c, end)
    scabs = delta is not None and delta < thickness
    out = {"wave_speed_m_s": c,
           "scab_thickness_m": delta if scabs else None,
           "scab_velocity_m_s": analytic.scab_velocity(pressure, c, rho, delta) if scabs else None,
           "ejection_velocity_m_s": None if sigma_c is None else float(analytic.ejection_velocity(sigma_c, rho, E))}
    if np.ndim(span):
        out["plate_quasi_static"] = history = None
        if supports is not None:
            D = analytic.plate_rigidity(E, thickness, nu)
            w_1 = analytic.plate_deflection(1.0, *span, D, supports)
            t = np.linspace(0.0, end, 2001)
            history = t, w_1 * pressure(t)
            k = int(np.argmax(np.abs(history[1])))
            out["plate_quasi_static"] = {"supports": supports, "deflection_per_pressure_m_Pa": w_1,
                                         "peak_deflection_m": float(history[1][k]), "peak_time_s": float(t[k])}
        return out, history
    sdof = history = None
    if supports is not None:
        props = analytic.strip_properties(E, rho, thickness, span, supports, nu)
        history = analytic.sdof_response(props, pressure, end)
        k = int(np.argmax(np.abs(history[1])))
        sdof = {"supports": supports, "peak_deflection_m": float(history[1][k]),
                "peak_time_s": float(history[0][k]), "frequency_Hz": props.f}
    return {**out, "sdof_elastic": sdof}, history
