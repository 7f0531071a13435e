# Two commands do everything on a fresh Debian 12 machine (root or sudo):
#   make demo   install what is missing, then run the demos (sound bar, Hopkinson bar BE16)
#   make test   install what is missing, then run the test suite (MPI tests included)
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
# DOLFINx 0.5.2, PETSc, MPI and gmsh come from Debian; the GL/EGL libraries let the
# VTK wheel (pyvista) render PNGs off-screen with no X server.
APT_PACKAGES := python3-dolfinx-real python3-petsc4py-real python3-mpi4py python3-gmsh \
                python3-scipy python3-venv python3-pip openmpi-bin \
                libgl1 libegl1 libgl1-mesa-dri libosmesa6 libxrender1 libx11-6
# `make test` only: a one-node Slurm for tests/test_batch.py (tests/slurm/local-slurm.sh).
# Not in APT_PACKAGES: `make install` also sets up cluster nodes, whose own Slurm Debian's
# would clash with.
TEST_APT_PACKAGES := slurm-wlm munge
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
# One BLAS thread per process (see dolfrag/__init__.py); MPI as root needs these.
export OPENBLAS_NUM_THREADS := 1
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1

.PHONY: install system-packages test-packages demo test check bench peer clean

install: system-packages $(VENV)/.installed

# $(call apt_install,PACKAGES): install those of PACKAGES that are missing
define apt_install
	@missing=$$(for p in $(1); do \
	    dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q "ok installed" || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	    echo "Installing Debian packages:" $$missing; \
	    $(SUDO) apt-get update -qq && \
	    $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	fi
endef

system-packages:
	$(call apt_install,$(APT_PACKAGES))

test-packages:
	$(call apt_install,$(TEST_APT_PACKAGES))

$(VENV)/.installed: pyproject.toml
	@[ -x $(PY) ] || /usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -e ".[dev]" "numpy<2"
	$(PY) -c "import dolfinx, petsc4py, gmsh, pyvista, numba, cantera, dolfrag; print('dolfinx', dolfinx.__version__, 'numba', numba.__version__, 'cantera', cantera.__version__)"
	@echo "Compiling the star kernels (numba, once per version of their sources: 3 minutes of CPU)..."
	@$(PY) -c "from dolfrag import viscosity; from dolfrag.rebar import cables; from dolfrag.interface import rate, rccm_kernel, softening_kernel; from dolfrag.solver import active_set, elastic_kernel, energy, star_kernel; star_kernel.warm(); active_set.warm(); elastic_kernel.warm(); viscosity.warm(); cables.warm(); rccm_kernel.warm(); softening_kernel.warm(); rate.warm(); energy.warm()"
	@touch $@

demo: install
	$(PY) demos/sound_bar.py
	$(PY) demos/shpb_be16.py

# -n auto --dist loadfile: one pytest worker per core (pytest-xdist), each test file on one
# worker, so that a file's module fixtures run once and the Slurm tests share one daemon.
# Much of the suite waits (Slurm's time limits, the slowed steps of the stop tests): on two
# cores it took 34 minutes serially, 15.5 with two workers (and the law matrix drawing each
# case's figures once, tests/test_law_matrix.py). An MPI test's ranks then share the cores
# with the other worker (Open MPI's mpi_yield_when_idle made that worse: a 2-rank theta run
# next to a busy core took 165 s instead of 10). --durations: the slowest tests, so that a
# suite grown slower says where.
test: install test-packages
	$(PY) -m pytest -q -rs --durations=15 -n auto --dist loadfile tests

# The quick tier, after each change: neither the MPI tests nor the slow ones (whole case runs)
check: install
	$(PY) -m pytest -q -x -m "not slow and not mpi" tests

bench: install
	$(PY) benchmarks/step_cost.py

# The peer comparison (docs/performance.md): Akantu in its own venv, for the benchmark only.
AKANTU_VENV := .venv-akantu
$(AKANTU_VENV)/.installed:
	@[ -x $(AKANTU_VENV)/bin/python ] || /usr/bin/python3 -m venv $(AKANTU_VENV)
	$(AKANTU_VENV)/bin/pip install -q --disable-pip-version-check "akantu==5.0.7.post1" "numpy<2"
	@touch $@

peer: install $(AKANTU_VENV)/.installed
	$(PY) benchmarks/peer_akantu.py --akantu-python $(AKANTU_VENV)/bin/python

# results, and the compiled kernels of every version of their sources (dolfrag/kernel_cache.py),
# as well as those that versions before it left beside the sources (*.nbi, *.nbc)
clean:
	rm -rf results .pytest_cache dolfrag/__pycache__/numba
	find dolfrag -name "*.nbi" -delete -o -name "*.nbc" -delete
