"""Alart-Curnier projections for unilateral contact with Coulomb friction, vectorised over
links, for a semi-smooth Newton. Pure numpy: no PETSc, no dolfinx, no MPI.

Sign convention (interface/links.py): g = u_B - u_A, n from A to B, g_N > 0 in opening.
The reactions are the force per unit area that A exerts on B through the contact:
r_N >= 0 pushes the faces apart (compression), r_T opposes the slip of B relative to A.
In the tension-positive traction of interface/laws.py they enter with a minus sign:
t_N = r_N(cohesive) - r_N, t_T = r_T(cohesive) - r_T.
"""
from typing import NamedTuple

import numpy as np


class ProjectionJacobian(NamedTuple):
    """Generalised Jacobian of (phi_N, phi_T); n links, m = d - 1.

    dN_drN (n,) -, dN_drT (n, m) -, dN_dgN (n,) Pa/m, dN_dgT (n, m) Pa/m,
    dT_drN (n, m) -, dT_drT (n, m, m) -, dT_dgN (n, m) Pa/m, dT_dgT (n, m, m) Pa/m
    (Pa s/m for dT_dgT when g_T_rate is a rate); dT_drT[i, a, b] = d phi_T[i, a] / d r_T[i, b].
    """
    dN_drN: np.ndarray
    dN_drT: np.ndarray
    dN_dgN: np.ndarray
    dN_dgT: np.ndarray
    dT_drN: np.ndarray
    dT_drT: np.ndarray
    dT_dgN: np.ndarray
    dT_dgT: np.ndarray


OPEN, STICK, SLIP = 0, 1, 2


class Branches(NamedTuple):
    """Which piece of the piecewise-smooth projections each link is on; n links, m = d - 1.

    contact (n,) bool: normal branch in contact (r~_N - rho_N g_N >= 0), else open.
    stick, slip (n,) bool: tangential branch (neither: a cone of radius 0, phi_T = r_T).
    pressed (n,) bool: r~_N > 0, the cone grows with the pressure.
    e (n, m): unit direction of y = r_T - rho_T g_T_rate where slipping, else 0.
    scale (n,): cone radius / |y| where slipping, else 0.
    """
    contact: np.ndarray
    stick: np.ndarray
    slip: np.ndarray
    pressed: np.ndarray
    e: np.ndarray
    scale: np.ndarray

    @property
    def status(self):
        """(n,) int: OPEN, STICK or SLIP; a link is open when its normal branch is."""
        return np.where(self.contact, np.where(self.stick, STICK, SLIP), OPEN)


def contact_friction_residual(r_N, r_T, g_N, g_T_rate, rho_N, rho_T, mu, shift, cohesion_T=0.0, compliance_N=0.0,
                              compliance_T=0.0, r_T_ref=0.0):
    """Alart-Curnier residuals of Signorini-Coulomb (Alart & Curnier 1991; docs/method.md, "Interface laws").

    symbol    meaning                                            unit        shape
    r_N       normal reaction, >= 0 in compression               Pa          (n,)
    r_T       tangential reaction on B                           Pa          (n, d-1)
    g_N       normal gap, > 0 in opening                         m           (n,)
    g_T_rate  tangential slip increment over the step            m           (n, d-1)
              (or slip rate, m/s: then rho_T is in Pa s/m)
    rho_N     normal augmentation                                Pa/m        scalar or (n,)
    rho_T     tangential augmentation                            Pa/m        scalar or (n,)
    mu        friction coefficient (mu (1 - beta) for RCCM)      -           scalar or (n,)
    shift     cohesion: R_c for an intact threshold link, else 0 Pa          scalar or (n,)
    cohesion_T  shear cohesion: radius of the cone at r~_N = 0 Pa          scalar or (n,)
    compliance_N  the normal compliance of a closed link             m/Pa        scalar or (n,)
    compliance_T  the tangential compliance of a sticking link       m/Pa        scalar or (n,)
    r_T_ref   the tangential reaction the step starts from           Pa          (n, d-1) or scalar

    Shifted Signorini on r~_N = r_N + shift:  r~_N >= 0, g_N >= 0, r~_N g_N = 0;
    Coulomb on the shifted cone:  |r_T| <= s = mu r~_N + cohesion_T, and r_T = -s v/|v| when
    slipping (cohesion_T = 0 but for a rigid linear-softening link, interface/models.py).
    phi_N = r~_N - proj_R+(r~_N - rho_N g_N)  =  r_N - max(-shift, r_N - rho_N g_N)
    phi_T = r_T - proj_D(r_T - rho_T g_T_rate),  D = disc of radius mu max(r~_N, 0) + cohesion_T
    With compliances the link is an elastic joint where it holds: the conditions act on
    g_N + compliance_N r_N and on g_T_rate + compliance_T (r_T - r_T_ref), so a closed link
    opens or closes by compliance_N r_N and a sticking one slips by compliance_T times its
    change of reaction (solver/active_set.COMPLIANCE says why and how stiff).
    Both vanish exactly when the conditions hold. rho only scales the Newton steps: a value
    of the order of the interface stiffness (C_N or E/h) balances reactions and gaps.
    Branches: contact where r~_N - rho_N g_N >= 0 (else open); with y = r_T - rho_T
    g_T_rate, stick where |y| <= radius and radius > 0, slip where |y| > radius > 0, and
    phi_T = r_T where the radius is 0.

    Returns phi_N (n,) Pa, phi_T (n, d-1) Pa and the Branches.
    """
    r_N, r_T, g_N, v = (np.asarray(a, dtype=float) for a in (r_N, r_T, g_N, g_T_rate))
    n = len(r_N)
    rho_N = np.asarray(rho_N, dtype=float)
    rho_T = np.asarray(rho_T, dtype=float)[..., None]
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (n,))
    r_shift = r_N + shift
    y_N = r_shift - rho_N * (g_N + compliance_N * r_N)
    contact = y_N >= 0
    phi_N = r_shift - np.maximum(0.0, y_N)
    pressed = r_shift > 0
    radius = mu * np.where(pressed, r_shift, 0.0) + cohesion_T
    v = v + np.asarray(compliance_T, dtype=float)[..., None] * (r_T - r_T_ref)  # the slip of the joint's slider
    y = r_T - rho_T * v
    norm_y = np.linalg.norm(y, axis=-1)
    cone = radius > 0
    stick = (norm_y <= radius) & cone
    slip = (norm_y > radius) & cone
    e = np.divide(y, norm_y[:, None], out=np.zeros_like(y), where=slip[:, None])
    scale = np.divide(radius, norm_y, out=np.zeros(n), where=slip)
    phi_T = np.where(stick[:, None], rho_T * v, r_T - scale[:, None] * y)
    return phi_N, phi_T, Branches(contact, stick, slip, pressed, e, scale)


def projection_jacobian(branches, rho_N, rho_T, mu, compliance_N=0.0, compliance_T=0.0):
    """Generalised Jacobian of (phi_N, phi_T) on the given Branches (same arguments as
    contact_friction_residual); mu is treated as fixed (no derivative)."""
    contact, stick, slip, pressed, e, scale = branches
    n, m = e.shape
    rho_N = np.broadcast_to(np.asarray(rho_N, dtype=float), (n,))
    rho_T = np.asarray(rho_T, dtype=float)[..., None]
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (n,))
    eye = np.eye(m)
    soft_T = (rho_T * np.asarray(compliance_T, dtype=float)[..., None])[..., None]  # rho c, -
    # slip: d(y/|y|)/dy = (I - e e^T) / |y|
    P = scale[:, None, None] * (eye - e[:, :, None] * e[:, None, :])
    dT_drT = np.where(stick[:, None, None], soft_T * eye, eye - (1 - soft_T) * P)
    dT_dgT = rho_T[..., None] * np.where(stick[:, None, None], eye, P)
    dT_drN = -(mu * (slip & pressed))[:, None] * e
    zeros = np.zeros((n, m))
    return ProjectionJacobian(np.where(contact, rho_N * compliance_N, 1.0), zeros, np.where(contact, rho_N, 0.0),
                              zeros, dT_drN, dT_drT, zeros, dT_dgT)


def contact_friction_projection(r_N, r_T, g_N, g_T_rate, rho_N, rho_T, mu, shift, cohesion_T=0.0, compliance_N=0.0,
                                compliance_T=0.0, r_T_ref=0.0):
    """contact_friction_residual with its projection_jacobian and the status (n,) int:
    0 = open (OPEN), 1 = stick (STICK), 2 = slip (SLIP); a link is open when the normal
    branch is. Returns phi_N, phi_T, a ProjectionJacobian, status."""
    phi_N, phi_T, branches = contact_friction_residual(r_N, r_T, g_N, g_T_rate, rho_N, rho_T, mu, shift,
                                                       cohesion_T, compliance_N, compliance_T, r_T_ref)
    return phi_N, phi_T, projection_jacobian(branches, rho_N, rho_T, mu, compliance_N, compliance_T), branches.status


def link_blocks(NN, NT, TN, TT):
    """Link-frame d x d blocks [[NN, NT], [TN, TT]] from (n, L), (n, L, m), (n, L, m), (n, L, m, m)."""
    top = np.concatenate([NN[..., None], NT], axis=-1)[..., None, :]
    bottom = np.concatenate([TN[..., None], TT], axis=-1)
    return np.concatenate([top, bottom], axis=-2)
