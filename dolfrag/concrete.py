"""Concrete from its strength class, and its tensile strength at a strain rate.

Strength classes of EN 1992-1-1 (Eurocode 2) Table 3.1, C12/15 ... C90/105, and the
formulas behind the table (MPa, GPa as the code writes them; SI in what this module
returns):

    f_cm  = f_ck + 8 MPa                          mean compressive strength
    f_ctm = 0.30 f_ck^(2/3)          (<= C50/60)  mean tensile strength
          = 2.12 ln(1 + f_cm / 10)   (above)
    E_cm  = 22 (f_cm / 10)^0.3 GPa                secant modulus
    nu    = 0.2                                   (EN 1992-1-1 3.1.3(4), uncracked)

Fracture energy, fib Model Code 2010 eq. 5.1-9: G_F = 73 f_cm^0.18 N/m (f_cm in MPa).
Density 2,400 kg/m^3 (EN 1991-1-1 Table A.1, plain normal-weight concrete).

Strength under compression, for the intact links of linear softening (Mohr-Coulomb with a
tension cut-off at f_ctm): internal friction mu_i = tan 37 deg = 0.75, the friction angle of
Richart, Brandtzaeg & Brown's (1928) confinement coefficient 4.1 = (1 + sin phi)/(1 - sin
phi), and the shear strength at zero pressure

    tau_c = f_cm (sqrt(1 + mu_i^2) - mu_i) / 2,

at which the best-oriented facet of a body under uniaxial compression slips when the
compression reaches f_cm.

Tensile dynamic increase factor, fib Model Code 2010 eqs. 5.1-108/109, with
eps0 = 1e-6 1/s:

    f_ct,imp / f_ctm = (rate / eps0)^0.018            rate <= 10 1/s
                     = 0.0062 (rate / eps0)^(1/3)     rate >  10 1/s

and 1 below eps0 (the code gives no increase for slower loading).
"""
import math
from typing import NamedTuple

import numpy as np

DENSITY = 2400.0  # kg/m^3
POISSON = 0.2
RATE_0 = 1e-6  # 1/s, fib Model Code 2010 reference strain rate in tension
INTERNAL_FRICTION = 0.75  # -, tan 37 deg
RATE_KNEE = 10.0  # 1/s, where the tensile DIF turns to the cube-root branch

# f_ck (MPa) of the classes of EN 1992-1-1 Table 3.1, by name f_ck/f_ck,cube
GRADES = {"C12/15": 12, "C16/20": 16, "C20/25": 20, "C25/30": 25, "C30/37": 30, "C35/45": 35,
          "C40/50": 40, "C45/55": 45, "C50/60": 50, "C55/67": 55, "C60/75": 60, "C70/85": 70,
          "C80/95": 80, "C90/105": 90}

SOURCES = {
    "f_ck": "EN 1992-1-1 Table 3.1",
    "f_cm": "EN 1992-1-1 Table 3.1: f_cm = f_ck + 8 MPa",
    "f_ctm": "EN 1992-1-1 Table 3.1: f_ctm = 0.30 f_ck^(2/3) (<= C50/60), 2.12 ln(1 + f_cm/10) above",
    "E": "EN 1992-1-1 Table 3.1: E_cm = 22 (f_cm/10)^0.3 GPa",
    "nu": "EN 1992-1-1 3.1.3(4): nu = 0.2 (uncracked)",
    "rho": "EN 1991-1-1 Table A.1: 2400 kg/m^3 (normal-weight concrete)",
    "G_F": "fib Model Code 2010 eq. 5.1-9: G_F = 73 f_cm^0.18 N/m",
    "mu_i": "tan 37 deg: the confinement coefficient 4.1 = (1 + sin phi)/(1 - sin phi) of Richart, "
            "Brandtzaeg & Brown 1928",
    "tau_c": "Mohr-Coulomb through f_cm: tau_c = f_cm (sqrt(1 + mu_i^2) - mu_i) / 2",
    "bond_tau_max": "fib Model Code 2010 Table 6.1-1: tau_bmax = 2.5 sqrt(f_cm) (pull-out, good bond)",
}


class Concrete(NamedTuple):
    """A strength class's values, SI: f_ck, f_cm, f_ctm (Pa), E (Pa), nu (-), rho (kg/m^3),
    G_F (J/m^2)."""
    grade: str
    f_ck: float
    f_cm: float
    f_ctm: float
    E: float
    nu: float
    rho: float
    G_F: float

    @property
    def characteristic_length(self):
        """Hillerborg's l_ch = E G_F / f_ctm^2 (m): the size below which a member fails
        by strength rather than by fracture."""
        return self.E * self.G_F / self.f_ctm**2


def tensile_strength(f_ck, f_cm):
    """f_ctm (MPa) from f_ck, f_cm (MPa), EN 1992-1-1 Table 3.1."""
    return 0.30 * f_ck ** (2 / 3) if f_ck <= 50 else 2.12 * math.log(1 + f_cm / 10)


def fracture_energy(f_cm):
    """G_F (J/m^2) from f_cm (MPa), fib Model Code 2010 eq. 5.1-9."""
    return 73.0 * f_cm**0.18


def concrete(grade):
    """The Concrete of a class name of EN 1992-1-1 Table 3.1 (e.g. "C30/37"); KeyError
    for another name."""
    f_ck = float(GRADES[grade])
    f_cm = f_ck + 8.0
    return Concrete(grade, f_ck * 1e6, f_cm * 1e6, tensile_strength(f_ck, f_cm) * 1e6,
                    22e9 * (f_cm / 10) ** 0.3, POISSON, DENSITY, fracture_energy(f_cm))


def shear_strength(f_cm, mu_i):
    """tau_c (Pa): the shear strength at zero pressure of a facet with internal friction mu_i
    (-) whose best-oriented copy, in a body under uniaxial compression, slips at f_cm (Pa).
    A facet at angle theta to the compression sigma carries the shear sigma sin cos and the
    pressure sigma sin^2; the largest of sin cos - mu_i sin^2 over theta is
    (sqrt(1 + mu_i^2) - mu_i) / 2."""
    return f_cm * (math.sqrt(1 + mu_i**2) - mu_i) / 2


def bond_strength(f_cm):
    """tau_bmax (Pa) of ribbed bars in concrete of mean compressive strength f_cm (Pa), pull-out
    failure in good bond conditions: 2.5 sqrt(f_cm) MPa, fib Model Code 2010 Table 6.1-1."""
    return 2.5e6 * math.sqrt(f_cm / 1e6)


def tensile_dif(rate):
    """fib Model Code 2010 tensile dynamic increase factor (-) at the strain rate
    ``rate`` (1/s, scalar or array): (rate/eps0)^0.018 up to 10 1/s, 0.0062
    (rate/eps0)^(1/3) above, 1 below eps0 = 1e-6 1/s."""
    x = np.maximum(np.asarray(rate, dtype=float), RATE_0) / RATE_0
    return np.where(x <= RATE_KNEE / RATE_0, x**0.018, 0.0062 * np.cbrt(x))
