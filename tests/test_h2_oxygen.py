"""Hydrogen in oxygen (dolfrag/loads/mixture.py, gas.py, docs/loads.md "The oxidiser"): the CJ
detonation of stoichiometric H2-O2 against NASA CEA's published one, the thermodynamic data
past their fitted range against NASA Glenn's, the mixture's spelling against air's, the
cache key, the built-in cases' load, `dolfrag loads`, and the same load on 1 and 2 ranks."""
import json
import math
import re
from dataclasses import asdict

import numpy as np
import pytest

from conftest import dolfrag_cli, mpirun
from dolfrag import loads
from dolfrag.case import load_case
from dolfrag.loads import gas
from dolfrag.loads.mixture import Mixture, composition

ATM = 101325.0      # Pa
BAR = 1e5           # Pa
OXYGEN = Mixture(2 / 3, "oxygen")  # 2 H2 + O2
# NASA CEA's CJ detonation of stoichiometric H2-O2 at 1 bar and 298.15 K: McBride & Gordon,
# NASA RP-1311 part II (1996), example 6, first column of "DETONATION PROPERTIES OF AN IDEAL
# REACTING GAS" (also nasa/cea's test/main_interface/reference_output/example6.out): DET VEL,
# P/P1, T, RHO/RHO1
CEA = {"D_m_s": 2835.53, "P_Pa": 18.7684 * BAR, "T_K": 3674.28, "density_ratio": 1.83868}


@pytest.fixture(autouse=True)
def cache(tmp_path_factory, monkeypatch):
    """One cache folder for the module, this process's memory of explosions emptied for each test."""
    folder = tmp_path_factory.getbasetemp() / "h2o2-cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(folder))
    monkeypatch.setattr(gas, "_KNOWN", {})
    return folder / "dolfrag"


@pytest.fixture(scope="module")
def at_one_bar():
    return gas.compute(OXYGEN, 298.15, BAR)


def test_cj_detonation_of_stoichiometric_h2_o2_is_nasa_cea_example_6(at_one_bar):
    found = at_one_bar
    # Cantera with NASA Glenn's own data (nasa_gas.yaml) lands as far from CEA as GRI-Mech does
    # (2.5e-4, 5.8e-4, 7.4e-4 against 2.6e-4, 6.1e-4, 7.5e-4 measured): the difference is the
    # data's revision (CEA's thermo.inp of 2004), not this computation; 3-4 times that allowed
    assert found.D_CJ_m_s == pytest.approx(CEA["D_m_s"], rel=1e-3)
    assert found.P_CJ_Pa == pytest.approx(CEA["P_Pa"], rel=2e-3)
    assert found.T_CJ_K == pytest.approx(CEA["T_K"], rel=2e-3)
    # mass across the front: rho2 / rho1 = D / (D - u_CJ); measured 1.5e-4 apart
    assert found.D_CJ_m_s / (found.D_CJ_m_s - found.u_CJ_m_s) == pytest.approx(CEA["density_ratio"], rel=1e-3)


def test_reflected_pressure_and_taylor_plateau_of_h2_o2_within_the_usual_estimates(at_one_bar):
    """As for H2-air (tests/test_h2_load.py): reflected 2.3-2.6 P_CJ, plateau 0.34-0.4 P_CJ,
    the plateau below P_AICC below P_CJ."""
    found = at_one_bar
    assert 2.3 < found.P_reflected_Pa / found.P_CJ_Pa < 2.6
    assert 0.34 < found.P_Taylor_Pa / found.P_CJ_Pa < 0.40
    assert found.P_Taylor_Pa < found.P_AICC_Pa < found.P_CJ_Pa


@pytest.mark.slow
def test_gri_mech_past_3500_K_gives_the_numbers_of_nasa_glenn_data_fitted_to_6000_K(monkeypatch):
    """The hottest mixture allowed (stoichiometric H2-O2 at the coldest and densest initial
    state, 250 K and 2 bar: reflected gas at 4,184 K) computed with GRI-Mech's fits (to 3500
    K) and with NASA Glenn's (nasa_gas.yaml, bundled with Cantera, fitted to 6000 K)."""
    extrapolated = gas.compute(OXYGEN, 250.0, 2e5)
    monkeypatch.setattr(gas, "MECHANISM", "nasa_gas.yaml")
    fitted = gas.compute(OXYGEN, 250.0, 2e5)
    assert extrapolated.T_reflected_K > 4000.0  # well past the end of GRI-Mech's fits
    # two fits of the same tabulated data: measured 2.1e-4 apart at most (T_reflected)
    for name, value in asdict(extrapolated).items():
        assert value == pytest.approx(getattr(fitted, name), rel=5e-4), name


def test_stoichiometric_oxygen_diluted_by_air_nitrogen_is_stoichiometric_air():
    diluted = Mixture(2 / 3, "oxygen", "N2", 3.76 / 6.76)
    air = Mixture(2 / 6.76)
    assert composition(diluted) == pytest.approx(composition(air), abs=1e-15)
    # the same mixture spelled two ways: the same equilibria up to the composition's round-off,
    # measured <= 3e-11 apart; the Taylor plateau 4e-9 (its adaptive ODE steps, rtol 1e-10,
    # move with that round-off): 1e-9 and 1e-7
    spelled = asdict(gas.compute(diluted, 293.15, ATM))
    for name, value in asdict(gas.compute(air, 293.15, ATM)).items():
        assert spelled[name] == pytest.approx(value, rel=1e-7 if name == "P_Taylor_Pa" else 1e-9), name


def test_argon_takes_part_and_burns_hotter_than_nitrogen():
    argon, nitrogen = Mixture(2 / 3, "oxygen", "Ar", 0.5), Mixture(2 / 3, "oxygen", "N2", 0.5)
    names = gas.unburnt(argon, 293.15, ATM).species_names
    assert "AR" in names and not any("N" in n for n in names if n != "AR")  # no nitrogen species
    assert gas.unburnt(OXYGEN, 293.15, ATM).n_species == 8  # H2, H, O, O2, OH, H2O, HO2, H2O2
    # the same heat in a diluent of lower heat capacity (monatomic: 3R/2 against 5R/2 at constant volume)
    assert gas.compute(argon, 293.15, ATM).T_AICC_K > gas.compute(nitrogen, 293.15, ATM).T_AICC_K + 200


def test_the_cache_key_holds_the_oxidiser_and_the_diluent():
    keys = [gas.cache_key(m, 293.15, ATM) for m in
            (Mixture(0.3), Mixture(0.3, "oxygen"), Mixture(0.5, "oxygen", "N2", 0.2), Mixture(0.5, "oxygen", "Ar", 0.2))]
    assert len({gas.cache_file(k) for k in keys}) == len(keys)
    assert keys[1]["oxidizer"] == "oxygen" and keys[3]["diluent"] == "Ar" and keys[3]["diluent_fraction"] == 0.2


# ---------------------------------------------------------------- the built-in cases
@pytest.mark.parametrize("name", ["wall-h2o2-detonation", "bunker-h2o2"])
def test_builtin_oxygen_cases_load_the_reflected_spike_of_stoichiometric_h2_o2(name):
    load = load_case(name).load
    assert loads.h2_mixture(load) == Mixture(0.667, "oxygen", "N2", 0.0)
    state = gas.explosion(loads.h2_mixture(load), load.T0, load.p0)
    p = loads.signal(loads.applied(load))
    assert p(0.0) == pytest.approx(state.P_reflected_Pa - load.p0, rel=1e-12)
    # ten decay times L / D_CJ later the spike's remainder, e^-10 (P_r - P_q), is 2e-3 of the
    # AICC plateau P_q about which the reverberations swing by at most 0.3 P_q
    late = 10 * load.room_length / state.D_CJ_m_s
    plateau = (state.P_AICC_Pa - load.p0) * (1 - late / load.duration)
    assert 0.7 * plateau < p(late) < 1.31 * plateau


def test_loads_command_prints_the_h2_o2_states_beside_nasa_cea(tmp_path):
    result = dolfrag_cli("loads", "wall-h2o2-detonation", "--out", tmp_path / "p.png")
    assert result.returncode == 0, result.stderr
    values = {k: float(v) for k, v in re.findall(r"^(\w+) = (\S+)", result.stdout, flags=re.M)}
    state = gas.explosion(Mixture(0.667, "oxygen"), 293.15, ATM)
    for name in ("P_AICC_Pa", "D_CJ_m_s", "P_CJ_Pa", "T_CJ_K", "P_reflected_Pa", "P_Taylor_Pa"):
        assert values[name] == pytest.approx(getattr(state, name), rel=1e-5), name  # printed to 6 digits
    assert "H2-oxygen" in result.stdout and "NASA CEA, published 2835.5 m/s" in result.stdout


@pytest.mark.mpi
def test_one_and_two_ranks_apply_the_same_h2_o2_load(tmp_path, cache):
    """tests/test_h2_load.py's 1-vs-2-rank run of the sound bar under a detonation in a 2 cm
    'room', the mixture argon-diluted hydrogen-oxygen (fresh: 300 K), the 2-rank run first so
    that its rank 0 computes and broadcasts."""
    sets = ["load.signal=h2-air", "load.peak=", "load.rise=", "load.h2_fraction=0.6", "load.oxidizer=oxygen",
            "load.diluent=Ar", "load.diluent_fraction=0.3", "load.regime=detonation", "load.T0=300",
            "load.room_length=0.02", "load.duration=1e-4", "mesh.size=0.004", "time.end=1e-5", "output.every=1",
            "output.fields=0", "output.figures=false"]
    args = ["-m", "dolfrag.cli", "run", "sound-bar", "--quiet", *(x for s in sets for x in ("--set", s))]
    mixture = Mixture(0.6, "oxygen", "Ar", 0.3)
    assert not gas.cache_file(gas.cache_key(mixture, 300.0, ATM)).exists()
    mpirun([*args, "--out", tmp_path / "two"], n=2)
    mpirun([*args, "--out", tmp_path / "one"], n=1)
    rows = {r: np.genfromtxt(tmp_path / r / "history.csv", delimiter=",", names=True) for r in ("one", "two")}
    np.testing.assert_array_equal(rows["one"]["load_Pa"], rows["two"]["load_Pa"])
    state = gas.explosion(mixture, 300.0, ATM)
    assert rows["one"]["load_Pa"][0] == pytest.approx(state.P_reflected_Pa - ATM, rel=0.05)  # the spike
    assert np.ptp(rows["one"]["load_Pa"]) > 0.3 * rows["one"]["load_Pa"][0]  # it decays over the run
    for r in ("one", "two"):
        block = json.loads((tmp_path / r / "summary.json").read_text())["load"]["h2_air"]
        assert block["D_CJ_m_s"] == state.D_CJ_m_s and block["oxidizer"] == "oxygen" and block["diluent"] == "Ar"
        assert math.isfinite(block["P_Taylor_Pa"])
