"""Every bad input exits 2 with one line naming the key, without a traceback, and writes
nothing: a table of them through the command's own entry point (cli.main, in-process:
most fail before meshing, in milliseconds), and more ranks than cells under mpirun."""
import os
import subprocess
import sys

import pytest

from conftest import ROOT
from dolfrag import cli

GEO = """Point(1) = {0, 0, 0}; Point(2) = {0.1, 0, 0}; Point(3) = {0.1, 0.04, 0}; Point(4) = {0, 0.04, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Surface("concrete") = {1}; Physical Curve("impact") = {4}; Physical Curve("free") = {2};
"""
TRIANGLE = """$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
2
1 1 "impact"
2 2 "concrete"
$EndPhysicalNames
$Nodes
3
1 0 0 0
2 0.1 0 0
3 0 0.1 0
$EndNodes
$Elements
2
1 1 2 1 1 3 1
2 2 2 2 1 1 2 3
$EndElements
"""  # one triangle, its edge x = 0 named "impact"
FILE = ["geometry.kind='file'", "geometry.file={geo}", "geometry.length=", "geometry.width=",
        "geometry.structured=", "load.boundary='impact'", "supports.rollers=[]"]
STEEL = ["materials.steel.E=2e11", "materials.steel.nu=0.3", "materials.steel.rho=7850.0"]
BARS = ["rebar.faces=['bottom']", "rebar.cover=0.01", "rebar.diameter=0.005", "rebar.spacing=0.1"]
SHORT = ["time.end=2e-6", "output.figures=false", "output.fields=0"]
H2_AIR = ["load.signal='h2-air'", "load.peak=", "load.rise=", "load.h2_fraction=0.296", "load.regime='detonation'",
          "load.room_length=3.0"]  # a detonation of stoichiometric H2-air in a 3 m room
H2_O2 = ["load.oxidizer='oxygen'", "load.h2_fraction=0.667"]  # ... of stoichiometric H2-O2

# name: (case, --set overrides, other arguments, the key the one line must name)
BAD = {
    "negative modulus": ("sound-bar", ["material.E=-1"], [], "material.E"),
    "non-numeric size": ("sound-bar", ["mesh.size=abc"], [], "mesh.size"),
    "unknown key": ("sound-bar", ["material.Ee=1"], [], "material.Ee"),
    "unknown section": ("sound-bar", ["solver.tol=1"], [], "solver"),
    "unknown law": ("sound-bar", ["interface.law='glue'"], [], "interface.law"),
    "unknown boundary": ("sound-bar", ["load.boundary='ceiling'"], [], "load.boundary"),
    "unknown case": ("no-such-case", [], [], "no-such-case"),
    "Poisson 0.5": ("sound-bar", ["material.nu=0.5"], [], "material.nu"),
    "cfl above 1": ("sound-bar", ["time.cfl=2"], [], "time.cfl"),
    "bars' step rule not a choice": ("wall-bending-clamped", ["time.bars_step=exact"], [], "time.bars_step"),
    "bond not a choice": ("wall-bending-simple", ["rebar.bond='glued'"], [], "rebar.bond"),
    "bond-slip under theta": ("wall-bending-simple", ["rebar.bond='fib2010'", "time.scheme='theta'",
                                                      "interface.law='elastic'", "interface.mu=",
                                                      "interface.rate_effect="], [],
                              "rebar.bond"),
    "bond-slip with the weyl step": ("wall-bending-simple", ["rebar.bond='fib2010'", "time.bars_step='weyl'"], [],
                                     "rebar.bond"),
    "bond-slip without a strength": ("wall-bending-simple", ["rebar.bond='fib2010'", "material.grade=",
                                                             "material.E=30e9", "material.nu=0.2",
                                                             "material.rho=2400", "interface.sigma_c=3e6",
                                                             "interface.G_c=100"], [], "rebar.bond_tau_max"),
    "bond-slip s3 inside the plateau": ("wall-bending-simple", ["rebar.bond='fib2010'", "rebar.bond_s3=0.001"], [],
                                        "rebar.bond_s3"),
    "bond strength with perfect bond": ("wall-bending-simple", ["rebar.bond_tau_max=1e7"], [],
                                        "rebar.bond_tau_max"),
    "intact shear cone without radius": ("compression-block", ["interface.tau_c=1e6"], [], "interface.tau_c"),
    "no end time": ("sound-bar", ["time.end=0"], [], "time.end"),
    "history every 0 steps": ("sound-bar", ["output.every=0"], [], "output.every"),
    "pulse shorter than its rise": ("sound-bar", ["load.duration=1e-6"], [], "load.duration"),
    "rccm strength and w": ("sound-bar", ["interface.law='rccm'", "interface.sigma_c=3e6", "interface.w=1"], [],
                            "interface.sigma_c"),
    "rccm without strength": ("sound-bar", ["interface.law='rccm'"], [], "interface.sigma_c"),
    "C_T and shear_ratio": ("sound-bar", ["interface.C_T=1e15", "interface.shear_ratio=2"], [], "interface.C_T"),
    "theta with a rigid law": ("sound-bar", ["time.scheme='theta'", "interface.law='threshold'", "interface.R_c=1e6",
                                             "interface.W_eth=1e-5"], [], "time.scheme"),
    "a boundary in two support lists": ("sound-bar", ["supports.clamped=['top']"], [], "supports"),
    "clamped load boundary": ("sound-bar", ["supports.clamped=['left']"], [], "supports.clamped"),
    "half a load region": ("sound-bar", ["load.region_min=[0.0, 0.0]"], [], "load.region_min"),
    "unknown geometry": ("sound-bar", ["geometry.kind='sphere'"], [], "geometry.kind"),
    "malformed --set": ("sound-bar", ["mesh.size"], [], "mesh.size"),
    "missing mesh file": ("sound-bar", [*FILE[:1], "geometry.file='absent.msh'", *FILE[2:]], [], "geometry.file"),
    "negative cell limit": ("sound-bar", ["run.max_cells=-1"], [], "run.max_cells"),
    "oversized mesh": ("sound-bar", ["mesh.size=1e-6"], [], "run.max_cells"),
    "too many steps": ("sound-bar", ["material.E=1e30"], [], "run.max_steps"),
    "two-cell mesh": ("sound-bar", ["mesh.size=0.2"], [], "mesh.size"),
    "--out is a file": ("sound-bar", [], ["--out", "{file}"], "--out"),
    "--out inside a file": ("sound-bar", [], ["--out", "{file}/out"], "--out"),
    "--out not empty": ("sound-bar", [], ["--out", "{full}"], "--out"),
    "--out not writable": ("sound-bar", [], ["--out", "/proc/sys/dolfrag-out"], "--out"),
    "oversized mesh of a .geo": ("sound-bar", FILE + ["mesh.size=1e-6"], [], "run.max_cells"),
    "a .msh above the cell limit": ("sound-bar", [s.replace("{geo}", "{msh}") for s in FILE]
                                    + ["run.max_cells=0.5"], [], "run.max_cells"),
    "group of a generated mesh": ("sound-bar", STEEL, [], "materials.steel"),
    "group not in the mesh file": ("sound-bar", FILE + STEEL + ["mesh.size=0.01"] + SHORT, [], "materials.steel"),
    "bar axis normal to its face": ("sound-bar", BARS + ["rebar.faces=['left']"], [], "rebar.direction"),
    "two bar axes in 2D": ("sound-bar", BARS + ["rebar.direction='xy'"], [], "rebar.direction"),
    "bar axis z in 2D": ("sound-bar", BARS + ["rebar.direction='z'"], [], "rebar.direction"),
    "bars thicker than their spacing": ("sound-bar", BARS + ["rebar.spacing=0.004"], [], "rebar.diameter"),
    "bars thicker than twice the cover": ("sound-bar", BARS + ["rebar.cover=0.002"], [], "rebar.diameter"),
    "rupture before yield": ("sound-bar", BARS + ["rebar.f_y=500e6", "rebar.eps_u=1e-3"], [], "rebar.eps_u"),
    "bar keys without faces": ("sound-bar", ["rebar.cover=0.01"], [], "rebar.cover"),
    "bar layer without spacing": ("sound-bar", BARS + ["rebar.spacing="], [], "rebar.spacing"),
    "fragments after the end": ("sound-bar", ["output.fragments_at=[1e-5, 1.0]"], [], "output.fragments_at"),
    "H2 fraction below 0.1": ("sound-bar", H2_AIR + ["load.h2_fraction=0.05"], [], "load.h2_fraction"),
    "H2 fraction above 0.6": ("sound-bar", H2_AIR + ["load.h2_fraction=0.7"], [], "load.h2_fraction"),
    "unknown explosion regime": ("sound-bar", H2_AIR + ["load.regime='boom'"], [], "load.regime"),
    "h2-air without a room length": ("sound-bar", H2_AIR + ["load.room_length="], [], "load.room_length"),
    "h2-air deflagration without rise": ("sound-bar", H2_AIR + ["load.regime='deflagration'"], [], "load.rise"),
    "rise of an h2-air detonation": ("sound-bar", H2_AIR + ["load.rise=1e-6"], [], "load.rise"),
    "heat loss of all the pressure": ("sound-bar", H2_AIR + ["load.heat_loss=1"], [], "load.heat_loss"),
    "h2-air with a given peak": ("sound-bar", H2_AIR + ["load.peak=1e6"], [], "load.peak"),
    "unknown oxidiser": ("sound-bar", H2_AIR + ["load.oxidizer='fluorine'"], [], "load.oxidizer"),
    "H2 above the H2-O2 detonation limit": ("sound-bar", H2_AIR + H2_O2 + ["load.h2_fraction=0.95"], [],
                                            "load.h2_fraction"),
    "H2 below the H2-O2 detonation limit": ("sound-bar", H2_AIR + H2_O2 + ["load.h2_fraction=0.1"], [],
                                            "load.h2_fraction"),
    "diluted air": ("sound-bar", H2_AIR + ["load.diluent_fraction=0.2"], [], "load.diluent_fraction"),
    "unknown diluent": ("sound-bar", H2_AIR + H2_O2 + ["load.diluent='He'"], [], "load.diluent"),
    "more diluent per O2 than air's N2": ("sound-bar", H2_AIR + H2_O2 + ["load.diluent_fraction=0.6"], [],
                                          "load.diluent_fraction"),
    "diluted oxygen mixture leaner than H2-air's limit": ("sound-bar", H2_AIR + H2_O2 + [
        "load.h2_fraction=0.2", "load.diluent_fraction=0.1"], [], "load.h2_fraction"),
    "negative drag coefficient": ("slab-3d-scabbing", ["debris.C_D=-1"], [], "debris.C_D"),
    "negative air density": ("slab-3d-scabbing", ["debris.air_density=-1.2"], [], "debris.air_density"),
    "ground level not a number": ("slab-3d-scabbing", ["debris.ground_z='floor'"], [], "debris.ground_z"),
    "no hazard energy": ("slab-3d-scabbing", ["debris.hazard_energy=0"], [], "debris.hazard_energy"),
    "negative hazard area": ("slab-3d-scabbing", ["debris.hazard_area=-55.7"], [], "debris.hazard_area"),
    "rings of no width": ("slab-3d-scabbing", ["debris.ring_width=0"], [], "debris.ring_width"),
    "debris switch not a bool": ("slab-3d-scabbing", ["debris.enabled=1"], [], "debris.enabled"),
    "unknown debris key": ("slab-3d-scabbing", ["debris.gravity=9.81"], [], "debris.gravity"),
    "door wider than the room": ("bunker-h2", ["geometry.door=[3.5, 2.0]"], [], "geometry.door"),
    "door higher than the room": ("bunker-h2", ["geometry.door=[0.9, 2.5]"], [], "geometry.door"),
    "door panel as thick as the wall": ("bunker-h2", ["geometry.door_thickness=0.2"], [], "geometry.door_thickness"),
    "room given two sizes": ("bunker-h2", ["geometry.inner=[3.0, 2.0]"], [], "geometry.inner"),
    "bunker wall on a box": ("slab-3d-scabbing", ["geometry.wall=0.2"], [], "geometry.wall"),
    "bunker bars on the ground": ("bunker-h2", ["rebar.faces=['ground']"], [], "rebar.faces"),
    "bunker bars along one axis": ("bunker-h2", ["rebar.direction='x'"], [], "rebar.direction"),
    "bars on a 2D mesh file": ("sound-bar", FILE + BARS + ["rebar.faces=['impact']"], [], "rebar.faces"),
    "file bars along one axis": ("bunker-two-rooms", ["rebar.direction='x'"], [], "rebar.direction"),
    "file bars on a group not in the mesh": ("bunker-two-rooms", ["rebar.faces=['roof']", "mesh.size=0.5"], [],
                                             "roof"),
    "theta on a wall in bending that breaks": ("wall-bending-clamped", [
        "time.scheme=theta", "time.dt=1e-4", "material.grade=", "material.E=35e9", "material.nu=0.2",
        "material.rho=2350", "interface.law=rccm", "interface.sigma_c=4e6", "interface.rate_effect="], [],
        "load.boundary"),
    "bunker material group not built": ("bunker-h2", ["materials.door.E=1e10", "materials.door.nu=0.2",
                                                      "materials.door.rho=2300.0"], [], "materials.door"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_input_exits_2_with_one_line_and_writes_nothing(name, tmp_path, capsys, monkeypatch):
    case, sets, extra, key = BAD[name]
    (tmp_path / "bar.geo").write_text(GEO)
    (tmp_path / "tri.msh").write_text(TRIANGLE)
    (tmp_path / "file").write_text("x")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("x")
    monkeypatch.chdir(tmp_path)  # relative paths (absent.msh) resolve here
    where = {"geo": tmp_path / "bar.geo", "msh": tmp_path / "tri.msh", "file": tmp_path / "file",
             "full": tmp_path / "full"}
    args = [a.format(**where) for a in extra] or ["--out", str(tmp_path / "out")]
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    status = cli.main(["run", case, *args, "--quiet", *(x for s in sets for x in ("--set", s.format(**where)))])
    err = capsys.readouterr().err
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and key in lines[0] and lines[0].startswith("dolfrag: error: "), err
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before  # nothing written


def test_more_ranks_than_cells_exits_2_on_every_rank(tmp_path):
    """A one-triangle mesh on two ranks: one rank would own nothing (mpirun -q: without
    its own banner about a non-zero exit)."""
    (tmp_path / "tri.msh").write_text(TRIANGLE)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OPENBLAS_NUM_THREADS="1")
    sets = [s.format(geo=tmp_path / "tri.msh") for s in FILE] + ["mesh.size=0.01"] + SHORT
    result = subprocess.run(["mpirun", "-q", "-n", "2", sys.executable, "-m", "dolfrag.cli", "run", "sound-bar",
                             "--out", str(tmp_path / "out"), *(x for s in sets for x in ("--set", s))],
                            capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "too few for 2 ranks" in lines[0] and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()
