"""Tests for dolfrag.case: TOML case files -> validated dataclasses."""
import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from dolfrag.case import CaseError, Interface, builtin_case_text, load_case

DEL = object()  # marks a key to delete from BASE
BASE = {
    "geometry": {"kind": "rectangle", "length": 2, "width": 0.1},
    "mesh": {"size": 0.01},
    "material": {"E": 3e10, "nu": 0.2, "rho": 2400.0},
    "load": {"boundary": "left", "peak": 1e6, "rise": 1e-5, "duration": 2e-5},
    "supports": {"rollers": ["bottom", "top"]},
    "time": {"end": 1e-4},
}
TABLE = {"load.signal": "table", "load.peak": DEL, "load.rise": DEL, "load.duration": DEL,
         "load.file": "p.csv"}
FILE = {"geometry.kind": "file", "geometry.length": DEL, "geometry.width": DEL}
STRETCH = {"load.kind": "stretch", "load.strain_rate": 600.0, "load.boundary": DEL, "load.peak": DEL,
           "load.rise": DEL, "load.duration": DEL, "interface.law": "linear_softening",
           "interface.sigma_c": 2e7, "interface.G_c": 100.0}


def _value(v):
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(map(_value, v)) + "]"
    return repr(v)


def _render(d, path=()):
    lines = [f"[{'.'.join(path)}]"] if path else []
    lines += [f"{k} = {_value(v)}" for k, v in d.items() if not isinstance(v, dict)]
    for k, v in d.items():
        if isinstance(v, dict):
            lines += _render(v, path + (k,))
    return lines


def write_case(tmp_path, changes=(), csv=None, name="bar.toml"):
    """Write BASE with dotted-key `changes` applied (DEL removes) and optionally p.csv."""
    d = copy.deepcopy(BASE)
    for key, v in dict(changes).items():
        *parents, last = key.split(".")
        table = d
        for p in parents:
            table = table.setdefault(p, {})
        table.pop(last, None) if v is DEL else table.__setitem__(last, v)
    if csv is not None:
        (tmp_path / "p.csv").write_text(csv)
    path = tmp_path / name
    path.write_text("\n".join(_render(d)) + "\n")
    return path


def test_valid_rectangle_values_and_defaults(tmp_path):
    case = load_case(write_case(tmp_path))
    assert case.name == "bar" and case.description == ""
    assert case.source == (tmp_path / "bar.toml").resolve()
    g = case.geometry
    assert (g.kind, g.length, g.width, g.thickness, g.file) == ("rectangle", 2.0, 0.1, None, None)
    assert isinstance(g.length, float)
    assert g.tdim == 2 and g.boundaries == ("left", "right", "bottom", "top")
    assert case.mesh.size == 0.01
    m = case.material
    assert (m.E, m.nu, m.rho, m.hypothesis) == (3e10, 0.2, 2400.0, "plane_strain")
    assert case.materials == {}
    i = case.interface
    assert (i.law, i.C_N, i.C_T, i.stiffness_ratio) == ("elastic", None, None, 10.0)
    ld = case.load
    assert (ld.boundary, ld.signal, ld.peak, ld.rise, ld.duration) == ("left", "triangular", 1e6, 1e-5, 2e-5)
    assert ld.file is None and ld.t is None and ld.p is None
    assert case.supports.rollers == ("bottom", "top") and case.supports.clamped == ()
    assert (case.time.scheme, case.time.end, case.time.cfl) == ("imex", 1e-4, 0.9)
    assert (case.output.every, case.output.fields, case.output.figures) == (10, 10, True)
    d = json.loads(json.dumps(case.to_dict()))
    assert d["geometry"]["length"] == 2.0 and d["supports"]["rollers"] == ["bottom", "top"]
    assert d["source"] == str(case.source)


def test_box_materials_and_rise_default(tmp_path):
    case = load_case(write_case(tmp_path, {
        "geometry.kind": "box", "geometry.thickness": 0.2, "load.rise": DEL,
        "material.hypothesis": "plane_stress", "materials.concrete": {"E": 2e11, "nu": 0.3, "rho": 7800},
        "supports.clamped": ["back"]}))
    assert case.geometry.tdim == 3 and "front" in case.geometry.boundaries
    assert case.load.rise == 0.0
    # a box's one material group is "concrete" (mesh.py)
    assert case.materials["concrete"].E == 2e11 and case.materials["concrete"].hypothesis == "plane_stress"


def test_stretch_load_needs_no_boundary_and_keeps_no_pressure_keys(tmp_path):
    case = load_case(write_case(tmp_path, STRETCH))
    load = case.load
    assert load.kind == "stretch" and load.strain_rate == 600.0
    assert load.boundary is None and load.signal is None and load.peak is None and load.region is None
    assert load_case(write_case(tmp_path)).load.kind == "pressure"


def test_table_load_relative_to_case_dir(tmp_path, monkeypatch):
    path = write_case(tmp_path, TABLE, csv="t,p\n0,0\n1e-5, 2e6\n\n3e-5,0\n")
    monkeypatch.chdir(tmp_path.parent)
    case = load_case(Path(tmp_path.name) / path.name)
    assert case.load.file == (tmp_path / "p.csv").resolve()
    assert case.load.t.dtype == np.float64
    np.testing.assert_array_equal(case.load.t, [0, 1e-5, 3e-5])
    np.testing.assert_array_equal(case.load.p, [0, 2e6, 0])
    assert case.load.peak is None and case.load.duration is None
    assert json.loads(json.dumps(case.to_dict()))["load"]["p"] == [0, 2e6, 0]


@pytest.mark.parametrize("changes, csv, key", [
    ({"mesh.size": DEL}, None, "mesh.size"),
    ({"time": DEL}, None, "time.end"),
    ({"material.E": -3.0}, None, "material.E"),
    ({"material.E": math.nan}, None, "material.E"),
    ({"material.nu": 0.5}, None, "material.nu"),
    ({"material.rho": "heavy"}, None, "material.rho"),
    ({"mesh.size": True}, None, "mesh.size"),
    ({"output.every": 2.5}, None, "output.every"),
    ({"output.figures": 1}, None, "output.figures"),
    ({"mesh": 3}, None, "mesh"),
    ({"foo.bar": 1}, None, "foo"),
    ({"material.Ee": 1.0}, None, "material.Ee"),
    ({"interface.law": "cohesive"}, None, "interface.law"),
    ({"time.scheme": "newmark"}, None, "time.scheme"),
    ({"time.dt": 1e-6}, None, "time.dt"),
    ({"time.scheme": "theta", "time.theta": 0.4}, None, "time.theta"),
    ({"time.scheme": "theta", "interface.law": "threshold", "interface.R_c": 1e6, "interface.W_eth": 1e-6},
     None, "time.scheme"),
    ({"load.boundary": "lft"}, None, "load.boundary"),
    ({"supports.rollers": ["bottom", "side"]}, None, "supports.rollers"),
    ({"supports.rollers": "bottom"}, None, "supports.rollers"),
    ({"supports.clamped": ["bottom"]}, None, "supports.clamped"),
    ({"supports.clamped": ["left"]}, None, "supports.clamped"),
    ({"load.rise": 3e-5}, None, "load.duration"),
    ({"geometry.thickness": 0.1}, None, "geometry.thickness"),
    ({"geometry.kind": "box"}, None, "geometry.thickness"),
    ({**FILE, "geometry.file": "nope.msh"}, None, "geometry.file"),
    ({**FILE}, None, "geometry.file"),
    ({"geometry.file": "mesh.msh"}, None, "geometry.file"),
    (TABLE, None, "load.file"),
    ({**TABLE, "load.peak": 1.0}, "0,0\n1,1\n", "load.peak"),
    ({"load.file": "p.csv"}, "0,0\n1,1\n", "load.file"),
    (TABLE, "t,p\n0,0\n1e-5,abc\n", "load.file * line 3"),
    (TABLE, "0,0\n1e-5,1\n1e-5,0\n", "load.file * line 3"),
    (TABLE, "0,0,0\n1,1,1\n", "load.file * line 2"),
    (TABLE, "t,p\n0,0\n", "load.file"),
    ({**STRETCH, "load.strain_rate": 0.0}, None, "load.strain_rate"),
    ({**STRETCH, "load.strain_rate": DEL}, None, "load.strain_rate"),
    ({**STRETCH, "load.boundary": "left"}, None, "load.boundary * load.kind is 'pressure'"),
    ({**STRETCH, "load.region_factor": 2.0}, None, "load.region_factor"),
    ({**STRETCH, "load.kind": "pull"}, None, "load.kind"),
    ({"load.strain_rate": 600.0}, None, "load.strain_rate * load.kind is 'stretch'"),
    ({**STRETCH, "interface.law": "elastic", "interface.sigma_c": DEL, "interface.G_c": DEL}, None,
     "load.kind = 'stretch' * interface.law = 'elastic'"),
    ({**STRETCH, "interface.law": "rccm", "interface.G_c": DEL, "time.scheme": "theta"}, None,
     "load.kind = 'stretch' * time.scheme = 'theta'"),
    ({"output.fragments_at": [1e-5, -1.0]}, None, "output.fragments_at"),
    ({"output.fragments_at": 1e-5}, None, "output.fragments_at"),
    ({"output.fragments_at": [True]}, None, "output.fragments_at"),
    ({"interface.law": "threshold", "interface.R_c": 1e6}, None, "interface.W_eth"),
    ({"interface.law": "rccm", "interface.sigma_c": 1e6, "interface.mu_i": -0.1}, None, "interface.mu_i"),
    ({"interface.law": "threshold", "interface.R_c": 1e6, "interface.W_eth": 1e-6, "interface.mu_i": 0.5}, None,
     "interface.mu_i"),
    ({"interface.law": "linear_softening", "interface.G_c": 50.0}, None, "interface.sigma_c"),
    ({"interface.law": "rccm", "interface.sigma_c": 1e6, "interface.G_c": 50.0}, None, "interface.G_c"),
    ({"interface.law": "rccm", "interface.sigma_c": 1e6, "interface.R_c": 1e6}, None, "interface.R_c"),
    ({"interface.law": "rccm_decoupled", "interface.sigma_c": 1e7, "interface.G_c": 1e-6}, None,
     "interface.G_c * C_N > sigma_c^2 / (2 G_c)"),
])
def test_invalid_case_raises_one_line_error(tmp_path, changes, csv, key):
    with pytest.raises(CaseError) as info:
        load_case(write_case(tmp_path, changes, csv))
    msg = str(info.value)
    assert "\n" not in msg
    for part in key.split(" * "):
        assert part in msg


def test_error_message_format(tmp_path):
    with pytest.raises(CaseError, match=r"^material\.E = -3\.0: must be a number > 0 \(Pa\)$"):
        load_case(write_case(tmp_path, {"material.E": -3.0}))
    with pytest.raises(CaseError, match="^unknown key 'material.Ee'; allowed: E, nu, rho, hypothesis, bulk_viscosity, grade$"):
        load_case(write_case(tmp_path, {"material.Ee": 1.0}))


def test_overrides(tmp_path):
    path = write_case(tmp_path)
    case = load_case(path, ["material.E=1e6", "mesh.size=1", "load.boundary=right",
                            'description="a b"', 'supports.rollers=["top"]', "output.figures=false",
                            "interface.C_N = 5e12"])
    assert case.material.E == 1e6 and case.mesh.size == 1.0 and isinstance(case.mesh.size, float)
    assert case.load.boundary == "right" and case.description == "a b"
    assert case.supports.rollers == ("top",) and case.output.figures is False
    assert case.interface.C_N == 5e12


def test_an_override_without_a_value_restores_the_default():
    # a theta case switched to imex: its time.dt is theta-only, and the error says how to drop it
    theta = ["time.scheme=theta", "time.dt=1e-4"]
    with pytest.raises(CaseError, match=r"^time\.dt = 0\.0001: only allowed when time\.scheme is 'theta' "
                                        r"\(--set time\.dt= removes it\)$"):
        load_case("sound-bar", [*theta, "time.scheme=imex"])
    case = load_case("sound-bar", [*theta, "time.scheme=imex", "time.dt="])
    assert case.time.scheme == "imex" and case.time.dt is None
    assert load_case("wall-bending-clamped").output.fields == 20  # the case's, against the default 10
    assert load_case("wall-bending-clamped", ["output.fields="]).output.fields == 10
    with pytest.raises(CaseError, match="^missing key mesh.size"):  # a required key has no default
        load_case("wall-bending-clamped", ["mesh.size="])


@pytest.mark.parametrize("item, key", [
    ("material.Ee=1", "material.Ee"),
    ("materal.E=1", "materal"),
    ("material.E=abc", "material.E = 'abc'"),
    ("output.every=0", "output.every"),
    ("material.E", "material.E"),
    ("material.E.x=1", "material.E"),
])
def test_bad_override(tmp_path, item, key):
    with pytest.raises(CaseError, match="^[^\n]*$") as info:
        load_case(write_case(tmp_path), [item])
    assert key in str(info.value)


def test_stiffness():
    assert Interface().stiffness(3e10, 0.01) == pytest.approx((10 * 3e10 / 0.01,) * 2)
    assert Interface(stiffness_ratio=2.0).stiffness(1.0, 0.5) == (4.0, 4.0)
    assert Interface(C_N=7.0).stiffness(1.0, 0.5) == (7.0, 20.0)
    assert Interface(C_N=7.0, C_T=3.0).stiffness(1.0, 0.5) == (7.0, 3.0)
    # a shear ratio follows the mesh: C_T = ratio * C_N at every h, given C_N included
    assert Interface(shear_ratio=4.0).stiffness(1.0, 0.5) == (20.0, 80.0)
    assert Interface(shear_ratio=4.0).stiffness(1.0, 0.25) == (40.0, 160.0)
    assert Interface(C_N=7.0, shear_ratio=0.5).stiffness(1.0, 0.5) == (7.0, 3.5)


def test_shear_ratio_and_C_T_together_are_refused():
    with pytest.raises(CaseError, match=r"^interface\.C_T = 1e\+14 Pa/m, interface\.shear_ratio = 4\.0: give one"):
        load_case("shpb-be16", ["interface.C_T=1e14", "interface.shear_ratio=4"])
    assert load_case("shpb-be16", ["interface.shear_ratio=4"]).interface.stiffness(35e9, 0.007)[1] == \
        pytest.approx(4 * 10 * 35e9 / 0.007, rel=1e-15)


def test_missing_or_invalid_file(tmp_path):
    with pytest.raises(CaseError, match="built-in cases"):
        load_case(tmp_path / "nope.toml")
    with pytest.raises(CaseError, match="built-in cases"):
        builtin_case_text("no-such-case-xyz")
    bad = tmp_path / "bad.toml"
    bad.write_text("[mesh]\nsize = = 1\n")
    with pytest.raises(CaseError, match=r"^[^\n]*bad\.toml[^\n]*line 2"):
        load_case(bad)


def test_a_checkpoint_written_when_the_case_classes_were_in_dolfrag_config_still_loads(tmp_path):
    """The case's classes moved from the module dolfrag.config to the package dolfrag.case:
    a run checkpointed before still resumes (runner/checkpoint.py maps the old name)."""
    import pickle
    from dolfrag.runner import checkpoint
    case = load_case("sound-bar")
    old = pickle.dumps(case, protocol=0).replace(b"dolfrag.case.sections", b"dolfrag.config")
    assert b"dolfrag.config" in old
    (tmp_path / checkpoint.FOLDER).mkdir()
    (tmp_path / checkpoint.FOLDER / checkpoint.CASE).write_bytes(old)
    assert checkpoint.case_of(tmp_path) == case
