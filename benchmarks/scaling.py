"""Parallel scaling of the imex step: measured at 1, 2, 4, ... ranks, predicted at 16, 128, 1024.

    python benchmarks/scaling.py [--cases 3d 2d bunker] [--ranks 1 2 4] [--elastic] [--set SECTION.KEY=VALUE ...]
        [--clock wall|cpu] [--repeat 1] [--fit-fractions 0.125 0.25 0.5] [--partition-sizes 0.015] [--json FILE]
    mpirun -n P python benchmarks/scaling.py [--cases 3d]     # this rank count's rows only

Measured: each case runs under ``mpirun -n P`` (dolfrag.run, quiet), and two
independent serial copies run at once (the 2-core baseline: two memory-bound processes slow
each other down). From summary.json -> timings_s: wall time per step of the time loop (sum of
the phases' means over ranks), parallel efficiency t_1 / (P t_P) and t_copy / (2 t_2), and each
phase's share. Beyond the cores (--oversubscribe) rows measure correctness and overheads only.

Predicted, for the 3D slab at production size (1 m x 1 m x 0.1 m, --production-cells N), and
with --cases bunker for bunker-h2's own geometry (its fine mesh: --production-cells 1167137):
    t_P = t0 + max_p(t1_bulk owned_p + t1_rest star_p)      compute, slowest part
          + X (c + t_msg(k, b))                            X ghost updates per step
          + A ceil(log2 P) tau                             A Allreduce per step
    E_P = (t0 + t1 N) / (P t_P),  t1 = t1_bulk + t1_rest
t0, t1_bulk, t1_rest: fitted to the compute time per step of a rank (time loop without
communication and output) against its cells n. The slab's points are 1-rank runs of the 3D
case shrunk laterally at the same mesh size. The bunker does not shrink without changing its
physics: its points are its own mesh split over the measured rank counts (use --clock cpu, so
that ranks beyond the cores count their own work only). owned_p, star_p
(halo.Halo.star_cells), k (largest neighbour count), b (largest bytes sent or received
per update): star partitions of the case's mesh into P parts on one process, scaled to N cells
(b by the surface-to-volume law). c:
DOLFINx's own cost per scatter beyond its messages (a 2-rank scatter less the ping-pong model).
t_msg: the 2-rank exchange of k messages, b bytes each way, measured here (shared memory),
or k alpha + b beta with an assumed cluster network; tau: a 2-rank Allreduce here, or assumed.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfrag  # BLAS thread limit, VTK before DOLFINx
import dolfrag.timing
import halo  # beside this script
from dolfrag import compat, mesh, space as spaces
from dolfrag.case import builtin_cases, load_case
from dolfrag.timing import PHASES

SLAB = "slab-3d-scabbing"
LAW = ["interface.law=rccm", "interface.sigma_c=10e6", "interface.mu=0.3"]  # the slab's law
OUTPUT = ["output.every=10", "output.fields=2", "output.figures=false"]
BOX = ["geometry.kind=box", "geometry.thickness=0.02", 'supports.rollers=["bottom","top","front","back"]']
PRODUCTION = ["geometry.kind=box", "geometry.length=1.0", "geometry.width=1.0", "geometry.thickness=0.1"]
# assumed inter-node network (not measured here): latency per message and per Allreduce
# tree level (s), bandwidth (B/s)
CLUSTER = {"alpha": 1.5e-6, "beta": 1 / 10e9, "tau": 1.5e-6}
PREDICT_RANKS = (16, 128, 1024)
TRIALS = 15  # timings of the network: repeated means, the smallest kept


def presets(elastic=False):
    """{key: (case, overrides, extents)}: the fixed cases, and the lateral extents (m) that
    the t(n) fit shrinks. The 3D one is a reduced slab once that case exists, else a 3D box
    version of sound-bar with the slab's interface law (with ``elastic``: sound-bar's
    elastic springs, the cheapest step). The bunker runs as built, to the end of its load
    (no extents: its t(n) points are its rank counts)."""
    law = [] if elastic else LAW
    if SLAB in builtin_cases() and not elastic:
        three = (SLAB, ["geometry.length=0.2", "geometry.width=0.2", "mesh.size=0.015", "time.end=1e-5", *OUTPUT],
                 {"length": 0.2, "width": 0.2})
    else:
        three = ("sound-bar", [*BOX, *law, "mesh.size=0.004", "time.end=4e-6", *OUTPUT], {"length": 0.12})
    return {"3d": three, "2d": ("sound-bar", [*law, "mesh.size=0.001", "time.end=3e-6", *OUTPUT], {"length": 0.12}),
            "bunker": ("bunker-h2", OUTPUT, None)}


def shrunk(extents, fraction):
    """Overrides scaling the lateral extents so the cell count is about ``fraction`` of theirs
    (same mesh size, so the same stars and time step)."""
    scale = fraction ** (1 / len(extents))
    return [f"geometry.{k}={scale * v:.6g}" for k, v in extents.items()]


def env():
    """The environment of the runs started here: without the variables of an mpirun this
    script may itself run under (Open MPI refuses recursive calls)."""
    mine = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_", "OPAL_", "ORTE_"))}
    return dict(mine, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OPENBLAS_NUM_THREADS="1")


def mpirun(n, args):
    """The mpirun command line for ``python args`` on n ranks (not bound to cores, like the
    serial copies; oversubscribed beyond the cores)."""
    over = ["--oversubscribe"] if n > os.cpu_count() else []
    return ["mpirun", "-n", str(n), "--bind-to", "none", *over, sys.executable, *map(str, args)]


def worker(case, sets, out, clock):
    """The arguments that make this script run ``case`` once into ``out`` (run_case)."""
    return [__file__, "--run", case, out, "--clock", clock, *(a for s in sets for a in ("--set", s))]


def run_case(case, sets, out, clock, comm=MPI.COMM_WORLD):
    """dolfrag.run of the case, its phases timed by ``clock``: "wall", or "cpu", the CPU
    seconds of each process (time.process_time: on a loaded machine, without the time a rank
    was descheduled; a rank waiting for another spins, so waits still count). Collective.

    The case runs one step first, untimed: numba loads each compiled kernel from its cache at
    the kernel's first call in a process, once (0.11 s in the 3D case at 972 cells, measured),
    which these runs of ~30 steps would otherwise count as ~3 ms a step, a fixed cost that
    production runs of ~10^5 steps do not have."""
    with tempfile.TemporaryDirectory() as warm:
        dolfrag.run(load_case(case, [*sets, "time.end=1e-12"]), comm.bcast(warm, root=0), quiet=True, comm=comm)
        comm.barrier()
    if clock == "cpu":  # PhaseTimer takes no clock argument: swap the one it reads
        dolfrag.timing.perf_counter = time.process_time
    return dolfrag.run(load_case(case, sets), out, quiet=True, comm=comm)


def per_step(summary):
    """Seconds per step of the time loop, by phase (mean over ranks) and total, plus the
    largest rank's communication time."""
    t, n = summary["timings_s"], summary["steps_done"]
    phases = {p: t[p]["mean"] / n for p in PHASES}
    return {"label": str(summary["ranks"]), "cells": summary["cells"], "ranks": summary["ranks"],
            "steps": n, "phases": phases, "total": sum(phases.values()),
            "communication_max": t["communication"]["max"] / n, "copies": 1, "efficiency": None,
            "interface_imbalance": t["interface"]["max"] / max(t["interface"]["mean"], 1e-300)}


def launch(n, case, sets, out, clock, copies=1, repeat=1):
    """Run the case under mpirun -n n (``copies`` independent runs started together);
    per_step of each, from the fastest of ``repeat`` such launches (the least disturbed by
    other work on the machine)."""
    runs = [_launch(n, case, sets, f"{out}-{r}", clock, copies) for r in range(repeat)]
    return min(runs, key=lambda rows: np.mean([row["total"] for row in rows]))


def _launch(n, case, sets, out, clock, copies):
    outs = [Path(f"{out}-{c}") for c in range(copies)]
    procs = [subprocess.Popen(mpirun(n, worker(case, sets, o, clock)), env=env(), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for o in outs]
    for p in procs:
        stdout, stderr = p.communicate()
        if p.returncode:
            raise RuntimeError(f"{' '.join(p.args)} failed:\n{stdout}\n{stderr[-3000:]}")
    return [per_step(json.loads((o / "summary.json").read_text())) for o in outs]


def measure_case(key, case, sets, ranks, tmp, clock, repeat):
    """Rows of the measured table for one case: each rank count, and the two serial copies."""
    rows = [launch(p, case, sets, f"{tmp}/{key}-{p}", clock, repeat=repeat)[0] for p in ranks]
    copies = launch(1, case, sets, f"{tmp}/{key}-copy", clock, copies=2, repeat=repeat)
    pair = dict(copies[0], total=np.mean([c["total"] for c in copies]), label="1 (two copies at once)", copies=2,
                phases={p: np.mean([c["phases"][p] for c in copies]) for p in PHASES},
                communication_max=max(c["communication_max"] for c in copies), interface_imbalance=None)
    one = next((r["total"] for r in rows if r["ranks"] == 1), None)
    for r in rows:
        if one is not None:
            r["efficiency"] = one / (r["ranks"] * r["total"])
        if r["ranks"] == 2:
            r["efficiency_copies"] = pair["total"] / (2 * r["total"])
    return rows + [pair]


def shares(r):
    """Per cent of a step in bulk, interface (the hard stars' passes included),
    communication (mean over ranks; the largest rank's), output, and the rest (update,
    diagnostics)."""
    ph, total = r["phases"], r["total"]
    parts = (ph["bulk"], ph["interface"] + ph["hard_stars"], ph["communication"], r["communication_max"], ph["output"],
             ph["update"] + ph["diagnostics"] + ph["implicit"])
    return [100 * x / total for x in parts]


def print_measured(key, case, sets, rows):
    print(f"\n### Measured: {key} ({case} {' '.join('--set ' + s for s in sets)})\n")
    print("| ranks | cells | steps | ms / step | efficiency vs 1 rank | vs two copies | bulk % | interface % "
          "| communication % (largest rank) | output % | update + diagnostics % | interface max / mean |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    for r in rows:
        eff = "" if r.get("efficiency") is None else f"{100 * r['efficiency']:.0f} %"
        vs = f"{100 * r['efficiency_copies']:.0f} %" if "efficiency_copies" in r else ""
        bulk, interface, comm, comm_max, output, rest = shares(r)
        print(f"| {r['label']} | {r['cells']:,} | {r['steps']} | {1e3 * r['total']:.2f} | {eff} | {vs} | "
              f"{bulk:.0f} | {interface:.0f} | {comm:.0f} ({comm_max:.0f}) | {output:.0f} | {rest:.0f} | "
              f"{'' if r['interface_imbalance'] is None else format(r['interface_imbalance'], '.2f')} |")


def fit_cost(rows):
    """t(n) = t0 + t1 n: a rank's compute time per step (the mean over ranks of all phases but
    communication and output) against its cells n = cells / ranks, fitted to the rows, with
    the standard error of t0 (None below 4 points); of t1, the bulk phase's share t1_bulk
    (fitted through the origin: K u has no fixed cost to speak of) and the rest.
    {t0, t0_fit, t0_error, t1, t1_bulk, t1_rest, points}; t0 is the fit's, floored at 0 (a
    negative intercept means none is resolved)."""
    n = np.array([r["cells"] / r["ranks"] for r in rows])
    bulk = np.array([r["phases"]["bulk"] for r in rows])
    t = np.array([r["total"] - r["phases"]["communication"] - r["phases"]["output"] for r in rows])
    if len(n) > 3:
        (t1, t0), cov = np.polyfit(n, t, 1, cov=True)
        error = float(np.sqrt(cov[1, 1]))
    else:
        (t1, t0), error = np.polyfit(n, t, 1), None
    t1_bulk = float(n @ bulk / (n @ n))
    return {"t0": max(float(t0), 0.0), "t0_fit": float(t0), "t0_error": error, "t1": float(t1), "t1_bulk": t1_bulk,
            "t1_rest": float(t1) - t1_bulk, "points": sorted((float(c), float(x)) for c, x in zip(n, t))}


def partition(geometry, size, parts):
    """Serial star partitions of the mesh of ``geometry`` at ``size`` (m) into each number
    of parts: {P: Halo}, the cell count and the seconds taken (mesh, partition + count)."""
    start = time.perf_counter()
    domain = mesh.build(geometry, size, MPI.COMM_SELF)
    tdim = domain.tdim
    c2v = compat.adjacency_array(domain.mesh.topology.connectivity(tdim, 0), tdim + 1).astype(np.int64)
    del domain
    built = time.perf_counter()
    halos = {P: halo.star_halo(c2v, compat.serial_cell_owners(c2v, P), P) for P in parts}
    return halos, len(c2v), (built - start, time.perf_counter() - built)


def pattern(part):
    """(largest neighbour count, largest bytes sent or received per update) over the parts."""
    return int(part["k"].max()), int(part["bytes"].max())


def timed(comm, fn, reps):
    """Seconds per call of fn: the mean over ``reps`` calls (the slowest rank's), of TRIALS
    such means the smallest (the uncontended cost: the model's) and the median (this machine
    under its load). Collective."""
    times = []
    for _ in range(TRIALS):
        comm.Barrier()
        start = time.perf_counter()
        for _ in range(reps):
            fn()
        times.append(comm.allreduce((time.perf_counter() - start) / reps, op=MPI.MAX))
    return {"min": float(np.min(times)), "median": float(np.median(times))}


def network(comm, patterns):
    """On 2 ranks: one-way ping-pong time by message size and its fit alpha + beta s, the
    Allreduce of 2 doubles, and each exchange pattern (k messages of b / k bytes each way at
    once: Isend / Irecv / Waitall), each ``timed``. Collective."""
    other = 1 - comm.rank

    one_way = {}
    for size in (8, 512, 4096, 32768, 262144, 2097152):
        buf = np.zeros(size, np.uint8)

        def ping():
            if comm.rank == 0:
                comm.Send(buf, other)
                comm.Recv(buf, other)
            else:
                comm.Recv(buf, other)
                comm.Send(buf, other)
        one_way[size] = {k: v / 2 for k, v in timed(comm, ping, max(10, min(2000, 2 ** 24 // size))).items()}
    sizes = np.array(list(one_way), float)
    t = np.array([o["min"] for o in one_way.values()])
    beta, alpha = np.polyfit(sizes, t, 1, w=1 / t)  # relative errors: latency and bandwidth both count
    x, y = np.zeros(2), np.zeros(2)
    tau = timed(comm, lambda: comm.Allreduce(x, y, op=MPI.MAX), 2000)
    exchanges = []
    for k, nbytes in patterns:
        send = [np.zeros(max(1, nbytes // k), np.uint8) for _ in range(k)]
        recv = [np.zeros_like(a) for a in send]

        def exchange():
            reqs = [comm.Irecv(r, other, tag=i) for i, r in enumerate(recv)]
            reqs += [comm.Isend(a, other, tag=i) for i, a in enumerate(send)]
            MPI.Request.Waitall(reqs)
        exchanges.append({"k": k, "bytes": nbytes, **timed(comm, exchange, 200)})
    return {"one_way": one_way, "alpha": float(alpha), "beta": float(beta), "tau": tau["min"],
            "allreduce": tau, "exchanges": exchanges}


def dolfinx_scatters(comm, case, sets):
    """The ghost updates of the imex step as DOLFINx does them, on the mesh of ``case`` on
    this communicator: a forward and a reverse (add) scatter of a DG-P1 vector field, each
    ``timed``, and the largest rank's neighbours and bytes. Collective."""
    c = load_case(case, sets)
    space = spaces.create(mesh.build(c.geometry, c.mesh.size, comm))
    f = compat.Function(space.V)
    cells = space.mesh.topology.index_map(space.mesh.topology.dim)
    k = len(np.unique(compat.ghost_owners(cells)))
    nbytes = cells.num_ghosts * (space.gdim + 1) * space.gdim * f.x.array.itemsize
    out = {"k": comm.allreduce(k, op=MPI.MAX), "bytes": comm.allreduce(nbytes, op=MPI.MAX)}
    out["forward"] = timed(comm, lambda: compat.scatter_forward(f), 200)
    out["reverse"] = timed(comm, lambda: compat.scatter_reverse_add(f), 200)
    return out


def measure_network(patterns, case, sets, tmp):
    spec = Path(tmp) / "patterns.json"
    spec.write_text(json.dumps({"patterns": patterns, "case": case, "sets": sets}))
    out = Path(tmp) / "network.json"
    subprocess.run(mpirun(2, [__file__, "--network", spec, out]), env=env(), check=True, capture_output=True)
    return json.loads(out.read_text())


def predict(cost, part, t_update, tau, exchanges, allreduces):
    """Predicted seconds per step by term, the efficiency, and the efficiency lost to each
    cause, at P parts (the module docstring's model). part: scaled_parts' entry; t_update:
    seconds per ghost update; tau: seconds per Allreduce tree level."""
    P, N = part["P"], part["N"]
    compute = np.max(cost["t1_bulk"] * part["owned"] + cost["t1_rest"] * part["star"])
    terms = {"t0": cost["t0"], "compute": compute, "ghost updates": exchanges * t_update,
             "Allreduce": allreduces * math.ceil(math.log2(P)) * tau}
    total = sum(terms.values())
    # P t_P = t_1(N) + (P - 1) t0 + (P compute - t1 N) + P (updates + Allreduce): the
    # efficiency lost to each, as shares of P t_P
    lost = {"fixed cost": (P - 1) * cost["t0"], "imbalance": P * compute - cost["t1"] * N,
            "communication": P * (terms["ghost updates"] + terms["Allreduce"])}
    return terms, total, (cost["t0"] + cost["t1"] * N) / (P * total), {k: v / (P * total) for k, v in lost.items()}


def scaled_parts(halos, n_cells, target, tdim, gdim):
    """{P: part} from an n_cells mesh's halos, scaled to ``target`` cells: owned and star
    work with the cell count, bytes per update (max of sent and received) by the
    surface-to-volume law (n^((d-1)/d)); the neighbours as counted."""
    r = target / n_cells
    return {P: {"P": P, "N": target, "owned": h.owned * r, "star": h.star_cells * r, "k": h.neighbours,
                "bytes": np.maximum(h.bytes_received(tdim, gdim), h.bytes_sent(tdim, gdim)) * r ** ((tdim - 1) / tdim)}
            for P, h in halos.items()}


def surface_law(by_size):
    """{P: b}: the log-log slope of ghosts_max against the cell count N over the partitioned
    sizes, to set against the surface-to-volume exponent (d-1)/d."""
    sizes = sorted(by_size.values(), key=lambda v: v[1])
    return {P: np.polyfit(np.log([n for _, n, _ in sizes]), np.log([h[P].ghosts.max() for h, _, _ in sizes]), 1)[0]
            for P in sizes[0][0]}


def update_times(parts, net):
    """Seconds per ghost update at each P: DOLFINx's own overhead per scatter (its measured
    2-rank scatter less the ping-pong model of its size), plus the largest part's messages:
    the measured 2-rank exchange of that pattern (shared memory) or k alpha + b beta with
    the assumed network (cluster). {network: {P: s}}, and the overhead (s)."""
    d = net["dolfinx"]
    scatter = (d["forward"]["min"] + d["reverse"]["min"]) / 2
    overhead = max(0.0, scatter - (d["k"] * net["alpha"] + d["bytes"] * net["beta"]))
    measured = {(e["k"], e["bytes"]): e["min"] for e in net["exchanges"]}
    return {"shared memory (measured)": {P: overhead + measured[pattern(p)] for P, p in parts.items()},
            "cluster (assumed)": {P: overhead + np.max(p["k"] * CLUSTER["alpha"] + p["bytes"] * CLUSTER["beta"])
                                  for P, p in parts.items()}}, overhead


def print_partitions(case, by_size, tdim, gdim):
    print(f"\n### Star partitions of the {case} mesh (serial, DOLFINx's partitioner)\n")
    print("| mesh size (m) | cells | P | owned / part (max / mean) | star work (max / mean) | ghosts / part (max / mean) "
          "| neighbours (max / mean) | bytes per update (max) |")
    print("|---:|---:|---:|---|---|---|---|---:|")
    for size, (hs, n, secs) in sorted(by_size.items(), reverse=True):
        for P, h in hs.items():
            nbytes = np.maximum(h.bytes_received(tdim, gdim), h.bytes_sent(tdim, gdim)).max()
            print(f"| {size} | {n:,} | {P} | {h.owned.max():,} / {h.owned.mean():,.0f} | "
                  f"{h.star_cells.max():,.0f} / {h.star_cells.mean():,.0f} | {h.ghosts.max():,} / {h.ghosts.mean():,.0f} "
                  f"| {h.neighbours.max()} / {h.neighbours.mean():.1f} | {nbytes:,} |")
        print(f"|  | mesh {secs[0]:.1f} s, partitions + counts {secs[1]:.1f} s |||||||")
    if len(by_size) > 1:
        print("\nghosts_max ~ N^b, fitted over the sizes: "
              + ", ".join(f"P = {P}: b = {b:.2f}" for P, b in surface_law(by_size).items())
              + f" (surface-to-volume: {(tdim - 1) / tdim:.2f})")


def print_inputs(cost, net, overhead, exchanges, allreduces):
    error = "" if cost["t0_error"] is None else f" +- {1e3 * cost['t0_error']:.3f}"
    print(f"\nt(n) = t0 + t1 n: fitted t0 = {1e3 * cost['t0_fit']:.3f}{error} ms (used: {1e3 * cost['t0']:.3f}), "
          f"t1 = {1e9 * cost['t1']:.0f} ns "
          f"(bulk {1e9 * cost['t1_bulk']:.0f}, rest {1e9 * cost['t1_rest']:.0f}); points (cells per rank, ms/step "
          "of compute): " + ", ".join(f"({n:,.0f}, {1e3 * t:.2f})" for n, t in cost["points"]))
    print(f"shared memory (2 ranks; smallest of {TRIALS} means, median in brackets): alpha = "
          f"{1e6 * net['alpha']:.2f} us, 1/beta = {1e-9 / net['beta']:.1f} GB/s, Allreduce tau = "
          f"{1e6 * net['tau']:.2f} us ({1e6 * net['allreduce']['median']:.2f}); {exchanges} ghost updates and "
          f"{allreduces:.2f} Allreduce per step\n  one way (B: us): " + ", ".join(
              f"{int(float(s)):,}: {1e6 * o['min']:.2f} ({1e6 * o['median']:.2f})" for s, o in net["one_way"].items()))
    d = net["dolfinx"]
    print(f"  DOLFINx scatters of the 3D case's DG-P1 field ({d['k']} neighbour, {d['bytes']:,} B): forward "
          f"{1e6 * d['forward']['min']:.1f} us ({1e6 * d['forward']['median']:.1f}), reverse "
          f"{1e6 * d['reverse']['min']:.1f} us ({1e6 * d['reverse']['median']:.1f}); ping-pong model "
          f"{1e6 * (d['k'] * net['alpha'] + d['bytes'] * net['beta']):.1f} us: overhead {1e6 * overhead:.1f} us")
    for e in net["exchanges"]:
        print(f"  exchange of {e['k']} messages, {e['bytes']:,} B each way: {1e6 * e['min']:.1f} us "
              f"({1e6 * e['median']:.1f}); ping-pong model {1e6 * (e['k'] * net['alpha'] + e['bytes'] * net['beta']):.1f} us")


def print_prediction(cost, parts, net, exchanges, allreduces, n_cells):
    updates, overhead = update_times(parts, net)
    print_inputs(cost, net, overhead, exchanges, allreduces)
    target = next(iter(parts.values()))["N"]
    print(f"\n### Predicted at {target:,} cells (from the {n_cells:,}-cell partitions)\n")
    print("| network | P | cells / part | t0 (ms) | compute (ms) | ghost updates (ms) | Allreduce (ms) "
          "| t_P (ms / step) | efficiency | with t0 +- its error | lost to fixed cost / imbalance / communication |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|")
    error = cost["t0_error"] or 0.0
    bounds = [dict(cost, t0=max(cost["t0_fit"] + e, 0.0)) for e in (error, -error)]
    results = []
    for name, tau in (("shared memory (measured)", net["tau"]), ("cluster (assumed)", CLUSTER["tau"])):
        for P, part in parts.items():
            terms, total, eff, lost = predict(cost, part, updates[name][P], tau, exchanges, allreduces)
            results.append({"network": name, "P": P, "terms_s": terms, "t_P_s": total, "efficiency": eff,
                            "lost": lost})
            low, high = (predict(b, part, updates[name][P], tau, exchanges, allreduces)[2] for b in bounds)
            print(f"| {name} | {P} | {target / P:,.0f} | " + " | ".join(f"{1e3 * v:.3f}" for v in terms.values())
                  + f" | {1e3 * total:.3f} | {100 * eff:.0f} % | {100 * low:.0f}-{100 * high:.0f} % | "
                  + " / ".join(f"{100 * v:.0f} %" for v in lost.values()) + " |")
    return results


def model_check(cost, geometry, size, net, exchanges, allreduces, measured, tdim, gdim):
    """The model at 2 ranks on the measured 3D case's own mesh, against the measured row."""
    row = next((r for r in measured if r["ranks"] == 2), None)
    if row is None:
        return
    halos, n_cells, _ = partition(geometry, size, [2])
    part = scaled_parts(halos, n_cells, n_cells, tdim, gdim)[2]
    d = net["dolfinx"]
    terms, total, _, _ = predict(cost, part, (d["forward"]["min"] + d["reverse"]["min"]) / 2, net["tau"],
                                 exchanges, allreduces)
    print(f"\nmodel check, the measured case at 2 ranks: predicted {1e3 * total:.2f} ms / step "
          f"({', '.join(f'{k} {1e3 * v:.2f}' for k, v in terms.items())}), measured "
          f"{1e3 * (row['total'] - row['phases']['output']):.2f} ms / step without output")


def predict_case(key, case, sets, measured, args, tmp):
    """The prediction of the module docstring for the slab ("3d") or the bunker at
    --production-cells, printed; returns the report's entries."""
    c = load_case(case, sets)
    tdim = gdim = 3
    split = [r for r in measured if r["copies"] == 1]
    if key == "bunker":
        cost, check, production = fit_cost(split), None, c.geometry
    else:
        singles = [r for r in split if r["ranks"] == 1]
        for f in args.fit_fractions:
            singles += launch(1, case, sets + shrunk(presets(args.elastic)["3d"][2], f), f"{tmp}/fit-{f}", args.clock,
                              repeat=args.repeat)
        cost, production = fit_cost(singles), load_case(case, sets + PRODUCTION).geometry
        check = fit_cost(split) if args.clock == "cpu" and len(split) > 1 else None
    if check:
        print("\ncross-check, per-rank compute of the measured runs (cells / P, ms/step): "
              + ", ".join(f"({n:,.0f}, {1e3 * t:.2f})" for n, t in check["points"])
              + f": t0 = {1e3 * check['t0_fit']:.3f} ms, t1 = {1e9 * check['t1']:.0f} ns")
    by_size = {s: partition(production, s, PREDICT_RANKS) for s in args.partition_sizes}
    print_partitions(case, by_size, tdim, gdim)
    halos, n_cells, _ = max(by_size.values(), key=lambda v: v[1])
    parts = scaled_parts(halos, n_cells, int(args.production_cells), tdim, gdim)
    net = measure_network([pattern(p) for p in parts.values()], case, sets, tmp)
    exchanges = 3 if c.rebar.faces else 2
    # star solver floors + convergence check each step; per history row: energies, probes,
    # 3 Newton statistics and the bars' largest force
    allreduces = (2 if c.interface.law != "elastic" else 0) + (5 + bool(c.rebar.faces)) / c.output.every
    prediction = print_prediction(cost, parts, net, exchanges, allreduces, n_cells)
    model_check(cost, c.geometry, c.mesh.size, net, exchanges, allreduces, measured, tdim, gdim)
    return {"fit": cost, "split_fit": check, "network": net, "prediction": prediction}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["3d", "2d"], choices=["3d", "2d", "bunker"],
                        help="bunker: bunker-h2 to the end of its load, predicted at its fine mesh "
                             "(with --clock cpu --production-cells 1167137)")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--elastic", action="store_true",
                        help="sound-bar's elastic interfaces (3D box and 2D) instead of the slab's law")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="extra override for every measured run")
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                        help="time the phases in wall seconds, or in CPU seconds of each process (loaded machines)")
    parser.add_argument("--fit-fractions", type=float, nargs="+", default=[0.125, 0.25, 0.5],
                        help="extra 1-rank runs for t(n): the 3D case shrunk to these fractions of its cells")
    parser.add_argument("--partition-sizes", type=float, nargs="+", default=[0.015],
                        help="mesh sizes (m) of the slab geometry partitioned serially (0.0077: ~1M cells)")
    parser.add_argument("--production-cells", type=float, default=1e6)
    parser.add_argument("--repeat", type=int, default=1, help="launch each run this many times, keep the fastest")
    parser.add_argument("--json", help="write every number here")
    parser.add_argument("--network", nargs=2, help=argparse.SUPPRESS)  # worker: patterns.json out.json
    parser.add_argument("--run", nargs=2, help=argparse.SUPPRESS)  # worker: case out
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.run:
        case, out = args.run
        run_case(case, args.set, out, args.clock, comm)
        return
    if args.network:
        spec = json.loads(Path(args.network[0]).read_text())
        result = network(comm, spec["patterns"])
        result["dolfinx"] = dolfinx_scatters(comm, spec["case"], spec["sets"])
        if comm.rank == 0:
            Path(args.network[1]).write_text(json.dumps(result))
        return
    cases = {k: (c, s + args.set) for k, (c, s, _) in presets(args.elastic).items() if k in args.cases}
    if comm.size > 1:  # started under mpirun: this rank count's rows only
        for key, (case, sets) in cases.items():
            with tempfile.TemporaryDirectory() as tmp:
                summary = run_case(case, sets, comm.bcast(tmp, root=0), args.clock, comm)
            if comm.rank == 0:
                print_measured(key, case, sets, [per_step(summary)])
        return
    # under `mpirun -n 1` this process is bound to one core, and the runs started from it
    # would inherit that: two ranks spinning on one core (measured: an Allreduce took ms)
    os.sched_setaffinity(0, range(os.cpu_count()))
    print(f"{time.strftime('%Y-%m-%d %H:%M')}, load average {os.getloadavg()[0]:.2f} (1 min) on "
          f"{os.cpu_count()} cores; phases timed by the {args.clock} clock; python {sys.executable}")
    report = {"date": time.strftime("%Y-%m-%d %H:%M"), "load_before": os.getloadavg(), "clock": args.clock}
    with tempfile.TemporaryDirectory() as tmp:
        for key, (case, sets) in cases.items():
            report[key] = measure_case(key, case, sets, args.ranks, tmp, args.clock, args.repeat)
            print_measured(key, case, sets, report[key])
        for key in ("3d", "bunker"):
            if key in cases:
                report[f"{key}_prediction"] = predict_case(key, *cases[key], report[key], args, tmp)
    report["load_after"] = os.getloadavg()
    print(f"\nload average after: {report['load_after'][0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()
