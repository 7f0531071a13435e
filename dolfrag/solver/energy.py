"""The energy balance of both integrators: the Energies they report, their global sum, and
the split of the contact reactions' work into what contact and friction dissipate and what
the cohesion of a rigid link stores."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from numba import njit


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


@njit(cache=True, error_model="numpy")
def reaction_work(r_N, r_T, dg, shift, cohesion_T):
    """The work of a step's contact reactions on each link, split (J/m^2 per link):
    (dissipated, stored). r_N (n,) Pa the normal reaction (>= -shift), r_T (n, d-1) Pa the
    tangential one, dg (n, d) m the link-frame jump increment of the step; shift (n,) Pa the
    cohesive tension the constraint carries, cohesion_T (n,) Pa the shear cohesion
    (interface/contact.py). The cohesion's work, shift dg_N + cohesion_T |dg_T|, is the work
    done on a rigid link, which it stores (model.absorb): the shear cohesion resists slip
    as friction does, being the part of the cone's radius mu (r_N + shift) + cohesion_T
    that does not grow with the pressure. The rest of the reactions' work, their contact
    and friction part, is dissipated.

    The stored part is read from the motion, not from the reactions, because the reactions
    of a star of rigid links are not unique: a self-stress around the vertex does no work on
    the star but moves work from link to link (StarOptions.regularisation, solver/stars/options.py), and a
    step's work pairs its reactions with the jumps of two steps, so a link that slipped in
    the last step and sticks in this one books any reaction inside its cone. Measured on
    sound-bar with linear softening and friction (step 95, the star of vertex (0.1079,
    0.0061)): 1 and 2 ranks took the same motion with reactions differing by a self-stress,
    and the former rule, the cohesive share cohesion_T / radius of r_T.dg_T, stored 1.09e-7
    and 9.1e-9 J/m on the link that had slipped. Both rules agree on a link slipping on
    the cone against dg_T (tests/test_reaction_work.py).

    Compiled, one loop over the links: in numpy these were a dozen calls a step."""
    n = dg.shape[0]
    dissipated, stored = np.empty(n), np.empty(n)
    rigid = np.zeros(dg.shape[1])  # no joint (the theta step's links are rigid)
    for l in range(n):
        dissipated[l], stored[l] = _link_work(r_N[l], r_T[l], dg[l], rigid, shift[l], cohesion_T[l])
    return dissipated, stored


@njit(cache=True, error_model="numpy", inline="always")  # called per link: inlined, see rccm_kernel
def _link_work(r_N, r_T, dg, dg_el, shift, cohesion_T):
    """(dissipated, stored) of one link (J/m^2), as reaction_work: r_T (d-1,), dg (d,);
    dg_el (d,) m the part of dg that is a rigid link's elastic joint (solver/active_set.py's
    COMPLIANCE): its work is stored too, and the cohesion works on the rest, the law's."""
    slip, tangential, elastic = 0.0, 0.0, r_N * dg_el[0]
    for i in range(1, len(dg)):
        slip += (dg[i] - dg_el[i]) ** 2
        tangential += r_T[i - 1] * dg[i]
        elastic += r_T[i - 1] * dg_el[i]
    stored = shift * (dg[0] - dg_el[0]) + cohesion_T * np.sqrt(slip) - elastic
    return -(r_N * dg[0] + tangential) - stored, stored


@njit(cache=True, error_model="numpy")
def book_reaction_work(r, slip, slip_before, elastic, shift, cohesion_T, weight, links, absorbed):
    """The work of a step's contact reactions r (n, d) (Pa, link frame) over the jump
    increments of this step and the last, slip + slip_before (n, d) (m: h B v_{n+1/2} and
    h B v_{n-1/2}), taken as a midpoint: -r . (g_{n+1} - g_{n-1}) / 2 per link, split by
    reaction_work, with elastic (n, d) (m) the rigid links' joints' part of those increments
    (stored with the cohesion's work: _link_work). Writes absorbed[links] = the stored part
    (J/m^2), copies slip into slip_before for the next step, and returns the dissipated part
    summed with the links' weights (J, J/m in 2D)."""
    n, d = r.shape
    dg = np.empty(d)
    total = 0.0
    for l in range(n):
        for i in range(d):
            dg[i] = slip[l, i] + slip_before[l, i]
            slip_before[l, i] = slip[l, i]
        dissipated, stored = _link_work(r[l, 0], r[l, 1:], dg, elastic[l], shift[l], cohesion_T[l])
        total += 0.5 * weight[l] * dissipated
        absorbed[links[l]] = 0.5 * stored
    return total


def warm():
    """Compile reaction_work and book_reaction_work into numba's cache, for the reactions
    as the solvers pass them (columns of the (n, d) link-frame array), 2D and 3D."""
    for d in (2, 3):
        r, dg = np.zeros((1, d)), np.zeros((1, d))
        reaction_work(r[:, 0], r[:, 1:], dg, np.zeros(1), np.zeros(1))
        book_reaction_work(r, dg, dg.copy(), dg.copy(), np.zeros(1), np.zeros(1), np.ones(1), np.zeros(1, dtype=np.int64),
                           np.zeros(1))
