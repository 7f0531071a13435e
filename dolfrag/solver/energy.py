"""The energy balance of both integrators: the Energies they report, their global sum, and
the split of the contact reactions' work into what contact and friction dissipate and what
the cohesion of a rigid link stores."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI


@dataclass
class Energies:
    """Global energies (J, or J/m in 2D) at the integrator's energy_time, and the broken-link count."""
    kinetic: float
    bulk: float
    interface: float
    damage: float
    contact: float
    external_work: float
    broken_links: int
    numerical: float = 0.0  # dissipated by the time scheme itself (theta > 1/2; 0 for imex)
    rebar: float = 0.0  # elastic energy of the bars
    plastic: float = 0.0  # dissipated by the bars' yielding
    viscous: float = 0.0  # dissipated by the artificial bulk viscosity (viscosity.py)

    @property
    def balance_error(self):
        return (self.kinetic + self.bulk + self.interface + self.damage + self.contact + self.numerical
                + self.rebar + self.plastic + self.viscous - self.external_work)


def global_energies(comm, kinetic, bulk, interface, damage, contact, external_work, broken_links, numerical=0.0,
                    rebar=0.0, plastic=0.0, viscous=0.0):
    """Energies summed over the ranks from this rank's shares (J; broken_links a count).
    Collective: one reduction."""
    total = comm.allreduce(np.array([kinetic, bulk, interface, damage, contact, external_work, broken_links,
                                     numerical, rebar, plastic, viscous]), op=MPI.SUM)
    return Energies(*total[:6], int(total[6]), numerical=total[7], rebar=total[8], plastic=total[9],
                    viscous=total[10])


def reaction_work(r_N, r_T, dg, shift, mu, cohesion_T):
    """The work of a step's contact reactions on each link, split (J/m^2 per link):
    (dissipated, stored). r_N (n,) Pa the normal reaction (>= -shift), r_T (n, d-1) Pa the
    tangential one, dg (n, d) m the link-frame jump increment of the step; shift (n,) Pa the
    cohesive tension the constraint carries, mu (n,) the friction coefficient, cohesion_T
    (n,) Pa the shear cohesion (interface/contact.py). The contact part r_N + shift and the
    friction share mu (r_N + shift) / (mu (r_N + shift) + cohesion_T) of the slip work are
    dissipated; the cohesive rest, -(-shift dg_N + (1 - friction share) r_T.dg_T), is the
    work done on a rigid link, which it stores (model.absorb)."""
    pressed = np.maximum(r_N + shift, 0.0)
    radius = mu * pressed + cohesion_T
    friction_share = np.divide(mu * pressed, radius, out=np.ones_like(radius), where=radius > 0)
    slip_work = np.sum(r_T * dg[:, 1:], axis=1)
    dissipated = -((r_N + shift) * dg[:, 0] + friction_share * slip_work)
    stored = -(-shift * dg[:, 0] + (1 - friction_share) * slip_work)
    return dissipated, stored
