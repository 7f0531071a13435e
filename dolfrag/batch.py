"""`dolfrag batch`: a Slurm job script that runs a case to its end through as many wall-time
limits as it needs (docs/cluster.md).

The job asks Slurm for SIGTERM a lead time before its limit (``--signal=TERM@lead``, without
``B:``: the signal goes to the job step, whose tasks are the ranks, and not to the batch
shell, which stays alive to decide what comes next). The ranks stop together at the end of a
step or within a long one (runner/signals.py), checkpoint, write summary.json with status
"interrupted" and exit 143; the shell then requeues the job (``scontrol requeue``), and the
next start finds the checkpoint and runs ``run --resume``. A completed run (exit 0) ends the
job; so does a failure (exit 1) or bad input (exit 2), which a restart would only repeat, and
a stop that did not advance the run (summary.json's steps_done), which would requeue forever
a job whose limit is too short to mesh and take one step.

The run's folder is <out>/run; the script (<out>/job.sbatch) and the log of every start
(<out>/slurm-<job id>.log, appended) sit beside it, so that a first start that must empty its
folder (a start killed before its first checkpoint) never removes them.

The environment variable DOLFRAG_BATCH_COMMAND, read when the script is written, replaces the
command the script runs (by default this Python with ``-m dolfrag.cli``): the tests run
``python tests/slow_step.py imex 0.75`` in its place, each step slowed by 0.75 s.
"""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

from dolfrag import guards, loads, outdir
from dolfrag.case import CaseError, load_case

COMMAND_VARIABLE = "DOLFRAG_BATCH_COMMAND"
SCRIPT = "job.sbatch"
RUN_FOLDER = "run"
# SIGTERM this long before the limit: 10 % of it, at most 5 minutes. A stop costs one
# abandoned step and a checkpoint (1.1 s measured for a 228 MB checkpoint, docs/usage.md §3);
# a few minutes leave room for a checkpoint of gigabytes on a slow parallel file system, and
# a short job still computes for 90 % of its limit.
LEAD_SHARE = 0.1
LEAD_MAX_S = 300
TIME = re.compile(r"^(\d+):([0-5]\d):([0-5]\d)$")
PARTITION = re.compile(r"^[\w.-]+(,[\w.-]+)*$")  # a name, or several separated by commas


def limit_seconds(text):
    """The wall-time limit ``HH:MM:SS`` in s; CaseError (one line) if malformed or under a
    minute (Slurm counts whole minutes)."""
    match = TIME.match(text)
    if not match:
        raise CaseError(f"--time = {text!r}: must be HH:MM:SS (minutes and seconds 00-59), e.g. 02:00:00")
    hours, minutes, seconds = map(int, match.groups())
    limit = 3600 * hours + 60 * minutes + seconds
    if limit < 60:
        raise CaseError(f"--time = {text!r}: must be at least 00:01:00 (Slurm's limits are whole minutes)")
    return limit


def signal_lead(limit):
    """s before a limit of ``limit`` s at which the job asks for SIGTERM (LEAD_SHARE, LEAD_MAX_S)."""
    return max(1, min(LEAD_MAX_S, int(LEAD_SHARE * limit)))


def check_ranks(ranks):
    """CaseError (one line) if ``ranks`` < 1."""
    if ranks < 1:
        raise CaseError(f"--ranks = {ranks}: must be a whole number >= 1 (MPI ranks, one per core)")


def check_partition(partition):
    """CaseError (one line) if ``partition`` (or None: the cluster's default) is not a Slurm
    partition name or a comma-separated list of them (it goes into an #SBATCH line as it is)."""
    if partition is not None and not PARTITION.match(partition):
        raise CaseError(f"--partition = {partition!r}: must be a partition name (letters, digits, '_', '.', '-'), "
                        "or several separated by commas")


def command():
    """The words that start dolfrag in the job: DOLFRAG_BATCH_COMMAND's if set, else this
    Python's ``-m dolfrag.cli``."""
    return shlex.split(os.environ[COMMAND_VARIABLE]) if os.environ.get(COMMAND_VARIABLE) \
        else [sys.executable, "-m", "dolfrag.cli"]


def script(case, overrides, ranks, time, out, words, workdir, partition=None, name="dolfrag"):
    """The text of the job script: ``case`` (a built-in name or a path, as given, resolved
    from ``workdir``) with ``overrides`` on ``ranks`` ranks, limit ``time`` (HH:MM:SS), run
    folder <out>/run; ``words`` start dolfrag (command())."""
    out = Path(out).absolute()
    lead = signal_lead(limit_seconds(time))
    dolfrag = " ".join(map(shlex.quote, words))
    # a folder without a checkpoint holds nothing worth keeping: --overwrite
    first = " ".join(shlex.quote(word) for word in [case, *(w for item in overrides for w in ("--set", item))])
    partition_line = f"#SBATCH --partition={partition}\n" if partition else ""
    return f"""#!/bin/bash
# {name} on {ranks} ranks, in steps of at most {time}: SIGTERM {lead} s before each limit
# stops the run with a checkpoint and the job requeues itself; the next start resumes it
# (dolfrag batch, docs/cluster.md).
#SBATCH --job-name={name}
#SBATCH --ntasks={ranks}
#SBATCH --time={time}
#SBATCH --signal=TERM@{lead}
#SBATCH --requeue
#SBATCH --open-mode=append
#SBATCH --output={out}/slurm-%j.log
#SBATCH --chdir={Path(workdir).absolute()}
{partition_line}
RUN={shlex.quote(str(out / RUN_FOLDER))}
DOLFRAG=({dolfrag})
steps_done() {{  # the run's steps_done in summary.json, -1 before it has one
    grep -o '"steps_done": [0-9]*' "$RUN/summary.json" 2>/dev/null | grep -o '[0-9]*$' || echo -1
}}
echo "dolfrag batch: start $((${{SLURM_RESTART_COUNT:-0}} + 1)) of job $SLURM_JOB_ID, $(date -Is)"
before=$(steps_done)
# a checkpoint is each rank's: every start keeps --ntasks={ranks}
if [ -d "$RUN/checkpoint" ]; then
    srun "${{DOLFRAG[@]}}" run --resume "$RUN"
else
    srun "${{DOLFRAG[@]}}" run {first} --out "$RUN" --overwrite
fi
status=$?
# 143 (SIGTERM) or 130 (SIGINT) with an "interrupted" summary: stopped with a checkpoint, so
# back to the queue if this start advanced the run; a completed run (0), a failure (1) or bad
# input (2) ends the job
if {{ [ $status = 143 ] || [ $status = 130 ]; }} && grep -q '"status": "interrupted"' "$RUN/summary.json" 2>/dev/null; then
    if [ "$(steps_done)" -gt "$before" ]; then
        echo "dolfrag batch: stopped with a checkpoint at step $(steps_done) (exit $status), $(date -Is): requeued"
        scontrol requeue "$SLURM_JOB_ID"
        exit $status
    fi
    echo "dolfrag batch: stopped at step $before, where this start began: not requeued; sbatch --time=<longer> resumes it"
fi
echo "dolfrag batch: ended with exit status $status, $(date -Is)"
exit $status
"""


def job_script(case, overrides, ranks, time, out, overwrite=False, partition=None):
    """Check every input as `run` would (CaseError, one line: the option or key, the value,
    what is allowed), then return the job script's text. Reads the case; writes nothing."""
    check_ranks(ranks)
    limit_seconds(time)
    check_partition(partition)
    loaded = load_case(case, overrides)
    guards.check(loaded, loads.applied(loaded.load))
    outdir.check(out, overwrite)
    return script(case, overrides, ranks, time, out, command(), Path.cwd(), partition, f"dolfrag-{loaded.name}")


class SubmitError(RuntimeError):
    """sbatch is missing or refused the script."""


def write(out, text):
    """Write the job script into the folder ``out`` (created); its path."""
    path = Path(out) / SCRIPT
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def submit(path):
    """sbatch ``path``; the job id. SubmitError (sbatch's own message, one line) if it is refused."""
    try:
        result = subprocess.run(["sbatch", "--parsable", str(path)], capture_output=True, text=True)
    except FileNotFoundError:
        raise SubmitError("sbatch: not found; is Slurm installed here (docs/cluster.md)?") from None
    if result.returncode != 0:
        raise SubmitError(" ".join(result.stderr.split()) or f"sbatch exited with {result.returncode}")
    return result.stdout.strip().split(";")[0]  # --parsable: "id" or "id;cluster"
