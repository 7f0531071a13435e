"""Semi-smooth Newton for the nonsmooth `imex` interface step, star by star (DESIGN.md §4).

With lumped mass and nodal interface quadrature the implicit part of a step splits into
one problem per vertex star. For the stars of one size, batched, the unknowns of a star
are its velocity increments ``x`` (q = copies x gdim) and, per link, the contact
reactions ``r = (r_N, r_T)`` in the link frame (r_N >= 0 pushes the faces apart):

    R_m = m x - h f + h BR^T (weight (t_coh(gbar) - r)) = 0
    phi(r, g_end, dg_T) = 0                     Alart-Curnier, interface/contact.py

    gbar  = g_n + h/4 BR x            the cohesive springs at (u_{n+1} + 2 u_n + u_{n-1}) / 4,
                                      which conserves energy while the law is elastic
    g_end = g_n + h BR (v_- + x)      non-penetration and slip at the end of the step

BR maps a star's components to the jumps of its links in each link's frame (normal first,
then tangents); f = f_ext - K u_n. The cohesive traction uses the damage at the start of
the step (lagged by one step, interface/models.py): with an implicit, softening traction
stiffer than the star's mass term (m + h^2/4 w dr/dg indefinite) Newton cycled between
opening and contact (period-20 cycles, measured) or found one of several solutions,
whichever round-off chose. Lagged, every star problem is monotone: Newton is exact on its
piecewise-linear pieces and stops in 4-10 iterations. Friction uses the law's coefficient
at the start of the step (mu (1 - beta_n) for RCCM), so its derivative is not needed.

Each star stops on its own. A star that Newton has not solved after FALLBACK iterations
(active-set wandering, measured on rigid laws with friction) is handed to projected
Gauss-Seidel sweeps over its links, still exact and local; a star still above STALL after
max_iterations is counted as unconverged, and the runner stops with ConvergenceError.
"""
import numpy as np
from mpi4py import MPI

from dolfrag.interface.contact import STICK, contact_friction_projection, link_blocks

# A link whose two copies are both prescribed (between supported copies, or in a patch
# test) has a known jump, so Newton cannot move it and its contact rows would be singular.
# Its reaction is the projection itself, taken with the augmentation FROZEN times larger
# (so a prescribed opening releases the constraint at once) and iterated as a fixed
# point: identity rows in the Jacobian.
FROZEN = 1e6

# Rigid constraints around a vertex are redundant: the jumps of an interior star sum to zero
# around the vertex, so when every link sticks (a rigid threshold or linear-softening star,
# or a frictional contact ring) the constraint rows lose rank and the exact Jacobian is
# singular. The Newton matrix gets REGULARISATION on the reaction diagonal (d phi / d r) of
# sticking links only (elsewhere Newton stays exact: on a piecewise-linear piece it lands in
# one step, which a cold start needs):
# the residual stays exact, so the solution does too; Newton converges at a rate of about
# REGULARISATION per iteration instead of exactly, and picks one of the equivalent
# reactions in the redundant directions (they do no work: same motion, same energies).
REGULARISATION = 1e-6

# Full Newton steps for this many iterations, then backtracking on the scaled residual:
# a semi-smooth Newton can cycle between active sets of contact and friction (measured on
# the rigid laws, and on linear softening with friction: period-4 cycles of a star whose
# sprung link toggles between open and slipping); halving the step (at most SHORTEST
# times) from the last point that lowered the residual breaks the cycle.
CYCLE = 20
SHORTEST = 6

# Where the semi-smooth Newton stalls (a link sitting on the kink between stick and slip,
# measured on the rigid laws with friction: residuals stuck at 1e-10 .. 2e-9 of the star's
# reactions), a star within STALL is accepted from FALLBACK iterations on.
STALL = 1e-8

# Newton iterations after which the stars still unconverged alternate projected Gauss-Seidel
# sweeps (_gauss_seidel, see SWEEPS) with full Newton steps from their result (which
# finish the job once Gauss-Seidel has found the active set).
FALLBACK = 30

# Projected Gauss-Seidel sweeps in the first fallback call, doubled at each call up to
# MAX_SWEEPS: Newton usually finishes after a few hundred, but with friction mu = 0.6 the
# sweeps crawl (measured: up to 14,455 before the reactions settle, sound-bar with linear
# softening), and a fixed budget of 300 let each Newton polish undo them.
SWEEPS = 300
MAX_SWEEPS = 20000

# Relative size below which a star's own scales give way to the step's largest (see solve).
FLOOR = 1e-6


def step_stiffness(links, m, h, gdim):
    """The step's own stiffness of each link (Pa/m): m / (h^2 weight), m the mean lumped
    mass (kg) of its two copies, from the flat mass m; h the step (s). It scales the
    augmentation of the contact projections, and bounds the springs a star can take."""
    m_pair = 0.5 * (m[gdim * links.dof_A] + m[gdim * links.dof_B])
    return m_pair / (h * h * links.weight)


class StarNewton:
    """Nonsmooth step solver for the owned stars.

    stars: interface/stars.Stars; links: the link table; model: an interface model
    (interface/models.py) giving the cohesive law, its state and friction; m: flat lumped
    mass of every local dof component (kg); h: time step (s).
    """

    def __init__(self, stars, jump, model, m, h, max_iterations=100, rtol=1e-10):
        links = jump.links
        self.stars, self.jump, self.model, self.h = stars, jump, model, h
        self.max_iterations, self.rtol = max_iterations, rtol
        d = stars.gdim
        frame = np.concatenate([links.normal[:, None, :], links.tangents], axis=1)  # (n, d, d)
        self._frame = frame
        self.r = np.zeros((len(links), d))  # contact reactions, link frame, Pa
        self._all_links = np.arange(len(links))
        k_step = step_stiffness(links, m, h, d)
        self.reaction = np.zeros_like(m)  # N: on the prescribed components of the stars
        self.contact_dissipated = 0.0  # J (J/m in 2D), owned links
        self.iterations = 0
        self.unconverged = 0
        self.residual = 0.0  # largest final scaled residual of the step's stars
        self._data = []
        self._cache = []
        for grp in stars.groups:
            n_s, q = grp.comps.shape
            k, L = q // d, grp.links.shape[1]
            s, l = np.nonzero(grp.valid)
            R = frame[grp.links[s, l]]
            BR = np.zeros((n_s, L, d, k, d))
            BR[s, l, :, grp.slot_B[s, l], :] = R
            BR[s, l, :, grp.slot_A[s, l], :] = -R
            weight = np.where(grp.valid, links.weight[grp.links], 0.0)
            m_star = m[grp.comps]
            rho = np.ones((n_s, L))
            rho[s, l] = k_step[grp.links[s, l]]
            fixed = stars.fixed(grp)
            held = fixed.reshape(n_s, k, d).all(axis=2)
            frozen = np.zeros((n_s, L), dtype=bool)  # both copies prescribed
            frozen[s, l] = held[s, grp.slot_A[s, l]] & held[s, grp.slot_B[s, l]]
            self._data.append((BR.reshape(n_s, L * d, q), weight, m_star, rho, fixed, frozen))
            # last Jacobian inverse of each star, reused while its damage does not change
            self._cache.append((np.zeros((n_s, q + L * d, q + L * d)), np.zeros(n_s, dtype=bool)))

    def solve(self, f, g_n, v, out):
        """Velocity increments of every owned star into out[star comps].

        f: flat f_ext - K u_n on local components (ghosts updated), N;
        g_n (n_links, gdim): link jumps of u_n (m), global frame; v: flat v_{n-1/2} (m/s);
        out: flat, holding on entry the increments of the prescribed components (m/s).
        Updates the model's state (damage), the contact reactions and the reactions of
        the prescribed components (``reaction``, N).
        """
        frame = self._frame
        g_loc = np.einsum("lij,lj->li", frame, g_n)
        dg_loc = self.h * np.einsum("lij,lj->li", frame, self.jump(v))
        state_n = self.model.state_at(self._all_links)
        self._mu, self._shift = self.model.friction(state_n), self.model.shift(state_n)
        self._cohesion_T = self.model.shear_cohesion(state_n)
        # A star far from the action (a millionth of the largest force or traction of this
        # rank's step) is converged at round-off of the whole problem, not of its own tiny terms.
        # (global, so that 1 and N ranks stop every star alike)
        force = np.abs(f).max(initial=0.0)  # N, and as a traction on the largest link (Pa)
        mine = np.array([self.h * force, max(np.abs(self.r).max(initial=0.0), np.abs(self._shift).max(initial=0.0),
                                             force / max(self.jump.links.weight.max(initial=0.0), 1e-300))])
        largest = np.empty(2)
        self.stars.comm.Allreduce(mine, largest, op=MPI.MAX)
        self._floor_m, self._floor_c = FLOOR * largest
        self.iterations = self.unconverged = 0
        self.residual = 0.0
        for grp, data, cache in zip(self.stars.groups, self._data, self._cache):
            x = self._solve_group(grp, data, cache, self.h * f[grp.comps], out[grp.comps], g_loc[grp.links],
                                  dg_loc[grp.links])
            out[grp.comps] = x

    def account(self, g_before, g_after):
        """Book the work the reactions of this step did, given the global-frame jumps
        g_{n-1} and g_{n+1} (n_links, gdim): -sum weight r . (g_{n+1} - g_{n-1}) / 2, its
        share of the discrete energy balance (solver/imex.py). The part of the contact
        reaction r~_N = r_N + shift and the friction mu r~_N is dissipated by contact; the
        cohesive part (-shift, and the shear cohesion's share of r_T) is stored in the
        rigid links of the model (model.absorb)."""
        dg = np.einsum("lij,lj->li", self._frame, g_after - g_before)
        r_N, r_T = self.r[:, 0], self.r[:, 1:]
        pressed = np.maximum(r_N + self._shift, 0.0)
        radius = self._mu * pressed + self._cohesion_T
        friction_share = np.divide(self._mu * pressed, radius, out=np.ones_like(radius), where=radius > 0)
        slip_work = np.sum(r_T * dg[:, 1:], axis=1)
        weight = self.jump.links.weight
        self.contact_dissipated -= 0.5 * weight @ ((r_N + self._shift) * dg[:, 0] + friction_share * slip_work)
        self.model.absorb(-0.5 * (-self._shift * dg[:, 0] + (1 - friction_share) * slip_work))

    def _solve_group(self, grp, data, cache, rhs, x_fixed, g_n, dg_pred):
        """Newton on the group's stars, each stopping on its own once its scaled residual
        is below rtol; a star still above STALL after max_iterations is counted unconverged.

        With the damage lagged, a star's Jacobian depends only on its contact pattern and
        beta_n: the first step of a star whose beta_n has not changed uses its last
        Jacobian's inverse, which solves its piecewise-linear problem exactly when the
        pattern has not changed either (the residual check decides)."""
        BR_all, weight_all, m_all, rho_all, fixed_all, frozen_all = data
        inverse, cached = cache
        h, d = self.h, self.stars.gdim
        n_s, q = rhs.shape
        L = grp.links.shape[1]
        if L == 0:  # lone copies (a corner of a single cell): no interface, explicit
            self.reaction[grp.comps] = np.where(fixed_all, m_all * x_fixed - rhs, 0.0) / h
            return np.where(fixed_all, x_fixed, rhs / m_all)
        x = np.where(fixed_all, x_fixed, 0.0)  # Newton never moves the prescribed components
        # reactions start from zero, not from the last step: around a rigid star they are
        # determined only up to self-equilibrated rings (see REGULARISATION), which a warm
        # start carried from step to step until they choked the friction cones (measured:
        # threshold and linear-softening runs then failed to converge; cold, they complete)
        r = np.zeros(grp.links.shape + (d,))
        state_n = self.model.state_at(grp.links)
        # padding slots: no cohesion and no friction, so their rows are the identity (open,
        # r = 0); a cohesive cone there made them stick at rest, a zero row in 3D stars
        mu, shift, cohesion_T = (np.where(grp.valid, a[grp.links], 0.0)
                                 for a in (self._mu, self._shift, self._cohesion_T))
        todo = np.arange(n_s)
        for iteration in range(1, self.max_iterations + 1):
            BR, w, m, rho, fixed = BR_all[todo], weight_all[todo], m_all[todo], rho_all[todo], fixed_all[todo]
            frozen = frozen_all[todo]
            valid = grp.valid[todo]
            Bx = np.matmul(BR, x[todo][:, :, None])[:, :, 0].reshape(-1, L, d)
            gbar = g_n[todo] + 0.25 * h * Bx
            slip = dg_pred[todo] + h * Bx
            g_end = g_n[todo] + slip
            g_end[..., 0] = np.where(valid, g_end[..., 0], 1.0)  # padding: open, so r stays 0
            rt = r[todo]
            law = self.model.cohesion(gbar[..., 0].ravel(), gbar[..., 1:].reshape(-1, d - 1),
                                      state_n[todo].ravel(), rt[..., 0].ravel())
            r_coh = np.concatenate([law.r_N[:, None], law.r_T], axis=1).reshape(-1, L, d)
            t = (r_coh - rt) * w[..., None]
            interface_force = h * np.matmul(t.reshape(-1, 1, L * d), BR)[:, 0]
            R_m = m * x[todo] - rhs[todo] + interface_force
            reaction = np.where(fixed, R_m / h, 0.0)
            R_m[fixed] = 0.0
            phi_N, phi_T, jac, status = contact_friction_projection(
                rt[..., 0].ravel(), rt[..., 1:].reshape(-1, d - 1), g_end[..., 0].ravel(),
                slip[..., 1:].reshape(-1, d - 1), *(2 * [np.where(frozen, FROZEN * rho, rho).ravel()]),
                mu[todo].ravel(), shift[todo].ravel(),
                cohesion_T[todo].ravel())
            phi = np.concatenate([phi_N[:, None], phi_T], axis=1).reshape(-1, L, d)
            scale_m = np.maximum(np.abs(rhs[todo]), np.maximum(np.abs(m * x[todo]), np.abs(interface_force))).max(axis=1)
            # the terms phi is made of, so that their cancellation (a sticking link moving
            # with its neighbours: slip = dg_pred + h B x ~ 0) sets no false floor
            terms = np.abs(g_n[todo]) + np.abs(dg_pred[todo]) + h * np.abs(Bx)
            scale_c = np.abs(rt).max(axis=(1, 2)) + (rho[..., None] * terms * valid[..., None]).max(axis=(1, 2))
            scaled = np.maximum(_ratio(np.abs(R_m).max(axis=1), np.maximum(scale_m, self._floor_m)),
                                _ratio(np.abs(phi).max(axis=(1, 2)), np.maximum(scale_c, self._floor_c)))
            done = scaled <= (self.rtol if iteration < FALLBACK else STALL)  # stalled: accept
            self.residual = max(self.residual, scaled[done].max(initial=0.0))
            g_mid = g_n[todo] + 0.5 * slip  # (g_n + g_{n+1}) / 2, where the energy is stored
            self.model.store(grp.links[todo][done], law.state.reshape(-1, L)[done], valid[done],
                             g_mid[done][..., 0], g_mid[done][..., 1:])
            self.reaction[grp.comps[todo[done]]] = reaction[done]
            self.iterations = max(self.iterations, iteration)
            if done.all():
                break
            keep = ~done
            R = np.concatenate([R_m[keep], phi[keep].reshape(-1, L * d)], axis=1)
            todo = todo[keep]
            if iteration >= FALLBACK and (iteration - FALLBACK) % 2 == 0:  # Newton wanders: Gauss-Seidel, then polish
                x[todo], r[todo] = self._gauss_seidel(
                    BR[keep], w[keep], m[keep], fixed[keep], valid[keep], law, keep, L, rhs[todo], x[todo],
                    r[todo], g_n[todo], dg_pred[todo], mu[todo], shift[todo], cohesion_T[todo],
                    sweeps=min(SWEEPS * 2 ** ((iteration - FALLBACK) // 2), MAX_SWEEPS))
                continue
            newton = np.ones(len(todo), dtype=bool)  # stars taking a Newton step from here
            if CYCLE < iteration < FALLBACK:  # a shorter step along the last direction
                if iteration == CYCLE + 1:  # backtracking state, made only for the rare stars that get here:
                    # the last point that lowered each star's residual, and the Newton step taken from it
                    base_x, base_r, base_scaled = x.copy(), r.copy(), np.full(n_s, np.inf)
                    direction, halvings = np.zeros((n_s, q + L * d)), np.zeros(n_s, dtype=int)
                back = (scaled[keep] >= base_scaled[todo]) & (halvings[todo] < SHORTEST)
                newton = ~back
                b = todo[back]
                halvings[b] += 1
                alpha = 0.5 ** halvings[b][:, None]
                x[b] = base_x[b] + alpha * direction[b, :q]
                r[b] = base_r[b] + (alpha * direction[b, q:]).reshape(-1, L, d)
                a = todo[newton]
                base_x[a], base_r[a], base_scaled[a], halvings[a] = x[a], r[a], scaled[keep][newton], 0
            reuse = cached[todo] if iteration == 1 else np.zeros(len(todo), dtype=bool)
            fresh = ~reuse & newton
            if fresh.any():
                new = keep.copy()
                new[keep] = fresh
                stick = (status == STICK).reshape(-1, L)[new]
                J = self._jacobian(BR[new], w[new], m[new], fixed[new], frozen[new], stick, law, jac, new, L)
                inverse[todo[fresh]] = np.linalg.inv(J)
                cached[todo[fresh]] = True
            a = todo[newton]
            delta = -np.matmul(inverse[a], R[newton][:, :, None])[:, :, 0]
            if CYCLE < iteration < FALLBACK:
                direction[a] = delta
            x[a] += delta[:, :q]
            r[a] += delta[:, q:].reshape(-1, L, d)
        else:
            # a star stalled at a stick-slip kink within STALL of its scales is accepted
            self.unconverged += np.count_nonzero(scaled[keep] > STALL)
            self.residual = max(self.residual, scaled[keep].max())
            self.model.store(grp.links[todo], law.state.reshape(-1, L)[keep], grp.valid[todo],
                             g_mid[keep][..., 0], g_mid[keep][..., 1:])
        self.r[grp.links[grp.valid]] = r[grp.valid]
        damaged = (self.model.state_at(grp.links) != state_n) & grp.valid
        cached[damaged.any(axis=1)] = False
        return x

    def _gauss_seidel(self, BR, w, m, fixed, valid, law, keep, L, rhs, x, r, g_n, dg_pred, mu, shift, cohesion_T,
                      sweeps=SWEEPS):
        """Projected Gauss-Seidel over the links of the given stars (the nonsmooth
        Gauss-Seidel of LMGC90, star by star): with the springs' tangent D of the current
        iterate held, x is linear in r, x = x0 + X r, so the end-of-step jumps are
        c + G r; each link in turn projects r_l - rho_l (its gap, its slip) onto the shifted
        Signorini-Coulomb set, rho_l = 1 / max diag G_ll. Returns x (n, q), r (n, L, d)."""
        h, d = self.h, self.stars.gdim
        n, q = m.shape
        pick = lambda a: a.reshape(-1, L, *a.shape[1:])[keep]  # noqa: E731
        D = link_blocks(pick(law.dr_N_dg_N), pick(law.dr_N_dg_T), pick(law.dr_T_dg_N), pick(law.dr_T_dg_T))
        BR4 = BR.reshape(n, L, d, q)
        A = 0.25 * h * h * np.einsum("slip,sl,slij,sljq->spq", BR4, w, D, BR4)
        A[:, np.arange(q), np.arange(q)] += m
        P = (BR * np.repeat(w, d, axis=1)[..., None]).transpose(0, 2, 1)  # B^T W, (n, q, L d)
        spring = np.einsum("slij,slj->sli", D, g_n).reshape(n, L * d)  # springs' traction at g_n
        x_fixed = np.where(fixed, x, 0.0)
        b0 = rhs - h * np.matmul(P, spring[..., None])[..., 0] - np.matmul(A, x_fixed[..., None])[..., 0]
        A[fixed[:, :, None] | fixed[:, None, :]] = 0.0
        A[:, np.arange(q), np.arange(q)] += fixed
        Ainv = np.linalg.inv(A)
        x0 = np.matmul(Ainv, np.where(fixed, x, b0)[..., None])[..., 0]
        X = h * np.matmul(Ainv, np.where(fixed[..., None], 0.0, P))
        c = (g_n + dg_pred).reshape(n, L * d) + h * np.matmul(BR, x0[..., None])[..., 0]
        G = (h * np.matmul(BR, X)).reshape(n, L, d, L, d)
        diag = np.einsum("slala->sla", G).max(axis=2)
        rho = np.divide(1.0, diag, out=np.zeros_like(diag), where=diag > 0)
        c = c.reshape(n, L, d)
        r = r.copy()
        for _ in range(sweeps):
            before = r.copy()
            for l in range(L):
                y = c[:, l] + np.einsum("sajb,sjb->sa", G[:, l], r)
                rho_l = rho[:, l]
                r_N = np.maximum(-shift[:, l], r[:, l, 0] - rho_l * y[:, 0])
                z = r[:, l, 1:] - rho_l[:, None] * (y[:, 1:] - g_n[:, l, 1:])
                radius = mu[:, l] * np.maximum(r_N + shift[:, l], 0.0) + cohesion_T[:, l]
                norm = np.linalg.norm(z, axis=1)
                z *= np.minimum(1.0, np.divide(radius, norm, out=np.ones_like(norm), where=norm > 0))[:, None]
                update = valid[:, l] & (rho_l > 0)
                r[:, l, 0] = np.where(update, r_N, r[:, l, 0])
                r[:, l, 1:] = np.where(update[:, None], z, r[:, l, 1:])
            if np.abs(r - before).max() <= 1e-14 * (np.abs(r).max() + self._floor_c):
                break
        return x0 + np.matmul(X, r.reshape(n, L * d, 1))[..., 0], r

    def _jacobian(self, BR, w, m, fixed, frozen, stick, law, jac, keep, L):
        """Generalised Jacobian (n, q + L d, q + L d) of (R_m, phi) for the stars ``keep``;
        on frozen links, identity rows (see FROZEN)."""
        h, d = self.h, self.stars.gdim
        n, q = m.shape
        N = q + L * d
        pick = lambda a: a.reshape(-1, L, *a.shape[1:])[keep]  # noqa: E731
        D = link_blocks(pick(law.dr_N_dg_N), pick(law.dr_N_dg_T), pick(law.dr_T_dg_N), pick(law.dr_T_dg_T))
        Jg = link_blocks(pick(jac.dN_dgN), pick(jac.dN_dgT), pick(jac.dT_dgN), pick(jac.dT_dgT))
        Jr = link_blocks(pick(jac.dN_drN), pick(jac.dN_drT), pick(jac.dT_drN), pick(jac.dT_drT))
        BR4 = BR.reshape(n, L, d, q)
        J = np.zeros((n, N, N))
        WDB = np.einsum("sl,slij,sljq->sliq", w, D, BR4).reshape(n, L * d, q)
        J[:, :q, :q] = 0.25 * h * h * np.matmul(BR.transpose(0, 2, 1), WDB)
        J[:, np.arange(q), np.arange(q)] += m
        J[:, :q, q:] = -h * BR.transpose(0, 2, 1) * np.repeat(w, d, axis=1)[:, None, :]
        J[:, q:, :q] = h * np.einsum("slij,sljq->sliq", Jg, BR4).reshape(n, L * d, q)
        rows = q + (np.arange(L)[:, None, None] * d + np.arange(d)[None, :, None])
        cols = q + (np.arange(L)[:, None, None] * d + np.arange(d)[None, None, :])
        J[:, rows, cols] = Jr + REGULARISATION * stick[..., None, None] * np.eye(d)
        frozen_rows = np.repeat(frozen, d, axis=1)
        J[:, q:, :][frozen_rows] = 0.0
        J[:, q + np.arange(L * d), q + np.arange(L * d)] += frozen_rows
        J[:, :q, :][fixed] = 0.0
        J[:, :, :q] *= ~fixed[:, None, :]
        J[:, np.arange(q), np.arange(q)] += fixed
        return J


class ConvergenceError(RuntimeError):
    """Vertex stars whose Newton did not converge (the runner saves the state first)."""


def _ratio(a, scale):
    """a / scale, 0 where both vanish (a star at rest), inf where only the scale does."""
    return np.divide(a, scale, out=np.where(a > 0, np.inf, 0.0), where=scale > 0)
