"""The ``shpb`` block of summary.json: a bar spalled by a pulse on one end (Hopkinson bar,
docs/hopkinson.md), measured as *Study and simulation of fragmentation phenomena of concrete
structures under stuffy explosion* measures it, next to the 1D closed form and the values
of that paper and of its experimental source (Brara et al. 2001).

Pure functions of Fragments (post/fragments.py) and numbers: no MPI, no dolfinx.

Blocks are the fragments with at least ``BLOCK_MASS_SHARE`` (2 %) of the total mass; the
smaller pieces of a damaged band are left out. They are ordered from the free end by the
distance of their centroid from it. The ejection velocity between neighbouring blocks i and
i + 1 is v_i - v_{i+1}, with v the centroid velocity along the bar axis counted positive
away from the body, towards the free end: positive when the block nearer the free end flies
away faster.
"""
import numpy as np
from scipy.signal import find_peaks

from dolfrag.reference import analytic
from dolfrag.post.fragments import breaks_by_time

MEASURE_TIME = 80e-6  # s: the paper measures the blocks 80 µs after the pulse starts
BLOCK_MASS_SHARE = 0.02  # blocks: fragments with >= 2 % of the mass (docs/hopkinson.md)

# The values of *Study and simulation of fragmentation phenomena of concrete structures under
# stuffy explosion* for the tests of Brara et al. 2001 (docs/hopkinson.md): break distances
# from the free end (m), for the test ("experiment", as the paper lists them) and the paper's
# simulation (in the order its breaks form), and the simulated blocks' velocities at 80 µs
# (m/s, as the paper gives them: about 2 m/s for BE16, 2.4 and 2.9 m/s for BE12).
PAPER = {
    "shpb-be16": {"experiment": {"breaks_from_free_end_m": [0.0658]},
                  "simulation": {"breaks_from_free_end_m": [0.065], "block_velocities_m_s": [2.0]}},
    "shpb-be12": {"experiment": {"breaks_from_free_end_m": [0.069, 0.041]},
                  "simulation": {"breaks_from_free_end_m": [0.042, 0.064], "block_velocities_m_s": [2.4, 2.9]}},
}


# A minimum of the free end's velocity counts as the pullback's only if the velocity then rises
# by this share of V_e before it falls lower. In 1D the spall signal's rebound is 2 V_e; the
# ringing of a 2D bar's lateral modes is far smaller (shpb-be16, h = 7 mm: 0.25 m/s with the
# bulk viscosity, 0.45 m/s without, against V_e = 2.32 m/s and a rebound of 3.5 m/s)
PULLBACK_PROMINENCE = 0.5


class FreeEndProbe:
    """The mean velocity of a bar's free end along its axis, recorded every step.

    comps: this rank's owned flat velocity components of the free end's dofs along the axis;
    outward: +1 or -1, the direction of the free end (``outward``): the record is positive
    when the end flies away from the bar. Recording is local; ``series`` sums over ranks."""

    def __init__(self, comps, outward):
        self.comps, self.outward = np.asarray(comps, dtype=np.int64), outward
        self.t, self.sums = [], []

    def record(self, t, v):
        """Add the time t (s) of the velocities v (m/s, flat, all local components)."""
        self.t.append(t)
        self.sums.append(v[self.comps].sum())

    def series(self, comm):
        """(t (s), mean outward velocity of the free end (m/s)), the same on every rank. Collective."""
        total = comm.allreduce(np.array([len(self.comps), *self.sums], dtype=float))
        return np.asarray(self.t), self.outward * total[1:] / max(total[0], 1.0)


def pullback(t, v, v_e, prominence=PULLBACK_PROMINENCE):
    """The free end's pullback (spall experiments' delta_u_fs) from its velocity history v (m/s,
    positive away from the bar) at the times t (s): the drop from the first peak of the velocity
    to the first minimum after it, and the rebound, the rise from that minimum to the next maximum.
    A minimum (or maximum) counts if v then rises (falls) by ``prominence`` times v_e (m/s,
    analytic.ejection_velocity) before it falls lower (rises higher). In 1D a spall plane
    opening at sigma_c gives a pullback and a rebound of 2 V_e = 2 sigma_c / (rho c), so half
    the pullback is the simulation's V_e (sigma_spall = 1/2 rho c delta_u_fs, Novikov, Divnov &
    Ivanov 1966). Returns a JSON-ready dict, or None when the velocity has no such peak and
    minimum (no spall signal yet)."""
    t, v = np.asarray(t, dtype=float), np.asarray(v, dtype=float)
    if len(v) < 3:
        return None
    peaks, _ = find_peaks(v, prominence=prominence * v_e)
    if not len(peaks):
        return None
    top = int(peaks[0])
    lows, _ = find_peaks(-v[top:], prominence=prominence * v_e)
    if not len(lows):
        return None
    low = top + int(lows[0])
    highs, _ = find_peaks(v[low:], prominence=prominence * v_e)
    high = low + int(highs[0]) if len(highs) else None
    drop = float(v[top] - v[low])
    return {"peak_m_s": float(v[top]), "peak_time_s": float(t[top]),
            "minimum_m_s": float(v[low]), "minimum_time_s": float(t[low]),
            "pullback_m_s": drop, "half_pullback_m_s": drop / 2,
            "rebound_m_s": None if high is None else float(v[high] - v[low]),
            "rebound_time_s": None if high is None else float(t[high])}


def blocks(frags, free_end, axis=0, share=BLOCK_MASS_SHARE):
    """Indices (into ``frags``) of the fragments with at least ``share`` of the total mass,
    nearest to the free end first (by centroid); free_end (m) is its coordinate on ``axis``."""
    big = np.flatnonzero(frags.mass >= share * frags.mass.sum())
    return big[np.argsort(np.abs(free_end - frags.centroid[big, axis]), kind="stable")]


def outward(frags, free_end, axis=0):
    """+1 if the free end lies on the positive side of the body's mass centre along
    ``axis``, else -1: the direction spalled pieces fly."""
    centre = frags.mass @ frags.centroid[:, axis] / frags.mass.sum()
    return 1.0 if free_end > centre else -1.0


def ejection_velocities(frags, free_end, axis=0, share=BLOCK_MASS_SHARE):
    """(n_blocks - 1,) m/s: v_i - v_{i+1} between consecutive blocks from the free end, v the
    centroid velocity along ``axis`` counted towards the free end (module docstring)."""
    v = outward(frags, free_end, axis) * frags.velocity[blocks(frags, free_end, axis, share), axis]
    return v[:-1] - v[1:]


def free_at(frags, i):
    """Time (s) fragment i came free: the last separation from a neighbour (its boundary
    completes then); None if it has no neighbour or a separation time is unknown."""
    times = frags.separated_at[np.any(frags.neighbours == i, axis=1)]
    return None if not len(times) or np.isnan(times).any() else float(times.max())


def _one_d(closed_form, measured_at):
    """analytic_1d: the closed form's plane and break time; its velocities only from the
    break on (None before it, when the 1D bar is still whole)."""
    spalled = measured_at >= closed_form.time
    velocities = {"scab_velocity_m_s": closed_form.scab_velocity, "rest_velocity_m_s": closed_form.rest_velocity,
                  "relative_velocity_m_s": closed_form.relative_velocity}
    return {"spall_distance_from_free_end_m": float(closed_form.distance), "break_time_s": float(closed_form.time),
            **{key: float(v) if spalled else None for key, v in velocities.items()}}


def shpb_block(final, measured, measured_at, free_end, sigma_c, rho, E, name=None, axis=0, closed_form=None,
               free_end_velocity=None, E_eff=None):
    """The ``shpb`` dict of summary.json (JSON-ready).

    final: Fragments at the end of the run, for ``breaks`` (fragments.breaks_by_time).
    measured: Fragments at ``measured_at`` (s): the step nearest MEASURE_TIME, or the
    end of a shorter run; blocks and ejection velocities are taken there.
    free_end (m): coordinate of the free end on ``axis``. sigma_c (Pa, or None), rho
    (kg/m^3), E (Pa): for analytic.ejection_velocity. name: the case name; the paper's
    values are attached for the cases in PAPER. closed_form: the 1D first spall of the bar
    (analytic.BarSpall, or None if it does not spall), reported as ``analytic_1d``, its
    velocities only if ``measured_at`` is after its break. free_end_velocity: (t (s), v (m/s))
    of the free end (FreeEndProbe.series), for ``pullback``; E_eff (Pa): the bar modulus of the
    mesh with its interface springs (homogenise.bar_modulus), for the V_e the discretisation
    gives in 1D.
    """
    order = blocks(measured, free_end, axis)
    ends = np.abs(free_end - np.stack([measured.bbox_min[order, axis], measured.bbox_max[order, axis]], axis=1))
    out = {
        "breaks": breaks_by_time(final, free_end, axis),
        "requested_time_s": MEASURE_TIME,
        "measured_at_s": float(measured_at),
        "block_mass_share": BLOCK_MASS_SHARE,
        "blocks": [{"mass_share": float(measured.mass[i] / measured.mass.sum()),
                    "extent_from_free_end_m": sorted(map(float, ends[j])),
                    "velocity_x_m_s": float(measured.velocity[i, axis]),
                    "free_at_s": free_at(measured, i)} for j, i in enumerate(order)],
        "ejection_velocities_m_s": ejection_velocities(measured, free_end, axis).tolist(),
        "analytic_ejection_velocity_m_s": None if sigma_c is None else float(
            analytic.ejection_velocity(sigma_c, rho, E)),
        "analytic_1d": None if closed_form is None else _one_d(closed_form, measured_at),
        "pullback": None if free_end_velocity is None or sigma_c is None else pullback(
            *free_end_velocity, analytic.ejection_velocity(sigma_c, rho, E)),
        "analytic_ejection_velocity_effective_m_s": None if sigma_c is None or E_eff is None else float(
            analytic.ejection_velocity(sigma_c, rho, E_eff)),
        "effective_modulus_Pa": None if E_eff is None else float(E_eff),
    }
    if name in PAPER:
        out["paper"] = PAPER[name]
    return out
