"""The bulk's stable explicit step of a case's mesh, cell by cell (docs/performance.md,
"The mesh's stable step").

    python benchmarks/stable_step.py bunker-wall-panel --sizes 0.1 0.0667 0.05
    python benchmarks/stable_step.py bunker-wall-panel --sizes 0.0667 --set mesh.optimize_threshold=0.6
    python benchmarks/stable_step.py bunker-wall-panel --sizes 0.0667 --set time.mass_scaling=0.3

Meshes the case at each size on one process (as the run does on rank 0) and prints its cells
and each cell's stable step 2 / omega_max of its own problem Ke x = omega^2 diag(me) x, in
units of h / c_p (c_p the P-wave speed of the case's material): the smallest, which is the
run's step (bars and time.cfl aside), the median, and how many cells lie below 0.2 and 0.25;
with time.mass_scaling, the steps of the scaled mesh. For a case with bars, also the stable
step dt_crit (us) of the bulk with its bars by each time.bars_step rule (rebar/stable_step.py)
and the seconds the "coupled" rule took.
"""
import argparse
import time

import numpy as np
from mpi4py import MPI

import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
from dolfrag import bulk, mesh, space as spaces
from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.rebar import stable_step
from dolfrag.reference import analytic


def cell_steps(case):
    """Each cell's stable step (s) of the case's mesh, and time.mass_scaling's summary
    block (None without it)."""
    domain = mesh.build(case.geometry, case.mesh.size, MPI.COMM_SELF, max_cells=case.run.max_cells,
                        optimize_threshold=case.mesh.optimize_threshold)
    space = spaces.create(domain)
    operators = bulk.assemble(space, domain, case, case.time.mass_scaling)
    Ke, idx = bulk.cell_matrices(operators.K, space)
    return bulk.cell_steps(Ke, operators.m.x.array[idx]), operators.mass_scaling


def bars_steps(case):
    """The stable step (s) of the case's bulk with its bars by the "weyl" and the "coupled"
    rule, and the seconds the latter took; None without bars."""
    problem = Problem.build(case, MPI.COMM_SELF)
    if problem.rebars is None:
        return None
    start = time.process_time()
    coupled = stable_step.stable_step("coupled", problem.bulk, problem.rebars, problem.space)
    seconds = time.process_time() - start
    return stable_step.stable_step("weyl", problem.bulk, problem.rebars, problem.space), coupled, seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case")
    parser.add_argument("--sizes", type=float, nargs="+", required=True, help="mesh sizes h (m)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args()
    print("| h (m) | cells | smallest step (h/c_p) | median | cells below 0.2 | below 0.25 | cells given mass | "
          "added mass (kg) | with the bars, weyl (us) | coupled (us) | its setup (s) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for h in args.sizes:
        case = load_case(args.case, [*args.set, f"mesh.size={h}"])
        steps, scaled = cell_steps(case)
        material = case.material
        steps *= analytic.wave_speed(analytic.p_wave_modulus(material.E, material.nu, material.hypothesis),
                                     material.rho) / h
        added = (f"{scaled['cells']:,} | {scaled['added_mass_kg']:.3g} of {scaled['mass_kg']:.4g}" if scaled
                 else "– | –")
        below = [np.sum(steps < bound * (1 - 1e-9)) for bound in (0.2, 0.25)]  # a scaled cell sits on its target
        bars = bars_steps(case)
        with_bars = f"{bars[0] * 1e6:.3g} | {bars[1] * 1e6:.3g} | {bars[2]:.1f}" if bars else "– | – | –"
        print(f"| {h:g} | {len(steps):,} | {steps.min():.3f} | {np.median(steps):.3f} | {below[0]:,} | "
              f"{below[1]:,} | {added} | {with_bars} |", flush=True)


if __name__ == "__main__":
    main()
