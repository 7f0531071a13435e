"""The discontinuous vector P1 space and its topology maps (every facet duplicated).

A *dof* here is a block dof of the DG space: the copy of one mesh vertex owned by one
cell, carrying ``gdim`` displacement components. Arrays of dof values are flat,
component-fastest, ``u[gdim * dof + k]``, exactly as in ``Function.x.array``.
All indices are process-local; ghost dofs follow owned ones.
"""
import math
from dataclasses import dataclass

import numpy as np

from dolfrag import compat


@dataclass
class Space:
    """DG-P1 vector space with the maps the interface code needs.

    V: the dolfinx space.   gdim: geometric dimension.
    cell_vertices (n_cells, gdim+1): local vertex of each cell corner (owned + ghost cells).
    cell_dofs (n_cells, gdim+1): block dof of each cell corner (column i = vertex i).
    dof_vertex (n_dofs,): the mesh vertex a dof is a copy of.
    x (n_dofs, gdim): coordinates of each dof (its vertex), m.
    n_owned_dofs: block dofs owned by this rank (the first ones).
    n_owned_vertices: mesh vertices owned by this rank (the first ones).
    """
    V: object
    gdim: int
    cell_vertices: np.ndarray
    cell_dofs: np.ndarray
    dof_vertex: np.ndarray
    x: np.ndarray
    n_owned_dofs: int
    n_owned_vertices: int

    @property
    def mesh(self):
        return self.V.mesh

    @property
    def n_owned_cells(self):
        return self.mesh.topology.index_map(self.mesh.topology.dim).size_local

    def components(self, dofs):
        """Flat indices of all components of ``dofs``: shape (..., k) -> (..., k * gdim)."""
        dofs = np.asarray(dofs)
        # explicit last axis: -1 cannot be inferred for an empty array (a rank without any)
        flat = self.gdim * dofs[..., None] + np.arange(self.gdim)
        return flat.reshape(*dofs.shape[:-1], dofs.shape[-1] * self.gdim)

    @property
    def vertex_x(self):
        """(n_vertices, gdim) coordinates of the local mesh vertices, m."""
        xv = np.empty((self.dof_vertex.max(initial=-1) + 1, self.gdim))
        xv[self.dof_vertex] = self.x
        return xv

    def boundary_facets(self, facet_tags, tag):
        """Cell (n,) and vertices (n, gdim) of each local boundary facet marked ``tag``."""
        fdim = self.mesh.topology.dim - 1
        facets = facet_tags.indices[facet_tags.values == tag]
        f2c = self.mesh.topology.connectivity(fdim, fdim + 1)
        cells = f2c.array[f2c.offsets[facets]]
        verts = compat.adjacency_array(self.mesh.topology.connectivity(fdim, 0), fdim + 1)
        return cells, verts[facets]

    def boundary_dofs(self, facet_tags, tag):
        """Dofs on the boundary facets marked ``tag`` (local, owned and ghost), sorted."""
        cells, verts = self.boundary_facets(facet_tags, tag)
        on_facet = (self.cell_vertices[cells][:, :, None] == verts[:, None, :]).any(axis=2)
        return np.unique(self.cell_dofs[cells][on_facet])

    def boundary_normals(self, facet_tags, tag):
        """(n, gdim) outward unit normals of the local boundary facets marked ``tag``."""
        cells, verts = self.boundary_facets(facet_tags, tag)
        xv = self.vertex_x
        n = facet_normals(xv[verts])
        outward = np.einsum("ij,ij->i", n, xv[verts].mean(axis=1) - self.x[self.cell_dofs[cells]].mean(axis=1))
        return n * np.sign(outward)[:, None]


def facet_normals(p):
    """Unit normals of facets with corner coordinates p (n, gdim, gdim); orientation arbitrary."""
    if p.shape[2] == 2:
        t = p[:, 1] - p[:, 0]
        n = np.column_stack([t[:, 1], -t[:, 0]])
    else:
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.linalg.norm(n, axis=1)[:, None]


def facet_measures(p):
    """Length (2D) or area (3D) of facets with corner coordinates p (n, gdim, gdim), m or m^2."""
    if p.shape[2] == 2:
        return np.linalg.norm(p[:, 1] - p[:, 0], axis=1)
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def cell_measures(x):
    """Area (2D) or volume (3D) of simplices with corner coordinates x (n, gdim + 1, gdim),
    m^2 or m^3."""
    d = x.shape[2]
    return np.abs(np.linalg.det(x[:, 1:] - x[:, :1])) / math.factorial(d)


def create(domain):
    """The DG-P1 vector space on ``domain.mesh`` with its maps. Not collective."""
    msh = domain.mesh
    tdim = msh.topology.dim
    V = compat.dg1_vector_space(msh)
    cell_vertices = compat.adjacency_array(msh.topology.connectivity(tdim, 0), tdim + 1)
    cell_dofs = compat.cell_dofs(V)
    imap = V.dofmap.index_map
    n_dofs = imap.size_local + imap.num_ghosts
    dof_vertex = np.empty(n_dofs, dtype=np.int32)
    dof_vertex[cell_dofs.ravel()] = cell_vertices.ravel()
    nodes = compat.geometry_nodes(msh)
    x = np.empty((n_dofs, msh.geometry.dim))
    x[cell_dofs.ravel()] = msh.geometry.x[nodes.ravel(), :msh.geometry.dim]
    return Space(V, msh.geometry.dim, cell_vertices, cell_dofs, dof_vertex, x,
                 imap.size_local, msh.topology.index_map(0).size_local)
