"""Airblast of a TNT charge: the Kingery-Bulmash fits, as UFC 3-340-02 charts them.

Kingery & Bulmash, "Airblast parameters from TNT spherical air burst and hemispherical
surface burst", ARBRL-TR-02555, US Army Ballistic Research Laboratory (1984): each blast
parameter Y of a charge of W kg of TNT at R m is a polynomial in log10 of the scaled
distance Z = R / W^(1/3) (m/kg^(1/3)),

    log10 Y = sum_i C_i U^i,   U = K_0 + K_1 log10 Z,

one to three segments per parameter, each valid on a range of Z. Y is a pressure in kPa,
or a time (ms) or an impulse (kPa ms) per kg^(1/3) (Hopkinson-Cranz scaling: multiply by
W^(1/3)). These are the curves of UFC 3-340-02 (2008) Figures 2-7 (free air) and 2-15
(surface burst), the fits ConWep and LS-DYNA's LOAD_BLAST evaluate. The coefficients are
the report's metric ones, as reproduced in public implementations of it; where two of
those disagreed (the ninth coefficient of the free-air reflected pressure, the sign of
the constant of the free-air middle duration segment) the value kept is the one that
makes adjacent segments meet (tests/test_charge.py).

Bursts: "free_air", a spherical charge far from any surface; "surface", a hemispherical
charge on rigid ground (its energy goes into a half space: about a 1.8 x heavier free-air
charge).
"""
from typing import NamedTuple

import numpy as np


class Segment(NamedTuple):
    """One polynomial of a fit: valid for Z in [Z_min, Z_max] (m/kg^(1/3)), U = K_0 + K_1
    log10 Z, log10 Y = sum_i C[i] U^i."""
    Z_min: float
    Z_max: float
    K: tuple
    C: tuple


_PRESSURE_U = (-0.214362789151, 1.35034249993)  # the U of both bursts' incident pressure

FITS = {
    "free_air": {
        "t_a": (Segment(0.0531, 40.0, (-0.253273111999, 1.37407043777),
                        (0.0720707787637, 1.36456871214, -0.0570035692784, -0.182832224796, 0.0118851436014,
                         0.0432648687627, -0.0007997367834, -0.00436073555033)),),
        "P_so": (Segment(0.0531, 40.0, _PRESSURE_U,
                         (2.611368669, -1.69012801396, 0.00804973591951, 0.336743114941, -0.00516226351334,
                          -0.0809228619888, -0.00478507266747, 0.00793030472242, 0.0007684469735)),),
        "P_r": (Segment(0.0531, 40.0, _PRESSURE_U,
                        (3.22958031387, -2.21400538997, 0.035119031446, 0.657599992109, 0.0141818951887,
                         -0.243076636231, -0.0158699803158, 0.0492741184234, 0.00227639644004,
                         -0.00397126276058)),),
        "t_o": (Segment(0.147, 0.888, (2.26367268496, 5.11588554305),
                        (-0.686608550419, 0.164953518069, 0.127788499497, 0.00291430135946, 0.00187957449227,
                         0.0173413962543, 0.00269739758043, -0.00361976502798, -0.00100926577934)),
                Segment(0.888, 2.28, (-1.33361206714, 9.2996288611),
                        (0.23031841078, -0.0297944268969, 0.0306329542941, 0.0183405574074, -0.0173964666286,
                         -0.00106321963576, 0.0056206003128, 0.0001618217499, -0.0006860188944)),
                Segment(2.28, 40.0, (-3.13005805346, 3.1524725364),
                        (0.621036276475, 0.0967031995552, -0.00801302059667, 0.00482705779732,
                         0.00187587272287, -0.00246738509321, -0.000841116668, 0.0006193291052))),
        "i_s": (Segment(0.0531, 0.792, (2.34723921354, 3.24299066475),
                        (2.38830516757, -0.443749377691, 0.168825414684, 0.0348138030308, -0.010435192824)),
                Segment(0.792, 40.0, (-1.75305660315, 2.30629231803),
                        (1.55197227115, -0.40463292088, -0.0142721946082, 0.00912366316617, -0.0006750681404,
                         -0.00800863718901, 0.00314819515931, 0.00152044783382, -0.0007470265899))),
        "i_r": (Segment(0.0531, 40.0, (-0.204004553231, 1.37882996018),
                        (2.55875660396, -0.903118886091, 0.101771877942, -0.0242139751146)),),
    },
    "surface": {
        "t_a": (Segment(0.0674, 40.0, (-0.202425716178, 1.37784223635),
                        (-0.0591634288046, 1.35706496258, 0.052492798645, -0.196563954086, -0.0601770052288,
                         0.0696360270891, 0.0215297490092, -0.0161658930785, -0.00232531970294,
                         0.00147752067524)),),
        "P_so": (Segment(0.0674, 40.0, _PRESSURE_U,
                         (2.78076916577, -1.6958988741, -0.154159376846, 0.514060730593, 0.0988534365274,
                          -0.293912623038, -0.0268112345019, 0.109097496421, 0.00162846756311,
                          -0.0214631030242, 0.0001456723382, 0.00167847752266)),),
        "P_r": (Segment(0.0674, 40.0, (-0.240657322658, 1.36637719229),
                        (3.40283217581, -2.21030870597, -0.218536586295, 0.895319589372, 0.24989009775,
                         -0.569249436807, -0.11791682383, 0.224131161411, 0.0245620259375, -0.0455116002694,
                         -0.0019093073888, 0.00361471193389)),),
        "t_o": (Segment(0.178, 1.01, (1.92946154068, 5.25099193925),
                        (-0.614227603559, 0.130143717675, 0.134872511954, 0.0391574276906, -0.00475933664702,
                         -0.00428144598008)),
                Segment(1.01, 2.78, (-2.12492525216, 9.2996288611),
                        (0.315409245784, -0.0297944268976, 0.030632954288, 0.0183405574086, -0.0173964666211,
                         -0.00106321963633, 0.00562060030977, 0.0001618217499, -0.0006860188944)),
                Segment(2.78, 40.0, (-3.53626218091, 3.46349745571),
                        (0.686906642409, 0.0933035304009, -0.0005849420883, -0.00226884995013,
                         -0.00295908591505, 0.00148029868929))),
        "i_s": (Segment(0.0674, 0.955, (2.06761908721, 3.0760329666),
                        (2.52455620925, -0.502992763686, 0.171335645235, 0.0450176963051, -0.0118964626402)),
                Segment(0.955, 40.0, (-1.94708846747, 2.40697745406),
                        (1.67281645863, -0.384519026965, -0.0260816706301, 0.00595798753822, 0.014544526107,
                         -0.00663289334734, -0.00284189327204, 0.0013644816227))),
        "i_r": (Segment(0.0674, 40.0, (-0.246208804814, 1.33422049854),
                        (2.70588058103, -0.949516092853, 0.112136118689, -0.0250659183287)),),
    },
}
BURSTS = tuple(FITS)
# what each fitted parameter is, and the SI factor from the fit's unit (kPa; ms or kPa ms,
# per kg^(1/3)) to Pa, s or Pa s per kg^(1/3)
PARAMETERS = {"t_a": 1e-3, "P_so": 1e3, "P_r": 1e3, "t_o": 1e-3, "i_s": 1.0, "i_r": 1.0}
SCALED = ("t_a", "t_o", "i_s", "i_r")  # Hopkinson-Cranz: these grow as W^(1/3) at equal Z


def scaled_range(burst):
    """(Z_min, Z_max) m/kg^(1/3): where every parameter of ``burst`` is fitted (the
    positive phase duration's fit starts latest)."""
    fits = FITS[burst].values()
    return max(fit[0].Z_min for fit in fits), min(fit[-1].Z_max for fit in fits)


def fitted(burst, name, Z):
    """Parameter ``name`` of PARAMETERS at scaled distances Z (m/kg^(1/3), array), SI
    (Pa; s or Pa s per kg^(1/3)); each Z read on the segment whose range holds it (at a
    join, the upper one). Z outside scaled_range(burst) raises ValueError."""
    Z = np.asarray(Z, dtype=np.float64)
    low, high = scaled_range(burst)
    if not np.all((Z >= low) & (Z <= high)):
        raise ValueError(f"Z = {Z.min() if np.any(Z < low) else Z.max():.4g} m/kg^(1/3): outside the "
                         f"{burst} fits' range [{low:g}, {high:g}]")
    log_Z = np.log10(Z)
    result = np.empty_like(Z)
    for segment in FITS[burst][name]:
        on = Z >= segment.Z_min
        U = segment.K[0] + segment.K[1] * log_Z[on]
        result[on] = 10.0 ** np.polynomial.polynomial.polyval(U, segment.C)
    return PARAMETERS[name] * result


def oblique(normal, side_on, angle):
    """The reflected value at an angle of incidence (rad, from the facet normal): the
    blend normal cos^2 a + side_on (1 + cos^2 a - 2 cos a) for a < pi/2 (Randers-Pehrson &
    Bannister, "Airblast loading model for DYNA2D and DYNA3D", ARL-TR-1310, 1997: the rule of
    LS-DYNA's LOAD_BLAST, after ConWep), never below side_on, and side_on beyond pi/2 (a
    facet facing away from the charge). Applied alike to peak pressures and impulses. The
    floor keeps the reflection coefficient >= 1, as in UFC 3-340-02 Figure 2-193 (the
    blend alone dips to side_on normal / (normal + side_on) near grazing incidence); the
    figure's rise near the Mach-stem angles (about 40-55 degrees) is not reproduced."""
    c = np.cos(np.minimum(angle, 0.5 * np.pi))
    return np.maximum(normal * c**2 + side_on * (1.0 + c**2 - 2.0 * c), side_on)


def blast_parameters(W, R, burst="surface", angle=0.0):
    """The blast of W kg of TNT at R m (arrays broadcast), SI:

    t_a (s) arrival time; P_so, P_r (Pa) incident and reflected peak overpressure;
    t_o (s) positive phase duration; i_s, i_r (Pa s) incident and reflected positive
    impulse. P_r and i_r at the angle of incidence ``angle`` (rad, 0: normal; oblique).
    burst: "free_air" or "surface" (BURSTS). Z = R / W^(1/3) outside scaled_range(burst)
    raises ValueError."""
    if burst not in FITS:
        raise ValueError(f"burst = {burst!r}: must be one of {', '.join(map(repr, BURSTS))}")
    cube_root = np.cbrt(np.asarray(W, dtype=np.float64))
    Z = np.asarray(R, dtype=np.float64) / cube_root
    values = {name: fitted(burst, name, Z) * (cube_root if name in SCALED else 1.0) for name in PARAMETERS}
    values["P_r"] = oblique(values["P_r"], values["P_so"], angle)
    values["i_r"] = oblique(values["i_r"], values["i_s"], angle)
    return values
