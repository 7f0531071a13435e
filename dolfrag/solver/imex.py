"""The `imex` step: explicit bulk, implicit interface.

Central difference for the bulk with the lumped mass M, and the interface springs taken
at the average ``(u_{n+1} + 2 u_n + u_{n-1}) / 4``. In velocity increments
``dv = v_{n+1/2} - v_{n-1/2}`` a step with linear springs K_i is

    (M + h^2/4 K_i) dv = h (f_ext(t_n) - K u_n - K_i u_n),     u_{n+1} = u_n + h v_{n+1/2},

whose matrix is block-diagonal over vertex stars (interface/stars.py); with damage,
contact and friction the same star split holds for the nonsmooth problem
(solver/semismooth.py). The step is stable for h below the bulk limit alone, whatever the
interface stiffness, and with linear springs it conserves exactly the discrete energy

    E_{n+1/2} = 1/2 v_{n+1/2}.M v_{n+1/2} + 1/2 u_{n+1}.K u_n + psi((g_n + g_{n+1}) / 2)

against the work W_{n+1/2} = sum_k f_ext(t_k).(u_{k+1} - u_{k-1}) / 2. Those are the
energies reported (plus the energy released by damage), so the balance error measures the
code and the nonsmooth events, not the time discretisation of the elastic part.

Parallel data flow per step: K u on owned cells, one forward ghost update of the force,
the star solves of owned vertices (no communication), one reverse update of the velocity
increments to their owners.
"""
import numpy as np

from dolfrag import compat, viscosity as bulk_viscosity
from dolfrag.loads.nodal import nodal_load
from dolfrag.solver import elastic_kernel
from dolfrag.solver.energy import global_energies
from dolfrag.solver.semismooth import StarNewton, step_stiffness
from dolfrag.timing import PhaseTimer


class ElasticSprings:
    """The linear step: star blocks A = M + h^2/4 K_i inverted once, and each step
    dv = h A^-1 (f - K_i u_n), with K_i u_n from the jumps of each star's own links, in one
    compiled loop over the stars (solver/elastic_kernel.py)."""

    def __init__(self, stars, jump, model, m, h):
        self.stars, self.jump, self.model, self.h = stars, jump, model, h
        blocks = jump.tangent_blocks(model.C_N, model.C_T)
        self.flat = flat = stars.flat(jump.links)
        self.K = np.ascontiguousarray(blocks[flat.links])  # per star link, N/m
        q = np.diff(flat.comp_off)
        self.inv_off = np.concatenate([[0], np.cumsum(q * q)]).astype(np.int64)
        self.inverse = np.empty(self.inv_off[-1])
        first = 0  # the flat layout lists the stars group by group
        for inv in stars.inverses(m, blocks, h * h / 4):
            self.inverse[self.inv_off[first]:self.inv_off[first + len(inv)]] = inv.ravel()
            first += len(inv)
        self._rhs, self._y = np.empty(len(flat.comps)), np.empty(len(flat.comps))

    contact_dissipated = 0.0  # no contact: the springs act in compression too
    iterations = unconverged = stalled = remembered = 0  # a direct solve
    residual = 0.0
    reaction = None  # the inverted blocks give prescribed components no increment
    layout = failed = None  # no star layout to checkpoint, no star left unsolved

    def solve(self, f, u, v, out):
        fl = self.flat
        elastic_kernel.elastic_stars(fl.comps, fl.comp_off, fl.link_off, fl.slot_A, fl.slot_B, self.K, self.inverse,
                                     self.inv_off, f, u, float(self.h), out, self._rhs, self._y)


class Imex:
    """Explicit-implicit integrator.

    space, bulk, jump: from space.py, bulk.py, interface/jumps.py; step: the interface
    step solver (ElasticSprings or semismooth.StarNewton) and its model; load: Function of
    nodal forces per pascal, times pressure p(t) (Pa), or a load applied per facet
    (loads.charge_load.ChargeLoad; pressure then its mean, for the history); h: time step
    (s); rebars: rebar/cables.Rebars, rebar/bond.BondedBars or None. The bars are
    explicit, like the bulk: their forces need every ghost displacement, so with bars each
    step ends with a forward scatter of u. viscosity:
    viscosity.BulkViscosity or None, explicit too (its forces from v_{n-1/2}). strength:
    interface/rate.RateStrength or None: the links' strengths at the bulk strain rate of
    v_{n-1/2}, set before each interface solve.
    """

    STATE = ("u", "v", "t", "n", "work", "_u_n")  # what a checkpoint keeps

    def __init__(self, space, bulk, jump, step, load, pressure, h, rebars=None, viscosity=None, strength=None):
        self.space, self.bulk, self.jump, self.interface = space, bulk, jump, step
        self.rebars, self.viscosity, self.strength = rebars, viscosity, strength
        self.model = step.model
        self.pressure, self.h = pressure, h
        V = space.V
        self.u, self.v, self.f, self.dv = (compat.Function(V) for _ in range(4))
        self.u.name, self.v.name = "displacement", "velocity"
        self._u_n = np.zeros_like(self.u.x.array) if rebars is not None else None  # u_n, for the bars' energy
        self.owned = slice(0, space.n_owned_dofs * space.gdim)
        comps = step.stars.comps
        self.star_comps = comps
        # updated here: owned components, plus the ghost ones of this rank's stars
        self.star_ghosts = comps[comps >= self.owned.stop]
        self.star_shared = self._shared(comps)
        self.load = nodal_load(load, pressure, self.owned)
        self.m = bulk.m.x.array
        self.t, self.n = 0.0, 0
        self.work = 0.0
        self.timer = step.timer = PhaseTimer()  # the star solver books its collective too
        self._imposed = None

    def _shared(self, comps):
        """Of this rank's star components, those a reverse update of dv may change: the
        owned ones another rank holds as ghosts, and the ghost ones (none in serial).
        Collective."""
        held = compat.Function(self.space.V)
        held.x.array[self.owned.stop:] = 1.0
        compat.scatter_reverse_add(held)
        return comps[(comps >= self.owned.stop) | (held.x.array[comps] != 0)]

    @classmethod
    def from_problem(cls, problem, h=None, load=None, pressure=None, step=None):
        """The integrator of ``problem`` (problem.Problem) with steps of h (s; default the
        problem's), a fresh interface model and its star step solver (``step``, a class
        called as StarNewton, for a nonsmooth law; linear springs get ElasticSprings), the
        problem's load vector and pressure unless given."""
        h = h or problem.h
        m = problem.bulk.m.x.array
        model = problem.interface_model(h, step_stiffness(problem.links, m, h, problem.space.gdim))
        solver = ElasticSprings if problem.law.springs else step or StarNewton
        return cls(problem.space, problem.bulk, problem.jump, solver(problem.stars, problem.jump, model, m, h),
                   problem.load if load is None else load, pressure or problem.pressure, h, rebars=problem.rebars,
                   viscosity=bulk_viscosity.build(problem.space, problem.domain, problem.case),
                   strength=problem.rate_strength())

    def impose(self, comps, velocity):
        """Prescribe the velocity of supported components from now on: ``velocity(t)``
        (m/s, an array like ``comps``) at the mid-step times t_{n+1/2}; comps: flat local
        components, all held by the supports. Drives patch tests and imposed motions; the
        reactions are the step solver's ``reaction`` (N). Their work joins the external
        work, h R.V in a step (V the imposed velocity), booked by the rank whose stars hold
        the component: the same discrete work as a pressure's, so the balance closes."""
        comps = np.asarray(comps, dtype=np.int64)
        if self.interface.reaction is None:
            raise ValueError("impose: the elastic law's inverted star blocks cannot move "
                             "prescribed components; use a nonsmooth law")
        if not self.interface.stars.constrained[comps].all():
            raise ValueError("impose: every component must be held by a support "
                             "(supports.clamped or supports.rollers)")
        booked = np.flatnonzero(np.isin(comps, self.star_comps))  # positions in comps of this rank's stars'
        self._imposed = (comps, velocity, booked, comps[booked])

    def set_velocity(self, v):
        """Start from the velocity v (m/s, every local component): v_{-1/2}. Its kinetic
        energy E_{-1/2} counts as work supplied before the first step, so that the balance
        still reads E_{n+1/2} = W_{n+1/2}."""
        self.v.x.array[:] = v
        own = self.owned
        self.work += 0.5 * self.m[own] @ self.v.x.array[own] ** 2

    @property
    def abandonable(self):
        """Whether a stop request can abandon a step midway: not with linear springs, whose
        steps are short (a stop waits for their end)."""
        return not isinstance(self.interface, ElasticSprings)

    @property
    def interrupt(self):
        """None, or a stop request (solver/interrupt.py) that the interface solver asks once
        a step; set, a stop abandons the step with StepInterrupted. Absent (AttributeError)
        unless ``abandonable``."""
        return self.interface.interrupt

    @interrupt.setter
    def interrupt(self, request):
        self.interface.interrupt = request

    @property
    def energy_time(self):
        """Time (s) of the Energies step() returns: t_{n+1/2}, the mid-step of the last step."""
        return self.t - self.h / 2

    def step(self, energies=False):
        """Advance from t_n to t_{n+1}. With ``energies``, return the Energies at
        t_{n+1/2} (collective), else None."""
        h, u, v, f, dv = self.h, self.u.x.array, self.v.x.array, self.f.x.array, self.dv.x.array
        own, timer = self.owned, self.timer
        timer.start()
        Ku = self.bulk.K_cells @ u[own]
        load = self.load.forces(self.t)
        np.negative(Ku, out=f[own])
        if self.rebars is not None:
            if energies:  # u_n, for the bars' energy at the end of the step
                np.copyto(self._u_n, u)
            f[own] += self.rebars.explicit_step(u, h)[own]
        f[own][self.load.rows] += load
        if self.viscosity is not None:
            self.viscosity.add_force(v, f)
        timer.lap("bulk")
        compat.scatter_forward(self.f)
        timer.lap("communication")

        dv[:] = 0.0
        if self._imposed is not None:
            comps, velocity, booked, booked_comps = self._imposed
            held = velocity(self.t + h / 2)
            dv[comps] = held - v[comps]
        if energies:
            g_n = self.jump(u)  # for the energy at the mid jump
        if self.strength is not None:
            self._set_strengths(v)
        self.interface.solve(f, u, v, dv)
        if self._imposed is not None:
            self.work += h * self.interface.reaction[booked_comps] @ held[booked]
        mine = dv[self.star_shared]
        timer.lap("interface")
        compat.scatter_reverse_add(self.dv)
        timer.lap("communication")
        dv[self.star_shared] = mine

        v_old_loaded = v[own][self.load.rows]
        v[own] += dv[own]
        u[own] += h * v[own]
        ghosts = self.star_ghosts
        v[ghosts] += dv[ghosts]
        u[ghosts] += h * v[ghosts]
        if self.viscosity is not None:
            self.viscosity.book(v, h)
        timer.lap("update")
        if self.rebars is not None:
            compat.scatter_forward(self.u)
            timer.lap("communication")
        self.work += h * load @ (v[own][self.load.rows] + v_old_loaded) / 2
        self.t += h
        self.n += 1
        timer.lap("update")
        if energies:
            result = self._energies(Ku, (g_n + self.jump(u)) / 2)
            timer.lap("diagnostics")
            return result
        return None

    def _set_strengths(self, v):
        """The links' strengths at the strain rate of v_{n-1/2} (its ghosts made current:
        a link's cells may hold another rank's vertices)."""
        if self.space.mesh.comm.size > 1:
            compat.scatter_forward(self.v)
            self.timer.lap("communication")
        self.interface.strengths_changed(self.strength.update(v, self.model))
        self.timer.lap("interface")

    def _energies(self, Ku, g_mid):
        own = self.owned
        v, u = self.v.x.array[own], self.u.x.array[own]
        weight = self.jump.links.weight
        bars = self.rebars
        kinetic = 0.5 * self.m[own] @ v**2 + (bars.kinetic_energy if bars else 0.0)
        return global_energies(self.space.mesh.comm, kinetic, 0.5 * u @ Ku,
                               weight @ self.model.stored_energy(*self.jump.local(g_mid)),
                               weight @ self.model.dissipated(), self.interface.contact_dissipated, self.work,
                               np.count_nonzero(self.model.broken()),
                               rebar=bars.stored_energy(self._u_n, self.u.x.array) if bars else 0.0,
                               plastic=bars.dissipated if bars else 0.0,
                               viscous=self.viscosity.dissipated if self.viscosity else 0.0)
