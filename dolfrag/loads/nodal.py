"""The nodal forces of a pressure load on a rank's owned dof components, as the
integrators apply them: ``rows`` (n,) int64, the owned flat components the load reaches,
and ``forces(t)`` (n,) N on them at time t (s).

A uniform load is one vector times one signal, f(t) = p(t) l (UniformLoad); a charge
gives each loaded facet its own p(t) (loads.charge_load.ChargeLoad, same interface).
"""
import numpy as np


class UniformLoad:
    """f(t) = p(t) l: l the nodal forces per pascal (a Function, loads.unit_pressure_vector),
    p = ``pressure`` (Pa, a function of t in s); owned: the slice of the owned components."""

    def __init__(self, load, pressure, owned):
        per_pascal = load.x.array[owned]
        self.rows = np.flatnonzero(per_pascal)
        self.per_pascal = per_pascal[self.rows]  # N/Pa
        self.pressure = pressure

    def forces(self, t):
        return float(self.pressure(t)) * self.per_pascal


def nodal_load(load, pressure, owned):
    """The nodal load of an integrator's ``load`` argument: a Function of nodal forces per
    pascal (times ``pressure``, a UniformLoad), or a load already applied per facet (a
    charge_load.ChargeLoad), returned as it is."""
    return load if hasattr(load, "forces") else UniformLoad(load, pressure, owned)
