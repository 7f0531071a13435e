"""Under mpirun: a theta run (solver/theta.py) of an RCCM bar that cracks; rank 0 saves the
energy history, the mean velocity of the free end and the Newton counts to argv[1] (.npz)."""
import sys

import numpy as np
from mpi4py import MPI

from conftest import ROOT
from dolfrag import loads, supports
from dolfrag.config import load_case
from dolfrag.runner import setup
from dolfrag.solver.theta import Theta

H_FACTOR = 4.0  # theta's step, in units of the imex step runner.setup chooses
STEPS = int(sys.argv[2]) if len(sys.argv) > 2 else 40

comm = MPI.COMM_WORLD
case = load_case(ROOT / "tests" / "cases" / "rccm-bar.toml", ["mesh.size=0.008"])
domain, space, links, imex, _, _ = setup(case, comm)
load = loads.unit_pressure_vector(space, domain, case.load.boundary)
fixed = supports.constrained_components(space, domain, case.supports)
integ = Theta(space, imex.bulk, imex.jump, imex.model, load, imex.pressure, H_FACTOR * imex.h, 0.5, fixed)
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
