"""The `theta` step: Moreau-Jean theta-method, bulk and interface implicit. The step problem
(residual.py), its Newton and energy (integrator.py), the linear algebra
(solver/sparse_system.py)."""
from dolfrag.solver.theta.integrator import ConvergenceError, NewtonReport, Theta  # noqa: F401
