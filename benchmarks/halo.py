"""The ghost layer of a star partition: what each part owns, ghosts and exchanges per step.

Under dolfrag's parallel layout (mesh.star_partitioner, docs/method.md "Parallel layout") a part holds
its own cells and every cell sharing a vertex with one of them, so its ghost cells are the
cells it does not own that share a vertex with a cell it owns. DG-P1 dofs live in cells,
so a ghost cell brings its (tdim + 1) vertex copies, gdim components each, as ghost
values: a forward update sends each part the ghost cells' values from their owners, a
reverse update sends them back. A vertex is owned by one of the parts owning a cell
around it (DOLFINx 0.5.2 picks one at random), and that part solves the vertex's star.

Everything here works on the whole mesh on one process, for any number of parts (a
partition need not be run to be measured): pure numpy / scipy.sparse, not collective.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass
class Halo:
    """Per-part counts of a star partition; every array has shape (n_parts,).

    owned: cells the part owns.   ghosts: cells it holds but does not own.
    neighbours: other parts it exchanges ghost values with (symmetric: a part ghosts a
    cell of each of its neighbours and they ghost one of its cells).
    sent: cells of this part ghosted by others, counted once per part ghosting them
    (what it sends in a forward update; ``ghosts`` is what it receives).
    star_cells: cells around the vertices the part owns, each cell counted once per
    such vertex and divided by the cell's tdim + 1 vertices: the share of the star
    (interface) work, summing to the cell count over the parts (float).
    """
    owned: np.ndarray
    ghosts: np.ndarray
    neighbours: np.ndarray
    sent: np.ndarray
    star_cells: np.ndarray

    def bytes_received(self, tdim, gdim, itemsize=8):
        """Bytes a part receives in one ghost update of a DG-P1 vector field (n_parts,)."""
        return self.ghosts * (tdim + 1) * gdim * itemsize

    def bytes_sent(self, tdim, gdim, itemsize=8):
        """Bytes a part sends in one ghost update of a DG-P1 vector field (n_parts,)."""
        return self.sent * (tdim + 1) * gdim * itemsize


def _incidence(rows, cols, shape):
    return sp.csr_matrix((np.ones(len(rows), dtype=np.int64), (rows, cols)), shape=shape)


def cell_vertex_incidence(c2v, n_vertices=None):
    """(n_cells, n_vertices) 0/1 CSR matrix of c2v (n_cells, tdim + 1) vertex indices."""
    n_cells, k = c2v.shape
    n_vertices = int(c2v.max(initial=-1)) + 1 if n_vertices is None else n_vertices
    return _incidence(np.repeat(np.arange(n_cells), k), c2v.ravel(), (n_cells, n_vertices))


def vertex_parts(C, owner, n_parts):
    """(n_parts, n_vertices) 0/1 CSR: the parts owning a cell around each vertex."""
    O = _incidence(np.arange(len(owner)), owner, (len(owner), n_parts))
    PV = (O.T @ C).tocsr()
    PV.data[:] = 1
    return PV, O


def random_vertex_owners(PV, seed=0):
    """Owner part of each vertex (n_vertices,), uniformly at random among the parts
    owning a cell around it (DOLFINx 0.5.2's rule: ``determine_sharing_ranks`` makes a
    random sharing rank the owner), drawn with a fixed seed."""
    by_vertex = PV.tocsc()
    count = np.diff(by_vertex.indptr)
    pick = np.floor(np.random.default_rng(seed).random(len(count)) * count).astype(np.int64)
    return by_vertex.indices[by_vertex.indptr[:-1] + pick]


def star_halo(c2v, owner, n_parts, vertex_owner=None):
    """Halo of the partition ``owner`` (n_cells,) int in [0, n_parts) of the mesh
    c2v (n_cells, tdim + 1); vertex_owner (n_vertices,): the part owning each vertex
    (default random_vertex_owners). Returns a Halo."""
    owner = np.asarray(owner, dtype=np.int64)
    C = cell_vertex_incidence(c2v)
    PV, O = vertex_parts(C, owner, n_parts)
    held = (PV @ C.T).tocsr()  # parts x cells: cells sharing a vertex with an owned cell
    held.data[:] = 1
    ghost = (held - O.T).tocsr()
    ghost.eliminate_zeros()
    pairs = (ghost @ O).tocsr()  # ghost cells of part p owned by part q
    if vertex_owner is None:
        vertex_owner = random_vertex_owners(PV)
    star_size = np.diff(C.tocsc().indptr)
    return Halo(owned=np.bincount(owner, minlength=n_parts),
                ghosts=np.asarray(ghost.sum(axis=1)).ravel(),
                neighbours=np.diff(pairs.indptr),
                sent=np.asarray(pairs.sum(axis=0)).ravel(),
                star_cells=np.bincount(vertex_owner, weights=star_size, minlength=n_parts) / c2v.shape[1])
