"""Static responses of a discretisation: a static stretch, or a static pressure, of the very
mesh that runs.

The interface springs add compliance, and on an unstructured mesh more than the 1D
series estimate says (-8 % wave speed measured on the sound bar against -4.7 %
predicted at C = 10 E / h, docs/validation.md). Tests that predict arrival times use this modulus; the slab's
slow-ramp check uses the static centre deflection (docs/slab.md).
"""
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from mpi4py import MPI
from petsc4py import PETSc

from dolfrag import bulk, bunker, loads, mesh, space as spaces, supports
from dolfrag.interface import links as link_table
from dolfrag.interface.jumps import Jump
from dolfrag.post.bunker import long_wall_centre


def interface_stiffness(jump, k_N, k_T):
    """Global interface stiffness B^T D B (scipy CSR, N/m) of springs k_N, k_T (Pa/m)."""
    D = jump.tangent_blocks(k_N, k_T)
    n = len(D)
    blocks = sp.bsr_matrix((D, np.arange(n), np.arange(n + 1)), shape=(n * jump.gdim, n * jump.gdim))
    return (jump.BT @ blocks @ jump.B).tocsr()


def uniaxial_strain_modulus(case):
    """M_eff (Pa) of the case's 2D rectangle mesh with its interface springs, from a
    static stretch in uniaxial strain: rollers on left (u_x = 0), bottom and top
    (u_y = 0), a unit pressure on right; M_eff = p L / |mean u_x(right)|.

    Runs serially on every calling rank (the mesh is rebuilt on COMM_SELF; gmsh is
    deterministic, so it is the same mesh a parallel run distributes)."""
    domain = mesh.build(case.geometry, case.mesh.size, MPI.COMM_SELF)
    space = spaces.create(domain)
    K_bulk = bulk.assemble(space, domain, case).K
    indptr, cols, vals = K_bulk.getValuesCSR()
    K = sp.csr_matrix((vals, cols, indptr), shape=K_bulk.getSize())
    C_N, C_T = case.interface.stiffness(case.material.E, case.mesh.size)
    K = K + interface_stiffness(Jump(space, link_table.build(space)), C_N, C_T)
    f = loads.unit_pressure_vector(space, domain, "right").x.array
    d = space.gdim
    fixed = np.concatenate([d * space.boundary_dofs(domain.facet_tags, domain.boundary_tag(b)) + axis
                            for b, axis in (("left", 0), ("bottom", 1), ("top", 1))])
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    u = np.zeros(K.shape[0])
    u[free] = spla.spsolve(K[free][:, free].tocsc(), f[free])
    right = space.boundary_dofs(domain.facet_tags, domain.boundary_tag("right"))
    return case.geometry.length / abs(u[d * right].mean())


def bar_modulus(case):
    """E_eff (Pa) of the case's 2D rectangle bar with its interface springs and its own
    supports, from a static push: the loaded face (load.boundary, left or right) held along
    the axis, one of its dofs also across it (no rigid motion), a unit pressure on the
    opposite (free) face; E_eff = p L / |mean u_x(free face)|. With rollers on the long
    faces this is uniaxial_strain_modulus; with free long faces, the bar modulus that sets
    the wave speed of a Hopkinson specimen. Serial on every calling rank (COMM_SELF; gmsh
    is deterministic: the same mesh a parallel run distributes). None when the opposite face
    is itself supported: there is no free end to push."""
    loaded = case.load.boundary
    free_face = "right" if loaded == "left" else "left"
    supports_ = case.supports
    if free_face in (*supports_.clamped, *supports_.rollers, *supports_.simple):
        return None
    domain = mesh.build(case.geometry, case.mesh.size, MPI.COMM_SELF)
    space = spaces.create(domain)
    K = _stiffness_with_springs(case, space, domain)
    f = loads.unit_pressure_vector(space, domain, free_face).x.array
    d = space.gdim
    held = space.boundary_dofs(domain.facet_tags, domain.boundary_tag(loaded))
    fixed = np.union1d(np.concatenate([d * held, [d * held[0] + 1]]),
                       supports.constrained_components(space, domain, case.supports))
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    u = np.zeros(K.shape[0])
    u[free] = spla.spsolve(K[free][:, free].tocsc(), f[free])
    end = space.boundary_dofs(domain.facet_tags, domain.boundary_tag(free_face))
    return case.geometry.length / abs(u[d * end].mean())


def _stiffness_with_springs(case, space, domain, stiffness_ratio=None):
    """K + B^T D B (scipy CSR, N/m) of the case's mesh, springs C_N, C_T (Pa/m) of the case,
    or stiffness_ratio * E / h both when given (large: nearly rigid interfaces)."""
    K_bulk = bulk.assemble(space, domain, case).K
    indptr, cols, vals = K_bulk.getValuesCSR()
    K = sp.csr_matrix((vals, cols, indptr), shape=K_bulk.getSize())
    C_N, C_T = case.interface.stiffness(case.material.E, case.mesh.size)
    if stiffness_ratio is not None:
        C_N = C_T = stiffness_ratio * case.material.E / case.mesh.size
    return K + interface_stiffness(Jump(space, link_table.build(space)), C_N, C_T)


def static_centre_deflection(case, stiffness_ratio=None, rtol=1e-10):
    """Centre deflection per unit pressure (m/Pa) of the case's slab mesh with its interface
    springs (or stiffness_ratio * E / h), its supports, and a uniform static pressure on
    its load boundary: the mean displacement along the thickness (z) of the dofs within one
    mesh size of the centre line (x, y) = (L_x / 2, L_y / 2), as the runner's deflection."""
    space, u = static_displacement(case, stiffness_ratio, rtol)
    g = case.geometry
    near = np.all(np.abs(space.x[:, :2] - np.array([g.length, g.width]) / 2) < case.mesh.size, axis=1)
    return float(u[space.gdim * np.flatnonzero(near) + 2].mean())


def static_long_wall_deflection(case, rtol=1e-10):
    """(cells, m/Pa): a bunker mesh's cell count and its long wall's outward (+y) centre
    deflection per unit inside pressure, as the bunker report measures it
    (post.bunker.long_wall_centre), with the springs and supports of static_displacement."""
    space, u = static_displacement(case, rtol=rtol)
    centre = long_wall_centre(space.x, bunker.layout(case.geometry), case.mesh.size)
    return space.n_owned_cells, float(u[space.gdim * centre + 1].mean())


def static_displacement(case, stiffness_ratio=None, rtol=1e-10):
    """(space, u): the case's mesh, serial, and its displacement per unit pressure (m/Pa,
    flat dof components) with its interface springs (or stiffness_ratio * E / h), its
    supports, and a uniform static pressure on its load boundary. Bulk and springs only (no
    bars, no contact: elastic springs in tension and compression). Conjugate gradients with
    PETSc's algebraic multigrid to ``rtol``. Serial on every calling rank (COMM_SELF; gmsh is
    deterministic: the same mesh a parallel run distributes)."""
    domain = mesh.build(case.geometry, case.mesh.size, MPI.COMM_SELF)
    space = spaces.create(domain)
    K = _stiffness_with_springs(case, space, domain, stiffness_ratio)
    f = loads.unit_pressure_vector(space, domain, case.load.boundary).x.array
    free = np.setdiff1d(np.arange(K.shape[0]), supports.constrained_components(space, domain, case.supports))
    A = K[free][:, free].tocsr()
    matrix = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr, A.indices, A.data), comm=MPI.COMM_SELF)
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setOperators(matrix)
    ksp.setType("cg")
    ksp.getPC().setType("gamg")
    ksp.setTolerances(rtol=rtol, max_it=10000)
    b, x = matrix.createVecs()
    b.array[:] = f[free]
    ksp.solve(b, x)
    if ksp.getConvergedReason() <= 0:
        raise RuntimeError(f"static solve did not converge: reason {ksp.getConvergedReason()}")
    u = np.zeros(K.shape[0])
    u[free] = x.array
    return space, u
