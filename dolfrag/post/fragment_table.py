"""fragments.csv: the fragments of a run as an engineer reads them, one row per piece.

Per fragment (post/fragments.Fragments gives mass, centroid and mean velocity): its volume,
speed, the kinetic energy of its mean motion, its largest dimension, when it came free
(``Fragments.came_free``), the material group holding most of its mass, and whether a
clamped or simply supported boundary holds it. SI units; in 2D per metre of depth (mass
kg/m, volume m^2, energy J/m).

Largest dimension: the largest distance between two vertices of the fragment's cells in the
undeformed configuration (the diameter of its point set; of its convex hull's vertices when
it has more than HULL_ABOVE points).

Parallel: every rank sends rank 0 one row per owned cell (fragment, volume, mass, group,
held, corners); rank 0 builds the table and broadcasts it, as post/fragments.py does.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.distance import pdist

from dolfrag.space import cell_measures

HULL_ABOVE = 64  # points: above this the diameter is taken over the convex hull's vertices
HOLDING = ("clamped", "simple")  # supports that hold a piece in place (rollers let it slide)


@dataclass(frozen=True)
class FragmentTable:
    """Every rank holds the same copy, in the order of the Fragments (id = row index).

    mass (k,) kg; volume (k,) m^3 (undeformed); centroid (k, gdim) m; velocity (k, gdim)
    m/s; speed (k,) m/s; kinetic_energy (k,) J, 1/2 m |v|^2 of the mean motion; size (k,)
    m, the largest dimension; came_free (k,) s (NaN: never joined to another piece);
    group (k,) the name of the material group holding most of its mass ("" for untagged
    cells); held (k,) bool, it touches a clamped or simply supported boundary. In 2D per
    metre of depth: kg/m, m^2, J/m.
    """
    mass: np.ndarray
    volume: np.ndarray
    centroid: np.ndarray
    velocity: np.ndarray
    speed: np.ndarray
    kinetic_energy: np.ndarray
    size: np.ndarray
    came_free: np.ndarray
    group: tuple
    held: np.ndarray

    def __len__(self):
        return len(self.mass)


def held_cells(space, domain, supports):
    """(n_owned_cells,) bool: the owned cells with a corner on a boundary listed in
    ``supports`` (case.Supports) as clamped or simple."""
    names = [name for kind in HOLDING for name in getattr(supports, kind)]
    dofs = np.concatenate([space.boundary_dofs(domain.facet_tags, domain.boundary_tag(name)) for name in names]
                          + [np.empty(0, dtype=np.int64)])
    return np.isin(space.cell_dofs[:space.n_owned_cells], dofs).any(axis=1)


def cell_groups(space, domain):
    """(n_owned_cells,) int: each owned cell's material group tag (-1 when untagged)."""
    tags = np.full(len(space.cell_dofs), -1, dtype=np.int64)
    tags[domain.cell_tags.indices] = domain.cell_tags.values
    return tags[:space.n_owned_cells]


def largest_dimension(points):
    """m: the largest distance between two of ``points`` (n, gdim); 0 for one point."""
    points = np.unique(points, axis=0)
    if len(points) > HULL_ABOVE:
        points = points[ConvexHull(points).vertices]
    return pdist(points).max(initial=0.0)


def _by_fragment(fragment, values, k):
    """Sum of ``values`` (n,) over the cells of each of k fragments."""
    return np.bincount(fragment, weights=values, minlength=k)


def _build(frags, rows, group_names):
    """The FragmentTable from the gathered cell rows (on rank 0)."""
    fragment, volume, mass, tag, held, corners = (np.concatenate(parts) for parts in zip(*rows))
    k, d = len(frags), frags.centroid.shape[1]
    tags, tag_index = np.unique(tag, return_inverse=True)
    group_mass = _by_fragment(fragment * len(tags) + tag_index, mass, k * len(tags)).reshape(k, len(tags))
    order = np.argsort(fragment, kind="stable")
    starts = np.searchsorted(fragment[order], np.arange(k + 1))
    points = corners[order]  # (n, (d + 1) d): one cell's corners a row
    size = np.array([largest_dimension(points[a:b].reshape(-1, d)) for a, b in zip(starts[:-1], starts[1:])])
    speed = np.linalg.norm(frags.velocity, axis=1)
    return FragmentTable(frags.mass, _by_fragment(fragment, volume, k), frags.centroid, frags.velocity, speed,
                         0.5 * frags.mass * speed**2, size, frags.came_free(),
                         tuple(group_names.get(t, "") for t in tags[group_mass.argmax(axis=1)]),
                         _by_fragment(fragment, held.astype(float), k) > 0)


def fragment_table(space, domain, supports, mass, frags, fragment_of_cell):
    """The FragmentTable of ``frags`` (post.fragments.Fragments, with each owned cell's
    fragment ``fragment_of_cell``). mass: flat lumped mass of every local dof component, kg.
    Collective; every rank returns the same table."""
    d = space.gdim
    dofs = space.cell_dofs[:space.n_owned_cells]
    corners = space.x[dofs]
    cell_mass = np.asarray(mass).reshape(-1, d)[dofs].mean(axis=2).sum(axis=1)
    rows = space.mesh.comm.gather((np.asarray(fragment_of_cell, dtype=np.int64), cell_measures(corners), cell_mass,
                                   cell_groups(space, domain), held_cells(space, domain, supports),
                                   corners.reshape(len(dofs), -1)), root=0)
    names = {tag: name for name, tag in domain.materials.items()}
    return space.mesh.comm.bcast(None if rows is None else _build(frags, rows, names), root=0)


def columns(gdim):
    """fragments.csv's header: names with units (per metre of depth in 2D)."""
    depth = "_per_m" if gdim == 2 else ""
    axes = "xyz"[:gdim]
    return ["id", f"mass_kg{depth}", "volume_m2" if gdim == 2 else "volume_m3", *(f"{a}_m" for a in axes),
            *(f"v{a}_m_s" for a in axes), "speed_m_s", f"kinetic_energy_J{depth}", "largest_dimension_m",
            "came_free_s", "group", "held"]


def rows(table):
    """fragments.csv's rows (``columns``), one per fragment."""
    return [[i, table.mass[i], table.volume[i], *table.centroid[i], *table.velocity[i], table.speed[i],
             table.kinetic_energy[i], table.size[i], table.came_free[i], table.group[i], int(table.held[i])]
            for i in range(len(table))]
