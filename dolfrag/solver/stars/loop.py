"""The compiled loops over a rank's stars: gather a step's data, solve every star (each
one's Newton in newton.py), and keep the factors of the pieces they converged on for the
next step's prediction (solver/active_set.py)."""
import numpy as np
from numba import njit

from dolfrag.solver.active_set import SLIP
from dolfrag.solver.stars.blocks import give_back, take
from dolfrag.solver.stars.gauss_seidel import sweep_space
from dolfrag.solver.stars.jacobian import factor_piece, kind_of, note_factored
from dolfrag.solver.stars.newton import newton_space, solve_each
from dolfrag.solver.stars.options import DEFAULT
from dolfrag.solver.stars.ordering import unknown_orders
from dolfrag.solver.stars.records import NONE, RIGID, Geometry, StepData, empty_cache, empty_outputs, star_at
from dolfrag.solver.stars.rigid import held_piece, held_stars, rigid_inverses
from dolfrag.solver.stars.residual import evaluation, evaluate


def star_geometry(comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed, h):
    """The layout's record (records.Geometry) of these arrays, with what it derives from them
    and the step h (s): each star's elimination order and rigid inverse."""
    d = frame.shape[1]
    return Geometry(comp_off, link_off, slot_A, slot_B, frame, weight, rho, frozen, mass, fixed,
                    unknown_orders(comp_off, link_off, slot_A, slot_B, d),
                    *rigid_inverses(comp_off, link_off, slot_A, slot_B, weight, rho, fixed, frozen, mass, h, d))


@njit(cache=True, error_model="numpy")
def gather_stars(comps, geometry, u, v, f, prescribed, data):
    """What solve_stars reads of the flat fields (over local components), into data
    (records.StepData, its h in s): per star link, g_n (L_total, d) = frame (u_B - u_A) (m)
    and dg = h frame (v_B - v_A) (m), the jumps of u and h v in its link frame (normal
    first); per star component (comps), rhs = h f (N s) and x_in = prescribed (m/s: the
    prescribed increments)."""
    h, rhs, x_in = data.h, data.rhs, data.x_in
    for i in range(len(comps)):
        rhs[i] = h * f[comps[i]]
        x_in[i] = prescribed[comps[i]]
    if geometry.frame.shape[1] == 2:  # the dimension a compile-time constant, as in solve_stars
        _gather_jumps(2, comps, geometry.comp_off, geometry.link_off, geometry.slot_A, geometry.slot_B,
                      geometry.frame, u, v, h, data.g_n, data.dg)
    else:
        _gather_jumps(3, comps, geometry.comp_off, geometry.link_off, geometry.slot_A, geometry.slot_B,
                      geometry.frame, u, v, h, data.g_n, data.dg)


@njit(cache=True, error_model="numpy")
def _gather_jumps(d, comps, comp_off, link_off, slot_A, slot_B, frame, u, v, h, g_out, dg_out):
    """gather_stars' jumps g_n and dg, in d dimensions (d a compile-time constant), each
    star's copies of u and v read once into u_s, v_s: 0.86 ms of CPU a call on the 31,632
    links of bunker-h2 at 0.2 m, against 1.09 ms reading them per link with d a variable."""
    q_max, _ = _largest(comp_off, link_off, np.arange(len(comp_off) - 1))
    u_s, v_s = np.empty(q_max), np.empty(q_max)
    for s in range(len(comp_off) - 1):
        p0 = comp_off[s]
        for i in range(comp_off[s + 1] - p0):  # the star's copies once, not once per link
            u_s[i], v_s[i] = u[comps[p0 + i]], v[comps[p0 + i]]
        for l in range(link_off[s], link_off[s + 1]):
            a, b = slot_A[l] * d, slot_B[l] * d
            for i in range(d):
                g, dg = 0.0, 0.0
                for j in range(d):
                    g += frame[l, i, j] * (u_s[b + j] - u_s[a + j])
                    dg += frame[l, i, j] * (v_s[b + j] - v_s[a + j])
                g_out[l, i] = g
                dg_out[l, i] = h * dg


@njit(cache=True, error_model="numpy", nogil=True)
def solve_stars(geometry, data, cache, out, options, todo=None, abort=None):
    """Solve every star of the rank for this step (with ``todo``, a per-star bool array, only
    those where it is True: the others' outputs are left as they are).

    geometry, data, cache, out: the records of stars/records.py; options: StarOptions. The
    cache holds each star's last Jacobian, piece and slip directions, what they are good
    for (NONE, APPROXIMATE, EXACT, STALE), and per link the (k_N, k_T, mu) they were formed
    with; Newton's Jacobians replace them (not APPROXIMATE ones: Newton then works in
    workspaces), and ``cached`` stays EXACT or STALE only where the star converged on the
    piece of its stored factors, APPROXIMATE where their prediction solved it, EXACT where
    an exact prediction solved it or where they are a large star's reference piece
    (StarOptions.flips), becomes STALE where Newton's last Jacobian was of a 3D slip
    (newton._keep_newton_factors; slip_dir then holds the directions and scales it was
    formed at), RIGID where the star converged closed and sticking on every link and
    qualifies for the rigid path (its block given back: blocks.py), else NONE.

    Writes into ``out`` x, reaction (N) per component; r (Pa), gbar, slip (the springs' jump
    and the step's jump increment g_{n+1} - g_n = h B (v_- + x), m) per link; per star
    status (CONVERGED, STALLED, UNCONVERGED) and its final scaled residual; counters: the
    most iterations, the unconverged and stalled stars, the stars solved at iteration 1. For
    an unconverged star only, what star_replay needs to start it as this call did: the
    pieces of its stored factors (entry_codes, per link) and what they were if it started
    from their prediction (entry_cached; NONE if it started from zero), and in
    cache.factored the data they were formed with. ``abort``: a one-element int8 array
    another thread may set (a stop request, solver/interrupt.py): the call then returns
    within one Newton iteration, its outputs unfinished. It releases the GIL, so that such a
    thread can run.
    """
    if todo is None:
        todo = np.ones(len(geometry.comp_off) - 1, dtype=np.bool_)
    if abort is None:
        abort = np.zeros(1, dtype=np.int8)
    if geometry.frame.shape[1] == 2:  # the dimension a compile-time constant: see _solve_stars
        _solve_stars(2, geometry, data, cache, out, options, todo, abort)
    else:
        _solve_stars(3, geometry, data, cache, out, options, todo, abort)


@njit(cache=True, error_model="numpy")
def _largest(comp_off, link_off, stars):
    """The most components and the most links of ``stars``."""
    q_max, L_max = 0, 0
    for s in stars:
        q_max = max(q_max, comp_off[s + 1] - comp_off[s])
        L_max = max(L_max, link_off[s + 1] - link_off[s])
    return q_max, L_max


@njit(cache=True, error_model="numpy")
def _solve_stars(d, geometry, data, cache, out, options, todo, abort):
    """solve_stars in d dimensions, d a compile-time constant: the loops over the
    components of a link are then unrolled (measured on captured steps of the damaged bars:
    a 2D call 21.5 -> 18.4 ms, 3D 91.4 -> 87.5 ms)."""
    n_stars = len(geometry.comp_off) - 1
    q_max, L_max = _largest(geometry.comp_off, geometry.link_off, np.arange(n_stars))
    # workspaces, once per call
    ev, sw = evaluation(d, q_max, L_max), sweep_space(d, q_max, L_max)
    nw = newton_space(d, q_max, L_max, options.flips)
    newton = todo
    if options.rigid and not abort[0]:  # the held stars first; Newton for the others (newton = todo less those solved)
        newton = np.empty_like(todo)
        held_stars(d, geometry, data, cache, out, options.rtol, todo, newton, np.empty(q_max), np.empty(q_max))
    solve_each(d, geometry, data, cache, out, options, ev, sw, nw, newton, abort)


@njit(cache=True, error_model="numpy")
def keep_pieces(stars, geometry, data, x, r, cache, options):
    """Store, for the next step's prediction, the LU factors of the Jacobian of the piece
    each of ``stars`` converged on (x per component, r per link), its slip directions held
    (factor_piece), with the friction, cohesion and springs of ``data`` (after the step);
    ``cached`` says what they are (kind_of). A star that qualifies for the rigid path
    (stars/rigid.py) and converged closed and sticking on every link stores no factors, only
    that piece (RIGID), where options.rigid, and gives its block back (blocks.py). Records as
    solve_stars; of ``options`` only the regularisation (the stored factors are Newton's
    matrix) and ``rigid`` are read."""
    if geometry.frame.shape[1] == 2:  # the dimension a compile-time constant, as in solve_stars
        _keep_pieces(2, stars, geometry, data, x, r, cache, options.regularisation, options.rigid)
    else:
        _keep_pieces(3, stars, geometry, data, x, r, cache, options.regularisation, options.rigid)


@njit(cache=True, error_model="numpy")
def _keep_pieces(d, stars, geometry, data, x, r, cache, regularisation, rigid):
    """keep_pieces in d dimensions, d a compile-time constant (see _solve_stars)."""
    q_max, L_max = _largest(geometry.comp_off, geometry.link_off, stars)
    ev = evaluation(d, q_max, L_max)
    position = np.empty(q_max + L_max * d + 3 * d, dtype=np.int64)
    for s in stars:
        p0, l0 = geometry.comp_off[s], geometry.link_off[s]
        star = star_at(geometry, data, s)
        q, L = star.q, star.L
        N = q + L * d
        if L == 0:  # no interface, no factors
            cache.cached[s] = NONE
            continue
        l1 = l0 + L
        evaluate(d, star, x[p0:p0 + q], r[l0:l1], 0.0, 0.0, ev)
        code, e = ev.code, ev.e
        if rigid and geometry.rigid_off[s + 1] > geometry.rigid_off[s] and held_piece(code[:L], star.shift):
            cache.codes[l0:l1] = code[:L]  # no factors: the rigid path (stars/rigid.py) next
            cache.cached[s] = RIGID
            give_back(cache.blocks, s)
            continue
        for l in range(L):
            if code[l] & SLIP:
                cache.slip_dir[l0 + l, :d - 1] = e[l, :d - 1]
                cache.slip_dir[l0 + l, d - 1] = 0.0
        at = take(cache.blocks, s)
        factor_piece(d, star, code[:L], cache.slip_dir[l0:l1], geometry.elimination[p0 + d * l0:p0 + d * l0 + N],
                     cache.factors[at:at + N * N],
                     cache.pivots[cache.piv_off[s]:cache.piv_off[s] + 2 * N + 1], position, ev, regularisation)
        cache.codes[l0:l1] = code[:L]
        note_factored(star, cache.factored[l0:l1])
        cache.cached[s] = kind_of(d, star, code)


def warm():
    """Compile the kernels (2D and 3D) into numba's cache on a tiny star of each."""
    for d in (2, 3):
        q, L = 2 * d, 1
        comp_off, link_off, slot_A, slot_B = np.array([0, q]), np.array([0, L]), np.array([0]), np.array([1])
        frame = np.eye(d)[None].copy()
        geometry = star_geometry(comp_off, link_off, slot_A, slot_B, frame, np.ones(L), np.ones(L), np.zeros(L, bool),
                                 np.ones(q), np.zeros(q, bool), 1.0)
        data = StepData(np.ones(q), np.zeros(q), np.zeros((L, d)), np.zeros((L, d)), np.zeros(L), np.zeros(L),
                        np.zeros(L), np.ones(L), np.ones(L), 1.0, 0.0, 0.0, np.zeros((L, d)))
        cache = empty_cache(comp_off, link_off, d)
        solve_stars(geometry, data, cache, empty_outputs(1, q, L, d), DEFAULT)
        keep_pieces(np.array([0]), geometry, data, np.zeros(q), np.zeros((L, d)), cache, DEFAULT)
        gather_stars(np.arange(q), geometry, *(np.zeros(q) for _ in range(4)), data)
