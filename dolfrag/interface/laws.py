"""Interface laws, vectorised over links. Pure numpy: no PETSc, no dolfinx, no MPI.

Sign convention (interface/links.py): g = u_B - u_A, g_N = g . n > 0 in opening,
tractions positive in tension, acting on B (their opposite on A).
"""
import numpy as np


def elastic(g_N, g_T, C_N, C_T):
    """Linear interface springs (the seed's interface elasticity, C = 10 E / h by default).

    g_N (n,) m: normal jump.            C_N Pa/m: normal stiffness.
    g_T (n, d-1) m: tangential jump.    C_T Pa/m: tangential stiffness.

    r_N = C_N g_N,  r_T = C_T g_T;  stored energy density psi = (C_N g_N^2 + C_T |g_T|^2) / 2.

    Returns r_N (n,) Pa, r_T (n, d-1) Pa, and the tangent stiffnesses dr_N/dg_N, dr_T/dg_T
    (Pa/m, broadcastable to (n,)).
    """
    return C_N * g_N, C_T * g_T, C_N, C_T


def elastic_energy(g_N, g_T, C_N, C_T):
    """Stored energy per unit interface area (J/m^2), (n,)."""
    return 0.5 * (C_N * g_N**2 + C_T * np.sum(g_T**2, axis=-1))
