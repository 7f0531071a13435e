"""The ``shpb`` block of summary.json: a bar spalled by a pulse on one end (Hopkinson bar,
docs/hopkinson.md), measured as the seed measures it, next to the 1D closed form and the
seed's own values.

Pure functions of Fragments (post/fragments.py) and numbers: no MPI, no dolfinx.

Blocks are the fragments with at least ``BLOCK_MASS_SHARE`` (2 %) of the total mass; the
smaller pieces of a damaged band are left out. They are ordered from the free end by the
distance of their centroid from it. The ejection velocity between neighbouring blocks i and
i + 1 is v_i - v_{i+1}, with v the centroid velocity along the bar axis counted positive
away from the body, towards the free end: positive when the block nearer the free end flies
away faster.
"""
import numpy as np

from dolfrag import analytic
from dolfrag.post.fragments import breaks_by_time

MEASURE_TIME = 80e-6  # s: the seed measures the blocks 80 µs after the pulse starts
BLOCK_MASS_SHARE = 0.02  # blocks: fragments with >= 2 % of the mass (docs/hopkinson.md §4)

# The seed's values (its §4, Brara et al. 2001; docs/hopkinson.md §1): break distances from
# the free end (m), in the order the breaks form. The seed gives no ejection velocities.
SEED = {
    "shpb-be16": {"experiment": {"breaks_from_free_end_m": [0.0658]},
                  "simulation": {"breaks_from_free_end_m": [0.065]}},
    "shpb-be12": {"simulation": {"breaks_from_free_end_m": [0.042, 0.064]}},
}


def tensile_strength(interface, C_N):
    """Peak tensile traction (Pa) of the law of ``interface`` (config.Interface) with normal
    stiffness C_N (Pa/m): sigma_c, sqrt(C_N w) for RCCM given w, R_c for ``threshold``;
    None for ``elastic``."""
    if interface.law == "elastic":
        return None
    if interface.law == "threshold":
        return interface.R_c
    if interface.sigma_c is None:
        return float(np.sqrt(C_N * interface.w))
    return interface.sigma_c


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


def shpb_block(final, measured, measured_at, free_end, sigma_c, rho, E, name=None, axis=0, closed_form=None):
    """The ``shpb`` dict of summary.json (JSON-ready).

    final: Fragments at the end of the run, for ``breaks`` (fragments.breaks_by_time).
    measured: Fragments at ``measured_at`` (s): the step nearest MEASURE_TIME, or the
    end of a shorter run; blocks and ejection velocities are taken there.
    free_end (m): coordinate of the free end on ``axis``. sigma_c (Pa, or None), rho
    (kg/m^3), E (Pa): for analytic.ejection_velocity. name: the case name; the seed's
    values are attached for the cases in SEED. closed_form: the 1D first spall of the bar
    (analytic.BarSpall, or None if it does not spall), reported as ``analytic_1d``, its
    velocities only if ``measured_at`` is after its break.
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
    }
    if name in SEED:
        out["seed"] = SEED[name]
    return out
