"""Loads: pressure-time signals p(t) (Pa) and their application on a boundary.

A positive pressure pushes into the body: the traction on the loaded boundary is
-p(t) n with n the outward normal.

Each signal is a pure function of its parameters (SI units) returning a vectorised p(t),
t in s (a float or an array), zero before t = 0 and after the signal's end (docs/loads.md).
The spatial profile is uniform on the loaded boundary, optionally times ``factor`` in a box
(a local over-pressure): one load vector times one signal. A charge is the exception: each
loaded facet gets its own p(t) from its distance to the charge (charge.py: the airblast
fits; charge_load.py: on the mesh), so the functions here that take one case.Load
signal refuse it.

An "h2-air" load is the deflagration or detonation shape with its levels computed from the
gas mixture, hydrogen in air or in oxygen (gas.py). ``applied(load, comm)`` gives the load as
applied, that shape; the functions here that read a signal take the applied load and refuse
an unshaped h2-air one. The gas states are computed once per process, with ``comm`` on rank 0
for every rank.
"""
from dataclasses import asdict, replace
from functools import reduce

import numpy as np
import ufl
from scipy.optimize import brentq

from dolfrag import compat
from dolfrag.loads import gas
from dolfrag.loads.mixture import Mixture

# h2-air defaults for the keys a case leaves out (docs/loads.md, "Hydrogen-air explosion"):
# the oscillation's amplitude (-), relative to the mean pressure (deflagration) or to the
# AICC plateau (detonation); the reverberations' e-folding time in acoustic periods 1/f
H2_AIR_AMPLITUDE = {"deflagration": 0.1, "detonation": 0.3}
H2_AIR_DAMPING_PERIODS = 3.0


def triangular(peak, rise, duration):
    """p(t): linear rise 0 -> ``peak`` (Pa) over ``rise`` (s), linear decay to 0 at
    ``duration`` (s), zero before 0 and after. Vectorised over t."""
    return lambda t: np.interp(t, [0.0, rise, duration], [0.0, peak, 0.0], left=0.0, right=0.0)


def tabulated(t_table, p_table):
    """p(t) linearly interpolated in a table (s, Pa); zero outside it."""
    return lambda t: np.interp(t, t_table, p_table, left=0.0, right=0.0)


def _window(t, duration):
    """(t clipped to [0, duration], mask of 0 <= t <= duration): the clip keeps the
    exponentials of the shapes finite where the mask zeroes them."""
    t = np.asarray(t, dtype=np.float64)
    return np.clip(t, 0.0, duration), (t >= 0.0) & (t <= duration)


def friedlander(peak, duration, alpha):
    """Modified Friedlander blast wave, positive phase only (no suction after it):

        p(t) = p_s (1 - t/t_d) exp(-alpha t/t_d)   for 0 <= t <= t_d, else 0

    p_s = ``peak`` (Pa) at t = 0, t_d = ``duration`` (s), alpha (-) the decay coefficient,
    >= -1 so that the maximum stays at t = 0 (alpha from the impulse ratio:
    ``friedlander_alpha``). Impulse p_s t_d k(alpha) (``friedlander_impulse_ratio``)."""
    def p(t):
        t, on = _window(t, duration)
        tau = t / duration
        return on * peak * (1.0 - tau) * np.exp(-alpha * tau)
    return p


def friedlander_impulse_ratio(alpha):
    """k = i / (p_s t_d) = 1/alpha - (1 - exp(-alpha)) / alpha^2 (-) of the Friedlander
    positive phase; 1/2 at alpha = 0 (its series below |alpha| = 1e-4, where the closed
    form loses digits to cancellation)."""
    if abs(alpha) < 1e-4:
        return 0.5 - alpha / 6.0 + alpha**2 / 24.0
    return (alpha + np.expm1(-alpha)) / alpha**2


def friedlander_alpha(impulse_ratio):
    """alpha (-) of the Friedlander wave with impulse i = k p_s t_d, k = ``impulse_ratio``
    in (0, e - 2]: the root of ``friedlander_impulse_ratio`` (NAVFAC DM-2.08 eq. 13a table;
    k = e - 2 is alpha = -1, the largest impulse with the peak still at t = 0)."""
    if not 0.0 < impulse_ratio <= np.e - 2.0:
        raise ValueError(f"impulse_ratio = {impulse_ratio!r}: must be in (0, e - 2 = 0.718]")
    # k(alpha) < 1/alpha for alpha > 0, so the root lies below 1/k
    return brentq(lambda a: friedlander_impulse_ratio(a) - impulse_ratio, -1.0, 1.0 / impulse_ratio,
                  xtol=1e-12)


def deflagration(peak, rise, duration, frequency, amplitude):
    """Closed-room deflagration: slow rise, smooth decay, superposed oscillations.

        p(t) = s(t) (1 + a sin(2 pi f t))                      for 0 <= t <= T, else 0
        s(t) = P (4 tau^3 - 3 tau^4),  tau = t / t_r           for t <= t_r
        s(t) = P (1 + cos(pi (t - t_r) / (T - t_r))) / 2       for t_r <= t <= T

    P = ``peak`` (Pa), the peak of the mean pressure s, reached at t_r = ``rise`` (s) > 0;
    T = ``duration`` (s) > t_r; f = ``frequency`` (Hz) and a = ``amplitude`` (-, in [0, 1])
    the oscillation, relative to the mean pressure, so p >= 0 and p <= P (1 + a).
    The rise grows as t^3 at first (a spherical flame's burnt volume, docs/loads.md) and s
    has zero slope at t_r and T, so only the oscillation has time scales shorter than t_r.
    Impulse of s: P (2 t_r / 5 + (T - t_r) / 2)."""
    def p(t):
        t, on = _window(t, duration)
        tau = np.minimum(t / rise, 1.0)
        ramp = 4.0 * tau**3 - 3.0 * tau**4
        fall = 0.5 * (1.0 + np.cos(np.pi * np.maximum(t - rise, 0.0) / (duration - rise)))
        mean = peak * np.where(t <= rise, ramp, fall)
        return on * mean * (1.0 + amplitude * np.sin(2.0 * np.pi * frequency * t))
    return p


def detonation(peak, plateau, decay, duration, frequency, amplitude, damping,
               local_peak=0.0, local_time=None, local_width=None):
    """Detonation reflected at a wall: spike, damped reverberations, optional local peak.

        p(t) = (1 - t/T) [P_q + (P_r - P_q) exp(-t/t_s) + a P_q exp(-t/t_o) sin(2 pi f t)]
               + h cos^2(pi (t - t_h) / w)   (the last term only for |t - t_h| < w/2)
        for 0 <= t <= T, else 0

    P_r = ``peak`` (Pa): the reflected CJ spike at t = 0 (about 2.4 P_CJ); P_q = ``plateau``
    (Pa, <= P_r): the level the reverberations settle to (P_AICC); t_s = ``decay`` (s): the
    spike's e-folding time; f = ``frequency`` (Hz), a = ``amplitude`` (-, in [0, 1],
    relative to P_q) and t_o = ``damping`` (s, the e-folding time of their amplitude): the
    reverberations; T = ``duration`` (s): the factor (1 - t/T) is the slow heat-loss and
    venting decay, UFC 3-340-02's triangular gas pressure, and ends p continuously at T;
    h = ``local_peak`` (Pa, 0 for none) at t_h = ``local_time`` (s), full width w =
    ``local_width`` (s), inside [0, T]: a second pressure peak (e.g. a reflection from a
    far wall), impulse h w / 2. p >= 0 (a <= 1), p(0) = P_r, which is the maximum when the
    spike falls faster than the reverberations and local peak rise."""
    omega = 2.0 * np.pi * frequency

    def p(t):
        t, on = _window(t, duration)
        level = plateau + (peak - plateau) * np.exp(-t / decay) \
            + amplitude * plateau * np.exp(-t / damping) * np.sin(omega * t)
        pressure = (1.0 - t / duration) * level
        if local_peak > 0.0:
            phase = (t - local_time) / local_width
            pressure = pressure + np.where(np.abs(phase) < 0.5, local_peak * np.cos(np.pi * phase) ** 2, 0.0)
        return on * pressure
    return p


def acoustic_frequency(sound_speed, length):
    """f = c / (2 L) (Hz): the fundamental of gas of sound speed c (m/s) between two rigid
    walls L (m) apart (the first longitudinal mode of a closed room)."""
    return sound_speed / (2.0 * length)


def h2_mixture(load):
    """The mixture.Mixture of an h2-air case.Load (an air mixture takes no diluent)."""
    if load.oxidizer == "air":
        return Mixture(load.h2_fraction)
    return Mixture(load.h2_fraction, load.oxidizer, load.diluent, load.diluent_fraction)


def applied(load, comm=None):
    """The case.Load as applied to the structure: an h2-air load becomes its deflagration
    or detonation (``load.regime``); any other load is returned unchanged. Overpressures (Pa), the mixture's gas.Explosion E, p0 its initial
    pressure, eta = ``heat_loss``, L = ``room_length``:

    deflagration: peak (1 - eta)(E.P_AICC - p0), frequency E.c_b / (2 L), rise and duration
    as given, amplitude as given or H2_AIR_AMPLITUDE;
    detonation: peak E.P_reflected - p0 (the spike is too short to lose heat), plateau
    (1 - eta)(E.P_AICC - p0), frequency E.c_b / (2 L), decay as given or L / E.D_CJ (the
    detonation's crossing time), damping as given or H2_AIR_DAMPING_PERIODS / f, amplitude
    as given or H2_AIR_AMPLITUDE, no local peak.

    With ``comm`` collective (gas.explosion: rank 0 computes, every rank gets its numbers)."""
    if load.signal != "h2-air":
        return load
    state = gas.explosion(h2_mixture(load), load.T0, load.p0, comm)
    f = acoustic_frequency(state.c_b_m_s, load.room_length)
    aicc = (1.0 - load.heat_loss) * (state.P_AICC_Pa - load.p0)
    amplitude = H2_AIR_AMPLITUDE[load.regime] if load.amplitude is None else load.amplitude
    if load.regime == "deflagration":
        return replace(load, signal="deflagration", peak=aicc, frequency=f, amplitude=amplitude)
    return replace(load, signal="detonation", peak=state.P_reflected_Pa - load.p0, plateau=aicc, frequency=f,
                   amplitude=amplitude, local_peak=0.0,
                   decay=load.room_length / state.D_CJ_m_s if load.decay is None else load.decay,
                   damping=H2_AIR_DAMPING_PERIODS / f if load.damping is None else load.damping)


def h2_air_numbers(load, comm=None):
    """The numbers behind an h2-air load's signal (SI, absolute pressures unless said
    overpressure): the mixture and its initial state, the gas.Explosion, the acoustic
    frequency (Hz), and the shape's overpressures (Pa): its peak, and for a detonation its
    plateau, decay and damping times (s). ``comm`` as in applied."""
    mixture, shaped = h2_mixture(load), applied(load, comm)
    state = gas.explosion(mixture, load.T0, load.p0, comm)
    numbers = {**asdict(mixture), "regime": load.regime, "T0_K": load.T0, "p0_Pa": load.p0,
               "mechanism": gas.MECHANISM, "cantera": gas.ct.__version__, **asdict(state),
               "frequency_Hz": shaped.frequency, "peak_overpressure_Pa": shaped.peak, "heat_loss": load.heat_loss}
    if load.regime == "detonation":
        numbers.update(plateau_overpressure_Pa=shaped.plateau, decay_s=shaped.decay, damping_s=shaped.damping)
    return numbers


def _one_signal(load):
    """ValueError for a charge, whose p(t) differs per facet (charge_load.ChargeLoad), and
    for an h2-air load not yet shaped from its gas."""
    if load.signal == "charge":
        raise ValueError("a charge has one p(t) per loaded facet: build charge_load.ChargeLoad on the mesh")
    if load.signal == "h2-air":
        raise ValueError("an h2-air load's signal is shaped from its gas first: loads.applied(load, comm)")


def signal(load):
    """The p(t) (Pa, vectorised over t in s) of an applied case.Load (``applied``)."""
    _one_signal(load)
    kind = load.signal
    if kind == "triangular":
        return triangular(load.peak, load.rise, load.duration)
    if kind == "friedlander":
        return friedlander(load.peak, load.duration, load.alpha)
    if kind == "deflagration":
        return deflagration(load.peak, load.rise, load.duration, load.frequency, load.amplitude)
    if kind == "detonation":
        return detonation(load.peak, load.plateau, load.decay, load.duration, load.frequency,
                          load.amplitude, load.damping, load.local_peak, load.local_time,
                          load.local_width)
    return tabulated(load.t, load.p)


def signal_end(load):
    """Time (s) after which the signal of an applied case.Load is zero."""
    _one_signal(load)
    return float(load.t[-1]) if load.signal == "table" else load.duration


def shortest_feature(load):
    """The shortest time feature (s) of an applied case.Load's signal, what a time step must
    resolve: a rise or a decay, a table interval, an oscillation's half period (crest to
    trough, as a triangle's rise), the Friedlander initial fall t_d / (1 + alpha) (the time
    its initial slope takes to reach 0), a local peak's rise w / 2; inf if none is > 0."""
    _one_signal(load)
    kind = load.signal
    if kind == "table":
        features = list(np.diff(load.t))
    elif kind in ("triangular", "deflagration"):
        features = [load.rise, load.duration - load.rise]
    elif kind == "friedlander":
        features = [load.duration / max(1.0, 1.0 + load.alpha)]
    else:
        features = [load.decay, load.damping, load.duration]
        if load.local_peak > 0:
            features.append(0.5 * load.local_width)
    if kind in ("deflagration", "detonation") and load.amplitude > 0:
        features.append(0.5 / load.frequency)
    return min([f for f in features if f > 0], default=np.inf)


def accuracy_time_step(load, end, per_feature=20):
    """A step (s) resolving the signal of an applied case.Load: its shortest_feature (s) over
    per_feature, at most end (s) / per_feature. A priori only: it knows nothing of the
    structure's periods or of crack events."""
    return min(shortest_feature(load), end) / per_feature


def signal_summary(load):
    """(peak Pa, time of the peak s, impulse Pa s, end s) of an applied case.Load's signal, sampled
    on [0, end] at 1/200 of its shortest feature (at most 2e6 samples) plus its kinks and
    peaks known in advance (a table's points, the rise, a local peak's centre), so that a
    piecewise-linear p is integrated exactly and a corner peak is not cut."""
    end = signal_end(load)
    count = int(min(2e6, np.ceil(200 * end / min(shortest_feature(load), end)))) + 1
    marks = load.t if load.signal == "table" else [x for x in (load.rise, load.local_time) if x is not None]
    t = np.union1d(np.linspace(0.0, end, count), np.clip(marks, 0.0, end))
    p = signal(load)(t)
    i = int(np.argmax(p))
    return float(p[i]), float(t[i]), float(np.trapz(p, t)), end


def summary_block(load, applied_load, comm=None, charge=None):
    """summary.json's "load" block of a pressure case.Load ``load``, as applied
    (``applied_load``, from ``applied``): its signal's peak (Pa), time of the peak (s),
    impulse (Pa s) and end (s) (signal_summary), and for h2-air the numbers behind it
    (``h2_air``: h2_air_numbers, ``comm`` as there); for a charge, ``charge.summary()`` (its
    charge_load.ChargeLoad)."""
    if load.signal == "charge":
        return charge.summary()
    peak, peak_time, impulse, end = signal_summary(applied_load)
    block = {"signal": load.signal, "peak_Pa": peak, "peak_time_s": peak_time, "impulse_Pa_s": impulse,
             "duration_s": end}
    if load.signal == "h2-air":
        block["h2_air"] = h2_air_numbers(load, comm)
    return block


def unit_pressure_vector(space, domain, boundary, region=None):
    """Nodal forces (Function) of a unit pressure (1 Pa) on a named boundary:
    the integral of -phi(x) n . w over it (N per Pa, per metre of depth in 2D). Collective.

    phi = 1, or with ``region = (lower, upper, factor)`` (two corners of a box, gdim
    coordinates each, m; factor >= 0): phi = factor on the facets whose midpoint is in the
    box, 1 elsewhere, a local over-pressure. phi is read at one point per facet, its midpoint
    (the degree-1 rule, exact for the linear test functions on flat facets)."""
    V = space.V
    w = ufl.TestFunction(V)
    ds = compat.facet_measure(space.mesh, domain.facet_tags)
    n = ufl.FacetNormal(space.mesh)
    tag = domain.boundary_tag(boundary)
    f = compat.Function(V)
    if region is None:
        compat.assemble_vector(-ufl.inner(n, w) * ds(tag), f)
        return f
    lower, upper, factor = region
    if not len(lower) == len(upper) == space.gdim:
        raise ValueError(f"region corners {lower}, {upper}: need {space.gdim} coordinates each (m)")
    x = ufl.SpatialCoordinate(space.mesh)
    inside = reduce(ufl.And, [ufl.And(ufl.ge(x[i], lo), ufl.le(x[i], hi))
                              for i, (lo, hi) in enumerate(zip(lower, upper))])
    phi = ufl.conditional(inside, float(factor), 1.0)
    compat.assemble_vector(-phi * ufl.inner(n, w) * ds(tag, metadata={"quadrature_degree": 1}), f)
    return f
