"""The compiled elastic star step against the global linear system it splits."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from mpi4py import MPI

from dolfrag.case import load_case
from dolfrag.problem import Problem
from dolfrag.runner.driver import integrator

BOX = ["geometry.kind=box", "geometry.length=0.03", "geometry.thickness=0.01",
       'supports.rollers=["bottom","top","front","back"]']


@pytest.mark.parametrize("shape", [["mesh.size=0.004"], ["mesh.size=0.005", *BOX]], ids=["2d", "3d"])
def test_star_step_solves_the_global_system(shape):
    """dv = h A^-1 (f - K_i u), A = M + h^2/4 K_i with K_i = B^T diag(w D) B over every
    link, solved globally by a sparse LU: the stars split this system exactly (each link
    joins two copies of one vertex), so the compiled loop over the stars must agree to
    round-off, prescribed components (the rollers) staying at 0."""
    problem = Problem.build(load_case("sound-bar", ["time.end=1e-6", *shape]), MPI.COMM_SELF)
    integ = integrator(problem)
    step, jump = integ.interface, integ.jump
    d, h, n = jump.gdim, integ.h, len(integ.m)
    blocks = jump.tangent_blocks(step.model.C_N, step.model.C_T)
    D = sp.bsr_matrix((blocks, np.arange(len(blocks)), np.arange(len(blocks) + 1)), shape=(d * len(blocks),) * 2)
    K_i = (jump.B.T @ D @ jump.B).tocsc()
    rng = np.random.default_rng(7)
    f, u = rng.standard_normal(n), 1e-6 * rng.standard_normal(n)
    free = ~step.stars.constrained
    A = (sp.diags(integ.m) + h * h / 4 * K_i)[free][:, free]
    expected = np.zeros(n)
    expected[free] = spla.spsolve(A.tocsc(), h * (f - K_i @ u)[free])
    dv = np.zeros(n)
    step.solve(f, u, None, dv)
    assert step.stars.constrained.any()  # supported components are in the check
    # the inverses come from LAPACK on blocks of condition ~1e2-1e3 (mass against h^2/4
    # times the springs): 1e-10 of the largest is round-off with a margin of 100
    assert np.abs(dv - expected).max() <= 1e-10 * np.abs(expected).max()
