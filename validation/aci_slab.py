"""The ACI 447/370 contest slab against its measured deflection (docs/validation.md, "A measured blast test").

    python validation/convergence.py aci-slab --laws linear_softening   # the runs: h = 3, 2, 1 cm, 80 ms
    python validation/aci_slab.py                                        # the table, and the figure
    python validation/aci_slab.py --runs results/aci-sensitivity/*/aci-slab/*   # any runs of the case

For each run of `aci-contest-slab` (its folder's history.csv): the peak mid-span deflection
of the back face and its time, and the deflection at the end of the measured record, each
against the measurement and as a ratio to it; for a finished run (summary.json) the span
positions of its through-cracks (clusters of broken links reaching both faces). Last, the
closed-form reference of blast design, the strip's elastic-perfectly plastic SDOF under the
same load (``sdof``). The figure draws w(t) of every run and of the SDOF with the measured
values. Lengths in m (printed in mm), times in s (printed in ms).
"""
import argparse
import csv
import json
from pathlib import Path

import numpy as np

from dolfrag import concrete, loads
from dolfrag.case import load_case
from dolfrag.reference import analytic

INCH = 0.0254  # m
# Read off the test's published deflection plot by third parties (docs/validation.md lists where):
# the back face's mid-span, about 4.25 in at 30 ms, and 3.55 in where the record ends (70 ms).
MEASURED = {"peak_m": 4.25 * INCH, "peak_time_s": 0.030, "record_end_s": 0.070, "at_record_end_m": 3.55 * INCH}
DEFAULT_RUNS = sorted(Path("results/convergence/aci-slab").glob("linear_softening-h*"))


def response(folder):
    """Peak |w| (m) and its time (s), |w| at the record's end (m, None if the run stopped
    before it), the time reached (s), broken links, from the run's history.csv."""
    with open(folder / "history.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time_s"]) for r in rows])
    w = np.abs([float(r["w_midspan_m"]) for r in rows])
    i = int(np.argmax(w))
    end = MEASURED["record_end_s"]
    summary = folder / "summary.json"
    wall = json.loads(summary.read_text()).get("wall") if summary.is_file() else None
    return {"t": t, "w": w, "peak_m": w[i], "peak_time_s": t[i], "reached_s": t[-1],
            "at_record_end_m": float(np.interp(end, t, w)) if t[-1] >= end else None,
            "broken": int(rows[-1]["broken_links"]),
            "through_cracks_m": None if wall is None else [c["position_m"] for c in wall["through_cracks"]]}


def sdof(overrides=()):
    """The elastic-perfectly plastic strip SDOF (Biggs 1964; analytic.sdof_response) of the
    case under its own load: mass and gross stiffness of the section, resistance 8 M_p / L
    from its bars (Whitney block at the grade's f_cm; static strengths, as the run's bars).
    Returns the response dict of ``response`` without cracks."""
    case = load_case("aci-contest-slab", overrides)
    g, bars = case.geometry, case.rebar
    steel = np.pi * bars.diameter**2 / 4 / bars.spacing  # m^2 per m
    f_cm = concrete.concrete(case.material.grade).f_cm
    M_p = analytic.rebar_plastic_moment(steel, bars.f_y, g.width - bars.cover, f_cm)
    props = analytic.strip_properties(case.material.E, case.material.rho, g.width, g.length, "simple",
                                      nu=case.material.nu)
    t, w = analytic.sdof_response(props, loads.signal(case.load), case.time.end,
                                  resistance=analytic.bending_resistance(0.0, M_p, g.length, "simple"))
    i = int(np.argmax(w))
    return {"t": t, "w": w, "peak_m": w[i], "peak_time_s": t[i], "reached_s": t[-1], "broken": 0,
            "at_record_end_m": float(np.interp(MEASURED["record_end_s"], t, w)), "through_cracks_m": None}


def label(folder):
    """The run's name: its folder's, after the study's (a study run with --out NAME/... is
    NAME/h...), with the mesh size once its summary is written."""
    study = folder.parent.parent.name
    name = folder.name if study == "convergence" else f"{study}, {folder.name}"
    summary = folder / "summary.json"
    if summary.is_file():
        case = json.loads(summary.read_text())["case"]
        return f"{name} (h = {case['mesh']['size'] * 100:g} cm)"
    return name


def table(results):
    head = ("| run | peak (mm) | / measured | at (ms) | at 70 ms (mm) | / measured | broken links | "
            "through cracks at x (m) | ran to (ms) |\n|---|---:|---:|---:|---:|---:|---:|---|---:|")
    rows = [f"| measured | {MEASURED['peak_m'] * 1e3:.0f} | 1 | {MEASURED['peak_time_s'] * 1e3:.0f} | "
            f"{MEASURED['at_record_end_m'] * 1e3:.0f} | 1 | | | |"]
    for name, r in results:
        end = r["at_record_end_m"]
        cracks = r["through_cracks_m"]
        cracks = "–" if cracks is None else ", ".join(f"{x:.2f}" for x in cracks) or "none"
        at_end = ("–", "–") if end is None else (f"{end * 1e3:.1f}", f"{end / MEASURED['at_record_end_m']:.2f}")
        rows.append(f"| {name} | {r['peak_m'] * 1e3:.1f} | {r['peak_m'] / MEASURED['peak_m']:.2f} | "
                    f"{r['peak_time_s'] * 1e3:.1f} | {at_end[0]} | {at_end[1]} | {r['broken']:,} | {cracks} | "
                    f"{r['reached_s'] * 1e3:.1f} |")
    return "\n".join([head, *rows])


def figure(results, reference, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for name, r in results:
        ax.plot(r["t"] * 1e3, r["w"] * 1e3, label=name)
    ax.plot(reference["t"] * 1e3, reference["w"] * 1e3, "k--", lw=1, label="strip SDOF, elastic-perfectly plastic")
    ax.plot([MEASURED["peak_time_s"] * 1e3, MEASURED["record_end_s"] * 1e3],
            [MEASURED["peak_m"] * 1e3, MEASURED["at_record_end_m"] * 1e3], "ks", label="measured (read off its plot)")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("mid-span deflection, back face (mm)")
    ax.set_title("aci-contest-slab")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=Path, nargs="+", default=DEFAULT_RUNS, help="run folders of aci-contest-slab")
    parser.add_argument("--figure", type=Path, default=Path("results/aci-slab-deflection.png"))
    args = parser.parse_args()
    results = [(label(f), response(f)) for f in args.runs if (f / "history.csv").is_file()]
    if not results:
        parser.exit(2, "aci_slab.py: no history.csv in the run folders given; make the runs first (see --help)\n")
    reference = sdof()
    print(table([*results, ("strip SDOF, elastic-perfectly plastic", reference)]))
    figure(results, reference, args.figure)
    print(f"\nfigure: {args.figure}")


if __name__ == "__main__":
    main()
