"""Cost of the hard 3D stars: a cracking box whose rigid stars with friction need the second pass.

    python benchmarks/hard_stars.py [--end 5e-5] [--repeat 1]
    mpirun -n 2 python benchmarks/hard_stars.py

The sound-bar case as a 20 mm thick box of 10 mm tetrahedra (613 cells), linear softening
with sigma_c = 0.4 MPa, G_c = 0.02 J/m^2 and friction mu = 0.3, under its 1 MPa pulse: from
about 40 us the free end cracks (about 100 links broken by 50 us). While held links were
rigid, most steps then left a few 3D stars of sticking and slipping links to the star
solver's second pass (solver/semismooth.py), the stars that made the cracking panel and
bunker steps cost seconds: 26 of the 125 steps, 2.3 s of CPU; with held links as stiff
joints (solver/active_set.COMPLIANCE) none, 0.3 s.
Prints the time loop's CPU time (rank 0; setup and the kernels' compilation excluded: one
untimed warm-up run of 5 steps), the steps, the steps whose stars went to the second pass,
the most Newton iterations of a step and their sum over the steps, star solves accepted
within give_up (stalled) and the links broken.
"""
import argparse
import time

from mpi4py import MPI

import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.runner.driver import prepare
from dolfrag.solver.star_kernel import DEFAULT

BOX = ["geometry.kind=box", "geometry.thickness=0.02", "mesh.size=0.01", "interface.law=linear_softening",
       "interface.sigma_c=4e5", "interface.G_c=0.02", "interface.mu=0.3", "output.fields=0", "output.figures=false"]


def run_once(end, comm, steps=None):
    """The box to ``end`` (s), or its first ``steps``; returns what main prints."""
    problem = Problem.build(load_case("sound-bar", [*BOX, f"time.end={end}"]), comm)
    integ = prepare(problem)[0]
    n_steps = problem.n_steps if steps is None else steps
    start = time.process_time()
    second, most, total = 0, 0, 0
    for _ in range(n_steps):
        integ.step()
        iterations = comm.allreduce(integ.interface.iterations, op=MPI.MAX)
        second += iterations > DEFAULT.max_iterations
        most, total = max(most, iterations), total + iterations
    cpu = comm.allreduce(time.process_time() - start, op=MPI.MAX)
    return dict(cpu=cpu, steps=n_steps, second=second, most=most, total=total,
                stalled=comm.allreduce(integ.interface.stalled),
                broken=comm.allreduce(int(integ.model.broken().sum())))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=5e-5, help="s")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    run_once(args.end, comm, steps=5)  # compiles what the cache lacks
    if comm.rank == 0:
        print(f"cracking 3D box, {comm.size} rank(s), to {args.end:g} s")
        print("| CPU of the time loop (s) | steps | steps with a second pass | most iterations | "
              "iterations summed | stalled star solves | broken links |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
    for _ in range(args.repeat):
        row = run_once(args.end, comm)
        if comm.rank == 0:
            print(f"| {row['cpu']:.2f} | {row['steps']} | {row['second']} | {row['most']} | {row['total']} | "
                  f"{row['stalled']} | {row['broken']} |", flush=True)


if __name__ == "__main__":
    main()
