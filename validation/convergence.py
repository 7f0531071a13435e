"""Mesh convergence of the structural answers (docs/validation.md, "Mesh convergence").

    python validation/convergence.py wall                       # wall-bending-clamped, h = 2, 1, 0.5 cm, 0.1 s
    python validation/convergence.py panel                      # bunker-wall-panel, h = 0.1, 0.0667, 0.05 m, 20 ms
    python validation/convergence.py aci-slab --laws linear_softening   # aci-contest-slab, h = 3, 2, 1 cm, 80 ms
    python validation/convergence.py wall --sizes 0.02 0.01 --end 0.04 --ranks 2
    python validation/convergence.py wall --table-only          # the table of the runs already made
    python validation/convergence.py wall --set load.peak=2e5 --out results/convergence-2bar   # below the resistance
    python validation/convergence.py panel --table-only --at 0.006 0.008   # also the runs' state at 6 and 8 ms
    python validation/convergence.py bunker --laws linear_softening   # bunker-h2, h = 0.2, 0.1, 0.05 m, 20 ms

Each study runs its case at each mesh size with concrete C30/37 from its class, once with
linear softening and the fib Model Code 2010 rate factor, and once with the reference paper's
coupling (interface.law = "rccm", w = sigma_c^2 / C_N, C_N = 10 E / h) at the same strength. Every run
is a plain `dolfrag run` under mpirun into results/convergence/<study>/<law>-h<size>/; a run
whose summary.json says "completed" is not made again, and one that says "interrupted" is
resumed from its checkpoint, so the study can be stopped (SIGTERM) and taken up later. It
prints a markdown table per law and, between the two finest meshes, the relative change of
each quantity against the goal (10 %; the hazard distance: one ring width).

Quantities (SI): first crack (s, the first link broken through), peak deflection (m, midspan
of the wall, centre of the panel, centre of the bunker's long wall), energy dissipated by cracking and by contact and friction
(J, J/m in 2D), crack length (m, 2D) or area (m^2, 3D): the facet area whose links are broken,
and the effective crack, sum of damage x facet area over the links (for linear softening, whose
damage is the fraction of G_c a link has dissipated, the area of a crack that dissipates as
much: within 1-6 % of D_damage / G_c on the studies' runs), loose pieces (not held by a support) and their mass (kg, kg/m in 2D); 3D also the median mass
of a loose piece and the debris hazard distance (m, DDESB).
"""
import argparse
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from dolfrag.runner import checkpoint

STUDIES = {
    "wall": {"case": "wall-bending-clamped", "sizes": [0.02, 0.01, 0.005], "end": 0.1},
    "panel": {"case": "bunker-wall-panel", "sizes": [0.1, 0.0667, 0.05], "end": 0.02},
    # 3.4, 5 and 10 cells through its 0.1 m: 0.5 cm would take about 4 hours on one rank
    "aci-slab": {"case": "aci-contest-slab", "sizes": [0.03, 0.02, 0.01], "end": 0.08},
    # 1, 2 and 4 tetrahedra through its walls: the 0.05 m mesh takes hours on 2 ranks
    "bunker": {"case": "bunker-h2", "sizes": [0.2, 0.1, 0.05], "end": 0.02},
}
THREE_D = ("panel", "bunker")
# concrete C30/37 from its class whatever the case file gives (its E, rho and strength removed)
CONCRETE = ["material.grade=C30/37", "material.E=", "material.rho=", "material.nu=", "interface.sigma_c="]
# the reference paper's coupling at the same strength (the grade's f_ctm) and stiffness rule
LAWS = {"linear_softening": ["interface.law=linear_softening", "interface.rate_effect=fib2010"],
        "rccm": ["interface.law=rccm", "interface.rate_effect="]}
HAZARD_RING = 1.0  # m, debris.ring_width's default: the hazard distance moves in these steps
GOAL = 0.10


def run_dir(out, law, size):
    return out / f"{law}-h{size:g}"


def run(case, folder, end, ranks, sets):
    """One run of ``case`` to time.end = ``end`` (s) into ``folder`` with the overrides
    ``sets`` (SECTION.KEY=VALUE): skipped when its summary says completed, resumed from its
    checkpoint when it says interrupted, on the same rank count; returns the folder."""
    status, ranks_then, ran_to = state(folder)
    ran_to = end if ran_to is None else ran_to
    if not np.isclose(ran_to, end, rtol=1e-9, atol=0.0):
        print(f"{Path(sys.argv[0]).name}: {folder} ran to time.end = {ran_to:g} s, not the {end:g} s asked; "
              "give another --out, or --end to match it", file=sys.stderr)
        sys.exit(2)
    if status == "completed":
        return folder
    dolfrag = Path(sys.executable).with_name("dolfrag")
    if status == "interrupted":
        ranks = ranks_then
        command = [str(dolfrag), "run", "--resume", str(folder), "--quiet"]
    else:
        command = [str(dolfrag), "run", case, "--out", str(folder), "--overwrite", "--quiet"]
        command += [arg for item in [f"time.end={end}", *sets] for arg in ("--set", item)]
    command = ["mpirun", "-n", str(ranks), *command]
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
    print(" ".join(command), flush=True)
    subprocess.run(command, env=env, check=False)
    return folder


def state(folder):
    """(status, ranks, time.end in s) of the run in this folder from its summary.json, or
    (None, None, None) if nothing ran there. A run whose launcher killed it before it wrote
    its summary but after a checkpoint counts as interrupted, with the checkpoint's ranks and
    case: started again with --overwrite it would lose that checkpoint."""
    summary = folder / "summary.json"
    if summary.is_file():
        saved = json.loads(summary.read_text())
        return saved.get("status"), saved.get("ranks"), saved["case"]["time"]["end"]
    written = checkpoint.ranks_of(folder)
    if not written:
        return None, None, None
    return "interrupted", written[0], checkpoint.case_of(folder).time.end


def _csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def measures(folder):
    """The study's quantities of one finished (or stopped) run, from its output files."""
    summary = json.loads((folder / "summary.json").read_text())
    links = _csv(folder / "links.csv") if (folder / "links.csv").is_file() else []
    broken = [row for row in links if row["broken"] in ("1", "True", "1.0")]
    pieces = _csv(folder / "fragments.csv") if (folder / "fragments.csv").is_file() else []
    loose = [row for row in pieces if row["held"] in ("0", "False", "0.0")]
    mass_key = next((k for k in (pieces[0] if pieces else {}) if k.startswith("mass_kg")), None)
    loose_mass = [float(row[mass_key]) for row in loose] if mass_key else []
    energies = summary.get("energies_J", {})
    deflection = (summary.get("wall") or {}).get("midspan_deflection") or {}
    long_wall = (summary.get("bunker") or {}).get("long_wall")
    if long_wall:
        deflection = {"peak_m": long_wall["peak_deflection_m"]}
    debris = summary.get("debris") or {}
    return {"status": summary["status"], "cells": summary["cells"], "ranks": summary["ranks"],
            "wall_time_s": summary.get("wall_time_s"),
            "first_crack_s": min((float(r["break_time_s"]) for r in broken), default=float("nan")),
            "peak_deflection_m": abs(deflection.get("peak_m", float("nan"))),
            "dissipated_J": energies.get("D_damage_J", 0.0) + energies.get("D_contact_J", 0.0),
            "crack_size": sum(float(r["weight"]) for r in broken),
            "effective_crack": sum(float(r["weight"]) * float(r.get("damage") or 0.0) for r in links),
            "loose_pieces": len(loose), "loose_mass": sum(loose_mass),
            "median_piece_mass": float(np.median(loose_mass)) if loose_mass else float("nan"),
            "hazard_distance_m": debris.get("hazard_distance_m")}


COLUMNS = [("cells", "cells", "{:,}"), ("first_crack_s", "first crack (ms)", "ms"),
           ("peak_deflection_m", "peak deflection (mm)", "mm"), ("dissipated_J", "dissipated (J)", "{:.4g}"),
           ("crack_size", "crack length (m) / area (m²)", "{:.4g}"),
           ("effective_crack", "effective crack (m / m²)", "{:.4g}"), ("loose_pieces", "loose pieces", "{:,}"),
           ("loose_mass", "their mass (kg)", "{:.4g}"), ("median_piece_mass", "median piece (kg)", "{:.3g}"),
           ("hazard_distance_m", "hazard distance (m)", "{}"), ("wall_time_s", "wall time (s)", "{:.0f}")]
COMPARED = ["peak_deflection_m", "dissipated_J", "crack_size", "effective_crack"]


def _cell(value, form):
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "–"
    if form == "ms":
        return f"{value * 1e3:.2f}"
    if form == "mm":
        return f"{value * 1e3:.2f}"
    return form.format(value)


def table(rows, three_d):
    """A markdown table of the runs (size, measures) of one law."""
    columns = [c for c in COLUMNS if three_d or c[0] not in ("median_piece_mass", "hazard_distance_m")]
    lines = ["| h (m) | status | " + " | ".join(title for _, title, _ in columns) + " |",
             "|---:|---|" + "---:|" * len(columns)]
    for size, m in rows:
        lines.append(f"| {size:g} | {m['status']} | " + " | ".join(_cell(m[key], form) for key, _, form in columns)
                     + " |")
    return "\n".join(lines)


def verdict(rows):
    """Between the two finest completed meshes: the relative change of each compared
    quantity against GOAL, and the hazard distance's change against one ring."""
    done = [(s, m) for s, m in rows if m["status"] == "completed"]
    if len(done) < 2:
        return "fewer than two completed meshes: no verdict"
    (h1, a), (h2, b) = sorted(done)[:2]  # the finest two
    parts = []
    for key in COMPARED:
        change = abs(a[key] - b[key]) / max(abs(a[key]), 1e-300)
        parts.append(f"{key} {change:.1%} ({'within' if change <= GOAL else 'over'} {GOAL:.0%})")
    if a["hazard_distance_m"] is not None and b["hazard_distance_m"] is not None:
        moved = abs(a["hazard_distance_m"] - b["hazard_distance_m"])
        parts.append(f"hazard distance {moved:g} m ({'within' if moved <= HAZARD_RING else 'over'} one ring)")
    return f"h = {h1:g} against {h2:g} m: " + "; ".join(parts)


# the deflection each case's history.csv gives (m): a wall's or panel's midspan, the bunker's long wall
DEFLECTION_COLUMNS = ("w_midspan_m", "w_long_wall_m")


def history_at(folder, times):
    """Rows of the run's history.csv nearest to each time (s): deflection (m, the column of
    DEFLECTION_COLUMNS it has), D_damage + D_contact (J), broken links; None for a time the
    run has not reached (past its last row by more than the rows' spacing: a run stopped, or
    still going)."""
    rows = _csv(folder / "history.csv")
    column = next((c for c in DEFLECTION_COLUMNS if rows and c in rows[0]), DEFLECTION_COLUMNS[0])
    t = np.array([float(row["time_s"]) for row in rows])
    spacing = np.max(np.diff(t)) if len(t) > 1 else 0.0
    reached = t[-1] + spacing if len(t) else -np.inf  # a run just started has a header only
    picked = [rows[int(np.argmin(np.abs(t - time)))] if time <= reached else None for time in times]
    return [None if row is None else
            (float(row["time_s"]), abs(float(row[column])),
             float(row["D_damage_J"]) + float(row["D_contact_J"]), int(row["broken_links"])) for row in picked]


def history_table(rows, times):
    """A markdown table, one row per mesh size, of history_at at each time ("–" where the run
    has not reached it)."""
    head = " | ".join(f"{t * 1e3:g} ms: deflection (mm), dissipated (J), broken" for t in times)
    lines = [f"| h (m) | {head} |", "|---:|" + "---|" * len(times)]
    for size, folder in rows:
        cells = " | ".join("–" if at is None else f"{at[1] * 1e3:.3f}, {at[2]:.4g}, {at[3]:,}"
                           for at in history_at(folder, times))
        lines.append(f"| {size:g} | {cells} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", choices=sorted(STUDIES))
    parser.add_argument("--sizes", type=float, nargs="+", help="mesh sizes (m), default the study's")
    parser.add_argument("--end", type=float, help="time.end (s), default the study's")
    parser.add_argument("--laws", nargs="+", choices=sorted(LAWS), default=list(LAWS))
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("results/convergence"))
    parser.add_argument("--table-only", action="store_true", help="tabulate the runs already made, run nothing")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="a further override of every run (give its own --out)")
    parser.add_argument("--at", type=float, nargs="+", default=[], metavar="T",
                        help="also tabulate deflection, dissipated energy and broken links at these times (s)")
    args = parser.parse_args()
    study = STUDIES[args.study]
    sizes, end = args.sizes or study["sizes"], args.end or study["end"]
    out = args.out / args.study
    for law in args.laws:
        rows, ends, folders = [], set(), []
        for size in sizes:
            folder = run_dir(out, law, size)
            if not args.table_only:
                run(study["case"], folder, end, args.ranks,
                    [f"mesh.size={size}", "output.figures=false", *CONCRETE, *LAWS[law], *args.set])
            if (folder / "summary.json").is_file():
                rows.append((size, measures(folder)))
            if (folder / "history.csv").is_file():  # a run stopped, or still going: its history
                ran_to = state(folder)[2]  # None while a run has written neither summary nor checkpoint
                if ran_to is not None:
                    ends.add(ran_to)
                folders.append((size, folder))
        ended = ", ".join(f"{e:g}" for e in sorted(ends)) if ends else f"{end:g}"
        print(f"\n### {study['case']}, interface.law = {law}, to {ended} s\n")
        print(table(rows, args.study in THREE_D))
        print("\n" + verdict(rows), flush=True)
        if args.at:
            print("\n" + history_table(folders, args.at), flush=True)


if __name__ == "__main__":
    main()
