"""The registry of interface laws (interface/models.LAWS): each law's model built from a
case, its capability flags as the config rules and the integrators use them, and the
tensile strength post-processing reads against the peak of the law's own traction."""
import numpy as np
import pytest

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
    assert type(model) is MODELS[name] and model.can_break == law.breakable
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
