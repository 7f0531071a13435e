"""Every call that depends on the DOLFINx version lives here (written for DOLFINx 0.5.2).

Newer DOLFINx renames much of this (``fem.functionspace``, ``u.x.petsc_vec``,
``plot.vtk_mesh``, 2D ``dofmap.list``, ``la.InsertMode``): a move to a newer
release should only need this module changed.
"""
import numpy as np
import ufl
import dolfinx
import dolfinx.cpp
import dolfinx.fem.petsc
import dolfinx.geometry
from dolfinx.io import gmshio

GhostMode = dolfinx.mesh.GhostMode


def default_cell_owners(comm, nparts, tdim, cells):
    """Owner rank of each local input cell, from DOLFINx's default graph partitioner.

    ``cells`` is the AdjacencyList_int64 handed to a partitioner. Collective.
    """
    partition = dolfinx.cpp.mesh.create_cell_partitioner()
    dest = partition(comm, nparts, tdim, cells, GhostMode.none)
    return dest.array[dest.offsets[:-1]]  # one owner per cell; an empty list may carry a stray entry


def serial_cell_owners(c2v, nparts):
    """Owner part of each cell (n_cells,) of the whole mesh c2v (n_cells, tdim + 1), split
    into nparts by DOLFINx's default graph partitioner on this process alone (nparts need
    not be the number of ranks). Not collective."""
    from mpi4py import MPI
    cells = dolfinx.cpp.graph.AdjacencyList_int64(np.ascontiguousarray(c2v, dtype=np.int64))
    return default_cell_owners(MPI.COMM_SELF, nparts, c2v.shape[1] - 1, cells)


def ghost_owners(index_map):
    """(num_ghosts,) owner rank of each ghost of an IndexMap."""
    return index_map.owners


def global_indices(index_map, local):
    """Global numbers of the ``local`` (owned or ghost) indices of ``index_map``."""
    return index_map.local_to_global(np.asarray(local, dtype=np.int32))


def adjacency_int32(data, offsets):
    return dolfinx.cpp.graph.AdjacencyList_int32(np.asarray(data, np.int32),
                                                 np.asarray(offsets, np.int32))


def adjacency_array(adj, width):
    """An AdjacencyList with constant row width as a 2D array (0.5.2 returns AdjacencyList)."""
    return adj.array.reshape(-1, width)


def gmsh_nodes(model):
    """(n, 3) coordinates (m) of the gmsh model's nodes, in the order the mesh input uses
    (row i = node tag i + 1): the points mesh_from_gmsh hands to the partitioner's cells."""
    return gmshio.extract_geometry(model)


def mesh_from_gmsh(comm, model, gdim, partitioner):
    """Distributed mesh plus cell and facet tags from a gmsh model held on rank 0.

    The steps of ``gmshio.model_to_mesh``, which in 0.5.2 takes no partitioner.
    Collective.
    """
    if comm.rank == 0:
        x = gmshio.extract_geometry(model)
        topologies = gmshio.extract_topology_and_markers(model)
        dims = {t: model.mesh.getElementProperties(t)[1] for t in topologies}
        cell_type = max(dims, key=dims.get)
        facet_types = [t for t in topologies if dims[t] == dims[cell_type] - 1]
        num_nodes = model.mesh.getElementProperties(cell_type)[3]
        cells = np.asarray(topologies[cell_type]["topology"], np.int64)
        cell_values = np.asarray(topologies[cell_type]["cell_data"], np.int32)
        if facet_types:
            num_facet_nodes = model.mesh.getElementProperties(facet_types[0])[3]
            facets = np.asarray(topologies[facet_types[0]]["topology"], np.int64)
            facet_values = np.asarray(topologies[facet_types[0]]["cell_data"], np.int32)
        else:
            num_facet_nodes = num_nodes - 1
            facets = np.empty((0, num_facet_nodes), np.int64)
            facet_values = np.empty(0, np.int32)
        header = (cell_type, num_nodes, num_facet_nodes)
    else:
        header = None
    cell_type, num_nodes, num_facet_nodes = comm.bcast(header, root=0)
    if comm.rank != 0:
        x = np.empty((0, gdim))
        cells = np.empty((0, num_nodes), np.int64)
        cell_values = np.empty(0, np.int32)
        facets = np.empty((0, num_facet_nodes), np.int64)
        facet_values = np.empty(0, np.int32)

    domain = gmshio.ufl_mesh(cell_type, gdim)
    cpp_cell = dolfinx.cpp.mesh.to_type(str(domain.ufl_cell()))
    cells = cells[:, gmshio.cell_perm_array(cpp_cell, num_nodes)]
    msh = dolfinx.mesh.create_mesh(comm, cells, x[:, :gdim], domain,
                                   ghost_mode=GhostMode.shared_facet, partitioner=partitioner)
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    entities, values = dolfinx.cpp.io.distribute_entity_data(msh._mesh, tdim, cells, cell_values)
    cell_tags = dolfinx.mesh.meshtags_from_entities(
        msh, tdim, dolfinx.cpp.graph.AdjacencyList_int32(entities), values.astype(np.int32))

    facet_type = dolfinx.cpp.mesh.cell_entity_type(cpp_cell, tdim - 1, 0)
    facets = facets[:, gmshio.cell_perm_array(facet_type, num_facet_nodes)]
    entities, values = dolfinx.cpp.io.distribute_entity_data(msh._mesh, tdim - 1, facets, facet_values)
    msh.topology.create_connectivity(tdim - 1, tdim)
    facet_tags = dolfinx.mesh.meshtags_from_entities(
        msh, tdim - 1, dolfinx.cpp.graph.AdjacencyList_int32(entities), values.astype(np.int32))
    return msh, cell_tags, facet_tags


def dg1_vector_space(msh):
    """Discontinuous vector P1: every cell owns its vertex copies (all facets duplicated)."""
    return dolfinx.fem.VectorFunctionSpace(msh, ("DG", 1))


Function = dolfinx.fem.Function


def dg1_scalar_space(msh):
    return dolfinx.fem.FunctionSpace(msh, ("DG", 1))


def dg0_space(msh):
    return dolfinx.fem.FunctionSpace(msh, ("DG", 0))


def cell_dofs(V):
    """(n_local_cells, dofs per cell) block dofs; for P1, column i is the copy of the cell's vertex i."""
    cells = V.mesh.topology.index_map(V.mesh.topology.dim)
    return V.dofmap.list.array.reshape(cells.size_local + cells.num_ghosts, -1)


def geometry_nodes(msh):
    """(n_local_cells, n_vertices) geometry node of each cell vertex (P1 geometry)."""
    tdim = msh.topology.dim
    return msh.geometry.dofmap.array.reshape(-1, tdim + 1)


def vertex_quadrature():
    """Quadrature at the vertices: makes the P1 mass matrix exactly diagonal (lumped)."""
    return {"quadrature_rule": "vertex", "quadrature_degree": 1}


def assemble_matrix(a):
    A = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(a))
    A.assemble()
    return A


def assemble_vector(L, out):
    """Assemble the linear form L into the Function ``out``: owned entries summed, ghosts updated."""
    from petsc4py import PETSc
    vec = out.vector
    with vec.localForm() as loc:
        loc.set(0.0)
    dolfinx.fem.petsc.assemble_vector(vec, dolfinx.fem.form(L))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)


def scatter_forward(u):
    u.x.scatter_forward()


def scatter_reverse_add(u):
    u.x.scatter_reverse(dolfinx.la.ScatterMode.add)


def facet_measure(msh, facet_tags):
    return ufl.Measure("ds", domain=msh, subdomain_data=facet_tags)


def bounding_box_tree(msh, dim):
    """Bounding-box tree of the local (owned and ghost) entities of dimension dim."""
    return dolfinx.geometry.BoundingBoxTree(msh, dim)


def point_candidates(tree, points):
    """AdjacencyList of the entities whose boxes hold each point (n, 3)."""
    return dolfinx.geometry.compute_collisions(tree, points)
