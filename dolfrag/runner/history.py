"""history.csv's first columns: step, time, load, the energy balance, broken links and the
Newton report; and the largest balance error of the run."""
import sys

import numpy as np
from mpi4py import MPI
from dolfrag.runner.context import Observer

ENERGY_COLUMNS = ["E_kinetic_J", "E_bulk_J", "E_interface_J", "E_rebar_J", "D_damage_J", "D_contact_J",
                  "D_numerical_J", "D_rebar_plastic_J", "D_viscous_J", "W_external_J", "balance_error_J"]
ENERGY_FIELDS = ["kinetic", "bulk", "interface", "rebar", "damage", "contact", "numerical", "plastic", "viscous",
                 "external_work", "balance_error"]
# Bulk viscosity dissipating more than this share of the external work is warned about:
# it then shapes the answer (measured: ~20 % of the work in wall-scabbing), where it is
# meant only to damp the ringing behind a front.
VISCOUS_SHARE = 0.05


class History:
    columns = ["step", "time_s", "load_Pa", *ENERGY_COLUMNS, "broken_links", "newton_iterations",
               "newton_unconverged", "newton_residual"]
    STATE = ("max_error", "max_work", "last", "viscous_warned")

    def __init__(self, ctx):
        self.ctx = ctx
        self.max_error = self.max_work = 0.0  # J
        self.last = None  # the last Energies
        self.viscous_warned = False

    def values(self, step):
        integ, comm, e = self.ctx.integ, self.ctx.comm, step.energies
        self.last = e
        self.max_error = max(self.max_error, abs(e.balance_error))
        self.max_work = max(self.max_work, abs(e.external_work))
        if not self.viscous_warned and e.viscous > VISCOUS_SHARE * abs(e.external_work) > 0:
            self.viscous_warned = True
            if comm.rank == 0:
                print(f"dolfrag: warning: at t = {integ.energy_time:.4g} s the bulk viscosity has dissipated "
                      f"{e.viscous:.4g} J, {e.viscous / abs(e.external_work):.1%} of the external work (over "
                      f"{VISCOUS_SHARE:.0%}: it shapes the answer; material.bulk_viscosity = false turns it off)",
                      file=sys.stderr)
        newton = [comm.allreduce(integ.interface.iterations, op=MPI.MAX),
                  comm.allreduce(integ.interface.unconverged, op=MPI.SUM),
                  comm.allreduce(integ.interface.residual, op=MPI.MAX)]
        return [step.k, integ.energy_time, integ.pressure(step.t_n), *(getattr(e, a) for a in ENERGY_FIELDS),
                e.broken_links, *newton]

    def summarise(self, summary):
        e = self.last
        if e is not None:
            summary["energies_J"] = {c: getattr(e, a) for c, a in zip(ENERGY_COLUMNS, ENERGY_FIELDS)}
            summary["broken_links"] = e.broken_links
        summary["max_abs_balance_error_J"] = self.max_error
        summary["balance_error_relative"] = self.max_error / self.max_work if self.max_work else 0.0


class Probes(Observer):
    """The mean velocity of every named boundary (owned dofs), a history column per
    component: v<axis>_<boundary>_m_s."""

    def __init__(self, ctx):
        space, domain = ctx.space, ctx.problem.domain
        self.ctx, self.comps = ctx, {}
        for name, tag in sorted(domain.boundaries.items()):
            dofs = space.boundary_dofs(domain.facet_tags, tag)
            dofs = dofs[dofs < space.n_owned_dofs]
            for k, axis in enumerate("xyz"[:space.gdim]):
                self.comps[f"v{axis}_{name}_m_s"] = space.gdim * dofs + k
        self.columns = list(self.comps)

    def values(self, step):
        v = self.ctx.integ.v.x.array
        sums = self.ctx.comm.allreduce(np.array([[v[c].sum(), len(c)] for c in self.comps.values()]).reshape(-1, 2))
        return list(sums[:, 0] / np.maximum(sums[:, 1], 1))


class RebarForce(Observer):
    """The largest bar force (N, N/m in 2D) of the step, and the bars' summary block."""
    columns = ["rebar_force_max_N"]

    def __init__(self, ctx):
        self.ctx = ctx

    @staticmethod
    def applies(problem):
        return problem.rebars is not None

    def values(self, step):
        return [self.ctx.comm.allreduce(self.ctx.integ.rebars.force_max, op=MPI.MAX)]

    def summarise(self, summary, final):
        bars, comm = self.ctx.integ.rebars, self.ctx.comm
        summary["rebar"] = {"segments": bars.count, "mass_kg": bars.mass, "peak_force_N": comm.allreduce(bars.peak_force, op=MPI.MAX),
                            "plastic_work_J": comm.allreduce(bars.plastic_work),
                            "ruptured_segments": bars.ruptures, "rupture_energy_J": comm.allreduce(bars.rupture_work),
                            "units": "N, J and kg per metre of depth in 2D"}
        if hasattr(bars, "bond_work"):  # bond-slip (rebar/bond.py): the plastic slip's work
            summary["rebar"]["bond_slip_work_J"] = comm.allreduce(bars.bond_work)
