"""RC wall section (issue 5): scabbing against the 1D closed forms, where bending damages
first with clamped and simple supports, and rank independence."""
import json

import pytest

import dolfrag
from conftest import mpirun
from dolfrag.config import load_case

# A 0.2 m strip of the wall with rollers on its cut ends: uniaxial strain through the
# thickness, as at midspan of the full wall, where the supports are far (5 x fewer cells)
STRIP = ["geometry.length=0.2", "supports.clamped=[]", "supports.rollers=[\"left\", \"right\"]",
         "output.fields=0", "output.figures=false"]


@pytest.fixture(scope="module")
def scab_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("wall-scabbing")
    return dolfrag.run(load_case("wall-scabbing", STRIP), out, quiet=True), out


def test_scab_leaves_the_free_face_as_the_1d_theory_says(scab_run):
    wall = scab_run[0]["wall"]
    scab, expected = wall["scab"], wall["estimates"]
    assert scab is not None and scab["velocity_m_s"] > 0
    # 30 %: the bound. It covers the 1 us front spread over ~1 cell of 5 mm (the
    # dispersed front traps less momentum: measured -22 % on the velocity, -9 % on the
    # thickness) and the interface compliance (c_eff a few per cent below the estimate's c)
    assert scab["thickness_m"] == pytest.approx(expected["scab_thickness_m"], rel=0.3)
    assert scab["velocity_m_s"] == pytest.approx(expected["scab_velocity_m_s"], rel=0.3)
    assert scab["thickness_m"] < 0.03 - 0.005  # in front of the bars, 30 mm in


def test_wall_strip_gives_the_same_scab_on_two_ranks(scab_run, tmp_path):
    serial, _ = scab_run
    sets = [arg for item in STRIP for arg in ("--set", item)]
    mpirun(["-m", "dolfrag.cli", "run", "wall-scabbing", *sets, "--out", tmp_path, "--quiet"])
    parallel = json.loads((tmp_path / "summary.json").read_text())
    assert parallel["ranks"] == 2
    assert parallel["broken_links"] == serial["broken_links"]
    assert parallel["fragments"]["count"] == serial["fragments"]["count"]
    # the star solves are the same problems on either rank count: round-off only (the
    # Newton tolerance, 1e-10 of the step's momentum, bounds what a reordering can move)
    for key in ("thickness_m", "velocity_m_s", "mass_kg"):
        assert parallel["wall"]["scab"][key] == pytest.approx(serial["wall"]["scab"][key], rel=1e-6)
    assert parallel["rebar"]["peak_force_N"] == pytest.approx(serial["rebar"]["peak_force_N"], rel=1e-6)


def bending(tmp_path, supports, end):
    case = load_case(f"wall-bending-{supports}", [f"time.end={end}", "output.fields=0", "output.figures=false"])
    return dolfrag.run(case, tmp_path, quiet=True)["wall"]["damage_by_zone"]


def test_clamped_bending_breaks_the_support_zones_before_midspan(tmp_path):
    # clamped: support moment p L^2 / 12, twice midspan's; measured first breaks at the
    # supports 20.6 ms, at midspan 23.5 ms: stop in between
    zones = bending(tmp_path, "clamped", 0.022)
    assert zones["first"] == "supports"
    assert zones["midspan"]["first_break_s"] is None


def test_simple_bending_breaks_midspan_first(tmp_path):
    # simply supported: the largest moment, p L^2 / 8, is at midspan; it breaks at 18.3 ms
    zones = bending(tmp_path, "simple", 0.02)
    assert zones["first"] == "midspan"
    assert zones["supports"]["first_break_s"] is None
