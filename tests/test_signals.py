"""Explosion signals (dolfrag/loads/, docs/loads.md): peak, duration, impulse and oscillation of each
signal against closed forms; the local over-pressure region; [load] validation; `dolfrag loads`."""
import re

import numpy as np
import pytest
from mpi4py import MPI

from conftest import box, dolfrag_cli, rectangle
from dolfrag import loads, mesh, space as spaces
from dolfrag.case import CaseError, builtin_case_text, load_case
from dolfrag.loads import accuracy_time_step

ATM = 101325.0  # Pa
# stoichiometric H2-air at a wall (docs/loads.md): P_CJ, reflected spike, P_AICC
P_CJ, P_REFL, P_AICC = 15.5 * ATM, 37.5 * ATM, 7.96 * ATM
# a deflagration like the reference paper's: about 0.1 s, oscillation in its measured 45-78 Hz band
DEFLAGRATION = dict(peak=2e5, rise=0.05, duration=0.1, frequency=60.0, amplitude=0.2)
# detonation: 180 Hz = c_AICC / 2L for a 3 m room (c_AICC ~ 1090 m/s); local peak at 8 ms
DETONATION = dict(peak=P_REFL, plateau=P_AICC, decay=0.5e-3, duration=20e-3, frequency=180.0,
                  amplitude=0.3, damping=5e-3, local_peak=5e5, local_time=8e-3, local_width=2e-3)


def crossing_frequency(t, x):
    """Frequency (Hz) of x(t) from its zero crossings, located by linear interpolation."""
    i = np.flatnonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    return (len(crossings) - 1) / (2.0 * (crossings[-1] - crossings[0]))


def closed_form_friedlander_impulse(peak, duration, alpha):
    return peak * duration * (1.0 / alpha - (1.0 - np.exp(-alpha)) / alpha**2)


# ---------------------------------------------------------------- Friedlander
@pytest.mark.parametrize("alpha", [-1.0, -0.52, 0.71, 3.67, 8.87])
def test_friedlander_peaks_at_zero_ends_at_t_d_and_has_the_closed_form_impulse(alpha):
    peak, t_d = 2e5, 4e-3
    p = loads.friedlander(peak, t_d, alpha)
    t = np.linspace(0.0, t_d, 400001)
    values = p(t)
    assert values[0] == peak and np.argmax(values) == 0
    assert p(t_d) == 0 and np.all(p(np.array([-1e-9, t_d * (1 + 1e-9), 1.0])) == 0)
    # trapezoid rule, step 1e-8 s: error ~ (alpha h / t_d)^2 / 12 < 1e-9 relative
    assert np.trapz(values, t) == pytest.approx(closed_form_friedlander_impulse(peak, t_d, alpha), rel=1e-8)


def test_friedlander_with_alpha_0_is_the_triangle_of_zero_rise():
    t = np.linspace(-1e-3, 5e-3, 6001)
    np.testing.assert_allclose(loads.friedlander(2e5, 4e-3, 0.0)(t), loads.triangular(2e5, 0.0, 4e-3)(t),
                               rtol=1e-13, atol=1e-9)  # two roundings of the same straight line


@pytest.mark.parametrize("k,alpha", [(0.7, -0.93), (0.6, -0.52), (0.5, 0.0), (0.4, 0.71), (0.3, 1.77),
                                     (0.2, 3.67), (0.1, 8.87)])
def test_friedlander_alpha_from_impulse_ratio_is_the_navfac_table(k, alpha):
    found = loads.friedlander_alpha(k)
    assert found == pytest.approx(alpha, abs=0.005)  # the table prints alpha to 2 decimals
    t = np.linspace(0.0, 1.0, 200001)
    # the signal with that alpha carries the impulse k p_s t_d (trapezoid error < 1e-9)
    assert np.trapz(loads.friedlander(1.0, 1.0, found)(t), t) == pytest.approx(k, rel=1e-8)


def test_friedlander_alpha_rejects_an_impulse_ratio_with_the_peak_not_at_zero():
    with pytest.raises(ValueError, match="impulse_ratio"):
        loads.friedlander_alpha(0.72)  # above e - 2: alpha < -1


# ---------------------------------------------------------------- deflagration
def deflagration_mean_impulse(peak, rise, duration, **_):
    """Impulse of the mean pressure: int_0^1 (4 tau^3 - 3 tau^4) = 2/5, half-cosine: 1/2."""
    return peak * (0.4 * rise + 0.5 * (duration - rise))


def test_deflagration_mean_pressure_peaks_at_rise_grows_as_t_cubed_and_ends_at_duration():
    prm = {**DEFLAGRATION, "amplitude": 0.0}
    p = loads.deflagration(**prm)
    t = np.union1d(np.linspace(0.0, 0.1, 100001), [prm["rise"]])
    values = p(t)
    assert values.max() == prm["peak"] and p(prm["rise"]) == prm["peak"]
    # zero slope at the peak: neighbours within sqrt(eps) t_r round to the peak too
    assert t[np.argmax(values)] == pytest.approx(prm["rise"], abs=1e-6)
    assert p(0.1) == 0 and np.all(p(np.array([-1e-9, 0.1 + 1e-9, 1.0])) == 0)
    # p(t) / t^3 -> 4 P / t_r^3: at t = 1e-3 t_r the t^4 term is 3/4 1e-3 of it
    assert p(1e-3 * prm["rise"]) / 1e-9 == pytest.approx(4 * prm["peak"], rel=1e-3)
    # trapezoid rule on 1e-6 s steps, p'' <= 12 P / t_r^2: error < 1e-9 relative
    assert np.trapz(values, t) == pytest.approx(deflagration_mean_impulse(**prm), rel=1e-9)


def test_deflagration_oscillation_has_the_given_relative_amplitude_and_keeps_p_in_bounds():
    p = loads.deflagration(**DEFLAGRATION)
    t = np.linspace(0.0, 0.1, 200001)
    values = p(t)
    peak, a = DEFLAGRATION["peak"], DEFLAGRATION["amplitude"]
    assert p(DEFLAGRATION["rise"]) == pytest.approx(peak, rel=1e-13)  # f t_r = 3: sin = 0 at the peak
    assert values.min() >= 0 and values.max() <= peak * (1 + a)
    assert np.all(loads.deflagration(**{**DEFLAGRATION, "amplitude": 1.0})(t) >= 0)
    mean = loads.deflagration(**{**DEFLAGRATION, "amplitude": 0.0})(t)
    inner = mean > 1e-3 * peak
    # samples 5e-7 s apart see the sine's crest within 1 - cos(2 pi f 2.5e-7) ~ 1e-8
    assert np.max(values[inner] / mean[inner] - 1) == pytest.approx(a, rel=1e-7)


@pytest.mark.parametrize("frequency", [45.0, 60.0, 78.0])  # the reference paper's measured band
def test_deflagration_oscillation_frequency_from_zero_crossings(frequency):
    prm = {**DEFLAGRATION, "frequency": frequency}
    t = np.linspace(1e-4, 0.1 - 1e-4, 200001)  # inside (0, T), where the mean pressure is > 0
    wave = loads.deflagration(**prm)(t) - loads.deflagration(**{**prm, "amplitude": 0.0})(t)
    # linear interpolation of crossings 5e-7 s apart: error ~ (2 pi f h)^2 relative, < 1e-7
    assert crossing_frequency(t, wave) == pytest.approx(frequency, rel=1e-6)


@pytest.mark.parametrize("frequency", [45.0, 60.0, 78.0])
def test_deflagration_oscillation_moves_the_impulse_by_less_than_its_integration_by_parts_bound(frequency):
    prm = {**DEFLAGRATION, "frequency": frequency}
    t = np.linspace(0.0, 0.1, 400001)
    impulse = np.trapz(loads.deflagration(**prm)(t), t)
    # a int s sin(w t) dt = -(a / w^2) int s'' sin(w t) dt (s, s' vanish at 0 and T), and
    # int |s''| = total variation of s' = 2 * 16 P / (9 t_r) + pi P / (T - t_r)
    peak, rise, duration, a = prm["peak"], prm["rise"], prm["duration"], prm["amplitude"]
    bound = a * peak * (32 / (9 * rise) + np.pi / (duration - rise)) / (2 * np.pi * frequency)**2
    assert abs(impulse - deflagration_mean_impulse(**prm)) <= bound
    assert bound < 1e-2 * deflagration_mean_impulse(**prm)  # so the check is sharp: < 1 %


# ---------------------------------------------------------------- detonation
def detonation_impulse(peak, plateau, decay, duration, frequency, amplitude, damping, local_peak, local_width,
                       **_):
    """Closed-form integral of the detonation formula of loads.detonation over [0, T]."""
    T = duration
    taper_exp = lambda lam: (np.exp(lam * T) - 1) / lam - (np.exp(lam * T) * (lam * T - 1) + 1) / (lam**2 * T)
    spike = taper_exp(-1 / decay)  # int (1 - t/T) exp(-t/t_s)
    reverb = taper_exp(complex(-1 / damping, 2 * np.pi * frequency)).imag
    return plateau * T / 2 + (peak - plateau) * spike + amplitude * plateau * reverb + local_peak * local_width / 2


def test_detonation_spikes_to_peak_at_zero_and_ends_at_duration_with_the_closed_form_impulse():
    p = loads.detonation(**DETONATION)
    t = np.linspace(0.0, DETONATION["duration"], 400001)
    values = p(t)
    assert values[0] == P_REFL and np.argmax(values) == 0
    assert P_REFL / P_CJ == pytest.approx(2.42, abs=0.005)  # docs/loads.md: the spike ~ 2.4 P_CJ
    assert p(DETONATION["duration"]) == 0 and np.all(p(np.array([-1e-9, 20e-3 + 1e-9, 1.0])) == 0)
    assert values.min() >= 0
    # trapezoid rule, steps 5e-8 s = 1e-4 t_s: error ~ 1e-9 relative on the spike
    assert np.trapz(values, t) == pytest.approx(detonation_impulse(**DETONATION), rel=1e-8)


def test_detonation_reverberation_frequency_and_damping_time_measured_from_the_signal():
    t = np.linspace(1e-5, DETONATION["duration"] - 1e-5, 400001)
    wave = loads.detonation(**DETONATION)(t) - loads.detonation(**{**DETONATION, "amplitude": 0.0})(t)
    # crossings by linear interpolation of samples 5e-8 s apart: < 1e-7 relative
    assert crossing_frequency(t, wave) == pytest.approx(DETONATION["frequency"], rel=1e-6)
    # crests at t_k = (k + 1/4) / f; their height over the (1 - t/T) taper decays as exp(-t/t_o)
    crests = (np.arange(3) + 0.25) / DETONATION["frequency"]
    heights = np.interp(crests, t, wave) / (1 - crests / DETONATION["duration"])
    slope = np.polyfit(crests, np.log(heights), 1)[0]
    assert -1 / slope == pytest.approx(DETONATION["damping"], rel=1e-6)  # interpolation, as above
    assert heights[0] == pytest.approx(DETONATION["amplitude"] * P_AICC * np.exp(-crests[0] / 5e-3), rel=1e-6)


def test_detonation_local_peak_has_its_height_time_support_and_impulse():
    t = np.union1d(np.linspace(0.0, DETONATION["duration"], 400001), [DETONATION["local_time"]])
    bump = loads.detonation(**DETONATION)(t) - loads.detonation(**{**DETONATION, "local_peak": 0.0})(t)
    assert bump.max() == pytest.approx(5e5, rel=1e-12) and t[np.argmax(bump)] == 8e-3
    outside = np.abs(t - 8e-3) >= 1e-3
    assert np.all(np.abs(bump[outside]) < 1e-9 * P_REFL)  # rounding of the subtraction only
    # cos^2 over its full width: h w / 2; trapezoid error ~ (pi h / w)^2 / 12 ~ 1e-8
    assert np.trapz(bump, t) == pytest.approx(5e5 * 2e-3 / 2, rel=1e-7)


# ---------------------------------------------------------------- via the case file
def case_file(tmp_path, load_lines, extra=""):
    text = re.sub(r"\[load\].*?\n\n", "[load]\nboundary = \"left\"\n" + load_lines + "\n\n",
                  builtin_case_text("sound-bar"), flags=re.S)
    path = tmp_path / "case.toml"
    path.write_text(text + extra)
    return path


def toml(prm):
    return "\n".join(f"{key} = {value!r}" if not isinstance(value, str) else f'{key} = "{value}"'
                     for key, value in prm.items())


SIGNAL_PRM = {
    "friedlander": dict(peak=2e5, duration=4e-3, alpha=1.77),
    "deflagration": DEFLAGRATION,
    "detonation": DETONATION,
}


@pytest.mark.parametrize("kind", sorted(SIGNAL_PRM))
def test_case_file_builds_the_same_signal_as_the_function(tmp_path, kind):
    load = load_case(case_file(tmp_path, toml({"signal": kind, **SIGNAL_PRM[kind]}))).load
    t = np.linspace(-1e-3, 0.12, 10001)
    np.testing.assert_array_equal(loads.signal(load)(t), getattr(loads, kind)(**SIGNAL_PRM[kind])(t))


@pytest.mark.parametrize("kind,shortest", [
    ("friedlander", 4e-3 / 2.77),      # t_d / (1 + alpha): the initial fall
    ("deflagration", 0.5 / 60.0),      # half a period < rise = decay = 50 ms
    ("detonation", 0.5e-3),            # the spike's decay < half a 180 Hz period, w / 2
])
def test_accuracy_time_step_resolves_each_signal_shortest_feature(tmp_path, kind, shortest):
    load = load_case(case_file(tmp_path, toml({"signal": kind, **SIGNAL_PRM[kind]}))).load
    assert accuracy_time_step(load, 1.0, per_feature=20) == pytest.approx(shortest / 20, rel=1e-12)


BAD_LOADS = [
    ({**DEFLAGRATION, "rise": 0.0}, "load.rise"),
    ({**DEFLAGRATION, "rise": 0.1}, "load.duration"),
    ({**DEFLAGRATION, "amplitude": 1.5}, "load.amplitude"),
    ({**DETONATION, "plateau": 2 * P_REFL}, "load.plateau"),
    ({**DETONATION, "local_time": 19.5e-3}, "load.local_time"),
    ({**DETONATION, "local_peak": 0.0}, "load.local_time"),
    ({k: v for k, v in DETONATION.items() if k != "local_width"}, "load.local_width"),
]


@pytest.mark.parametrize("prm,key", BAD_LOADS)
def test_bad_signal_parameters_raise_one_line_naming_the_key(tmp_path, prm, key):
    kind = "deflagration" if "rise" in prm else "detonation"
    with pytest.raises(CaseError) as info:
        load_case(case_file(tmp_path, toml({"signal": kind, **prm})))
    assert key in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("overrides,key", [
    (["load.alpha=1.0"], "load.alpha"),  # a friedlander key on the triangular signal
    (["load.signal=friedlander"], "load.rise"),
    (["load.region_factor=2"], "load.region_min"),
    (["load.region_min=[0, 0, 0]", "load.region_max=[1, 1, 1]", "load.region_factor=2"], "load.region_min"),
    (["load.region_min=[0, 0.03]", "load.region_max=[1, 0.01]", "load.region_factor=2"], "load.region_max"),
    (["load.region_min=[0, 'a']", "load.region_max=[1, 1]", "load.region_factor=2"], "load.region_min"),
])
def test_bad_load_overrides_raise_one_line_naming_the_key(overrides, key):
    with pytest.raises(CaseError, match=re.escape(key)):
        load_case("sound-bar", overrides)


def test_region_keys_give_the_region_of_the_load_vector():
    load = load_case("sound-bar", ["load.region_min=[-0.001, 0.01]", "load.region_max=[0.001, 0.03]",
                                   "load.region_factor=3"]).load
    assert load.region == ((-0.001, 0.01), (0.001, 0.03), 3.0)
    assert load_case("sound-bar").load.region is None


# ---------------------------------------------------------------- spatial profile
def resultant(space, f):
    """Sum of the nodal forces over all ranks (owned dofs only), N per Pa."""
    owned = space.V.dofmap.index_map.size_local * space.gdim
    return space.mesh.comm.allreduce(f.x.array[:owned].reshape(-1, space.gdim).sum(axis=0), op=MPI.SUM)


@pytest.mark.parametrize("name,lower,upper,area_in,area_out,normal", [
    # left edge x = 0, y in [0, 0.04], facets 1 cm: two facets in, two out
    ("left", (-1e-3, 0.01), (1e-3, 0.03), 0.02, 0.02, (1, 0)),
    # a box cutting facets: a facet is in when its midpoint (0.015, 0.025) is
    ("left", (-1e-3, 0.014), (1e-3, 0.026), 0.02, 0.02, (1, 0)),
    # top edge y = 0.04: facets with midpoints x = 0.005 .. 0.045 in
    ("top", (0.0, 0.035), (0.05, 0.05), 0.05, 0.07, (0, -1)),
])
def test_region_resultant_is_area_out_plus_factor_area_in(name, lower, upper, area_in, area_out, normal):
    geometry = rectangle()
    geometry.structured = True
    domain = mesh.build(geometry, 0.01, MPI.COMM_WORLD)
    space = spaces.create(domain)
    factor = 3.0
    f = loads.unit_pressure_vector(space, domain, name, (lower, upper, factor))
    # a sum of per-facet exact integrals: machine precision
    np.testing.assert_allclose(resultant(space, f), (area_out + factor * area_in) * np.array(normal),
                               atol=1e-14)


# "back" is the face z = thickness = 0.03 (inward normal -z)
@pytest.mark.parametrize("lower,upper,share", [((-1, -1, 0.02), (1, 1, 0.04), 1.0),
                                               ((-1, -1, 0.0), (1, 1, 0.029), 0.0)])
def test_region_on_a_3d_face_all_in_or_all_out(lower, upper, share):
    domain = mesh.build(box(), 0.02, MPI.COMM_WORLD)
    space = spaces.create(domain)
    factor, area = 2.5, 0.1 * 0.05
    f = loads.unit_pressure_vector(space, domain, "back", (lower, upper, factor))
    np.testing.assert_allclose(resultant(space, f), (1 + (factor - 1) * share) * area * np.array([0, 0, -1]),
                               atol=1e-14)


# ---------------------------------------------------------------- command line
def printed(stdout):
    return {k: float(v) for k, v in re.findall(r"^(\w+) = (\S+)$", stdout, flags=re.M)}


def test_loads_command_writes_the_png_and_prints_the_triangle_closed_forms(tmp_path):
    out = tmp_path / "plots" / "p.png"
    result = dolfrag_cli("loads", "sound-bar", "--out", out)
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[0] == str(out) and out.stat().st_size > 1000
    values = printed(result.stdout)
    # sound-bar: 1 MPa, rise 2 us, duration 10 us; impulse peak * duration / 2, exact (kinks sampled)
    assert values["peak_Pa"] == 1e6 and values["peak_time_s"] == 2e-6 and values["duration_s"] == 1e-5
    assert values["impulse_Pa_s"] == pytest.approx(5.0, rel=1e-6)  # printed to 6 digits


def test_loads_command_on_a_friedlander_case_prints_its_closed_form_impulse(tmp_path):
    prm = SIGNAL_PRM["friedlander"]
    path = case_file(tmp_path, toml({"signal": "friedlander", **prm}))
    result = dolfrag_cli("loads", path, "--set", "time.end=5e-3", "--out", tmp_path / "p.png")
    assert result.returncode == 0, result.stderr
    values = printed(result.stdout)
    assert values["peak_Pa"] == 2e5 and values["peak_time_s"] == 0 and values["duration_s"] == 4e-3
    # sampled at 1/200 of t_d / (1 + alpha): trapezoid error ~ 1e-6; printed to 6 digits
    assert values["impulse_Pa_s"] == pytest.approx(closed_form_friedlander_impulse(**prm), rel=1e-5)


def test_loads_command_bad_input_exits_2_with_one_line(tmp_path):
    result = dolfrag_cli("loads", "sound-bar", "--set", "load.amplitude=0.5", "--out", tmp_path / "p.png")
    assert result.returncode == 2 and "load.amplitude" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "p.png").exists()
