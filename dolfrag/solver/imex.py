"""The `imex` step: explicit bulk, implicit interface (shared/DESIGN.md §4).

Central difference for the bulk with the lumped mass M, and the interface force
taken at the average ``(u_{n+1} + 2 u_n + u_{n-1}) / 4``. In velocity increments
``dv = v_{n+1/2} - v_{n-1/2}`` one step is

    (M + h^2/4 K_i) dv = h (f_ext(t_n) - K u_n - K_i u_n),     u_{n+1} = u_n + h v_{n+1/2},

whose matrix is block-diagonal over vertex stars (interface/stars.py). The step is
stable for h below the bulk limit alone, whatever the interface stiffness, and
conserves exactly the discrete energy

    E_{n+1/2} = 1/2 v_{n+1/2}.M v_{n+1/2} + 1/2 u_{n+1}.K u_n + 1/2 gbar.K_i gbar,
    gbar = (u_n + u_{n+1}) / 2,

against the work W_{n+1/2} = sum_k f_ext(t_k).(u_{k+1} - u_{k-1}) / 2. Those are the
energies this module reports, so the balance error measures the code, not the
time discretisation.

Parallel data flow per step: K u on owned rows, one forward ghost update of the
force, the star solves of owned vertices (no communication), one reverse update of
the velocity increments to their owners.
"""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from dolfrag import compat
from dolfrag.interface import laws


@dataclass
class Energies:
    """Global energies (J, or J/m in 2D) at t_{n+1/2}; collective to compute."""
    kinetic: float
    bulk: float
    interface: float
    external_work: float

    @property
    def balance_error(self):
        return self.kinetic + self.bulk + self.interface - self.external_work


class Imex:
    """Explicit-implicit integrator with linear interface springs C_N, C_T (Pa/m).

    space, bulk, jump, stars: from space.py, bulk.py, interface/. load: Function of
    nodal forces per pascal; pressure: p(t) in Pa. h: time step (s).
    """

    def __init__(self, space, bulk, jump, stars, C_N, C_T, load, pressure, h):
        self.space, self.bulk, self.jump, self.stars = space, bulk, jump, stars
        self.C_N, self.C_T = C_N, C_T
        self.pressure, self.h = pressure, h
        V = space.V
        self.u, self.v, self.f, self.dv = (compat.Function(V) for _ in range(4))
        self.u.name, self.v.name = "displacement", "velocity"
        self.owned = slice(0, space.n_owned_dofs * space.gdim)
        # updated here: owned components, plus the ghost ones of this rank's stars
        self.star_ghosts = stars.comps[stars.comps >= self.owned.stop]
        g = load.x.array[self.owned]
        self.loaded = np.flatnonzero(g)
        self.g_load = g[self.loaded]
        self.m = bulk.m.x.array
        self.t, self.n = 0.0, 0
        self.work = 0.0
        self._g = jump(self.u.x.array)
        stars.factorise(self.m, jump.tangent_blocks(C_N, C_T), h * h / 4)

    def step(self, energies=False):
        """Advance from t_n to t_{n+1}. With ``energies``, return the Energies at
        t_{n+1/2} (collective), else None."""
        h, u, v, f, dv = self.h, self.u.x.array, self.v.x.array, self.f.x.array, self.dv.x.array
        own = self.owned
        Ku = self.bulk.K_cells @ u[own]
        p = float(self.pressure(self.t))
        np.negative(Ku, out=f[own])
        f[own][self.loaded] += p * self.g_load
        compat.scatter_forward(self.f)

        g_N, g_T = self.jump.local(self._g)
        r_N, r_T, _, _ = laws.elastic(g_N, g_T, self.C_N, self.C_T)
        rhs = h * (f - self.jump.force(r_N, r_T))

        dv[:] = 0.0
        self.stars.solve(rhs, dv)
        mine = dv[self.stars.comps]
        compat.scatter_reverse_add(self.dv)
        dv[self.stars.comps] = mine

        v_old_loaded = v[own][self.loaded]
        v[own] += dv[own]
        u[own] += h * v[own]
        ghosts = self.star_ghosts
        v[ghosts] += dv[ghosts]
        u[ghosts] += h * v[ghosts]
        self.work += p * h * self.g_load @ (v[own][self.loaded] + v_old_loaded) / 2
        g_old, self._g = self._g, self.jump(u)
        self.t += h
        self.n += 1
        if energies:
            return self._energies(Ku, (g_old + self._g) / 2)
        return None

    def _energies(self, Ku, g_mid):
        own = self.owned
        v, u = self.v.x.array[own], self.u.x.array[own]
        g_N, g_T = self.jump.local(g_mid)
        local = np.array([0.5 * self.m[own] @ v**2, 0.5 * u @ Ku,
                          self.jump.links.weight @ laws.elastic_energy(g_N, g_T, self.C_N, self.C_T),
                          self.work])
        return Energies(*self.space.mesh.comm.allreduce(local, op=MPI.SUM))
