"""Size and run-length guards, from the case alone (before meshing): a mesh or a run too
big for the machine is refused with its estimate and the key that raises the limit, and
a body only a few elements thick gets a one-line warning.

Estimates (measured on gmsh's meshes, dolfrag/cases at several sizes h): an unstructured
triangle mesh has about 2.4 cells per h^2 of area (2.33-2.41), a structured one 2 per
square, a tetrahedral one about 6 per h^3 of volume (5.7 on a 0.3 m x 0.3 m x 0.1 m slab
at h = 0.03 m). The bulk's stable step is about 0.5 h / c_p in 2D (0.47-0.66) and
0.16 h / c_p in 3D (c_p the P-wave speed). The bars are left out: where they shorten the
step (rebar/stable_step.py; the 2D bending walls by a fifth), the run takes more steps than
the estimate.
"""
import math
import sys

from dolfrag import bunker, concrete, viscosity
from dolfrag.reference import analytic
from dolfrag.case import CaseError

CELLS_PER_H2 = 2.4         # triangles per h^2 of area (unstructured)
CELLS_PER_H2_GRID = 2.0    # triangles per h^2 of area (geometry.structured)
CELLS_PER_H3 = 6.0         # tetrahedra per h^3 of volume
STEP_PER_H = {2: 0.5, 3: 0.16}   # stable bulk step x c_p / h
THIN = 3                   # fewer elements than this across: warned
SLIVER = 0.2               # a stable step below this share of the estimate: a sliver sets it
AXES = {"left": 0, "right": 0, "bottom": 1, "top": 1, "front": 2, "back": 2}
EXTENT_KEYS = ("geometry.length", "geometry.width", "geometry.thickness")


def extents(geometry):
    """(length, width[, thickness]) (m) of a rectangle or box; None for an imported mesh
    or a bunker (its walls: _bunker_warning)."""
    if geometry.kind in ("file", "bunker"):
        return None
    return (geometry.length, geometry.width, geometry.thickness)[:geometry.tdim]


def elements_across(length, h):
    """Elements gmsh puts along an edge of this length (m) at element size h (m): it places
    int(length / h + 1.99) points (meshGEdge.cpp), so 0.2 m at h = 0.0667 m is 3 elements."""
    return int(length / h + 0.99)


def cells_in(sides, h, structured=False):
    """Cells gmsh makes in a rectangle or box of these sides (m) at element size h (m)."""
    if len(sides) == 3:
        return CELLS_PER_H3 * math.prod(sides) / h**3
    return (CELLS_PER_H2_GRID if structured else CELLS_PER_H2) * math.prod(sides) / h**2


def cells_estimate(geometry, h):
    """Cells gmsh makes for a rectangle, box or bunker at element size h (m); None for a
    file (mesh.build estimates a .geo from its bounding box once gmsh has read it)."""
    if geometry.kind == "bunker":
        return CELLS_PER_H3 * bunker.layout(geometry).volume() / h**3
    sides = extents(geometry)
    return None if sides is None else cells_in(sides, h, geometry.structured)


def stable_step_estimate(case):
    """The bulk's stable step (s) gmsh's cells of mesh.size usually give (module docstring),
    with the stiffest material."""
    c_p = max(math.sqrt(analytic.p_wave_modulus(m.E, m.nu, case.material.hypothesis) / m.rho)
              for m in (case.material, *case.materials.values()))
    return STEP_PER_H[case.geometry.tdim] * case.mesh.size / c_p


def sliver_warning(case, dt_crit):
    """The one-line warning (or None) when the mesh's stable step dt_crit (s, the bulk's,
    before time.cfl and the bulk viscosity) is below SLIVER x stable_step_estimate: a flat
    cell (a sliver) then sets every step of the run."""
    expected = stable_step_estimate(case)
    if dt_crit >= SLIVER * expected:
        return None
    return (f"dolfrag: warning: the mesh's stable step, {dt_crit:.3g} s, is {expected / dt_crit:.0f} times below "
            f"the {expected:.3g} s cells of mesh.size = {case.mesh.size:g} m usually give: a flat cell (a sliver) "
            "sets it; another mesh.size, or gmsh's Mesh.Smoothing and Mesh.OptimizeThreshold in a .geo, may remove it")


def steps_estimate(case, applied_load):
    """Time steps of the run: time.end over the step, for imex time.cfl x the bulk's
    estimated stable step at mesh.size with the stiffest material, for theta time.dt or
    the accuracy step of the load as applied (``applied_load``, loads.applied)."""
    time = case.time
    if time.scheme == "theta":
        from dolfrag.loads import accuracy_time_step
        return time.end / (time.dt or accuracy_time_step(applied_load, time.end))
    factor = viscosity.step_factor() if viscosity.applies(case) else 1.0  # it lowers the stable step
    return time.end / (time.cfl * factor * stable_step_estimate(case))


def check(case, applied_load):
    """Refuse (CaseError) a case whose mesh or run is above run.max_cells / run.max_steps,
    or whose mesh.size exceeds the body's thinnest extent; applied_load: its load as applied
    (loads.applied). Returns the warning (one line, or None) when fewer than THIN elements
    fit across the loaded thickness or the thinnest extent."""
    h = case.mesh.size
    sides = extents(case.geometry)
    thinnest = None if sides is None else min(range(len(sides)), key=sides.__getitem__)
    if sides is not None and h > sides[thinnest]:
        raise CaseError(f"mesh.size = {h!r}: larger than the body's thinnest extent "
                        f"{EXTENT_KEYS[thinnest]} = {sides[thinnest]!r}; must be <= {sides[thinnest]:g} m "
                        f"(<= {sides[thinnest] / THIN:.3g} m for {THIN} elements across)")
    cells = cells_estimate(case.geometry, h)
    if cells is not None and cells > case.run.max_cells:
        raise CaseError(f"mesh.size = {h!r}: about {cells:.3g} cells, above run.max_cells = "
                        f"{case.run.max_cells:g}; raise mesh.size or run.max_cells (--set run.max_cells=...)")
    steps = steps_estimate(case, applied_load)
    if steps > case.run.max_steps:
        raise CaseError(f"time.end = {case.time.end!r}: about {steps:.3g} time steps of {case.time.end / steps:.3g} s "
                        f"(the stable step at mesh.size and material.E), above run.max_steps = "
                        f"{case.run.max_steps:g}; shorten time.end or raise run.max_steps (--set run.max_steps=...)")
    if case.geometry.kind == "bunker":
        return _bunker_warning(case.geometry, h)
    if sides is None:
        return None
    loaded = AXES.get(case.load.boundary) if case.load.kind == "pressure" else None
    for axis, what in ((loaded, "loaded thickness"), (thinnest, "thinnest extent")):
        if axis is not None and axis < len(sides) and elements_across(sides[axis], h) < THIN:
            return (f"dolfrag: warning: the {what} {EXTENT_KEYS[axis]} = {sides[axis]:g} m is only "
                    f"{elements_across(sides[axis], h)} elements across at mesh.size = {h:g} m; {THIN} or more "
                    "resolve a wave or a bending crack")
    return None


def _bunker_warning(geometry, h):
    """The one-line warning when fewer than THIN elements fit across a bunker's thinnest
    concrete (its walls, or the door panel), else None; CaseError when not even one does."""
    thinnest = bunker.layout(geometry).thinnest()
    if h > thinnest:
        raise CaseError(f"mesh.size = {h!r}: larger than the bunker's thinnest concrete (geometry.wall, or "
                        f"geometry.door_thickness), {thinnest:g} m; must be <= {thinnest:g} m")
    if elements_across(thinnest, h) >= THIN:
        return None
    return (f"dolfrag: warning: the bunker's thinnest concrete (geometry.wall, or geometry.door_thickness) is "
            f"{thinnest:g} m, only {elements_across(thinnest, h)} elements across at mesh.size = {h:g} m; {THIN} "
            "or more resolve a wave or a bending crack")


def is_structure(case):
    """A reinforced, supported or bunker case (not a free specimen such as a Hopkinson bar)."""
    sup = case.supports
    return bool(case.rebar.faces or sup.clamped or sup.simple or case.geometry.kind == "bunker")


def toughness_warning(case):
    """The one-line warning (or None) when a structure's crack energy follows the mesh:
    RCCM with w = sigma_c^2 / C_N and C_N = stiffness_ratio E / h makes it proportional
    to h, far below the fracture energy of concrete (docs/materials.md)."""
    interface = case.interface
    if interface.law != "rccm" or interface.w is not None or not is_structure(case):
        return None
    C_N = interface.stiffness(case.material.E, case.mesh.size)[0]
    grade = case.material.grade
    G_F = (f"G_F = {concrete.concrete(grade).G_F:.0f} J/m^2 for {grade}" if grade else
           "G_F = 100-150 J/m^2 for ordinary concrete")
    return (f"dolfrag: warning: interface.law = 'rccm' ties the crack energy to the mesh: w = sigma_c^2 / C_N = "
            f"{interface.sigma_c**2 / C_N:.3g} J/m^2 at mesh.size = {case.mesh.size:g} m, where concrete needs "
            f"{G_F} (fib Model Code 2010); interface.law = 'linear_softening' with material.grade keeps it "
            "(docs/materials.md)")


def warn(line, comm):
    """Print a warning line (or nothing for None) to stderr on rank 0."""
    if line and comm.rank == 0:
        print(line, file=sys.stderr)


def report(case, applied_load, comm):
    """check(case, applied_load), its warning printed to stderr by rank 0."""
    warn(check(case, applied_load), comm)
