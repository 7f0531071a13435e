"""The link table: one link per vertex of every interior facet.

Conventions, defined here once for the whole package:

* A link joins the copy of a mesh vertex in cell A to the copy of the same vertex
  in cell B, the two cells sharing the facet.
* The unit normal ``n`` points from A to B. Which cell is A is fixed by geometry
  alone: ``n . e > 0`` for the fixed direction ``e = ORIENTATION`` (ties, i.e. normals
  orthogonal to e, are broken by a second fixed direction), so the table is the same
  whatever the mesh numbering or the number of ranks.
* The jump is ``g = u_B - u_A``; ``g_N = g . n`` (> 0 opening), ``g_T = g - g_N n``.
* The weight is the facet measure divided by its number of vertices (nodal, lumped
  quadrature): m per metre of depth in 2D, m^2 in 3D. A tensile traction t (Pa) on a
  link pulls B towards A with the force ``weight * t``, and A towards B.
* A link belongs to the star of its vertex, and is kept by the rank owning that
  vertex: every link is owned exactly once, and a rank holds whole stars.
"""
from dataclasses import dataclass

import numpy as np

from dolfrag import compat
from dolfrag.space import facet_measures, facet_normals

ORIENTATION = np.array([0.8, 0.5, 0.33166247903554])  # generic unit vector
TIE_BREAK = np.array([-0.5, 0.8, 0.33166247903554])


@dataclass
class Links:
    """Owned links of this rank (process-local dof and vertex indices).

    dof_A, dof_B (n,) int32: block dofs of the two copies.
    vertex (n,) int32: the mesh vertex (owned by this rank).
    normal (n, gdim): unit normal from A to B.
    tangents (n, gdim-1, gdim): orthonormal tangent basis.
    weight (n,): facet measure / vertices per facet (m in 2D, m^2 in 3D).
    facet (n,) int32: local facet index.
    """
    dof_A: np.ndarray
    dof_B: np.ndarray
    vertex: np.ndarray
    normal: np.ndarray
    tangents: np.ndarray
    weight: np.ndarray
    facet: np.ndarray

    def __len__(self):
        return len(self.weight)

    def frames(self):
        """(n, gdim, gdim): each link's frame, the normal then the tangents, as rows."""
        return np.concatenate([self.normal[:, None, :], self.tangents], axis=1)


def tangent_basis(n):
    """(n, d-1, d) orthonormal tangents completing the unit normals n (n, d)."""
    if n.shape[1] == 2:
        return np.stack([-n[:, 1], n[:, 0]], axis=1)[:, None, :]
    helper = np.where(np.abs(n[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return np.stack([t1, np.cross(n, t1)], axis=1)


def build(space):
    """Links of every interior facet vertex owned by this rank. Not collective."""
    msh = space.mesh
    tdim = msh.topology.dim
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    interior = np.flatnonzero(np.diff(f2c.offsets) == 2)
    cells = f2c.array[f2c.offsets[interior][:, None] + np.arange(2)]
    verts = compat.adjacency_array(msh.topology.connectivity(tdim - 1, 0), tdim)[interior]
    xv = space.vertex_x
    p = xv[verts]
    n = facet_normals(p)
    e = ORIENTATION[:space.gdim]
    along = n @ e
    along = np.where(np.abs(along) > 1e-12, along, n @ TIE_BREAK[:space.gdim])
    n *= np.sign(along)[:, None]
    centre = space.x[space.cell_dofs[cells[:, 0]]].mean(axis=1)
    first_is_B = np.einsum("ij,ij->i", centre - p.mean(axis=1), n) > 0
    cell_A = np.where(first_is_B, cells[:, 1], cells[:, 0])
    cell_B = np.where(first_is_B, cells[:, 0], cells[:, 1])

    def copy_in(cell, vertex):
        hit = space.cell_vertices[cell] == vertex[:, None]
        return space.cell_dofs[cell][hit]

    rows = []
    for j in range(tdim):  # facet corners: 2 in 2D, 3 in 3D
        v = verts[:, j]
        rows.append((copy_in(cell_A, v), copy_in(cell_B, v), v))
    dof_A, dof_B, vertex = (np.concatenate(c) for c in zip(*rows))
    facet = np.tile(interior, tdim)
    keep = vertex < space.n_owned_vertices
    normal = np.tile(n, (tdim, 1))[keep]
    weight = np.tile(facet_measures(p) / tdim, tdim)[keep]
    return Links(dof_A[keep].astype(np.int32), dof_B[keep].astype(np.int32),
                 vertex[keep].astype(np.int32), normal, tangent_basis(normal), weight,
                 facet[keep].astype(np.int32))
