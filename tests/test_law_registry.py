"""The registry of interface laws (interface/models.LAWS): each law's model built from a
case, its capability flags as the config rules and the integrators use them, and the
tensile strength post-processing reads against the peak of the law's own traction."""
import numpy as np
import pytest

import dolfrag
from dolfrag.case import CaseError, load_case
from dolfrag.interface import laws, models

E, SIZE = 35e9, 0.005  # Pa, m: C_N = 10 E / h = 7e13 Pa/m
PARAMETERS = {
    "elastic": [],
    "rccm": ["interface.sigma_c=4e6"],
    "rccm_decoupled": ["interface.sigma_c=4e6", "interface.G_c=100"],
    "threshold": ["interface.R_c=4e6", "interface.W_eth=1e-6"],
    "linear_softening": ["interface.sigma_c=4e6", "interface.G_c=100"],
}
MODELS = {"elastic": models.Elastic, "rccm": models.Rccm, "rccm_decoupled": models.RccmDecoupled,
          "threshold": models.Threshold, "linear_softening": models.LinearSoftening}


def case(name, more=()):
    return load_case("sound-bar", [f"interface.law={name}", *PARAMETERS[name], f"mesh.size={SIZE}", *more])


def peak_traction(name, interface, C_N, C_T):
    """The largest normal traction (Pa) of the law's pure function along a slow opening."""
    # m: geometric steps of 0.35 % from 1e-10 m (the RCCM peak is at u0 = sigma_c / C_N = 5.7e-8 m)
    g = np.r_[0.0, np.geomspace(1e-10, 1e-4, 4000)][:, None]
    g_T = np.zeros((len(g), 1, 1))
    step = {"rccm": lambda gN, gT, s: laws.rccm(gN, gT, s, C_N, C_T, interface.adhesion_energy(C_N)),
            "rccm_decoupled": lambda gN, gT, s: laws.rccm_decoupled(gN, gT, s, C_N, C_T, interface.sigma_c,
                                                                    interface.G_c),
            "linear_softening": lambda gN, gT, s: laws.linear_softening(gN, gT, s, interface.sigma_c, interface.G_c),
            "threshold": lambda gN, gT, s: laws.threshold(gN, s, interface.R_c, interface.W_eth)}[name]
    start = np.zeros(1, dtype=bool) if name == "threshold" else (np.zeros(1) if name == "linear_softening"
                                                                  else np.ones(1))
    return laws.drive(step, g, g_T, start)[0].max()


@pytest.mark.parametrize("name", list(models.LAWS))
def test_each_law_builds_its_model_and_states_its_strength(name):
    c = case(name)
    law = models.law(c.interface)
    model = models.build(c.interface, E, SIZE, 7, h=1e-8)
    assert type(model) is MODELS[name] and law.breakable == (name != "elastic")
    assert law.rigid == (model.C_N is None)  # a rigid law has no springs
    C_N, C_T = c.interface.stiffness(E, SIZE)
    strength = law.tensile_strength(c.interface, C_N)
    if law.springs:
        assert strength is None
    else:
        # the drive resolves the peak to 0.35 % of the opening, so the traction on the rising
        # branch of the springs to 0.35 %; a wrong rule (sigma_c for sqrt(C_N w), w for
        # sigma_c^2 / C_N) is off by far more
        assert peak_traction(name, c.interface, C_N, C_T) == pytest.approx(strength, rel=0.01)


@pytest.mark.parametrize("name", list(models.LAWS))
def test_the_flags_decide_what_the_case_may_ask(name):
    law = models.LAWS[name]
    theta = ["time.scheme=theta"]
    if law.theta:
        case(name, theta)
    else:
        with pytest.raises(CaseError, match="time.scheme = 'theta'"):
            case(name, theta)
    stretch = ["load.kind=stretch", "load.strain_rate=100", "load.boundary=", "load.signal=", "load.peak=",
               "load.rise=", "load.duration=", 'supports.rollers=[]']
    if law.springs:
        with pytest.raises(CaseError, match="load.kind = 'stretch'"):
            case(name, stretch)
    else:
        case(name, stretch)


def _toy_rules(interface, C_N):
    return None if interface.sigma_c is not None else "interface.sigma_c: the toy law needs it, Pa"


# The toy law: the reference paper's RCCM given by its strength alone (w = sigma_c^2 / C_N),
# without friction, viscosity or internal friction; one entry, nothing else
TOY = models.Law(build=lambda i, n, C_N, C_T, h, k: models.Rccm(n, C_N, C_T, i.sigma_c**2 / C_N, h=h),
                 keys=("sigma_c",), rules=_toy_rules, breakable=True, theta=True)
# the sound bar's 1 MPa pulse comes back from the free end as 1 MPa of tension: a strength
# of 0.5 MPa breaks it there; a coarser mesh keeps the run short
SPALL = ["interface.sigma_c=5e5", "mesh.size=0.004", "output.fields=0", "output.figures=false"]


def test_a_law_added_as_one_registry_entry_brings_its_keys_and_rules_and_runs(tmp_path, monkeypatch):
    monkeypatch.setitem(models.LAWS, "toy", TOY)
    toy = load_case("sound-bar", ["interface.law=toy", *SPALL])
    assert toy.interface.sigma_c == 5e5
    with pytest.raises(CaseError, match="interface.mu = 0.5: only allowed when interface.law is 'rccm' or"):
        load_case("sound-bar", ["interface.law=toy", *SPALL, "interface.mu=0.5"])
    with pytest.raises(CaseError, match="the toy law needs it"):
        load_case("sound-bar", ["interface.law=toy"])
    load_case("sound-bar", ["interface.law=toy", *SPALL, "time.scheme=theta"])  # its theta flag
    ran = dolfrag.run(toy, tmp_path / "toy", quiet=True)
    # RCCM with the keys the toy law leaves out at their defaults (0) is the same law: the
    # same arithmetic, so the same numbers
    rccm = dolfrag.run(load_case("sound-bar", ["interface.law=rccm", *SPALL]), tmp_path / "rccm", quiet=True)
    assert ran["status"] == "completed"
    assert ran["broken_links"] > 0
    assert ran["broken_links"] == rccm["broken_links"]
    assert ran["energies_J"] == rccm["energies_J"]
