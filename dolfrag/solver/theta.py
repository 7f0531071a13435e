"""The `theta` step: Moreau-Jean theta-method, bulk and interface implicit (DESIGN.md §4).

A step t_n -> t_{n+1} = t_n + h solves for the velocity increment x = v_{n+1} - v_n of
every dof component and, where the interface has contact, the link reactions r (link
frame, normal first; Pa, r_N >= 0 pushes the faces apart), the mean force density of the
step's contact impulse:

    M x = h f_theta + h B^T w R^T r
    u_{n+1} = u_n + h (theta v_{n+1} + (1 - theta) v_n) = u_n + h (v_n + theta x)
    f_theta = p_theta l - K u_theta - B^T w R^T t(g_theta)
    phi(r, g_{n+1}, g_{n+1} - g_n) = 0

u_theta = theta u_{n+1} + (1 - theta) u_n; g = R B u the link jumps in the link frames R
(interface/jumps.py, links.py); w the link weights; t the cohesive traction of the model
with its damage lagged by one step (interface/models.py: each step problem is monotone),
plus the bars' step forces C^T (N m) when there are rebars (rebar.py: the mean force over
the step's strain path along the mean chord, a discrete gradient; its tangent in u_{n+1},
material and geometric, not symmetric, joins the matrix);
p_theta = theta p(t_{n+1}) + (1 - theta) p(t_n) the pressure on the load vector l; phi the
Alart-Curnier projection (interface/contact.py): Signorini on the end-of-step gap, Coulomb
with mu(state_n) on the step's slip, no penalty. With linear forces Newton's matrix is
W = M + theta^2 h^2 (K + B^T w D B), D the link stiffness: a global sparse operator (K
couples the copies of a cell, the links the copies of a vertex), so every Newton iteration
is one PETSc KSP solve (MUMPS LU) of the generalised Jacobian of (x, r) together. The
reaction unknowns and rows are scaled per link so that every entry is of the order of the
link's mass m_l (r = m_l / (h w) r~, rows times h w, augmentation rho = m_l / (theta h^2 w)),
which keeps the pivoting of the saddle-point system sound.

Energy. With D the link stiffness at the converged point (piecewise constant: contact keeps
g_N >= 0 at the ends of the steps), the step obeys exactly

    Delta(1/2 v.M v + 1/2 u.K u + psi(g)) + D_contact + D_num = p_theta l.(u_{n+1} - u_n)
    D_contact = -sum w r.(g_{n+1} - g_n) >= 0   (inelastic impacts, friction)
    D_num = (theta - 1/2) (x.M x + du.K du + sum w dg.D dg) >= 0,  du = u_{n+1} - u_n

so theta = 1/2 conserves energy (trapezoidal rule) and theta > 1/2 damps the high
frequencies: D_num is reported as its own number (Energies.numerical). The bars add
Delta E_rebar + D_rebar_plastic on the left: the work of their step forces, exactly (any
round-off rest is booked in D_num). The energy
released by damage is booked at g_{n+1} by model.store, where this scheme stores it; for
the rigid laws (threshold, linear softening) the cohesive part of the constraint reactions'
work is stored in the links (model.absorb), split from D_contact as the star Newton does.

Newton. A backtracking line search on the residual norm; damped steps after CYCLE
iterations (active-set cycles); on sticking links, REGULARISATION on the reaction diagonal
(rigid constraints around a vertex are redundant; the residual stays exact), and a stronger
one on all links in contact once a sub-step needs more than a few iterations. The factorisation
is what costs (~75 % of a run): an iteration first tries the one in hand while almost no
link or bar changed state (STALE_CONTRACTION), and the Jacobian is refactorised only when
it changed. A step Newton cannot finish in max_iterations is cut into two half steps,
recursively max_cuts times (the next steps start from the halving the last one needed),
then given LAST_RESORT times the iterations once, before ConvergenceError is raised with
the state left at the start of that sub-step. Parallel: owned rows are owned dof components (dolfinx's layout) and
owned links (vertex owner); off-process contributions go through PETSc's assembly, ghost
values through dolfinx scatters; the answer does not depend on the rank count beyond
solver round-off.
"""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from dolfrag import compat, loads
from dolfrag.interface import laws, models
from dolfrag.interface.contact import contact_friction_projection, link_blocks
from dolfrag.timing import PhaseTimer
from dolfrag.solver import semismooth
from dolfrag.solver.imex import Energies
from dolfrag.solver.semismooth import CYCLE, REGULARISATION, STALL

# Doublings of MUMPS' workspace relaxation tried when a factorisation runs out of it.
MUMPS_RELAXATIONS = 6
# A Newton correction from the factorisation in hand (an older Jacobian of the same step
# length) is taken when it divides the scaled residual by 10 at least; else the Jacobian
# is assembled and factorised at the current iterate. That is tried only while at most
# STALE_STATES of the links and bars are in another state (open, stick, slip; slack,
# taut, yielding) than where it was assembled: a semi-smooth Newton step with a stale
# active set sends the iterates astray (measured on wall-bending-clamped from 20 ms: 228
# iterations and a cut with any state changed, 162 with none, 180 without reuse; over 100
# elastic steps, 19 factorisations at 0.002 and 74 at 0).
STALE_CONTRACTION = 0.1
STALE_STATES = 0.002
# The regularisation of redundant contact rows in a sub-step (a step Newton could not
# finish whole, or one started at the last step's halving), from its REGULARISE_AFTER-th
# iteration on, while the scaled residual is above NEAR: a sticking or closed link whose
# constraint is redundant takes reactions of ~1/REGULARISATION times its residual from a
# Newton step; at 1e-6 Newton cycled between such reactions down to h/16 (measured twice at
# 34-36 ms of wall-bending-clamped: both sub-steps converge from the 5th iteration at 1e-3,
# one still fails from the 10th). Near the solution the active set has settled, and 1e-3
# would only slow the last digits down (a full run stalled at 3e-8 after 30 iterations;
# measured). Not in whole steps: there it slowed the cracking RCCM bar of tests/mpi_theta.py
# from 7-11 to 12-58 iterations a step and made one rank cut a step the other did not.
CYCLE_REGULARISATION = 1e-3
REGULARISE_AFTER = 5
NEAR = 1e-4
# A sub-step that does not converge at the last halving gets LAST_RESORT times the
# iterations once (stick-slip cycles of a few links: one needed 94 iterations at h/16, at
# 37.7 ms of wall-bending-clamped; measured) before ConvergenceError.
LAST_RESORT = 4
# Steps without a halving before the sub-steps are made twice as long again.
RELAX_AFTER = 4

KSP_REASONS = {getattr(PETSc.KSP.ConvergedReason, k): k for k in dir(PETSc.KSP.ConvergedReason)
               if not k.startswith("_")}


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
    reactions dissipated so far on this rank's links (J, J/m in 2D); the caps. unconverged
    and stalled stay 0: a step that does not converge is cut, then raises ConvergenceError."""
    max_iterations: int
    rtol: float
    iterations: int = 0
    cuts: int = 0
    residual: float = 0.0
    unconverged: int = 0
    stalled: int = 0
    contact_dissipated: float = 0.0


def accuracy_time_step(load, end, per_feature=20):
    """A step (s) resolving the load signal (config.Load): its shortest feature
    (loads.shortest_feature: a rise, a decay, a table interval, an oscillation's half period)
    over per_feature, at most end / per_feature. A priori only: it knows nothing of the
    structure's periods or of crack events."""
    return min(loads.shortest_feature(load), end) / per_feature


class Theta:
    """Moreau-Jean integrator with the surface of solver/imex.Imex.

    space, bulk, jump: from space.py, bulk.py, interface/jumps.py; model: an interface model
    (interface/models.py: Elastic springs, or a law with damage, contact and friction);
    load: Function of nodal forces per pascal; pressure: p(t) in Pa; h: time step (s), any
    size (the scheme is unconditionally stable); theta in [1/2, 1]; constrained: flat local
    dof components held at zero (supports.constrained_components, or a boolean mask such as
    Stars.constrained); max_iterations, rtol: Newton's cap and tolerance on the residual
    scaled by the step's largest momentum term; max_cuts: halvings of a step Newton cannot
    finish. Collective.
    """

    def __init__(self, space, bulk, jump, model, load, pressure, h, theta=0.5, constrained=(),
                 max_iterations=30, rtol=1e-10, max_cuts=4, rebars=None):
        if not 0.5 <= theta <= 1.0:
            raise ValueError(f"theta = {theta!r}: must be in [1/2, 1]")
        if not h > 0:
            raise ValueError(f"h = {h!r}: the time step must be > 0 (s)")
        self.space, self.bulk, self.jump, self.model = space, bulk, jump, model
        self.rebars = rebars
        self.pressure, self.h, self.theta = pressure, h, theta
        self.max_cuts = max_cuts
        self._depth = self._deepest = self._calm = 0  # sub-step halvings: the next step's, this step's deepest
        self.comm = space.mesh.comm
        self.timer = PhaseTimer()
        self.u, self.v, self.x, self.force = (compat.Function(space.V) for _ in range(4))
        self.u.name, self.v.name = "displacement", "velocity"
        d = self.d = space.gdim
        n_x = space.n_owned_dofs * d
        self.owned = slice(0, n_x)
        self.m = bulk.m.x.array
        self.load_vector = load.x.array[self.owned].copy()  # N per Pa
        self.t, self.n = 0.0, 0
        self.work = self.numerical = 0.0  # this rank's shares, J
        self.interface = NewtonReport(max_iterations, rtol)
        self.contact = not isinstance(model, models.Elastic)

        links = jump.links
        self.frame = np.concatenate([links.normal[:, None, :], links.tangents], axis=1)  # (n, d, d)
        self.w = links.weight
        self.cA = space.components(links.dof_A[:, None])
        self.cB = space.components(links.dof_B[:, None])
        self.m_link = 0.5 * (self.m[self.cA[:, 0]] + self.m[self.cB[:, 0]])  # kg
        self.r = np.zeros((len(links), d))  # contact reactions of the last step, Pa
        self._g = np.zeros((len(links), d))  # link-frame jumps of u_n, m
        self._x_last, self._h_last = np.zeros(n_x), 0.0  # last velocity increment: Newton's start
        n_r = len(links) * d if self.contact else 0
        start = self.comm.exscan(n_x + n_r) or 0
        constrained = np.asarray(constrained)
        self._fixed = self._owner_flags(np.flatnonzero(constrained) if constrained.dtype == bool else constrained)
        self._frozen = self._frozen_links() if self.contact else np.zeros((0, d), dtype=bool)
        self._x_global = self._global_components(start)
        self._r_global = start + n_x + np.arange(n_r).reshape(-1, d)
        self._build_pattern()
        self._create_solver(n_x + n_r, start)

    # ------------------------------------------------------------------ setup
    def _owner_flags(self, constrained):
        """Flat bool (local comps): held at zero, as the owner of the component says."""
        f = self.force
        f.x.array[:] = 0.0
        f.x.array[np.asarray(constrained, dtype=np.int64)] = 1.0
        compat.scatter_forward(f)
        return f.x.array > 0.5

    def _frozen_links(self):
        """(n_links, d) bool: link components whose jump involves held components only.
        Their reaction is undetermined (a zero column): it is set to 0 with an identity row."""
        free = ~self._fixed
        moves = np.abs(self.frame) > 1e-12  # (n, a, j): component a of the jump reads comp j
        return ~np.any(moves & (free[self.cA] | free[self.cB])[:, None, :], axis=2)

    def _global_components(self, start):
        """Global row of every local dof component (owned and ghost), via a forward scatter."""
        f = self.force
        n_x = self.owned.stop
        f.x.array[:n_x] = start + np.arange(n_x)
        compat.scatter_forward(f)
        return np.rint(f.x.array).astype(np.int64)  # exact: float64 holds integers < 2^53

    def _build_pattern(self):
        """Global rows and columns of every block of the step Jacobian, the entries each
        block drops (held dof components, frozen link components), and the unique CSR
        pattern they add up to. Values come from _values in the same block order."""
        gx, d, fixed = self._x_global, self.d, self._fixed
        n_x = self.owned.stop
        own = np.arange(n_x)
        indptr, cols, _ = self.bulk.K.getValuesCSR()
        k_start = self.bulk.K.getOwnershipRange()[0]
        k_rows = np.repeat(own, np.diff(indptr))
        k_cols = cols.astype(np.int64) - k_start
        if np.any((k_cols < 0) | (k_cols >= n_x)):
            raise RuntimeError("K couples dofs across ranks: it is no longer block-diagonal per owned cell")
        self._k_values = self.bulk.K.getValuesCSR()[2].copy()
        cA, cB = self.cA, self.cB
        blocks = {
            "mass": (gx[own], gx[own], np.zeros(n_x, dtype=bool)),
            "bulk": (gx[k_rows], gx[k_cols], fixed[k_rows] | fixed[k_cols]),
            "springs": _stack([_outer(gx[X], gx[Y], fixed[X], fixed[Y]) for X, Y in ((cB, cB), (cA, cA), (cA, cB),
                                                                                     (cB, cA))]),
        }
        if self.contact:
            gr, frozen = self._r_global, self._frozen
            blocks["impulse"] = _stack([_outer(gx[X], gr, fixed[X], frozen) for X in (cB, cA)])
            blocks["gap"] = _stack([_outer(gr, gx[Y], frozen, fixed[Y]) for Y in (cB, cA)])
            blocks["reaction"] = _outer(gr, gr, frozen, frozen)
            blocks["frozen"] = (gr, gr, np.zeros(gr.shape, dtype=bool))
        if self.rebars is not None:  # each segment once, from the rank counting it
            comps = self.rebars.comps[self.rebars.counted]
            blocks["rebar"] = _outer(gx[comps], gx[comps], fixed[comps], fixed[comps])
        self._blocks = list(blocks)
        rows = np.concatenate([b[0].ravel() for b in blocks.values()])
        cols = np.concatenate([b[1].ravel() for b in blocks.values()])
        self._keep = ~np.concatenate([b[2].ravel() for b in blocks.values()])
        size = self.comm.allreduce(n_x + (self._r_global.size if self.contact else 0))
        key, self._slot = np.unique(rows * size + cols, return_inverse=True)
        self._rows, self._cols = key // size, key % size
        self._size = size

    def _create_solver(self, n_local, start):
        comm = self.comm
        ranges = np.array(comm.allgather(start) + [self._size])
        d_nnz, o_nnz = _preallocation(comm, self._rows, self._cols, ranges)
        A = PETSc.Mat().createAIJ(size=((n_local, self._size), (n_local, self._size)),
                                  nnz=(d_nnz, o_nnz), comm=comm)
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        rowmap, count = np.unique(self._rows, return_counts=True)
        self._csr = (np.r_[0, np.cumsum(count)].astype(PETSc.IntType), self._cols.astype(PETSc.IntType),
                     rowmap.astype(PETSc.IntType))
        ksp = PETSc.KSP().create(comm)
        ksp.setOperators(A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        if self.contact:  # a saddle point with zero pivots: MUMPS' pivoting LU
            pc.setType("lu")
            pc.setFactorSolverType("mumps")
        else:  # W positive definite; symmetric but for the bars' step tangent
            pc.setType("cholesky" if self.rebars is None else "lu")
            # serial: PETSc's own factor solves 4x faster than MUMPS (10 against 40 ms at
            # 72k unknowns, measured); in parallel MUMPS is the distributed one
            pc.setFactorSolverType("petsc" if comm.size == 1 else "mumps")
            if comm.size == 1:
                pc.setFactorOrdering("nd")
        ksp.setOptionsPrefix("dolfrag_theta_")
        ksp.setFromOptions()
        self.A, self.ksp = A, ksp
        self._rhs, self._dz = A.createVecs()
        self._last_values = self._assembled_h = self._factored_status = None

    @property
    def energy_time(self):
        """Time (s) of the energies step() returns: t_{n+1} (imex's are at t_{n+1/2})."""
        return self.t

    # ------------------------------------------------------------------ one step
    def step(self, energies=False):
        """Advance from t_n to t_n + h as 2^k sub-steps, k the halvings the last steps
        needed (each sub-step halved further while Newton needs it, k back down by one
        after RELAX_AFTER steps without a halving): a step Newton cannot finish costs
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
            if self._calm == RELAX_AFTER:
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
            if depth < self.max_cuts:
                self._advance(h / 2, depth + 1)
                self._advance(h / 2, depth + 1)
                return
            try:  # the last resort before giving up: LAST_RESORT times the iterations
                self._substep(h, LAST_RESORT * self.interface.max_iterations, escalate=True)
            except _NotConverged:
                raise ConvergenceError(self.t, h, failure.residual, failure.iterations, failure.reason) from None
        self.interface.cuts += 1
        self._deepest = max(self._deepest, depth)

    def _substep(self, h, cap=None, escalate=False):
        """Newton on (x, r) for one step of length h, at most ``cap`` iterations (default
        max_iterations), with CYCLE_REGULARISATION once it needs many if ``escalate``;
        commits only once converged."""
        step = self._step_data(h)
        x = self._x_last * (h / self._h_last) if self._h_last else np.zeros(self.owned.stop)
        r = np.where(self._frozen, 0.0, self.r) if self.contact else self.r
        point = self._evaluate(step, x, r)
        cap = cap or self.interface.max_iterations
        for iteration in range(1, cap + 1):
            if point.converged:
                break
            self.interface.iterations += 1
            if self._reusable(iteration, h, point):  # the factorisation in hand first
                dx, dr = self._correction(step, point, self._solve(point))
                trial = self._evaluate(step, x + dx, r + dr)
                if trial.converged or trial.error <= STALE_CONTRACTION * point.error:
                    x, r, point = x + dx, r + dr, trial
                    continue
            far = escalate and iteration >= REGULARISE_AFTER and point.error > NEAR
            step.regularisation = CYCLE_REGULARISATION if far else REGULARISATION
            self._factorise(step, point)
            dx, dr = self._correction(step, point, self._solve(point))
            if iteration > CYCLE:  # break active-set cycles: shorter, varying steps (as the star Newton)
                dx, dr = (0.5 ** (1 + iteration % 3) * a for a in (dx, dr))
            x, r, point = self._line_search(step, x, r, point, dx, dr)
        else:
            # stalled on a stick-slip kink within STALL: accepted, as the star Newton does
            if not point.converged and point.error > STALL:
                raise _NotConverged(point.error, cap, f"Newton did not converge in {cap} iterations")
        self.interface.residual = max(self.interface.residual, point.error)
        self._commit(step, point, x, r)

    def _reusable(self, iteration, h, point):
        """Whether Newton's iteration tries the factorisation in hand (STALE_CONTRACTION):
        of the same step length, assembled where every link and bar was in the same state
        (open, stick, slip; slack, taut, yielding) as at ``point``, so that only the smooth
        parts of the Jacobian moved. Collective."""
        if not (iteration <= CYCLE and self._assembled_h == h and self._factored_status is not None):
            return False
        changed = sum(np.count_nonzero(a != b) for a, b in zip(point.status, self._factored_status))
        total = sum(len(a) for a in point.status)
        changed, total = self.comm.allreduce(np.array([changed, total]))
        return changed <= STALE_STATES * total

    def _step_data(self, h):
        """The _Step of an attempt of length h from the current state."""
        th = self.theta
        if hasattr(self.model, "h"):
            self.model.h = h  # the viscous damage update integrates over the step actually taken
        state_n = self.model.state_at(np.arange(len(self.w))) if self.contact else None
        p_theta = th * float(self.pressure(self.t + h)) + (1 - th) * float(self.pressure(self.t))
        step = _Step(h, p_theta, state_n, self.m_link / (th * h * h * self.w), self.m_link / (h * self.w))
        if self.contact:
            step.mu, step.shift = self.model.friction(state_n), self.model.shift(state_n)
            step.cohesion_T = self.model.shear_cohesion(state_n)
        return step

    def _line_search(self, step, x, r, point, dx, dr, backtracks=4):
        """Backtracking on the residual norm; when no shorter step lowers it, the full step
        is taken anyway: a semi-smooth Newton step that changes the active set may raise
        the norm and still be the right one."""
        alpha, full = 1.0, None
        for _ in range(backtracks + 1):
            trial = self._evaluate(step, x + alpha * dx, r + alpha * dr)
            if trial.norm <= (1 - 1e-4 * alpha) * point.norm or trial.converged:
                return x + alpha * dx, r + alpha * dr, trial
            full = full or trial
            alpha /= 2
        return x + dx, r + dr, full

    def _evaluate(self, step, x, r):
        """Scaled residual (momentum rows in N s, link rows h w phi in N s) at (x, r)."""
        h, th, own = step.h, self.theta, self.owned
        xf = self.x.x.array
        xf[own] = x
        compat.scatter_forward(self.x)
        du = h * (self.v.x.array + th * xf)  # u_{n+1} - u_n, every local component
        g_end = self._g + np.einsum("lij,lj->li", self.frame, self.jump(du))
        g_theta = self._g + th * (g_end - self._g)
        point = _Point(g_end, g_theta)
        if self.contact:
            phi_N, phi_T, point.jac, status = contact_friction_projection(
                r[:, 0], r[:, 1:], g_end[:, 0], g_end[:, 1:] - self._g[:, 1:], step.rho, step.rho, step.mu,
                step.shift, step.cohesion_T)
            phi = np.where(self._frozen, 0.0, (h * self.w)[:, None] * np.column_stack([phi_N, phi_T]))
            # Contact keeps g_N >= 0 at the ends of the steps, so g_theta,N >= 0 wherever it
            # holds; round-off makes that +-1e-20 m, and the sign would flip the spring's
            # tangent at random (Newton cycles, refactorisations): the law is read at |g_N|.
            closed = point.jac.dN_drN == 0
            point.status.append(status)
            g_theta = np.column_stack([np.where(closed, np.abs(g_theta[:, 0]), g_theta[:, 0]), g_theta[:, 1:]])
        law = point.law = self._cohesion(g_theta, step.state_n, r[:, 0])
        t = np.column_stack([law.r_N, law.r_T]) - r  # Pa, tension positive
        f = self.force.x.array
        f[:] = self.jump.BT @ (self.w[:, None] * np.einsum("lai,la->li", self.frame, t)).ravel()
        if self.rebars is not None:
            u_n = self.u.x.array
            point.bars = self.rebars.step(u_n, u_n + du)
            end = point.bars.end  # slack, taut, yielding; each segment once, from the rank counting it
            point.status.append(((end.N > 0) + (end.k == 0))[self.rebars.counted])
            f -= self.rebars.step_forces(point.bars, counted_only=True)
        compat.scatter_reverse_add(self.force)
        inertia = self.m[own] * x
        load = h * step.p_theta * self.load_vector
        elastic = h * (self.bulk.K_cells @ (self.u.x.array[own] + th * du[own]))
        interface = h * f[own]
        R_m = np.where(self._fixed[own], 0.0, inertia - load + elastic + interface)
        scale = max(np.abs(a).max(initial=0.0) for a in (inertia, load, elastic, interface))
        F = np.concatenate([R_m, phi.ravel()]) if self.contact else R_m
        error, scale, sq = _global_norms(self.comm, F, scale)
        point.F, point.norm = F, np.sqrt(sq)
        point.error = error / scale if scale > 0 else 0.0
        point.converged = error <= self.interface.rtol * scale
        return point

    def _cohesion(self, g, state_n, r_N=None):
        """models.Cohesion at link-frame jumps g (n, d): the model's, or the elastic springs'.
        r_N (n,) Pa: the contact pressure of the same iterate (>= 0 in compression), for
        the law's internal friction."""
        if self.contact:
            return self.model.cohesion(g[:, 0], g[:, 1:], state_n, r_N)
        n, m = g.shape[0], self.d - 1
        r_N, r_T, k_N, k_T = laws.elastic(g[:, 0], g[:, 1:], self.model.C_N, self.model.C_T)
        zeros = np.zeros((n, m))
        return models.Cohesion(r_N, r_T, np.full(n, k_N), np.broadcast_to(k_T * np.eye(m), (n, m, m)),
                               zeros, zeros, None)

    def _values(self, step, point):
        """Jacobian entries, block by block in _build_pattern's order (before dropping)."""
        h, th, R = step.h, self.theta, self.frame
        law = point.law
        D = link_blocks(law.dr_N_dg_N, law.dr_N_dg_T, law.dr_T_dg_N, law.dr_T_dg_T)
        S = (th * th * h * h * self.w)[:, None, None] * np.matmul(R.transpose(0, 2, 1), np.matmul(D, R))
        values = {"mass": self.m[self.owned], "bulk": th * th * h * h * self._k_values,
                  "springs": np.stack([S, S, -S, -S])}
        if self.contact:
            jac, m_l = point.jac, self.m_link[:, None, None]
            Jg = link_blocks(jac.dN_dgN, jac.dN_dgT, jac.dT_dgN, jac.dT_dgT) / step.rho[:, None, None]
            Jr = link_blocks(jac.dN_drN, jac.dN_drT, jac.dT_drN, jac.dT_drT)
            # Links in contact around a vertex can be redundant constraints (their jumps sum
            # to zero around it; semismooth.REGULARISATION): sticking links in their tangential
            # rows, which get REGULARISATION on the diagonal, and, once cracks run straight
            # through a vertex (facets with one normal on both sides), closed links in their
            # normal rows, where Newton then cycled between reactions of +-1e9 Pa (measured at
            # 35.5 ms of wall-bending-clamped, down to h/16). Once Newton needs more than a
            # few iterations both get CYCLE_REGULARISATION; the normal rows not before, as
            # their large reactions make any regularisation cost iterations (3 against 6 per
            # elastic step, measured). The residual stays exact.
            stick = np.all(jac.dT_drT == 0, axis=(1, 2))
            Jr[:, 1:, 1:] += step.regularisation * stick[:, None, None] * np.eye(self.d - 1)
            if step.regularisation > REGULARISATION:
                Jr[:, 0, 0] += step.regularisation * (jac.dN_drN == 0)
            RT = m_l * R.transpose(0, 2, 1)
            gap = m_l * np.matmul(Jg, R)
            values.update(impulse=np.stack([-RT, RT]), gap=np.stack([gap, -gap]), reaction=m_l * Jr,
                          frozen=np.where(self._frozen, self.m_link[:, None], 0.0))
        if self.rebars is not None:  # d(force)/dx = h d(force)/du_{n+1} theta h: material and geometric
            values["rebar"] = th * h * h * self.rebars.step_blocks(point.bars)
        return np.concatenate([values[k].ravel() for k in self._blocks]) * self._keep

    def _factorise(self, step, point):
        """Assemble the Jacobian at ``point``; PETSc refactorises at the next solve, and not
        at all when no entry changed on any rank (the springs' part depends on h only)."""
        if self.contact or self.rebars is not None or step.h != self._assembled_h:
            values = np.bincount(self._slot, weights=self._values(step, point), minlength=len(self._rows))
            changed = self._last_values is None or not np.array_equal(values, self._last_values)
            if self.comm.allreduce(changed, op=MPI.LOR):
                self.A.zeroEntries()
                self.A.setValuesIJV(*self._csr[:2], values, addv=PETSc.InsertMode.ADD_VALUES, rowmap=self._csr[2])
                self.A.assemble()
                self._last_values = values
        self._assembled_h, self._factored_status = step.h, point.status

    def _correction(self, step, point, dz):
        """(dx, dr): the velocity and reaction parts of a solution dz of the scaled system."""
        n_x = self.owned.stop
        dz[:n_x][self._fixed[self.owned]] = 0.0
        dr = step.sigma[:, None] * dz[n_x:].reshape(-1, self.d) if self.contact else 0.0
        return dz[:n_x], dr

    def _solve(self, point):
        """Solve the last assembled Jacobian against -F(point)."""
        self._rhs.array[:] = -point.F
        for _ in range(MUMPS_RELAXATIONS + 1):
            try:
                self.ksp.solve(self._rhs, self._dz)
            except PETSc.Error as err:
                self._last_values = self._assembled_h = self._factored_status = None
                raise _NotConverged(point.error, self.interface.iterations, f"linear solve failed: {err}") from None
            reason = self.ksp.getConvergedReason()
            if reason >= 0 or not self._mumps_short_of_workspace():
                break
        if reason < 0:
            self._last_values = self._assembled_h = self._factored_status = None  # not reused
            raise _NotConverged(point.error, self.interface.iterations,
                                f"linear solve failed: {KSP_REASONS.get(reason, reason)}")
        return self._dz.array.copy()

    def _mumps_short_of_workspace(self):
        """After a failed factorisation: if MUMPS ran out of workspace (INFOG(1) = -8, -9:
        pivots delayed by nearly redundant constraints, e.g. all links of a rigid law
        sticking at t = 0), double its workspace relaxation ICNTL(14) and return True: the
        next solve factorises anew. Collective."""
        pc = self.ksp.getPC()
        if pc.getFactorSolverType() != "mumps" or pc.getFactorMatrix().getMumpsInfog(1) not in (-8, -9):
            return False
        options = PETSc.Options(self.ksp.getOptionsPrefix())
        options["mat_mumps_icntl_14"] = 2 * options.getInt("mat_mumps_icntl_14", 20)  # MUMPS' default: 20 %
        pc.reset()  # forgets the factor and the operators
        self.ksp.setOperators(self.A)
        self.ksp.setFromOptions()
        return True

    def _commit(self, step, point, x, r):
        """Accept the converged step: fields, damage, energies, time."""
        h, th, own = step.h, self.theta, self.owned
        xf = self.x.x.array
        xf[own] = x
        compat.scatter_forward(self.x)
        du = h * (self.v.x.array + th * xf)
        dg = point.g_end - self._g
        law = point.law
        D = link_blocks(law.dr_N_dg_N, law.dr_N_dg_T, law.dr_T_dg_N, law.dr_T_dg_T)
        spring_work = self.w @ np.einsum("li,lij,lj->l", dg, D, dg)
        self.numerical += (th - 0.5) * (x @ (self.m[own] * x) + du[own] @ (self.bulk.K_cells @ du[own]) + spring_work)
        if self.rebars is not None:
            self.numerical += self._accept_bars(point.bars, du)
        self.work += step.p_theta * self.load_vector @ du[own]
        if self.contact:
            g = point.g_end
            state = self.model.cohesion(g[:, 0], g[:, 1:], step.state_n, r[:, 0]).state
            every = np.arange(len(self.w))[:, None]
            self.model.store(every, state[:, None], np.ones_like(every, dtype=bool), g[:, :1], g[:, None, 1:])
            self._book_reactions(step, r, dg)
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

    def _book_reactions(self, step, r, dg):
        """Split the work of the step's reactions -w r.dg (J/m^2 per link) as the star Newton
        does (semismooth.StarNewton.account): the contact part r~_N = r_N + shift and the
        friction share of r_T is dissipated; the cohesive part of a rigid link's constraint
        (-shift, and the shear cohesion's share of r_T) is stored in it (model.absorb, after
        model.store)."""
        r_N, r_T = r[:, 0], r[:, 1:]
        pressed = np.maximum(r_N + step.shift, 0.0)
        radius = step.mu * pressed + step.cohesion_T
        friction_share = np.divide(step.mu * pressed, radius, out=np.ones_like(radius), where=radius > 0)
        slip_work = np.sum(r_T * dg[:, 1:], axis=1)
        self.interface.contact_dissipated -= self.w @ ((r_N + step.shift) * dg[:, 0] + friction_share * slip_work)
        self.model.absorb(-(-step.shift * dg[:, 0] + (1 - friction_share) * slip_work))

    def _energies(self):
        own = self.owned
        u_all = self.u.x.array
        v, u = self.v.x.array[own], u_all[own]
        g = self._g
        local = np.array([0.5 * self.m[own] @ v**2, 0.5 * u @ (self.bulk.K_cells @ u),
                          self.w @ self.model.stored_energy(g[:, 0], g[:, 1:]),
                          self.w @ self.model.dissipated(), self.interface.contact_dissipated, self.work,
                          np.count_nonzero(self.model.broken()), self.numerical,
                          self.rebars.elastic_energy(u_all) if self.rebars else 0.0,
                          self.rebars.dissipated if self.rebars else 0.0])
        total = self.comm.allreduce(local, op=MPI.SUM)
        return Energies(*total[:6], int(total[6]), total[7], rebar=total[8], plastic=total[9])


class _Step:
    """What one step attempt of length h keeps fixed: the lagged state, friction, scalings."""

    def __init__(self, h, p_theta, state_n, rho, sigma):
        self.h, self.p_theta, self.state_n, self.rho, self.sigma = h, p_theta, state_n, rho, sigma
        self.mu = self.shift = self.cohesion_T = None
        self.regularisation = REGULARISATION  # on the redundant rows of links in contact (_values)


class _Point:
    """The step's jumps, cohesion and contact Jacobian at one Newton iterate."""

    def __init__(self, g_end, g_theta):
        self.g_end, self.g_theta = g_end, g_theta
        self.law = self.jac = self.F = None
        self.bars = None  # the bars' rebar.CableStep to u_{n+1}, with rebars
        self.status = []  # the links' contact states and the bars' regimes (int arrays)
        self.norm = self.error = 0.0
        self.converged = False


def _outer(rows, cols, drop_rows, drop_cols):
    """Entries (rows[l, i], cols[l, j]) of a d x d block per link: rows, columns (n, d, d) and
    whether each entry is dropped (a held dof or frozen link component on either side)."""
    shape = rows.shape + cols.shape[1:]
    return (np.broadcast_to(rows[:, :, None], shape), np.broadcast_to(cols[:, None, :], shape),
            drop_rows[:, :, None] | drop_cols[:, None, :])


def _stack(blocks):
    """Several _outer blocks as one (k, n, d, d) block."""
    return tuple(np.stack(parts) for parts in zip(*blocks))


def _global_norms(comm, F, scale):
    """(max |F|, max scale, sum F^2) over all ranks. Collective."""
    local = np.array([np.abs(F).max(initial=0.0), scale])
    largest = np.empty(2)
    comm.Allreduce(local, largest, op=MPI.MAX)
    return largest[0], largest[1], comm.allreduce(float(F @ F), op=MPI.SUM)


def _preallocation(comm, rows, cols, ranges):
    """Nonzeros per owned row in the diagonal and off-diagonal blocks, for entries
    (rows, cols) given by any rank (each rank sends the owners theirs). Collective."""
    rank = comm.rank
    if comm.size > 1:
        owner = np.searchsorted(ranges, rows, side="right") - 1
        got = comm.alltoall([np.stack([rows[owner == k], cols[owner == k]]) for k in range(comm.size)])
        pairs = np.unique(np.concatenate(got, axis=1), axis=1)
        rows, cols = pairs
    start, stop = ranges[rank], ranges[rank + 1]
    local = rows - start
    diagonal = (cols >= start) & (cols < stop)
    n = stop - start
    return (np.bincount(local[diagonal], minlength=n).astype(PETSc.IntType),
            np.bincount(local[~diagonal], minlength=n).astype(PETSc.IntType))
