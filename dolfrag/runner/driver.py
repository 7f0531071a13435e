"""`run(case, out)`: build the problem, step it through the time loop with its observers,
and write summary.json once, at the end (completed, failed or interrupted)."""
import hashlib
import os
import traceback
from pathlib import Path
from time import perf_counter

import numpy as np
from mpi4py import MPI

from dolfrag import __version__, guards, loads
from dolfrag.case import Case, CaseError, load_case
from dolfrag.post.output import RunOutput
from dolfrag.problem import Problem
from dolfrag.progress import Progress
from dolfrag.runner import checkpoint
from dolfrag.runner.breaks import BreakTimes
from dolfrag.runner.context import RunContext
from dolfrag.runner.fields import FieldSnapshots
from dolfrag.runner.final import common_figures, finish
from dolfrag.runner.fragment_times import RequestedFragments
from dolfrag.runner.history import History, Probes, RebarForce
from dolfrag.runner.loop import Guard, time_loop
from dolfrag.runner.reports import REPORTS
from dolfrag.runner.signals import Stop
from dolfrag.solver import Integrator
from dolfrag.solver.imex import Imex
from dolfrag.solver import star_replay
from dolfrag.solver.semismooth import ConvergenceError
from dolfrag.solver.theta import Theta
from dolfrag.loads.stretch import Stretch

REPORT_ERRORS = "report_errors.txt"  # the tracebacks of the parts of a run's end that failed


def integrator(problem) -> Integrator:
    """The case's integrator (time.scheme), built from ``problem``."""
    return (Theta if problem.case.time.scheme == "theta" else Imex).from_problem(problem)


def prepare(problem):
    """(integrator, stretch): the case's integrator, and for a stretch load its
    stretch.Stretch, started on it (else None). Collective."""
    integ, case, stretch = integrator(problem), problem.case, None
    if case.load.kind == "stretch":
        stretch = Stretch(problem.space, problem.domain, case.load.strain_rate)
        stretch.start(integ, problem.stars.comps)
    return integ, stretch


def resume_command(out, comm, verb="run --resume"):
    """The command that continues the run in ``out``: under a Slurm job, srun (a job script
    of `dolfrag batch` resumes by itself when requeued), else mpirun on as many ranks."""
    launcher = "srun " if "SLURM_JOB_ID" in os.environ else "" if comm.size == 1 else f"mpirun -n {comm.size} "
    return f"{launcher}dolfrag {verb} {out}"


def run(case, out, quiet=False, comm=None, resume=False):
    """Run ``case`` (a case.Case, a case file path or a built-in name; ignored with
    ``resume``, which continues the run whose checkpoint is in ``out``); write
    summary.json, history.csv, fields.pvd, links.csv and figures/ into ``out``. Collective.
    Returns the summary dict; its "status" is "interrupted" after SIGINT or SIGTERM."""
    comm = comm or MPI.COMM_WORLD
    out = Path(out)
    ctx, saved, wall_start = _start(case, out, comm, resume)
    case, problem, integ = ctx.case, ctx.problem, ctx.integ
    first_step = saved["step"] if saved else 0
    history, rows, observers, reports, fields, output = _observers(ctx, saved and first_step)
    stateful = _stateful(integ, output, rows + observers)
    before = 0.0  # s of wall time of the segments before this one
    if saved is not None:  # the loaded states dropped as they are restored: not kept twice (the star factors)
        states = _by_name(saved.pop("objects"), rows + observers)
        for name, obj in stateful.items():
            checkpoint.restore_object(obj, states.pop(name))
        before = saved["wall_time_s"]

    def save(k):
        checkpoint.write(out, comm, {"step": k, "layout": _layout(problem),
                                     "cells": problem.owned_cell_centroids(),
                                     "wall_time_s": before + perf_counter() - wall_start,
                                     "objects": {n: checkpoint.object_state(o) for n, o in stateful.items()}},
                         case)

    summary = _header(case, problem, integ, comm)
    if saved is not None:
        summary["resumed_from_step"] = first_step
    progress = Progress(problem.n_steps, quiet=quiet, rank=comm.rank)
    stop = Stop(comm)
    try:
        with stop:
            fields.start()
            try:
                last = time_loop(ctx, observers, rows, output, stop, save, progress, first_step,
                                 _guard(integ, stop, stateful))
            except ConvergenceError:
                output.failure(lambda vtk: fields.write(integ.t, vtk))  # the state, for a look
                _dump_failed_stars(integ, out, comm)
                raise
        summary["timings_s"] = integ.timer.summary(comm)
        # star solves accepted at their best iterate within StarOptions.give_up (imex)
        summary["stalled_star_solves"] = comm.allreduce(integ.interface.stalled)
        summary["second_pass_starts"] = comm.allreduce(integ.interface.remembered)
        summary["status"] = "completed" if last == problem.n_steps else "interrupted"
    except BaseException as err:
        summary["status"] = f"failed at t = {integ.t:.6g} s: {type(err).__name__}: {err}"
        _close(summary, history, integ, output, before + perf_counter() - wall_start)
        output.summary(summary)
        raise
    _close(summary, history, integ, output, before + perf_counter() - wall_start)
    if summary["status"] != "completed":
        summary.update(signal=stop.signal.name, time_reached_s=integ.t, resume=resume_command(out, comm))
        output.summary(summary)
        return summary
    with stop:  # a stop while the reports are made leaves the rest to `dolfrag report`
        _complete(ctx, output, fields, summary, [*rows[1:], *observers, *reports], reports, stop)
    if summary["status"] == "interrupted":
        summary.update(signal=stop.signal.name, time_reached_s=integ.t, resume=resume_command(out, comm, "report"))
        output.summary(summary)
    return summary


def _start(case, out, comm, resume):
    """(ctx, saved, wall_start): the RunContext of ``case`` (a Case, a case name or file; the
    checkpoint's case in ``out`` if ``resume``) with its problem built and its integrator
    started, the checkpoint's data (None unless resuming) and the perf_counter() time (s) at
    which the run's wall time starts, once the load and the limits are known. Collective;
    raises CaseError on bad input or a checkpoint of another partition."""
    if resume:
        case = checkpoint.case_of(out)
    elif not isinstance(case, Case):
        case = load_case(case)
    applied = loads.applied(case.load, comm)
    guards.report(case, applied, comm)
    wall_start = perf_counter()
    saved = checkpoint.load(out, comm) if resume else None
    problem = Problem.build(case, comm, saved and checkpoint.owner_rule(saved["cells"], comm), applied)
    guards.warn(guards.toughness_warning(case), comm)  # once the mesh is known good: after bad input
    integ, stretch = prepare(problem)
    if saved is not None and saved["layout"] != _layout(problem):
        raise CaseError(f"--resume {out}: this rank's mesh partition differs from the checkpoint's")
    return RunContext(problem, integ, comm, out, stretch, np.full(len(problem.links), np.nan)), saved, wall_start


def _stateful(integ, output, providers):
    """{checkpoint key: object} of every object whose state a checkpoint keeps: the
    integrator's parts, the fields file and the history's and observers'
    ``providers``, each under its class name."""
    return {"integrator": integ, "model": integ.model, "interface": integ.interface, "rebars": integ.rebars,
            "star_layout": integ.interface.layout, "viscosity": integ.viscosity, "fields_file": output.vtk,
            **{type(o).__name__: o for o in providers}}


def _by_name(states, providers):
    """A checkpoint's {key: state} with each of ``providers`` under its class name. A
    checkpoint written before the observers were named keys them by class name and
    position among the providers ("History0"), an order a resumed run shares: those keys
    are renamed, so that such a run still resumes."""
    states = dict(states)
    for i, provider in enumerate(providers):
        name = type(provider).__name__
        if f"{name}{i}" in states:
            states[name] = states.pop(f"{name}{i}")
    return states


def _guard(integ, stop, stateful):
    """For an integrator that can abandon a step (``abandonable``), the loop.Guard of its
    steps, keeping what a step changes; else None."""
    if not integ.abandonable:
        return None
    changed = ("integrator", "model", "interface", "star_layout", "rebars", "viscosity")
    return Guard(integ, stop, checkpoint.Rewind([stateful[name] for name in changed]))


def _dump_failed_stars(integ, out, comm):
    """Each rank's unconverged vertex stars (imex), for solver/star_replay.py."""
    failed = integ.interface.failed
    if failed is not None:
        star_replay.dump(Path(out) / f"failed_stars_rank{comm.rank}.npz", failed, t=integ.t, step=integ.n,
                         rank=comm.rank)


def _observers(ctx, resume_step):
    """(history, rows, observers, reports, fields, output) of a run: the history columns'
    providers in order (history first), the observers of every step, the per-kind reports
    that apply, the field snapshots, and the RunOutput (history.csv continued after
    resume_step, if given)."""
    reports = [report(ctx) for report in REPORTS if report.applies(ctx.case)]
    history = History(ctx)
    rows = [history, Probes(ctx), *(r for r in reports if r.columns),
            *([RebarForce(ctx)] if RebarForce.applies(ctx.problem) else [])]
    fields = FieldSnapshots(ctx, None, resume_step)
    output = RunOutput(ctx.out, ctx.comm, [c for row in rows for c in row.columns], fields=bool(fields.steps),
                       resume_step=resume_step)
    fields.output = output
    observers = [BreakTimes(ctx), fields, RequestedFragments(ctx), *(r for r in reports if r.observe is not None)]
    return history, rows, observers, reports, fields, output


def _complete(ctx, output, fields, summary, summarising, reports, stop):
    """A completed loop's end: fragments and links.csv, every block of summary.json, the
    figures, each a part of an _End. summary.json is written before the figures, and again
    if one of them failed or was not made. Collective."""
    end = _End(ctx, stop)
    final = end.part("fragments", lambda: finish(ctx, output, fields.damage, summary["wall_time_s"], summary))
    if final is not None:
        for observer in dict.fromkeys(summarising):  # each once, in order
            if observer.summarise is not None:
                end.part(f"{type(observer).__name__}.summarise", lambda: observer.summarise(summary, final))
    end.settle(summary)
    output.summary(summary)
    if ctx.case.output.figures and final is not None:
        folder = ctx.out / "figures"
        end.part("figures", lambda: common_figures(ctx, folder, final))
        for report in reports:
            end.part(f"{type(report).__name__}.figures", lambda: report.figures(folder, final))
        if end.settle(summary):
            output.summary(summary)


class _End:
    """The parts of a completed loop's end, each run guarded: one that raises, on any rank,
    is named ("name: Error: message", one line, the first failing rank's; its traceback goes
    to REPORT_ERRORS in the run's folder) and the parts after it still run; after a stop
    request (SIGINT, SIGTERM) the parts left are not made, and named as missing."""

    def __init__(self, ctx, stop):
        self.ctx, self.stop, self.failures, self.missing = ctx, stop, [], []
        if ctx.comm.rank == 0:
            (ctx.out / REPORT_ERRORS).unlink(missing_ok=True)  # a remade end starts clean

    def part(self, name, action):
        """action()'s value, or None if it failed or was not made. Collective."""
        if self.missing or self.stop.pending():
            self.missing.append(name)
            return None
        try:
            value, error = action(), None
        except Exception as err:  # a report's bug must not cost the run: it is named instead
            value, error = None, (f"{name}: {type(err).__name__}: {' '.join(str(err).split())}",
                                  traceback.format_exc())
        error = next((e for e in self.ctx.comm.allgather(error) if e), None)
        if error is None:
            return value
        self.failures.append(error[0])
        if self.ctx.comm.rank == 0:
            with open(self.ctx.out / REPORT_ERRORS, "a") as f:
                f.write(error[1] + "\n")
        return None

    def settle(self, summary):
        """The summary's status: "interrupted" (with ``missing_outputs``) if a stop left parts
        unmade, "report_failed" (with ``report_errors``) if one failed, else "completed".
        Returns whether the end is incomplete."""
        summary["status"] = "interrupted" if self.missing else "report_failed" if self.failures else "completed"
        for key, names in (("report_errors", self.failures), ("missing_outputs", self.missing)):
            if names:
                summary[key] = names
        return bool(self.failures or self.missing)


def _close(summary, history, integ, output, wall_time):
    """Close history.csv and fields.pvd; the steps, wall time and energies into ``summary``."""
    summary["steps_done"] = integ.n
    summary["wall_time_s"] = wall_time
    history.summarise(summary)
    output.close()


def _header(case, problem, integ, comm):
    space = problem.space
    return {"case": case.to_dict(), "version": __version__, "ranks": comm.size,
            "cells": space.mesh.topology.index_map(space.mesh.topology.dim).size_global,
            "links": comm.allreduce(len(problem.links)), "dofs": space.V.dofmap.index_map.size_global * space.gdim,
            "steps": problem.n_steps, "dt_s": integ.h, "dt_crit_s": problem.dt_crit,
            **({"mass_scaling": problem.bulk.mass_scaling} if problem.bulk.mass_scaling else {}),
            "interface_stiffness_Pa_m": {"C_N": integ.model.C_N, "C_T": integ.model.C_T},
            **({"load": loads.summary_block(case.load, problem.applied_load, comm, charge=problem.load)}
               if case.load.kind == "pressure" else {}),
            "status": "running"}


def _layout(problem):
    """This rank's share of the mesh: owned dofs, links, and a digest of the dof coordinates."""
    space = problem.space
    digest = hashlib.sha1(np.ascontiguousarray(space.x).tobytes()).hexdigest()
    return space.n_owned_dofs, len(problem.links), digest
