"""Bulk operators: K kills rigid motions, reproduces uniform-strain energy; M sums to the mass."""
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from conftest import ROOT, box, rectangle
from dolfrag import bulk, mesh, space as spaces

E, NU, RHO = 35e9, 0.2, 2350.0
# K entries are ~E = 3.5e10; products with unit-size vectors lose ~1e-16 relative per
# term, so rigid-motion forces are zero to ~1e-12 of ||K|| ||x||.
ROUNDOFF = 1e-11


def build(geometry, size, hypothesis="plane_strain", groups=None, domain=None):
    domain = domain or mesh.build(geometry, size, MPI.COMM_SELF)
    space = spaces.create(domain)
    material = SimpleNamespace(E=E, nu=NU, rho=RHO, hypothesis=hypothesis)
    case = SimpleNamespace(material=material, materials=groups or {})
    ops = bulk.assemble(space, domain, case)
    return domain, space, ops


@pytest.fixture(scope="module", params=["2d", "3d"])
def setup(request):
    if request.param == "2d":
        return build(rectangle(), 0.01)
    return build(box(), 0.02)


def cell_data(space, ops):
    Ke, idx = bulk.cell_matrices(ops.K, space)
    d = space.gdim
    coords = space.x[idx // d]  # coordinate of each component's dof
    comp = idx % d
    return Ke, idx, coords, comp


def rigid_modes(coords, comp, d):
    """Translations and infinitesimal rotations evaluated on each cell's components."""
    modes = [np.where(comp == k, 1.0, 0.0) for k in range(d)]
    pairs = [(0, 1)] if d == 2 else [(0, 1), (1, 2), (0, 2)]
    for a, b in pairs:  # rotation in plane (a, b): u_a = -x_b, u_b = x_a
        modes.append(np.where(comp == a, -coords[..., b], 0.0) + np.where(comp == b, coords[..., a], 0.0))
    return modes


def test_cell_stiffness_annihilates_rigid_body_modes(setup):
    _, space, ops = setup
    Ke, idx, coords, comp = cell_data(space, ops)
    for mode in rigid_modes(coords, comp, space.gdim):
        force = np.einsum("cij,cj->ci", Ke, mode)
        scale = np.abs(Ke).max() * np.abs(mode).max()
        assert np.abs(force).max() < ROUNDOFF * scale


@pytest.mark.parametrize("hypothesis", ["plane_strain", "plane_stress", "3d"])
def test_uniform_strain_energy_equals_closed_form(hypothesis):
    if hypothesis == "3d":
        domain, space, ops = build(box(), 0.02)
        volume = 0.1 * 0.05 * 0.03
    else:
        domain, space, ops = build(rectangle(), 0.01, hypothesis)
        volume = 0.12 * 0.04
    d = space.gdim
    eps = np.array([[1.0, 0.3, -0.2], [0.3, -0.5, 0.4], [-0.2, 0.4, 0.7]])[:d, :d] * 1e-4
    u = (space.x @ eps.T).ravel()  # u = eps x at every dof: P1 reproduces it exactly
    Ku = ops.K.createVecRight()
    ops.K.mult(PETSc.Vec().createWithArray(u), Ku)
    energy = 0.5 * u @ Ku.getArray()
    lam = E * NU / ((1 + NU) * (1 - 2 * NU))
    mu = E / (2 * (1 + NU))
    if hypothesis == "plane_stress":
        lam = 2 * lam * mu / (lam + 2 * mu)
    expected = 0.5 * volume * (lam * np.trace(eps) ** 2 + 2 * mu * np.sum(eps * eps))
    # exact for P1 and uniform strain: only round-off (1e-12) separates the two
    assert energy == pytest.approx(expected, rel=1e-10)


def test_lumped_mass_is_rho_times_volume(setup):
    _, space, ops = setup
    d = space.gdim
    volume = 0.12 * 0.04 if d == 2 else 0.1 * 0.05 * 0.03
    m = ops.m.x.array.reshape(-1, d)
    assert np.allclose(m[:, 0], m[:, 1:].T)  # the same lumped mass for every component
    assert m[:, 0].sum() == pytest.approx(RHO * volume, rel=1e-12)


def test_two_materials_from_an_imported_geo_file():
    geo = ROOT / "meshes" / "bar-two-materials.geo"
    geometry = SimpleNamespace(kind="file", tdim=2, file=str(geo))
    domain = mesh.build(geometry, 0.01, MPI.COMM_SELF)
    assert set(domain.materials) == {"concrete", "steel"}
    assert set(domain.boundaries) == {"left", "right", "bottom", "top"}
    steel = SimpleNamespace(E=200e9, nu=0.3, rho=7850.0)
    _, space, ops = build(None, None, groups={"steel": steel}, domain=domain)
    total = ops.m.x.array[::2].sum()
    assert total == pytest.approx(RHO * 0.1 * 0.05 + 7850.0 * 0.2 * 0.05, rel=1e-12)
