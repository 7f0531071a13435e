"""Every built-in case with every interface law of the registry (interface/models.LAWS), as
short runs: each accepted pair ends with summary.json status "completed" (its reports and
observers ran, and its figures where draws_figures says), each refused pair is refused with
its reason. A law added to the registry joins the matrix by itself; it then needs its keys
in LAW_KEYS."""
import json
import math

import pytest
from mpi4py import MPI

import dolfrag
from conftest import mpirun
from dolfrag.case import CaseError, builtin_cases, load_case
from dolfrag.interface.models import LAWS

# The keys each law needs, and those it does not take, over any case's own: a strength
# where the case has none (the elastic bars), the concrete's G_F order for the
# energy-based laws, the reference paper's threshold values
NOT_COHESIVE = ["interface.sigma_c=", "interface.w=", "interface.G_c=", "interface.rate_effect=", "interface.b=",
                "interface.mu_i="]
LAW_KEYS = {
    "elastic": [*NOT_COHESIVE, "interface.mu="],
    "rccm": ["interface.G_c=", "interface.rate_effect="],
    "rccm_decoupled": ["interface.G_c=140", "interface.rate_effect=", "interface.b="],
    "threshold": [*NOT_COHESIVE, "interface.R_c=4e6", "interface.W_eth=1e-5"],
    "linear_softening": ["interface.G_c=140", "interface.b=", "interface.mu_i="],
}
# The cases without a strength of their own (elastic wave checks) get the reference paper's
STRENGTHLESS = {"sound-bar", "two-material-bar"}
# The pairs a case refuses, and why (the error names it)
REFUSED = {
    ("expanding-bar", "elastic"): "inverted star blocks cannot move prescribed components",
}
# The cases whose own tests run on 2 ranks run the matrix on 2 ranks too
TWO_RANKS = {"bunker-h2", "expanding-bar", "spall-bar", "sound-bar", "shpb-be16"}
# A coarser mesh where the case's own takes a minute to build and step (the laws and the
# reports do not depend on the mesh size)
COARSER = {"bunker-two-rooms": ["mesh.size=0.2"], "chiquito-slab-s5": ["mesh.size=0.15"],
           "mendonca-slab": ["mesh.size=0.08"]}
# A run of a few explicit steps: the reports, observers and figures all run at its end. The
# step of these meshes is 0.05-0.1 of a P-wave's time across mesh.size (their smallest cells
# set it): DT_SHARE of it gives 3-6 steps
STEPS, DT_SHARE = 3, 0.1


def draws_figures(name, law):
    """Whether the pair draws its figures. The figures read any law's state alike
    (post/figures.py), and drawing them is most of a short run: 7.5 of 15 s for
    slab-3d-scabbing (cProfile, off-screen VTK). So each case draws them with one law, the
    laws taking turns through the cases: every case and every law draws
    (test_every_law_draws_its_figures_in_2d_and_3d)."""
    accepted = [other for other in LAWS if (name, other) not in REFUSED]
    return accepted[builtin_cases().index(name) % len(accepted)] == law


def keys(name, law):
    """The --set items of the pair (case ``name``, ``law``), as a short run."""
    case = load_case(name, COARSER.get(name, []))
    strength = ["interface.sigma_c=4e6"] if name in STRENGTHLESS and law not in ("elastic", "threshold") else []
    end = STEPS * DT_SHARE * case.mesh.size / math.sqrt(case.material.E / case.material.rho)  # s
    return [f"interface.law={law}", *LAW_KEYS[law], *strength, *COARSER.get(name, []), f"time.end={end:.3g}",
            "output.fields=1", f"output.figures={str(draws_figures(name, law)).lower()}"]


PAIRS = [(name, law) for name in builtin_cases() for law in LAWS]


def test_every_law_has_its_keys():
    assert set(LAW_KEYS) == set(LAWS), "a new law needs its keys in LAW_KEYS"


def test_every_law_draws_its_figures_in_2d_and_3d():
    drawn = {(law, load_case(name).geometry.tdim) for name, law in PAIRS
             if (name, law) not in REFUSED and draws_figures(name, law)}
    assert drawn == {(law, tdim) for law in LAWS for tdim in (2, 3)}


@pytest.mark.parametrize("name,law", [p for p in PAIRS if p in REFUSED])
def test_a_refused_pair_says_why(name, law):
    with pytest.raises(CaseError, match=REFUSED[name, law]):
        load_case(name, keys(name, law))


@pytest.mark.slow
@pytest.mark.parametrize("name,law", [p for p in PAIRS if p not in REFUSED and p[0] not in TWO_RANKS])
def test_every_law_completes_every_case(name, law, tmp_path):
    summary = dolfrag.run(load_case(name, keys(name, law)), tmp_path, quiet=True, comm=MPI.COMM_SELF)
    assert summary["status"] == "completed", summary.get("report_errors")
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "completed"
    assert summary["steps_done"] == summary["steps"] >= 1


@pytest.mark.mpi
def test_every_law_completes_the_cases_run_on_two_ranks(tmp_path):
    mpirun(["tests/mpi_law_matrix.py", tmp_path, *sorted(TWO_RANKS)], n=2)
    statuses = json.loads((tmp_path / "statuses.json").read_text())
    expected = {name: {law: ["completed", 2] for law in LAWS if (name, law) not in REFUSED} for name in TWO_RANKS}
    assert statuses == expected
