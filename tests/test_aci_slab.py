"""The ACI 447/370 contest slab (aci-contest-slab): its case file says what the test's open
sources give, and validation/aci_slab.py reads a run's response as it says (on a history
written by hand, so that nothing is run)."""
import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT
from dolfrag import concrete, loads
from dolfrag.case import load_case

INCH, PSI = 0.0254, 6894.757  # m, Pa
SCRIPT = ROOT / "validation" / "aci_slab.py"


@pytest.fixture(scope="module")
def case():
    return load_case("aci-contest-slab")


def test_the_load_carries_the_stated_peak_and_impulse_over_its_duration(case):
    load = case.load
    # 344.74 kPa is 50 psi to five digits (6e-6 apart)
    assert load.peak == pytest.approx(50 * PSI, rel=1e-5)
    impulse = load.peak * load.duration * loads.friedlander_impulse_ratio(load.alpha)
    # 1,020 psi ms: alpha is given to four digits, which moves the impulse by 7e-5
    assert impulse == pytest.approx(1020 * PSI * 1e-3, rel=1e-4)


def test_the_strip_carries_the_slab_s_nine_bars_and_its_span_and_thickness(case):
    bar = np.pi * case.rebar.diameter**2 / 4  # m^2, a No. 3 bar (0.375 in)
    # steel per metre of the strip's depth: nine bars across the 33.75 in width. The lengths
    # are exact conversions of inches (round-off only)
    assert bar / case.rebar.spacing == pytest.approx(9 * np.pi * (0.375 * INCH) ** 2 / 4 / (33.75 * INCH),
                                                     rel=1e-12)
    assert (case.geometry.length, case.geometry.width) == pytest.approx((52 * INCH, 4 * INCH), rel=1e-12)
    # 496 MPa is 72 ksi to three digits (8.5e-4 apart)
    assert case.rebar.f_y == pytest.approx(72e3 * PSI, rel=1e-3)


def test_the_grade_s_mean_strength_is_the_nearest_to_the_measured_one(case):
    measured = 5400 * PSI / 1e6  # MPa
    f_cm = {name: f_ck + 8 for name, f_ck in concrete.GRADES.items()}
    assert min(f_cm, key=lambda name: abs(f_cm[name] - measured)) == case.material.grade


def _history(folder, t, w):
    folder.mkdir(parents=True)
    rows = "".join(f"{i},{ti},{wi},{i}\n" for i, (ti, wi) in enumerate(zip(t, w)))
    (folder / "history.csv").write_text("step,time_s,w_midspan_m,broken_links\n" + rows)


def test_the_script_reads_the_peak_and_the_deflection_where_the_record_ends(tmp_path):
    t = np.linspace(0.0, 0.08, 81)
    run, short = tmp_path / "convergence" / "aci-slab" / "run", tmp_path / "stiffer" / "aci-slab" / "short"
    _history(run, t, 0.1 * np.minimum(t / 0.03, 1.0) - 0.05 * np.maximum(t - 0.03, 0.0))
    _history(short, t[:41], 0.05 * t[:41] / 0.04)
    result = subprocess.run([sys.executable, str(SCRIPT), "--runs", str(run), str(short),
                             "--figure", str(tmp_path / "w.png")], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in result.stdout.splitlines() if line.startswith("| ")}
    # the run: largest 0.1 m at 30 ms (0.1 / 4.25 in = 0.93); at 70 ms 0.1 - 0.05 * 0.04 m
    assert rows["run"][:4] == ["100.0", "0.93", "30.0", "98.0"]
    assert rows["run"][6] == "–"  # no summary.json: no crack list
    # a run of another study is named after it; stopped at 40 ms: no value at 70 ms
    assert rows["stiffer, short"][3] == "–" and rows["stiffer, short"][7] == "40.0"
    assert (tmp_path / "w.png").stat().st_size > 0


def test_the_script_says_which_runs_it_lacks(tmp_path):
    result = subprocess.run([sys.executable, str(SCRIPT), "--runs", str(tmp_path / "none")],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "no history.csv" in result.stderr


def test_a_run_whose_exact_bars_turned_past_their_yield_says_so(case):
    from dolfrag.runner.reports.wall import turning_warning
    span = case.geometry.length
    # the exact bars' run of this case: 115 mm, 2 w / L = 0.17 rad, past sqrt(2 f_y / E_s) = 0.070
    exact = dataclasses.replace(case.rebar, kinematics="exact")
    line = turning_warning(exact, 0.115, span)
    assert line.startswith("dolfrag: warning:") and "0.17 rad" in line and "0.07 rad" in line
    assert turning_warning(exact, 0.04, span) is None  # 0.061 rad: below
    assert turning_warning(case.rebar, 0.4, span) is None  # small-strain bars read no rotation
