"""The theta step's problem at one Newton iterate: residual and Jacobian entries.

A step t_n -> t_{n+1} = t_n + h solves for the velocity increment x = v_{n+1} - v_n of
every dof component and, where the interface has contact, the link reactions r (link
frame, normal first; Pa, r_N >= 0 pushes the faces apart), the mean force density of the
step's contact impulse:

    M x = h f_theta + h B^T w R^T r
    u_{n+1} = u_n + h (theta v_{n+1} + (1 - theta) v_n) = u_n + h (v_n + theta x)
    f_theta = l_theta - K u_theta - B^T w R^T t(g_theta)
    phi(r, g_{n+1}, g_{n+1} - g_n) = 0

u_theta = theta u_{n+1} + (1 - theta) u_n; g = R B u the link jumps in the link frames R
(interface/jumps.py, links.py); w the link weights; t the cohesive traction of the model
with its damage lagged by one step (interface/models.py: each step problem is monotone),
plus the bars' step forces C^T (N m) when there are rebars (rebar.py: the mean force over
the step's strain path along the mean chord, a discrete gradient; its tangent in u_{n+1},
material and geometric, not symmetric, joins the matrix);
l_theta = theta l(t_{n+1}) + (1 - theta) l(t_n) the nodal forces of the load (for a
uniform pressure l(t) = p(t) times the load vector; loads/nodal.py); phi the
Alart-Curnier projection (interface/contact.py): Signorini on the end-of-step gap, Coulomb
with mu(state_n) on the step's slip, no penalty. With linear forces Newton's matrix is
W = M + theta^2 h^2 (K + B^T w D B), D the link stiffness: a global sparse operator (K
couples the copies of a cell, the links the copies of a vertex), so every Newton iteration
is one solve (solver/sparse_system.py) of the generalised Jacobian of (x, r) together. The
reaction unknowns and rows are scaled per link so that every entry is of the order of the
link's mass m_l (r = m_l / (h w) r~, rows times h w, augmentation rho = m_l / (theta h^2 w)),
which keeps the pivoting of the saddle-point system sound.

Parallel: owned rows are owned dof components (dolfinx's layout) and owned links (vertex
owner); ghost values go through dolfinx scatters.
"""
import numpy as np
from mpi4py import MPI

from dolfrag import compat
from dolfrag.interface import laws, models
from dolfrag.interface.contact import contact_friction_projection, link_blocks


class Step:
    """What one step attempt of length h keeps fixed: the lagged state, friction, scalings,
    the jumps g_n (n, d) m of the step's start, and the regularisation of the redundant rows
    of links in contact (ThetaResidual.values)."""

    def __init__(self, h, load_theta, state_n, rho, sigma, g_n, regularisation):
        self.h, self.load_theta, self.state_n, self.rho, self.sigma = h, load_theta, state_n, rho, sigma
        self.g_n, self.regularisation = g_n, regularisation
        self.mu = self.shift = self.cohesion_T = None


class Point:
    """The step's jumps, cohesion and contact Jacobian at one Newton iterate."""

    def __init__(self, g_end, g_theta):
        self.g_end, self.g_theta = g_end, g_theta
        self.law = self.jac = self.F = None
        self.bars = None  # the bars' rebar.CableStep to u_{n+1}, with rebars
        self.status = []  # the links' contact states and the bars' regimes (int arrays)
        self.norm = self.error = 0.0
        self.converged = False


class ThetaResidual:
    """The step problem on space, bulk, jump (space.py, bulk.py, interface/jumps.py) with an
    interface model, the nodal load (loads/nodal.py), theta, the held components
    ``constrained`` (flat local indices or a boolean mask), the bars (rebar/cables.Rebars or None)
    and the state u, v (Functions: u_n, v_n, owned by the integrator); rtol: the tolerance
    on the scaled residual; regularisation: on the reaction diagonal of sticking links, whose
    constraints around a vertex are redundant; contact: the links have contact and
    friction, their reactions unknowns of the step (every law but linear springs:
    interface/models.Law.springs). Collective."""

    def __init__(self, space, bulk, jump, model, load, theta, constrained, rebars, u, v, rtol, regularisation,
                 contact):
        self.space, self.bulk, self.jump, self.model, self.rebars = space, bulk, jump, model, rebars
        self.theta, self.u, self.v, self.rtol, self.regularisation = theta, u, v, rtol, regularisation
        self.comm = space.mesh.comm
        self.x, self.force = compat.Function(space.V), compat.Function(space.V)
        d = self.d = space.gdim
        n_x = space.n_owned_dofs * d
        self.owned = slice(0, n_x)
        self.m = bulk.m.x.array
        self.load = load
        self.contact = contact
        links = jump.links
        self.frame = links.frames()  # (n, d, d)
        self.w = links.weight
        self.cA = space.components(links.dof_A[:, None])
        self.cB = space.components(links.dof_B[:, None])
        self.m_link = 0.5 * (self.m[self.cA[:, 0]] + self.m[self.cB[:, 0]])  # kg
        self.n_r = len(links) * d if self.contact else 0
        self.start = self.comm.exscan(n_x + self.n_r) or 0  # this rank's first global row
        constrained = np.asarray(constrained)
        self.fixed = self._owner_flags(np.flatnonzero(constrained) if constrained.dtype == bool else constrained)
        self.frozen = self._frozen_links() if self.contact else np.zeros((0, d), dtype=bool)
        self._x_global = self._global_components()
        self._r_global = self.start + n_x + np.arange(self.n_r).reshape(-1, d)
        self._k_values = self.bulk.K.getValuesCSR()[2].copy()

    # ------------------------------------------------------------------ layout
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
        free = ~self.fixed
        moves = np.abs(self.frame) > 1e-12  # (n, a, j): component a of the jump reads comp j
        return ~np.any(moves & (free[self.cA] | free[self.cB])[:, None, :], axis=2)

    def _global_components(self):
        """Global row of every local dof component (owned and ghost), via a forward scatter."""
        f = self.force
        n_x = self.owned.stop
        f.x.array[:n_x] = self.start + np.arange(n_x)
        compat.scatter_forward(f)
        return np.rint(f.x.array).astype(np.int64)  # exact: float64 holds integers < 2^53

    def blocks(self):
        """{name: (global rows, global columns, dropped)} of every block of the step
        Jacobian, in the order of ``values``: dropped entries are those of held dof
        components and frozen link components."""
        gx, fixed = self._x_global, self.fixed
        n_x = self.owned.stop
        own = np.arange(n_x)
        indptr, cols, _ = self.bulk.K.getValuesCSR()
        k_start = self.bulk.K.getOwnershipRange()[0]
        k_rows = np.repeat(own, np.diff(indptr))
        k_cols = cols.astype(np.int64) - k_start
        if np.any((k_cols < 0) | (k_cols >= n_x)):
            raise RuntimeError("K couples dofs across ranks: it is no longer block-diagonal per owned cell")
        cA, cB = self.cA, self.cB
        blocks = {
            "mass": (gx[own], gx[own], np.zeros(n_x, dtype=bool)),
            "bulk": (gx[k_rows], gx[k_cols], fixed[k_rows] | fixed[k_cols]),
            "springs": _stack([_outer(gx[X], gx[Y], fixed[X], fixed[Y]) for X, Y in ((cB, cB), (cA, cA), (cA, cB),
                                                                                     (cB, cA))]),
        }
        if self.contact:
            gr, frozen = self._r_global, self.frozen
            blocks["impulse"] = _stack([_outer(gx[X], gr, fixed[X], frozen) for X in (cB, cA)])
            blocks["gap"] = _stack([_outer(gr, gx[Y], frozen, fixed[Y]) for Y in (cB, cA)])
            blocks["reaction"] = _outer(gr, gr, frozen, frozen)
            blocks["frozen"] = (gr, gr, np.zeros(gr.shape, dtype=bool))
        if self.rebars is not None:  # each segment once, from the rank counting it
            comps = self.rebars.comps[self.rebars.counted]
            blocks["rebar"] = _outer(gx[comps], gx[comps], fixed[comps], fixed[comps])
        return blocks

    # ------------------------------------------------------------------ one iterate
    def step_data(self, h, t, g_n, regularisation):
        """The Step of an attempt of length h from time t (s), jumps g_n; its load forces
        load_theta (owned components, N) theta l(t + h) + (1 - theta) l(t)."""
        th = self.theta
        if hasattr(self.model, "h"):
            self.model.h = h  # the viscous damage update integrates over the step actually taken
        state_n = self.model.state_at(np.arange(len(self.w))) if self.contact else None
        load_theta = np.zeros(self.owned.stop)
        load_theta[self.load.rows] = th * self.load.forces(t + h) + (1 - th) * self.load.forces(t)
        step = Step(h, load_theta, state_n, self.m_link / (th * h * h * self.w), self.m_link / (h * self.w), g_n,
                    regularisation)
        if self.contact:
            step.mu, step.shift = self.model.friction(state_n), self.model.shift(state_n)
            step.cohesion_T = self.model.shear_cohesion(state_n)
        return step

    def displacement_increment(self, step, x):
        """u_{n+1} - u_n (m) on every local component for the owned velocity increments x."""
        xf = self.x.x.array
        xf[self.owned] = x
        compat.scatter_forward(self.x)
        return step.h * (self.v.x.array + self.theta * xf)

    def evaluate(self, step, x, r):
        """Scaled residual (momentum rows in N s, link rows h w phi in N s) at (x, r)."""
        h, th, own, g_n = step.h, self.theta, self.owned, step.g_n
        du = self.displacement_increment(step, x)  # u_{n+1} - u_n, every local component
        g_end = g_n + np.einsum("lij,lj->li", self.frame, self.jump(du))
        g_theta = g_n + th * (g_end - g_n)
        point = Point(g_end, g_theta)
        if self.contact:
            phi_N, phi_T, point.jac, status = contact_friction_projection(
                r[:, 0], r[:, 1:], g_end[:, 0], g_end[:, 1:] - g_n[:, 1:], step.rho, step.rho, step.mu,
                step.shift, step.cohesion_T)
            phi = np.where(self.frozen, 0.0, (h * self.w)[:, None] * np.column_stack([phi_N, phi_T]))
            # Contact keeps g_N >= 0 at the ends of the steps, so g_theta,N >= 0 wherever it
            # holds; round-off makes that +-1e-20 m, and the sign would flip the spring's
            # tangent at random (Newton cycles, refactorisations): the law is read at |g_N|.
            closed = point.jac.dN_drN == 0
            point.status.append(status)
            g_theta = np.column_stack([np.where(closed, np.abs(g_theta[:, 0]), g_theta[:, 0]), g_theta[:, 1:]])
        law = point.law = self.cohesion(g_theta, step.state_n, r[:, 0])
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
        load = h * step.load_theta
        elastic = h * (self.bulk.K_cells @ (self.u.x.array[own] + th * du[own]))
        interface = h * f[own]
        R_m = np.where(self.fixed[own], 0.0, inertia - load + elastic + interface)
        scale = max(np.abs(a).max(initial=0.0) for a in (inertia, load, elastic, interface))
        F = np.concatenate([R_m, phi.ravel()]) if self.contact else R_m
        error, scale, sq = _global_norms(self.comm, F, scale)
        point.F, point.norm = F, np.sqrt(sq)
        point.error = error / scale if scale > 0 else 0.0
        point.converged = error <= self.rtol * scale
        return point

    def cohesion(self, g, state_n, r_N=None):
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

    def values(self, step, point):
        """{block name: Jacobian entries} at ``point``, shaped as ``blocks`` (dropped ones included)."""
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
            # to zero around it; the base regularisation): sticking links in their tangential
            # rows, which get the base regularisation on the diagonal, and, once cracks run straight
            # through a vertex (facets with one normal on both sides), closed links in their
            # normal rows, where Newton then cycled between reactions of +-1e9 Pa (measured at
            # 35.5 ms of wall-bending-clamped, down to h/16). Once Newton needs more than a
            # few iterations both get a stronger one; the normal rows not before, as
            # their large reactions make any regularisation cost iterations (3 against 6 per
            # elastic step, measured). The residual stays exact.
            stick = np.all(jac.dT_drT == 0, axis=(1, 2))
            Jr[:, 1:, 1:] += step.regularisation * stick[:, None, None] * np.eye(self.d - 1)
            if step.regularisation > self.regularisation:
                Jr[:, 0, 0] += step.regularisation * (jac.dN_drN == 0)
            RT = m_l * R.transpose(0, 2, 1)
            gap = m_l * np.matmul(Jg, R)
            values.update(impulse=np.stack([-RT, RT]), gap=np.stack([gap, -gap]), reaction=m_l * Jr,
                          frozen=np.where(self.frozen, self.m_link[:, None], 0.0))
        if self.rebars is not None:  # d(force)/dx = h d(force)/du_{n+1} theta h: material and geometric
            values["rebar"] = th * h * h * self.rebars.step_blocks(point.bars)
        return values

    def correction(self, step, dz):
        """(dx, dr): the velocity and reaction parts of a solution dz of the scaled system."""
        n_x = self.owned.stop
        dz[:n_x][self.fixed[self.owned]] = 0.0
        dr = step.sigma[:, None] * dz[n_x:].reshape(-1, self.d) if self.contact else 0.0
        return dz[:n_x], dr


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
