"""The nonsmooth imex step (solver/semismooth.py): RCCM cohesion, exact unilateral
contact, energy bookkeeping, rank independence."""
import numpy as np
from mpi4py import MPI

from dolfrag.config import load_case
from dolfrag.runner import setup


def test_intact_rccm_never_interpenetrates_and_closes_the_energy_balance():
    # sigma_c = 1 GPa: nothing breaks; closing interfaces are rigid (exact contact)
    case = load_case("sound-bar", ["interface.law=rccm", "interface.sigma_c=1e9", "mesh.size=0.004"])
    _, _, _, integ, n_steps, _ = setup(case, MPI.COMM_SELF)
    worst_gap, largest_u = 0.0, 0.0
    for _ in range(n_steps - 1):
        integ.step()
        worst_gap = min(worst_gap, integ.jump.local(integ._g)[0].min())
        largest_u = max(largest_u, np.abs(integ.u.x.array).max())
    energies = integ.step(energies=True)
    # Newton stops at |phi| <= 1e-10 of the reaction scale, i.e. gaps of 1e-10 r / rho
    # ~ 1e-22 m here: 1e-12 of the displacement leaves a wide margin and no penalty could
    # pass it (a penalty C_N = 10 E / h would let ~1e-3 of the displacement through).
    assert worst_gap >= -1e-12 * largest_u
    # Contact at the end of the step is an inelastic impact (restitution 0): it dissipates,
    # and with that dissipation counted the discrete balance is exact to round-off.
    assert energies.contact > 1e-3 * energies.external_work
    assert abs(energies.balance_error) < 1e-10 * energies.external_work
    assert energies.broken_links == 0 and energies.damage == 0
