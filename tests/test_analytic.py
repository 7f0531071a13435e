"""Closed forms of analytic.py against each other, an independent 1D bar and published numbers."""
import dataclasses

import numpy as np
import pytest

from dolfrag import loads
from dolfrag.reference import analytic


def test_bar_wave_speed_of_concrete_is_3859_m_s():
    # docs/hopkinson.md: E = 35 GPa, rho = 2350 -> bar speed c = 3859 m/s (E alone, 1D)
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
    # a ramped pulse spalls at c sigma_c / (2 |dp/dt of the tail|) (docs/hopkinson.md)
    c, sigma_c = 3700.0, 5e6
    pulse = loads.triangular(10e6, 5e-6, 25e-6)  # tail: 10 MPa over 20 us
    expected = c * sigma_c / (2 * 10e6 / 20e-6)
    # 2.3e-5 m sampling in s and 1.25e-8 s in tau (c tau = 4.6e-5 m): within 1e-4 m
    assert analytic.spall_distance(pulse, c, sigma_c, 25e-6) == pytest.approx(expected, abs=1e-4)


def test_no_spall_below_the_strength():
    assert analytic.spall_distance(loads.triangular(4e6, 0.0, 25e-6), 3700.0, 5e6, 25e-6) is None


def brittle_bar(pressure, E, rho, sigma_c, length, t_end, cells=1200):
    """An independent 1D check of bar_spall: a staggered finite-difference bar at Courant
    number 0.999 (velocities at nodes, stresses in cells), the pressure on x = 0, free at
    x = length; the first cell to reach sigma_c in tension breaks (its stress is zero from
    then on) and no other does. Returns (distance of the break from the free end (m), its
    time (s), centre-of-mass velocities (m/s) of the free-side and loaded-side pieces at t_end)."""
    dx = length / cells
    dt = 0.999 * dx / np.sqrt(E / rho)
    m = np.full(cells + 1, rho * dx)
    m[[0, -1]] /= 2
    v, stress = np.zeros(cells + 1), np.zeros(cells)  # tension positive
    cut, when = None, None
    for k in range(int(np.ceil(t_end / dt))):
        force = np.zeros(cells + 1)
        force[:-1] += stress
        force[1:] -= stress
        force[0] += pressure((k + 0.5) * dt)
        v += dt * force / m
        stress += E * dt * np.diff(v) / dx
        if cut is None and stress.max() >= sigma_c:
            cut, when = int(np.flatnonzero(stress >= sigma_c)[-1]), (k + 1) * dt  # nearest the free end
        if cut is not None:
            stress[cut] = 0.0
    free, loaded = slice(cut + 1, None), slice(0, cut + 1)
    return (length - (cut + 0.5) * dx, when, m[free] @ v[free] / m[free].sum(),
            m[loaded] @ v[loaded] / m[loaded].sum())


# docs/hopkinson.md §2: the BE16 and BE12 pulses (rise 10 us, decay at E eps_dot)
@pytest.mark.parametrize("sigma_0, sigma_c, duration", [(36e6, 21e6, 58.98e-6), (58e6, 28e6, 83.65e-6)])
def test_bar_spall_matches_a_finite_difference_bar(sigma_0, sigma_c, duration):
    E, rho, L = 35e9, 2350.0, 0.12
    pulse = loads.triangular(sigma_0, 10e-6, duration)
    # measured at 80 us, before BE12's pulse has fully entered
    closed = analytic.bar_spall(pulse, analytic.wave_speed(E, rho), rho, sigma_c, L, duration, at=80e-6)
    distance, time, v_scab, v_rest = brittle_bar(pulse, E, rho, sigma_c, L, 80e-6)
    # the bar's cells are 0.1 mm and its steps 26 ns: the plane within one cell, the time
    # within a few steps
    assert closed.distance == pytest.approx(distance, abs=1.5e-4)
    assert closed.time == pytest.approx(time, abs=0.1e-6)
    # momentum is exact in the bar up to the break; a cell's error in the plane moves the
    # masses by 0.2 %
    assert closed.scab_velocity == pytest.approx(v_scab, rel=5e-3)
    assert closed.rest_velocity == pytest.approx(v_rest, rel=5e-3)


def test_block_velocities_of_be16_differ_from_the_crack_speed_jump():
    # The blocks' centre-of-mass velocity difference is, in 1D, scab minus rest: 3.44 m/s for
    # BE16 (brittle_bar: 5.62 - 2.19), not the crack's sigma_c / (rho c) = 2.32 m/s
    # (docs/hopkinson.md)
    E, rho = 35e9, 2350.0
    closed = analytic.bar_spall(loads.triangular(36e6, 10e-6, 58.98e-6), analytic.wave_speed(E, rho), rho,
                                21e6, 0.12, 58.98e-6)
    # the scab's velocity is (2 sigma_0 - sigma_c) / (rho c) on a linear tail.
    # The window opens at a sample of 2001 over the 59 us pulse, up to 29 ns after the rise
    # ends: 0.735 MPa/us x 29 ns on a mean 25.5 MPa is <= 8.4e-4 relative (measured -7.7e-4)
    assert closed.scab_velocity == pytest.approx(analytic.triangular_scab_velocity(36e6, 21e6, rho,
                                                                                   analytic.wave_speed(E, rho)),
                                                 rel=1e-3)
    assert closed.relative_velocity > 1.25 * analytic.ejection_velocity(21e6, rho, E)


# SDOF of a one-way wall strip (Biggs 1964), per metre of width
WALL = analytic.strip_properties(E=35e9, rho=2350, thickness=0.1, span=1.0, supports="clamped")


def constant(p):
    """p(t) = p (Pa) for t >= 0: a step load applied at t = 0."""
    return lambda t: np.full_like(t, p)


def test_strip_properties_of_the_wall():
    # the wall of docs/wall.md, 3 digits: M = 235 kg/m^2, EI_g = 2.92 MN m^2/m, k = 1.12e9, f = 396 Hz
    assert WALL.M == pytest.approx(235, abs=0.5)
    assert WALL.EI == pytest.approx(2.92e6, abs=0.005e6)
    assert WALL.k == pytest.approx(1.12e9, abs=0.005e9)
    assert WALL.f == pytest.approx(396, abs=0.5)


@pytest.mark.parametrize("supports, beta_L", [("clamped", 4.7300), ("simple", np.pi)])
def test_sdof_frequency_is_the_euler_bernoulli_first_mode(supports, beta_L):
    # f_1 = (beta L)^2 / (2 pi L^2) sqrt(EI / (rho h)). The static shape's Rayleigh quotient
    # is <= 0.4 % high, and Biggs's 2-digit K_LM moves f by up to 0.7 %: within 1 %
    strip = analytic.strip_properties(35e9, 2350, 0.1, 1.0, supports)
    f_1 = beta_L**2 / (2 * np.pi) * np.sqrt(strip.EI / (2350 * 0.1))
    assert strip.f == pytest.approx(f_1, rel=1e-2)


def test_unknown_supports_are_rejected_by_name():
    with pytest.raises(ValueError, match="supports.*clamped.*simple"):
        analytic.strip_properties(35e9, 2350, 0.1, 1.0, "pinned")


def test_step_load_peak_is_2F0_over_k_at_half_period():
    F_0 = 1e5 * WALL.span
    y_max, t_max = analytic.sdof_peak_deflection(WALL, constant(1e5), WALL.T)
    # dt = T / 200: the sampled peak misses the true one by <= dt / 2, i.e. by
    # 1 - cos(pi / 200) = 1.2e-4 of the amplitude F_0 / k, 6e-5 of the peak
    assert y_max == pytest.approx(analytic.step_load_peak_deflection(F_0, WALL.k), rel=1e-4)
    assert t_max == pytest.approx(WALL.T / 2, abs=WALL.T / 200)


def test_short_pulse_peak_is_impulse_over_K_LM_M_omega():
    t_d, p_0 = WALL.T / 100, 1e5
    impulse = p_0 * t_d / 2 * WALL.span
    y_max, _ = analytic.sdof_peak_deflection(WALL, loads.triangular(p_0, t_d / 2, t_d), WALL.T / 2,
                                             dt=t_d / 100)
    # finite duration: 1 - (omega t_d)^2 / 48 = 1 - 8e-5 for a symmetric triangle; trapezoidal
    # sampling of the kinks off the grid: <= (dt / t_d)^2 = 1e-4 of the impulse
    expected = analytic.impulsive_elastic_deflection(impulse, WALL.K_LM, WALL.M, WALL.k)
    assert y_max == pytest.approx(expected, rel=5e-4)


def test_slow_ramp_is_followed_quasi_statically():
    # exact ramp response: y - F / k = -(F_0 / k) sin(omega t) / (omega t_r), so the lag is
    # bounded by F_0 / (k omega t_r) (0.8 % of F_0 / k here) and reached; the scheme's
    # amplitude error, (omega dt)^2 / 12 ~ 1e-4, is within the 1e-3 margins
    p_0, t_r = 1e5, 20 * WALL.T
    F_over_k = lambda t: p_0 * WALL.span * np.clip(t / t_r, 0, 1) / WALL.k  # noqa: E731
    t, y = analytic.sdof_response(WALL, lambda t: p_0 * np.clip(t / t_r, 0, 1), t_r)
    bound = p_0 * WALL.span / (WALL.k * WALL.omega * t_r)
    lag = np.max(np.abs(y - F_over_k(t)))
    assert bound * (1 - 1e-3) <= lag <= bound * (1 + 1e-3)


def test_elastoplastic_step_peak_is_Rm_ye_over_2_Rm_minus_F0():
    # one K_LM for the whole history: the energy balance behind the closed form holds only
    # if the mass factor does not switch
    R_m = WALL.k * 1e-3
    F_0 = 0.8 * R_m
    y_max, _ = analytic.sdof_peak_deflection(WALL, constant(F_0 / WALL.span), 2 * WALL.T,
                                             resistance=R_m, K_LM=WALL.K_LM)
    # dt = T / 1000: the trapezoidal work of R over the step that crosses the kink errs by
    # ~ k (v dt)^2 / 8, 1e-5 of the strain energy; 1e-4 leaves room for the peak sampling
    assert y_max == pytest.approx(analytic.step_load_peak_deflection(F_0, WALL.k, R_m), rel=1e-4)
    assert y_max == pytest.approx(2.5 * R_m / WALL.k, rel=1e-4)


def test_rigid_plastic_impulsive_peak_is_I2_over_2_KLM_M_Rm():
    # k -> infinity: 1e6 x the wall's stiffness, R_m / k = 2e-10 m of elastic deflection, and
    # the elastic phase lasts far less than a step: the default factor switch is exercised
    rigid = dataclasses.replace(WALL, k=1e6 * WALL.k)
    R_m, F_0 = 2.7e5, 2.7e8
    impulse = np.sqrt(2 * WALL.K_LM_plastic * WALL.M * R_m * 0.05)  # 5 cm expected
    t_d = 2 * impulse / F_0
    expected = analytic.rigid_plastic_impulsive_deflection(impulse, WALL.K_LM_plastic, WALL.M, R_m)
    y_max, _ = analytic.sdof_peak_deflection(rigid, loads.triangular(F_0 / WALL.span, t_d / 2, t_d),
                                             2 * np.sqrt(2 * expected * WALL.K_LM_plastic * WALL.M / R_m),
                                             dt=t_d / 50, resistance=R_m)
    # the pulse is not instantaneous: R_m removes up to R_m t_d of its momentum, so up to
    # 2 R_m t_d / I = 4e-3 of y_max (2e-3 measured)
    assert y_max == pytest.approx(expected, rel=2 * R_m * t_d / impulse)


def test_mechanism_accelerates_with_the_plastic_load_mass_factor():
    # past R_m, v^2 = 2 (F - R_m) y / (K_LM M), i.e. y = (F - R_m) t^2 / (2 K_LM M)
    # with K_LM = 0.66; the elastic 0.77 would be 14 % off
    stiff = dataclasses.replace(WALL, k=1e4 * WALL.k)
    R_m = 2.7e5
    F_0, t_end = 1.5 * R_m, 0.01
    t, y = analytic.sdof_response(stiff, constant(F_0 / WALL.span), t_end, dt=1e-6, resistance=R_m)
    expected = (F_0 - R_m) * t_end**2 / (2 * WALL.K_LM_plastic * WALL.M)
    # the elastic phase, t_y = acos(1 - R_m / F_0) / omega, starts the parabola late and fast:
    # an O(t_y / t_end) error (1.9 t_y / t_end measured)
    t_y = np.arccos(1 - R_m / F_0) / stiff.omega
    assert y[-1] == pytest.approx(expected, rel=4 * t_y / t_end)


def test_clamped_wall_resistance_from_its_bars():
    # the wall's bars: Ø10/150 each face, f_y = 500 MPa, d = 70 mm -> M_p ~ 17 kN m/m (2 digits);
    # f_c = 40 MPa as in §5
    A_s = np.pi * 0.010**2 / 4 / 0.150
    M_p = analytic.rebar_plastic_moment(A_s, 500e6, 0.070, 40e6)
    assert M_p == pytest.approx(17e3, abs=0.5e3)
    # R_m = 8 (M_ps + M_pm) / L = 16 M_p ~ 2.7 bar on 1 m (from the rounded 17 kN m/m)
    assert analytic.bending_resistance(17e3, 17e3, 1.0, "clamped") == pytest.approx(2.7e5, abs=0.05e5)
    assert analytic.bending_resistance(17e3, 17e3, 1.0, "simple") == pytest.approx(1.36e5)


@pytest.mark.parametrize("rate, zmr, grady, gc", [(0.1, 2.28, 13.4, 1.99), (1, 0.818, 2.88, 1.64),
                                                  (10, 0.206, 0.621, 0.557), (100, 0.0459, 0.134, 0.131),
                                                  (1000, 0.0100, 0.0288, 0.0287)])
def test_fragment_sizes_match_the_printed_table(rate, zmr, grady, gc):
    # a table of the three theories printed to 3 significant digits: within half a unit of the last
    for size, printed in ((analytic.zhou_molinari_ramesh_size, zmr), (analytic.grady_size, grady),
                          (analytic.glenn_chudnovsky_size, gc)):
        assert size(rate) == pytest.approx(printed, rel=5e-3, abs=5e-5)


def test_fragmentation_scales_of_the_zmr_material():
    # Zhou, Molinari & Ramesh's material: E = 275 GPa, rho = 2750, sigma_c = 300 MPa, G_c = 100 N/m ->
    # L0 = 0.306 mm, eps_dot_0 = 3.57e4 1/s (3 digits)
    E, rho, sigma_c, G_c = 275e9, 2750.0, 300e6, 100.0
    assert analytic.fragmentation_length(E, G_c, sigma_c) == pytest.approx(0.306e-3, rel=2e-3)
    assert analytic.fragmentation_strain_rate(E, rho, G_c, sigma_c) == pytest.approx(3.57e4, rel=2e-3)
    # Grady's dimensional form (24 G_c / (rho eps_dot^2))^(1/3) is s / L0 times L0
    rate = 1e5
    grady = analytic.grady_size(rate / analytic.fragmentation_strain_rate(E, rho, G_c, sigma_c))
    assert grady * analytic.fragmentation_length(E, G_c, sigma_c) == pytest.approx(
        np.cbrt(24 * G_c / (rho * rate**2)), rel=1e-12)


# Thin plates under uniform pressure: the coefficient alpha of w = alpha q a^4 / D
def plate_alpha(deflection, b_over_a=1.0, **kw):
    return deflection(1.0, 1.0, b_over_a, 1.0, **kw)


def test_clamped_square_plate_deflects_0_00126_q_a4_over_D():
    # Timoshenko & Woinowsky-Krieger (1959) table 35 prints 0.00126, three digits cut
    # from the converged value (0.0012653 here): within one unit of the last digit
    assert plate_alpha(analytic.clamped_plate_deflection) == pytest.approx(0.00126, abs=1e-5)
    # the one-term Ritz value of the textbooks, (1 - s^2)^2 (1 - t^2)^2 alone: 0.00133
    assert plate_alpha(analytic.clamped_plate_deflection, terms=1) == pytest.approx(0.00133, abs=5e-6)
    # converged: a sixth term moves the fifth digit by less than 1e-4 relative
    assert plate_alpha(analytic.clamped_plate_deflection, terms=6) == pytest.approx(
        plate_alpha(analytic.clamped_plate_deflection), rel=1e-4)


def test_simply_supported_square_plate_deflects_0_00406_q_a4_over_D():
    # Timoshenko & Woinowsky-Krieger table 8: 0.00406; Roark (table 11.4, case 1a,
    # nu = 0.3) writes it w = 0.0444 q a^4 / (E t^3) = 0.0444 / (12 (1 - 0.3^2)) q a^4 / D
    alpha = plate_alpha(analytic.simply_supported_plate_deflection)
    assert alpha == pytest.approx(0.00406, abs=5e-6)  # half a unit of the last digit
    assert 12 * (1 - 0.3**2) * alpha == pytest.approx(0.0444, abs=5e-5)
    # a long plate bends as a strip, 5 q a^4 / (384 D); at b = 20 a the ends are far
    # (their effect decays as exp(-pi b / (2 a)))
    assert plate_alpha(analytic.simply_supported_plate_deflection, 20.0) == pytest.approx(5 / 384, rel=1e-6)


def test_plate_rigidity_is_E_t3_over_12_1_minus_nu2():
    # the slab: E t^3 = 35 GPa x 1e-3 m^3 = 3.5e7 N m over 12 (1 - 0.2^2) = 11.52
    assert analytic.plate_rigidity(35e9, 0.1, 0.2) == pytest.approx(35e9 * 1e-3 / 11.52, rel=1e-12)
    with pytest.raises(ValueError, match="clamped"):
        analytic.plate_deflection(1.0, 1.0, 1.0, 1.0, "rollers")


def test_catenary_sags_balance_the_parabola_tension_against_the_cable_stretch():
    # a taut cable's parabola: H = q L^2 / (8 w), strain 8 w^2 / (3 L^2) (small sag); the
    # elastic sag makes H = E A strain, the plastic one H = A f_y (round-off only)
    q, L, E_s, A, f_y = 2e4, 1.2, 200e9, 5.2e-4, 5e8
    w = analytic.catenary_sag_elastic(q, L, E_s, A)
    assert q * L**2 / (8 * w) == pytest.approx(E_s * A * 8 * w**2 / (3 * L**2), rel=1e-12)
    assert q * L**2 / (8 * analytic.catenary_sag_plastic(q, L, A, f_y)) == pytest.approx(A * f_y, rel=1e-12)
    # the taut-cable cubic H^3 = E A q^2 L^2 / 24 (Irvine 1981)
    assert (q * L**2 / (8 * w)) ** 3 == pytest.approx(E_s * A * q**2 * L**2 / 24, rel=1e-12)
