"""Cost of a time step: ns per element-step and peak memory.

    python benchmarks/step_cost.py [--cells 10000 100000] [--steps 200] [--skip 0]
                                   [--law elastic|rccm] [--scheme imex|theta] [--h-factor 1]
                                   [--dim 2|3] [--set SECTION.KEY=VALUE ...]
    mpirun -n 2 python benchmarks/step_cost.py

Each imex row also gives the bytes the step must stream at least once per element (its
operators, link table and state): divided by the printed bandwidth, the time a step could
not go below.

--scheme theta times the Moreau-Jean step (solver/theta.py, theta = 1/2) at h-factor times
the imex step, after 5 warm-up steps (the first include MUMPS' symbolic analysis), and
reports its mean Newton iterations per step.

A 2D plane-strain bar (the sound-bar case, refined to about the requested number of
triangles) under its pulse; with --dim 3 the same bar as a box of square section, in
tetrahedra. Times only the time loop (setup excluded; --skip steps run untimed before it,
e.g. to time the 3D bar once its links are damaged) and, for the
breakdown, each part of the step repeated alone. Prints one table on rank 0.
With --law rccm the interfaces are RCCM (sigma_c = 0.4 MPa, so the reflected 1 MPa pulse damages
them) with exact contact: the nonsmooth star Newton of every step is timed.
"""
import argparse
import resource
import time

import numpy as np
from mpi4py import MPI

import dolfrag  # noqa: F401  (BLAS thread limit, VTK before DOLFINx)
from dolfrag import loads
from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.runner.driver import integrator
from dolfrag.solver.theta import Theta

# gmsh puts about 2.33 A / h^2 triangles in an area A and 5.5 V / h^3 tetrahedra in a
# volume V (measured).
TRIANGLES_PER_AREA_H2 = 2.33
TETRAHEDRA_PER_VOLUME_H3 = 5.5


def timed(fn, repeat, comm, cpu=None):
    """Wall time (s) of one call of fn, the mean of ``repeat``; with cpu (a list), the CPU
    time of this rank's process per call is appended to it (on a shared machine the wall
    time includes waiting for a core, CPU time does not)."""
    comm.barrier()
    start, start_cpu = time.perf_counter(), time.process_time()
    for _ in range(repeat):
        fn()
    if cpu is not None:
        cpu.append((time.process_time() - start_cpu) / repeat)
    comm.barrier()
    return (time.perf_counter() - start) / repeat


LAWS = {"elastic": [], "rccm": ["interface.law=rccm", "interface.sigma_c=4e5"]}


def measure(cells, steps, comm, law, scheme="imex", h_factor=1.0, dim=2, overrides=(), skip=0):
    case = load_case("sound-bar")
    L, W = case.geometry.length, case.geometry.width
    if dim == 2:
        size = np.sqrt(TRIANGLES_PER_AREA_H2 * L * W / cells)
        shape = []
    else:  # the bar as a square-section box, rollers on its four long faces
        size = np.cbrt(TETRAHEDRA_PER_VOLUME_H3 * L * W * W / cells)
        shape = ["geometry.kind=box", f"geometry.thickness={W}", 'supports.rollers=["bottom","top","front","back"]']
    case = load_case("sound-bar", [f"mesh.size={size}", "time.end=1.0", *shape, *LAWS[law], *overrides])
    problem = Problem.build(case, comm)
    domain, space, integ = problem.domain, problem.space, integrator(problem)
    n_cells = space.mesh.topology.index_map(dim).size_global
    if scheme == "theta":
        return (n_cells, *measure_theta(integ, loads.unit_pressure_vector(space, domain, case.load.boundary),
                                        steps, comm, h_factor, problem.law))
    for _ in range(1 + skip):  # warm-up (and, on a fresh install, the star kernel's compilation)
        integ.step()
    cpu = []
    per_step = timed(integ.step, steps, comm, cpu)
    cpu_ns = f"CPU {1e9 * comm.allreduce(cpu[0], op=MPI.MAX) / (n_cells / comm.size):.0f} ns/elem-step"
    u = integ.u.x.array
    rss = peak_memory(comm)
    floor = comm.allreduce(streamed_bytes(integ), op=MPI.MAX) / (n_cells / comm.size)
    streamed = f"streams >= {floor:.0f} B/elem-step"
    if law != "elastic":
        broken = comm.allreduce(int(integ.model.broken().sum()))
        iterations = comm.allreduce(integ.interface.iterations, op=MPI.MAX)
        return n_cells, per_step, (f"{cpu_ns}; star Newton: {iterations} iterations (last step), {broken} broken "
                                   f"links, {streamed}"), rss
    parts = {
        "bulk K u": lambda: integ.bulk.K_cells @ u[integ.owned],
        "ghost update": lambda: integ.f.x.scatter_forward(),
        "star step": lambda: integ.interface.solve(integ.f.x.array, u, None, integ.dv.x.array),
    }
    breakdown = ", ".join(f"{k} {1e9 * timed(fn, steps, comm) / n_cells:.0f}" for k, fn in parts.items())
    return n_cells, per_step, f"{cpu_ns}; {breakdown}; {streamed}", rss


def streamed_bytes(integ):
    """Bytes an imex step must read at least once (its operators, link table and state
    vectors), on this rank: the memory traffic a step could not go below. Numpy's
    temporaries come on top."""
    arrays = [integ.bulk.K_cells.data, integ.bulk.K_cells.indices, integ.m, integ.u.x.array, integ.v.x.array,
              integ.f.x.array, integ.dv.x.array]
    jump = integ.jump
    arrays += [jump.B.data, jump.B.indices, jump.BT.data, jump.BT.indices, jump.links.normal,
               jump.links.tangents, jump.links.weight, integ.star_comps]
    solver = integ.interface
    layout = getattr(solver, "layout", None)
    if layout is not None:  # the star kernel's flat layout and its cached factors: the blocks taken
        cache = layout.cache()
        arrays += [*layout.geometry(), *cache.blocks, cache.factors[:cache.blocks.top[0]], layout.comps, layout.links]
        arrays += [getattr(cache, f) for f in cache._fields if f not in ("blocks", "factors")]
    else:  # the elastic step's flat layout and inverses
        fl = solver.flat
        arrays += [fl.comps, fl.comp_off, fl.link_off, fl.slot_A, fl.slot_B, solver.K, solver.inverse, solver.inv_off]
    return sum(a.nbytes for a in arrays)


def bandwidth(megabytes=128):
    """Memory bandwidth (bytes/s) of a numpy copy on this machine: read + write of a
    ``megabytes`` array, best of 5."""
    a = np.ones(megabytes * 2**20 // 8)
    b = np.empty_like(a)
    best = min(timed_once(lambda: np.copyto(b, a)) for _ in range(5))
    return 2 * a.nbytes / best


def timed_once(fn):
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def peak_memory(comm):
    """Largest peak resident memory over the ranks, MB."""
    return comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, op=MPI.MAX) / 1024


def measure_theta(imex, load, steps, comm, h_factor, law):
    """The theta step on the imex integrator's mesh and model (of the interface/models.Law
    ``law``), h_factor times its step."""
    integ = Theta(imex.space, imex.bulk, imex.jump, imex.model, load, imex.pressure, h_factor * imex.h, 0.5,
                  imex.interface.stars.constrained, contact=not law.springs)
    for _ in range(5):
        integ.step()
    iterations = []

    def step():
        integ.step()
        iterations.append(integ.interface.iterations)
    per_step = timed(step, steps, comm)
    broken = comm.allreduce(int(integ.model.broken().sum()))
    return per_step, (f"h = {integ.h:.3g} s, {np.mean(iterations):.1f} Newton iterations/step, "
                      f"{broken} broken links"), peak_memory(comm)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--skip", type=int, default=0, help="imex steps run untimed before the timed ones")
    parser.add_argument("--law", choices=sorted(LAWS), default="elastic")
    parser.add_argument("--scheme", choices=("imex", "theta"), default="imex")
    parser.add_argument("--h-factor", type=float, default=1.0, help="theta step / imex step")
    parser.add_argument("--dim", type=int, choices=(2, 3), default=2, help="2D bar or 3D box bar")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a key of the bar's case, e.g. material.bulk_viscosity=false")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print(f"{args.scheme} step, {'2D plane strain' if args.dim == 2 else '3D'}, {args.law} interfaces, "
              f"{comm.size} rank(s)")
        print(f"{'cells':>8s} {'ms/step':>8s} {'ns/elem-step':>13s} {'peak MB/rank':>13s}  "
              "breakdown ns/elem-step (wall) / notes")
    for target in args.cells:
        n_cells, per_step, breakdown, rss = measure(target, args.steps, comm, args.law, args.scheme, args.h_factor,
                                                    args.dim, args.set, args.skip)
        if comm.rank == 0:
            print(f"{n_cells:8d} {1e3 * per_step:8.2f} {1e9 * per_step / n_cells:13.0f} {rss:13.0f}  {breakdown}")
    # after the runs, so that its array is not in their peak memory; every rank at once, as in a run
    speed = bandwidth()
    if comm.rank == 0:
        print(f"memory bandwidth (numpy copy, read + write, per rank with all ranks copying): {speed / 1e9:.1f} GB/s")


if __name__ == "__main__":
    main()
