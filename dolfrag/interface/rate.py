"""Tensile strength at the strain rate of the bulk beside each link.

A link's strain rate is the rate of normal strain across its facet, n . eps_dot . n
(1/s), averaged over the two cells the facet joins. On DG-P1 cells the velocity gradient
is constant, eps_dot = sym(sum_a v_a (x) grad N_a), so the rate needs no quadrature and
does not depend on the mesh size the way an opening rate divided by h would. The link's
strength is then

    sigma_c(link) = sigma_c x DIF(rate)        (fib Model Code 2010, concrete.tensile_dif)

with sigma_c the static strength of [interface]. The model keeps the strength a link had
when it started to open (LinearSoftening.set_strength), so each crack dissipates G_c.

The rate uses the velocities v_{n-1/2} of the last half step, as the explicit bulk does.
"""
import numpy as np
from numba import njit

from dolfrag import concrete
from dolfrag.viscosity import shape_gradients

# A link's strength follows the rate in steps of this relative size. Each change makes the
# star's stored factors stale (the strength shifts its contact constraint), and changes at
# round-off level every step left some 3D stars to Newton with stale factors that stalled
# (measured on a reduced bunker: unconverged at step 3-15); 1 % is far below the scatter of
# the tests behind the fib factor.
STRENGTH_STEP = 0.01


class RateStrength:
    """Per-link strengths from the bulk strain rate, for the links of one rank.

    space: space.Space; links: interface/links.Links (this rank's); sigma_c: the static
    strength (Pa). ``rates(v)`` gives each link's normal strain rate (1/s) from the flat
    local velocities v (m/s, current on every local cell: ghosts included);
    ``update(v, model)`` passes sigma_c x DIF(rate) to the model (in steps of
    STRENGTH_STEP) and returns the links whose strength changed."""

    def __init__(self, space, links, sigma_c):
        dof_cell = np.empty(space.cell_dofs.max(initial=-1) + 1, dtype=np.int64)
        dof_cell[space.cell_dofs] = np.arange(len(space.cell_dofs))[:, None]
        cells, local = np.unique(np.concatenate([dof_cell[links.dof_A], dof_cell[links.dof_B]]),
                                 return_inverse=True)
        self.cell_A, self.cell_B = np.split(local.astype(np.int64), 2)
        dofs = space.cell_dofs[cells]
        self.grads = np.ascontiguousarray(shape_gradients(space.x[dofs])[0])
        self.comps = np.ascontiguousarray(space.components(dofs), dtype=np.int64)
        self.normal = np.ascontiguousarray(links.normal)
        self.sigma_c = float(sigma_c)
        self._rate = np.empty(len(links))
        self._gradient = np.empty((len(cells), self.grads.shape[2], self.grads.shape[2]))

    def rates(self, v):
        """n . eps_dot . n (1/s) of every link, the mean of its two cells'."""
        _normal_rates(self.cell_A, self.cell_B, self.normal, self.grads, self.comps, v, self._gradient, self._rate)
        return self._rate

    def update(self, v, model):
        """Give ``model`` (LinearSoftening) the strengths at the rates of the velocities v;
        the indices of the links whose strength changed."""
        return model.set_strength(self.sigma_c * concrete.tensile_dif(self.rates(v)), STRENGTH_STEP)


@njit(cache=True)
def _normal_rates(cell_A, cell_B, normal, grads, comps, v, gradient, out):
    """out[l] = (n . L_A . n + n . L_B . n) / 2, with L = sum_a v_a (x) grad N_a of a cell,
    formed once per cell into gradient (cells, d, d): a cell borders up to d + 1 links, and
    forming it per link cost twice as much (bunker-h2 at 0.2 m, 31,632 links: 1.06 against 0.54
    ms of CPU a call)."""
    k, d = grads.shape[1], grads.shape[2]
    for cell in range(len(grads)):
        for i in range(d):
            for j in range(d):
                s = 0.0
                for a in range(k):
                    s += v[comps[cell, a * d + i]] * grads[cell, a, j]
                gradient[cell, i, j] = s
    for link in range(len(out)):
        A, B = cell_A[link], cell_B[link]
        total = 0.0
        for i in range(d):
            for j in range(d):
                total += normal[link, i] * normal[link, j] * (gradient[A, i, j] + gradient[B, i, j])
        out[link] = 0.5 * total


def warm():
    """Compile the rates (2D and 3D) into numba's cache on one link of two cells."""
    for d in (2, 3):
        k = d + 1
        grads, comps = np.ones((2, k, d)), np.arange(2 * k * d).reshape(2, -1)
        _normal_rates(np.zeros(1, np.int64), np.ones(1, np.int64), np.ones((1, d)), grads, comps,
                      np.ones(2 * k * d), np.empty((2, d, d)), np.empty(1))
