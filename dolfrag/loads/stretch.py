"""The uniform stretch of an expanding bar (case.Load kind "stretch", docs/method.md "Expanding bar").

The body starts unstressed, moving with v_x = eps_dot (x - x_mid), v_y = 0, and the x
velocity of the boundaries ``left`` and ``right`` is held at -/+ eps_dot L / 2 from t = 0
(L, x_mid: the x extent of the body and its middle). In 1D that motion is a uniform strain
rate: no wave starts at the ends, the stress grows as E eps_dot t everywhere.

Central differences carry v at half steps, so the velocity set before the first step is
v_{-1/2}; the discrete energy then starts at E_{-1/2} = 1/2 v_{-1/2}.M v_{-1/2} (u_0 = 0).
The held components are supports of the star solve (solver/imex.py ``Imex.impose``). Their
reactions R (N, at t_n) do the work h R.(v_{n-1/2} + v_{n+1/2}) / 2 = h R.V in step n (the
same discrete work as a pressure's; V the held velocity, the same at every half step), so
that E_{n+1/2} - E_{-1/2} = W_{n+1/2} closes to the solver's tolerance.
"""
import numpy as np
from mpi4py import MPI

from dolfrag.case import STRETCHED, CaseError


def end_components(space, domain):
    """Flat local x components (owned and ghost) of every copy of every vertex on the
    STRETCHED boundaries (also the copies in cells that touch a boundary at a vertex only):
    a list of arrays, one per boundary. Raises CaseError if the mesh lacks one."""
    comps = []
    for name in STRETCHED:
        if name not in domain.boundaries:
            raise CaseError(f"load.kind = 'stretch': the mesh has no boundary {name!r} (a stretch "
                            f"holds the x velocity of {' and '.join(map(repr, STRETCHED))}); boundaries: "
                            f"{', '.join(sorted(domain.boundaries)) or 'none'}")
        _, vertices = space.boundary_facets(domain.facet_tags, domain.boundaries[name])
        comps.append(space.gdim * np.flatnonzero(np.isin(space.dof_vertex, vertices)))
    return comps


class Stretch:
    """The stretch of one run: start it on an Imex (``start``), then ``book`` every step.

    rate: eps_dot (1/s). length, x_mid (m): the body's x extent and middle (global).
    comps: flat local x components of the ends that this rank's stars solve; velocity:
    their held velocity (m/s), same shape. initial_energy: E_{-1/2} (J, J/m in 2D, global).
    """

    STATE = ("_work",)  # what a checkpoint keeps

    def __init__(self, space, domain, rate):
        comm = space.mesh.comm
        x = space.x[:space.n_owned_dofs, 0]
        lo = comm.allreduce(x.min(initial=np.inf), op=MPI.MIN)
        hi = comm.allreduce(x.max(initial=-np.inf), op=MPI.MAX)
        self.rate, self.length, self.x_mid = rate, hi - lo, 0.5 * (lo + hi)
        self.held = np.concatenate(end_components(space, domain))
        self._space = space
        self.comps = self.velocity = None
        self.initial_energy = 0.0
        self._work = 0.0  # J, this rank's stars

    def start(self, integ, star_comps):
        """Set v_{-1/2} on every local dof and hold the ends (only the components of this
        rank's stars ``star_comps``: the others are solved, and sent, by their star's rank).
        Collective."""
        space = self._space
        d = space.gdim
        v = integ.v.x.array
        v[:] = 0.0
        v[0::d] = self.rate * (space.x[:, 0] - self.x_mid)
        self.comps = np.intersect1d(self.held, star_comps)
        self.velocity = v[self.comps].copy()
        integ.impose(self.comps, lambda t: self.velocity)
        own = slice(0, space.n_owned_dofs * d)
        self.initial_energy = space.mesh.comm.allreduce(0.5 * integ.m[own] @ v[own] ** 2)

    def book(self, integ):
        """Add the work of the ends' reactions in the step just taken (after integ.step)."""
        self._work += integ.h * integ.interface.reaction[self.comps] @ self.velocity

    def supplied(self, comm):
        """E_{-1/2} plus the ends' work so far (J, J/m in 2D), global. Collective."""
        return self.initial_energy + comm.allreduce(self._work)
