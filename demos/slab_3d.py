# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: light
# ---

# # A clamped slab in 3D: slow bending against the thin-plate closed form
#
# The reinforced concrete wall of the reference paper (*Study and simulation of fragmentation
# phenomena of concrete structures under stuffy explosion*) is a slab, 1 m × 1 m × 0.10 m, clamped on its
# four edges (the built-in cases `slab-3d-scabbing` and `slab-3d-bending`, docs/slab.md).
# Before it cracks, a pressure that rises slowly against the slab's first period bends it
# statically, and a thin clamped square plate of side $a$ and thickness $t$ deflects at its
# centre by (Timoshenko & Woinowsky-Krieger, §44, table 35)
#
# $$w = \alpha \frac{q a^4}{D}, \qquad \alpha = 0.00126, \qquad D = \frac{E t^3}{12 (1 - \nu^2)}.$$
#
# `dolfrag.reference.analytic.clamped_plate_deflection` computes $\alpha$ by Ritz (0.0012653).
#
# This demo runs a reduced slab, `tests/cases/slab-ramp.toml`: plain concrete 0.5 m × 0.5 m
# × 0.05 m (span / thickness = 10, as the full slab), E = 35 GPa, ν = 0.2,
# ρ = 2350 kg/m³, tetrahedra of 25 mm (two through the thickness, 4,662 cells), elastic
# interfaces on every facet (C_N = C_T = 10 E/h), clamped edges, a pressure rising as
# $P(4\tau^3 - 3\tau^4)$, $\tau = t / t_r$, to P = 1 bar in $t_r$ = 7.5 ms (ten periods of
# the first mode), `theta` steps of 50 µs. It compares the centre deflection at the peak
# with the thin plate and with the static solution of the same mesh (`homogenise.py`),
# which the slow run must follow to within its quasi-static lag $12/(\omega t_r)^2$ ≈ 0.3 %.
# The gap to the thin plate is the discretisation's: P1 tetrahedra lock in bending (two
# through the thickness are too stiff), the interface springs and the shear deformation of
# a plate only ten times thinner than wide soften it (docs/slab.md measures each).
#
# Run: `python demos/slab_3d.py` or `mpirun -n 2 .venv/bin/python demos/slab_3d.py`
# (options after the script name are `--set section.key=value` overrides, e.g.
# `--set mesh.size=0.02`). The full slab cases run the same way:
# `mpirun -n 2 .venv/bin/dolfrag run slab-3d-scabbing --out results/slab-scabbing`.

# +
import argparse
from pathlib import Path

from mpi4py import MPI

import dolfrag
from dolfrag.reference import analytic, homogenise
from dolfrag.case import load_case

parser = argparse.ArgumentParser()
parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
case = load_case(Path(__file__).resolve().parents[1] / "tests" / "cases" / "slab-ramp.toml",
                 parser.parse_args().set)
summary = dolfrag.run(case, f"results/{case.name}", quiet=True)
# -

# The centre deflection (the mean displacement across the thickness near the centre line)
# peaks with the load; `summary.json` → `wall` has it, and the thin-plate estimate beside it.

# +
comm = MPI.COMM_WORLD
w_static = homogenise.static_centre_deflection(case) if comm.rank == 0 else None
w_static = comm.bcast(w_static, root=0)
if comm.rank == 0:
    g, mat = case.geometry, case.material
    D = analytic.plate_rigidity(mat.E, g.thickness, mat.nu)
    w_plate = analytic.clamped_plate_deflection(case.load.peak, g.length, g.width, D)
    w_run = summary["wall"]["midspan_deflection"]["peak_m"]
    print(f"\nClamped slab {g.length} m x {g.width} m x {g.thickness} m, {summary['cells']} tetrahedra, "
          f"{summary['ranks']} rank(s), {summary['wall_time_s']:.1f} s")
    print(f"{'centre deflection at 1 bar':36s} {'w (um)':>8s} {'/ thin plate':>12s}")
    for label, w in (("thin plate, 0.0012653 q a^4 / D", w_plate),
                     ("static solution of this mesh", w_static * case.load.peak),
                     ("dolfrag, slow ramp (theta)", w_run)):
        print(f"{label:36s} {w * 1e6:8.3f} {w / w_plate:12.4f}")
    print(f"slow run / static solution - 1: {w_run / (w_static * case.load.peak) - 1:+.2%} "
          f"(quasi-static lag, expected ~ +0.3 %)")
    print(f"Energy balance error: {summary['balance_error_relative']:.1e} of the work")
# -
