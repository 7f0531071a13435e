"""The discrete problem of a case: mesh, space, bulk operators, links, stars, rebars,
supports and load, built once by ``Problem.build(case, comm)``.

A Problem holds no time-stepping state but the bars' (cables.Rebars keeps its plastic strains
beside its geometry): the integrators (solver/imex.py, solver/theta/) are built from it
and carry u, v, t and the interface model's state.
"""
import math
import sys
from dataclasses import dataclass

import numpy as np

from dolfrag import bulk, compat, guards, loads, mass_scaling, mesh, space as spaces, supports, viscosity
from dolfrag.case import CaseError
from dolfrag.interface import links as link_table, models, rate
from dolfrag.interface.jumps import Jump
from dolfrag.rebar import bond, cables, faces as rebar_faces, layout as rebar_layout, stable_step as rebar_step
from dolfrag.interface.stars import Stars
from dolfrag.loads.charge_load import ChargeLoad
from dolfrag.loads.stretch import end_components


@dataclass(frozen=True)
class Problem:
    """case: case.Case; domain, space: mesh.py, space.py; bulk: bulk.py's operators (lumped
    mass m, stiffness K, the bulk's own stable step); rebars: cables.Rebars or None; links, jump, stars:
    interface/; held: flat local components held by the supports (a stretch's ends
    included); applied_load: case.load as applied (loads.applied: an h2-air load shaped from
    its gas); load: Function of nodal forces per pascal, or for a charge its
    loads.charge_load.ChargeLoad (a p(t) per facet); pressure: p(t) (Pa), for a charge the
    mean over the loaded boundary; dt_crit: the stable explicit step (s) of the bulk with its
    bars and, under imex, its viscosity; h: the time step (s), n_steps of it to
    case.time.end."""
    case: object
    comm: object
    domain: object
    space: object
    bulk: object
    rebars: object
    links: object
    jump: object
    stars: object
    held: np.ndarray
    applied_load: object
    load: object
    pressure: object
    dt_crit: float
    h: float
    n_steps: int

    @property
    def law(self):
        """The interface law (interface/models.Law) of the case."""
        return models.law(self.case.interface)

    @property
    def stiffness(self):
        """(C_N, C_T) Pa/m: the interface springs by the case's stiffness rule."""
        return self.case.interface.stiffness(self.case.material.E, self.case.mesh.size)

    def owned_cell_centroids(self):
        """(n_owned_cells, gdim) m: the centroids of this rank's cells, which say where the
        mesh was partitioned (checkpoint.owner_rule)."""
        space = self.space
        return space.x[space.cell_dofs[:space.n_owned_cells]].mean(axis=1)

    def interface_model(self, h=None, k_step=np.inf):
        """A fresh interface model (all links sound) for steps of h (s; default the
        problem's); k_step as in models.build."""
        case = self.case
        return models.build(case.interface, case.material.E, case.mesh.size, len(self.links), h or self.h, k_step)

    def rate_strength(self):
        """The links' strengths at the bulk strain rate (interface/rate.RateStrength) when
        interface.rate_effect asks for them, else None."""
        interface = self.case.interface
        if interface.rate_effect != "fib2010":
            return None
        return rate.RateStrength(self.space, self.links, interface.sigma_c)

    @classmethod
    def build(cls, case, comm, owner_rule=None, applied_load=None):
        """Mesh and operators of ``case`` (case.Case) on ``comm``; owner_rule: which rank
        owns each cell, as in mesh.build (default: the graph partitioner's choice);
        applied_load: loads.applied(case.load, comm) when already made. Collective.
        Raises CaseError for a boundary name the mesh lacks."""
        if applied_load is None:
            applied_load = loads.applied(case.load, comm)
        domain = mesh.build(case.geometry, case.mesh.size, comm, owner_rule, max_cells=case.run.max_cells,
                            optimize_threshold=case.mesh.optimize_threshold)
        _check_boundaries(case, domain)
        space = spaces.create(domain)
        bulk_ops = bulk.assemble(space, domain, case, case.time.mass_scaling)
        sliver = case.time.scheme == "imex" and guards.sliver_warning(case, bulk_ops.dt_bulk)
        heavy = bulk_ops.mass_scaling and mass_scaling.warning(bulk_ops.mass_scaling["added_mass_kg"],
                                                              bulk_ops.mass_scaling["mass_kg"])
        for line in (sliver, heavy):
            if line and comm.rank == 0:
                print(line, file=sys.stderr)
        bars = _rebars(case, domain, space, bulk_ops, comm)
        links = link_table.build(space)
        held = supports.constrained_components(space, domain, case.supports)
        if case.load.kind == "stretch":  # its ends are supports whose velocity is prescribed
            held = np.union1d(held, np.concatenate(end_components(space, domain)))
        stars = Stars(space, links, held)
        dt_crit = _stable_step(case, bulk_ops, bars, space)
        h, n_steps = _time_step(case.time, applied_load, dt_crit)
        if case.load.signal == "charge":
            load = ChargeLoad(case.load, space, domain, comm)
            pressure = load.mean_pressure
        elif case.load.kind == "pressure":
            load = loads.unit_pressure_vector(space, domain, case.load.boundary, case.load.region)
            pressure = loads.signal(applied_load)
        else:
            load, pressure = compat.Function(space.V), np.zeros_like  # no pressure: p(t) = 0
        return cls(case, comm, domain, space, bulk_ops, bars, links, Jump(space, links), stars, held, applied_load,
                   load, pressure, dt_crit, h, n_steps)


def _check_boundaries(case, domain):
    named = ([("load.boundary", case.load.boundary)] if case.load.kind == "pressure" else []) + [
        (f"supports.{kind}", name) for kind in ("rollers", "clamped", "simple")
        for name in getattr(case.supports, kind)]
    for key, name in named:
        if name not in domain.boundaries:
            raise CaseError(f"{key} = {name!r}: not a boundary of the mesh; boundaries: "
                            f"{', '.join(sorted(domain.boundaries)) or 'none'}")


def _rebars(case, domain, space, bulk_ops, comm):
    """The case's bars (None without rebar.faces): perfectly bonded, their mass joins the
    bulk's; with bond-slip (rebar.bond), their own nodes carry it."""
    if not case.rebar.faces:
        return None
    if case.geometry.kind == "file":
        lines, areas = rebar_faces.polylines(case.rebar, space, domain, comm)
    else:
        lines, areas = rebar_layout.layer_polylines(case.rebar, case.geometry, space.gdim)
    r = case.rebar
    if r.bond == "fib2010":
        return bond.BondedBars(space, lines, areas, r.diameter, r.E, r.f_y, r.rho, case.mesh.size, comm,
                               bond.BondLaw(tau_max=r.bond_tau_max, s3=r.bond_s3), eps_u=r.eps_u,
                               small_strain=r.kinematics == "small_strain")
    bars = cables.Rebars(space, lines, areas, r.E, r.f_y, r.rho, case.mesh.size, comm, eps_u=r.eps_u,
                         small_strain=r.kinematics == "small_strain")
    bars.add_mass(bulk_ops.m.x.array)
    return bars


def _stable_step(case, bulk_ops, bars, space):
    """dt_crit (s): the bulk's stable explicit step, with the bars' stiffness (their mass
    already in bulk_ops.m) by time.bars_step, and under imex lowered by the viscosity's
    linear term. Collective."""
    dt_crit = bulk_ops.dt_bulk
    if bars is not None:
        dt_crit = rebar_step.stable_step(case.time.bars_step, bulk_ops, bars, space)
    if case.time.scheme == "imex" and viscosity.applies(case):
        dt_crit *= viscosity.step_factor()
    return dt_crit


def _time_step(time, applied_load, dt_crit):
    """(h s, n_steps) for the case's ``time`` section: theta's step follows the accuracy of
    the load as applied (it is unconditionally stable), imex's the bulk's stable step;
    either is shortened to end exactly at time.end."""
    if time.scheme == "theta":
        h = time.dt or loads.accuracy_time_step(applied_load, time.end)
    else:
        h = time.cfl * dt_crit
    n_steps = math.ceil(time.end / h)
    return time.end / n_steps, n_steps
