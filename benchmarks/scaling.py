"""Parallel scaling of the imex step: measured at 1, 2, 4, ... ranks, predicted at 16, 128, 1024.

    python benchmarks/scaling.py [--cases 3d 2d] [--ranks 1 2 4] [--elastic] [--set SECTION.KEY=VALUE ...]
        [--repeat 1] [--fit-fractions 0.125 0.25 0.5] [--partition-sizes 0.015] [--json FILE]
    mpirun -n P python benchmarks/scaling.py [--cases 3d]     # this rank count's rows only

Measured: each case runs under ``mpirun -n P`` (the `dolfrag` CLI, --quiet), and two
independent serial copies run at once (the 2-core baseline: two memory-bound processes slow
each other down). From summary.json -> timings_s: wall time per step of the time loop (sum of
the phases' means over ranks), parallel efficiency t_1 / (P t_P) and t_copy / (2 t_2), and each
phase's share. Beyond the cores (--oversubscribe) rows measure correctness and overheads only.

Predicted, for the 3D slab at production size (1 m x 1 m x 0.1 m, --production-cells N):
    t_P = t0 + max_p(t1_bulk owned_p + t1_rest star_p)           compute, slowest part
          + X max_p(k_p alpha + max(in_p, out_p) beta)          X ghost updates per step
          + A ceil(log2 P) tau                                  A Allreduce per step
    E_P = (t0 + t1 N) / (P t_P),  t1 = t1_bulk + t1_rest
t0, t1_bulk, t1_rest: fitted to 1-rank runs of the 3D case shrunk laterally at the same mesh
size (time loop without output); owned_p, star_p (dolfrag.halo.Halo.star_cells), k_p
(neighbours), in_p / out_p (bytes per update): star partitions of the slab mesh into P parts
on one process, scaled to N cells (the bytes by the surface-to-volume law); alpha, beta, tau:
2-rank ping-pong and Allreduce here (shared memory), and an assumed cluster network.
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

import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
from dolfrag import compat, halo, mesh, space as spaces
from dolfrag.config import builtin_cases, load_case
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


def presets(elastic=False):
    """{key: (case, overrides, extents)}: the fixed cases, and the lateral extents (m) that
    the t(n) fit shrinks. The 3D one is a reduced slab once that case exists, else a 3D box
    version of sound-bar with the slab's interface law (with ``elastic``: sound-bar's
    elastic springs, the cheapest step)."""
    law = [] if elastic else LAW
    if SLAB in builtin_cases() and not elastic:
        three = (SLAB, ["geometry.length=0.2", "geometry.width=0.2", "mesh.size=0.015", "time.end=1e-5", *OUTPUT],
                 {"length": 0.2, "width": 0.2})
    else:
        three = ("sound-bar", [*BOX, *law, "mesh.size=0.004", "time.end=4e-6", *OUTPUT], {"length": 0.12})
    return {"3d": three, "2d": ("sound-bar", [*law, "mesh.size=0.001", "time.end=3e-6", *OUTPUT], {"length": 0.12})}


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


def cli_run(case, sets, out):
    return ["-m", "dolfrag.cli", "run", case, "--out", out, "--quiet", *(a for s in sets for a in ("--set", s))]


def per_step(summary, label=None):
    """Seconds per step of the time loop, by phase (mean over ranks) and total, plus the
    largest rank's communication time."""
    t, n = summary["timings_s"], summary["steps_done"]
    phases = {p: t[p]["mean"] / n for p in PHASES}
    return {"label": label or str(summary["ranks"]), "cells": summary["cells"], "ranks": summary["ranks"],
            "steps": n, "phases": phases, "total": sum(phases.values()),
            "communication_max": t["communication"]["max"] / n, "copies": 1, "efficiency": None,
            "interface_imbalance": t["interface"]["max"] / max(t["interface"]["mean"], 1e-300)}


def launch(n, case, sets, out, copies=1, repeat=1):
    """Run the case under mpirun -n n (``copies`` independent runs started together);
    per_step of each, from the fastest of ``repeat`` such launches (the least disturbed by
    other work on the machine)."""
    runs = [_launch(n, case, sets, f"{out}-{r}", copies) for r in range(repeat)]
    return min(runs, key=lambda rows: np.mean([row["total"] for row in rows]))


def _launch(n, case, sets, out, copies):
    outs = [Path(f"{out}-{c}") for c in range(copies)]
    procs = [subprocess.Popen(mpirun(n, cli_run(case, sets, o)), env=env(), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for o in outs]
    for p in procs:
        stdout, stderr = p.communicate()
        if p.returncode:
            raise RuntimeError(f"{' '.join(p.args)} failed:\n{stdout}\n{stderr[-3000:]}")
    return [per_step(json.loads((o / "summary.json").read_text())) for o in outs]


def measure_case(key, case, sets, ranks, tmp, repeat):
    """Rows of the measured table for one case: each rank count, and the two serial copies."""
    rows = [launch(p, case, sets, f"{tmp}/{key}-{p}", repeat=repeat)[0] for p in ranks]
    copies = launch(1, case, sets, f"{tmp}/{key}-copy", copies=2, repeat=repeat)
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
    """Per cent of a step in bulk, interface, communication (mean over ranks; the largest
    rank's), output, and the rest (update, diagnostics)."""
    ph, total = r["phases"], r["total"]
    parts = (ph["bulk"], ph["interface"], ph["communication"], r["communication_max"], ph["output"],
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
    """t(n) = t0 + t1 n (s per step, n cells) over 1-rank rows, time loop without output;
    the bulk phase and the rest fitted apart. {t0, t1, t1_bulk, t1_rest, points}."""
    n = np.array([r["cells"] for r in rows], float)
    bulk = np.array([r["phases"]["bulk"] for r in rows])
    rest = np.array([r["total"] - r["phases"]["output"] for r in rows]) - bulk
    (b1, b0), (r1, r0) = np.polyfit(n, bulk, 1), np.polyfit(n, rest, 1)
    return {"t0": b0 + r0, "t1": b1 + r1, "t1_bulk": b1, "t1_rest": r1,
            "points": [(int(c), float(b + x)) for c, b, x in zip(n, bulk, rest)]}


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


def pattern(h, tdim, gdim):
    """(largest neighbour count, largest bytes sent or received per update) over the parts."""
    k = h.neighbours
    b = np.maximum(h.bytes_received(tdim, gdim), h.bytes_sent(tdim, gdim))
    return int(k.max()), int(b.max())


def network(comm, patterns, trials=15):
    """On 2 ranks: one-way ping-pong time by message size and its fit alpha + beta s, the
    Allreduce of 2 doubles, and each exchange pattern (k messages of b / k bytes each way at
    once: Isend / Irecv / Waitall). Each time (s) is a mean over many repetitions; of
    ``trials`` such means, the smallest (the uncontended cost: the model's) and the median
    (this machine under its load). Collective."""
    other = 1 - comm.rank

    def timed(fn, reps):
        times = []
        for _ in range(trials):
            comm.Barrier()
            t = time.perf_counter()
            for _ in range(reps):
                fn()
            times.append((time.perf_counter() - t) / reps)
        return {"min": float(np.min(times)), "median": float(np.median(times))}

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
        one_way[size] = {k: v / 2 for k, v in timed(ping, max(10, min(2000, 2 ** 24 // size))).items()}
    sizes = np.array(list(one_way), float)
    t = np.array([o["min"] for o in one_way.values()])
    beta, alpha = np.polyfit(sizes, t, 1, w=1 / t)  # relative errors: latency and bandwidth both count
    x, y = np.zeros(2), np.zeros(2)
    tau = timed(lambda: comm.Allreduce(x, y, op=MPI.MAX), 2000)
    exchanges = []
    for k, nbytes in patterns:
        send = [np.zeros(max(1, nbytes // k), np.uint8) for _ in range(k)]
        recv = [np.zeros_like(a) for a in send]

        def exchange():
            reqs = [comm.Irecv(r, other, tag=i) for i, r in enumerate(recv)]
            reqs += [comm.Isend(a, other, tag=i) for i, a in enumerate(send)]
            MPI.Request.Waitall(reqs)
        exchanges.append({"k": k, "bytes": nbytes, **timed(exchange, 200)})
    return {"one_way": one_way, "alpha": float(alpha), "beta": float(beta), "tau": tau["min"],
            "allreduce": tau, "exchanges": exchanges}


def dolfinx_scatters(comm, case, sets, trials=15):
    """The ghost updates of the imex step as DOLFINx does them, on the mesh of ``case`` on
    this communicator: mean time (s) of a forward and of a reverse (add) scatter of a DG-P1
    vector field (min and median over trials), and the largest rank's neighbours and bytes.
    Collective."""
    c = load_case(case, sets)
    space = spaces.create(mesh.build(c.geometry, c.mesh.size, comm))
    f = compat.Function(space.V)
    cells = space.mesh.topology.index_map(space.mesh.topology.dim)
    k = len(np.unique(compat.ghost_owners(cells)))
    nbytes = cells.num_ghosts * (space.gdim + 1) * space.gdim * f.x.array.itemsize
    out = {"k": comm.allreduce(k, op=MPI.MAX), "bytes": comm.allreduce(nbytes, op=MPI.MAX)}
    for name, fn in (("forward", lambda: compat.scatter_forward(f)), ("reverse", lambda: compat.scatter_reverse_add(f))):
        times = []
        for _ in range(trials):
            comm.Barrier()
            t = time.perf_counter()
            for _ in range(200):
                fn()
            times.append(comm.allreduce((time.perf_counter() - t) / 200, op=MPI.MAX))
        out[name] = {"min": float(np.min(times)), "median": float(np.median(times))}
    return out


def measure_network(patterns, case, sets, tmp):
    spec = Path(tmp) / "patterns.json"
    spec.write_text(json.dumps({"patterns": patterns, "case": case, "sets": sets}))
    out = Path(tmp) / "network.json"
    subprocess.run(mpirun(2, [__file__, "--network", spec, out]), env=env(), check=True, capture_output=True)
    return json.loads(out.read_text())


def predict(cost, part, net, exchanges, allreduces):
    """Predicted seconds per step by term, and the efficiency, at P parts (see the module
    docstring). part: {"P", "N", "owned", "star", "k", "bytes"} (arrays per part scaled to N)."""
    P, N = part["P"], part["N"]
    compute = np.max(cost["t1_bulk"] * part["owned"] + cost["t1_rest"] * part["star"])
    terms = {"t0": cost["t0"], "compute": compute,
             "exchanges": exchanges * np.max(part["k"] * net["alpha"] + part["bytes"] * net["beta"]),
             "allreduce": allreduces * math.ceil(math.log2(P)) * net["tau"]}
    total = sum(terms.values())
    # P t_P = t_1(N) + (P - 1) t0 + (P compute - t1 N) + P (exchanges + Allreduce): the
    # efficiency lost to each, as shares of P t_P
    lost = {"fixed cost": (P - 1) * cost["t0"], "imbalance": P * compute - cost["t1"] * N,
            "communication": P * (terms["exchanges"] + terms["allreduce"])}
    return terms, total, (cost["t0"] + cost["t1"] * N) / (P * total), {k: v / (P * total) for k, v in lost.items()}


def scaled_parts(halos, n_cells, target, tdim, gdim):
    """Per-part arrays scaled from an n_cells mesh to ``target`` cells: owned and star work
    with the cell count, ghost bytes by the surface-to-volume law (n^((d-1)/d)); the
    neighbours as measured."""
    r = target / n_cells
    out = {}
    for P, h in halos.items():
        b = np.maximum(h.bytes_received(tdim, gdim), h.bytes_sent(tdim, gdim))
        out[P] = {"P": P, "N": target, "owned": h.owned * r, "star": h.star_cells * r, "k": h.neighbours,
                  "bytes": b * r ** ((tdim - 1) / tdim)}
    return out


def surface_law(by_size, tdim):
    """Per P: the free log-log fit ghosts_max ~ a N^b over the partitioned sizes, against
    the surface-to-volume exponent (d-1)/d. {P: (b, points)}."""
    out = {}
    Ps = sorted(next(iter(by_size.values()))[0])
    for P in Ps:
        pts = sorted((n, int(h[P].ghosts.max())) for h, n, _ in by_size.values())
        b = np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0] if len(pts) > 1 else None
        out[P] = (b, pts)
    return out


def print_prediction(cost, by_size, net, exchanges, allreduces, target, tdim, gdim):
    largest = max(by_size, key=lambda s: by_size[s][1])
    halos, n_cells, seconds = by_size[largest]
    print(f"\n### Star partitions of the slab mesh (serial, DOLFINx's partitioner)\n")
    print("| mesh size (m) | cells | P | owned / part (max / mean) | star work (max / mean) | ghosts / part (max) "
          "| neighbours (max) | bytes per update (max) |")
    print("|---:|---:|---:|---|---|---:|---:|---:|")
    for size, (hs, n, secs) in sorted(by_size.items(), reverse=True):
        for P, h in hs.items():
            k, nbytes = pattern(h, tdim, gdim)
            print(f"| {size} | {n:,} | {P} | {h.owned.max():,} / {h.owned.mean():,.0f} | "
                  f"{h.star_cells.max():,.0f} / {h.star_cells.mean():,.0f} | {h.ghosts.max():,} | {k} | {nbytes:,} |")
        print(f"|  | mesh {secs[0]:.1f} s, partitions + counts {secs[1]:.1f} s |||||||")
    law = surface_law(by_size, tdim)
    if len(by_size) > 1:
        print("\nghosts_max ~ N^b, fitted: " + ", ".join(f"P = {P}: b = {b:.2f}" for P, (b, _) in law.items())
              + f" (surface-to-volume: {(tdim - 1) / tdim:.2f})")
    print(f"\nt(n) = {1e3 * cost['t0']:.3f} ms + {1e9 * cost['t1']:.0f} ns x n "
          f"(bulk {1e9 * cost['t1_bulk']:.0f}, rest {1e9 * cost['t1_rest']:.0f}); points (cells, ms/step): "
          + ", ".join(f"({n:,}, {1e3 * t:.2f})" for n, t in cost["points"]))
    print(f"shared memory (2 ranks, smallest of the trials' means): alpha = {1e6 * net['alpha']:.2f} us, "
          f"1/beta = {1e-9 / net['beta']:.1f} GB/s, Allreduce tau = {1e6 * net['tau']:.2f} us "
          f"(median {1e6 * net['allreduce']['median']:.2f}); {exchanges} ghost updates and {allreduces:.1f} "
          "Allreduce per step\n  one way (B: us, median us): " + ", ".join(
              f"{int(float(s)):,}: {1e6 * o['min']:.2f}, {1e6 * o['median']:.2f}" for s, o in net["one_way"].items()))
    d = net["dolfinx"]
    print(f"  DOLFINx scatters of the 3D case's DG-P1 field on 2 ranks ({d['k']} neighbour, {d['bytes']:,} B): "
          f"forward {1e6 * d['forward']['min']:.1f} us, reverse {1e6 * d['reverse']['min']:.1f} us (medians "
          f"{1e6 * d['forward']['median']:.1f}, {1e6 * d['reverse']['median']:.1f}); model "
          f"{1e6 * (d['k'] * net['alpha'] + d['bytes'] * net['beta']):.1f} us")
    for e in net["exchanges"]:
        print(f"  exchange of {e['k']} messages, {e['bytes']:,} B each way: {1e6 * e['min']:.1f} us "
              f"(median {1e6 * e['median']:.1f}), model k alpha + b beta "
              f"{1e6 * (e['k'] * net['alpha'] + e['bytes'] * net['beta']):.1f} us")
    parts = scaled_parts(halos, n_cells, target, tdim, gdim)
    print(f"\n### Predicted at {target:,} cells (partitions of the {n_cells:,}-cell mesh scaled)\n")
    print("| network | P | cells / part | t0 (ms) | compute (ms) | ghost updates (ms) | Allreduce (ms) "
          "| t_P (ms / step) | efficiency | lost to fixed cost / imbalance / communication |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    results = []
    for name, params in (("shared memory (measured)", net),
                         ("cluster (assumed)", CLUSTER)):
        for P, part in parts.items():
            terms, total, eff, lost = predict(cost, part, params, exchanges, allreduces)
            results.append({"network": name, "P": P, "terms_s": terms, "t_P_s": total, "efficiency": eff,
                            "lost": lost})
            print(f"| {name} | {P} | {target / P:,.0f} | " + " | ".join(f"{1e3 * v:.3f}" for v in terms.values())
                  + f" | {1e3 * total:.3f} | {100 * eff:.0f} % | "
                  + " / ".join(f"{100 * v:.0f} %" for v in lost.values()) + " |")
    return results


def model_check(cost, geometry, size, net, exchanges, allreduces, measured, tdim, gdim):
    """The model at 2 ranks on the measured 3D case's own mesh, against the measured row."""
    halos, n_cells, _ = partition(geometry, size, [2])
    part = scaled_parts(halos, n_cells, n_cells, tdim, gdim)[2]
    terms, total, _, _ = predict(cost, part, net, exchanges, allreduces)
    row = next((r for r in measured if r["ranks"] == 2), None)
    if row is None:
        return
    print(f"\nmodel check, 3D case at 2 ranks: predicted {1e3 * total:.2f} ms / step "
          f"({', '.join(f'{k} {1e3 * v:.2f}' for k, v in terms.items())}), measured "
          f"{1e3 * (row['total'] - row['phases']['output']):.2f} ms / step without output")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["3d", "2d"], choices=["3d", "2d"])
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--elastic", action="store_true",
                        help="sound-bar's elastic interfaces (3D box and 2D) instead of the slab's law")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="extra override for every measured run (e.g. interface.law=elastic)")
    parser.add_argument("--fit-fractions", type=float, nargs="+", default=[0.125, 0.25, 0.5],
                        help="extra 1-rank runs for t(n): the 3D case shrunk to these fractions of its cells")
    parser.add_argument("--partition-sizes", type=float, nargs="+", default=[0.015],
                        help="mesh sizes (m) of the slab geometry partitioned serially (0.0077: ~1M cells)")
    parser.add_argument("--production-cells", type=float, default=1e6)
    parser.add_argument("--repeat", type=int, default=1, help="launch each run this many times, keep the fastest")
    parser.add_argument("--json", help="write every number here")
    parser.add_argument("--network", nargs=2, help=argparse.SUPPRESS)  # worker: patterns.json out.json
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
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
                summary = dolfrag.run(load_case(case, sets), comm.bcast(tmp, root=0), quiet=True)
            if comm.rank == 0:
                print_measured(key, case, sets, [per_step(summary)])
        return
    print(f"{time.strftime('%Y-%m-%d %H:%M')}, load average {os.getloadavg()[0]:.2f} (1 min) on "
          f"{os.cpu_count()} cores; python {sys.executable}")
    report = {"date": time.strftime("%Y-%m-%d %H:%M"), "load_before": os.getloadavg()}
    with tempfile.TemporaryDirectory() as tmp:
        for key, (case, sets) in cases.items():
            report[key] = measure_case(key, case, sets, args.ranks, tmp, args.repeat)
            print_measured(key, case, sets, report[key])
        if "3d" in cases:
            case, sets = cases["3d"]
            c = load_case(case, sets)
            tdim = gdim = 3
            singles = [r for r in report["3d"] if r["ranks"] == 1 and r["copies"] == 1]
            for f in args.fit_fractions:
                singles += launch(1, case, sets + shrunk(presets(args.elastic)["3d"][2], f), f"{tmp}/fit-{f}",
                                  repeat=args.repeat)
            cost = fit_cost(singles)
            production = load_case(case, sets + PRODUCTION).geometry
            by_size = {s: partition(production, s, PREDICT_RANKS) for s in args.partition_sizes}
            largest = by_size[max(by_size, key=lambda s: by_size[s][1])][0]
            net = measure_network([pattern(largest[P], tdim, gdim) for P in PREDICT_RANKS], case, sets, tmp)
            exchanges = 3 if c.rebar.faces else 2
            # star solver floors + convergence check each step; per history row: energies,
            # probes, 3 Newton statistics and the bars' largest force
            allreduces = (2 if c.interface.law != "elastic" else 0) + (5 + bool(c.rebar.faces)) / c.output.every
            report["fit"], report["network"] = cost, net
            report["prediction"] = print_prediction(cost, by_size, net, exchanges, allreduces,
                                                    int(args.production_cells), tdim, gdim)
            model_check(cost, c.geometry, c.mesh.size, net, exchanges, allreduces, report["3d"], tdim, gdim)
    report["load_after"] = os.getloadavg()
    print(f"\nload average after: {report['load_after'][0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()
