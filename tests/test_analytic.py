"""Closed forms of analytic.py against each other and against PHYSICS.md's numbers."""
import numpy as np
import pytest

from dolfrag import analytic, loads


def test_p_wave_speed_of_concrete_matches_physics_md():
    # PHYSICS.md §3: E = 35 GPa, rho = 2350 -> bar speed c = 3859 m/s (E alone, 1D)
    assert analytic.wave_speed(35e9, 2350) == pytest.approx(3859, abs=1)


@pytest.mark.parametrize("sigma_0", [6e6, 10e6, 20e6])
def test_general_spall_criterion_reduces_to_the_triangular_closed_forms(sigma_0):
    c, rho, sigma_c, t_d = 3700.0, 2400.0, 5e6, 25e-6
    pulse = loads.triangular(sigma_0, 0.0, t_d)
    delta = analytic.spall_distance(pulse, c, sigma_c, t_d)
    # sampling: 2001 points over c t_d / 2 -> 2.3e-5 m resolution
    assert delta == pytest.approx(analytic.triangular_spall_distance(c * t_d, sigma_c, sigma_0), abs=5e-5)
    V = analytic.scab_velocity(pulse, c, rho, delta)
    # V = 2 sigma_0 / (rho c) (1 - delta / lambda): delta's 2.3e-5 m error on delta >= 11.6 mm
    # moves V by <= 0.3 x 2e-3 = 6e-4 relative; the trapezoid rule is exact on the ramp
    assert V == pytest.approx(analytic.triangular_scab_velocity(sigma_0, sigma_c, rho, c), rel=1e-3)


def test_a_rise_time_moves_the_spall_by_the_unloading_rate_only():
    # PHYSICS.md §3: a ramped pulse spalls at c sigma_c / (2 |dp/dt of the tail|)
    c, sigma_c = 3700.0, 5e6
    pulse = loads.triangular(10e6, 5e-6, 25e-6)  # tail: 10 MPa over 20 us
    expected = c * sigma_c / (2 * 10e6 / 20e-6)
    # 2.3e-5 m sampling in s and 1.25e-8 s in tau (c tau = 4.6e-5 m): within 1e-4 m
    assert analytic.spall_distance(pulse, c, sigma_c, 25e-6) == pytest.approx(expected, abs=1e-4)


def test_no_spall_below_the_strength():
    assert analytic.spall_distance(loads.triangular(4e6, 0.0, 25e-6), 3700.0, 5e6, 25e-6) is None
