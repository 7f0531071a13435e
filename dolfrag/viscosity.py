"""Artificial bulk viscosity: a pressure that damps the ringing behind steep compressive
fronts, as explicit wave codes do (von Neumann & Richtmyer 1950, J. Appl. Phys. 21:232,
quadratic term; Landshoff 1955, Los Alamos LA-1930, linear term; LS-DYNA's
*CONTROL_BULK_VISCOSITY, whose defaults are used here).

In each cell, compressed at the volumetric strain rate div v < 0 (1/s),

    q = rho l (Q_1 l (div v)^2 - Q_2 c div v),       q = 0 when div v >= 0,

a pressure (Pa) added to the stress as -q I: rho (kg/m^3), c the cell's dilatational wave
speed sqrt((lambda + 2 mu) / rho) (m/s, plane-stress lambda in plane stress), l the cell's
size (m, area^(1/2) in 2D, volume^(1/3) in 3D), Q_1 quadratic, Q_2 linear (-). On DG-P1
cells div v is constant, and the nodal force of vertex a is q |cell| grad N_a (N, or N/m
in 2D): its power q |cell| div v <= 0 is always dissipation. The dissipated energy is
booked as the work of these forces, with the same rule as the external work of the time
step (solver/imex.py), so the energy balance stays exact.

The force uses the velocity of the last half step, v_{n-1/2}, like every explicit code; the
linear term then lowers the stable step by the factor sqrt(1 + Q_2^2) - Q_2 (0.94 at
Q_2 = 0.06), which ``step_factor`` gives and the run applies.
"""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from numba import njit

from dolfrag import bulk, compat
from dolfrag.space import cell_measures


@dataclass(frozen=True)
class ViscosityOptions:
    """The coefficients (-): LS-DYNA's defaults."""
    quadratic: float = 1.5  # Q_1
    linear: float = 0.06  # Q_2


def pressure(div_v, rho, length, c, options=ViscosityOptions()):
    """q (Pa) of cells compressed at div_v (1/s): rho (kg/m^3) l (m) (Q_1 l div_v^2 -
    Q_2 c div_v) where div_v < 0, else 0; c (m/s). Vectorised."""
    rate = np.minimum(div_v, 0.0)
    return rho * length * (options.quadratic * length * rate**2 - options.linear * c * rate)


def step_factor(options=ViscosityOptions()):
    """Factor (-) on the stable step of the bulk alone: sqrt(1 + Q_2^2) - Q_2, the bound
    2 (sqrt(1 + xi^2) - xi) / omega of central differences with a damping ratio xi = Q_2 at
    the highest frequency (the quadratic term's share, Q_1 l |div v| / c, is left out: it is
    ~1e-3 at the strain rates of a concrete specimen)."""
    return float(np.sqrt(1 + options.linear**2) - options.linear)


def shape_gradients(x):
    """grad N_a (n, d + 1, d) (1/m) and measure (n,) (m^2 or m^3) of P1 simplices with
    vertex coordinates x (n, d + 1, d), m."""
    edges = x[:, 1:] - x[:, :1]  # (n, d, d): rows x_a - x_0
    inv = np.linalg.inv(edges)  # columns: grad N_a, a = 1..d
    grads = np.concatenate([-inv.sum(axis=2)[:, None, :], np.swapaxes(inv, 1, 2)], axis=1)
    return grads, cell_measures(x)


class BulkViscosity:
    """The viscous forces of this rank's owned cells, and the energy they dissipate.

    comps (n, (d+1) d): the flat velocity components of each owned cell; grads, measure,
    rho (kg/m^3), length (m), c (m/s): per owned cell. ``add_force(v, f)`` adds the forces
    of the velocities v to f; ``book(v_new, h)`` books their work over the step that took the
    velocities to v_new. ``dissipated`` (J, J/m in 2D): this rank's share."""
    STATE = ("dissipated",)  # what a checkpoint keeps (the forces live within a step)

    def __init__(self, comps, grads, measure, rho, c, options=ViscosityOptions()):
        self.comps, self.grads = comps, grads
        self.rho, self.c, self.options = rho, c, options
        self.measure = measure
        self.length = measure ** (1 / grads.shape[2])
        self.force = np.zeros(comps.shape)
        self.v_old = np.zeros(comps.shape)
        self.dissipated = 0.0

    def add_force(self, v, f):
        """f[comps] += q |cell| grad N_a for the velocities v (m/s, flat, local)."""
        _add_forces(self.comps, self.grads, self.measure, self.rho, self.length, self.c, self.options.quadratic,
                    self.options.linear, v, self.v_old, self.force, f)

    def book(self, v_new, h):
        """Add the work of the last forces over the step, -h f.(v_old + v_new) / 2 (J), to
        ``dissipated``; v_new (m/s, flat, local): the velocities after the step."""
        self.dissipated -= h * _power(self.comps, self.force, self.v_old, v_new) / 2


# The forces cell by cell, compiled: numpy's version (a gather, an einsum, the pressure
# and the scatter, each a pass with its temporaries) cost about half the elastic step it
# is added to. Measured on sound-bar, forces and booking, CPU per element-step: 67 -> 28 ns
# (10,050 triangles), 117 -> 44 ns (9,555 tetrahedra). ``pressure`` above is the law they
# follow (tests/test_viscosity.py).

@njit(cache=True, error_model="numpy")
def _add_forces(comps, grads, measure, rho, length, c, quadratic, linear, v, v_old, force, f):
    """Per cell e: v_old[e] = v[comps[e]], div v, q (as ``pressure``), force[e] = q |cell|
    grad N_a, added to f[comps[e]]."""
    n, k, d = grads.shape
    for e in range(n):
        div = 0.0
        for a in range(k):
            for i in range(d):
                v_old[e, a * d + i] = v[comps[e, a * d + i]]
                div += grads[e, a, i] * v_old[e, a * d + i]
        rate = min(div, 0.0)
        s = rho[e] * length[e] * (quadratic * length[e] * rate * rate - linear * c[e] * rate) * measure[e]
        for a in range(k):
            for i in range(d):
                force[e, a * d + i] = s * grads[e, a, i]
                f[comps[e, a * d + i]] += force[e, a * d + i]


@njit(cache=True, error_model="numpy")
def _power(comps, force, v_old, v_new):
    """Sum over the cells' components of force . (v_old + v_new[comps]) (N m/s)."""
    total = 0.0
    for e in range(comps.shape[0]):
        for j in range(comps.shape[1]):
            total += force[e, j] * (v_old[e, j] + v_new[comps[e, j]])
    return total


def applies(case):
    """Whether ``bulk_viscosity`` is on in [material] or any [materials.NAME] group."""
    return case.material.bulk_viscosity or any(m.bulk_viscosity for m in case.materials.values())


def build(space, domain, case, options=ViscosityOptions()):
    """The BulkViscosity of the case's owned cells where ``bulk_viscosity`` is on ([material]
    or its [materials.NAME] group), or None if it is off everywhere."""
    on = np.full(space.n_owned_cells, case.material.bulk_viscosity)
    if case.materials:
        tags = np.full(len(space.cell_dofs), -1, dtype=np.int32)
        tags[domain.cell_tags.indices] = domain.cell_tags.values
        for name, mat in case.materials.items():
            on[tags[:space.n_owned_cells] == domain.materials[name]] = mat.bulk_viscosity
    if not space.mesh.comm.allreduce(bool(on.any()), op=MPI.LOR):
        return None
    lam, mu, rho = bulk.material_fields(space, domain, case.material, case.materials)
    cells = np.flatnonzero(on)
    cell_value = lambda f: f.x.array[compat.cell_dofs(f.function_space)[cells, 0]]  # noqa: E731
    rho_c, modulus = cell_value(rho), cell_value(lam) + 2 * cell_value(mu)
    dofs = space.cell_dofs[cells]
    grads, measure = shape_gradients(space.x[dofs])
    return BulkViscosity(space.components(dofs), grads, measure, rho_c, np.sqrt(modulus / rho_c), options)



def warm():
    """Compile the forces (2D and 3D) into numba's cache on one cell of each."""
    for d in (2, 3):
        k = d + 1
        comps = np.arange(k * d).reshape(1, -1)
        visc = BulkViscosity(comps, np.ones((1, k, d)), np.ones(1), np.ones(1), np.ones(1))
        visc.add_force(np.ones(k * d), np.zeros(k * d))
        visc.book(np.ones(k * d), 1.0)
