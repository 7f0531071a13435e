"""dolfrag: fragmentation of concrete under dynamic loads, with cohesive interfaces
on every facet of a DOLFINx mesh. SI units throughout (m, kg, s, Pa, J).

``dolfrag.run(case, out)`` is the one public entry point; the CLI, demos, tests and
benchmarks all go through it.
"""
try:
    # VTK must be loaded before DOLFINx: the other order aborts the process with
    # std::bad_alloc when a scalar bar is drawn (measured with DOLFINx 0.5.2 and VTK 9).
    import pyvista  # noqa: F401
except ImportError:
    pass

import os

# One OpenMP thread per process for MUMPS (the theta step's LU): set before petsc4py loads,
# which threadpoolctl cannot reach; two threads per rank on these 2-core machines made the
# factorisation 1.5x slower (measured).
os.environ.setdefault("OMP_NUM_THREADS", "1")

try:
    # One BLAS thread per process: MPI ranks already fill the cores, and threaded
    # OpenBLAS inverts the small star blocks 1,500x slower (20 s against 14 ms for
    # 1,500 12x12 blocks, measured on these 2-core machines).
    from threadpoolctl import threadpool_limits
    threadpool_limits(1)
except ImportError:
    pass

__version__ = "0.1.0"

# numba's cache of the compiled kernels in a directory per version of their sources: numba
# alone would keep a kernel's compiled callees from other modules after they change
from dolfrag.kernel_cache import use_versioned_cache  # noqa: E402

use_versioned_cache()


# the one entry point, bound after the package's settings above (the machinery of a run is
# the package dolfrag.runner)
from dolfrag.runner.driver import run  # noqa: E402,F401
