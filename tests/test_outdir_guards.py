"""Safe output folders (--out, --overwrite) and the size and run-length guards: refused
before meshing, in a fraction of a second, with one line."""
import os
import subprocess
import sys
import time

import pytest

import dolfrag.mesh
from conftest import ROOT, dolfrag_cli
from dolfrag import guards, loads
from dolfrag.case import CaseError, load_case
from dolfrag.runner.driver import run

pytestmark = pytest.mark.slow  # whole runs of cases, seconds each: not in `make check`

SMALL = ["--set", "mesh.size=0.01", "--set", "time.end=2e-6", "--set", "output.fields=0",
         "--set", "output.figures=false", "--quiet"]


def _check(case):
    """guards.check of a case with its load as applied."""
    return guards.check(case, loads.applied(case.load))


def snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def one_line_exit_2(result, key):
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0] and "Traceback" not in result.stderr, result.stderr


def test_a_rerun_into_a_non_empty_folder_is_refused_and_leaves_it_as_it_was(tmp_path):
    out = tmp_path / "out"
    assert dolfrag_cli("run", "sound-bar", "--out", out, *SMALL).returncode == 0
    (out / "notes.txt").write_text("mine")
    before = snapshot(out)
    one_line_exit_2(dolfrag_cli("run", "sound-bar", "--out", out, *SMALL), "--out")
    assert snapshot(out) == before


def test_overwrite_empties_the_folder_first(tmp_path):
    out = tmp_path / "out"
    (out / "old" / "deep").mkdir(parents=True)
    (out / "summary.json").write_text('{"status": "completed"}')
    (out / "old" / "deep" / "stale.png").write_bytes(b"png")
    result = dolfrag_cli("run", "sound-bar", "--out", out, "--overwrite", *SMALL)
    assert result.returncode == 0, result.stderr
    assert not (out / "old").exists()  # nothing of the first run is left
    assert '"status": "completed"' in (out / "summary.json").read_text()
    assert '"steps"' in (out / "summary.json").read_text()  # the new run's summary


def test_an_empty_folder_is_accepted(tmp_path):
    (tmp_path / "out").mkdir()
    assert dolfrag_cli("run", "sound-bar", "--out", tmp_path / "out", *SMALL).returncode == 0


@pytest.mark.parametrize("where", ["file", "inside a file", "read-only"])
def test_out_that_cannot_be_a_folder_is_refused_before_meshing(where, tmp_path):
    (tmp_path / "f").write_text("x")
    out = {"file": tmp_path / "f", "inside a file": tmp_path / "f" / "out",
           "read-only": "/proc/sys/dolfrag-out"}[where]  # /proc/sys: read-only even for root
    one_line_exit_2(dolfrag_cli("run", "sound-bar", "--out", out), "--out")
    assert (tmp_path / "f").read_text() == "x"


@pytest.fixture
def no_meshing(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("meshing started")
    monkeypatch.setattr(dolfrag.mesh, "build", refuse)


@pytest.mark.parametrize("override, key", [("mesh.size=1e-6", "run.max_cells"), ("material.E=1e30", "run.max_steps"),
                                           ("mesh.size=0.13", "geometry.width")])
def test_an_oversized_case_is_refused_before_gmsh_starts(override, key, tmp_path, no_meshing, comm):
    case = load_case("sound-bar", [override])
    start = time.perf_counter()
    with pytest.raises(CaseError, match=key) as err:
        run(case, tmp_path / "out", comm=comm)
    # the guard is arithmetic on the case: milliseconds; gmsh at mesh.size = 1e-6 would not end
    assert time.perf_counter() - start < 0.2
    assert "\n" not in str(err.value) and not (tmp_path / "out").exists()


def test_the_limits_are_keys_that_raise_them():
    big = load_case("sound-bar", ["mesh.size=1e-4"])
    with pytest.raises(CaseError, match="about 1.15e\\+06 cells"):  # 2.4 x 0.12 x 0.04 / 1e-8 = 1.15e6
        _check(load_case("sound-bar", ["mesh.size=1e-4", "run.max_cells=1e6"]))
    assert _check(big) is None


def test_the_estimates_match_the_mesh_and_the_stable_step(comm):
    """cells_estimate and steps_estimate against a meshed 2D and 3D case: within 25 %
    (the constants are rounded means over meshes whose boundary layers differ). The
    estimate leaves the bars out: with their coupled step (rebar/stable_step.py) this slab's
    step is its bulk's own (measured: the estimate is 1.00 of the steps; 0.75 with the
    "weyl" step)."""
    from dolfrag.problem import Problem
    for name, sets in [("sound-bar", ["mesh.size=0.004"]),
                       ("slab-3d-scabbing", ["geometry.length=0.2", "geometry.width=0.2", "mesh.size=0.025"])]:
        case = load_case(name, sets + ["time.end=1e-5"])
        problem = Problem.build(case, comm)
        cells = problem.domain.mesh.topology.index_map(problem.domain.tdim).size_global
        assert guards.cells_estimate(case.geometry, case.mesh.size) == pytest.approx(cells, rel=0.25)
        assert guards.steps_estimate(case, problem.applied_load) == pytest.approx(problem.n_steps, rel=0.25)


@pytest.mark.parametrize("override, axis", [("mesh.size=0.025", "geometry.width"),
                                            ("load.boundary='bottom'", "geometry.width")])
def test_a_thin_body_gets_one_warning_line(override, axis):
    case = load_case("sound-bar", ["mesh.size=0.025", override, "supports.rollers=[]"])
    warning = _check(case)  # the 0.04 m width: 2 elements across
    assert warning is not None and axis in warning and "2 elements across" in warning and "\n" not in warning
    assert _check(load_case("sound-bar", ["mesh.size=0.01"])) is None  # 4 across the width
    assert _check(load_case("sound-bar", ["mesh.size=0.015"])) is None  # 0.04 / 0.015 = 2.7: gmsh puts 3


def test_on_2_ranks_a_non_empty_folder_is_refused_and_overwrite_empties_it(tmp_path):
    """outdir.prepare is collective: every rank refuses, or every rank runs after rank 0
    emptied the folder (mpirun -q: without its own banner about a non-zero exit)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "stale.csv").write_text("old")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OPENBLAS_NUM_THREADS="1")
    command = ["mpirun", "-q", "-n", "2", sys.executable, "-m", "dolfrag.cli", "run", "sound-bar", "--out", str(out),
               *SMALL]
    refused = subprocess.run(command, capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    one_line_exit_2(refused, "--out")
    assert [p.name for p in out.iterdir()] == ["stale.csv"]
    ran = subprocess.run(command + ["--overwrite"], capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    assert ran.returncode == 0, ran.stderr
    assert not (out / "stale.csv").exists() and '"ranks": 2' in (out / "summary.json").read_text()
