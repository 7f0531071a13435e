"""`dolfrag batch` (dolfrag/batch.py): the job script it writes, its refusals of bad input, and
the job itself on a one-node Slurm started on this machine (tests/slurm/local-slurm.sh): a
2-rank run that outlasts its 1-minute limit is stopped by the early SIGTERM, requeued and
resumed until it ends as the uninterrupted run; a run that fails on bad input is not requeued,
nor is a start that made no step.

The scheduler tests fail (not skip) with the daemons' error when Slurm cannot start here.
"""
import csv
import json
import os
import re
import subprocess
import sys
import time

import pytest

from conftest import ROOT, dolfrag_cli
from dolfrag import batch

START = ROOT / "tests" / "slurm" / "local-slurm.sh"
SLURM_CONF = os.path.join(os.environ.get("DOLFRAG_SLURM_DIR", "/var/spool/dolfrag-slurm"), "slurm.conf")  # local-slurm.sh's
# imex on a cracking bar: 85 steps, 50 broken links (tests/test_resume.py, IMEX)
CASE = ["tests/cases/rccm-bar.toml", "--set", "time.end=80e-6", "--set", "mesh.size=0.008",
        "--set", "output.every=1", "--set", "output.fields=3"]
# each step of the first start slowed by 0.75 s (tests/slow_step.py): 64 s of steps, more than
# the 60 s limit, so that the first start is always stopped; the ranks mostly sleep, leaving the
# cores to others. The resumed start runs unslowed, in seconds: when it, too, was slowed, it
# needed ~55 of its 60 s under the suite's load, and once finished its last step so close to
# the limit that Slurm cancelled it while it exited (FAILED instead of COMPLETED).
SLOW_STEP_S = 0.75
FINAL = {"COMPLETED", "FAILED", "TIMEOUT", "CANCELLED", "NODE_FAIL", "OUT_OF_MEMORY", "BOOT_FAIL", "DEADLINE"}


def test_the_signal_lead_is_a_tenth_of_the_limit_and_at_most_five_minutes():
    assert batch.signal_lead(batch.limit_seconds("00:01:00")) == 6
    assert batch.signal_lead(batch.limit_seconds("00:30:00")) == 180
    assert batch.signal_lead(batch.limit_seconds("48:00:00")) == 300


def test_dry_run_prints_a_requeueable_script_and_writes_nothing(tmp_path):
    out = tmp_path / "job"
    result = dolfrag_cli("batch", *CASE, "--ranks", "4", "--time", "02:00:00", "--out", out, "--partition", "big",
                         "--dry-run")
    assert result.returncode == 0, result.stderr
    lines = [line.strip() for line in result.stdout.splitlines()]
    for line in ("#SBATCH --ntasks=4", "#SBATCH --time=02:00:00", "#SBATCH --signal=TERM@300", "#SBATCH --requeue",
                 "#SBATCH --open-mode=append", "#SBATCH --partition=big", f"RUN={out}/run",
                 'srun "${DOLFRAG[@]}" run --resume "$RUN"', 'scontrol requeue "$SLURM_JOB_ID"'):
        assert line in lines, line
    first = next(line for line in lines if "--overwrite" in line)
    assert "run tests/cases/rccm-bar.toml --set time.end=80e-6" in first and "--set output.fields=3" in first
    assert not out.exists()


def test_the_fine_bunker_script_in_docs_cluster_md_is_what_batch_prints():
    printed = dolfrag_cli("batch", "bunker-h2", "--set", "mesh.size=0.028", "--ranks", "128", "--time", "01:00:00",
                          "--out", "results/bunker-fine", "--dry-run")
    assert printed.returncode == 0, printed.stderr
    shown = re.search(r"```sh\n(#!/bin/bash\n.*?)```", (ROOT / "docs" / "cluster.md").read_text(), re.S).group(1)

    def same_places(text):  # the page's repository is /home/me/dolfrag, its Python that of .venv
        return re.sub(r"^DOLFRAG=\(\S+", "DOLFRAG=(PYTHON", text.replace(str(ROOT), "/home/me/dolfrag"), flags=re.M)

    assert same_places(printed.stdout) == same_places(shown)


@pytest.mark.parametrize("option, value, says", [
    ("--time", "1:00:00:00", "--time = '1:00:00:00': must be HH:MM:SS"),
    ("--time", "00:00:40", "must be at least 00:01:00"),
    ("--ranks", "0", "--ranks = 0: must be a whole number >= 1"),
    ("--partition", "big queue", "--partition = 'big queue': must be a partition name"),
    ("--set", "mesh.size=-1", "mesh.size = -1: must be a number > 0"),
])
def test_bad_batch_input_exits_2_in_one_line_and_writes_nothing(tmp_path, option, value, says):
    args = {"--time": "00:10:00", "--ranks": "2"}
    args[option] = value
    result = dolfrag_cli("batch", "sound-bar", "--out", tmp_path / "job", *(w for kv in args.items() for w in kv))
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1 and lines[0].startswith("dolfrag: error: "), result.stderr
    assert says in lines[0] and not (tmp_path / "job").exists()


def test_an_unknown_case_is_refused_before_anything_is_queued(tmp_path):
    result = dolfrag_cli("batch", "no-such-case", "--ranks", "2", "--time", "00:10:00", "--out", tmp_path / "job",
                         "--submit")
    assert result.returncode == 2 and "case 'no-such-case': no such file or built-in case" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "job").exists()


# ---- on a real scheduler -------------------------------------------------------------------

@pytest.fixture(scope="module")
def slurm():
    """The environment of commands that talk to the local Slurm, started if it is not up."""
    try:
        started = subprocess.run([str(START), "start"], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired as err:
        pytest.fail(f"{START} start: no answer in 120 s: {err.stdout}{err.stderr}")
    assert started.returncode == 0, f"the local Slurm did not start ({START} start):\n{started.stdout}{started.stderr}"
    env = dict(os.environ, SLURM_CONF=SLURM_CONF)
    cpus = subprocess.run(["sinfo", "-h", "-o", "%c"], capture_output=True, text=True, env=env).stdout.strip()
    assert cpus.isdigit() and int(cpus) >= 2, f"the local Slurm's node has CPUs={cpus!r}: the 2-rank jobs would pend"
    return dict(os.environ, SLURM_CONF=SLURM_CONF, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1",
                OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def job_fields(job, env):
    """`scontrol show job` of ``job`` as {field: value}."""
    shown = subprocess.run(["scontrol", "show", "job", "-o", job], capture_output=True, text=True, env=env)
    assert shown.returncode == 0, shown.stderr
    return dict(re.findall(r"(\w+)=(\S*)", shown.stdout))


def wait_for(job, env, log, timeout):
    """{field: value} of ``job`` once it has ended; cancels it and fails after ``timeout`` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        fields = job_fields(job, env)
        if fields["JobState"] in FINAL:
            return fields
        time.sleep(2)
    subprocess.run(["scancel", job], env=env)
    pytest.fail(f"job {job} still {fields['JobState']} (Reason={fields.get('Reason')}) after {timeout} s; its log:\n"
                f"{log.read_text() if log.exists() else '(none)'}")


def submit(args, env, cwd=ROOT):
    """`dolfrag batch args --submit` (the first start's steps slowed, tests/slow_step.py); the job id."""
    slowed = dict(env, **{batch.COMMAND_VARIABLE: f"{sys.executable} tests/slow_step.py imex-first {SLOW_STEP_S}"})
    result = subprocess.run([sys.executable, "-m", "dolfrag.cli", "batch", *map(str, args), "--submit"],
                            capture_output=True, text=True, env=slowed, cwd=cwd)
    assert result.returncode == 0, result.stderr
    return re.search(r"submitted job (\d+)", result.stdout).group(1)


@pytest.mark.mpi
def test_a_job_past_its_time_limit_is_requeued_and_resumes_to_the_uninterrupted_run(tmp_path, slurm):
    out = tmp_path / "job"
    started = time.monotonic()
    job = submit([*CASE, "--ranks", 2, "--time", "00:01:00", "--out", out], slurm)
    # the reference, while the job's ranks sleep through their slowed steps (5 s of compute)
    whole = subprocess.run(["mpirun", "-n", "2", sys.executable, "-m", "dolfrag.cli", "run", *CASE, "--quiet",
                            "--out", str(tmp_path / "whole")], capture_output=True, text=True, env=slurm, cwd=ROOT)
    assert whole.returncode == 0, whole.stderr
    log = out / f"slurm-{job}.log"
    # a stopped start of 60 s, a requeue held cred_expire = 10 s (local-slurm.sh), a fast start
    fields = wait_for(job, slurm, log, timeout=240)
    text = log.read_text()
    print(f"job {job}: {fields['JobState']} after {time.monotonic() - started:.0f} s, "
          f"{fields['Restarts']} requeue(s)\n{text}")
    assert fields["JobState"] == "COMPLETED" and fields["ExitCode"] == "0:0", text
    requeues = int(fields["Restarts"])
    assert requeues == 1 and text.count(": requeued") == requeues, text
    assert text.count("dolfrag batch: start") == requeues + 1 and text.count("SIGTERM: stopped") == requeues
    got = json.loads((out / "run" / "summary.json").read_text())
    expected = json.loads((tmp_path / "whole" / "summary.json").read_text())
    assert got["status"] == "completed" and got["resumed_from_step"] > 0
    # the 2-rank tolerance of tests/test_resume.py (assert_same_run): the uninterrupted run may
    # be partitioned otherwise than the stopped one (which the resumed ones keep), so the two
    # differ as 1 and 2 ranks do, by the star solves' tolerance: 1e-6 of the work for energies
    assert got["broken_links"] == expected["broken_links"] > 10 and got["steps_done"] == expected["steps"]
    assert got["fragments"]["count"] == expected["fragments"]["count"]
    work = expected["energies_J"]["W_external_J"]
    for name, value in expected["energies_J"].items():
        assert abs(got["energies_J"][name] - value) <= 1e-6 * work, name
    with open(out / "run" / "history.csv") as f:
        steps = [int(row["step"]) for row in csv.DictReader(f)]
    assert steps == list(range(1, expected["steps"] + 1))  # each step once: no repeat, no gap
    times = re.findall(r'timestep="([^"]+)"', (out / "run" / "fields.pvd").read_text())
    assert times == re.findall(r'timestep="([^"]+)"', (tmp_path / "whole" / "fields.pvd").read_text())


@pytest.mark.mpi
def test_a_job_whose_run_fails_on_bad_input_ends_without_requeue(tmp_path, slurm):
    case = tmp_path / "bar.toml"
    case.write_text((ROOT / CASE[0]).read_text())
    out = tmp_path / "job"
    written = subprocess.run([sys.executable, "-m", "dolfrag.cli", "batch", case, *CASE[1:], "--ranks", "2",
                              "--time", "00:01:00", "--out", out], capture_output=True, text=True, env=slurm, cwd=ROOT)
    assert written.returncode == 0, written.stderr
    case.unlink()  # the case is gone when the job starts: the run exits 2
    submitted = subprocess.run(["sbatch", "--parsable", out / batch.SCRIPT], capture_output=True, text=True, env=slurm)
    assert submitted.returncode == 0, submitted.stderr
    job = submitted.stdout.strip()
    fields = wait_for(job, slurm, out / f"slurm-{job}.log", timeout=120)
    text = (out / f"slurm-{job}.log").read_text()
    assert fields["JobState"] == "FAILED" and fields["ExitCode"] == "2:0" and fields["Restarts"] == "0", text
    assert "no such file or built-in case" in text and ": requeued" not in text
    assert "ended with exit status 2" in text


@pytest.mark.mpi
def test_a_start_that_makes_no_step_ends_the_job_instead_of_requeuing_it_forever(tmp_path, slurm):
    out = tmp_path / "job"
    # a start that spends its whole limit before the time loop (meshing, say) and is killed
    # by the signal there: the run's summary stays the earlier stop's
    meshing = dict(slurm, **{batch.COMMAND_VARIABLE: "bash -c 'sleep 100' meshing"})
    written = subprocess.run([sys.executable, "-m", "dolfrag.cli", "batch", *CASE, "--ranks", "2", "--time",
                              "00:01:00", "--out", out], capture_output=True, text=True, env=meshing, cwd=ROOT)
    assert written.returncode == 0, written.stderr
    (out / "run" / "checkpoint").mkdir(parents=True)
    (out / "run" / "summary.json").write_text(json.dumps({"status": "interrupted", "steps_done": 5}, indent=2))
    submitted = subprocess.run(["sbatch", "--parsable", out / batch.SCRIPT], capture_output=True, text=True, env=slurm)
    assert submitted.returncode == 0, submitted.stderr
    job = submitted.stdout.strip()
    log = out / f"slurm-{job}.log"
    fields = wait_for(job, slurm, log, timeout=120)
    text = log.read_text()
    # srun returns 143 for tasks killed by SIGTERM, as for a clean stop
    assert fields["JobState"] == "FAILED" and fields["ExitCode"] == "143:0" and fields["Restarts"] == "0", text
    assert "stopped at step 5, where this start began: not requeued" in text and ": requeued" not in text
