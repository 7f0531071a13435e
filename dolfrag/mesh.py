"""Meshes: gmsh builders (2D rectangle, 3D box, the bunker of bunker.py), import of .geo/.msh,
and distribution.

Every builder names its boundaries (``left``/``right`` at x = 0 / x = length,
``bottom``/``top`` at y = 0 / y = width, ``front``/``back`` at z = 0 / z = thickness)
and tags every cell with the material group ``concrete``. An imported file names
its own boundaries and materials through physical groups. Lengths in metres.

The mesh is distributed so that each rank holds every cell around the vertices it
owns (whole vertex stars, docs/method.md "Parallel layout"): the interface step of a vertex is
then solved by the vertex's owner with no communication. The owner of each cell comes
from DOLFINx's graph partitioner, or, for tests that need to know where the partition
boundary runs, from a geometric ``owner_rule`` given to ``build``.
"""
import functools
import math
from dataclasses import dataclass
from pathlib import Path

import gmsh
import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from dolfrag import bunker, compat, guards
from dolfrag.case import CaseError

BOX_FACES = ("left", "right", "bottom", "top", "front", "back")


@dataclass
class Domain:
    """A distributed mesh with named boundaries and material groups.

    boundaries: name -> facet tag value; materials: name -> cell tag value.
    """
    mesh: object
    cell_tags: object
    facet_tags: object
    boundaries: dict
    materials: dict
    size: float

    @property
    def tdim(self):
        return self.mesh.topology.dim

    def boundary_tag(self, name):
        if name not in self.boundaries:
            raise CaseError(f"boundary {name!r} is not in the mesh; boundaries: "
                            f"{', '.join(sorted(self.boundaries)) or 'none'}")
        return self.boundaries[name]


def star_partitioner(comm, nparts, tdim, cells, ghost_mode, owners=compat.default_cell_owners):
    """Cell destinations: the owner first (``owners(comm, nparts, tdim, cells)``, by default
    DOLFINx's graph partitioner), then every rank owning a cell that shares a vertex with
    it. Each rank then holds the whole star of every vertex of its own cells (DOLFINx 0.5.2
    refuses ``GhostMode.shared_vertex``). Collective."""
    owner = owners(comm, nparts, tdim, cells)
    c2v = compat.adjacency_array(cells, tdim + 1)
    n_cells = len(c2v)
    pairs = np.unique(np.column_stack([c2v.ravel(), np.repeat(owner, tdim + 1)]), axis=0)
    pairs = np.concatenate(comm.allgather(pairs)) if comm.size > 1 else pairs
    n_vertices = int(max(pairs[:, 0].max(initial=-1), c2v.max(initial=-1))) + 1
    vertex_ranks = sp.csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                                 shape=(n_vertices, nparts))
    cell_vertices = sp.csr_matrix((np.ones(c2v.size), (np.repeat(np.arange(n_cells), tdim + 1),
                                                       c2v.ravel())), shape=(n_cells, n_vertices))
    cell_ranks = (cell_vertices @ vertex_ranks).tocsr()
    rows = np.repeat(np.arange(n_cells), np.diff(cell_ranks.indptr))
    ranks = cell_ranks.indices
    key = np.where(ranks == owner[rows], -1, ranks)
    order = np.lexsort((key, rows))
    return compat.adjacency_int32(ranks[order], cell_ranks.indptr)


def _start_gmsh():
    gmsh.initialize(["-noenv"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    return gmsh


def _name_boundaries(gmsh, tdim, extent):
    """Physical groups for the box faces (or rectangle edges) by their centre of mass."""
    tol = 1e-9 * max(extent)
    faces = {}
    for _, tag in gmsh.model.getEntities(tdim - 1):
        c = gmsh.model.occ.getCenterOfMass(tdim - 1, tag)
        for axis in range(tdim):
            for side, where in enumerate((0.0, extent[axis])):
                if abs(c[axis] - where) < tol:
                    faces.setdefault(BOX_FACES[2 * axis + side], []).append(tag)
    for value, name in enumerate(BOX_FACES[:2 * tdim], start=1):
        gmsh.model.setPhysicalName(tdim - 1, gmsh.model.addPhysicalGroup(tdim - 1, faces[name], value), name)


def _build_box(gmsh, geometry, size, optimize_threshold=None):
    tdim = geometry.tdim
    if tdim == 2:
        extent = (geometry.length, geometry.width)
        gmsh.model.occ.addRectangle(0, 0, 0, *extent)
    else:
        extent = (geometry.length, geometry.width, geometry.thickness)
        gmsh.model.occ.addBox(0, 0, 0, *extent)
    gmsh.model.occ.synchronize()
    body = [tag for _, tag in gmsh.model.getEntities(tdim)]
    gmsh.model.setPhysicalName(tdim, gmsh.model.addPhysicalGroup(tdim, body, 1), "concrete")
    _name_boundaries(gmsh, tdim, extent)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMin", size)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMax", size)
    if tdim == 2 and geometry.structured:
        for _, curve in gmsh.model.getEntities(1):
            length = gmsh.model.occ.getMass(1, curve)
            gmsh.model.mesh.setTransfiniteCurve(curve, max(1, round(length / size)) + 1)
        for surface in body:
            gmsh.model.mesh.setTransfiniteSurface(surface, "Alternate")
    if optimize_threshold is not None:
        gmsh.option.setNumber("Mesh.OptimizeThreshold", optimize_threshold)
    gmsh.model.mesh.generate(tdim)
    return tdim


def _read_file(gmsh, path, tdim, size, max_cells, optimize_threshold=None):
    """Read a .geo (meshed here, at most ``size`` m, if its bounding box holds at most about
    ``max_cells`` cells) or a .msh (at most ``max_cells`` cells)."""
    if not path.exists():
        raise CaseError(f"geometry.file = {str(path)!r}: file not found")
    try:
        gmsh.open(str(path))
    except Exception as err:
        raise CaseError(f"geometry.file = {str(path)!r}: gmsh cannot read it ({err})") from None
    if path.suffix == ".geo":
        box = gmsh.model.getBoundingBox(-1, -1)
        cells = guards.cells_in([box[3 + k] - box[k] for k in range(tdim)], size)
        if cells > max_cells:
            raise CaseError(f"mesh.size = {size!r}: about {cells:.3g} cells in the bounding box of geometry.file, "
                            f"above run.max_cells = {max_cells:g}; raise mesh.size or run.max_cells")
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", size)
        if optimize_threshold is not None:
            gmsh.option.setNumber("Mesh.OptimizeThreshold", optimize_threshold)
        gmsh.model.mesh.generate(tdim)
    else:
        cells = sum(len(tags) for tags in gmsh.model.mesh.getElements(tdim)[1])
        if cells > max_cells:
            raise CaseError(f"geometry.file = {str(path)!r}: {cells} cells, above run.max_cells = {max_cells:g}; "
                            "raise run.max_cells")
    if not gmsh.model.getPhysicalGroups(tdim):
        raise CaseError(f"geometry.file = {str(path)!r}: no physical group of dimension {tdim} "
                        "(the material groups); add one per material")
    return tdim


def _physical_names(gmsh, dim):
    return {gmsh.model.getPhysicalName(dim, tag) or f"group{tag}": tag
            for _, tag in gmsh.model.getPhysicalGroups(dim)}


def _geometric_owners(owner_rule, x, gdim):
    """The ``owners`` of star_partitioner from ``owner_rule(centroids (n, gdim) m) -> (n,)
    int ranks``, the input nodes' coordinates x (m) being on this rank (all of them on rank
    0, where gmsh meshed; none elsewhere, where there are no input cells either)."""
    def owners(comm, nparts, tdim, cells):
        centroids = x[compat.adjacency_array(cells, tdim + 1)].mean(axis=1)[:, :gdim]
        rank = np.asarray(owner_rule(centroids), dtype=np.int32).reshape(len(centroids))
        if np.any((rank < 0) | (rank >= nparts)):
            raise ValueError(f"owner_rule gave ranks outside [0, {nparts})")
        return rank
    return owners


def build(geometry, size, comm=MPI.COMM_WORLD, owner_rule=None, max_cells=math.inf, optimize_threshold=None):
    """Mesh ``geometry`` (a case.Geometry) with element size ``size`` (m) and distribute it.

    owner_rule: None (DOLFINx's graph partitioner decides which rank owns each cell), or a
    function of the cell centroids (n, gdim) (m) returning each cell's owner rank (n,): a
    partition boundary where a test wants it (e.g. ``lambda c: c[:, 0] > L / 2`` on 2
    ranks); the stars around it are still completed by star_partitioner. max_cells: the
    limit on an imported file's cells (guards.py checks a rectangle or box before this).
    optimize_threshold: gmsh's Mesh.OptimizeThreshold for a meshed 3D geometry (None: the
    builder's own). gmsh runs on rank 0 only; collective.
    """
    header, error = None, None
    if comm.rank == 0:
        _start_gmsh()
        try:
            gmsh.model.add("dolfrag")
            if geometry.kind == "file":
                tdim = _read_file(gmsh, Path(geometry.file), geometry.tdim, size, max_cells, optimize_threshold)
            elif geometry.kind == "bunker":
                tdim = bunker.build(gmsh, geometry, size, optimize_threshold)
            else:
                tdim = _build_box(gmsh, geometry, size, optimize_threshold)
            header = (tdim, _physical_names(gmsh, tdim - 1), _physical_names(gmsh, tdim))
        except CaseError as err:
            error = str(err)
            gmsh.finalize()
    header, error = comm.bcast((header, error), root=0)
    if error:
        raise CaseError(error)
    tdim, boundaries, materials = header
    partitioner = star_partitioner
    if owner_rule is not None:
        x = compat.gmsh_nodes(gmsh.model) if comm.rank == 0 else np.empty((0, 3))
        partitioner = functools.partial(star_partitioner, owners=_geometric_owners(owner_rule, x, tdim))
    try:
        msh, cell_tags, facet_tags = compat.mesh_from_gmsh(comm, gmsh.model, tdim, partitioner)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    cells = msh.topology.index_map(tdim)
    if comm.allreduce(cells.size_local, op=MPI.MIN) == 0:
        raise CaseError(f"mesh.size = {size!r}: {cells.size_global} cells, too few for {comm.size} ranks "
                        "(every rank must own a cell); run on fewer ranks or lower mesh.size")
    for dim in (tdim - 1, 0):
        msh.topology.create_connectivity(dim, tdim)
        msh.topology.create_connectivity(tdim, dim)
    msh.topology.create_connectivity(tdim - 1, 0)
    return Domain(msh, cell_tags, facet_tags, boundaries, materials, size)
