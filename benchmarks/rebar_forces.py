"""CPU time of the bars' explicit forces (rebar/cables.py, Rebars.forces), per segment and call.

    python benchmarks/rebar_forces.py                       # wall-bending-clamped's bars at h = 5 mm
    python benchmarks/rebar_forces.py --size 0.0025 --calls 2000
    python benchmarks/rebar_forces.py --kinematics small_strain

The case's bars on its mesh (one process), a random displacement of 1e-4 m (strains of about
1e-2: slack, elastic and yielding segments alike), the forces computed ``calls`` times after
one warm-up call; prints the segments, and the CPU time (time.process_time) per call and per
segment, best of ``repeat`` rounds.
"""
import argparse
import time

import numpy as np
from mpi4py import MPI

import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
from dolfrag import mesh, space as spaces
from dolfrag.case import load_case
from dolfrag.rebar import cables, layout


def bars_of(name, size, kinematics):
    case = load_case(name, [f"mesh.size={size}"])  # the kinematics by argument: the script runs on earlier code
    comm = MPI.COMM_SELF
    space = spaces.create(mesh.build(case.geometry, size, comm))
    lines, areas = layout.layer_polylines(case.rebar, case.geometry, space.gdim)
    r = case.rebar
    options = {"small_strain": True} if kinematics == "small_strain" else {}
    return cables.Rebars(space, lines, areas, r.E, r.f_y, r.rho, size, comm, **options)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="wall-bending-clamped")
    parser.add_argument("--size", type=float, default=0.005, help="mesh.size (m)")
    parser.add_argument("--kinematics", default="exact", choices=("exact", "small_strain"))
    parser.add_argument("--calls", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    bars = bars_of(args.case, args.size, args.kinematics)
    u = np.random.default_rng(1).normal(scale=1e-4, size=bars.C.shape[1])
    bars.forces(u, commit=False)  # compiled, or loaded from numba's cache
    best = np.inf
    for _ in range(args.repeat):
        start = time.process_time()
        for _ in range(args.calls):
            bars.forces(u, commit=False)
        best = min(best, (time.process_time() - start) / args.calls)
    n = len(bars.L)
    print(f"{args.case}, h = {args.size:g} m, {args.kinematics}: {n:,} segments, "
          f"{best * 1e6:.2f} us a call, {best / n * 1e9:.1f} ns a segment (CPU, best of {args.repeat})")


if __name__ == "__main__":
    main()
