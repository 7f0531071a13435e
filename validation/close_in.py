"""Close-in charges on RC slabs against the tests of Chiquito et al. 2023 (docs/validation.md,
"A close-in charge").

    python validation/close_in.py s5                  # 15 kg TNT 0.5 m above: h = 0.075, 0.06, 0.05 m, to 2 ms
    python validation/close_in.py s4 --sizes 0.05     # the same charge 1.0 m above
    python validation/close_in.py s5 --table-only     # the table of the runs already made

M. Chiquito, L. M. Lopez, R. Castedo, A. P. Santos and A. Perez-Caldentey, "Full-scale field
tests on concrete slabs subjected to close-in blast loads", Buildings 13(8), 2068 (2023):
slab S5 was punched through under its charge, slab S4 bent without a hole. Each run is the
built-in case `chiquito-slab-s5` (half the slab, cut at mid-span), a plain `dolfrag run` under
mpirun into results/close-in/<test>-h<size>/; a completed run is not made again, an interrupted
one is resumed (validation/convergence.py's rules).

What is read from a run's fragments.pvd (the end state, each cell with its fragment and
whether a support holds it): a cell is *gone* where its fragment is loose (no support holds it:
thrown off the slab, or hanging on the bars, which do not hold pieces together). Areas (m^2)
and masses (kg) are of the whole slab, twice the half modelled; the count of loose pieces is
of the half:

* crater and spall: the area of the front (charge side, z = 0) and back face made of gone cells,
  also as a share of the tested slab's face (4.40 x 1.46 m, its overhangs on the supports
  included, as the test's shares of damaged face are);
* breach: the plan area where every point through the thickness is in a gone cell, sampled on
  vertical lines ``SPACING`` apart at ``LEVELS`` depths; its equivalent diameter sqrt(4 A / pi);
* the plug's mass and mean speed away from the charge: the gone pieces that reach both faces.
"""
import argparse
import json
from pathlib import Path

import numpy as np
import pyvista as pv

from convergence import run, state

TESTS = {  # the charge's centre (m) in the case's frame: mid-span (x = 2.0), mid-width, above the front face
    "s5": {"position": "[2.0, 0.73, -0.5]", "outcome": "punched through; about 7 % of the face damaged"},
    "s4": {"position": "[2.0, 0.73, -1.0]", "outcome": "bent, no hole; about 3 % of the face damaged"},
}
CASE, SIZES, END = "chiquito-slab-s5", [0.075, 0.06, 0.05], 0.002
SYMMETRY = 2.0  # the model is the half of the slab on one side of its mid-span plane
FACE = 4.40 * 1.46  # m^2, a face of the tested slab
SPACING = 0.005  # m between the sampled vertical lines: a tenth of the finest mesh
LEVELS = 12  # depths sampled on each line, at the centres of LEVELS equal layers


def cells(out):
    """fragments.pvd's grid, its cells' vertex copies (conn), and per cell whether its piece
    is loose (gone) and which fragment it is in."""
    reader = pv.get_reader(str(out / "fragments.pvd"))
    grid = reader.read()[0]
    (_, conn), = grid.cells_dict.items()
    first = conn[:, 0]
    return grid, conn, grid.point_data["held"][first] == 0, grid.point_data["fragment"][first].astype(int)


def face_facets(grid, conn, z, tol=1e-9):
    """The cells with a facet on the face z = const (mask over the cells), and those facets'
    corners (k, 3, 3), undeformed."""
    points = grid.points[conn]  # (cells, 4, 3)
    on = np.abs(points[:, :, 2] - z) < tol
    tri = on.sum(axis=1) == 3
    return tri, points[tri][on[tri]].reshape(-1, 3, 3)


def face_area(grid, conn, chosen, z):
    """The area (m^2, this model's) of the face z = const made of the chosen cells' facets."""
    tri, corners = face_facets(grid, conn, z)
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    return float(area[chosen[tri]].sum())


def through_area(grid, chosen, thickness, spacing=SPACING, levels=LEVELS):
    """The plan area (m^2, this model's) where every sampled depth lies in a chosen cell."""
    lo, hi = np.array(grid.bounds[0::2]), np.array(grid.bounds[1::2])
    xs = np.arange(lo[0] + spacing / 2, hi[0], spacing)
    ys = np.arange(lo[1] + spacing / 2, hi[1], spacing)
    zs = (np.arange(levels) + 0.5) * thickness / levels
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    found = grid.find_containing_cell(np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]))
    inside = np.where(found >= 0, chosen[np.maximum(found, 0)], False).reshape(len(xs), len(ys), levels)
    return float(inside.all(axis=2).sum() * spacing**2)


def measures(folder):
    """The close-in quantities of one completed run (module docstring), whole-slab areas."""
    summary = json.loads((folder / "summary.json").read_text())
    thickness = summary["case"]["geometry"]["thickness"]
    pieces = np.genfromtxt(folder / "fragments.csv", delimiter=",", names=True)
    grid, conn, gone, fragment = cells(folder)
    front, back = (face_area(grid, conn, gone, z) for z in (0.0, thickness))
    breach = SYMMETRY * through_area(grid, gone, thickness)
    reach = np.ones(len(pieces), dtype=bool)  # gone pieces with facets on both faces
    for z in (0.0, thickness):
        touches = np.zeros(len(pieces), dtype=bool)
        touches[fragment[face_facets(grid, conn, z)[0] & gone]] = True
        reach &= touches
    plug_mass = SYMMETRY * pieces["mass_kg"][reach].sum()
    plug_speed = (pieces["mass_kg"][reach] @ pieces["vz_m_s"][reach] / pieces["mass_kg"][reach].sum()
                  if reach.any() else float("nan"))
    loose = pieces["held"] == 0
    return {"status": summary["status"], "cells": summary["cells"], "wall_time_s": summary.get("wall_time_s"),
            "broken_links": summary["broken_links"],
            "crater_m2": SYMMETRY * front, "crater_share": SYMMETRY * front / FACE,
            "spall_m2": SYMMETRY * back, "spall_share": SYMMETRY * back / FACE,
            "breach_m2": breach, "breach_diameter_m": np.sqrt(4 * breach / np.pi),
            "plug_kg": plug_mass, "plug_speed_m_s": plug_speed,
            "loose_pieces": int(loose.sum()), "loose_kg": SYMMETRY * pieces["mass_kg"][loose].sum()}


COLUMNS = [("cells", "cells", "{:,}"), ("broken_links", "links broken", "{:,}"),
           ("crater_m2", "crater (m²)", "{:.3f}"), ("crater_share", "of the slab's face", "{:.1%}"),
           ("spall_m2", "spall (m²)", "{:.3f}"), ("spall_share", "of the slab's face", "{:.1%}"),
           ("breach_m2", "breach (m²)", "{:.3f}"), ("breach_diameter_m", "its diameter (m)", "{:.2f}"),
           ("plug_kg", "plug (kg)", "{:.1f}"), ("plug_speed_m_s", "plug speed (m/s)", "{:.1f}"),
           ("loose_pieces", "loose pieces (half)", "{:,}"), ("loose_kg", "their mass (kg)", "{:.1f}"),
           ("wall_time_s", "wall time (s)", "{:.0f}")]


def faces_png(folders, path, title):
    """The front and back faces of each run (a row per mesh): the gone cells coloured by
    their fragment's speed, the rest grey; the half slab modelled, mid-span on the right."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(folders), 2, figsize=(10, 0.6 + 2.5 * len(folders)), squeeze=False,
                             layout="constrained")
    top = max(float(np.genfromtxt(f / "fragments.csv", delimiter=",", names=True)["speed_m_s"].max())
              for _, f in folders)
    for (size, folder), row in zip(folders, axes):
        grid, conn, gone, _ = cells(folder)
        speed = grid.point_data["fragment_speed"][conn[:, 0]]
        thickness = float(np.ptp(grid.points[:, 2]))
        for ax, z, side in zip(row, (0.0, thickness), ("front (charge side)", "back")):
            tri, corners = face_facets(grid, conn, z)
            ax.add_collection(matplotlib.collections.PolyCollection(
                corners[~gone[tri], :, :2], facecolor="0.85", edgecolor="0.6", linewidth=0.1))
            shown = matplotlib.collections.PolyCollection(corners[gone[tri], :, :2], cmap="viridis",
                                                          edgecolor="none")
            shown.set_array(speed[tri][gone[tri]])
            shown.set_clim(0.0, top)
            ax.add_collection(shown)
            ax.set_xlim(grid.bounds[0], grid.bounds[1])
            ax.set_ylim(grid.bounds[2], grid.bounds[3])
            ax.set_aspect("equal")
            ax.set_title(f"h = {size:g} m, {side} face", fontsize=9)
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
    fig.colorbar(shown, ax=axes, label="speed of the loose piece (m/s)", shrink=0.9)
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(rows):
    lines = ["| h (m) | status | " + " | ".join(title for _, title, _ in COLUMNS) + " |",
             "|---:|---|" + "---:|" * len(COLUMNS)]
    for size, m in rows:
        values = ("–" if m[key] is None or (isinstance(m[key], float) and not np.isfinite(m[key]))
                  else form.format(m[key]) for key, _, form in COLUMNS)
        lines.append(f"| {size:g} | {m['status']} | " + " | ".join(values) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("test", choices=sorted(TESTS))
    parser.add_argument("--sizes", type=float, nargs="+", default=SIZES, help="mesh sizes (m)")
    parser.add_argument("--end", type=float, default=END, help="time.end (s)")
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("results/close-in"))
    parser.add_argument("--table-only", action="store_true", help="tabulate the runs already made, run nothing")
    args = parser.parse_args()
    test = TESTS[args.test]
    rows, folders = [], []
    for size in args.sizes:
        folder = args.out / f"{args.test}-h{size:g}"
        if not args.table_only:
            run(CASE, folder, args.end, args.ranks, [f"mesh.size={size}", f"load.position={test['position']}",
                                                     "output.figures=false", "output.fields=4"])
        if state(folder)[0] == "completed":
            rows.append((size, measures(folder)))
            folders.append((size, folder))
    print(f"\n### {CASE} as test {args.test.upper()} (measured: {test['outcome']}), to {args.end:g} s\n")
    print(table(rows))
    if folders:
        path = args.out / f"{args.test}-faces.png"
        faces_png(folders, path, f"{CASE} as test {args.test.upper()}, t = {args.end * 1e3:.3g} ms: "
                                 "what is gone from each face")
        print(f"\n{path}")


if __name__ == "__main__":
    main()
