"""The uniform stretch of an expanding bar (case.Load kind "stretch", docs/method.md "Expanding bar").

The body starts unstressed, moving with v_x = eps_dot (x - x_mid), v_y = 0, and the x
velocity of the boundaries ``left`` and ``right`` is held at -/+ eps_dot L / 2 from t = 0
(L, x_mid: the x extent of the body and its middle). In 1D that motion is a uniform strain
rate: no wave starts at the ends, the stress grows as E eps_dot t everywhere.

Central differences carry v at half steps, so the velocity set before the first step is
v_{-1/2}. The held components are supports of the star solve (solver/imex.py ``Imex.impose``);
the integrator books their reactions' work and the starting energy E_{-1/2} = 1/2
v_{-1/2}.M v_{-1/2} with the external work (``Imex.impose``, ``Imex.set_velocity``), so that
E_{n+1/2} = W_{n+1/2} closes to the solver's tolerance.
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
    """The stretch of one run, started on an Imex by ``start``.

    rate: eps_dot (1/s). length, x_mid (m): the body's x extent and middle (global).
    held: flat local x components of both ends.
    """

    def __init__(self, space, domain, rate):
        comm = space.mesh.comm
        x = space.x[:space.n_owned_dofs, 0]
        lo = comm.allreduce(x.min(initial=np.inf), op=MPI.MIN)
        hi = comm.allreduce(x.max(initial=-np.inf), op=MPI.MAX)
        self.rate, self.length, self.x_mid = rate, hi - lo, 0.5 * (lo + hi)
        self.held = np.concatenate(end_components(space, domain))
        self._space = space

    def start(self, integ, star_comps):
        """Set v_{-1/2} on every local dof and hold the ends (only the components of this
        rank's stars ``star_comps``: the others are solved, and sent, by their star's rank)."""
        space = self._space
        d = space.gdim
        v = np.zeros_like(integ.v.x.array)
        v[0::d] = self.rate * (space.x[:, 0] - self.x_mid)
        integ.set_velocity(v)
        comps = np.intersect1d(self.held, star_comps)
        velocity = v[comps]
        integ.impose(comps, lambda t: velocity)
