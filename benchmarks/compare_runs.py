"""Compare two versions of dolfrag on the same run: the fields and broken links at its end.

    python benchmarks/compare_runs.py run CASE END OUT.npz [--set SECTION.KEY=VALUE ...]
    python benchmarks/compare_runs.py diff A.npz B.npz

``run`` steps the built-in case CASE to END (s) with the dolfrag on the path (set
PYTHONPATH to a checkout of another commit to run that one), prints the CPU time of the
time loop (setup excluded) and the broken links, and saves velocities, displacements, link
states and broken links. ``diff`` prints the largest velocity and displacement differences
relative to the largest value, and whether the same links broke.
"""
import argparse
import time

import numpy as np


def run(case_name, end, out, overrides):
    from mpi4py import MPI

    import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
    from dolfrag.case import load_case
    from dolfrag.problem import Problem
    from dolfrag.runner.driver import prepare

    case = load_case(case_name, [f"time.end={end}", *overrides])
    problem = Problem.build(case, MPI.COMM_SELF)
    integ, n_steps = prepare(problem)[0], problem.n_steps
    start = time.process_time()
    for _ in range(n_steps):
        integ.step()
    cpu = time.process_time() - start
    model = integ.model
    broken = model.broken()
    np.savez(out, v=integ.v.x.array, u=integ.u.x.array, broken=broken, state=model.state_at(np.arange(len(broken))))
    print(f"{case_name} to {end:g} s: {n_steps} steps, {cpu:.1f} s CPU, {int(broken.sum())} broken links")


def diff(a, b):
    a, b = np.load(a), np.load(b)
    for key in ("v", "u"):
        print(f"{key}: largest difference / largest value {np.abs(a[key] - b[key]).max() / np.abs(a[key]).max():.2e}")
    same = np.array_equal(a["broken"], b["broken"])
    print(f"broken links {int(a['broken'].sum())} / {int(b['broken'].sum())}, the same links: {same}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    one = sub.add_parser("run")
    one.add_argument("case")
    one.add_argument("end", type=float)
    one.add_argument("out")
    one.add_argument("--set", action="append", default=[], dest="overrides")
    two = sub.add_parser("diff")
    two.add_argument("a")
    two.add_argument("b")
    args = parser.parse_args()
    if args.command == "run":
        run(args.case, args.end, args.out, args.overrides)
    else:
        diff(args.a, args.b)


if __name__ == "__main__":
    main()
