"""The bunker: a closed reinforced concrete room on a rigid foundation (geometry.kind = "bunker").

The room's inside is the box [t, t + L_x] x [t, t + L_y] x [0, H] (m, z up), ``geometry.inner``
= (L_x, L_y, H); walls and roof are ``geometry.wall`` = t thick. The four walls stand on the
ground plane z = 0; the two long walls (normal y) run the whole outer length, the two short
walls (normal x) fit between them, and the roof covers the whole outer plan on top. A door
``geometry.door`` = (width, height) opens in the middle of the wall at y = 0 from the ground
up; with ``geometry.door_thickness`` > 0 it is closed by a concrete panel that thick, flush
with the inner face (a weaker part of the wall, the volume group ``door``), else it is a hole.
``geometry.scale`` multiplies every length (0.05: a 1/20 scale mock-up).

Physical groups (mesh.py names the mesh's):
  volumes  wall_south (y = 0, with the door), wall_north, wall_west (x = 0), wall_east, roof,
           and door (the panel, when there is one);
  faces    inner (every face of the room's inside: the walls', the roof's underside and the
           door panel's inner face; where an explosion loads it), ground (z = 0, clamped to the
           foundation), door (the faces of the opening, where there is one, and the panel's
           outer face), outer (the rest of the outside).
Every face between two volumes is an interface like any other facet of the mesh.
"""
from dataclasses import dataclass

import numpy as np

PIECES = ("wall_south", "wall_north", "wall_west", "wall_east", "roof")
BOUNDARIES = ("inner", "outer", "ground", "door")
# per piece: the axis across its thickness and whether the room lies on its high side
# along that axis (so the inner face is the piece's low face there)
_THIN_AXIS = {"wall_south": (1, True), "wall_north": (1, False), "wall_west": (0, True),
              "wall_east": (0, False), "roof": (2, False)}


@dataclass(frozen=True)
class Layout:
    """The bunker in metres, scale applied: pieces name -> (lo (3,), hi (3,)) boxes;
    opening: the door's box through the wall at y = 0 (lo, hi); panel: the door panel's
    box or None; room: the inside (lo, hi); wall, door_thickness: the thicknesses (m, 0
    without a panel)."""
    pieces: dict
    opening: tuple
    panel: tuple | None
    room: tuple
    wall: float
    door_thickness: float

    @property
    def outer_extent(self):
        return self.pieces["roof"][1]

    def volume(self):
        """Concrete volume (m^3): the pieces less the opening, plus the panel."""
        size = lambda box: float(np.prod(box[1] - box[0]))  # noqa: E731
        return sum(map(size, self.pieces.values())) - size(self.opening) + (size(self.panel) if self.panel else 0.0)

    def thinnest(self):
        """The thinnest concrete (m): the walls, or the door panel."""
        return min(self.wall, self.door_thickness) if self.panel else self.wall


def layout(geometry):
    """The Layout of a case.Geometry of kind "bunker"."""
    s = geometry.scale
    (L_x, L_y, H), t = (s * np.asarray(geometry.inner, dtype=float)), s * geometry.wall
    width, height = s * np.asarray(geometry.door, dtype=float)
    X, Y = L_x + 2 * t, L_y + 2 * t
    box = lambda lo, hi: (np.array(lo, dtype=float), np.array(hi, dtype=float))  # noqa: E731
    pieces = {"wall_south": box((0, 0, 0), (X, t, H)), "wall_north": box((0, t + L_y, 0), (X, Y, H)),
              "wall_west": box((0, t, 0), (t, t + L_y, H)), "wall_east": box((t + L_x, t, 0), (X, t + L_y, H)),
              "roof": box((0, 0, H), (X, Y, H + t))}
    opening = box((X / 2 - width / 2, 0, 0), (X / 2 + width / 2, t, height))
    d = s * geometry.door_thickness
    panel = box((X / 2 - width / 2, t - d, 0), (X / 2 + width / 2, t, height)) if d > 0 else None
    return Layout(pieces, opening, panel, box((t, t, 0), (t + L_x, t + L_y, H)), t, d)


def _within(face, box, tol):
    """Whether the bounding box ``face`` (lo, hi) lies in the box (lo, hi), up to tol (m)."""
    return bool(np.all(face[0] >= box[0] - tol) and np.all(face[1] <= box[1] + tol))


def face_group(face, lay, tol):
    """The boundary group (one of BOUNDARIES) of an outside face by its bounding box (lo, hi)
    (m): a face's centre may lie in the opening when the face has the door cut out of it."""
    lo, hi = lay.room
    if face[1][2] < tol:
        return "ground"
    flat = np.abs(face[1] - face[0]) < tol
    on_room_plane = np.any(flat & ((np.abs(face[0] - lo) < tol) | (np.abs(face[0] - hi) < tol)))
    if on_room_plane and _within(face, lay.room, tol):
        return "inner"
    if _within(face, lay.opening, tol):
        return "door"
    return "outer"


def build(gmsh, geometry, size, optimize_threshold=None):
    """Mesh the bunker of ``geometry`` with gmsh's OpenCASCADE kernel at element size
    ``size`` (m) and name its groups; optimize_threshold: gmsh's Mesh.OptimizeThreshold
    (None: 0.8). Returns the topological dimension, 3."""
    lay = layout(geometry)
    occ = gmsh.model.occ
    boxes = {name: [(3, occ.addBox(*lo, *(hi - lo)))] for name, (lo, hi) in lay.pieces.items()}
    lo, hi = lay.opening
    # a door as high as the room cuts its wall in two
    boxes["wall_south"], _ = occ.cut(boxes["wall_south"], [(3, occ.addBox(*lo, *(hi - lo)))])
    if lay.panel:
        lo, hi = lay.panel
        boxes["door"] = [(3, occ.addBox(*lo, *(hi - lo)))]
    names = [name for name in boxes for _ in boxes[name]]
    _, children = occ.fragment([box for name in boxes for box in boxes[name]], [])
    occ.synchronize()
    for value, name in enumerate(boxes, start=1):
        volumes = [tag for owner, child in zip(names, children) if owner == name for _, tag in child]
        gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, volumes, value), name)
    outside = gmsh.model.getBoundary(gmsh.model.getEntities(3), combined=True, oriented=False)
    tol = 1e-6 * float(lay.outer_extent.max())
    faces = {}
    for _, tag in outside:
        box = np.array(occ.getBoundingBox(2, abs(tag)))
        faces.setdefault(face_group((box[:3], box[3:]), lay, tol), []).append(abs(tag))
    for value, name in enumerate(BOUNDARIES, start=1):
        if name in faces:
            gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, faces[name], value), name)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMin", size)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMax", size)
    # Through walls one or two elements thick the Delaunay mesh keeps slivers (inner radius
    # 2e-5 m at size 0.2 m: a stable step of 1e-8 s) unless smoothed and optimised down to
    # a quality of 0.8: then the smallest inner radius is >= 0.35 x the median (0.2 and 0.1
    # m meshes). HXT gives as good tetrahedra but not the same mesh twice.
    gmsh.option.setNumber("Mesh.Smoothing", 5)
    gmsh.option.setNumber("Mesh.OptimizeThreshold", 0.8 if optimize_threshold is None else optimize_threshold)
    gmsh.model.mesh.generate(3)
    return 3


def _bars_in(lo, hi, thin, room_high, faces, cover, diameter, spacing):
    """The bars of one piece (lo, hi its box, m): near each face in ``faces`` ("inner",
    "outer"), two layers, one along each in-plane axis, the second one diameter further in;
    bars ``spacing`` apart, centred, as many as fit with half a spacing to each edge."""
    lines = []
    plane = [a for a in range(3) if a != thin]
    for face in faces:
        on_low = (face == "inner") == room_high  # the face sits on the piece's low side
        for layer, along in enumerate(plane):
            across = plane[1 - layer]
            depth = cover + layer * diameter
            level = lo[thin] + depth if on_low else hi[thin] - depth
            extent = hi[across] - lo[across]
            count = max(1, int(np.floor(extent / spacing + 1e-9)))
            for position in lo[across] + extent / 2 + (np.arange(count) - (count - 1) / 2) * spacing:
                ends = np.empty((2, 3))
                ends[:, thin], ends[:, across] = level, position
                ends[:, along] = lo[along], hi[along]
                lines.append(ends)
    return lines


def _clip(line, box):
    """The parts of an axis-parallel bar (2, 3) outside an axis-aligned box (lo, hi)."""
    lo, hi = box
    axis = int(np.argmax(np.abs(line[1] - line[0])))
    other = [a for a in range(3) if a != axis]
    a, b = sorted(line[:, axis])
    if not all(lo[k] < line[0, k] < hi[k] for k in other) or b <= lo[axis] or a >= hi[axis]:
        return [line]
    parts = []
    for start, stop in ((a, min(b, lo[axis])), (max(a, hi[axis]), b)):
        if stop > start:
            part = line.copy()
            part[:, axis] = start, stop
            parts.append(part)
    return parts


def rebar_polylines(rebar, geometry):
    """Polylines (list of (2, 3) arrays, m) and steel areas (m^2) of the bunker's bars: in
    every wall and the roof, near each face of ``rebar.faces`` ("inner", "outer"), a layer
    along each in-plane axis at ``rebar.cover`` (face to axis; the second layer one diameter
    further in), ``rebar.spacing`` apart. Bars stop at the door opening: none ties the door
    panel to the wall."""
    lay = layout(geometry)
    lines = []
    for name, (lo, hi) in lay.pieces.items():
        thin, room_high = _THIN_AXIS[name]
        for line in _bars_in(lo, hi, thin, room_high, rebar.faces, rebar.cover, rebar.diameter, rebar.spacing):
            lines.extend(_clip(line, lay.opening) if name == "wall_south" else [line])
    return lines, np.full(len(lines), np.pi * rebar.diameter**2 / 4)
