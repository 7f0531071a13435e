"""time.mass_scaling: the cells below the target step get exactly the mass that brings them
to it, the others nothing; a run keeps its energy balance; bad uses are refused.
(1, 2 and 3 ranks: tests/test_slab.py runs its reduced slab with it.)"""
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

import dolfrag
from conftest import box, dolfrag_cli
from dolfrag import bulk, mass_scaling, mesh, space as spaces
from dolfrag.case import load_case
from dolfrag.reference import analytic

CONCRETE = SimpleNamespace(E=30e9, nu=0.2, rho=2400.0, hypothesis="plane_strain")
C_P = analytic.wave_speed(analytic.p_wave_modulus(CONCRETE.E, CONCRETE.nu), CONCRETE.rho)  # m/s
PANEL, H = box(3.0, 2.0, 0.2), 0.1  # gmsh's default mesh: 14 cells below 0.2 h / c_p (measured)


@pytest.fixture(scope="module")
def panel():
    domain = mesh.build(PANEL, H, MPI.COMM_SELF)
    space = spaces.create(domain)
    case = SimpleNamespace(material=CONCRETE, materials={}, mesh=SimpleNamespace(size=H))
    plain, scaled = bulk.assemble(space, domain, case), bulk.assemble(space, domain, case, 0.2)
    Ke, idx = bulk.cell_matrices(plain.K, space)
    return plain, scaled, Ke, idx


def test_the_scaled_cells_reach_the_target_step_and_the_others_keep_their_mass(panel):
    plain, scaled, Ke, idx = panel
    target = 0.2 * H / C_P
    before = bulk.cell_steps(Ke, plain.m.x.array[idx])
    after = bulk.cell_steps(Ke, scaled.m.x.array[idx])
    below = before < target
    assert 0 < below.sum() < 0.01 * len(before)  # a few poor cells
    # omega^2 scales as 1 / mass: the scaled cells land on the target to round-off (the
    # 12 x 12 eigenvalue solve's, ~1e-15; 1e-10 leaves room, a wrong factor is O(1))
    assert after[below] == pytest.approx(target, rel=1e-10)
    assert np.array_equal(scaled.m.x.array[idx][~below], plain.m.x.array[idx][~below])
    assert scaled.dt_bulk == pytest.approx(target, rel=1e-10) and plain.dt_bulk < target
    block = scaled.mass_scaling
    assert block["cells"] == below.sum()
    added = (scaled.m.x.array[idx] - plain.m.x.array[idx]).sum() / 3  # each vertex's mass once per axis
    # the same sums in another order, and lumped masses that add up to rho V exactly: round-off
    assert block["added_mass_kg"] == pytest.approx(added, rel=1e-12)
    assert block["mass_kg"] == pytest.approx(2400.0 * 3.0 * 2.0 * 0.2, rel=1e-12)


def test_the_warning_names_the_added_share():
    assert mass_scaling.warning(0.5, 100.0) is None  # 0.5 %: below ADDED_SHARE
    line = mass_scaling.warning(2.0, 100.0)
    assert "2.0%" in line and "time.mass_scaling" in line and "\n" not in line


def test_a_run_with_mass_scaling_keeps_its_energy_balance_and_reports_the_added_mass(tmp_path):
    """The 3D sound bar's box at 8 mm, its steps 0.9 x 0.3 h / c_p: the heavier cells are
    ordinary mass to the scheme, so its discrete energy still balances to round-off."""
    sets = ["geometry.kind=box", "geometry.thickness=0.02", "mesh.size=0.008", "output.fields=0",
            "output.figures=false", "time.end=4e-5"]
    plain = dolfrag.run(load_case("sound-bar", sets), tmp_path / "plain", quiet=True)
    scaled = dolfrag.run(load_case("sound-bar", [*sets, "time.mass_scaling=0.3"]), tmp_path / "scaled", quiet=True)
    block = scaled["mass_scaling"]
    assert block["cells"] > 0 and 0 < block["added_mass_kg"] < 0.01 * block["mass_kg"]
    assert scaled["dt_crit_s"] > plain["dt_crit_s"] and scaled["steps"] < plain["steps"]
    # the round-off bound of test_sound_bar's energy balance
    assert scaled["balance_error_relative"] < 1e-10
    assert "mass_scaling" not in plain


def test_mass_scaling_is_refused_under_theta_and_out_of_range():
    for value, extra in (("0.3", ["--set", "time.scheme=theta"]), ("0", []), ("1.5", [])):
        result = dolfrag_cli("run", "sound-bar", "--set", f"time.mass_scaling={value}", *extra, "--out", "/dev/null/x")
        assert result.returncode == 2, result.stderr
        assert "time.mass_scaling" in result.stderr and len(result.stderr.strip().splitlines()) == 1
