"""The explicit step with bars (time.bars_step, rebar/stable_step.py): the coupled
eigenvalue is the whole system's, and it lies between the Weyl bound and the bulk's own; a
checkpoint from before the key resumes with the step it was made with. The same step on 1,
2 and 3 ranks and a random partition: tests/test_slab.py."""
import pickle

import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.linalg import eigsh

from dolfrag import bulk
from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.runner import checkpoint

CASES = {"2D wall": ("wall-bending-clamped", []),
         "3D slab": ("slab-3d-bending", ["geometry.length=0.4", "geometry.width=0.4", "mesh.size=0.04"])}


def build(name, sets, rule):
    return Problem.build(load_case(name, [*sets, f"time.bars_step={rule}", "output.figures=false"]), MPI.COMM_SELF)


def whole_system_omega2(problem):
    """lambda_max(M^-1 (K_bulk + sum_j k_j C_j^T C_j)) over every component, formed from the
    bars' own chord operator C (cables.Rebars.C) instead of the gathered blocks."""
    bars, ops = problem.rebars, problem.bulk
    n = ops.K_cells.shape[0]
    C = bars.C[:, :n]
    k = np.repeat(bars.E_s * bars.area / bars.L, bars.d)
    scale = sp.diags(1 / np.sqrt(ops.m.x.array[:n]))
    A = scale @ (ops.K_cells.tocsr() + C.T @ sp.diags(k) @ C) @ scale
    return eigsh(A, k=1, which="LA", v0=np.ones(n), tol=0, return_eigenvectors=False)[0]


@pytest.mark.parametrize("name", CASES)
def test_coupled_step_is_the_whole_systems_and_lies_between_the_weyl_bound_and_the_bulks(name):
    case, sets = CASES[name]
    coupled, weyl = build(case, sets, "coupled"), build(case, sets, "weyl")
    # Lanczos to machine precision on the same operator assembled two ways: round-off
    assert coupled.dt_crit == pytest.approx(2 / np.sqrt(whole_system_omega2(coupled)), rel=1e-9)
    ops = coupled.bulk
    q = ops.K_cells.data.shape[1]
    with_bars_mass = bulk.stable_time_step(ops.K_cells.data, ops.m.x.array[:ops.K_cells.shape[0]].reshape(-1, q),
                                           MPI.COMM_SELF)
    # adding the bars' stiffness can only shorten the bulk's step; Weyl's sum bounds the
    # coupled eigenvalue from above (and Gershgorin the bars' alone)
    assert weyl.dt_crit <= coupled.dt_crit <= with_bars_mass * (1 + 1e-12)
    # measured: 1.28 and 1.23 times the Weyl step (the slab's is its bulk's own); a rule
    # that fell back to the bound would give 1
    assert coupled.dt_crit > 1.1 * weyl.dt_crit


def test_a_checkpoint_from_before_the_rule_resumes_with_the_weyl_step_it_was_made_with(tmp_path):
    case = load_case("wall-bending-clamped", [])
    object.__delattr__(case.time, "bars_step")  # as a Case pickled before the key existed
    (tmp_path / checkpoint.FOLDER).mkdir()
    (tmp_path / checkpoint.FOLDER / checkpoint.CASE).write_bytes(pickle.dumps(case))
    assert checkpoint.case_of(tmp_path).time.bars_step == "weyl"
    fresh = load_case("wall-bending-clamped", [])
    (tmp_path / checkpoint.FOLDER / checkpoint.CASE).write_bytes(pickle.dumps(fresh))
    assert checkpoint.case_of(tmp_path) == fresh
