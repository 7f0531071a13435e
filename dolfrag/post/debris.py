"""Debris throw: where the fragments of a 3D run land, and the hazard they make there
(docs/fragments.md).

Each fragment not held by a support flies from its centroid with its mean velocity, as a
point mass under gravity (g, along -z) and quadratic air drag,

    m dv/dt = m g - 1/2 rho_air C_D A |v| v,

A the presented area of the sphere of the fragment's volume, pi (3 V / (4 pi))^(2/3), until it
reaches the ground plane z = ground_z. scipy's solve_ivp (DOP853, RTOL, ATOL) integrates it and
locates the ground as a terminal event (root of the dense output to machine precision).

Hazard (DDESB, DoD 6055.09-M; DDESB Technical Paper 13): a fragment landing with an impact
energy 1/2 m v^2 >= hazard_energy (79 J) is hazardous. Their areal density is counted in
annuli of equal width w around the structure's centre (plan view): annulus k = 0, 1, ... holds
the ranges [k w, (k + 1) w), area pi w^2 (2 k + 1). The hazard distance is the outer radius
(k + 1) w of the farthest annulus holding at least one hazardous fragment per hazard_area
(55.7 m^2, 600 ft^2); beyond it the density is below the limit. 0 without such an annulus.
"""
from typing import NamedTuple

import numpy as np
from scipy.integrate import solve_ivp

G = 9.81  # m/s^2, gravity along -z
RTOL = 1e-10  # solve_ivp's relative tolerance on the state
ATOL = 1e-12  # its absolute tolerance (m, m/s): far below a landing point's millimetre
MAX_SEGMENTS = 60  # a flight not landed within the first span is continued, each span twice the last


class Landing(NamedTuple):
    """point (3,) m where the fragment reaches the ground; time (s) of flight; velocity
    (3,) m/s at impact."""
    point: np.ndarray
    time: float
    velocity: np.ndarray


def presented_area(volume):
    """m^2: the cross-section pi r^2 of the sphere of ``volume`` (m^3)."""
    return np.pi * (3 * np.asarray(volume) / (4 * np.pi)) ** (2 / 3)


def drag_factor(mass, volume, C_D, air_density):
    """1/m: rho_air C_D A / (2 m), the drag deceleration per squared speed."""
    return air_density * C_D * presented_area(volume) / (2 * np.asarray(mass))


def fly(x0, v0, drag, ground_z, g=G):
    """The Landing of a point mass launched from x0 (3,) m with v0 (3,) m/s, decelerated by
    ``drag`` |v| v (drag in 1/m, ``drag_factor``) and pulled down by g (m/s^2), on the plane
    z = ground_z (m). A launch at or below the ground lands where it is."""
    x0, v0 = np.asarray(x0, dtype=float), np.asarray(v0, dtype=float)
    if x0[2] <= ground_z:
        return Landing(x0.copy(), 0.0, v0.copy())

    def motion(t, state):
        v = state[3:]
        return np.concatenate([v, -drag * np.linalg.norm(v) * v - [0.0, 0.0, g]])

    def ground(t, state):
        return state[2] - ground_z
    ground.terminal, ground.direction = True, -1

    # the drag-free flight time: an upper bound without drag, a first span with it
    span = (v0[2] + np.sqrt(v0[2] ** 2 + 2 * g * (x0[2] - ground_z))) / g
    state, t0 = np.concatenate([x0, v0]), 0.0
    for _ in range(MAX_SEGMENTS):
        flight = solve_ivp(motion, (t0, t0 + 2 * span), state, method="DOP853", rtol=RTOL, atol=ATOL,
                           events=ground)
        if flight.t_events[0].size:
            end = flight.y_events[0][0]
            return Landing(np.array([end[0], end[1], ground_z]), float(flight.t_events[0][0]), end[3:])
        state, t0, span = flight.y[:, -1], flight.t[-1], 2 * span
    raise RuntimeError(f"a fragment launched from {x0} m at {v0} m/s did not land in {t0:.3g} s")


class Throw(NamedTuple):
    """The debris of the thrown fragments: ids (n,) their rows in fragments.csv; mass (n,)
    kg; area (n,) m^2; launch (n, 3) m; launch_velocity (n, 3) m/s; landing (n, 3) m;
    range (n,) m from the structure's centre in plan; time (n,) s of flight; impact_speed
    (n,) m/s; impact_energy (n,) J."""
    ids: np.ndarray
    mass: np.ndarray
    area: np.ndarray
    launch: np.ndarray
    launch_velocity: np.ndarray
    landing: np.ndarray
    range: np.ndarray
    time: np.ndarray
    impact_speed: np.ndarray
    impact_energy: np.ndarray


def throw(table, centre, ground_z, C_D, air_density, g=G):
    """The Throw of the fragments of ``table`` (post.fragment_table.FragmentTable, 3D) that
    no support holds, each from its centroid with its mean velocity. centre (2,) m: the
    structure's centre in plan (x, y), whence the ranges are measured."""
    ids = np.flatnonzero(~table.held)
    drag = drag_factor(table.mass[ids], table.volume[ids], C_D, air_density)
    landings = [fly(table.centroid[i], table.velocity[i], k, ground_z, g) for i, k in zip(ids, drag)]
    landing = np.array([f.point for f in landings]).reshape(-1, 3)
    velocity = np.array([f.velocity for f in landings]).reshape(-1, 3)
    speed = np.linalg.norm(velocity, axis=1)
    return Throw(ids, table.mass[ids], presented_area(table.volume[ids]), table.centroid[ids],
                 table.velocity[ids], landing, np.linalg.norm(landing[:, :2] - centre, axis=1),
                 np.array([f.time for f in landings]), speed, 0.5 * table.mass[ids] * speed**2)


def ring_density(ranges, ring_width):
    """Areal density (1/m^2) of the points at ``ranges`` (m) in annuli of width ring_width
    (m) around the centre: annulus k holds [k w, (k + 1) w), area pi w^2 (2 k + 1). Returns
    (counts, areas) per annulus, out to the farthest point's."""
    ring = np.floor(np.asarray(ranges) / ring_width).astype(np.int64)
    counts = np.bincount(ring)
    return counts, np.pi * ring_width**2 * (2 * np.arange(len(counts)) + 1)


def hazard_distance(ranges, energies, hazard_energy, hazard_area, ring_width):
    """m: the outer radius of the farthest annulus (``ring_density``) holding at least one
    fragment with an impact energy >= hazard_energy (J) per hazard_area (m^2); 0 if none."""
    hazardous = np.asarray(energies) >= hazard_energy
    counts, areas = ring_density(np.asarray(ranges)[hazardous], ring_width)
    dense = np.flatnonzero(counts * hazard_area >= areas)
    return float(dense[-1] + 1) * ring_width if len(dense) else 0.0


def block(debris, options, centre, ground_z, held):
    """JSON-ready summary of a Throw ``debris``: counts, the largest range and the hazard
    distance. options: case.Debris; centre (2,) m; ground_z m; held: fragments not thrown."""
    hazardous = debris.impact_energy >= options.hazard_energy
    return {"thrown": len(debris.ids), "held": int(held), "hazardous": int(hazardous.sum()),
            "largest_range_m": float(debris.range.max(initial=0.0)),
            "hazard_distance_m": hazard_distance(debris.range, debris.impact_energy, options.hazard_energy,
                                                 options.hazard_area, options.ring_width),
            "largest_impact_energy_J": float(debris.impact_energy.max(initial=0.0)),
            "centre_m": [float(c) for c in centre], "ground_z_m": float(ground_z),
            "C_D": options.C_D, "air_density_kg_m3": options.air_density, "g_m_s2": G,
            "hazard_energy_J": options.hazard_energy, "hazard_area_m2": options.hazard_area,
            "ring_width_m": options.ring_width}


def columns():
    """debris.csv's header: names with units."""
    return ["id", "mass_kg", "area_m2", "launch_x_m", "launch_y_m", "launch_z_m", "launch_vx_m_s", "launch_vy_m_s",
            "launch_vz_m_s", "landing_x_m", "landing_y_m", "range_m", "flight_time_s", "impact_speed_m_s",
            "impact_energy_J", "hazardous"]


def rows(debris, hazard_energy):
    """debris.csv's rows (``columns``) of a Throw."""
    return [[int(i), debris.mass[j], debris.area[j], *debris.launch[j], *debris.launch_velocity[j],
             *debris.landing[j, :2], debris.range[j], debris.time[j], debris.impact_speed[j],
             debris.impact_energy[j], int(debris.impact_energy[j] >= hazard_energy)]
            for j, i in enumerate(debris.ids)]
