"""Under mpirun: write this partition's link table and star sizes (gathered on rank 0)."""
import sys

import numpy as np
from mpi4py import MPI

from conftest import box, rectangle
from dolfrag import mesh, space as spaces
from dolfrag.interface import links as link_table

geometry = rectangle() if sys.argv[1] == "2d" else box()
size = float(sys.argv[2])
comm = MPI.COMM_WORLD
domain = mesh.build(geometry, size, comm)
space = spaces.create(domain)
links = link_table.build(space)
table = np.column_stack([space.x[links.dof_A], space.x[links.dof_B], links.normal, links.weight])
owned_star_copies = np.count_nonzero(space.dof_vertex < space.n_owned_vertices)
owned_vertices = space.n_owned_vertices
tables = comm.gather(table, root=0)
stars = comm.allreduce(owned_star_copies)
n_cells = space.mesh.topology.index_map(space.gdim).size_global
if comm.rank == 0:
    np.savez(sys.argv[3], table=np.concatenate(tables), star_copies=stars, n_cells=n_cells)
