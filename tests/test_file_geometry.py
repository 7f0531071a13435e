"""The built-in case on an imported gmsh file (two-material-bar, meshes/bar-two-materials.geo),
shortened: both material groups take their own density, the pulse is causal, energy holds."""
import json

import numpy as np
import pytest

from conftest import dolfrag_cli
from dolfrag.reference import analytic
from dolfrag.case import load_case


def test_two_material_bar_from_a_geo_file_runs(tmp_path):
    out = tmp_path / "out"
    result = dolfrag_cli("run", "two-material-bar", "--out", out, "--quiet", "--set", "mesh.size=0.01",
                         "--set", "output.figures=false", "--set", "output.fields=0")
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    case = load_case("two-material-bar")
    concrete, steel = case.material, case.materials["steel"]
    # 0.1 m of concrete and 0.2 m of steel, 0.05 m wide (the .geo): kg per metre of depth
    assert sum(summary["fragments"]["mass"]) == pytest.approx(
        concrete.rho * 0.1 * 0.05 + steel.rho * 0.2 * 0.05, rel=1e-12)
    assert summary["balance_error_relative"] < 1e-12  # imex conserves energy to round-off
    history = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    t, v = history["time_s"], history["vx_right_m_s"]
    arrival = t[np.argmax(v >= v.max() / 2)]
    # no faster than the bulk P-waves without the springs' compliance (measured: 82 us)
    c_concrete, c_steel = (analytic.wave_speed(analytic.p_wave_modulus(m.E, m.nu), m.rho) for m in (concrete, steel))
    assert arrival > 0.1 / c_concrete + 0.2 / c_steel + case.load.rise / 2
    assert v.max() > 0  # the pulse arrived within time.end
