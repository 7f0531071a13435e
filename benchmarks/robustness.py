"""Robustness of the nonsmooth imex step: the expanding bar over three decades of strain rate.

    python benchmarks/robustness.py [--laws linear_softening rccm] [--sizes 0.006 0.004 0.003]
                                    [--rates 0.1 1 10 100]

The case expanding-bar (a 2D bar stretched at a uniform strain rate, ends held) with each
interface law, mesh size and normalised strain rate

    rate* = eps_dot / (c sigma_c^3 / (E^2 G_c)),   c = sqrt(E / rho),

the rate at which the 1D fragmentation theories (Grady; Drugan; Zhou-Molinari-Ramesh) put
the transition between few and many fragments at rate* ~ 1. Each law is taken at its own
strength and toughness, the case's sigma_c = 20 MPa and G_c = 100 J/m^2: linear_softening
directly; rccm with the adhesion energy w = G_c (its work to separation) and the stiffness
C_N = C_T = sigma_c^2 / G_c = 4e12 Pa/m that gives it the peak sigma_c (with C_N = 10 E / h
instead, its peak sqrt(C_N w) would be 42-76 MPa, and its cohesive time below one step
on these meshes). Each run lasts until
2.5 times the time the uniform stretch takes to reach sigma_c, plus 10 cohesive times
E G_c / (c sigma_c^2). A run passes if no vertex star is left unconverged (the run's
ConvergenceError). Prints one table row per run: steps, broken links, links at least half
damaged (RCCM counts a link broken only at beta = 0.01, far in its tail), star solves
accepted within GIVE_UP (stalled), the most Newton iterations of a step, CPU time.
"""
import argparse
import time

import numpy as np
from mpi4py import MPI

import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.runner.driver import prepare



def law_options(law, sigma_c, G_c):
    """Case overrides giving ``law`` the peak sigma_c (Pa) and work to separation G_c (J/m^2)."""
    if law == "rccm":
        C_N = sigma_c**2 / G_c
        return ["interface.law=rccm", "interface.sigma_c=", "interface.G_c=", f"interface.w={G_c}",
                f"interface.C_N={C_N}", f"interface.C_T={C_N}"]
    return [f"interface.law={law}", f"interface.sigma_c={sigma_c}", f"interface.G_c={G_c}"]


def run_one(law, size, rate, comm=MPI.COMM_SELF):
    """Run the expanding bar at normalised rate ``rate`` (-) with ``law`` on ``size`` (m)
    triangles; returns a dict of what the table prints."""
    base = load_case("expanding-bar")
    E, rho = base.material.E, base.material.rho
    sigma_c, G_c = base.interface.sigma_c, base.interface.G_c
    c = np.sqrt(E / rho)
    eps_dot = rate * c * sigma_c**3 / (E**2 * G_c)
    end = 2.5 * sigma_c / (E * eps_dot) + 10 * E * G_c / (c * sigma_c**2)
    case = load_case("expanding-bar", [f"mesh.size={size}", f"load.strain_rate={eps_dot}", f"time.end={end}",
                                       "output.fields=0", "output.figures=false", *law_options(law, sigma_c, G_c)])
    problem = Problem.build(case, comm)
    integ, n_steps = prepare(problem)[0], problem.n_steps
    start = time.process_time()
    iterations, failed_at = 0, None
    for _ in range(n_steps):
        integ.step()
        iterations = max(iterations, integ.interface.iterations)
        if comm.allreduce(integ.interface.unconverged):
            failed_at = integ.t
            break
    return dict(law=law, size=size, rate=rate, eps_dot=eps_dot, steps=integ.n, n_steps=n_steps,
                broken=comm.allreduce(int(integ.model.broken().sum())),
                damaged=comm.allreduce(int((integ.model.damage() >= 0.5).sum())),
                damage_max=comm.allreduce(float(integ.model.damage().max(initial=0.0)), op=MPI.MAX),
                stalled=comm.allreduce(integ.interface.stalled),
                iterations=iterations, failed_at=failed_at, cpu=time.process_time() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", nargs="+", default=["linear_softening", "rccm"])
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.006, 0.004, 0.003])
    parser.add_argument("--rates", type=float, nargs="+", default=[0.1, 1.0, 10.0, 100.0])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print("| law | mesh size (mm) | rate* | strain rate (1/s) | steps | broken links | damaged >= 50 % "
              "| stalled star solves | most Newton iterations | result | CPU (s) |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for law in args.laws:
        for size in args.sizes:
            for rate in args.rates:
                row = run_one(law, size, rate, comm)
                result = "completes" if row["failed_at"] is None else f"ConvergenceError at {row['failed_at']:.3g} s"
                if comm.rank == 0:
                    print(f"| {law} | {1e3 * size:g} | {rate:g} | {row['eps_dot']:.3g} | {row['steps']} | "
                          f"{row['broken']} | {row['damaged']} | {row['stalled']} | {row['iterations']} | {result} | "
                          f"{row['cpu']:.1f} |",
                          flush=True)


if __name__ == "__main__":
    main()
