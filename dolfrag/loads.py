"""Loads: pressure-time signals p(t) (Pa) and their application on a boundary.

A positive pressure pushes into the body: the traction on the loaded boundary is
-p(t) n with n the outward normal.
"""
import numpy as np
import ufl

from dolfrag import compat


def triangular(peak, rise, duration):
    """p(t): linear rise 0 -> ``peak`` (Pa) over ``rise`` (s), linear decay to 0 at
    ``duration`` (s), zero before 0 and after. Vectorised over t."""
    return lambda t: np.interp(t, [0.0, rise, duration], [0.0, peak, 0.0], left=0.0, right=0.0)


def tabulated(t_table, p_table):
    """p(t) linearly interpolated in a table (s, Pa); zero outside it."""
    return lambda t: np.interp(t, t_table, p_table, left=0.0, right=0.0)


def signal(load):
    """The p(t) of a config.Load."""
    if load.signal == "triangular":
        return triangular(load.peak, load.rise, load.duration)
    return tabulated(load.t, load.p)


def unit_pressure_vector(space, domain, boundary):
    """Nodal forces (Function) of a unit pressure (1 Pa) on a named boundary:
    the integral of -n . w over it (N per Pa, per metre of depth in 2D). Collective."""
    V = space.V
    w = ufl.TestFunction(V)
    ds = compat.facet_measure(space.mesh, domain.facet_tags)
    n = ufl.FacetNormal(space.mesh)
    f = compat.Function(V)
    compat.assemble_vector(-ufl.inner(n, w) * ds(domain.boundary_tag(boundary)), f)
    return f
