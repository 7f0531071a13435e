"""Under mpirun: DOLFINx's own ghost layer of a star-partitioned mesh against benchmarks/halo.py,
which counts it from the cell owners alone (on rank 0). Writes an .npz on rank 0."""
import sys

import numpy as np
from mpi4py import MPI

from conftest import ROOT, box, rectangle
from dolfrag import compat, mesh, space as spaces

sys.path.insert(0, str(ROOT / "benchmarks"))
import halo  # noqa: E402

geometry = rectangle() if sys.argv[1] == "2d" else box()
size = float(sys.argv[2])
comm = MPI.COMM_WORLD
recorded = {}
star_partitioner = mesh.star_partitioner


def recording_partitioner(comm, nparts, tdim, cells, ghost_mode):
    dest = star_partitioner(comm, nparts, tdim, cells, ghost_mode)
    recorded["c2v"] = compat.adjacency_array(cells, tdim + 1).copy()
    recorded["owner"] = dest.array[dest.offsets[:-1]].copy()
    return dest


mesh.star_partitioner = recording_partitioner
domain = mesh.build(geometry, size, comm)
space = spaces.create(domain)
msh, tdim = domain.mesh, domain.tdim
cells = msh.topology.index_map(tdim)
ghost_owners = np.bincount(compat.ghost_owners(cells), minlength=comm.size)  # ghost cells from each rank
# input (gmsh) index of each owned vertex: its geometry node's input index
c2v = compat.adjacency_array(msh.topology.connectivity(tdim, 0), tdim + 1)
node = np.empty(msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts, np.int64)
node[c2v.ravel()] = compat.geometry_nodes(msh).ravel()
owned_vertices = np.asarray(msh.geometry.input_global_indices)[node[:space.n_owned_vertices]]
local = comm.gather((cells.size_local, cells.num_ghosts, space.V.dofmap.index_map.num_ghosts,
                     ghost_owners, owned_vertices), root=0)
inputs = comm.gather(recorded, root=0)
if comm.rank == 0:
    c2v_in = np.concatenate([r["c2v"] for r in inputs if len(r["c2v"])])
    owner = np.concatenate([r["owner"] for r in inputs if len(r["c2v"])])
    counted = halo.star_halo(c2v_in, owner, comm.size)
    PV, _ = halo.vertex_parts(halo.cell_vertex_incidence(c2v_in), owner, comm.size)
    eligible = [bool(PV[rank].toarray().ravel()[r[4]].all()) for rank, r in enumerate(local)]
    pairs = np.array([r[3] for r in local])  # pairs[p, q]: ghost cells of p owned by q
    np.savez(sys.argv[3], owned=[r[0] for r in local], ghosts=[r[1] for r in local],
             dof_ghosts=[r[2] for r in local], neighbours=np.count_nonzero(pairs, axis=1), sent=pairs.sum(axis=0),
             vertex_owner_eligible=eligible, counted_owned=counted.owned, counted_ghosts=counted.ghosts,
             counted_neighbours=counted.neighbours, counted_sent=counted.sent, tdim=tdim)
