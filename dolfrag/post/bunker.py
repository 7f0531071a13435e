"""The bunker's block of summary.json: how far its long wall bent, against thin plates of the
same panel, and which walls and the roof broke into how many free fragments."""
import numpy as np

from dolfrag import bunker
from dolfrag.reference import analytic

LONG_WALL = "wall_north"  # the long wall without the door: a plain panel


def long_wall_centre(x, lay, size):
    """Indices of the points ``x`` (n, 3) (m) on the long wall's centre line across its
    thickness: in the wall_north box, within one mesh size of (x, z) = (X / 2, H / 2) (an
    unstructured mesh may have no vertex nearer a line)."""
    lo, hi = lay.pieces[LONG_WALL]
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2])
    inside = (x[:, 1] >= lo[1] - 1e-9 * hi[1]) & np.all(np.abs(x[:, [0, 2]] - centre) < size, axis=1)
    return np.flatnonzero(inside)


def panel(geometry):
    """(a, b, t) m: the long wall as a plate, spanning the room's length between the short
    walls' mid-planes and its height from the ground to the roof's mid-plane, wall thick."""
    lay = bunker.layout(geometry)
    (L_x, _, H), t = lay.room[1] - lay.room[0], lay.wall
    return float(L_x + t), float(H + t / 2), t


def plate_estimates(geometry, material):
    """Centre deflection per unit pressure (m/Pa) of the long wall as a thin plate
    (analytic.py), clamped and simply supported on its four edges: its real edges (a clamped
    base, corners with the short walls and the roof) lie between."""
    a, b, t = panel(geometry)
    D = analytic.plate_rigidity(material.E, t, material.nu)
    return {"span_m": [a, b], "thickness_m": t,
            "clamped_m_Pa": analytic.clamped_plate_deflection(1.0, a, b, D),
            "simply_supported_m_Pa": analytic.simply_supported_plate_deflection(1.0, a, b, D)}


def pieces(table):
    """Per volume group (the walls, the roof, the door panel): the free fragments (not held by
    a support) that mostly came from it, their mass (kg), and the largest speed (m/s).
    table: post.fragment_table.FragmentTable."""
    block = {}
    group = np.asarray(table.group)
    for name in dict.fromkeys(table.group):
        free = (group == name) & ~table.held
        block[name] = {"free_fragments": int(free.sum()), "free_mass_kg": float(table.mass[free].sum()),
                       "largest_speed_m_s": float(table.speed[free].max(initial=0.0))}
    return block
