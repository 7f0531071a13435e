"""Shared helpers: MPI subprocess runs and small meshes."""
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
MPI_RANKS = 2  # these machines have 2 cores


def mpirun(args, n=MPI_RANKS, timeout=300):
    """Run ``python args...`` under mpirun -n n; returns the CompletedProcess (checked)."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OPENBLAS_NUM_THREADS="1")
    cmd = ["mpirun", "-n", str(n)] + (["--oversubscribe"] if n > os.cpu_count() else []) \
        + [sys.executable, *map(str, args)]
    result = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout, cwd=ROOT)
    assert result.returncode == 0, f"{' '.join(cmd)} failed:\n{result.stdout}\n{result.stderr[-3000:]}"
    return result


def dolfrag_cli(*args, cwd=ROOT):
    """Run the `dolfrag` command serially; returns the CompletedProcess (not checked)."""
    return subprocess.run([sys.executable, "-m", "dolfrag.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))


def rectangle(length=0.12, width=0.04):
    return SimpleNamespace(kind="rectangle", tdim=2, length=length, width=width, structured=False)


def box(length=0.1, width=0.05, thickness=0.03):
    return SimpleNamespace(kind="box", tdim=3, length=length, width=width, thickness=thickness)


@pytest.fixture(scope="session")
def comm():
    return MPI.COMM_WORLD
