"""1D spall (docs/hopkinson.md) with the built-in case spall-bar: where the first spall plane
forms and how fast the spalled piece flies, against the closed forms."""
import numpy as np
import pytest
from mpi4py import MPI

from dolfrag import loads
from dolfrag.reference import analytic, homogenise
from dolfrag.case import load_case
from dolfrag.runner.driver import run


@pytest.fixture(scope="module")
def spall(tmp_path_factory):
    case = load_case("spall-bar", ["output.fields=0", "output.figures=false",
                                   "output.fragments_at=[1.2e-4, 1.0e-4]"])
    summary = run(case, tmp_path_factory.mktemp("spall"), quiet=True, comm=MPI.COMM_SELF)
    # the wave speed of the discretisation run (bulk slowed by the interface springs)
    c = analytic.wave_speed(homogenise.uniaxial_strain_modulus(case), case.material.rho)
    return case, summary, c


def test_first_spall_plane_forms_at_lambda_sigma_c_over_two_sigma_0(spall):
    case, summary, c = spall
    load, sigma_c = case.load, case.interface.sigma_c
    wavelength = c * (load.duration - load.rise)  # the decaying part sets the tension
    expected = analytic.triangular_spall_distance(wavelength, sigma_c, load.peak)
    # the general criterion on the actual (ramped) signal agrees with the closed form
    assert analytic.spall_distance(loads.signal(load), c, sigma_c, load.duration) == \
        pytest.approx(expected, abs=c * load.duration / 2000)
    breaks = summary["breaks"]
    first_time = breaks[0]["time_s"]
    first = [b["distance_from_free_end_m"] for b in breaks if b["time_s"] == first_time]
    # one mesh size (planes are grid lines h apart) plus 10 %
    assert np.all(np.abs(np.array(first) - expected) <= case.mesh.size + 0.1 * expected), first
    # causality: no plane can break before the reflected peak reaches the predicted one
    # (measured: 2.0 us after it, 0.8 us for the damage to start and 1.2 us to run through)
    peak_at_free_end = load.rise + case.geometry.length / c
    assert first_time > peak_at_free_end + (expected - case.mesh.size) / c


def test_spalled_piece_flies_off_with_the_trapped_momentum(spall):
    case, summary, c = spall
    load, sigma_c = case.load, case.interface.sigma_c
    frags = summary["fragments"]
    plane = case.geometry.length - summary["breaks"][0]["distance_from_free_end_m"]
    piece = np.array(frags["centroid"])[:, 0] > plane  # everything the first plane cut off
    mass = np.array(frags["mass"])[piece]
    velocity = mass @ np.array(frags["velocity"])[piece, 0] / mass.sum()
    expected = analytic.triangular_scab_velocity(load.peak, sigma_c, case.material.rho, c)
    # 15 %: the ramped front traps a little less momentum than the sharp
    # one of the closed form (analytic.scab_velocity on the actual signal: -8 %)
    assert velocity == pytest.approx(expected, rel=0.15)
    assert velocity > 0  # away from the bar


def test_half_the_free_end_pullback_is_sigma_c_over_rho_c_eff(spall):
    case, summary, c = spall
    rho, sigma_c = case.material.rho, case.interface.sigma_c
    block = summary["shpb"]
    # with rollers the bar modulus of the mesh is its uniaxial-strain modulus (the same
    # static solve but one extra held component, already held by the rollers): round-off
    assert block["analytic_ejection_velocity_effective_m_s"] == pytest.approx(sigma_c / (rho * c), rel=1e-9)
    # Novikov's spall relation on a 1D-like bar: half the drop of the free end's velocity
    # from its peak to its first minimum is sigma_c / (rho c_eff) (measured -1.5 %); 5 %
    # leaves room for the steps' sampling (0.4 us against a 19 us fall) and the crack's
    # finite opening; a minimum picked on the ringing (0.1 m/s deep) would miss by 80 %
    half = block["pullback"]["half_pullback_m_s"]
    assert half == pytest.approx(sigma_c / (rho * c), rel=0.05)
    # the pullback's minimum is the spall signal: after the first break, within the time
    # the signal needs to cross the spalled piece (first plane at 37 mm: 10 us)
    first = summary["breaks"][0]
    assert first["time_s"] < block["pullback"]["minimum_time_s"] < first["time_s"] + \
        first["distance_from_free_end_m"] / c + 2 * summary["dt_s"]


def test_spalling_closes_the_energy_balance(spall):
    _, summary, _ = spall
    # lagged damage books exactly the energy each break frees (solver/semismooth.py)
    assert summary["balance_error_relative"] < 1e-10
    assert summary["energies_J"]["D_damage_J"] > 0


def test_fragments_are_reported_at_the_requested_times(spall):
    case, summary, _ = spall
    at = summary["fragments_at"]
    assert [a["requested_time_s"] for a in at] == [1.0e-4, 1.2e-4]  # sorted
    for a in at:  # the step nearest to each time
        assert abs(a["time_s"] - a["requested_time_s"]) <= summary["dt_s"] / 2 * (1 + 1e-9)
    # before the first plane breaks (103 us) the bar is whole; after, the end piece is off
    assert at[0]["count"] == 1 and at[1]["count"] > 1
    assert summary["breaks"][0]["time_s"] < at[1]["time_s"]


# A sharp front (no rise) of 40 MPa decaying linearly to zero over 30 us on a 150 mm x 30 mm
# concrete bar, sigma_c = 15 MPa, h = 2 mm, in uniaxial strain (rollers on the long faces):
# docs/notes/sharp-fronts.md. The same bar with a free mantle cuts its loaded end (a declared
# gap of docs/hopkinson.md, not asserted here).
SHARP = ["geometry.length=0.15", "geometry.width=0.03", "mesh.size=0.002", "interface.sigma_c=15e6",
         "load.peak=40e6", "load.rise=0", "load.duration=30e-6", "time.end=60e-6",
         'supports.rollers=["bottom","top"]', "output.fields=0", "output.figures=false", "output.every=20"]


@pytest.fixture(scope="module")
def sharp(tmp_path_factory):
    case = load_case("shpb-be16", SHARP)
    summary = run(case, tmp_path_factory.mktemp("sharp"), quiet=True, comm=MPI.COMM_SELF)
    c = analytic.wave_speed(homogenise.uniaxial_strain_modulus(case), case.material.rho)
    return case, summary, c


def test_a_sharp_front_leaves_the_loaded_end_of_a_uniaxial_strain_bar_whole(sharp):
    case, summary, _ = sharp
    frags = summary["fragments"]
    # every cell within 20 mm of the loaded end (x = 0) belongs to one fragment
    assert sum(lo[0] < 0.02 for lo in frags["bbox_min"]) == 1
    assert not [b for b in summary["breaks"] if b["distance_from_free_end_m"] > case.geometry.length - 0.02]


def test_a_sharp_front_spalls_where_and_as_fast_as_1d_says(sharp):
    case, summary, c = sharp
    pulse, rho, sigma_c = loads.signal(case.load), case.material.rho, case.interface.sigma_c
    delta = analytic.spall_distance(pulse, c, sigma_c, case.load.duration)  # 20.3 mm at c_eff
    first = summary["breaks"][0]["distance_from_free_end_m"]
    # 10 % + h (measured 23.4 mm: +3.0 mm against 4.0 allowed; 28.4 mm without the bulk viscosity)
    assert first == pytest.approx(delta, abs=0.1 * delta + case.mesh.size)
    frags = summary["fragments"]
    piece = np.array(frags["centroid"])[:, 0] > case.geometry.length - first
    mass = np.array(frags["mass"])[piece]
    velocity = mass @ np.array(frags["velocity"])[piece, 0] / mass.sum()
    # the trapped momentum (2 sigma_0 - sigma_c) / (rho c_eff) = 7.65 m/s, within 20 %
    # (measured 6.26 m/s, -18 %: the front is sharper than a cell, as in the wall's scab)
    assert velocity == pytest.approx(analytic.scab_velocity(pulse, c, rho, delta), rel=0.2)
    assert summary["balance_error_relative"] < 1e-10 and summary["energies_J"]["D_viscous_J"] > 0
