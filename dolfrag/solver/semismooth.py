"""Semi-smooth Newton for the nonsmooth `imex` interface step, star by star.

With lumped mass and nodal interface quadrature the implicit part of a step splits into
one problem per vertex star. The unknowns of a star are its velocity increments ``x``
(q = copies x gdim) and, per link, the contact reactions ``r = (r_N, r_T)`` in the link
frame (r_N >= 0 pushes the faces apart):

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
Lagged, every model's springs are secants fixed for the step (model.secants).

A step starts from the affine prediction of each star's last piece (solver/active_set.py):
most stars are solved by it, checked by one residual evaluation, and only the stars whose
piece changed pay for a Jacobian: where only the damage changed, the stored factors go on
as a chord while it contracts (StarOptions.chord). The others start from zero.

Each star stops on its own (the tuning: solver/stars/options.StarOptions). A star its
prediction started and Newton has not solved after ``restart`` iterations starts again from
zero. A star that Newton has not solved after ``fallback`` iterations (active-set wandering,
measured on rigid laws with friction) is handed to projected Gauss-Seidel sweeps over its
links, still exact and local; a star still above ``stall`` after max_iterations is given the
best iterate it reached, accepted within ``give_up`` (and counted), else counted as
unconverged. A step with an unconverged star solves it again with ESCALATION
times the iterations, and once more with Gauss-Seidel to round-off (LAST_SWEEP_TOL); a star
still unconverged then stops the run with ConvergenceError. A star that this second pass
accepted within give_up starts the next step there (REMEMBER).

The solves run in one compiled loop over the rank's stars (solver/star_kernel.py); this
module gathers a step's data for it and books what it returns (damage, contact work).
"""
import numpy as np
from mpi4py import MPI

from dolfrag.interface.stars import FlatStars
from dolfrag.solver import star_kernel, star_replay
from dolfrag.solver.active_set import joint_jumps
from dolfrag.solver.energy import book_reaction_work
from dolfrag.solver.interrupt import Responsive, StepInterrupted
from dolfrag.solver.star_kernel import (DEFAULT, ITERATIONS, N_FIRST, N_STALLED, N_UNCONVERGED, Cache, Geometry,
                                         Outputs, StepData, empty_cache)
from dolfrag.solver.stars.blocks import gather, give_back_all, scatter
from dolfrag.solver.stars.options import sweep_tolerance
from dolfrag.timing import PhaseTimer

# Relative size below which a star's own scales give way to the step's largest (see solve).
FLOOR = 1e-6
# A step with a star unsolved after max_iterations solves it again (from the cache the first
# pass left) with ESCALATION times the iterations and SECOND_REGULARISATION on the reaction
# diagonal of its sticking links where no joint holds it (StarOptions.regularisation
# elsewhere), before the run stops. What it solved while held links were rigid, before they
# were stiff joints: rings of rigid links around an interior vertex, pressed and
# sticking, whose reactions are redundant around the ring (linear softening, decoupled
# RCCM). At 1e-6 their Newton stalls at 1-7e-6 and stays there through 5,000 iterations;
# at 1e-3 the same stars (dolfrag replay of the dumps: wall-bending-clamped at 38.9 ms,
# 6 links; bunker-h2 at 6.95 and 7.43 ms, 15 links) converge or are accepted within stall
# after 45-90 iterations (1e-9: unconverged). As in theta's sub-steps
# (NewtonOptions.cycle_regularisation), the residual stays exact: a larger regularisation
# only slows the last digits down, which is why the first pass keeps 1e-6. 20 times the
# first pass's 50 iterations: the 1,000 the second pass has had since the first pass had 100.
ESCALATION = 20
SECOND_REGULARISATION = 1e-3
# The second pass's Newton steps between Gauss-Seidel calls (StarOptions.polish; the first
# pass alternates, 1). The Newton step after a call lands on the piece the sweeps found and
# pays a new Jacobian and LU; the steps after it mostly stay on that piece and reuse them, and
# a call every other iteration undid their progress. Measured on the 26 second-pass calls of
# benchmarks/hard_stars.py, solved again alone: 7.4-7.7 s of CPU at 1, 3.6-4.0 s from 8 to
# 30, every star accepted within give_up; the whole box 9.3-11.0 s against 6.3-7.6 s.
SECOND_POLISH = 10
# A star the second pass leaves unconverged is solved a third time as in the second pass,
# with its Gauss-Seidel sweeps run to round-off instead of StarOptions.sweep_tol: measured on
# bunker-h2 at 0.1 m (linear softening, 8.49 ms), a 3D star that sweeps stopped at 1e-4 left
# at 1.2e-6 after both passes, and that sweeps to 1e-14 solve (accepted within stall).
LAST_SWEEP_TOL = 1e-14
# A star the second pass did not solve to rtol (accepted within give_up, the pressed rings of
# rigid links above) is, in a cracking structure, the same star at the next step, and the
# first pass's max_iterations only delay it: such a star starts the next step in the second
# pass (StarNewton.remember). Measured on the cracked bunker-wall-panel (0.1 m, linear
# softening, resumed at 20 ms for 54 steps, 2 ranks): its 4-6 hard stars a step, of 90-108
# copies and 45-54 links, took 51 first-pass iterations each (45 ms) before the second pass
# solved them in 43-223; the interface phase 35.8 -> 18.4 s, the same broken links, kinetic
# energy equal to 2e-11. benchmarks/hard_stars.py: 5.4 -> 4.1 s of CPU.
REMEMBER = True


def step_stiffness(links, m, h, gdim):
    """The step's own stiffness of each link (Pa/m): m / (h^2 weight), m the mean lumped
    mass (kg) of its two copies, from the flat mass m; h the step (s). It scales the
    augmentation of the contact projections, and bounds the springs a star can take."""
    m_pair = 0.5 * (m[gdim * links.dof_A] + m[gdim * links.dof_B])
    return m_pair / (h * h * links.weight)


class StarLayout(FlatStars):
    """A rank's stars flat, as the kernel reads them (solver/star_kernel.py): the flat
    layout (interface/stars.FlatStars), each link's frame, weight, step stiffness rho
    (Pa/m) and whether both its copies are prescribed (frozen), each component's mass and
    whether it is prescribed, each star's elimination order of its unknowns, and the cache
    of each star's last Jacobian factors (blocks of one pool: solver/stars/blocks.py)."""
    # what a checkpoint keeps: the cached factors decide which stars reuse theirs, so a
    # resumed run takes the same iterates as an uninterrupted one; of the factors only those
    # of the stars that hold some (held_factors), restored once ``cached`` and ``pivots`` are
    STATE = ("cached", "pivots", "held_factors", "codes", "slip_dir", "factored")
    # what a step's rewind keeps (runner/checkpoint.Rewind): the factors are most of a rank's
    # state (533 of 585 MB for the 0.1 m bunker), and copying them before every guarded step
    # took 41 % of the 0.04 m panel's time; a rewound step drops them instead (rewound)
    REWIND = ("codes", "slip_dir", "cached", "factored")

    def __init__(self, stars, links, m, h):
        super().__init__(stars, links)
        d = stars.gdim
        self.frame = np.ascontiguousarray(links.frames()[self.links])  # normal, then tangents
        self.weight = np.ascontiguousarray(links.weight[self.links], dtype=float)
        self.rho = np.ascontiguousarray(step_stiffness(links, m, h, d)[self.links])
        self.mass = np.ascontiguousarray(m[self.comps])
        self.fixed = np.ascontiguousarray(stars.constrained[self.comps])
        held = np.zeros(len(stars.constrained) // d, dtype=bool)  # per local dof: every component prescribed
        held[self.comps[::d] // d] = self.fixed.reshape(-1, d).all(axis=1)
        self.frozen = np.ascontiguousarray(held[links.dof_A[self.links]] & held[links.dof_B[self.links]])
        self._geometry = star_kernel.star_geometry(self.comp_off, self.link_off, self.slot_A, self.slot_B, self.frame,
                                                   self.weight, self.rho, self.frozen, self.mass, self.fixed, h)
        # per star its factors, what they are (star_kernel.NONE, ...), per link their piece, slip
        # directions and (k_N, k_T, mu): records.Cache
        (self.blocks, self.piv_off, self.factors, self.pivots, self.codes, self.slip_dir, self.cached,
         self.factored) = empty_cache(self.comp_off, self.link_off, d)

    @property
    def slip_dir(self):
        """Per star link, the 3D slip direction and projection scale its star's factors hold
        (stars/jacobian.piece_branches), (n, d)."""
        return self._slip_dir

    @slip_dir.setter
    def slip_dir(self, value):  # from a checkpoint of before the scale column: scale 0, held directions
        padded = np.pad(value, ((0, 0), (0, self.frame.shape[1] - value.shape[1])))
        if hasattr(self, "_slip_dir"):
            self._slip_dir[...] = padded  # in place, as checkpoint.restore_object restores arrays
        else:
            self._slip_dir = padded

    @property
    def held_factors(self):
        """The factors of the stars that hold some (``cached`` neither NONE nor RIGID), one
        star after the other, of each the n_c N values its solves read (n_c its coupled
        unknowns, the first entry of its pivots): what a checkpoint keeps of ``factors``.
        Read-only: a copy already, which the checkpoint takes as it is."""
        used = self._used()[1]
        out = np.empty(used.sum())
        gather(self.blocks, self.factors, used, out)
        out.flags.writeable = False
        return out

    @held_factors.setter
    def held_factors(self, values):
        """From held_factors' values, or from a checkpoint written when a star's whole block was
        kept (N^2 values each)."""
        holds, used = self._used()
        N = self.blocks.size
        whole = values.size != used.sum() and values.size == (N[holds] ** 2).sum()
        give_back_all(self.blocks)
        scatter(self.blocks, self.factors, values, holds, used, np.where(holds, N * N, 0) if whole else used)

    def _used(self):
        """Per star whether it holds factors, and how many values of its block they are."""
        holds = (self.cached != star_kernel.NONE) & (self.cached != star_kernel.RIGID)
        n_c = self.pivots[self.piv_off[:-1]]
        return holds, np.where(holds, n_c * self.blocks.size, 0)

    def rewound(self):
        """After a rewind: no star has stored factors (star_kernel.NONE), as before the first
        step, since the abandoned step may have formed some in place; their blocks are free."""
        self.cached[:] = star_kernel.NONE
        give_back_all(self.blocks)

    def geometry(self):
        """The layout as the kernel reads it (records.Geometry)."""
        return self._geometry

    def cache(self):
        """The stored factors as the kernel reads them (records.Cache): built at each call, as
        a checkpoint's restore replaces the arrays."""
        return Cache(self.blocks, self.piv_off, self.factors, self.pivots, self.codes, self.slip_dir, self.cached,
                     self.factored)


class StarNewton:
    """Nonsmooth step solver for the owned stars.

    stars: interface/stars.Stars; jump: interface/jumps.Jump (its link table); model: an
    interface model (interface/models.py) giving the cohesive law, its state and friction;
    m: flat lumped mass of every local dof component (kg); h: time step (s); options: the
    star Newton's tuning (solver/stars/options.StarOptions), with ``tuning`` (its fields by
    name, e.g. max_iterations=1) replacing some; escalation: the second pass's factor on
    max_iterations (1: none). ``remember`` (REMEMBER): whether a star that the last step's
    second pass did not solve to rtol starts this step in the second pass.
    """

    def __init__(self, stars, jump, model, m, h, escalation=ESCALATION, options=DEFAULT, **tuning):
        links = jump.links
        self.stars, self.jump, self.model, self.h = stars, jump, model, h
        self.options = options._replace(**tuning)
        self.escalation = escalation
        self.remember = REMEMBER
        self.first = 0  # stars solved at iteration 1 (from their prediction or from zero) in the last step
        self.timer = PhaseTimer()  # the integrator's, once it owns this solver
        d = stars.gdim
        self.layout = StarLayout(stars, links, m, h)
        self._all_links = np.arange(len(links))
        self._largest_weight = max(links.weight.max(initial=0.0), 1e-300)  # m or m^2: a force as a traction
        self.reaction = np.zeros_like(m)  # N: on the prescribed components of the stars
        self.contact_dissipated = 0.0  # J (J/m in 2D), owned links
        self.iterations = 0
        self.unconverged = 0
        self.stalled = 0  # star solves accepted within GIVE_UP, over the run
        self.remembered = 0  # star solves started in the second pass (REMEMBER), over the run
        self.residual = 0.0  # largest final scaled residual of the step's stars
        n_comps, n_links = len(self.layout.comps), len(self.layout.links)
        # the kernel's outputs, reused every step
        self._x, self._reaction, self._rhs, self._x_in = (np.zeros(n_comps) for _ in range(4))
        self._r, self._gbar, self._slip, self._g_loc, self._dg_loc = (np.zeros((n_links, d)) for _ in range(5))
        self._r_n = np.zeros((n_links, d))  # the reactions of the step before
        self._joint_before = np.zeros((n_links, d))  # the last step's elastic jump of the rigid links' joints
        # this step's mid jump, the law's opening and the joints' elastic jump (joint_jumps)
        self._g_mid, self._opening, self._joint = (np.zeros((n_links, d)) for _ in range(3))
        self._slip_before = np.zeros((n_links, d))  # the last step's g_n - g_{n-1} (none before the first)
        self._absorbed = np.zeros(len(links))  # the cohesion's work of a step per link, J/m^2
        self.status = np.zeros(self.layout.n_stars, dtype=np.int8)  # star_kernel.CONVERGED, STALLED, ...
        self.star_residual = np.zeros(self.layout.n_stars)  # each star's final scaled residual
        self._counters = np.zeros(4, dtype=np.int64)
        self._first = np.ones(self.layout.n_stars, dtype=np.bool_)  # the first pass's todo
        self._second = np.zeros(self.layout.n_stars, dtype=np.bool_)  # this step's second pass's
        self._hard = np.zeros(self.layout.n_stars, dtype=np.bool_)  # the stars starting there (REMEMBER)
        self._no_stop = np.zeros(1, dtype=np.int8)  # the kernel's abort flag without a stop request
        self._responsive = Responsive()
        self._entry_codes = np.zeros(n_links, dtype=np.int8)  # of unconverged stars only
        self._entry_cached = np.zeros(self.layout.n_stars, dtype=np.int8)
        self.failed = None  # the unconverged stars' kernel inputs (star_replay.select), when a step has some
        self._data = None  # the link states and what _data_at gave at them
        self._position = np.empty(len(links), dtype=np.int64)  # of each link in the layout
        self._position[self.layout.links] = np.arange(len(links))

    max_iterations = property(lambda self: self.options.max_iterations,
                              lambda self, n: self._tune(max_iterations=n))
    rtol = property(lambda self: self.options.rtol, lambda self, rtol: self._tune(rtol=rtol))
    # False: every star starts from zero (no affine prediction)
    predict = property(lambda self: self.options.predict, lambda self, predict: self._tune(predict=predict))

    def _tune(self, **fields):
        self.options = self.options._replace(**fields)

    # None, or a stop request (solver/interrupt.py): the star loop then runs in a worker
    # thread, gives up when its flag is set, and the step raises StepInterrupted
    interrupt = None

    def solve(self, f, u, v, out):
        """Velocity increments of every owned star into out[star comps].

        f: flat f_ext - K u_n on local components (ghosts updated), N; u, v: flat u_n (m)
        and v_{n-1/2} (m/s), current on the stars' components: the links' jumps come from
        them; out: flat, holding on entry the increments of the prescribed components (m/s).
        Updates the model's state (damage), the contact reactions and the reactions of
        the prescribed components (``reaction``, N), and books the contact work
        (contact_dissipated, model.absorb).
        """
        lay, h = self.layout, self.h
        g_loc, dg_loc = self._g_loc, self._dg_loc  # link frame: the jumps of u_n and h v_{n-1/2}
        rhs, x_in = self._rhs, self._x_in  # h f and the prescribed increments, per star component
        state_n = self.model.state_at(self._all_links)
        per_link = self._data_at(state_n)
        geometry = lay.geometry()
        # its floors are set once the step's largest terms are known (below)
        self._r_n[:] = self._r  # the reactions of the step before: the sticking links' elastic reference
        data = StepData(rhs, x_in, g_loc, dg_loc, *per_link, float(h), 0.0, 0.0, self._r_n)
        star_kernel.gather_stars(lay.comps, geometry, u, v, f, out, data)
        # A star far from the action (a millionth of the largest force or traction of this
        # rank's step) is converged at round-off of the whole problem, not of its own tiny terms.
        # (global, so that 1 and N ranks stop every star alike)
        force = np.abs(f).max(initial=0.0)  # N, and as a traction on the largest link (Pa)
        mine = np.array([h * force, max(np.abs(self._r).max(initial=0.0), np.abs(per_link[1]).max(initial=0.0),
                                        force / self._largest_weight)])
        largest = np.empty(2)
        self.timer.lap("interface")
        self.stars.comm.Allreduce(mine, largest, op=MPI.MAX)
        self.timer.lap("communication")
        floor_m, floor_c = FLOOR * largest
        data = data._replace(floor_m=float(floor_m), floor_c=float(floor_c))
        outputs = Outputs(self._x, self._r, self._reaction, self._gbar, self._slip, self.status, self.star_residual,
                          self._counters, self._entry_codes, self._entry_cached)
        interrupt = self.interrupt
        call = _call if interrupt is None else self._responsive  # a stop request: in a worker thread
        abort = self._no_stop if interrupt is None else interrupt.flag

        def solve_stars(options, todo):
            self._counters[:] = 0
            call(star_kernel.solve_stars, geometry, data, lay.cache(), outputs, options, todo, abort)

        self._passes(solve_stars, abort)
        if interrupt is not None and interrupt.pending():  # every rank asks once a step
            raise StepInterrupted
        out[lay.comps] = self._x
        self.reaction[lay.comps] = self._reaction
        self.iterations = int(self._counters[ITERATIONS])
        self.unconverged = int(self._counters[N_UNCONVERGED])
        self.stalled += int(self._counters[N_STALLED])
        self.first = int(self._counters[N_FIRST])
        self.residual = self.star_residual.max(initial=0.0)
        if self.unconverged:
            self.failed = star_replay.failed(np.flatnonzero(self.status == star_kernel.UNCONVERGED), lay.comps,
                                             geometry, data, lay.cache(), outputs, self.options)
        # the state after the step, from the accepted jumps g_mid = (g_n + g_{n+1}) / 2; the
        # law's opening is g_mid less the elastic jump of the rigid links' joints
        joint_jumps(g_loc, self._slip, self._r_n, self._r, per_link[1], lay.rho, lay.frozen, self._g_mid,
                    self._opening, self._joint)
        changed = self.model.advance(lay.links, self._gbar, self._g_mid, self._r[:, 0], self._opening)
        self._book_contact_work(*per_link[1:3], self._joint)
        if len(changed):  # the stars whose damage changed: their factors are now stale (StarOptions.chord)
            self._mark_stale(changed)
            self._refresh(changed)  # in place: data holds the new values
        renew = np.flatnonzero(lay.cached == star_kernel.NONE)
        if len(renew):  # the Jacobians of the converged pieces, for the next step's prediction
            star_kernel.keep_pieces(renew, geometry, data, self._x, self._r, lay.cache(), self.options)

    def _passes(self, solve_stars, abort):
        """The step's passes over the stars: the first over all but those that start in the
        second (REMEMBER), the second and third (_solve_unconverged_again) over those and the
        ones the first left unsolved; then which stars start in the second pass next step."""
        hard = self._hard  # only a second pass with REMEMBER sets it
        n_hard = int(np.count_nonzero(hard))
        np.logical_not(hard, out=self._first)
        solve_stars(self.options, self._first)
        self.timer.lap("interface")
        self.status[hard] = star_kernel.UNCONVERGED
        self.remembered += n_hard
        if (n_hard or self._counters[N_UNCONVERGED]) and self.escalation > 1 and not abort[0]:
            self._solve_unconverged_again(solve_stars)
            self.timer.lap("hard_stars")
            if self.remember:
                np.logical_and(self._second, self.status != star_kernel.CONVERGED, out=hard)
        elif n_hard:  # a stop request cut the step short: start the next one afresh
            hard[:] = False

    def _solve_unconverged_again(self, solve_stars):
        """Solve the stars the first pass left unconverged (or skipped: REMEMBER) again, with
        ``escalation`` times the iterations and SECOND_REGULARISATION, and those still
        unconverged a third time with sweeps to LAST_SWEEP_TOL where the second pass stopped
        them earlier (3D stars: StarOptions.sweep_tol); the others keep their solutions and
        cached factors, as if no star had failed (so the answer does not depend on which rank
        a failed star fell to). Only those stars are solved: each star's solve depends on its
        own data alone (measured on the cracking bunker-wall-panel, 2,012 stars, one
        unconverged: the second pass over all stars took 12.8 s)."""
        iterations, n_first = self._counters[ITERATIONS], self._counters[N_FIRST]
        again = self.options._replace(max_iterations=self.escalation * self.max_iterations,
                                      regularisation=SECOND_REGULARISATION, polish=SECOND_POLISH)
        passes = [again]
        # a third pass where it sweeps further than the second (else it would repeat it exactly)
        if sweep_tolerance(again, self.stars.gdim) > LAST_SWEEP_TOL:
            passes.append(again._replace(sweep_tol=LAST_SWEEP_TOL))
        for options in passes:
            todo = self.status == star_kernel.UNCONVERGED
            if options is again:
                self._second[:] = todo
            if not todo.any():
                break
            solve_stars(options, todo)
            iterations, n_first = max(iterations, self._counters[ITERATIONS]), n_first + self._counters[N_FIRST]
        self._counters[ITERATIONS], self._counters[N_FIRST] = iterations, n_first
        self._counters[N_UNCONVERGED] = np.count_nonzero(self.status == star_kernel.UNCONVERGED)
        self._counters[N_STALLED] = np.count_nonzero(self.status == star_kernel.STALLED)

    @property
    def r(self):
        """The contact reactions of the last step (n_links, gdim), link frame, Pa."""
        r = np.zeros((self.layout.n_links, self.stars.gdim))
        r[self.layout.links] = self._r
        return r

    def _data_at(self, state):
        """Per star link, the kernel's friction mu, cohesion shift and cohesion_T (Pa) and
        the springs' secants k_N, k_T (Pa/m) at the link states ``state`` (of every link).
        They are functions of the states alone, which stay the same from most steps to the
        next: the last call's are returned while they do (measured on wall-bending-clamped:
        58 us of a 1.1 ms step), and after a step only its changed links are evaluated
        again (_refresh)."""
        if self._data is None or not np.array_equal(state, self._data[0]):
            self._data = (state.copy(), self._link_data(state[self.layout.links], self.layout.links))
        return self._data[1]

    def strengths_changed(self, links):
        """The model changed the strength of the links ``links`` (indices into the rank's
        links, interface/rate.py): their kernel data are evaluated again, and the factors of
        their stars, formed with the old strengths, go on as a chord (STALE) only."""
        if self._data is not None and len(links):
            changed = self._position[links]
            self._refresh(changed)
            self._mark_stale(changed)

    def _mark_stale(self, changed):
        """The stars of the star links ``changed`` (positions) keep their exact factors as
        a chord (star_kernel.STALE)."""
        lay = self.layout
        stars = lay.star_of_link[changed]
        lay.cached[stars[lay.cached[stars] == star_kernel.EXACT]] = star_kernel.STALE

    def _refresh(self, changed):
        """The kernel's per-link data after the star links ``changed`` took new states:
        evaluated on those links alone, into the arrays _data_at gave."""
        known, data = self._data
        links = self.layout.links[changed]
        state = self.model.state_at(links)
        known[links] = state
        for array, values in zip(data, self._link_values(state, links)):
            array[changed] = values

    def _link_data(self, state, links):
        """(mu, shift, cohesion_T, k_N, k_T) at the states ``state`` of the links ``links``,
        one float array each."""
        n = len(state)
        return tuple(np.array(np.broadcast_to(a, (n,)), dtype=float) for a in self._link_values(state, links))

    def _link_values(self, state, links):
        """(mu, shift, cohesion_T, k_N, k_T) at the states ``state`` of the links ``links``,
        as the model gives them."""
        model = self.model
        return (model.friction(state, links), model.shift(state, links), model.shear_cohesion(state, links),
                *model.secants(state, links))

    def _book_contact_work(self, shift, cohesion_T, joint):
        """Book the work the reactions of this step did, -sum weight r . (g_{n+1} - g_{n-1}) / 2,
        its share of the discrete energy balance (solver/imex.py), from the jump increments
        of this step and the last (h B v_{n+1/2} + h B v_{n-1/2}, link frame), split by
        energy.reaction_work with the step's shift and cohesion_T (Pa, per star link): the
        cohesion's work is stored in the rigid links of the model (model.absorb), the rest
        is dissipated by contact and friction, less the work on the rigid links' joints
        (their elastic jump increment of this step, ``joint`` (n, d) m: active_set.joint_jumps),
        which those store. The stars hold every link of the rank once."""
        lay = self.layout
        # the joints' elastic jump increments of this step and the last
        self._joint_before += joint
        # the star links are every link once: _absorbed is overwritten whole
        self.contact_dissipated += book_reaction_work(self._r, self._slip, self._slip_before, self._joint_before,
                                                      shift, cohesion_T, lay.weight, lay.links, self._absorbed)
        self._joint_before[:] = joint
        self.model.absorb(self._absorbed)


def _call(function, *args):
    return function(*args)


class ConvergenceError(RuntimeError):
    """Vertex stars whose Newton did not converge (the runner saves the state first)."""
