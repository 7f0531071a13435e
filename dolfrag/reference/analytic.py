"""Closed forms used for validation. One pure function per formula, SI units; nothing
runs on import."""
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np


def p_wave_modulus(E, nu, hypothesis="plane_strain"):
    """Uniaxial-strain (P-wave) modulus lambda + 2 mu (Pa); in plane stress the
    in-plane one, E / (1 - nu^2)."""
    if hypothesis == "plane_stress":
        return E / (1 - nu**2)
    return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def series_interface_modulus(M, C_N, spacing):
    """1D estimate of the modulus of a bulk of modulus M (Pa) cut every ``spacing`` (m) by
    springs C_N (Pa/m) in series: M / (1 + M / (C_N spacing)); M itself for C_N None (a
    rigid law, interface/models.py: no springs, no added compliance)."""
    return M if C_N is None else M / (1 + M / (C_N * spacing))


def wave_speed(modulus, rho):
    """sqrt(modulus / rho), m/s."""
    return np.sqrt(modulus / rho)


def free_end_arrival_time(length, c, rise):
    """Time (s) at which the free-end velocity reaches half its peak under a pulse
    rising linearly over ``rise`` (s) applied at t = 0 a distance ``length`` (m) away,
    for a non-dispersive wave of speed c (m/s): L / c + rise / 2."""
    return length / c + rise / 2


def spall_distance(pressure, c, sigma_c, duration, samples=2001):
    """First spall plane (m from the free end) of a compressive pulse p(t) (Pa, a function
    of t >= 0 vectorised over t) reflecting at a free end, 1D, wave speed c (m/s), tensile
    strength sigma_c (Pa) (docs/hopkinson.md): the smallest s at which the net tension
    max_tau [p(tau) - p(tau + 2 s / c)] reaches sigma_c. None if it never does within the
    pulse (``duration``, s). Accurate to about c * duration / (2 samples)."""
    tau = np.linspace(0.0, duration, samples)
    s = np.linspace(0.0, c * duration / 2, samples)
    tension = np.max(pressure(tau) - pressure(tau + 2 * s[:, None] / c), axis=1)
    reached = np.flatnonzero(tension >= sigma_c)
    if not len(reached):
        return None
    k = reached[0]
    if k == 0:
        return 0.0
    return float(np.interp(sigma_c, tension[k - 1:k + 1], s[k - 1:k + 1]))


def scab_velocity(pressure, c, rho, delta, start=0.0, samples=2001):
    """Velocity (m/s) of a scab of thickness delta (m) cut by a pulse p(t) (Pa): the momentum
    trapped in it over its mass, (1 / (rho delta)) int_start^{start + 2 delta / c} p(tau) dtau
    (docs/hopkinson.md). ``start`` (s): the pulse time that opens the window, 0 for a sharp front,
    the end of the rise for a ramped one (``bar_spall``)."""
    tau = np.linspace(start, start + 2 * delta / c, samples)
    return float(np.trapz(pressure(tau), tau) / (rho * delta))


class BarSpall(NamedTuple):
    """The first spall of a 1D bar (``bar_spall``)."""
    distance: float  # m from the free end
    time: float  # s after the pulse starts on the loaded end
    scab_velocity: float  # m/s: the piece between the free end and the plane
    rest_velocity: float  # m/s: the centre of mass of the rest of the bar

    @property
    def relative_velocity(self):
        """Scab minus rest (m/s): the centre-of-mass velocity difference of the two blocks in 1D."""
        return self.scab_velocity - self.rest_velocity


def bar_spall(pressure, c, rho, sigma_c, length, duration, at=None, samples=2001):
    """First spall of a bar of ``length`` (m), loaded on one end by the pressure p(t) (Pa,
    ``duration`` s), free on the other; 1D, wave speed c (m/s), density rho (kg/m^3),
    brittle at sigma_c (Pa). None if it does not spall.

    The plane is ``spall_distance``. It breaks at the first pulse time tau at which the drop
    p(tau) - p(tau + 2 delta / c) reaches sigma_c, i.e. at t = tau + (L + delta) / c; the scab
    keeps the momentum of that window of the pulse (``scab_velocity``) and the rest of the
    bar what else of the pulse has entered by the time ``at`` (s, default: all of it). The
    velocities hold from the break on, as long as no second plane breaks (docs/hopkinson.md
    §3).
    """
    delta = spall_distance(pressure, c, sigma_c, duration, samples)
    if delta is None:
        return None
    tau = np.linspace(0.0, duration, samples)
    drop = pressure(tau) - pressure(tau + 2 * delta / c)
    # delta is interpolated, so the drop there peaks at sigma_c to within sampling error;
    # a linear tail holds that peak over an interval, whose start is the break
    start = tau[np.argmax(drop >= drop.max() - 1e-6 * sigma_c)]
    scab = scab_velocity(pressure, c, rho, delta, start, samples)
    entered = np.linspace(0.0, duration if at is None else min(at, duration), samples)
    impulse = np.trapz(pressure(entered), entered)  # Pa s, per unit area
    rest = (impulse - rho * delta * scab) / (rho * (length - delta))
    return BarSpall(delta, float(start + (length + delta) / c), scab, float(rest))


def triangular_spall_distance(wavelength, sigma_c, sigma_0):
    """Spall plane of a sharp-fronted triangular pulse of peak sigma_0 and spatial length
    wavelength = c t_d: lambda sigma_c / (2 sigma_0) (m)."""
    return wavelength * sigma_c / (2 * sigma_0)


def triangular_scab_velocity(sigma_0, sigma_c, rho, c):
    """Scab velocity of a sharp-fronted triangular pulse: (2 sigma_0 - sigma_c) / (rho c), m/s."""
    return (2 * sigma_0 - sigma_c) / (rho * c)


def ejection_velocity(sigma_c, rho, E):
    """V_e = sigma_c / sqrt(rho E) = sigma_c / (rho c) (m/s): the particle-velocity jump that
    the unloading wave of a 1D spall plane opening at the tensile strength sigma_c (Pa)
    carries; rho kg/m^3, E Pa (the bar modulus; pass the mesh's effective modulus for the
    discretisation's value). At a free surface the jump doubles: the free end's velocity
    drops by 2 V_e from its peak to its first minimum (the pullback, post/shpb.py), so spall
    experiments read the strength as sigma_spall = 1/2 rho c delta_u_fs (Novikov, Divnov &
    Ivanov 1966). V_e is not the centre-of-mass velocity difference of the blocks on either
    side of the plane: that is ``BarSpall.relative_velocity``, set by the pulse's impulse."""
    return sigma_c / np.sqrt(rho * E)


# Fragmentation of a bar stretched at a uniform strain rate: scales of a
# linear-softening cohesive law (Camacho & Ortiz 1996; Drugan 2001) and the mean fragment
# size of three theories, each as s / L0 against the normalised rate eps_dot / eps_dot_0.

def fragmentation_length(E, G_c, sigma_c):
    """L0 = E G_c / sigma_c^2 (m): the cohesive length of a bar of modulus E (Pa) with
    strength sigma_c (Pa) and toughness G_c (J/m^2)."""
    return E * G_c / sigma_c**2


def fragmentation_strain_rate(E, rho, G_c, sigma_c):
    """eps_dot_0 = c sigma_c^3 / (E^2 G_c) (1/s), c = sqrt(E / rho): the rate at which the
    time to reach sigma_c, sigma_c / (E eps_dot), equals L0 / c. E Pa, rho kg/m^3, G_c J/m^2,
    sigma_c Pa."""
    return np.sqrt(E / rho) * sigma_c**3 / (E**2 * G_c)


def grady_size(rate):
    """Grady 1988 (J. Mech. Phys. Solids 36:353), energy balance: s / L0 = (24 / rate^2)^(1/3),
    rate = eps_dot / eps_dot_0 (i.e. s = (24 G_c / (rho eps_dot^2))^(1/3))."""
    return np.cbrt(24 / np.asarray(rate, dtype=float) ** 2)


def glenn_chudnovsky_size(rate):
    """Glenn & Chudnovsky 1986 (J. Appl. Phys. 59:1379), elastic and fracture energy:
    s / L0 = (4 / rate) sinh(asinh(1.5 rate) / 3); 2 at low rate, Grady's at high rate."""
    rate = np.asarray(rate, dtype=float)
    return 4 / rate * np.sinh(np.arcsinh(1.5 * rate) / 3)


def zhou_molinari_ramesh_size(rate):
    """Zhou, Molinari & Ramesh 2006 (Appl. Phys. Lett. 88:261918), fit to 1D simulations of a
    linear-softening bar: s / L0 = 4.5 / (1 + 4.5 rate^(2/3))."""
    return 4.5 / (1 + 4.5 * np.asarray(rate, dtype=float) ** (2 / 3))


# Single-degree-of-freedom model of a one-way wall strip (Biggs 1964, "Introduction to
# Structural Dynamics", ch. 5, table 5.1; UFC 3-340-02 ch. 3). Everything is
# per metre of wall width: loads and resistances are total forces on the strip (N/m), the
# pressure being p = F / L.

# Biggs's tabulated factors for a uniformly loaded strip with distributed mass. K_LM is his
# rounded column, not K_M / K_L (0.41 / 0.53 = 0.774); docs/wall.md's f = 396 Hz uses 0.77.
# The plastic row is the mechanism: one midspan hinge (simple) or three hinges (clamped).
_TRANSFORMATION_FACTORS = {
    "clamped": {"K_L": 0.53, "K_M": 0.41, "K_LM": 0.77, "K_LM_plastic": 0.66},
    "simple": {"K_L": 0.64, "K_M": 0.50, "K_LM": 0.78, "K_LM_plastic": 0.66},
}
# 384 EI / (c L^3) relates the total load F = p L to the midspan deflection, elastic range.
_STIFFNESS_DIVISOR = {"clamped": 1.0, "simple": 5.0}


def _check_supports(supports):
    if supports not in _TRANSFORMATION_FACTORS:
        raise ValueError(f"supports must be one of {sorted(_TRANSFORMATION_FACTORS)}, "
                         f"got {supports!r}")


@dataclass(frozen=True)
class StripSDOF:
    """Equivalent SDOF of a one-way strip, per metre of width (Biggs 1964, table 5.1).

    span     L, m
    M        total mass rho h L, kg/m
    EI       bending stiffness, N m^2/m
    k        elastic stiffness, total load F = p L per midspan deflection, N/m per m (= N/m^2)
    K_L, K_M load and mass factors, elastic range
    K_LM     load-mass factor, elastic range
    K_LM_plastic  load-mass factor of the plastic mechanism
    """
    span: float
    M: float
    EI: float
    k: float
    K_L: float
    K_M: float
    K_LM: float
    K_LM_plastic: float

    @property
    def omega(self):
        """Elastic circular frequency sqrt(k / (K_LM M)), rad/s."""
        return np.sqrt(self.k / (self.K_LM * self.M))

    @property
    def f(self):
        """Elastic natural frequency omega / (2 pi), Hz."""
        return self.omega / (2 * np.pi)

    @property
    def T(self):
        """Elastic natural period 1 / f, s."""
        return 1 / self.f


def strip_properties(E, rho, thickness, span, supports, nu=0.0):
    """SDOF properties of a one-way strip of a wall under uniform pressure, per metre of
    width (Biggs 1964, table 5.1).

    E Pa, rho kg/m^3, thickness h m, span L m; supports "clamped" (fixed-fixed) or "simple".
    nu: Poisson's ratio of cylindrical bending, EI = E h^3 / (12 (1 - nu^2)). The default 0
    gives the beam value EI_g; a plane-strain 2D section of the wall (the
    strip cannot contract across its width) bends with the bulk nu (0.2: EI +4 %, f +2 %).
    M = rho h L (kg/m); k = 384 EI / L^3 clamped, 384 EI / (5 L^3) simple (N/m per m);
    f = sqrt(k / (K_LM M)) / (2 pi). Raises ValueError for other supports.
    """
    _check_supports(supports)
    EI = E * thickness**3 / (12 * (1 - nu**2))
    k = 384 * EI / (_STIFFNESS_DIVISOR[supports] * span**3)
    return StripSDOF(span=span, M=rho * thickness * span, EI=EI, k=k,
                     **_TRANSFORMATION_FACTORS[supports])


def bending_resistance(M_ps, M_pm, span, supports):
    """Ultimate resistance R_m of a uniformly loaded one-way strip (Biggs 1964, table 5.1;
    UFC 3-340-02 ch. 3): the total load per metre of width (N/m) that forms the mechanism,
    8 (M_ps + M_pm) / L clamped, 8 M_pm / L simple. M_ps, M_pm: plastic moments at the
    supports and at midspan, N m/m; span L, m. The pressure is R_m / L (Pa)."""
    _check_supports(supports)
    if supports == "clamped":
        return 8 * (M_ps + M_pm) / span
    return 8 * M_pm / span


def rebar_plastic_moment(area_per_width, f_y, d, f_c):
    """Plastic moment of an under-reinforced section, per metre of width (N m/m): the
    Whitney stress block of UFC 3-340-02 ch. 4 (and ACI 318), M_p = A_s f_y (d - a / 2),
    a = A_s f_y / (0.85 f_c). A_s: tension steel area per width, m^2/m; f_y: steel yield
    stress, Pa; d: depth of that steel from the compressed face, m; f_c: concrete compressive
    strength, Pa. Static strengths in, static moment out: dynamic increase factors are the
    caller's choice."""
    a = area_per_width * f_y / (0.85 * f_c)
    return area_per_width * f_y * (d - a / 2)


def sdof_response(props, pressure, t_end, dt=None, resistance=None, K_LM=None):
    """Midspan deflection history of a strip SDOF from rest (Biggs 1964 ch. 5):
    K_LM M y'' + R(y) = F(t) = p(t) L.

    props StripSDOF; pressure: p(t) in Pa, vectorised over t (s); t_end s.
    resistance: None for R = k y, or R_m (N/m, e.g. bending_resistance) for an
    elastic-perfectly-plastic R = k (y - y_p) limited to +-R_m (same resistance in rebound).
    K_LM: None uses props.K_LM while elastic and props.K_LM_plastic while yielding, with y
    and y' continuous at the switch as in Biggs's range-by-range integration (kinetic energy
    jumps there); a number fixes one factor for the whole history.
    dt: the step, s; the default min(T / 200, t_end / 2000) keeps the scheme's period error
    (omega dt)^2 / 12 below 1e-4 and samples the load 2000 times: pass a smaller dt for load
    features shorter than ~t_end / 100.
    Average-acceleration Newmark (trapezoidal rule; unconditionally stable, second order, no
    numerical damping); each step is solved exactly on the elastic or the yielding branch,
    picked by an elastic trial.
    Returns t (n + 1,) s and y (n + 1,) m, y > 0 in the direction of p > 0.
    """
    if dt is None:
        dt = min(props.T / 200, t_end / 2000)
    n = int(np.ceil(t_end / dt))
    t = np.linspace(0.0, t_end, n + 1)
    h = t[1] - t[0]
    F = np.broadcast_to(np.asarray(pressure(t), dtype=float) * props.span, t.shape)
    m_elastic = (props.K_LM if K_LM is None else K_LM) * props.M
    m_plastic = (props.K_LM_plastic if K_LM is None else K_LM) * props.M
    R_m = np.inf if resistance is None else resistance
    k = props.k
    c = 4 / h**2
    y = np.zeros(n + 1)
    v, a, y_p = 0.0, F[0] / m_elastic, 0.0
    for i in range(1, n + 1):
        # Newmark: a_{i} = c (y_i - y_star), v_i = v_{i-1} + h (a_{i-1} + a_i) / 2
        y_star = y[i - 1] + h * v + h**2 / 4 * a
        y_i = (F[i] + m_elastic * c * y_star + k * y_p) / (m_elastic * c + k)
        R = k * (y_i - y_p)
        if abs(R) > R_m:
            R = np.copysign(R_m, R)
            y_i = y_star + (F[i] - R) / (m_plastic * c)
            y_p = y_i - R / k
        a_i = c * (y_i - y_star)
        v += h / 2 * (a + a_i)
        a = a_i
        y[i] = y_i
    return t, y


def sdof_peak_deflection(props, pressure, t_end, dt=None, resistance=None, K_LM=None):
    """Largest midspan deflection (m) of sdof_response (same arguments) and its time (s)."""
    t, y = sdof_response(props, pressure, t_end, dt=dt, resistance=resistance, K_LM=K_LM)
    i = np.argmax(y)
    return y[i], t[i]


def step_load_peak_deflection(F_0, k, R_m=np.inf):
    """Peak deflection (m) of an SDOF from rest under a step load F_0 (N/m), elastic stiffness
    k (N/m per m), elastic-perfectly-plastic with resistance R_m (N/m) (Biggs 1964 ch. 2 and 5):
    2 F_0 / k (dynamic load factor 2) while 2 F_0 <= R_m; else, from F_0 y_max =
    R_m (y_max - y_e / 2) with y_e = R_m / k, y_max = R_m y_e / (2 (R_m - F_0)); inf when
    F_0 >= R_m (no bound). Independent of the mass. Vectorised over F_0 and R_m."""
    F_0, R_m = np.broadcast_arrays(np.asarray(F_0, dtype=float), np.asarray(R_m, dtype=float))
    # the plastic branch is evaluated everywhere, including where it is discarded (R_m = inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        plastic = R_m**2 / (2 * k * (R_m - F_0))
    return np.where(2 * F_0 <= R_m, 2 * F_0 / k, np.where(F_0 < R_m, plastic, np.inf))


def impulsive_elastic_deflection(impulse, K_LM, M, k):
    """Peak deflection (m) of an elastic SDOF under a pulse much shorter than its period
    (Biggs 1964 ch. 2): the impulse gives the velocity impulse / (K_LM M), hence
    y_max = impulse / (K_LM M omega) = impulse / sqrt(K_LM M k). impulse: int F dt, N s/m
    (the pressure impulse times L); M kg/m; k N/m per m."""
    return impulse / np.sqrt(K_LM * M * k)


def rigid_plastic_impulsive_deflection(impulse, K_LM, M, R_m):
    """Peak deflection (m) of a rigid-plastic SDOF under a short pulse (Biggs 1964 ch. 5): the
    kinetic energy impulse^2 / (2 K_LM M) is dissipated by R_m,
    y_max = impulse^2 / (2 K_LM M R_m). impulse N s/m, M kg/m, R_m N/m; the same formula holds
    per square metre (Pa s, kg/m^2, Pa)."""
    return impulse**2 / (2 * K_LM * M * R_m)


# Thin (Kirchhoff) rectangular plates under a uniform pressure q: sides a (x) and b (y), m;
# flexural rigidity D = E t^3 / (12 (1 - nu^2)), N m. Timoshenko & Woinowsky-Krieger (1959),
# "Theory of Plates and Shells", §30 (Navier, simply supported, table 8: w = 0.00406 q a^4 / D
# for a square) and §44 (clamped, table 35: 0.00126 q a^4 / D).

def plate_rigidity(E, thickness, nu):
    """Flexural rigidity D = E t^3 / (12 (1 - nu^2)) (N m) of a plate t (m) thick; E Pa."""
    return E * thickness**3 / (12 * (1 - nu**2))


def simply_supported_plate_deflection(q, a, b, D, terms=201):
    """Centre deflection (m) of a simply supported a x b plate (m) under q (Pa): Navier's
    series 16 q / (pi^6 D) sum over odd m, n of (-1)^((m+n)/2 - 1) / (m n (m^2/a^2 +
    n^2/b^2)^2). ``terms`` odd indices per axis; the error falls as terms^-5."""
    k = np.arange(1, 2 * terms, 2)
    m, n = np.meshgrid(k, k, indexing="ij")
    sign = (-1.0) ** ((m + n) // 2 - 1)
    return float(16 * q / (np.pi**6 * D) * np.sum(sign / (m * n * (m**2 / a**2 + n**2 / b**2)**2)))


def clamped_plate_deflection(q, a, b, D, terms=5):
    """Centre deflection (m) of an a x b plate (m) clamped on its four edges under q (Pa),
    by Ritz on w = sum c_ij phi_i(2x/a) phi_j(2y/b), phi_i(s) = (1 - s^2)^2 s^(2i), i <
    ``terms`` (clamped on s = +-1, even like the load). With w = dw/dn = 0 on the edges the
    twist term of the energy integrates to zero, so the energy is D/2 int (lap w)^2 - int q w
    and the answer does not depend on nu. Converged to 5 digits from 3 terms on a square
    (0.0012653 q a^4 / D; one term gives the textbook 0.00133); more than ~6 terms gain
    nothing in float64 (the monomial basis is ill-conditioned)."""
    s = np.polynomial.Polynomial([0.0, 1.0])
    phi = [(1 - s**2)**2 * s**(2 * i) for i in range(terms)]

    def integral(p):
        antiderivative = p.integ()
        return antiderivative(1.0) - antiderivative(-1.0)

    gram = [np.array([[integral(p.deriv(k) * r.deriv(k)) for r in phi] for p in phi]) for k in range(3)]
    mean = np.array([integral(p) for p in phi])
    # on s in [-1, 1]: d/dx = (2/a) d/ds, dA = (a b / 4) ds dt; int w_xx w_yy = int w_xy^2
    K = D * a * b / 4 * ((2 / a)**4 * np.kron(gram[2], gram[0]) + (2 / b)**4 * np.kron(gram[0], gram[2])
                         + 2 * (2 / a)**2 * (2 / b)**2 * np.kron(gram[1], gram[1]))
    c = np.linalg.solve(K, q * a * b / 4 * np.kron(mean, mean))
    return float(c[0])  # phi_i(0) = 1 for i = 0, else 0


def plate_deflection(q, a, b, D, supports):
    """Centre deflection (m) of a thin rectangular plate, ``supports`` "clamped" or "simple"
    on all four edges (the two functions above). Raises ValueError for other supports."""
    if supports == "clamped":
        return clamped_plate_deflection(q, a, b, D)
    if supports == "simple":
        return simply_supported_plate_deflection(q, a, b, D)
    raise ValueError(f"supports must be 'clamped' or 'simple', got {supports!r}")


def catenary_sag_elastic(q, span, E_s, area):
    """Midspan sag (m) of an initially straight, unstressed elastic cable pinned at both
    ends a distance ``span`` (m) apart, under a uniform transverse load q (N/m; N/m per
    metre of depth in 2D with ``area`` per metre): the taut-cable (membrane) cubic.

    Small sag: the shape is the parabola y = q x (span - x) / (2 H), H the horizontal
    tension; its strain (1 / span) int 1/2 y'^2 dx = q^2 span^2 / (24 H^2) gives
    H = E_s A eps, i.e. H^3 = E_s A q^2 span^2 / 24 (Irvine, Cable Structures, 1981,
    a taut flat cable), and w = q span^2 / (8 H) = (3 q span^4 / (64 E_s A))^(1/3).
    Neglects O((w / span)^2): the tension's variation H / cos(phi) and higher slopes."""
    return (3 * q * span**4 / (64 * E_s * area)) ** (1 / 3)


def catenary_sag_plastic(q, span, area, f_y):
    """Midspan sag (m) of a cable pinned at both ends ``span`` (m) apart once it yields
    under a uniform transverse load q (N/m): the parabola's horizontal tension is held at
    A f_y, so w = q span^2 / (8 A f_y) (small sag, as catenary_sag_elastic). Valid when the
    elastic sag's strain 8 w^2 / (3 span^2) exceeds f_y / E_s: the elastic cable would
    yield first."""
    return q * span**2 / (8 * area * f_y)
