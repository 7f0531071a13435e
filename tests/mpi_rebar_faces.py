"""Under mpirun: the bar polylines behind a mesh file's face groups (dolfrag/rebar/faces.py), saved by rank 0."""
import sys

import numpy as np
from mpi4py import MPI

from dolfrag import mesh, space as spaces
from dolfrag.rebar import faces as rebar_faces
from dolfrag.case import load_case

case = load_case(sys.argv[1], sys.argv[3:])
comm = MPI.COMM_WORLD
domain = mesh.build(case.geometry, case.mesh.size, comm)
lines, areas = rebar_faces.polylines(case.rebar, spaces.create(domain), domain, comm)
if comm.rank == 0:
    np.savez(sys.argv[2], lines=np.array(lines), areas=areas)
