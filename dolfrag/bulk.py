"""Bulk elasticity on the DG-P1 space: stiffness K and lumped (diagonal) mass M.

Linear isotropic elasticity, per material group, in plane strain, plane stress
(unit thickness: forces per metre of depth) or 3D. With a discontinuous space K is
block-diagonal, one (gdim+1)·gdim square block per cell. Units: E in Pa, rho in
kg/m^3, so K in N/m and M in kg.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import ufl
from mpi4py import MPI

from dolfrag import compat, mass_scaling
from dolfrag.case import CaseError


@dataclass
class Bulk:
    """K: assembled PETSc matrix (owned rows). K_cells: the same operator as a scipy
    block-sparse matrix of the owned cells' blocks on the owned dof components, applied
    in the time loop (2.3x faster than the AIJ product, measured). m: Function, lumped
    mass of every dof component (kg), owned and ghost values set. dt_bulk: stable
    central-difference step of the bulk alone (s), the same on every rank (the run's,
    with bars and viscosity, is problem.Problem.dt_crit); with mass scaling (mass_scaling.py)
    m and dt_bulk are the scaled ones."""
    K: object
    K_cells: sp.bsr_matrix
    m: object
    dt_bulk: float
    mass_scaling: dict | None = None  # time.mass_scaling's cells, added and total mass (kg), all ranks


def material_fields(space, domain, default, groups):
    """DG0 fields (lam, mu, rho) from the cell tags; groups: name -> case.Material
    overriding ``default`` for the cells of that physical group."""
    Q = compat.dg0_space(space.mesh)
    lam, mu, rho = (compat.Function(Q) for _ in range(3))
    n_cells = len(space.cell_dofs)
    E = np.full(n_cells, default.E)
    nu = np.full(n_cells, default.nu)
    dens = np.full(n_cells, default.rho)
    tags = np.full(n_cells, -1, dtype=np.int32)
    tags[domain.cell_tags.indices] = domain.cell_tags.values
    for name, mat in groups.items():
        if name not in domain.materials:
            raise CaseError(f"materials.{name}: not a material group of the mesh; groups: "
                            f"{', '.join(sorted(domain.materials)) or 'none'}")
        cells = tags == domain.materials[name]
        E[cells], nu[cells], dens[cells] = mat.E, mat.nu, mat.rho
    mu_c = E / (2 * (1 + nu))
    lam_c = E * nu / ((1 + nu) * (1 - 2 * nu))
    if space.gdim == 2 and default.hypothesis == "plane_stress":
        lam_c = 2 * lam_c * mu_c / (lam_c + 2 * mu_c)
    cell_of_dof = compat.cell_dofs(Q)[:, 0]
    for f, values in ((lam, lam_c), (mu, mu_c), (rho, dens)):
        f.x.array[cell_of_dof] = values
    return lam, mu, rho


def stiffness_form(V, lam, mu):
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    eps = lambda z: ufl.sym(ufl.grad(z))  # noqa: E731
    sigma = 2 * mu * eps(u) + lam * ufl.tr(eps(u)) * ufl.Identity(len(u))
    return ufl.inner(sigma, eps(w)) * ufl.dx


def lumped_mass_form(V, rho):
    w = ufl.TestFunction(V)
    ones = ufl.as_vector([1.0] * V.mesh.geometry.dim)
    return rho * ufl.inner(ones, w) * ufl.dx(metadata=compat.vertex_quadrature())


def cell_matrices(K, space):
    """Per-cell stiffness blocks (n_owned_cells, q, q) and their flat dof indices (n, q),
    q = (gdim+1)·gdim, read from the owned rows of the block-diagonal K."""
    indptr, cols, vals = K.getValuesCSR()
    q = space.cell_dofs.shape[1] * space.gdim
    if np.any(np.diff(indptr) != q):
        raise RuntimeError("K is not block-diagonal with one full block per cell")
    start = K.getOwnershipRange()[0]
    idx = np.sort(space.components(space.cell_dofs[:space.n_owned_cells]), axis=1)
    rows_cols = cols.reshape(-1, q) - start
    assert np.array_equal(rows_cols[idx], np.broadcast_to(idx[:, None, :], idx.shape + (q,)))
    return vals.reshape(-1, q)[idx], idx


def cell_steps(Ke, me):
    """Each cell's own central-difference limit 2/omega_e (s): omega_e^2 the largest
    eigenvalue of Ke x = omega^2 diag(me) x (Ke (n, q, q) in N/m, me (n, q) in kg)."""
    s = 1 / np.sqrt(me)
    return 2 / np.sqrt(np.linalg.eigvalsh(s[:, :, None] * Ke * s[:, None, :])[:, -1])


def stable_time_step(Ke, me, comm):
    """Central-difference limit 2/omega_max of the bulk alone (s). With K block-diagonal
    and M diagonal, omega_max^2 is the largest eigenvalue of the cell problems, so the
    shortest cell step is exact. Collective."""
    return comm.allreduce(cell_steps(Ke, me).min(initial=np.inf), op=MPI.MIN)


def scale_mass(Ke, me, p_modulus, rho, length, gdim, comm):
    """time.mass_scaling (mass_scaling.py) on the owned cells, in place on me (n, q) (kg,
    each vertex's mass once per component): each cell's mass times the factor that brings
    its step up to length / c_p, with p_modulus = lambda + 2 mu (Pa) and rho (kg/m^3) per
    cell and length = F h (m). Returns the summary block: the cells scaled, the added and
    the total mass (kg, kg/m in 2D). Collective."""
    factor = mass_scaling.factors(cell_steps(Ke, me), length / np.sqrt(p_modulus / rho))
    added = comm.allreduce(float(np.sum((factor[:, None] - 1) * me)), op=MPI.SUM) / gdim
    total = comm.allreduce(float(np.sum(me)), op=MPI.SUM) / gdim
    me *= factor[:, None]
    return {"cells": comm.allreduce(int(np.sum(factor > 1)), op=MPI.SUM), "added_mass_kg": added, "mass_kg": total}


def assemble(space, domain, case, mass_scaling_share=None):
    """K, lumped mass and the bulk stable step for the case's materials; with
    mass_scaling_share F (time.mass_scaling), the cells' mass scaled to a step of at
    least F h / c_p (h = case.mesh.size). Collective."""
    lam, mu, rho = material_fields(space, domain, case.material, case.materials)
    K = compat.assemble_matrix(stiffness_form(space.V, lam, mu))
    m = compat.Function(space.V)
    compat.assemble_vector(lumped_mass_form(space.V, rho), m)
    Ke, idx = cell_matrices(K, space)
    if not np.array_equal(idx.ravel(), np.arange(idx.size)):
        raise RuntimeError("the DG dofs are not numbered cell by cell: K_cells needs a permutation "
                           "(DOLFINx changed its DG dof layout)")
    n = len(Ke)
    K_cells = sp.bsr_matrix((Ke, np.arange(n), np.arange(n + 1)), shape=(idx.size, idx.size))
    summary = None
    if mass_scaling_share:
        cell_value = lambda f: f.x.array[compat.cell_dofs(lam.function_space)[:n, 0]]  # noqa: E731
        me = m.x.array[idx]
        summary = scale_mass(Ke, me, cell_value(lam) + 2 * cell_value(mu), cell_value(rho),
                             mass_scaling_share * case.mesh.size, space.gdim, space.mesh.comm)
        m.x.array[idx] = me
        compat.scatter_forward(m)  # a ghost cell's copies take its owner's scaled mass
    return Bulk(K, K_cells, m, stable_time_step(Ke, m.x.array[idx], space.mesh.comm), summary)
