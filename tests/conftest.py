"""Shared helpers: MPI subprocess runs and small meshes."""
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

# OpenBLAS and numpy's own loops (np.exp, np.log, ...) pick their kernels by the CPU they run
# on, and an AVX-512 machine rounds and sums in another order than an AVX2 one. Measured: the
# pinned numbers of tests/test_same_results.py moved by 1e-9 to 2e-7 of their scale between two
# such machines, and came back to the digit with OpenBLAS's AVX2 ("Haswell") kernels and numpy's
# AVX-512 loops switched off, which every x86-64 CPU since 2013 runs the same. Set before numpy
# loads; workers and mpirun's ranks inherit them. numpy ignores a feature the CPU lacks.
os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", "AVX512F AVX512CD AVX512_KNL AVX512_KNM "
                      "AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL")

ROOT = Path(__file__).resolve().parents[1]
MPI_RANKS = 2  # these machines have 2 cores
# The files that take minutes (serially: 100-580 s each), run first: pytest-xdist (`make test`)
# hands each file to the next free worker in collection order, and one started last leaves the
# other core idle while it ends.
LONG_FIRST = ["test_law_matrix.py", "test_resume.py", "test_batch.py", "test_same_results.py"]


def pytest_collection_modifyitems(items):
    items.sort(key=lambda item: LONG_FIRST.index(item.path.name) if item.path.name in LONG_FIRST
               else len(LONG_FIRST))


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


def copied_cache(cache):
    """A copy of a star cache given as a list of its records.Cache fields (its blocks a
    record of arrays), to solve from again."""
    return [c._make(a.copy() for a in c) if isinstance(c, tuple) else c.copy() for c in cache]


def rectangle(length=0.12, width=0.04):
    return SimpleNamespace(kind="rectangle", tdim=2, length=length, width=width, structured=False)


def box(length=0.1, width=0.05, thickness=0.03):
    return SimpleNamespace(kind="box", tdim=3, length=length, width=width, thickness=thickness)


@pytest.fixture(scope="session")
def comm():
    # Imported here, not at the top: under pytest-xdist (`make test`) this file is also read
    # by the process that starts the workers, and an MPI started there (a singleton) leaves
    # its launcher's variables (PMIX_*, OMPI_MCA_ess...) in the environment the workers
    # inherit; each worker's mpirun then fails at once, with no message.
    from mpi4py import MPI
    return MPI.COMM_WORLD
