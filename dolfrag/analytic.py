"""Closed forms used for validation. One pure function per formula, SI units; nothing
runs on import."""
import numpy as np


def p_wave_modulus(E, nu, hypothesis="plane_strain"):
    """Uniaxial-strain (P-wave) modulus lambda + 2 mu (Pa); in plane stress the
    in-plane one, E / (1 - nu^2)."""
    if hypothesis == "plane_stress":
        return E / (1 - nu**2)
    return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def series_interface_modulus(M, C_N, spacing):
    """1D estimate of the modulus of a bulk of modulus M (Pa) cut every ``spacing`` (m) by
    springs C_N (Pa/m) in series: M / (1 + M / (C_N spacing)) (PHYSICS.md §2)."""
    return M / (1 + M / (C_N * spacing))


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
    strength sigma_c (Pa) (PHYSICS.md §3): the smallest s at which the net tension
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


def scab_velocity(pressure, c, rho, delta, samples=2001):
    """Velocity (m/s) of a scab of thickness delta (m) cut by a pulse p(t) (Pa): the momentum
    trapped in it over its mass, (1 / (rho delta)) int_0^{2 delta / c} p(tau) dtau
    (PHYSICS.md §3)."""
    tau = np.linspace(0.0, 2 * delta / c, samples)
    return float(np.trapz(pressure(tau), tau) / (rho * delta))


def triangular_spall_distance(wavelength, sigma_c, sigma_0):
    """Spall plane of a sharp-fronted triangular pulse of peak sigma_0 and spatial length
    wavelength = c t_d: lambda sigma_c / (2 sigma_0) (m, PHYSICS.md §3)."""
    return wavelength * sigma_c / (2 * sigma_0)


def triangular_scab_velocity(sigma_0, sigma_c, rho, c):
    """Scab velocity of a sharp-fronted triangular pulse: (2 sigma_0 - sigma_c) / (rho c), m/s."""
    return (2 * sigma_0 - sigma_c) / (rho * c)


def ejection_velocity(sigma_c, rho, E):
    """Relative velocity (m/s) of the two blocks on either side of a 1D spall plane that
    opens at the tensile strength sigma_c (Pa): sigma_c / sqrt(rho E) = sigma_c / (rho c),
    the particle-velocity jump of the unloading wave the crack sends out (PHYSICS.md §3,
    "Why V_e"); rho kg/m^3, E Pa (the bar modulus)."""
    return sigma_c / np.sqrt(rho * E)


def spall_time(length, delta, c, rise):
    """Time (s) at which the first spall plane, delta (m) from the free end of a bar of
    ``length`` (m), reaches the strength under a pulse rising linearly over ``rise`` (s)
    then decaying linearly, applied at t = 0 on the far end (1D, wave speed c m/s;
    docs/hopkinson.md §3): the reflected peak has travelled L + delta, rise + (L + delta) / c.
    """
    return rise + (length + delta) / c
