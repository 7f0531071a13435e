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
