"""Each star's semi-smooth Newton, in one loop over the stars (solve_each): its start (zero,
or the prediction of its stored factors), its iterations (full steps, backtracking,
Gauss-Seidel, restart: StarOptions), which matrix each step solves with (the stored
factors, a chord, a Woodbury correction, a fresh Jacobian), and what the star keeps of
them for the next step."""
from collections import namedtuple

import numpy as np
from numba import njit

from dolfrag.solver.active_set import CONTACT, SLIP, SPRING, affine_constant
from dolfrag.solver.stars.blocks import give_back, take
from dolfrag.solver.stars.gauss_seidel import gauss_seidel
from dolfrag.solver.stars.jacobian import factor_jacobian, flip_rows, kind_of, note_factored
from dolfrag.solver.stars.lu import solve_star, woodbury_factor, woodbury_solve
from dolfrag.solver.stars.options import sweep_tolerance
from dolfrag.solver.stars.records import (APPROXIMATE, CONVERGED, EXACT, ITERATIONS, N_FIRST, N_STALLED,
                                          N_UNCONVERGED, NONE, RIGID, STALE, STALLED, UNCONVERGED, star_at)
from dolfrag.solver.stars.residual import B_SCALE, evaluate
from dolfrag.solver.stars.rigid import held_piece

# Newton's workspaces, sized for the largest star of a call (q_max components, L_max links,
# N_max unknowns): the iterate (x, r); the piece and data the star started from (code_in,
# factored_in); the step, its direction and the iterates backtracking and the fallback go
# back to; solve_star's (work, nonzero) and factor_jacobian's (position); the Woodbury
# correction's (U, V, Z (2 flips, N_max), the capacitance and its pivots, t; the flipped
# links and the (link, piece) pairs it was built for); the factors Newton forms for a star
# whose stored ones are APPROXIMATE (held_store, held_index, held_code) or that has no block
# (held_store: blocks.py); and per link the slip direction and scale of Newton's last
# factors (formed_at).
NewtonSpace = namedtuple("NewtonSpace", "x r code_in factored_in delta direction best_x best_r base_x base_r work "
                                        "position nonzero U V Z cap cap_piv t flipped built held_store held_index "
                                        "held_code formed_at")


@njit(cache=True, error_model="numpy")
def newton_space(d, q_max, L_max, flips):
    """A NewtonSpace for stars of up to q_max components and L_max links, Woodbury
    corrections of up to ``flips`` links."""
    N_max = q_max + L_max * d
    return NewtonSpace(np.empty(q_max), np.empty((L_max, d)), np.empty(L_max, dtype=np.int8), np.empty((L_max, 3)),
                       np.empty(N_max), np.empty(N_max), np.empty(q_max), np.empty((L_max, d)), np.empty(q_max),
                       np.empty((L_max, d)), np.empty(N_max), np.empty(N_max + 3 * d, dtype=np.int64),
                       np.empty(N_max, dtype=np.int64), np.empty((2 * flips, N_max)), np.empty((2 * flips, N_max)),
                       np.empty((2 * flips, N_max)), np.empty(4 * flips * flips), np.empty(2 * flips, np.int64),
                       np.empty(2 * flips), np.empty(flips, np.int64), np.empty((flips, 2), np.int64),
                       np.empty(N_max * N_max), np.empty(2 * N_max + 1, np.int64), np.empty(L_max, np.int8),
                       np.empty((L_max, d)))


@njit(cache=True, error_model="numpy")
def solve_each(d, geometry, data, cache, out, options, ev, sw, nw, todo, abort):
    """Solve each star s where todo[s] (records: Geometry, StepData, Cache, Outputs;
    StarOptions) and write its outputs and what its stored factors are now
    (solvers.loop.solve_stars says what each means). ev, sw, nw: the workspaces of
    evaluate, gauss_seidel and Newton (Evaluation, SweepSpace, NewtonSpace). Returns
    unfinished where ``abort`` gets set.

    The stars the held path solved (rigid.held_stars, before this loop) are not in todo; a
    star it refused, or that reaches Newton with the path off, starts from zero if it had
    no factors (RIGID).

    The loop over the stars is here, with the record fields it reads taken into locals
    once: numba increfs every array of every record passed to a compiled function on entry
    and decrefs it on return (atomic NRT calls, which its reference-count pruning leaves in
    functions with branches), and a field read in a loop can cost such a pair per pass. A
    call per star taking the records (solve_one(s, geometry, data, cache, out, ..., nw),
    with _start and _finish) made ~370 of them per star, 3 us: the kernel was 62 % slower
    (benchmarks/step_cost.py --law rccm, see the commit). Per star only star_at and the
    per-iteration kernels are called, whose entry refcounts the pruning removes or few."""
    comp_off, link_off, elimination = geometry.comp_off, geometry.link_off, geometry.elimination
    rigid_off = geometry.rigid_off
    factors, blocks, block_at, pivots, piv_off = cache.factors, cache.blocks, cache.blocks.at, cache.pivots, \
        cache.piv_off
    codes, cached, factored, slip_dir = cache.codes, cache.cached, cache.factored, cache.slip_dir
    status, residual, counters = out.status, out.residual, out.counters
    x_out, reaction_out, r_out, gbar_out, slip_out = out.x, out.reaction, out.r, out.gbar, out.slip
    code, R, e, branch, reaction, gbar, slip = ev.code, ev.R, ev.e, ev.branch, ev.reaction, ev.gbar, ev.slip
    x_nw, r_nw, code_in, factored_in, delta, direction = nw.x, nw.r, nw.code_in, nw.factored_in, nw.delta, \
        nw.direction
    work, nonzero, formed_at = nw.work, nw.nonzero, nw.formed_at
    for s in range(len(comp_off) - 1):
        if abort[0]:
            return
        if not todo[s]:
            continue
        p0, l0 = comp_off[s], link_off[s]
        star = star_at(geometry, data, s)
        q, L = star.q, star.L
        N = q + L * d
        fixed, x_in = star.fixed, star.x_in
        if L == 0:  # lone copies (a corner of a single cell): no interface, explicit
            m, rhs = star.m, star.rhs
            for i in range(q):
                x_out[p0 + i] = x_in[i] if fixed[i] else rhs[i] / m[i]
                reaction_out[p0 + i] = (m[i] * x_in[i] - rhs[i]) / star.h if fixed[i] else 0.0
            status[s], residual[s] = CONVERGED, 0.0
            continue
        l1 = l0 + L
        xs, rs = x_nw[:q], r_nw[:L]
        r0, r1 = rigid_off[s], rigid_off[s + 1]
        if cached[s] == RIGID:  # no factors to predict with (the held path refused it, or is off)
            cached[s] = NONE
        # a star without a block (it kept no factors: blocks.py) forms Newton's in a workspace,
        # and takes one only if it keeps them
        loose = block_at[s] < 0
        at = 0 if loose else block_at[s]
        store = nw.held_store[:N * N] if loose else factors[at:at + N * N]
        index = pivots[piv_off[s]:piv_off[s] + 2 * N + 1]
        order = elimination[p0 + d * l0:p0 + d * l0 + N]
        scode = codes[l0:l1]
        # the start: zero but the prescribed increments, or, from the stored factors (store,
        # index), their affine prediction; the piece and data it starts from into code_in,
        # factored_in
        imposed = False
        for i in range(q):
            xs[i] = x_in[i] if fixed[i] else 0.0
            imposed = imposed or (fixed[i] and x_in[i] != 0.0)
        # reactions start from zero (or from this step's prediction), never from the last
        # step: while held links were rigid their reactions were determined only up to
        # self-equilibrated rings (see StarOptions.regularisation), which a warm start carried
        # from step to step until they choked the friction cones (measured: threshold and
        # linear-softening runs then failed to converge; cold, they complete)
        for l in range(L):  # with the piece and data the star starts from, element by element
            for i in range(d):  # (slice assignments cost more per star: measured)
                rs[l, i] = 0.0
            code_in[l] = codes[l0 + l]
            for i in range(3):
                factored_in[l, i] = factored[l0 + l, i]
        predicted = cached[s] != NONE and options.predict and not imposed  # imposed motion: not cached
        if predicted:
            affine_constant(d, star, codes[l0:l1], slip_dir[l0:l1], delta)
            solve_star(d, store, index, delta[:N], work, nonzero)
            for i in range(q):
                xs[i] = -delta[i]
            for l in range(L):
                for i in range(d):
                    rs[l, i] = -delta[q + i * L + l]
        start = cached[s] if predicted else NONE
        # Newton's matrix: its factors, its piece and what it is (the stored ones, except
        # for held-direction factors, which Newton leaves in place: see APPROXIMATE)
        held = cached[s] == APPROXIMATE
        kind = cached[s]
        if held:
            store, index = nw.held_store[:N * N], nw.held_index[:2 * N + 1]
            scode = nw.held_code[:L]
            scode[:] = code_in[:L]
            kind = NONE
        n_built, n_u = -1, 0  # how many flipped links the Woodbury correction was built for (-1: none)
        smooth = False  # store holds an exact Jacobian formed in this call at a 3D slip (_keep_newton_factors)
        has_best = False
        best_scaled, base_scaled, halvings = np.inf, np.inf, 0
        mark_scaled, mark_k, ending = np.inf, 0, False  # the best's last tenfold fall (StarOptions.plateau)
        chord_from = np.inf  # the residual the last chord step started from (none yet: inf)
        since = 0  # the iteration this start began after: the schedule (cycle, fallback) counts from it
        for iteration in range(1, options.max_iterations + 2):
            if abort[0]:  # a star may take seconds (semismooth.ESCALATION)
                return
            k = iteration - since
            scaled_m, scaled_c = evaluate(d, star, xs, rs, data.floor_m, data.floor_c, ev)
            scaled = max(scaled_m, scaled_c)
            last = iteration > options.max_iterations or ending  # the best iterate, evaluated once more
            done, stalled = _accepted(k, last, scaled_m, scaled_c, options)
            same = True
            for l in range(L):
                same = same and code[l] == scode[l]
            if iteration == 1 and done:
                counters[N_FIRST] += 1
            counters[ITERATIONS] = max(counters[ITERATIONS], iteration)
            if done or last:
                if done and smooth:  # Newton's last Jacobian, the next step's chord (_keep_newton_factors)
                    _keep_newton_factors(d, s, star, l0, held, nw, cache)
                    cached[s] = STALE
                else:
                    cached[s] = _kept(done, iteration == 1, predicted, held, kind, same,
                                            index[0] >= options.woodbury)
                if done and options.rigid and r1 > r0 and held_piece(code[:L], star.shift):
                    # closed and sticking on every link: the rigid path next, as keep_pieces
                    # decides for a star without factors (a star kept on its exact factors
                    # never went back to it: after a restart, none did)
                    for l in range(L):
                        codes[l0 + l] = code[l]
                    cached[s] = RIGID
                    give_back(blocks, s)
                elif loose and cached[s] != NONE:
                    at = take(blocks, s)
                    for i in range(index[0] * N):
                        factors[at + i] = store[i]
                # the outcome: status and counters, for an unconverged star what star_replay
                # needs to start it again (its entry pieces, data and start), its residual, and
                # the iterate with what evaluate left of it in ev
                if done:
                    status[s] = CONVERGED if scaled <= options.rtol else STALLED
                    if stalled:
                        counters[N_STALLED] += 1
                else:  # above give_up even at its best: the run stops (ConvergenceError)
                    status[s] = UNCONVERGED
                    counters[N_UNCONVERGED] += 1
                    out.entry_codes[l0:l1] = code_in[:L]
                    factored[l0:l1] = factored_in[:L]
                    out.entry_cached[s] = start
                residual[s] = scaled
                _write(d, p0, l0, q, L, xs, rs, reaction, gbar, slip, x_out, reaction_out, r_out, gbar_out, slip_out)
                break
            if predicted and iteration == options.restart:  # from zero, with the schedule of a start from zero
                for i in range(q):
                    xs[i] = x_in[i] if fixed[i] else 0.0
                rs[:, :] = 0.0
                since = options.restart
                continue
            if k >= options.fallback:
                if not has_best:
                    nw.best_x[:q], nw.best_r[:L], has_best = xs, rs, True
                if scaled < best_scaled:
                    nw.best_x[:q], nw.best_r[:L], best_scaled = xs, rs, scaled
                if best_scaled < 0.1 * mark_scaled or best_scaled <= options.give_up < mark_scaled:
                    mark_scaled, mark_k = best_scaled, k
                ending = best_scaled <= options.give_up and k - mark_k >= options.plateau
            if (iteration == options.max_iterations or ending) and has_best:
                xs[:], rs[:, :] = nw.best_x[:q], nw.best_r[:L]
                continue
            calls, off = divmod(k - options.fallback, options.polish + 1)
            if k >= options.fallback and off == 0:  # Newton wanders: Gauss-Seidel, then polish
                sweeps = min(options.sweeps * 2 ** calls, options.max_sweeps)
                gauss_seidel(d, star, xs, rs, ev.gbar, code, data.floor_c, sweeps, sweep_tolerance(options, d), sw)
                continue
            if options.cycle < k < options.fallback:  # a shorter step along the last direction
                if k == options.cycle + 1:
                    nw.base_x[:q], nw.base_r[:L], base_scaled, halvings = xs, rs, np.inf, 0
                    direction[:N] = 0.0
                if scaled >= base_scaled and halvings < options.shortest:
                    halvings += 1
                    _step_back(d, q, L, 0.5 ** halvings, nw)
                    continue
                nw.base_x[:q], nw.base_r[:L], base_scaled, halvings = xs, rs, scaled, 0
            # on the piece of its stored factors (an affine piece, whose Jacobian the piece
            # and the step's data determine) a star reuses them - a prediction only short
            # of regularisation is finished by them; stale ones while they contract (chord);
            # elsewhere a fresh Jacobian replaces them
            chord = kind == STALE and k < options.cycle and scaled <= options.chord * chord_from
            n_f = -1
            if kind == EXACT and not same and index[0] >= options.woodbury:
                n_f = _flips(star.frozen, scode, code, nw.flipped)
            if same and chord:
                chord_from = scaled
            elif n_f > 0:  # the stored factors and a Woodbury correction for the flipped links
                if _fresh(n_f, n_built, code, nw):
                    n_u = _woodbury_update(d, star, N, n_f, scode, code, store, index, nw, options.regularisation)
                    n_built = n_f
            elif not (kind == EXACT and same):
                factor_jacobian(d, star, code, ev, order, store, index, nw.position, options.regularisation)
                scode[:] = code[:L]
                if not held:
                    note_factored(star, factored[l0:l1])
                kind = EXACT if kind_of(d, star, code) == EXACT else NONE  # the exact Jacobian at the iterate
                smooth = kind == NONE
                if smooth:
                    for l in range(L):
                        for i in range(d - 1):
                            formed_at[l, i] = e[l, i]
                        formed_at[l, d - 1] = branch[l, B_SCALE]
                n_built = -1
            delta[:N] = R[:N]
            if n_f > 0:
                woodbury_solve(d, store, index, nw.V[:n_u, :N], nw.Z[:n_u, :N], nw.cap, nw.cap_piv, delta[:N], nw.t,
                               nw.work, nw.nonzero)
            else:
                solve_star(d, store, index, delta[:N], work, nonzero)
            if options.cycle < k < options.fallback:
                direction[:N] = -delta[:N]
            for i in range(q):
                xs[i] -= delta[i]
            for l in range(L):
                for i in range(d):
                    rs[l, i] -= delta[q + i * L + l]


@njit(cache=True, error_model="numpy")
def _write(d, p0, l0, q, L, x, r, reaction, gbar, slip, x_out, reaction_out, r_out, gbar_out, slip_out):
    """A star's iterate (x, r) and what evaluate left of it (reaction, gbar, slip) into the
    outputs (records.Outputs' arrays), at its first component p0 and link l0. (Arrays, not
    the records: see solve_each.)"""
    for i in range(q):
        x_out[p0 + i] = x[i]
        reaction_out[p0 + i] = reaction[i]
    for l in range(L):
        for i in range(d):
            r_out[l0 + l, i] = r[l, i]
            gbar_out[l0 + l, i] = gbar[l, i]
            slip_out[l0 + l, i] = slip[l, i]


@njit(cache=True, error_model="numpy")
def _accepted(k, last, scaled_m, scaled_c, options):
    """Whether an iterate with scaled residuals scaled_m, scaled_c at iteration k of its
    start (last: the best iterate, after max_iterations) is accepted, and whether as
    stalled (above stall, from fallback on: see StarOptions)."""
    scaled = max(scaled_m, scaled_c)
    if k < options.fallback:
        return scaled <= options.rtol, False
    done = scaled <= (options.give_up if last else options.stall) or (
        scaled_c <= options.stall and scaled_m <= options.give_up)
    return done, done and scaled > options.stall


@njit(cache=True, error_model="numpy")
def _kept(done, first, predicted, held, kind, same, large):
    """What a star's stored factors are after its solve (Cache.cached), unless Newton's last
    Jacobian was of a 3D slip (_keep_newton_factors). They stay valid if they are the
    Jacobian of the piece it converged on (same: then only damage can change them), or if
    they solved it by its prediction (first: at the first iteration): the iterate then sits
    on the kink between that piece and the one it reads (an intact link at g_N = 0, open or
    closed), where both solve the star to rtol (measured on the 3D bar: 114-207 stars a
    step, each factorised again for the next step's prediction, 6 % of the step); and a
    large star's exact factors stay its reference piece (see StarOptions.flips), whatever
    piece it ended on. Held-direction factors (held) stay where their prediction solved
    the star."""
    if held:
        return APPROXIMATE if done and first else NONE
    if done and kind == EXACT and ((first and predicted) or large):
        return kind
    if (kind == EXACT or kind == STALE) and same and done:
        return kind
    return NONE


@njit(cache=True, error_model="numpy")
def _step_back(d, q, L, alpha, nw):
    """The iterate alpha of the way along the last Newton direction from the base point
    backtracking returns to."""
    x, r, base_x, base_r, direction = nw.x, nw.r, nw.base_x, nw.base_r, nw.direction
    for i in range(q):
        x[i] = base_x[i] + alpha * direction[i]
    for l in range(L):
        for i in range(d):
            r[l, i] = base_r[l, i] + alpha * direction[q + i * L + l]


@njit(cache=True, error_model="numpy")
def _keep_newton_factors(d, s, star, l0, held, nw, cache):
    """A 3D star that converged after Newton's last Jacobian was formed at a slip keeps that
    Jacobian as its STALE factors: the next step predicts with them, and Newton uses them as
    a chord while they contract (StarOptions.chord), instead of starting from held-direction
    factors (APPROXIMATE) that keep_pieces forms again and that contract poorly. They are
    copied from the workspaces where its start was held (nw), else already in place; its slipping links' slip_dir get the direction
    and scale they were formed at, from which factor_piece forms them again. Measured on
    slab-3d-bending resumed at 0.1 s on 2 ranks, 150 steps, before, after, after, before:
    solve_stars 16.5-17.5 -> 15.1-16.7 ms, keep_pieces 6.8-7.2 -> 0.9 ms a step; the same
    broken links and fragments."""
    L = star.L
    N = star.q + L * d
    codes, slip_dir = cache.codes, cache.slip_dir
    if held:
        at = cache.blocks.at[s]
        store = cache.factors[at:at + N * N]
        index = cache.pivots[cache.piv_off[s]:cache.piv_off[s] + 2 * N + 1]
        held_store, held_index, held_code = nw.held_store, nw.held_index, nw.held_code
        n_c = held_index[0]
        for i in range(n_c * N):
            store[i] = held_store[i]
        for i in range(2 * N + 1):  # the condensed links' copies too, after the pivots
            index[i] = held_index[i]
        for l in range(L):
            codes[l0 + l] = held_code[l]
        note_factored(star, cache.factored[l0:l0 + L])
    formed_at = nw.formed_at
    for l in range(L):
        if codes[l0 + l] & SLIP:
            for i in range(d):
                slip_dir[l0 + l, i] = formed_at[l, i]


@njit(cache=True, error_model="numpy")
def _flips(frozen, scode, code, flipped):
    """How many links read another piece than scode, their indices into flipped; -1 if more
    than len(flipped), or if any is frozen or differs otherwise than in CONTACT and SPRING."""
    n = 0
    for l in range(len(frozen)):
        if code[l] != scode[l]:
            if frozen[l] or ((code[l] ^ scode[l]) & ~(CONTACT | SPRING)) != 0 or n == len(flipped):
                return -1
            flipped[n] = l
            n += 1
    return n


@njit(cache=True, error_model="numpy")
def _fresh(n_f, n_built, code, nw):
    """Whether the n_f links in nw.flipped, on their pieces ``code``, are other than those
    the Woodbury correction in nw was built for (n_built of them: nw.built)."""
    fresh = n_f != n_built
    flipped, built = nw.flipped, nw.built
    for i in range(n_f):
        fresh = fresh or flipped[i] != built[i, 0] or code[flipped[i]] != built[i, 1]
    return fresh


@njit(cache=True, error_model="numpy")
def _woodbury_update(d, star, N, n_f, scode, code, store, index, nw, regularisation):
    """Build in nw the Woodbury correction of the factors (store, index) of the piece scode,
    formed with ``regularisation``, for the n_f links in nw.flipped going to their pieces
    ``code``; returns its rank."""
    n_u = 0
    flipped, built, U, V = nw.flipped, nw.built, nw.U, nw.V
    for i in range(n_f):
        l = flipped[i]
        n_u += flip_rows(d, star, l, scode[l], code[l], U[n_u:n_u + 2, :N], V[n_u:n_u + 2, :N], regularisation)
        built[i, 0], built[i, 1] = l, code[l]
    woodbury_factor(d, store, index, nw.U[:n_u, :N], nw.V[:n_u, :N], nw.Z[:n_u, :N], nw.cap, nw.cap_piv, nw.work,
                    nw.nonzero)
    return n_u
