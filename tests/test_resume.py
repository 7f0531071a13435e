"""Checkpoint, stop and resume (dolfrag/runner/checkpoint.py, signals.py): a run stopped by
SIGTERM at a known step and resumed ends as the uninterrupted run, on 1 and 2 ranks, with
each step once in history.csv and each snapshot once in fields.pvd; a theta or imex step too
slow to finish before the launcher's kill is abandoned, and the last completed step
checkpointed."""
import csv
import json
import os
import pickle
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import ROOT

# a cracking bar: 101 imex steps, 8 links broken at step 90, 63 at step 95, 79 and 7
# fragments at 80 us
RUN = ["shpb-be12", "--quiet", "--set", "time.end=80e-6", "--set", "output.every=1", "--set", "output.fields=4",
       "--set", "output.figures=false", "--set", "output.fragments_at=[40e-6,75e-6]"]
STOP_AT = 92  # the step after which SIGTERM arrives: while the bar cracks


def dolfrag(args, ranks, stop_at=None):
    """``dolfrag args`` on ``ranks`` ranks (mpirun), SIGTERM sent by rank 0 to itself after step
    ``stop_at``; the CompletedProcess (not checked)."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OPENBLAS_NUM_THREADS="1")
    env.pop("DOLFRAG_SIGNAL_AT_STEP", None)
    if stop_at is not None:
        env["DOLFRAG_SIGNAL_AT_STEP"] = str(stop_at)
    return subprocess.run(["mpirun", "-n", str(ranks), sys.executable, "-m", "dolfrag.cli", *map(str, args)],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)


def compared(summary):
    """The numbers a resumed run must reproduce."""
    return {"energies_J": summary["energies_J"], "broken_links": summary["broken_links"],
            "fragments": summary["fragments"]["count"], "masses": sorted(summary["fragments"]["mass"]),
            "shpb": summary["shpb"]["blocks"], "steps_done": summary["steps_done"],
            "fragments_at": [(f["time_s"], f["count"], sorted(f["mass"])) for f in summary["fragments_at"]]}


def assert_same_run(got, expected, ranks):
    """Bit for bit on 1 rank. On 2, DOLFINx's graph partitioner may split the mesh otherwise in
    the uninterrupted run than in the stopped one (the resumed run keeps the stopped one's
    partition): the runs then differ as 1 and 2 ranks do, by the star solves' tolerance
    (tests/test_nonsmooth.py: 1e-6 of the work for energies, 1e-8 for fragment masses)."""
    if ranks == 1:
        assert compared(got) == compared(expected)
        return
    assert got["broken_links"] == expected["broken_links"] and got["steps_done"] == expected["steps_done"]
    assert got["fragments"]["count"] == expected["fragments"]["count"]
    assert [f["count"] for f in got["fragments_at"]] == [f["count"] for f in expected["fragments_at"]]
    work = expected["energies_J"]["W_external_J"]
    for name, value in expected["energies_J"].items():
        assert abs(got["energies_J"][name] - value) <= 1e-6 * work, name
    assert np.allclose(sorted(got["fragments"]["mass"]), sorted(expected["fragments"]["mass"]), rtol=1e-8)


@pytest.mark.mpi
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_run_stopped_by_sigterm_and_resumed_ends_as_the_uninterrupted_run(tmp_path, ranks):
    whole = dolfrag(["run", *RUN, "--out", tmp_path / "whole"], ranks)
    assert whole.returncode == 0, whole.stderr
    out = tmp_path / "stopped"
    stopped = dolfrag(["run", *RUN, "--out", out], ranks, stop_at=STOP_AT)
    assert stopped.returncode == 143, stopped.stderr  # 128 + SIGTERM
    # dolfrag's own line; mpirun then adds its banner on a non-zero exit (lines of dashes)
    lines = stopped.stderr.split("-" * 20)[0].strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stopped.stderr and "SIGTERM" in lines[0], stopped.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps_done"] == STOP_AT
    assert summary["resume"].endswith(f"dolfrag run --resume {out}") and summary["time_reached_s"] > 0
    assert (ranks > 1) == summary["resume"].startswith(f"mpirun -n {ranks} ")
    assert f"--resume {out}" in lines[0]
    resumed = dolfrag(["run", "--resume", out, "--quiet"], ranks)
    assert resumed.returncode == 0, resumed.stderr
    expected = json.loads((tmp_path / "whole" / "summary.json").read_text())
    got = json.loads((out / "summary.json").read_text())
    # imex is deterministic: the resumed run repeats the same operations on the same bits,
    # cracking on both sides of the stop
    assert expected["broken_links"] > 10 and 0 < summary["broken_links"] < expected["broken_links"]
    assert_same_run(got, expected, ranks)
    assert got["status"] == "completed" and got["resumed_from_step"] == STOP_AT
    with open(out / "history.csv") as f:
        steps = [int(row["step"]) for row in csv.DictReader(f)]
    assert steps == list(range(1, expected["steps"] + 1))
    if ranks == 1:
        with open(tmp_path / "whole" / "history.csv") as f, open(out / "history.csv") as g:
            assert f.read() == g.read()
    times = [float(t) for t in re.findall(r'timestep="([^"]+)"', (out / "fields.pvd").read_text())]
    whole_times = [float(t) for t in re.findall(r'timestep="([^"]+)"',
                                                (tmp_path / "whole" / "fields.pvd").read_text())]
    assert times == whole_times and len(times) == 5


# the integrator's parts and the outputs, keyed by name in every checkpoint; the observers
# were keyed by their position among them until they were named
FIXED_KEYS = ("integrator", "model", "interface", "rebars", "star_layout", "viscosity", "fields_file")


def positional(folder):
    """Rewrite the checkpoint in ``folder`` as one written before the observers were named:
    each observer's state under its class name followed by its position ("History0")."""
    for path in (folder / "checkpoint").glob("rank*.pkl"):
        data = pickle.loads(path.read_bytes())
        observers = [key for key in data["objects"] if key not in FIXED_KEYS]
        data["objects"] = {**{key: data["objects"][key] for key in FIXED_KEYS},
                           **{f"{key}{i}": data["objects"][key] for i, key in enumerate(observers)}}
        path.write_bytes(pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL))
    return observers


@pytest.mark.mpi
def test_a_checkpoint_with_the_observers_by_position_resumes_as_one_with_their_names(tmp_path):
    named = tmp_path / "named"
    assert dolfrag(["run", *RUN, "--out", named], 1, stop_at=STOP_AT).returncode == 143
    old = tmp_path / "positional"
    shutil.copytree(named, old)
    assert positional(old) == ["History", "Probes", "BreakTimes", "FieldSnapshots", "RequestedFragments",
                               "BarReport"]
    for out in (named, old):
        resumed = dolfrag(["run", "--resume", out, "--quiet"], 1)
        assert resumed.returncode == 0, resumed.stderr
    got, expected = (json.loads((out / "summary.json").read_text()) for out in (old, named))
    assert compared(got) == compared(expected) and got["resumed_from_step"] == STOP_AT
    assert (old / "history.csv").read_text() == (named / "history.csv").read_text()


@pytest.mark.slow
def test_a_killed_run_resumes_from_its_last_periodic_checkpoint_without_repeating_a_step(tmp_path):
    whole = dolfrag(["run", *RUN, "--out", tmp_path / "whole"], 1)
    assert whole.returncode == 0, whole.stderr
    out = tmp_path / "killed"
    # a checkpoint after every step; SIGKILL after step 24, before its checkpoint: step 24's
    # history row and field snapshot (fields at steps 0, 12, 24, 36, 48) are written, the
    # checkpoint is of step 23
    every_step = ["--set", "output.checkpoint_every=1e-9"]
    killed = dolfrag(["run", *RUN, *every_step, "--out", out], 1, stop_at="24:SIGKILL")
    assert killed.returncode != 0 and not (out / "summary.json").exists()
    with open(out / "history.csv") as f:
        assert [int(row["step"]) for row in csv.DictReader(f)][-1] == 24
    assert dolfrag(["run", "--resume", out, "--quiet"], 1).returncode == 0
    expected = json.loads((tmp_path / "whole" / "summary.json").read_text())
    got = json.loads((out / "summary.json").read_text())
    assert compared(got) == compared(expected) and got["resumed_from_step"] == 23
    with open(tmp_path / "whole" / "history.csv") as f, open(out / "history.csv") as g:
        assert f.read() == g.read()
    times = re.findall(r'timestep="([^"]+)"', (out / "fields.pvd").read_text())
    assert times == re.findall(r'timestep="([^"]+)"', (tmp_path / "whole" / "fields.pvd").read_text())
    pieces = re.findall(r'file="([^"]+)"', (out / "fields.pvd").read_text())
    assert len(set(pieces)) == len(times) == 5 and all((out / p).exists() for p in pieces)


@pytest.mark.slow
def test_resume_on_another_rank_count_is_refused_in_one_line(tmp_path):
    out = tmp_path / "run"
    assert dolfrag(["run", *RUN, "--out", out], 1, stop_at=5).returncode == 143
    result = dolfrag(["run", "--resume", out], 2)
    assert result.returncode != 0
    assert "written on 1 rank(s); resume it with mpirun -n 1" in result.stderr and "Traceback" not in result.stderr


def test_cases_into_a_closed_pipe_prints_no_traceback():
    # `true` reads nothing: the pipe is closed before the list is written
    result = subprocess.run(f"{sys.executable} -m dolfrag.cli cases | true", shell=True, capture_output=True,
                            text=True, cwd=ROOT)
    assert result.stderr == ""


# theta on a cracking bar: 50 steps, 42 broken links, contact
THETA = ["tests/cases/rccm-bar.toml", "--quiet", "--set", "time.scheme=theta", "--set", "time.dt=1.5e-6",
         "--set", "time.end=75e-6", "--set", "mesh.size=0.008", "--set", "output.every=1", "--set", "output.fields=3"]


@pytest.mark.mpi
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_stopped_theta_run_resumes_to_the_same_result_within_newton_tolerance(tmp_path, ranks):
    assert dolfrag(["run", *THETA, "--out", tmp_path / "whole"], ranks).returncode == 0
    out = tmp_path / "stopped"
    assert dolfrag(["run", *THETA, "--out", out], ranks, stop_at=25).returncode == 143
    resumed = dolfrag(["run", "--resume", out, "--quiet"], ranks)
    assert resumed.returncode == 0, resumed.stderr
    expected = json.loads((tmp_path / "whole" / "summary.json").read_text())
    got = json.loads((out / "summary.json").read_text())
    assert got["broken_links"] == expected["broken_links"] > 10
    assert got["fragments"]["count"] == expected["fragments"]["count"]
    work = expected["energies_J"]["W_external_J"]
    for name, value in expected["energies_J"].items():
        # the resumed run factorises its matrix anew where the uninterrupted one may reuse
        # the last factorisation: the Newton iterates differ, both stop at 1e-10 of the
        # momentum scale (the tolerance of tests/test_theta.py's 1 against 2 ranks): 1e-8
        # of the work covers it
        assert abs(got["energies_J"][name] - value) <= 1e-8 * work, name
    with open(out / "history.csv") as f:
        steps = [int(row["step"]) for row in csv.DictReader(f)]
    assert steps == list(range(1, expected["steps"] + 1))


# Open MPI's mpirun, sent SIGTERM, passes it to the ranks after odls_base_sigkill_timeout
# seconds and kills them as many seconds later (default 1: about 1.3 s to stop; measured with
# Open MPI 4.1.4); docs/usage.md says how to lengthen it. KILL_WAIT s leaves a stop that takes
# at most one Newton iteration of the slowed theta step (4-6 s) room to finish.
KILL_WAIT = 10
# imex on the same bar, the star loop of every step slowed (tests/slow_step.py)
IMEX = ["tests/cases/rccm-bar.toml", "--quiet", "--set", "time.end=80e-6",  # 85 steps, 50 broken links
        "--set", "mesh.size=0.008", "--set", "output.every=1", "--set", "output.fields=3"]
# scheme: (arguments, s the step is slowed by, s into step 2 the signal is sent to mpirun,
# which passes it on KILL_WAIT s later)
SLOWED = {
    "theta": (THETA, 2.0, 6.0),  # 2 s per residual evaluation: steps of 10-20 s
    "imex": (IMEX, 15.0, 1.0),  # the ranks get it 11 s into the 15 s of step 2
}
# s from the ranks' SIGTERM to their exit: theta finishes the Newton iteration in progress
# (one slowed evaluation or three); the star loop gives up within one of its polls (10 ms),
# the main thread takes the signal within solver/interrupt.SLICE, and the rest is the
# checkpoint of a small bar
STOP_TAKES = {"theta": KILL_WAIT, "imex": 3.0}


@pytest.mark.mpi
@pytest.mark.parametrize("scheme", SLOWED)
def test_a_stop_within_a_slow_step_checkpoints_the_last_completed_step_and_resumes(tmp_path, scheme):
    args, slow, into = SLOWED[scheme]
    assert dolfrag(["run", *args, "--out", tmp_path / "whole"], 2).returncode == 0
    out = tmp_path / "stopped"
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OPENBLAS_NUM_THREADS="1")
    command = ["mpirun", "--mca", "odls_base_sigkill_timeout", str(KILL_WAIT), "-n", "2", sys.executable,
               "tests/slow_step.py", scheme, str(slow), "run", *args, "--out", str(out)]
    slowed = subprocess.Popen(command, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    history = out / "history.csv"
    while not (history.is_file() and len(history.read_text().splitlines()) >= 2):  # step 1 is done
        assert slowed.poll() is None, slowed.communicate()
        time.sleep(0.2)
    time.sleep(into)  # within step 2
    slowed.send_signal(signal.SIGTERM)
    sent = time.time()
    _, err = slowed.communicate(timeout=4 * KILL_WAIT)
    took = time.time() - sent
    summary = json.loads((out / "summary.json").read_text())  # written before the launcher's kill
    assert summary["status"] == "interrupted" and summary["signal"] == "SIGTERM", err
    # the ranks get the signal KILL_WAIT s after mpirun, and wrote their summary soon after;
    # mpirun itself returns some seconds later (8 s measured, with or without a slow step)
    written = (out / "summary.json").stat().st_mtime - sent
    assert written < KILL_WAIT + STOP_TAKES[scheme] and took < 2 * KILL_WAIT, (written, took)
    # back to the end of step 1 up to the round-off of one addition
    assert summary["steps_done"] == 1 and summary["time_reached_s"] == pytest.approx(summary["dt_s"], rel=1e-12)
    assert "resume with" in err
    resumed = dolfrag(["run", "--resume", out, "--quiet"], 2)
    assert resumed.returncode == 0, resumed.stderr
    expected = json.loads((tmp_path / "whole" / "summary.json").read_text())
    got = json.loads((out / "summary.json").read_text())
    assert got["broken_links"] == expected["broken_links"] > 10 and got["resumed_from_step"] == 1
    work = expected["energies_J"]["W_external_J"]
    for name, value in expected["energies_J"].items():
        assert abs(got["energies_J"][name] - value) <= 1e-8 * work, name  # as the theta resume above
