"""Fragments: the connected pieces of the body, from the broken state of the links.

Rule: two cells sharing an interior facet belong to the same fragment if at least
one link of that facet is not broken. A facet is cut only when all its links are
broken. Fragments are the connected components of the cell graph whose edges are the
facets that are not cut. A cell with every facet cut is a fragment of its own.

The links of one facet may sit on different ranks (interface/links.py), so a facet is
identified by a key that is the same on every rank: the sorted pair of global indices
of its two cells. Each interior facet joins exactly two cells, so no facet index map
is needed.

The time a facet is cut is the time its last link broke. Two fragments that touch
separated when the last facet between them was cut: ``Fragments.separated_at``.

Parallel limit: every rank sends rank 0 one row per owned cell and one per owned
link. Rank 0 builds the global graph and works out the fragments, then broadcasts them.
Rank 0's memory grows with the global mesh. This is fine for the post-processing of a
single run; a distributed union-find would be needed for very large meshes.
"""
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

# Fragments are ordered by their centroids rounded to 10^-ORDER_DIGITS of the body size.
# Mirror-image cells share a centroid x up to round-off (seen on the test rectangle), and
# 1 and 2 ranks sum in different orders. Rounding keeps the order the same.
ORDER_DIGITS = 9


@dataclass(frozen=True)
class Fragments:
    """The fragments of the body. Every rank holds the same copy, ordered by centroid
    x, then y, then z.

    mass (k,) kg (kg per metre of depth in 2D).
    centroid (k, gdim) m: mass centre, in the deformed configuration if a displacement
    was given.
    velocity (k, gdim) m/s: mean velocity, momentum / mass.
    bbox_min, bbox_max (k, gdim) m: corners of the bounding box of the fragment's cells.
    cells (k,) int64: number of cells.
    neighbours (p, 2) int64: pairs of fragments (indices in this order, i < j) that share
    cut facets; separated_at (p,) s: when the last facet between them was cut (NaN if no
    break times were given).
    """
    mass: np.ndarray
    centroid: np.ndarray
    velocity: np.ndarray
    bbox_min: np.ndarray
    bbox_max: np.ndarray
    cells: np.ndarray
    neighbours: np.ndarray
    separated_at: np.ndarray

    def __len__(self):
        return len(self.mass)

    def came_free(self):
        """(k,) s: when each fragment came free, the latest ``separated_at`` of the pairs it
        is in (the last facet joining it to another piece was cut then); NaN for a piece
        that touches no other (never joined) or whose break times are unknown."""
        time = np.full(len(self), np.nan)
        for side in (0, 1):
            np.fmax.at(time, self.neighbours[:, side], self.separated_at)
        return time

    def to_dict(self):
        """JSON-ready dict of plain lists (for summary.json), plus ``count``; NaN times
        become null."""
        out = {name: getattr(self, name).tolist()
               for name in ("mass", "centroid", "velocity", "bbox_min", "bbox_max", "cells", "neighbours")}
        out["separated_at"] = [None if np.isnan(t) else t for t in self.separated_at.tolist()]
        return {"count": len(self), **out}


def _cell_rows(space, mass, velocity, displacement):
    """Per owned cell: mass (n,) kg, momentum, first moment of mass, min and max corner
    (n, gdim each). The mass of a dof is the mean of its component masses. These are
    equal for the lumped mass."""
    d = space.gdim
    dofs = space.cell_dofs[:space.n_owned_cells]
    m = np.asarray(mass).reshape(-1, d)[dofs]
    x = space.x if displacement is None else space.x + np.asarray(displacement).reshape(-1, d)
    x = x[dofs]
    m_dof = m.mean(axis=2)
    momentum = (m * np.asarray(velocity).reshape(-1, d)[dofs]).sum(axis=1)
    moment = (m_dof[..., None] * x).sum(axis=1)
    return m_dof.sum(axis=1), momentum, moment, x.min(axis=1), x.max(axis=1)


def _facet_rows(space, links, broken, break_time):
    """Per owned link: global indices (n, 2) of its facet's two cells, sorted, whether
    the link holds (not broken), and when it broke (s)."""
    tdim = space.mesh.topology.dim
    f2c = space.mesh.topology.connectivity(tdim - 1, tdim)
    local = f2c.array[f2c.offsets[links.facet][:, None] + np.arange(2)]
    cells = space.mesh.topology.index_map(tdim).local_to_global(local.ravel().astype(np.int32))
    return np.sort(cells.reshape(-1, 2), axis=1), ~np.asarray(broken, dtype=bool), break_time


def _reduce(order, starts, values, ufunc=np.add):
    """``ufunc`` over the rows of each fragment (rows taken in ``order``; fragment i
    starts at row ``starts[i]``)."""
    return ufunc.reduceat(values[order], starts, axis=0)


def _combine(n_cells, cell_rows, facet_rows):
    """Fragments from the gathered rows of all ranks (on rank 0), and the fragment of
    every cell (n_cells,) int64, by global cell index."""
    gidx = np.concatenate([r[0] for r in cell_rows])
    fields = []
    for j in range(5):  # mass, momentum, moment, min corner, max corner
        parts = np.concatenate([r[1][j] for r in cell_rows])
        full = np.empty((n_cells,) + parts.shape[1:])
        full[gidx] = parts
        fields.append(full)
    mass, momentum, moment, lo, hi = fields
    pairs = np.concatenate([r[0] for r in facet_rows]).astype(np.int64)
    holds = np.concatenate([r[1] for r in facet_rows])
    link_time = np.concatenate([r[2] for r in facet_rows])
    key, inverse = np.unique(pairs[:, 0] * n_cells + pairs[:, 1], return_inverse=True)
    joined = np.bincount(inverse, weights=holds, minlength=len(key)) > 0
    facet_time = np.full(len(key), -np.inf)
    np.maximum.at(facet_time, inverse, np.where(np.isnan(link_time), -np.inf, link_time))
    a, b = key[joined] // n_cells, key[joined] % n_cells
    graph = sp.csr_matrix((np.ones(len(a)), (a, b)), shape=(n_cells, n_cells))
    k, labels = connected_components(graph, directed=False)
    order = np.argsort(labels, kind="stable")
    starts = np.searchsorted(labels[order], np.arange(k))
    m = _reduce(order, starts, mass)
    centroid = _reduce(order, starts, moment) / m[:, None]
    velocity = _reduce(order, starts, momentum) / m[:, None]
    bbox_min = _reduce(order, starts, lo, np.minimum)
    bbox_max = _reduce(order, starts, hi, np.maximum)
    count = np.diff(np.append(starts, n_cells)).astype(np.int64)
    scale = np.max(hi.max(axis=0) - lo.min(axis=0))
    rounded = np.round(centroid / scale, ORDER_DIGITS)
    sort = np.lexsort(rounded.T[::-1])
    position = np.empty(k, dtype=np.int64)
    position[sort] = np.arange(k)
    neighbours, separated_at = _separations(position[labels], key[~joined], facet_time[~joined], n_cells)
    return Fragments(m[sort], centroid[sort], velocity[sort], bbox_min[sort], bbox_max[sort],
                     count[sort], neighbours, separated_at), position[labels]


def _separations(fragment_of_cell, cut_keys, cut_time, n_cells):
    """Pairs of fragments sharing cut facets, and when their last shared facet was cut."""
    pair = np.sort(fragment_of_cell[np.stack([cut_keys // n_cells, cut_keys % n_cells], axis=1)], axis=1)
    between = pair[:, 0] != pair[:, 1]  # facets cut inside a fragment do not separate it
    k = fragment_of_cell.max() + 1
    pair_key, inverse = np.unique(pair[between, 0] * k + pair[between, 1], return_inverse=True)
    time = np.full(len(pair_key), -np.inf)
    np.maximum.at(time, inverse, cut_time[between])
    return np.stack([pair_key // k, pair_key % k], axis=1), np.where(np.isinf(time), np.nan, time)


def fragments(space, links, broken, mass, velocity, displacement=None, break_time=None, of_cells=False):
    """The fragments of the body (module rule). Collective. Every rank returns the same
    Fragments, whatever the number of ranks. Reads its inputs and never changes them.

    space: space.Space. links: interface.links.Links, the owned links of this rank.
    broken (n_owned_links,) bool: e.g. ``model.broken()``.
    mass: flat lumped mass of every local dof component, kg (``bulk.m.x.array``).
    velocity, displacement: flat dof arrays like ``Function.x.array``, m/s and m. Only
    the owned values are read. The centroid and bbox include the displacement if
    one is given. break_time (n_owned_links,) s: when each broken link broke (NaN for
    the others), for ``separated_at``. of_cells: also return the fragment (index into
    the Fragments) of each owned cell, (n_owned_cells,) int64.
    """
    broken = np.asarray(broken)
    if broken.shape != (len(links),):
        raise ValueError(f"broken has shape {broken.shape}; expected ({len(links)},), "
                         "one flag per owned link")
    comm = space.mesh.comm
    tdim = space.mesh.topology.dim
    imap = space.mesh.topology.index_map(tdim)
    gidx = imap.local_to_global(np.arange(space.n_owned_cells, dtype=np.int32))
    cell_rows = comm.gather((gidx, _cell_rows(space, mass, velocity, displacement)), root=0)
    if break_time is None:
        break_time = np.full(len(links), np.nan)
    facet_rows = comm.gather(_facet_rows(space, links, broken, np.asarray(break_time, dtype=float)), root=0)
    result, of_cell = _combine(imap.size_global, cell_rows, facet_rows) if comm.rank == 0 else (None, None)
    frags = comm.bcast(result, root=0)
    if not of_cells:
        return frags
    return frags, comm.scatter([of_cell[rows[0]] for rows in cell_rows] if comm.rank == 0 else None, root=0)


class Breaks(NamedTuple):
    """Breaks of a bar-like body, in order along the bar (from the free end if one was
    given): distance (m) from the free end, or position on the axis; time (s) it
    completed, NaN if unknown."""
    distance: np.ndarray
    time: np.ndarray


def breaks_along(frags, axis=0, free_end=None):
    """Breaks of a bar-like body along ``axis``.

    The fragments are ordered by centroid along the axis. A break is the midpoint
    between one fragment's bbox_max and the next one's bbox_min; it completed when
    those two fragments separated (``Fragments.separated_at``). If ``free_end`` is given
    (m, the coordinate of the free end), distances are ``|free_end - position|``, nearest
    first. Every fragment counts, even a single detached cell.
    """
    order = np.argsort(frags.centroid[:, axis], kind="stable")
    lo, hi = frags.bbox_min[order, axis], frags.bbox_max[order, axis]
    position = 0.5 * (hi[:-1] + lo[1:])
    when = dict(zip(map(tuple, frags.neighbours.tolist()), frags.separated_at))
    pairs = np.sort(np.stack([order[:-1], order[1:]], axis=1), axis=1)
    time = np.array([when.get(tuple(p), np.nan) for p in pairs.tolist()])
    if free_end is None:
        return Breaks(position, time)
    distance = np.abs(free_end - position)
    nearest = np.argsort(distance, kind="stable")
    return Breaks(distance[nearest], time[nearest])


def breaks_by_time(frags, free_end, axis=0):
    """JSON-ready breaks of a bar (``breaks_along`` from ``free_end``, m): a list of
    {distance_from_free_end_m, time_s}, first to complete first, unknown times (None) last."""
    along = breaks_along(frags, axis=axis, free_end=free_end)
    first = np.argsort(np.nan_to_num(along.time, nan=np.inf), kind="stable")
    return [{"distance_from_free_end_m": float(along.distance[i]),
             "time_s": None if np.isnan(along.time[i]) else float(along.time[i])} for i in first]
