"""The rules between keys and sections that a single field's spec cannot say: a case that
breaks one is refused with a CaseError naming the keys."""
from __future__ import annotations


import numpy as np

from dolfrag import bunker
from dolfrag.loads import mixture
from dolfrag.interface.models import law as _law
from dolfrag.loads.explosives import EQUIVALENCES, EQUIVALENTS, SOURCE as EXPLOSIVES_SOURCE
from dolfrag.case.schema import CaseError, _show
from dolfrag.case.sections import BOX_BOUNDARIES, Case, Geometry, Load, Rebar


def _check(case: Case) -> None:
    """Rules linking several keys or sections."""
    _check_interface(case)
    if case.time.scheme == "theta":
        _check_theta(case)
    load = case.load
    if load.signal == "triangular" and load.duration < load.rise:
        raise CaseError(f"load.duration = {load.duration!r}: "
                        f"must be >= load.rise = {load.rise!r} (s)")
    _check_load(load, case.geometry)
    if load.kind == "stretch":
        _check_stretch(case)
    _check_boundaries(case)
    if case.geometry.kind == "bunker":
        _check_bunker(case.geometry)
    _check_rebar(case.rebar, case.geometry)
    _check_groups(case)
    late = [t for t in case.output.fragments_at if t > case.time.end]
    if late:
        raise CaseError(f"output.fragments_at = {_show(list(case.output.fragments_at))}: {late[0]!r} s is past "
                        f"time.end = {case.time.end!r} s; every time must be in [0, time.end]")
    _check_layers(case)
    _check_bond(case)
    if load.boundary in case.supports.clamped:
        raise CaseError(f"supports.clamped = {_show(list(case.supports.clamped))}: {load.boundary!r} is the "
                        "load.boundary (the loaded boundary may not be clamped)")


def _check_interface(case: Case) -> None:
    """The interface law's own rules (its entry in interface/models.LAWS, with the normal
    stiffness of the stiffness rule) and the stiffness keys."""
    interface = case.interface
    problem = _law(interface).rules(interface, interface.stiffness(case.material.E, case.mesh.size)[0])
    if problem:
        raise CaseError(problem)
    if interface.C_T is not None and interface.shear_ratio is not None:
        raise CaseError(f"interface.C_T = {interface.C_T:g} Pa/m, interface.shear_ratio = "
                        f"{interface.shear_ratio!r}: give one of them (C_T in Pa/m, or shear_ratio = C_T / C_N)")


def _check_theta(case: Case) -> None:
    """What the theta scheme needs, and the runs it does not finish: a rectangle pushed
    across its thickness (a pressure on its bottom or top, normal to y) between supports,
    a wall section in bending, with links that break. Once such a section cracks through,
    its pieces hang on the supports and the bars in contact with friction, and theta's
    global semi-smooth Newton stops on a step that no cut resolves; which step depends on
    the path (measured with RCCM at 20 mm: wall-bending-simple stops at 25.9 ms on 1 rank,
    with sub-steps down to h/16 and h/256, 20 times the iterations or the contact
    regularisation escalated in every step; wall-bending-clamped completes on 1 rank and
    stops at 33.8 ms on 2; without bars both stop at 91 ms; docs/wall.md). The star-local
    imex steps through them."""
    law, interface, load, sup = _law(case.interface), case.interface, case.load, case.supports
    if load.signal == "charge" and case.time.dt is None:
        raise CaseError("time.dt: missing (required when time.scheme is 'theta' and load.signal is 'charge': "
                        "the charge's shortest positive phase is known only on the mesh), s")
    if not law.theta:
        raise CaseError(f"time.scheme = 'theta' with interface.law = {interface.law!r}: not available yet "
                        "(the rigid laws run with 'imex')")
    bending = (case.geometry.kind == "rectangle" and load.boundary in ("bottom", "top")
               and bool(sup.clamped or sup.simple))
    if law.breakable and bending:
        raise CaseError(f"time.scheme = 'theta' with interface.law = {interface.law!r} on load.boundary = "
                        f"{load.boundary!r} between supports: not available (a wall section in bending that "
                        "cracks through stops theta's Newton on a step no cut resolves: wall-bending-simple at "
                        "25.9 ms, wall-bending-clamped at 33.8 ms on 2 ranks; docs/wall.md); "
                        "use time.scheme = 'imex'")


def _check_boundaries(case: Case) -> None:
    """Every boundary a key names exists (on a geometry that knows its boundaries), and is in
    one support list at most."""
    load, sup, known = case.load, case.supports, case.geometry.boundaries
    named = {**({"load.boundary": load.boundary} if load.kind == "pressure" else {}),
             "supports.rollers": list(sup.rollers),
             "supports.clamped": list(sup.clamped), "supports.simple": list(sup.simple),
             "rebar.faces": list(case.rebar.faces)}
    for key, value in named.items():
        for name in [value] if isinstance(value, str) else value:
            if known is not None and name not in known:
                raise CaseError(f"{key} = {_show(value)}: unknown boundary {name!r}; "
                                f"allowed: {', '.join(known)}")
    kinds = {"rollers": sup.rollers, "clamped": sup.clamped, "simple": sup.simple}
    for kind, names in kinds.items():
        for other, others in kinds.items():
            both = sorted(set(names) & set(others))
            if kind < other and both:
                raise CaseError(f"supports.{kind} = {_show(list(names))}: {both[0]!r} is also in "
                                f"supports.{other} (a boundary may be in one list only)")


def _check_layers(case: Case) -> None:
    """Bar layers have a body to lie in: a geometry that has faces to lay them along, their
    sizes given, and a cover (m) under half the body's smallest extent."""
    bars, geometry = case.rebar, case.geometry
    if not bars.faces:
        return
    if geometry.kind == "file" and geometry.tdim == 2:
        raise CaseError(f"rebar.faces = {_show(list(bars.faces))}: layers need a rectangle, box, bunker or "
                        "a 3D mesh file (geometry.dim = 3)")
    for key in ("cover", "diameter", "spacing"):
        if getattr(bars, key) is None:
            raise CaseError(f"rebar.{key}: missing (required when rebar.faces is given), m")
    thinnest = (geometry.scale * geometry.wall if geometry.kind == "bunker" else np.inf if geometry.kind == "file"
                else min(x for x in (geometry.length, geometry.width, geometry.thickness) if x))
    if not bars.cover < thinnest / 2:
        raise CaseError(f"rebar.cover = {bars.cover!r}: must be < {thinnest / 2:g} m (half the body's "
                        "smallest extent), or the layers cross")


def _check_bond(case: Case) -> None:
    """Bond-slip (rebar/bond.py) has bars, a bond strength, the explicit step it is
    integrated in, and a stable step that counts the bars' own nodes."""
    bars = case.rebar
    if bars.bond == "perfect":
        return
    where = f"rebar.bond = {bars.bond!r}:"
    if not bars.faces:
        raise CaseError(f"{where} only allowed when rebar.faces is given (a list of faces to lay bars along)")
    if case.time.scheme != "imex":
        raise CaseError(f"{where} needs time.scheme = 'imex' (the bars' own nodes are integrated explicitly); "
                        f"time.scheme = {case.time.scheme!r}")
    if case.time.bars_step != "coupled":
        raise CaseError(f"{where} needs time.bars_step = 'coupled' (the step with the bars' own nodes); "
                        f"time.bars_step = {case.time.bars_step!r}")
    if bars.bond_tau_max is None and case.material.grade is None:
        raise CaseError("rebar.bond_tau_max: missing (required when rebar.bond is 'fib2010' and material.grade "
                        "is not given: the default is 2.5 sqrt(f_cm) of the grade), Pa")


BUILT_GROUP = "concrete"  # the material group of every cell of a generated rectangle or box (mesh.py)


def _check_bunker(geometry: Geometry) -> None:
    """The door fits its wall: narrower than the room, no higher than it, its panel thinner
    than the wall."""
    (L_x, _, H), (width, height) = geometry.inner, geometry.door
    for key, value, limit, what in (("door", width, L_x, "< geometry.inner[0], the room's length"),
                                    ("door", height, H, "<= geometry.inner[2], the room's height"),
                                    ("door_thickness", geometry.door_thickness, geometry.wall, "< geometry.wall")):
        if value > limit or (value == limit and what.startswith("< ")):
            shown = list(geometry.door) if key == "door" else value
            raise CaseError(f"geometry.{key} = {_show(shown)}: {value:g} m must be {what} = {limit:g} m")


def _built_groups(geometry: Geometry) -> tuple[str, ...]:
    """The material groups a generated geometry names (mesh.py, bunker.py)."""
    if geometry.kind == "bunker":
        return bunker.PIECES + (("door",) if geometry.door_thickness > 0 else ())
    return (BUILT_GROUP,)


def _check_groups(case: Case) -> None:
    """[materials.NAME] of a generated geometry: NAME is one of its groups (an imported
    mesh's groups are checked once it is read, bulk.material_fields)."""
    if case.geometry.kind == "file":
        return
    allowed = _built_groups(case.geometry)
    for name in case.materials:
        if name not in allowed:
            raise CaseError(f"materials.{name}: not a material group of the {case.geometry.kind}; allowed: "
                            f"{', '.join(map(repr, allowed))} (other groups need geometry.kind = 'file')")


def _check_rebar(bars: Rebar, geometry: Geometry) -> None:
    """[rebar] keys among themselves and against the geometry's dimension (the layers
    themselves: rebar/layout.layer_polylines)."""
    optional = ("cover", "diameter", "spacing", "f_y", "eps_u")
    if not bars.faces:
        for key in optional:
            if getattr(bars, key) is not None:
                raise CaseError(f"rebar.{key} = {getattr(bars, key)!r}: only allowed when rebar.faces is given "
                                "(a list of faces to lay bars along)")
        return
    dim = geometry.tdim
    if geometry.kind == "bunker":
        if set(bars.faces) - {"inner", "outer"}:
            raise CaseError(f"rebar.faces = {_show(list(bars.faces))}: in a bunker must be among 'inner', 'outer' "
                            "(layers near that face of every wall and the roof)")
        if bars.direction != "both":
            raise CaseError(f"rebar.direction = {bars.direction!r}: in a bunker must be 'both' (a layer along "
                            "each in-plane axis of every wall and the roof)")
    if geometry.kind == "file" and dim == 3 and bars.direction != "both":
        raise CaseError(f"rebar.direction = {bars.direction!r}: on a mesh file must be 'both' (a layer along "
                        "each in-plane axis behind every flat part of each face group)")
    if dim == 2 and bars.direction not in ("x", "y"):
        raise CaseError(f"rebar.direction = {bars.direction!r}: in 2D must be 'x' or 'y' (the bar axis)")
    for face in (f for f in bars.faces if f in BOX_BOUNDARIES):
        normal = "xyz"[BOX_BOUNDARIES.index(face) // 2]
        if not set(bars.direction) - {normal}:
            raise CaseError(f"rebar.direction = {bars.direction!r}: no axis along face {face!r} of rebar.faces "
                            f"(its normal is {normal}); allowed: axes other than {normal!r}")
    if bars.diameter is not None and bars.spacing is not None and bars.diameter >= bars.spacing:
        raise CaseError(f"rebar.diameter = {bars.diameter!r}: must be < rebar.spacing = {bars.spacing!r} m "
                        "(neighbouring bars would overlap)")
    if bars.diameter is not None and bars.cover is not None and bars.diameter / 2 > bars.cover:
        raise CaseError(f"rebar.diameter = {bars.diameter!r}: must be <= 2 x rebar.cover = {2 * bars.cover:g} m "
                        "(the cover is measured face to bar axis: a thicker bar sticks out of the body)")
    if bars.eps_u is not None and bars.f_y is not None and bars.eps_u <= bars.f_y / bars.E:
        raise CaseError(f"rebar.eps_u = {bars.eps_u!r}: must be > the yield strain rebar.f_y / rebar.E = "
                        f"{bars.f_y / bars.E:.3g} (the bar yields before it ruptures)")


STRETCHED = ("left", "right")  # the boundaries a stretch pulls apart along x


def _check_stretch(case: Case) -> None:
    """What a stretch needs: the imex star solve (Imex.impose holds the end velocities as
    supports) with a nonsmooth law. (Rectangles and boxes have the STRETCHED boundaries;
    the runner checks an imported mesh.)"""
    where = "load.kind = 'stretch' with"
    if case.time.scheme != "imex":
        raise CaseError(f"{where} time.scheme = {case.time.scheme!r}: not available (the imposed end "
                        "velocities need the imex star solve); use time.scheme = 'imex'")
    if _law(case.interface).springs:
        raise CaseError(f"{where} interface.law = {case.interface.law!r}: not available (its inverted star blocks "
                        "cannot move prescribed components); use a nonsmooth law, e.g. 'linear_softening'")


def _check_load(load: Load, geometry: Geometry) -> None:
    """Rules linking the keys of [load] (and the region to the geometry's dimension)."""
    if load.signal == "h2-air":
        _check_h2_air(load)
    if load.signal == "charge":
        _check_charge(load, geometry)
    if load.signal == "deflagration" or (load.signal == "h2-air" and load.regime == "deflagration"):
        if load.rise <= 0:
            raise CaseError(f"load.rise = {load.rise!r}: must be > 0 for a deflagration (s)")
        if load.duration <= load.rise:
            raise CaseError(f"load.duration = {load.duration!r}: must be > load.rise = "
                            f"{load.rise!r} for a deflagration (s)")
    if load.signal == "detonation":
        if load.plateau > load.peak:
            raise CaseError(f"load.plateau = {load.plateau!r}: must be <= load.peak = "
                            f"{load.peak!r} (Pa; the spike decays to the plateau)")
        local = {"local_time": load.local_time, "local_width": load.local_width}
        if load.local_peak == 0:
            for name, value in local.items():
                if value is not None:
                    raise CaseError(f"load.{name} = {value!r}: only allowed when load.local_peak > 0")
        else:
            for name, value in local.items():
                if value is None:
                    raise CaseError(f"missing key load.{name} (required when load.local_peak > 0): "
                                    "must be a number (s)")
            start, stop = load.local_time - load.local_width / 2, load.local_time + load.local_width / 2
            if start < 0 or stop > load.duration:
                raise CaseError(f"load.local_time = {load.local_time!r}, load.local_width = "
                                f"{load.local_width!r}: the local peak [{start:.3g}, {stop:.3g}] s "
                                f"must lie inside [0, load.duration = {load.duration!r}] s")
    corners = {"region_min": load.region_min, "region_max": load.region_max}
    keys = {**corners, "region_factor": load.region_factor}
    given = [name for name, value in keys.items() if value is not None]
    if given and len(given) < len(keys):
        missing = ", ".join(f"load.{name}" for name in keys if name not in given)
        raise CaseError(f"load.{given[0]} = {_show(keys[given[0]])}: the region needs "
                        f"load.region_min, load.region_max and load.region_factor; missing {missing}")
    if given:
        for name, corner in corners.items():
            if geometry.tdim is not None and len(corner) != geometry.tdim:
                raise CaseError(f"load.{name} = {_show(list(corner))}: must have {geometry.tdim} "
                                f"coordinates (m), one per axis of the {geometry.tdim}D geometry")
        if not all(lo < hi for lo, hi in zip(load.region_min, load.region_max)):
            raise CaseError(f"load.region_max = {_show(list(load.region_max))}: every coordinate must "
                            f"be > load.region_min = {_show(list(load.region_min))} (m)")


def _check_charge(load: Load, geometry: Geometry) -> None:
    """A charge: its centre has the geometry's dimension, its explosive the equivalence
    asked, and no region (its own distances shape the load)."""
    if geometry.tdim is not None and len(load.position) != geometry.tdim:
        raise CaseError(f"load.position = {_show(list(load.position))}: must have {geometry.tdim} coordinates (m), "
                        f"one per axis of the {geometry.tdim}D geometry")
    if EQUIVALENTS[load.explosive][EQUIVALENCES.index(load.equivalence)] is None:
        raise CaseError(f"load.equivalence = {load.equivalence!r}: {load.explosive} has no {load.equivalence} "
                        f"equivalence in {EXPLOSIVES_SOURCE}; allowed: 'pressure'")
    if load.region_factor is not None:
        raise CaseError(f"load.region_factor = {load.region_factor!r}: a charge's pressure follows from each "
                        "facet's distance and angle; remove the region keys")


def _check_h2_air(load: Load) -> None:
    """The mixture of an h2-air load within its limits (loads/mixture.py), and the keys that
    belong to one regime only."""
    _check_mixture(load)
    only = {"deflagration": ("rise",), "detonation": ("decay", "damping")}
    for regime, names in only.items():
        for name in names:
            value = getattr(load, name)
            if regime != load.regime and value is not None:
                raise CaseError(f"load.{name} = {value!r}: only allowed when load.regime is {regime!r} "
                                f"(--set load.{name}= removes it)")
    if load.regime == "deflagration" and load.rise is None:
        raise CaseError("missing key load.rise (required when load.regime is 'deflagration'): "
                        "must be a number > 0 (s)")


def _check_mixture(load: Load) -> None:
    """h2_fraction within its oxidiser's limits; a diluted oxygen mixture no more diluted
    than air and of an equivalence ratio within air's limits (loads/mixture.py's docstring)."""
    low, high = mixture.H2_LIMITS[load.oxidizer]
    if not low <= load.h2_fraction <= high:
        raise CaseError(f"load.h2_fraction = {load.h2_fraction!r}: with load.oxidizer = {load.oxidizer!r} must be "
                        f">= {low:g} and <= {high:g} (-, H2 by volume in H2-{load.oxidizer}: "
                        f"{'its detonation limits' if load.oxidizer == 'oxygen' else 'a complete burn'})")
    if load.oxidizer != "oxygen" or load.diluent_fraction == 0:
        return
    given = mixture.Mixture(load.h2_fraction, load.oxidizer, load.diluent, load.diluent_fraction)
    phi = mixture.equivalence_ratio(load.h2_fraction, "oxygen")
    phi_low, phi_high = (mixture.equivalence_ratio(x, "air") for x in mixture.H2_LIMITS["air"])
    if not phi_low <= phi <= phi_high:
        x_low, x_high = (2 * p / (2 * p + 1) for p in (phi_low, phi_high))  # x = 2 phi / (2 phi + 1) in oxygen
        raise CaseError(f"load.h2_fraction = {load.h2_fraction!r}: with load.diluent_fraction > 0 must be >= "
                        f"{x_low:.3f} and <= {x_high:.3f} (-, the equivalence ratios {phi_low:.3g}-{phi_high:.3g} "
                        f"of H2-air's limits)")
    per_o2 = mixture.diluent_per_o2(given)
    if per_o2 > mixture.DILUENT_PER_O2:
        most = mixture.DILUENT_PER_O2 * (1 - load.h2_fraction) / (1 + mixture.DILUENT_PER_O2 * (1 - load.h2_fraction))
        raise CaseError(f"load.diluent_fraction = {load.diluent_fraction!r}: {per_o2:.3g} moles of {load.diluent} "
                        f"per mole of O2; at most {mixture.DILUENT_PER_O2:g} (air's N2) allowed, i.e. "
                        f"<= {most:.4f} with load.h2_fraction = {load.h2_fraction!r} (-, of the whole mixture)")


