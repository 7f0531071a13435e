"""The `dolfrag` command: built-in cases, and bad input -> exit 2, one line, nothing written."""
import pytest

from conftest import dolfrag_cli
import dolfrag
from dolfrag.case import builtin_case_text, builtin_cases, load_case

SMALL = ["--set", "mesh.size=0.01", "--set", "time.end=2e-6", "--set", "output.fields=0",
         "--set", "output.figures=false"]
GEO = """Point(1) = {0, 0, 0}; Point(2) = {0.1, 0, 0}; Point(3) = {0.1, 0.04, 0}; Point(4) = {0, 0.04, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Surface("concrete") = {1}; Physical Curve("impact") = {4}; Physical Curve("free") = {2};
"""


def case_file(tmp_path, geometry, load):
    text = builtin_case_text("sound-bar")
    text = text.replace('kind = "rectangle"\nlength = 0.12        # m\nwidth = 0.04         # m', geometry)
    text = text.replace('boundary = "left"\nsignal = "triangular"\npeak = 1.0e6         # Pa, '
                        'compressive (pushes into the bar)\nrise = 2.0e-6        # s\nduration = 10.0e-6   # s',
                        load)
    text = text.replace('rollers = ["bottom", "top"]', "rollers = []")
    path = tmp_path / "case.toml"
    path.write_text(text)
    return path


def test_cases_lists_the_built_ins_with_their_descriptions_and_prints_one_that_loads(tmp_path):
    listing = dolfrag_cli("cases")
    assert listing.returncode == 0
    lines = dict(line.split(None, 1) for line in listing.stdout.splitlines())
    assert list(lines) == builtin_cases()
    assert all(lines[name] == load_case(name).description and lines[name] for name in lines)
    printed = dolfrag_cli("cases", "sound-bar")
    assert printed.returncode == 0
    (tmp_path / "copy.toml").write_text(printed.stdout)
    assert load_case(tmp_path / "copy.toml").material.E == 35e9


def test_version():
    result = dolfrag_cli("--version")
    assert result.returncode == 0 and result.stdout.strip() == f"dolfrag {dolfrag.__version__}"


def test_a_small_run_writes_its_outputs(tmp_path):
    result = dolfrag_cli("run", "sound-bar", "--out", tmp_path / "out", "--quiet", *SMALL)
    assert result.returncode == 0, result.stderr
    assert {p.name for p in (tmp_path / "out").iterdir()} >= {"summary.json", "history.csv"}


BAD = {
    "negative": (["--set", "material.E=-1"], "material.E"),
    "non-numeric": (["--set", "mesh.size=abc"], "mesh.size"),
    "unknown key": (["--set", "material.Ee=1"], "material.Ee"),
    "unknown law": (["--set", "interface.law=glue"], "interface.law"),
    "unknown boundary": (["--set", "load.boundary=ceiling"], "load.boundary"),
    "unknown case": ([], "no-such-case"),
}


@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_input_exits_2_with_one_line_and_writes_nothing(kind, tmp_path):
    args, key = BAD[kind]
    case = "no-such-case" if kind == "unknown case" else "sound-bar"
    check(dolfrag_cli("run", case, "--out", tmp_path / "out", *args), key, tmp_path)


def check(result, key, tmp_path):
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0] and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_missing_parameter(tmp_path):
    path = tmp_path / "case.toml"
    path.write_text(builtin_case_text("sound-bar").replace("E = 35e9", ""))
    check(dolfrag_cli("run", path, "--out", tmp_path / "out"), "material.E", tmp_path)


def test_missing_mesh_file(tmp_path):
    path = case_file(tmp_path, 'kind = "file"\nfile = "absent.msh"', 'boundary = "impact"\npeak = 1e6\nduration = 1e-5')
    check(dolfrag_cli("run", path, "--out", tmp_path / "out"), "geometry.file", tmp_path)


def test_unreadable_csv(tmp_path):
    (tmp_path / "p.csv").write_text("t,p\n0,0\n1e-6,oops\n")
    path = case_file(tmp_path, 'kind = "rectangle"\nlength = 0.1\nwidth = 0.04',
                     'boundary = "left"\nsignal = "table"\nfile = "p.csv"')
    check(dolfrag_cli("run", path, "--out", tmp_path / "out"), "p.csv", tmp_path)


def test_unknown_boundary_of_an_imported_mesh(tmp_path):
    (tmp_path / "bar.geo").write_text(GEO)
    path = case_file(tmp_path, 'kind = "file"\nfile = "bar.geo"', 'boundary = "left"\npeak = 1e6\nduration = 1e-5')
    result = dolfrag_cli("run", path, "--out", tmp_path / "out", *SMALL[:2])
    check(result, "load.boundary", tmp_path)
    assert "impact" in result.stderr  # the message lists the boundaries that exist


def test_imported_mesh_runs_with_its_own_boundary_names(tmp_path):
    (tmp_path / "bar.geo").write_text(GEO)
    path = case_file(tmp_path, 'kind = "file"\nfile = "bar.geo"', 'boundary = "impact"\npeak = 1e6\nduration = 1e-5')
    result = dolfrag_cli("run", path, "--out", tmp_path / "out", "--quiet", *SMALL)
    assert result.returncode == 0, result.stderr
    assert "vx_impact_m_s" in (tmp_path / "out" / "history.csv").read_text().splitlines()[0]


def test_the_entry_point_and_the_run_package_do_not_clash():
    """``dolfrag.run`` is the function; the machinery of a run is the package
    ``dolfrag.runner``, reachable as an attribute once imported."""
    import dolfrag
    import dolfrag.runner.loop
    assert callable(dolfrag.run) and dolfrag.run is dolfrag.runner.driver.run
    assert callable(dolfrag.runner.loop.time_loop)


def test_the_resume_line_names_the_launcher_the_run_was_started_with(monkeypatch):
    """mpirun on more than one rank, nothing on one, srun inside a Slurm job (where mpirun
    would start a second job's worth of ranks outside the allocation)."""
    from mpi4py import MPI
    from dolfrag.runner.driver import resume_command
    monkeypatch.delenv("SLURM_JOB_ID", raising=False)
    assert resume_command("r", MPI.COMM_SELF) == "dolfrag run --resume r"
    monkeypatch.setenv("SLURM_JOB_ID", "42")
    assert resume_command("r", MPI.COMM_SELF) == "srun dolfrag run --resume r"
