"""The `dolfrag` command: a thin layer over dolfrag.runner.

    dolfrag run CASE [--out DIR] [--overwrite] [--set section.key=value ...] [--quiet]
    dolfrag run --resume DIR [--quiet]
    dolfrag report DIR
    dolfrag cases [NAME]
    dolfrag --version
    dolfrag loads CASE [--set section.key=value ...] [--out PNG]
    dolfrag batch CASE --ranks N --time HH:MM:SS --out DIR [--partition P] [--set ...]
                  [--overwrite] [--submit | --dry-run]

`loads` plots the case's pressure p(t) over [0, time.end] (default PNG:
results/<case name>/load.png) and prints the PNG path, then the signal's peak (Pa)
and its time (s), impulse (Pa s) and duration (s) as `name = value` lines; for an
h2-air load also the gas states behind it (AICC, CJ detonation, reflected pressure,
Taylor plateau, burnt-gas sound speed, acoustic frequency) beside published values. A
charge is applied on the meshed boundary (the mesh is built): p(t) at the nearest and
farthest loaded facets and the face's mean, maps of peak pressure and impulse, and the
charge's numbers (TNT mass, Z range, the blast at both facets).

`batch` writes DIR/job.sbatch, a Slurm job that runs the case in DIR/run on N ranks and
requeues itself at each wall-time limit until the run completes (dolfrag/batch.py,
docs/cluster.md); `--submit` also submits it and prints the job id, `--dry-run` prints the
script and writes nothing. Its inputs are checked as `run` checks them, before anything is
queued.

CASE is a case file (TOML) or a built-in case name. Bad input exits with status 2
and one line naming the key, the value and what is allowed. `run` refuses an --out
folder that is not empty (a run never mixes its files with another's) unless
--overwrite, which empties it first.

`run` checkpoints every output.checkpoint_every seconds of wall time and at the end;
SIGINT or SIGTERM stop it at the end of the current step (checkpoint, summary.json with
status "interrupted"), exit 130 or 143; `--resume DIR` continues it on as many ranks.
A stop while the outputs are made after the loop leaves the rest unmade, named in
summary.json (status "interrupted", `missing_outputs`). A completed run is not resumed
(exit 2). If a report or figure fails after the time loop, summary.json still holds what the loop produced, with status "report_failed" and the
failing part named; the command exits 1 with one line (`--debug`: and the tracebacks,
which the folder's report_errors.txt keeps). `report DIR` makes the reports of a run whose
loop finished again from its last checkpoint, without recomputing (`run --resume` does the
same for a run whose reports failed).
"""
import argparse
import json
import signal
import sys
import traceback
from pathlib import Path

from mpi4py import MPI

from dolfrag import __version__, batch, guards, loads, outdir
from dolfrag.case import CaseError, builtin_case_text, builtin_cases, load_case
from dolfrag.loads import gas
from dolfrag.runner.driver import REPORT_ERRORS, run
from dolfrag.runner.signals import EXIT_CODES
from dolfrag.solver import star_replay
from dolfrag.solver.semismooth import ConvergenceError


def _parser():
    parser = argparse.ArgumentParser(prog="dolfrag", description="Fragmentation of concrete "
                                     "under dynamic loads (cohesive interfaces on every facet). SI units.")
    parser.add_argument("--version", action="version", version=f"dolfrag {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a case")
    run.add_argument("case", nargs="?", help="case file (.toml) or built-in case name (see `dolfrag cases`)")
    run.add_argument("--resume", metavar="DIR", help="continue the run whose checkpoint is in DIR (same rank count)")
    run.add_argument("--out", help="output folder, new or empty (default: results/<case name>)")
    run.add_argument("--overwrite", action="store_true", help="empty a non-empty --out folder first")
    run.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                     help="override a case parameter, e.g. --set mesh.size=0.004 (repeatable); "
                          "no value (--set time.dt=) removes it")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--debug", action="store_true", help="print the tracebacks of failed reports")
    report = sub.add_parser("report", help="make the reports, figures and summary.json of a finished run again "
                                           "from its checkpoint (same rank count)")
    report.add_argument("dir", help="the run's output folder")
    report.add_argument("--debug", action="store_true", help="print the tracebacks of failed reports")
    cases = sub.add_parser("cases", help="list the built-in cases with what each is for, or print one as TOML")
    cases.add_argument("name", nargs="?")
    plot = sub.add_parser("loads", help="plot a case's load signal p(t) to PNG, print peak and impulse")
    plot.add_argument("case", help="case file (.toml) or built-in case name")
    plot.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                      help="override a case parameter, e.g. --set load.peak=2e6 (repeatable)")
    plot.add_argument("--out", help="PNG file (default: results/<case name>/load.png)")
    job = sub.add_parser("batch", help="write a Slurm job script that runs a case through wall-time limits "
                                       "(checkpoint, requeue, resume)")
    job.add_argument("case", help="case file (.toml) or built-in case name")
    job.add_argument("--ranks", type=int, required=True, help="MPI ranks (Slurm tasks), the same at every start")
    job.add_argument("--time", required=True, metavar="HH:MM:SS", help="wall-time limit of each start")
    job.add_argument("--out", required=True, metavar="DIR",
                     help="new or empty folder: job.sbatch, the Slurm log, the run in DIR/run")
    job.add_argument("--partition", help="Slurm partition (default: the cluster's)")
    job.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                     help="override a case parameter, as for run (repeatable)")
    job.add_argument("--overwrite", action="store_true", help="empty a non-empty --out folder first")
    mode = job.add_mutually_exclusive_group()
    mode.add_argument("--submit", action="store_true", help="submit the script with sbatch and print the job id")
    mode.add_argument("--dry-run", action="store_true", help="print the script; write nothing")
    replay = sub.add_parser("replay", help="solve again the vertex stars a stopped run could not solve")
    replay.add_argument("dump", help="a failed_stars_rank<r>.npz the stopped run wrote")
    replay.add_argument("--max-iterations", type=int, help="Newton iterations per star (default: the run's)")
    return parser


def _plot_load(case, out, comm):
    """Draw the case's p(t) over [0, time.end] and print the path, peak, impulse, duration
    (and an h2-air load's gas states)."""
    from dolfrag.post.figures import signal_png
    if case.load.kind != "pressure":
        raise CaseError(f"load.kind = {case.load.kind!r}: no pressure signal to plot (only load.kind = 'pressure')")
    if case.load.signal == "charge":
        _plot_charge(case, out, comm)
        return
    applied = loads.applied(case.load, comm)
    peak, peak_time, impulse, duration = loads.signal_summary(applied)
    path = Path(out or f"results/{case.name}/load.png")
    if comm.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
    signal_png(loads.signal(applied), case.time.end, path, comm,
               f"{case.load.signal} on '{case.load.boundary}': peak {peak:.3g} Pa, impulse {impulse:.3g} Pa s")
    if comm.rank == 0:
        print(f"{path}\npeak_Pa = {peak:.6g}\npeak_time_s = {peak_time:.6g}\n"
              f"impulse_Pa_s = {impulse:.6g}\nduration_s = {duration:.6g}")
        if case.load.signal == "h2-air":
            print(_h2_air_lines(loads.h2_air_numbers(case.load, comm)))


def _plot_charge(case, out, comm):
    """Build the mesh, apply the charge on it (loads.charge_load), draw charge_png and print
    the path and the charge's numbers as `name = value` lines (SI)."""
    from dolfrag import mesh, space as spaces
    from dolfrag.loads.charge_load import ChargeLoad
    from dolfrag.post.figures import charge_png
    domain = mesh.build(case.geometry, case.mesh.size, comm, max_cells=case.run.max_cells,
                        optimize_threshold=case.mesh.optimize_threshold)
    charge = ChargeLoad(case.load, spaces.create(domain), domain, comm)
    path = Path(out or f"results/{case.name}/load.png")
    if comm.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
    block = charge.summary()
    charge_png(charge, case.time.end, path, comm,
               f"{block['mass_kg']:g} kg {block['explosive']} ({block['tnt_mass_kg']:.3g} kg TNT), {block['burst']}, "
               f"on '{case.load.boundary}'")
    if comm.rank == 0:
        lines = [str(path)] + [f"{name} = {value:.6g}" for name, value in block.items()
                               if isinstance(value, float)]
        for point in ("nearest", "farthest"):
            lines += [f"{point}.{name} = {value:.6g}" for name, value in block[point].items()
                      if isinstance(value, float)]
        print("\n".join(lines))


def _h2_air_lines(numbers):
    """`name = value  # note` lines of an h2-air load's numbers (loads.h2_air_numbers), SI,
    pressures also in bar, beside gas.PUBLISHED for its oxidiser (the stoichiometric mixture)."""
    bar, ref = 1e-5, gas.PUBLISHED[numbers["oxidizer"]]
    P_CJ, published = numbers["P_CJ_Pa"], f"{ref['state']}, published"
    aicc = f"{numbers['P_AICC_Pa'] * bar:.3f} bar absolute"
    notes = {
        "P_AICC_Pa": f"{aicc}; {published} {ref['P_AICC_Pa'] * bar:.0f} bar" if "P_AICC_Pa" in ref else aicc,
        "T_AICC_K": "adiabatic isochoric complete combustion",
        "c_b_m_s": "burnt gas (AICC), equilibrium sound speed",
        "frequency_Hz": "c_b / (2 room_length)",
        "D_CJ_m_s": f"{published} {ref['D_CJ_m_s']:g} m/s",
        "P_CJ_Pa": f"{P_CJ * bar:.2f} bar absolute; {published} {ref['P_CJ_Pa'] * bar:.3g} bar",
        "T_CJ_K": f"{published} {ref['T_CJ_K']:g} K" if "T_CJ_K" in ref else "",
        "u_CJ_m_s": "burnt gas velocity behind the CJ front",
        "P_reflected_Pa": f"{numbers['P_reflected_Pa'] * bar:.2f} bar absolute = {numbers['P_reflected_Pa'] / P_CJ:.2f}"
                          f" P_CJ; usual estimate {ref['reflected_per_P_CJ']} P_CJ",
        "T_reflected_K": "",
        "P_Taylor_Pa": f"{numbers['P_Taylor_Pa'] * bar:.2f} bar absolute = {numbers['P_Taylor_Pa'] / P_CJ:.3f} P_CJ;"
                       f" usual estimate {ref['Taylor_per_P_CJ']} P_CJ",
        "peak_overpressure_Pa": "(1 - heat_loss)(P_AICC - p0), the mean pressure's peak"
                                if numbers["regime"] == "deflagration" else "P_reflected - p0, the spike",
        "plateau_overpressure_Pa": "(1 - heat_loss)(P_AICC - p0)",
        "decay_s": "", "damping_s": ""}
    diluted = f" + {numbers['diluent_fraction']:g} {numbers['diluent']}" if numbers.get("diluent_fraction") else ""
    head = (f"# h2-air, {numbers['h2_fraction']:g} H2 by volume in H2-{numbers['oxidizer']}{diluted}, "
            f"{numbers['regime']}, T0 = {numbers['T0_K']:g} K, p0 = {numbers['p0_Pa']:g} Pa "
            f"(Cantera {numbers['cantera']}, {numbers['mechanism']}: the species of the mixture's elements)")
    return "\n".join([head] + [f"{name} = {numbers[name]:.6g}" + (f"  # {note}" if note else "")
                                for name, note in notes.items() if name in numbers])


def _case_list():
    """One line per built-in case: its name and its description."""
    names = builtin_cases()
    width = max(map(len, names))
    return "\n".join(f"{name:<{width}}  {load_case(name).description}" for name in names)


def _case_text(name):
    """A built-in case's TOML, followed by comment lines giving the values its strength
    class fills in and where each comes from (so the text stays a valid case file)."""
    text, case = builtin_case_text(name), load_case(name)
    sources, case = case.sources, case.to_dict()
    if not sources:
        return text
    lines = ["", "# Values in force that the file does not give (SI units), and their source:"]
    for key, source in sources.items():
        value = case
        for part in key.split("."):
            value = value[part]
        lines.append(f"#   {key} = {value:.6g}  ({source})")
    return text.rstrip("\n") + "\n" + "\n".join(lines)


def main(argv=None):
    # a closed pipe (`dolfrag cases | head`) ends the process quietly, as for any command-line tool
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    parser = _parser()
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    if args.command == "run" and (args.case is None) == (args.resume is None):
        parser.error("run: give a CASE or --resume DIR (not both)")
    if args.command == "run" and args.resume and (args.set or args.out or args.overwrite):
        parser.error("run --resume DIR: the case and its folder are the checkpoint's (no --set, --out, --overwrite)")
    try:
        if args.command == "report" or (args.command == "run" and args.resume):
            folder = args.dir if args.command == "report" else args.resume
            _check_resumable(folder, remake=args.command == "report")
            quiet = args.command == "report" or args.quiet  # a remade report has no steps to show
            summary = run(None, folder, quiet=quiet, comm=comm, resume=True)
            return _report(summary, folder, comm, quiet and args.command == "run", args.debug)
        if args.command == "replay":
            if comm.rank == 0:
                print(star_replay.report(args.dump, args.max_iterations))
            return 0
        if args.command == "batch":
            return _batch(args, comm)
        if args.command == "cases":
            if comm.rank == 0:
                print(_case_text(args.name) if args.name else _case_list())
            return 0
        case = load_case(args.case, args.set)
        if args.command == "loads":
            _plot_load(case, args.out, comm)
            return 0
        out = args.out or f"results/{case.name}"
        guards.check(case, loads.applied(case.load, comm))  # refuse before emptying the folder
        outdir.prepare(out, args.overwrite, comm)
        summary = run(case, out, quiet=args.quiet, comm=comm)
        return _report(summary, out, comm, args.quiet, args.debug)
    except CaseError as err:
        if comm.rank == 0:
            print(f"dolfrag: error: {err}", file=sys.stderr)
        return 2
    except batch.SubmitError as err:
        print(f"dolfrag: error: {err}", file=sys.stderr)
        return 1
    except ConvergenceError as err:  # raised on every rank at once (its check is collective)
        if comm.rank == 0:
            print(f"dolfrag: error: the run stopped: {err}; summary.json has what it reached", file=sys.stderr)
        return 1
    except Exception:
        if comm.size == 1:
            raise
        # one rank failing alone would leave the others waiting in a collective forever
        traceback.print_exc()
        comm.Abort(1)
    return 0


def _batch(args, comm):
    """`dolfrag batch`: check, then print (--dry-run) or write the job script, and submit it."""
    text = batch.job_script(args.case, args.set, args.ranks, args.time, args.out, args.overwrite, args.partition)
    if args.dry_run:
        print(text, end="")
        return 0
    outdir.prepare(args.out, args.overwrite, comm)
    path = batch.write(args.out, text)
    print(path)
    if args.submit:
        job = batch.submit(path)
        print(f"submitted job {job}; its log: {Path(args.out) / f'slurm-{job}.log'}")
    return 0


def _check_resumable(folder, remake):
    """Refuse (CaseError) a `run --resume` of a completed run, and a `report` of a run whose
    time loop has not finished, as its summary.json tells."""
    path = Path(folder) / "summary.json"
    summary = json.loads(path.read_text()) if path.is_file() else {}
    finished = summary.get("steps") is not None and summary.get("steps_done") == summary["steps"]
    if remake and not finished:
        raise CaseError(f"report {folder}: its time loop has not finished ({path}: steps_done = "
                        f"{summary.get('steps_done')!r} of steps = {summary.get('steps')!r}); continue it with "
                        f"dolfrag run --resume {folder}")
    if not remake and summary.get("status") == "completed":
        raise CaseError(f"--resume {folder}: the run is already complete ({path}: status 'completed'); "
                        f"dolfrag report {folder} makes its reports again")


def _report(summary, folder, comm, quiet, debug):
    """One line on a finished, interrupted or report-failed run; the exit status (128 +
    signal when stopped, 1 when a report failed)."""
    if summary["status"] == "interrupted" and "missing_outputs" in summary:
        if comm.rank == 0:
            print(f"dolfrag: {summary['signal']}: stopped after the time loop, while making its outputs; not made: "
                  f"{', '.join(summary['missing_outputs'])}; make them with: {summary['resume']}", file=sys.stderr)
        return EXIT_CODES[signal.Signals[summary["signal"]]]
    if summary["status"] == "interrupted":
        if comm.rank == 0:
            print(f"dolfrag: {summary['signal']}: stopped at t = {summary['time_reached_s']:.6g} s (step "
                  f"{summary['steps_done']} of {summary['steps']}), checkpoint written; resume with: "
                  f"{summary['resume']}", file=sys.stderr)
        return EXIT_CODES[signal.Signals[summary["signal"]]]
    if summary["status"] == "report_failed":
        if comm.rank == 0:
            errors = Path(folder) / REPORT_ERRORS
            if debug:
                print(errors.read_text(), file=sys.stderr)
            print(f"dolfrag: error: the time loop completed but {len(summary['report_errors'])} report part(s) "
                  f"failed, first {summary['report_errors'][0]}; summary.json has the rest (status "
                  f"'report_failed'), {errors} the tracebacks; after a fix: dolfrag report {folder}", file=sys.stderr)
        return 1
    if comm.rank == 0 and not quiet:
        print(f"{summary['case']['name']}: {summary['steps']} steps, {summary['cells']} cells, "
              f"{summary['links']} links, {summary['wall_time_s']:.1f} s on {summary['ranks']} rank(s); "
              f"energy balance error {summary['balance_error_relative']:.1e} of the work")
    return 0


if __name__ == "__main__":
    sys.exit(main())
