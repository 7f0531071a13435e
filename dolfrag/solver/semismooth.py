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

A step starts from the affine prediction of each star's last piece (solver/active_set.py):
most stars are solved by it, checked by one residual evaluation, and only the stars whose
piece or damage changed pay for a Jacobian. The others start from zero (see _solve_group).

Each star stops on its own. A star that Newton has not solved after FALLBACK iterations
(active-set wandering, measured on rigid laws with friction) is handed to projected
Gauss-Seidel sweeps over its links, still exact and local; a star still above STALL after
max_iterations is given the best iterate it reached, accepted within GIVE_UP (and counted),
else counted as unconverged, and the runner stops with ConvergenceError.
"""
import numpy as np
from mpi4py import MPI

from dolfrag.interface.contact import contact_friction_residual, link_blocks, projection_jacobian
from dolfrag.solver.active_set import SLIP, ActiveSets, pattern_code
from dolfrag.timing import PhaseTimer

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

# A star has converged once its residual is below RTOL of its largest term (scaled as in
# _solve_group): ~1e6 times round-off, where the quadratic phase of Newton has ended.
RTOL = 1e-10

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

# From FALLBACK on, a star whose contact and friction are within STALL and whose momentum
# is within GIVE_UP is accepted; so is, after max_iterations, the best iterate it reached
# if within GIVE_UP overall (both counted: StarNewton.stalled). Measured on
# wall-bending-clamped under imex at 51 ms: a closed star of 6 links (4 broken and in
# contact, 1 partly damaged and sticking, 1 intact), whose normal springs (opening only)
# sit on their kink at g_N = 0: Gauss-Seidel solves its contact and friction to 1e-10, and
# leaves the momentum at 6.3e-7 (the springs' side of the kink read at a gap exact only to
# the contact tolerance, 1e-13 m); each Newton polish from there sent it astray (3.8e-5 at
# the 100th iteration, where the run stopped), and accepting only that best iterate made
# the stars that meet it again pay 100 iterations and 35 Gauss-Seidel calls each (the run
# slowed 17-fold). Reading closed links' springs at the jump contact pins (spring_jump)
# removed that case; GIVE_UP stays the last net. 1e-6 of the star's momentum is far below
# any error of the discretisation; a star above it still stops the run.
GIVE_UP = 1e-6

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

# Stars whose Jacobians are built together at the end of a step: at the first step that is
# every star, and the Jacobians, their inverses and the block inverse's temporaries would
# triple the memory of the stored inverses (100k triangles: 1.8 GB peak against 0.9 GB).
CHUNK = 2048


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

    def __init__(self, stars, jump, model, m, h, max_iterations=100, rtol=RTOL, predict=True):
        links = jump.links
        self.stars, self.jump, self.model, self.h = stars, jump, model, h
        self.max_iterations, self.rtol = max_iterations, rtol
        self.predict = predict  # False: every star starts from zero (as before solver/active_set.py)
        self.first = 0  # stars solved at iteration 1 (from their prediction or from zero) in the last step
        self.timer = PhaseTimer()  # the integrator's, once it owns this solver
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
        self.stalled = 0  # star solves accepted within GIVE_UP, over the run
        self.residual = 0.0  # largest final scaled residual of the step's stars
        self._data = []
        self._sets = []
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
            self._sets.append(ActiveSets(n_s, L, d, q + L * d))

    needs_jumps = True  # every step: the contact work of each step is booked from them

    def solve(self, f, u, g_n, v, out):
        """Velocity increments of every owned star into out[star comps].

        f: flat f_ext - K u_n on local components (ghosts updated), N; u: flat u_n (m, not
        used: the jumps carry it); g_n (n_links, gdim): link jumps of u_n (m), global frame;
        v: flat v_{n-1/2} (m/s);
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
        self.timer.lap("interface")
        self.stars.comm.Allreduce(mine, largest, op=MPI.MAX)
        self.timer.lap("communication")
        self._floor_m, self._floor_c = FLOOR * largest
        self.iterations = self.unconverged = self.first = 0
        self.residual = 0.0
        for grp, data, sets in zip(self.stars.groups, self._data, self._sets):
            x = self._solve_group(grp, data, sets, self.h * f[grp.comps], out[grp.comps], g_loc[grp.links],
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

    def _solve_group(self, grp, data, sets, rhs, x_fixed, g_n, dg_pred):
        """Newton on the group's stars, each stopping on its own once its scaled residual
        is below rtol; a star still above STALL after max_iterations gets its best iterate,
        accepted within GIVE_UP, else counted unconverged.

        Iteration 1 evaluates the residual at the affine prediction of each star whose last
        piece is cached (``sets``): a star still on that piece is solved there (exactly, but
        for round-off and the REGULARISATION of sticking links, which the next step, taken
        with the cached inverse, removes), and the residual check decides, as for any
        iterate. Every other star starts from zero. Newton's Jacobians go into ``sets``; a
        star that converges on the piece of its stored Jacobian keeps it, and the others,
        and every star whose damage changed, get the Jacobian of their converged piece,
        with the new damage, for the next step."""
        BR_all, weight_all, m_all, rho_all, fixed_all, frozen_all = data
        h, d = self.h, self.stars.gdim
        n_s, q = rhs.shape
        L = grp.links.shape[1]
        if L == 0:  # lone copies (a corner of a single cell): no interface, explicit
            self.reaction[grp.comps] = np.where(fixed_all, m_all * x_fixed - rhs, 0.0) / h
            return np.where(fixed_all, x_fixed, rhs / m_all)
        x = np.where(fixed_all, x_fixed, 0.0)  # Newton never moves the prescribed components
        # reactions start from zero (or from this step's prediction), never from the last
        # step: around a rigid star they are determined only up to self-equilibrated rings
        # (see REGULARISATION), which a warm start carried from step to step until they
        # choked the friction cones (measured: threshold and linear-softening runs then
        # failed to converge; cold, they complete)
        r = np.zeros(grp.links.shape + (d,))
        state_n = self.model.state_at(grp.links)
        # padding slots: no cohesion and no friction, so their rows are the identity (open,
        # r = 0); a cohesive cone there made them stick at rest, a zero row in 3D stars
        mu, shift, cohesion_T = (np.where(grp.valid, a[grp.links], 0.0)
                                 for a in (self._mu, self._shift, self._cohesion_T))
        predicted = sets.valid & ~(fixed_all & (x_fixed != 0)).any(axis=1) & self.predict  # imposed: not cached
        if predicted.any():  # on every star at once: cheaper than gathering the predicted ones
            t_pinned = self.model.springs(pinned_normal_jump(g_n, dg_pred).ravel(), g_n[..., 1:].reshape(-1, d - 1),
                                          state_n.ravel()).r_N.reshape(n_s, L)
            z = sets.predict(BR_all, weight_all, rho_all, rhs, fixed_all, g_n, dg_pred, mu, shift, cohesion_T, h,
                             t_pinned)
            x[predicted], r[predicted] = z[predicted, :q], _per_link(z[predicted, q:], L, d)
        todo = np.arange(n_s)
        best = None  # from FALLBACK on: each star's best iterate (x, r, scaled residual)
        for iteration in range(1, self.max_iterations + 2):
            pick = (lambda a: a) if iteration == 1 else (lambda a: a[todo])  # noqa: E731 (no copies at first)
            BR, w, m, rho, fixed, frozen, valid = (pick(a) for a in (BR_all, weight_all, m_all, rho_all, fixed_all,
                                                                     frozen_all, grp.valid))
            x_t, r_t, g_t, dg_t, state_t, rhs_t = (pick(a) for a in (x, r, g_n, dg_pred, state_n, rhs))
            mu_t, shift_t, cohesion_T_t = pick(mu), pick(shift), pick(cohesion_T)
            Bx = np.einsum("spq,sq->sp", BR, x_t).reshape(-1, L, d)
            gbar = g_t + 0.25 * h * Bx
            slip = dg_t + h * Bx
            g_end = g_t + slip
            g_end[..., 0] = np.where(valid, g_end[..., 0], 1.0)  # padding: open, so r stays 0
            rho_link = np.where(frozen, FROZEN * rho, rho).ravel()
            phi_N, phi_T, branches = contact_friction_residual(
                r_t[..., 0].ravel(), r_t[..., 1:].reshape(-1, d - 1), g_end[..., 0].ravel(),
                slip[..., 1:].reshape(-1, d - 1), rho_link, rho_link, mu_t.ravel(), shift_t.ravel(),
                cohesion_T_t.ravel())
            closed = branches.contact.reshape(-1, L) & valid
            gbar = spring_jump(gbar, g_t, dg_t, closed)
            law = self.model.springs(gbar[..., 0].ravel(), gbar[..., 1:].reshape(-1, d - 1), state_t.ravel())
            r_coh = np.concatenate([law.r_N[:, None], law.r_T], axis=1).reshape(-1, L, d)
            t = (r_coh - r_t) * w[..., None]
            interface_force = h * np.einsum("spq,sp->sq", BR, t.reshape(-1, L * d))
            R_m = m * x_t - rhs_t + interface_force
            reaction = np.where(fixed, R_m / h, 0.0)
            R_m[fixed] = 0.0
            phi = np.concatenate([phi_N[:, None], phi_T], axis=1).reshape(-1, L, d)
            scale_m = np.maximum(np.abs(rhs_t), np.maximum(np.abs(m * x_t), np.abs(interface_force))).max(axis=1)
            # the terms phi is made of, so that their cancellation (a sticking link moving
            # with its neighbours: slip = dg_pred + h B x ~ 0) sets no false floor
            terms = np.abs(g_t) + np.abs(dg_t) + h * np.abs(Bx)
            scale_c = np.abs(r_t).max(axis=(1, 2)) + (rho[..., None] * terms * valid[..., None]).max(axis=(1, 2))
            scaled_m = _ratio(np.abs(R_m).max(axis=1), np.maximum(scale_m, self._floor_m))
            scaled_c = _ratio(np.abs(phi).max(axis=(1, 2)), np.maximum(scale_c, self._floor_c))
            scaled = np.maximum(scaled_m, scaled_c)
            last = iteration > self.max_iterations  # the best iterates, evaluated once more
            if iteration < FALLBACK:
                done = scaled <= self.rtol
            else:  # stalled: accepted (see STALL, GIVE_UP)
                done = (scaled <= (GIVE_UP if last else STALL)) | ((scaled_c <= STALL) & (scaled_m <= GIVE_UP))
                self.stalled += np.count_nonzero(done & (scaled > STALL))
            code = _code(branches, gbar, valid, L)
            # a star's stored inverse stays valid if it is the Jacobian of the piece the star
            # converged on (then only damage can change it, see below)
            ends_on = (code[done] == sets.code[todo[done]]).all(axis=1) & sets.valid[todo[done]]
            sets.valid[todo[done]] = ends_on
            if iteration == 1:  # the residual decides; the piece only whether the cached inverse may finish
                on_piece = predicted & (code == sets.code).all(axis=1)
                self.first += np.count_nonzero(done)
            self.residual = max(self.residual, scaled[done].max(initial=0.0))
            g_mid = g_t + 0.5 * slip  # (g_n + g_{n+1}) / 2, where the energy is stored
            every = slice(None) if done.all() else done  # views, not copies, in the common case
            self._store(grp.links[todo][every], gbar[every], state_t[every], r_t[every][..., 0], valid[every],
                        g_mid[every])
            self.reaction[grp.comps[todo[every]]] = reaction[every]
            self.iterations = max(self.iterations, iteration)
            if done.all():
                break
            keep = ~done
            if last:  # above GIVE_UP even at its best: the runner stops (ConvergenceError)
                self.unconverged += np.count_nonzero(keep)
                self.residual = max(self.residual, scaled[keep].max())
                self._store(grp.links[todo[keep]], gbar[keep], state_t[keep], r_t[keep][..., 0], valid[keep],
                            g_mid[keep])
                break
            if iteration >= FALLBACK:
                if best is None:
                    best = x.copy(), r.copy(), np.full(n_s, np.inf)
                better = scaled < best[2][todo]
                b = todo[better]
                best[0][b], best[1][b], best[2][b] = x_t[better], r_t[better], scaled[better]
            R = np.concatenate([R_m[keep], _per_component(phi[keep])], axis=1)
            todo = todo[keep]
            if iteration == self.max_iterations and best is not None:
                x[todo], r[todo] = best[0][todo], best[1][todo]
                continue
            if iteration >= FALLBACK and (iteration - FALLBACK) % 2 == 0:  # Newton wanders: Gauss-Seidel, then polish
                x[todo], r[todo] = self._gauss_seidel(
                    BR[keep], w[keep], m[keep], fixed[keep], valid[keep],
                    *_spring_affine(law, keep, L, g_t[keep], closed[keep]), rhs[todo],
                    x[todo], r[todo], g_n[todo], dg_pred[todo], mu[todo], shift[todo], cohesion_T[todo],
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
                r[b] = base_r[b] + _per_link(alpha * direction[b, q:], L, d)
                a = todo[newton]
                base_x[a], base_r[a], base_scaled[a], halvings[a] = x[a], r[a], scaled[keep][newton], 0
            # on its cached piece, a prediction only short of REGULARISATION is finished by
            # the cached inverse; elsewhere a fresh Jacobian (the sets' storage serves Newton)
            fresh = ~on_piece[todo] & newton if iteration == 1 else newton
            if fresh.any():
                new = keep.copy()
                new[keep] = fresh
                jac = projection_jacobian(_subset(branches, new, L), rho_link.reshape(-1, L)[new].ravel(),
                                          rho_link.reshape(-1, L)[new].ravel(), mu_t[new].ravel())
                D = _spring_affine(law, new, L, g_t[new], closed[new])[0]
                J = self._jacobian(BR[new], w[new], m[new], fixed[new], frozen[new],
                                   branches.stick.reshape(-1, L)[new], D, jac)
                sets.keep(todo[fresh], block_inverse(J, q + L), code[new], D, cacheable=self._cacheable(frozen[new], code[new]))
            a = todo[newton]
            delta = -np.einsum("sij,sj->si", sets.inverse[a], R[newton])
            if CYCLE < iteration < FALLBACK:
                direction[a] = delta
            x[a] += delta[:, :q]
            r[a] += _per_link(delta[:, q:], L, d)
        self.r[grp.links[grp.valid]] = r[grp.valid]
        damaged = ((self.model.state_at(grp.links) != state_n) & grp.valid).any(axis=1)
        renew = np.flatnonzero(~sets.valid | damaged)
        for chunk in range(0, len(renew), CHUNK):  # bounded temporaries: at the first step, every star
            self._keep_pieces(grp, data, sets, renew[chunk:chunk + CHUNK], x, r, g_n, dg_pred)
        return x

    def _cacheable(self, frozen, code):
        """Stars (n,) whose Jacobian is that of an affine piece: no frozen link (a fixed-point
        iteration) and, in 3D, no slipping link (smooth, not affine)."""
        affine = ~frozen.any(axis=1)
        return affine & ~((code & SLIP) > 0).any(axis=1) if self.stars.gdim == 3 else affine

    def _store(self, links, gbar, state_n, r_N, valid, g_mid):
        """Accept the stars' converged state: the law's trial state at their springs' jumps
        gbar (n, L, d) from state_n (n, L), with the contact pressure r_N (n, L)."""
        d = gbar.shape[-1]
        state = self.model.trial_state(gbar[..., 0].ravel(), gbar[..., 1:].reshape(-1, d - 1), state_n.ravel(),
                                       r_N.ravel())
        self.model.store(links, state.reshape(state_n.shape), valid, g_mid[..., 0], g_mid[..., 1:])

    def _keep_pieces(self, grp, data, sets, stars, x, r, g_n, dg_pred):
        """Store, for the next step's prediction, the Jacobian of the piece each given star
        converged on (x, r), with the damage after the step (``_cacheable`` ones only)."""
        BR_all, weight_all, m_all, rho_all, fixed_all, frozen_all = data
        sets.valid[stars] = False
        if not len(stars):
            return
        h, d, L = self.h, self.stars.gdim, grp.links.shape[1]
        links, valid = grp.links[stars], grp.valid[stars]
        state = self.model.state_at(links)
        mu, shift, cohesion_T = (np.where(valid, a, 0.0) for a in (self.model.friction(state), self.model.shift(state),
                                                                   self.model.shear_cohesion(state)))
        Bx = np.einsum("spq,sq->sp", BR_all[stars], x[stars]).reshape(-1, L, d)
        gbar = g_n[stars] + 0.25 * h * Bx
        slip = dg_pred[stars] + h * Bx
        g_end = g_n[stars] + slip
        g_end[..., 0] = np.where(valid, g_end[..., 0], 1.0)
        rho = rho_all[stars].ravel()
        _, _, branches = contact_friction_residual(
            r[stars][..., 0].ravel(), r[stars][..., 1:].reshape(-1, d - 1), g_end[..., 0].ravel(),
            slip[..., 1:].reshape(-1, d - 1), rho, rho, mu.ravel(), shift.ravel(), cohesion_T.ravel())
        closed = branches.contact.reshape(-1, L) & valid
        gbar = spring_jump(gbar, g_n[stars], dg_pred[stars], closed)
        law = self.model.springs(gbar[..., 0].ravel(), gbar[..., 1:].reshape(-1, d - 1), state.ravel())
        D = _spring_affine(law, np.ones(len(stars), dtype=bool), L, g_n[stars], closed)[0]
        code = _code(branches, gbar, valid, L)
        J = self._jacobian(BR_all[stars], weight_all[stars], m_all[stars], fixed_all[stars], frozen_all[stars],
                           branches.stick.reshape(-1, L), D, projection_jacobian(branches, rho, rho, mu.ravel()))
        sets.keep(stars, block_inverse(J, BR_all.shape[2] + L), code, D, cacheable=self._cacheable(frozen_all[stars], code))

    def _gauss_seidel(self, BR, w, m, fixed, valid, D, t0, rhs, x, r, g_n, dg_pred, mu, shift, cohesion_T,
                      sweeps=SWEEPS):
        """Projected Gauss-Seidel over the links of the given stars (the nonsmooth
        Gauss-Seidel of LMGC90, star by star): with the springs' affine model of the current
        iterate held (_spring_affine: traction t0 + D h B x / 4), x is linear in r,
        x = x0 + X r, so the end-of-step jumps are
        c + G r; each link in turn projects r_l - rho_l (its gap, its slip) onto the shifted
        Signorini-Coulomb set, rho_l = 1 / max diag G_ll. Returns x (n, q), r (n, L, d)."""
        h, d = self.h, self.stars.gdim
        n, q = m.shape
        L = D.shape[1]
        BR4 = BR.reshape(n, L, d, q)
        A = 0.25 * h * h * np.einsum("slip,sl,slij,sljq->spq", BR4, w, D, BR4)
        A[:, np.arange(q), np.arange(q)] += m
        P = (BR * np.repeat(w, d, axis=1)[..., None]).transpose(0, 2, 1)  # B^T W, (n, q, L d)
        spring = t0.reshape(n, L * d)  # springs' traction at x = 0
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

    def _jacobian(self, BR, w, m, fixed, frozen, stick, D, jac):
        """Generalised Jacobian (n, q + L d, q + L d) of (R_m, phi) for n stars, from the
        springs' link tangents D (n, L, d, d) and the ProjectionJacobian jac (flat over the
        n L links); on frozen links, identity rows (see FROZEN). Unknowns in the order
        (x, r_N of every link, then each tangential component of every link): the
        tangential rows of frictionless links, diagonal only, then form the trailing block
        that block_inverse splits off."""
        h, d = self.h, self.stars.gdim
        n, q = m.shape
        L = D.shape[1]
        N = q + L * d
        shape = lambda a: a.reshape(n, L, *a.shape[1:])  # noqa: E731
        Jg = link_blocks(*map(shape, (jac.dN_dgN, jac.dN_dgT, jac.dT_dgN, jac.dT_dgT)))
        Jr = link_blocks(*map(shape, (jac.dN_drN, jac.dN_drT, jac.dT_drN, jac.dT_drT)))
        BR4 = BR.reshape(n, L, d, q)
        J = np.zeros((n, N, N))
        WDB = np.einsum("sl,slij,sljq->sliq", w, D, BR4).reshape(n, L * d, q)
        J[:, :q, :q] = 0.25 * h * h * np.matmul(BR.transpose(0, 2, 1), WDB)
        J[:, np.arange(q), np.arange(q)] += m
        J[:, :q, q:] = -h * np.einsum("sliq,sl->sqil", BR4, w).reshape(n, q, L * d)
        J[:, q:, :q] = h * np.einsum("slij,sljq->silq", Jg, BR4).reshape(n, L * d, q)
        at = q + np.arange(d)[None, :] * L + np.arange(L)[:, None]  # (L, d): position of r_l,i
        J[:, at[:, :, None], at[:, None, :]] = Jr + REGULARISATION * stick[..., None, None] * np.eye(d)
        if frozen.any():  # (each a full pass over J: skipped where none, the common case)
            frozen_rows = np.tile(frozen, (1, d))
            J[:, q:, :][frozen_rows] = 0.0
            J[:, q + np.arange(L * d), q + np.arange(L * d)] += frozen_rows
        if fixed.any():
            J[:, :q, :][fixed] = 0.0
            J[:, :, :q] *= ~fixed[:, None, :]
            J[:, np.arange(q), np.arange(q)] += fixed
        return J


class ConvergenceError(RuntimeError):
    """Vertex stars whose Newton did not converge (the runner saves the state first)."""


def block_inverse(J, k):
    """np.linalg.inv of a batch of star Jacobians J (n, N, N), cheaper where the trailing
    N - k rows (the tangential rows of _jacobian's order, k = q + L) have their diagonal as
    only nonzero, as a frictionless link's have (every intact RCCM link): then
    J = [[A, B], [0, D]] with D diagonal, and its inverse is [[A^-1, -A^-1 B D^-1], [0, D^-1]],
    A only inverted densely (2D stars: 18 of 24 rows, 3D ~104 of ~174: 1.8x and 3.5x
    cheaper than LAPACK's batched inverse of J, measured). Other stars: np.linalg.inv."""
    n, N, _ = J.shape
    inverse = np.empty_like(J)
    trailing = np.arange(k, N)
    diagonal = J[:, trailing, trailing]
    split = (np.count_nonzero(J[:, k:, :], axis=2) == 1).all(axis=1) & (diagonal != 0).all(axis=1)
    if (~split).any():
        inverse[~split] = np.linalg.inv(J[~split])
    if split.any():
        A_inv = np.linalg.inv(J[split, :k, :k])
        D_inv = 1.0 / diagonal[split]
        inverse[split, :k, :k] = A_inv
        inverse[split, :k, k:] = -np.matmul(A_inv, J[split, :k, k:]) * D_inv[:, None, :]
        inverse[split, k:, :k] = 0.0
        inverse[split, k:, k:] = 0.0
        inverse[np.flatnonzero(split)[:, None], trailing, trailing] = D_inv
    return inverse


def _per_component(r):
    """Link quantities (n, L, d) as the reaction rows of _jacobian: (n, d L), component-major."""
    return r.transpose(0, 2, 1).reshape(len(r), -1)


def _per_link(v, L, d):
    """The inverse of _per_component: (n, d L) -> (n, L, d)."""
    return v.reshape(len(v), d, L).transpose(0, 2, 1)


def _subset(flat, stars, L):
    """A NamedTuple of arrays flat over the links of n stars (n L, ...), kept for ``stars``
    (bool (n,))."""
    return type(flat)(*(a.reshape(-1, L, *a.shape[1:])[stars].reshape(-1, *a.shape[1:]) for a in flat))


def spring_jump(gbar, g_n, dg, closed):
    """The jumps (n, L, d) at which the springs are read: gbar = g_n + h B x / 4, but on
    ``closed`` links (contact branch) the normal part is 3 g_n,N / 4 - dg_N / 4, its value
    where g_end,N = g_n,N + dg_N + h B x_N = 0, which the constraint holds. So a closed
    link's normal spring does not move with x: read at gbar(x) instead, a spring acting in
    opening only sat on its kink at g_N = 0 at gaps exact to the contact tolerance (1e-13
    m), and Newton and Gauss-Seidel, each on one side, did not meet (measured:
    semismooth.GIVE_UP). At a solution both readings agree to that tolerance."""
    out = gbar.copy()
    out[..., 0] = np.where(closed, pinned_normal_jump(g_n, dg), gbar[..., 0])
    return out


def pinned_normal_jump(g_n, dg):
    """gbar_N (n, L) of a closed link: 3 g_n,N / 4 - dg_N / 4 (see spring_jump)."""
    return 0.75 * g_n[..., 0] - 0.25 * dg[..., 0]


def _spring_affine(law, stars, L, g_n, closed):
    """The springs' affine model on the current piece, for ``stars`` (bool (n,)) of a
    Cohesion read at spring_jump: the tangent D (n, L, d, d) in the jump gbar, without the
    normal column on closed links (their normal jump is pinned), and the traction at
    x = 0, t0 (n, L, d): D g_n, plus on closed links the law's normal traction at the
    pinned jump."""
    D = _link_tangent(law, stars, L)
    D[..., :, 0] *= ~closed[..., None]
    t0 = np.einsum("slij,slj->sli", D, g_n)
    t0[..., 0] += np.where(closed, law.r_N.reshape(-1, L)[stars], 0.0)
    return D, t0


def _link_tangent(law, stars, L):
    """The springs' link-frame tangent blocks (n, L, d, d) of a Cohesion (flat over n L
    links), for ``stars`` (bool (n,))."""
    pick = lambda a: a.reshape(-1, L, *a.shape[1:])[stars]  # noqa: E731
    return link_blocks(pick(law.dr_N_dg_N), pick(law.dr_N_dg_T), pick(law.dr_T_dg_N), pick(law.dr_T_dg_T))


def _code(branches, gbar, valid, L):
    """The pieces (n, L) of the links of n stars (0 on padding slots)."""
    flat = pattern_code(branches, gbar[..., 0].ravel())
    return np.where(valid, flat.reshape(-1, L), 0)


def _ratio(a, scale):
    """a / scale, 0 where both vanish (a star at rest), inf where only the scale does."""
    return np.divide(a, scale, out=np.where(a > 0, np.inf, 0.0), where=scale > 0)
