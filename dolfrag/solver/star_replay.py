"""The vertex stars a step could not solve, saved and solved again on their own.

When a star of the nonsmooth `imex` step ends above StarOptions.give_up
(solver/star_kernel.py), the run stops with ConvergenceError, and each rank writes its failed stars' kernel inputs to
``failed_stars_rank<r>.npz`` in the run's folder: a small flat layout of those stars alone
(the arrays of solve_stars' records, by their field names), the pieces their stored factors held and whether they
started from that prediction. Solving them again needs no mesh, no case and no MPI:

    dolfrag replay results/bunker-h2/failed_stars_rank0.npz [--max-iterations N]

prints, per star, its size, its links by piece, the residual of the run and that of the
replay (the same, to round-off, unless the kernel changed), so a change to the solver can be
tried on the exact star that failed.
"""
import numpy as np

from dolfrag.solver import star_kernel
from dolfrag.solver.active_set import CONTACT, SLIP, STICK
from dolfrag.solver.star_kernel import DEFAULT, Geometry, StepData, empty_cache, empty_outputs, star_at
from dolfrag.solver.stars.blocks import take

START = {star_kernel.NONE: "from zero", star_kernel.APPROXIMATE: "from its held-slip prediction",
         star_kernel.EXACT: "predicted", star_kernel.STALE: "predicted by stale factors"}
# the fields of the kernel's records (Geometry, StepData, Cache) a dump holds per component and
# per link, by the same names; of the rest, the scalars, and not the stars' elimination order
# and rigid inverses (Geometry), which replay forms again from their links
PER_COMP = ("mass", "fixed", "rhs", "x_in")
PER_LINK = ("slot_A", "slot_B", "frame", "weight", "rho", "frozen", "g_n", "dg", "mu", "shift", "cohesion_T", "k_N", "k_T",
            "codes", "slip_dir", "factored", "r_n")


def select(stars, comp_off, link_off, per_comp, per_link):
    """The flat layout of ``stars`` alone: (comp_off, link_off) rebased, and the rows of each
    array of per_comp (dict of arrays over the components) and per_link (over the star
    links) that belong to them."""
    q = comp_off[stars + 1] - comp_off[stars]
    L = link_off[stars + 1] - link_off[stars]
    comps = np.concatenate([np.arange(comp_off[s], comp_off[s + 1]) for s in stars])
    links = np.concatenate([np.arange(link_off[s], link_off[s + 1]) for s in stars])
    out = {"comp_off": np.concatenate([[0], np.cumsum(q)]), "link_off": np.concatenate([[0], np.cumsum(L)])}
    out.update({k: np.ascontiguousarray(v[comps]) for k, v in per_comp.items()})
    out.update({k: np.ascontiguousarray(v[links]) for k, v in per_link.items()})
    return out


def failed(stars, comps, geometry, data, cache, out, options):
    """The dump of ``stars`` (unconverged in the solve_stars call of these records: Geometry,
    StepData, Cache, Outputs, StarOptions) whose components are comps (local dof
    components): select's layout of their arrays, with the pieces and start they entered
    the call with (entry_codes as codes, entry_cached as cached), their residuals and the
    call's scalars."""
    fields = geometry._asdict() | data._asdict() | cache._asdict() | {"codes": out.entry_codes}
    arrays = select(stars, geometry.comp_off, geometry.link_off, {k: fields[k] for k in PER_COMP} | {"comps": comps},
                    {k: fields[k] for k in PER_LINK})
    arrays.update(cached=out.entry_cached[stars], residual=out.residual[stars], star=stars, h=data.h,
                  floor_m=data.floor_m, floor_c=data.floor_c, rtol=options.rtol, max_iterations=options.max_iterations,
                  predict=options.predict)
    return arrays


def dump(path, arrays, **context):
    """Write a failed-star layout (select's dict of PER_COMP and PER_LINK, plus cached and the
    scalars h, rtol, max_iterations, predict, floor_m, floor_c) and
    what the run knew of it (t, step, rank, residual) to path (.npz)."""
    np.savez(path, **arrays, **context)


def replay(path, regularisation=DEFAULT.regularisation, sweep_tol=DEFAULT.sweep_tol, plateau=DEFAULT.plateau,
           polish=DEFAULT.polish, **change):
    """Solve the stars of the dump at ``path`` again, each alone, from the start the run gave
    them; ``change`` overrides scalars (e.g. max_iterations); regularisation: on sticking
    links' reaction diagonals (a step's second pass takes semismooth.SECOND_REGULARISATION);
    sweep_tol: where Gauss-Seidel stops (its third pass: semismooth.LAST_SWEEP_TOL);
    plateau: StarOptions.plateau (a value above the iterations: the stars run to the end);
    polish: StarOptions.polish (the second pass: semismooth.SECOND_POLISH).
    Returns (status, residual, iterations) per star, star_kernel's status codes."""
    data = dict(np.load(path))
    data.update(change)
    comp_off, link_off, d = data["comp_off"], data["link_off"], data["frame"].shape[1]
    if data["slip_dir"].shape[1] < d:  # a dump of before slip_dir held the scales: directions held, scale 0
        data["slip_dir"] = np.pad(data["slip_dir"], ((0, 0), (0, d - data["slip_dir"].shape[1])))
    n = len(comp_off) - 1
    status, residual, iterations = np.zeros(n, np.int8), np.zeros(n), np.zeros(n, np.int64)
    for s in range(n):  # one call per star: the kernel counts iterations per call
        one = slice(s, s + 1)
        star = select(np.array([s]), comp_off, link_off, {k: data[k] for k in PER_COMP},
                      {k: data[k] for k in PER_LINK if k in data})
        geometry = star_kernel.star_geometry(*(star[k] for k in Geometry._fields[:-3]), float(data["h"]))
        elimination = geometry.elimination
        step = StepData(**{k: star[k] for k in StepData._fields[:-4]}, h=float(data["h"]),
                        floor_m=float(data["floor_m"]), floor_c=float(data["floor_c"]),
                        r_n=star["r_n"] if "r_n" in star else np.zeros_like(star["g_n"]))
        q, L = star["comp_off"][1], star["link_off"][1]
        N = q + L * d
        cache = empty_cache(star["comp_off"], star["link_off"], d)._replace(
            codes=star["codes"], slip_dir=star["slip_dir"], cached=data["cached"][one].copy(),
            factored=star["factored"].copy())
        if cache.cached[0] != star_kernel.NONE:  # the stored factors its prediction used
            k_N, k_T, mu = star["factored"].T.copy()  # the data they were formed with, by the run's first pass
            at = take(cache.blocks, 0)
            star_kernel.factor_piece(d, star_at(geometry, step._replace(mu=mu, k_N=k_N, k_T=k_T), 0), cache.codes,
                                     cache.slip_dir, elimination, cache.factors[at:at + N * N], cache.pivots,
                                     np.empty(N + 3 * d, np.int64), star_kernel.evaluation(d, q, L),
                                     DEFAULT.regularisation)
        out = empty_outputs(1, q, L, d)
        options = DEFAULT._replace(rtol=float(data["rtol"]), max_iterations=int(data["max_iterations"]),
                                   predict=bool(data["predict"]), regularisation=float(regularisation),
                                   sweep_tol=float(sweep_tol), plateau=int(plateau), polish=int(polish))
        star_kernel.solve_stars(geometry, step, cache, out, options)
        status[s], residual[s], iterations[s] = out.status[0], out.residual[0], out.counters[star_kernel.ITERATIONS]
    return status, residual, iterations


def describe(path):
    """One line per star of the dump: its size, its links by piece, the run's residual."""
    data = np.load(path)
    comp_off, link_off = data["comp_off"], data["link_off"]
    lines = [f"{path}: t = {float(data['t']):.6g} s, step {int(data['step'])}, rank {int(data['rank'])}"]
    for s in range(len(comp_off) - 1):
        codes = data["codes"][link_off[s]:link_off[s + 1]]
        contact, stick, slip = ((codes & bit) > 0 for bit in (CONTACT, STICK, SLIP))
        lines.append(f"star {s}: {comp_off[s + 1] - comp_off[s]} components, {len(codes)} links "
                     f"({contact.sum()} in contact, {stick.sum()} sticking, {slip.sum()} slipping), "
                     f"{START[int(data['cached'][s])]}, run's residual {data['residual'][s]:.3g}")
    return "\n".join(lines)


def report(path, max_iterations=None):
    """describe(path) and, per star, how the replay ended (max_iterations: the run's if None)."""
    change = {} if max_iterations is None else {"max_iterations": max_iterations}
    names = {star_kernel.CONVERGED: "converged", star_kernel.STALLED: "stalled (accepted)",
             star_kernel.UNCONVERGED: "unconverged"}
    lines = [describe(path)]
    for s, (status, residual, iterations) in enumerate(zip(*replay(path, **change))):
        lines.append(f"star {s}: replay {names[int(status)]}, residual {residual:.3g} after {iterations} iterations")
    return "\n".join(lines)
