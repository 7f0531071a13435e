"""The `theta` integrator: Moreau-Jean theta-method, bulk and interface implicit; its Newton
policy, the accepted step and its energy (the step problem: residual.py; the linear
algebra: solver/sparse_system.py; the tuning: solver/options.NewtonOptions).

Energy. With D the link stiffness at the converged point (piecewise constant: contact keeps
g_N >= 0 at the ends of the steps), the step obeys exactly

    Delta(1/2 v.M v + 1/2 u.K u + psi(g)) + D_contact + D_num = l_theta.(u_{n+1} - u_n)
    D_contact = -sum w r.(g_{n+1} - g_n) >= 0   (inelastic impacts, friction)
    D_num = (theta - 1/2) (x.M x + du.K du + sum w dg.D dg) >= 0,  du = u_{n+1} - u_n

so theta = 1/2 conserves energy (trapezoidal rule) and theta > 1/2 damps the high
frequencies: D_num is reported as its own number (Energies.numerical). The bars add
Delta E_rebar + D_rebar_plastic on the left: the work of their step forces, exactly (any
round-off rest is booked in D_num). The energy released by damage is booked at g_{n+1} by
model.store, where this scheme stores it; for the rigid laws (threshold, linear softening)
the cohesive part of the constraint reactions' work is stored in the links (model.absorb),
split from D_contact as the star Newton does (solver/energy.reaction_work).

Newton. A backtracking line search on the residual norm; damped steps after ``cycle``
iterations (active-set cycles); on sticking links, ``regularisation`` on the reaction
diagonal (rigid constraints around a vertex are redundant; the residual stays exact), and a
stronger one on all links in contact once a sub-step needs more than a few iterations. The
factorisation is what costs (~75 % of a run): an iteration first tries the one in hand while
almost no link or bar changed state (``stale_contraction``), and the Jacobian is
refactorised only when it changed. A step Newton cannot finish in max_iterations is cut into
two half steps, recursively max_cuts times (the next steps start from the halving the last
one needed), then given ``last_resort`` times the iterations once, before ConvergenceError is
raised with the state left at the start of that sub-step. The answer does not depend on the
rank count beyond solver round-off.
"""
from dataclasses import dataclass

import numpy as np

from dolfrag import compat
from dolfrag.interface.contact import link_blocks
from dolfrag.solver import semismooth
from dolfrag.solver.energy import global_energies, reaction_work
from dolfrag.solver.interrupt import StepInterrupted
from dolfrag.solver.options import NewtonOptions
from dolfrag.solver.sparse_system import LinearSolveError, SparseSystem
from dolfrag.loads.nodal import nodal_load
from dolfrag.solver.theta.residual import ThetaResidual
from dolfrag.timing import PhaseTimer


class ConvergenceError(semismooth.ConvergenceError):
    """A step that did not converge, even cut max_cuts times; the state is left at t_n."""

    def __init__(self, t, h, residual, iterations, reason):
        self.t, self.h, self.residual, self.iterations, self.reason = t, h, residual, iterations, reason
        super().__init__(f"theta step at t = {t:.6g} s did not converge with sub-steps down to h = {h:.3g} s: "
                         f"{reason}; scaled residual {residual:.3g} after {iterations} Newton iterations")


class _NotConverged(Exception):
    def __init__(self, residual, iterations, reason):
        super().__init__(reason)
        self.residual, self.iterations, self.reason = residual, iterations, reason


@dataclass
class NewtonReport:
    """Newton iterations of the last step (all its sub-steps), its extra sub-steps from step
    cutting, the largest final scaled residual of its sub-steps, and the energy the contact
    reactions dissipated so far on this rank's links (J, J/m in 2D); the caps. unconverged,
    stalled and remembered stay 0: a step that does not converge is cut, then raises
    ConvergenceError."""
    layout = failed = None  # one global system: no star layout, no star left unsolved
    max_iterations: int
    rtol: float
    iterations: int = 0
    cuts: int = 0
    residual: float = 0.0
    unconverged: int = 0
    stalled: int = 0
    remembered: int = 0
    contact_dissipated: float = 0.0


class Theta:
    """Moreau-Jean integrator with the surface of solver/imex.Imex.

    space, bulk, jump: from space.py, bulk.py, interface/jumps.py; model: an interface model
    (interface/models.py: Elastic springs, or a law with damage, contact and friction);
    load, pressure: as in Imex (a load vector per pascal times p(t) in Pa, or a load applied
    per facet); h: time step (s), any
    size (the scheme is unconditionally stable); theta in [1/2, 1]; constrained: flat local
    dof components held at zero (supports.constrained_components, or a boolean mask such as
    Stars.constrained); options: solver/options.NewtonOptions; contact: the law has contact
    and friction (not linear springs everywhere: interface/models.Law.springs). Collective.
    """

    # what a checkpoint keeps (a resumed run refactorises at its first step)
    STATE = ("u", "v", "t", "n", "work", "numerical", "r", "_g", "_x_last", "_h_last", "_depth", "_deepest", "_calm")
    # None, or a stop request (solver/interrupt.py) whose pending() is asked before each
    # Newton iteration (a theta step may take minutes, more than a launcher waits after its
    # SIGTERM); True abandons the step with StepInterrupted
    interrupt = None
    abandonable = True
    viscosity = None  # the bulk viscosity is explicit: imex's alone

    def __init__(self, space, bulk, jump, model, load, pressure, h, theta=0.5, constrained=(), rebars=None,
                 options=NewtonOptions(), *, contact):
        if not 0.5 <= theta <= 1.0:
            raise ValueError(f"theta = {theta!r}: must be in [1/2, 1]")
        if not h > 0:
            raise ValueError(f"h = {h!r}: the time step must be > 0 (s)")
        self.space, self.bulk, self.jump, self.model = space, bulk, jump, model
        self.rebars, self.options = rebars, options
        self.pressure, self.h, self.theta = pressure, h, theta
        self._depth = self._deepest = self._calm = 0  # sub-step halvings: the next step's, this step's deepest
        self.comm = space.mesh.comm
        self.timer = PhaseTimer()
        self.u, self.v = compat.Function(space.V), compat.Function(space.V)
        self.u.name, self.v.name = "displacement", "velocity"
        load = nodal_load(load, pressure, slice(0, space.n_owned_dofs * space.gdim))
        res = self.residual = ThetaResidual(space, bulk, jump, model, load, theta, constrained, rebars, self.u,
                                            self.v, options.rtol, options.regularisation, contact)
        self.owned, self.m, self.contact = res.owned, res.m, res.contact
        self.t, self.n = 0.0, 0
        self.work = self.numerical = 0.0  # this rank's shares, J
        self.interface = NewtonReport(options.max_iterations, options.rtol)
        n_links, d = len(jump.links), space.gdim
        self.r = np.zeros((n_links, d))  # contact reactions of the last step, Pa
        self._g = np.zeros((n_links, d))  # link-frame jumps of u_n, m
        self._x_last, self._h_last = np.zeros(self.owned.stop), 0.0  # last velocity increment: Newton's start
        factor = "lu" if self.contact else "cholesky" if rebars is None else "lu-nonsymmetric"
        self.system = SparseSystem(self.comm, res.blocks(), self.owned.stop + res.n_r, res.start, factor,
                                   options.mumps_relaxations)
        self._assembled_h = self._factored_status = None  # the factorisation in hand

    @classmethod
    def from_problem(cls, problem, h=None, theta=None, load=None, pressure=None, rebars=True,
                     options=NewtonOptions()):
        """The integrator of ``problem`` (problem.Problem): steps of h (s) and theta (default
        the case's), a fresh model of the case's interface law, the problem's load vector,
        pressure and bars (rebars=False: none), its supports held."""
        theta = problem.case.time.theta if theta is None else theta
        return cls(problem.space, problem.bulk, problem.jump, problem.interface_model(h),
                   problem.load if load is None else load, pressure or problem.pressure, h or problem.h,
                   0.5 if theta is None else theta, problem.stars.constrained,
                   rebars=problem.rebars if rebars else None, options=options, contact=not problem.law.springs)

    @property
    def energy_time(self):
        """Time (s) of the energies step() returns: t_{n+1} (imex's are at t_{n+1/2})."""
        return self.t

    # ------------------------------------------------------------------ one step
    def step(self, energies=False):
        """Advance from t_n to t_n + h as 2^k sub-steps, k the halvings the last steps
        needed (each sub-step halved further while Newton needs it, k back down by one
        after relax_after steps without a halving): a step Newton cannot finish costs
        max_iterations iterations, and once cracks spread most steps need the same cuts
        as the one before. With ``energies``, return the Energies at t_{n+1}
        (collective), else None."""
        self.interface.iterations = self.interface.cuts = 0
        self.interface.residual = 0.0
        self.timer.start()
        start = self._deepest = self._depth
        for _ in range(2**start):
            self._advance(self.h / 2**start, start)
        self.interface.cuts -= 1  # sub-steps beyond the first
        if self._deepest > start:
            self._depth, self._calm = self._deepest, 0
        elif start:
            self._calm += 1
            if self._calm == self.options.relax_after:
                self._depth, self._calm = start - 1, 0
        self.n += 1
        self.timer.lap("implicit")
        if not energies:
            return None
        result = self._energies()
        self.timer.lap("diagnostics")
        return result

    def _advance(self, h, depth):
        try:
            self._substep(h, escalate=depth > 0)
        except _NotConverged as failure:
            if depth < self.options.max_cuts:
                self._advance(h / 2, depth + 1)
                self._advance(h / 2, depth + 1)
                return
            try:  # the last resort before giving up: last_resort times the iterations
                self._substep(h, self.options.last_resort * self.interface.max_iterations, escalate=True)
            except _NotConverged:
                raise ConvergenceError(self.t, h, failure.residual, failure.iterations, failure.reason) from None
        self.interface.cuts += 1
        self._deepest = max(self._deepest, depth)

    def _step_data(self, h):
        """The residual.Step of an attempt of length h from the current state."""
        return self.residual.step_data(h, self.t, self._g, self.options.regularisation)

    def _evaluate(self, step, x, r):
        return self.residual.evaluate(step, x, r)

    def _substep(self, h, cap=None, escalate=False):
        """Newton on (x, r) for one step of length h, at most ``cap`` iterations (default
        max_iterations), with the cycle regularisation once it needs many if ``escalate``;
        commits only once converged."""
        opt = self.options
        step = self._step_data(h)
        x = self._x_last * (h / self._h_last) if self._h_last else np.zeros(self.owned.stop)
        r = np.where(self.residual.frozen, 0.0, self.r) if self.contact else self.r
        point = self._evaluate(step, x, r)
        cap = cap or self.interface.max_iterations
        for iteration in range(1, cap + 1):
            if point.converged:
                break
            if self.interrupt is not None and self.interrupt.pending():
                raise StepInterrupted
            self.interface.iterations += 1
            if self._reusable(iteration, h, point):  # the factorisation in hand first
                dx, dr = self.residual.correction(step, self._solve(point))
                trial = self._evaluate(step, x + dx, r + dr)
                if trial.converged or trial.error <= opt.stale_contraction * point.error:
                    x, r, point = x + dx, r + dr, trial
                    continue
            far = escalate and iteration >= opt.regularise_after and point.error > opt.near
            step.regularisation = opt.cycle_regularisation if far else opt.regularisation
            self._factorise(step, point)
            dx, dr = self.residual.correction(step, self._solve(point))
            if iteration > opt.cycle:  # break active-set cycles: shorter, varying steps (as the star Newton)
                dx, dr = (0.5 ** (1 + iteration % 3) * a for a in (dx, dr))
            x, r, point = self._line_search(step, x, r, point, dx, dr)
        else:
            # stalled on a stick-slip kink within stall: accepted, as the star Newton does
            if not point.converged and point.error > opt.stall:
                raise _NotConverged(point.error, cap, f"Newton did not converge in {cap} iterations")
        self.interface.residual = max(self.interface.residual, point.error)
        self._commit(step, point, x, r)

    def _reusable(self, iteration, h, point):
        """Whether Newton's iteration tries the factorisation in hand (stale_contraction):
        of the same step length, assembled where every link and bar was in the same state
        (open, stick, slip; slack, taut, yielding) as at ``point``, so that only the smooth
        parts of the Jacobian moved. Collective."""
        if not (iteration <= self.options.cycle and self._assembled_h == h and self._factored_status is not None):
            return False
        changed = sum(np.count_nonzero(a != b) for a, b in zip(point.status, self._factored_status))
        total = sum(len(a) for a in point.status)
        changed, total = self.comm.allreduce(np.array([changed, total]))
        return changed <= self.options.stale_states * total

    def _line_search(self, step, x, r, point, dx, dr):
        """Backtracking on the residual norm; when no shorter step lowers it, the full step
        is taken anyway: a semi-smooth Newton step that changes the active set may raise
        the norm and still be the right one."""
        alpha, full = 1.0, None
        for _ in range(self.options.backtracks + 1):
            trial = self._evaluate(step, x + alpha * dx, r + alpha * dr)
            if trial.norm <= (1 - 1e-4 * alpha) * point.norm or trial.converged:
                return x + alpha * dx, r + alpha * dr, trial
            full = full or trial
            alpha /= 2
        return x + dx, r + dr, full

    def _factorise(self, step, point):
        """Assemble the Jacobian at ``point`` (the system refactorises at the next solve, and
        not at all when no entry changed on any rank: the springs' part depends on h only)."""
        if self.contact or self.rebars is not None or step.h != self._assembled_h:
            self.system.assemble(self.residual.values(step, point))
        self._assembled_h, self._factored_status = step.h, point.status

    def _solve(self, point):
        """Solve the last assembled Jacobian against -F(point)."""
        try:
            return self.system.solve(-point.F)
        except LinearSolveError as err:
            self._assembled_h = self._factored_status = None  # not reused
            raise _NotConverged(point.error, self.interface.iterations, str(err)) from None

    # ------------------------------------------------------------------ the accepted step
    def _commit(self, step, point, x, r):
        """Accept the converged step: fields, damage, energies, time."""
        h, th, own = step.h, self.theta, self.owned
        du = self.residual.displacement_increment(step, x)
        xf = self.residual.x.x.array
        dg = point.g_end - self._g
        law = point.law
        D = link_blocks(law.dr_N_dg_N, law.dr_N_dg_T, law.dr_T_dg_N, law.dr_T_dg_T)
        w = self.residual.w
        spring_work = w @ np.einsum("li,lij,lj->l", dg, D, dg)
        self.numerical += (th - 0.5) * (x @ (self.m[own] * x) + du[own] @ (self.bulk.K_cells @ du[own]) + spring_work)
        if self.rebars is not None:
            self.numerical += self._accept_bars(point.bars, du)
        self.work += step.load_theta @ du[own]
        if self.contact:
            g = point.g_end
            state = self.model.cohesion(g[:, 0], g[:, 1:], step.state_n, r[:, 0]).state
            self.model.store(np.arange(len(w)), state, g[:, 0], g[:, 1:])
            # split as the star Newton does: contact and friction dissipate, the cohesive
            # part of a rigid link's constraint is stored in it (after model.store)
            dissipated, stored = reaction_work(r[:, 0], r[:, 1:], dg, step.shift, step.cohesion_T)
            self.interface.contact_dissipated += w @ dissipated
            self.model.absorb(stored)
            self.r = r
        self.u.x.array[:] += du
        self.v.x.array[:] += xf
        self._g = point.g_end
        self._x_last, self._h_last = x, h
        self.t += h

    def _accept_bars(self, step, du):
        """Accept the bars' state at u_{n+1} = u_n + du and return what the work of their
        step forces leaves out of their state functions (J, this rank's counted segments):
        the elastic energy change and the plastic work take all of it (rebar.py's discrete
        gradient), so this is round-off, booked to keep the balance exact."""
        bars, u_n = self.rebars, self.u.x.array
        energy_n, dissipated_n = bars.elastic_energy(u_n), bars.dissipated
        bars.accept(step.end)
        return bars.work(step, du) - (bars.elastic_energy(u_n + du) - energy_n) - (bars.dissipated - dissipated_n)

    def _energies(self):
        own, w, g = self.owned, self.residual.w, self._g
        u_all = self.u.x.array
        v, u = self.v.x.array[own], u_all[own]
        bars = self.rebars
        return global_energies(self.comm, 0.5 * self.m[own] @ v**2, 0.5 * u @ (self.bulk.K_cells @ u),
                               w @ self.model.stored_energy(g[:, 0], g[:, 1:]), w @ self.model.dissipated(),
                               self.interface.contact_dissipated, self.work, np.count_nonzero(self.model.broken()),
                               self.numerical, bars.elastic_energy(u_all) if bars else 0.0,
                               bars.dissipated if bars else 0.0)
