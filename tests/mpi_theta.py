"""Under mpirun: a theta run (solver/theta.py) of an RCCM bar that cracks; rank 0 saves the
energy history, the mean velocity of the free end and the Newton counts to argv[1] (.npz)."""
import sys

import numpy as np
from mpi4py import MPI

from conftest import ROOT
from dolfrag import loads
from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.solver.theta import Theta

H_FACTOR = 4.0  # theta's step, in units of the imex step Problem.build chooses
STEPS = int(sys.argv[2]) if len(sys.argv) > 2 else 40

comm = MPI.COMM_WORLD
case = load_case(ROOT / "tests" / "cases" / "rccm-bar.toml", ["mesh.size=0.008"])
problem = Problem.build(case, comm)
domain, space = problem.domain, problem.space
load = loads.unit_pressure_vector(space, domain, case.load.boundary)
integ = Theta.from_problem(problem, h=H_FACTOR * problem.h, theta=0.5, load=load)
right = space.boundary_dofs(domain.facet_tags, domain.boundary_tag("right"))
right = space.gdim * right[right < space.n_owned_dofs]
names = ["kinetic", "bulk", "interface", "damage", "contact", "external_work", "numerical", "broken_links"]
rows = []
for _ in range(STEPS):
    e = integ.step(energies=True)
    v_sum, count = comm.allreduce(np.array([integ.v.x.array[right].sum(), len(right)]))
    rows.append([getattr(e, a) for a in names] + [e.balance_error, v_sum / count,
                                                  integ.interface.iterations, integ.interface.cuts])
if comm.rank == 0:
    np.savez(sys.argv[1], history=np.array(rows), names=names + ["balance_error", "v_right", "iterations", "cuts"])
