"""Selective mass scaling: a few poor cells must not set the explicit step of the whole mesh.

The central-difference step of the bulk is the shortest of the cells' own stable steps
2 / omega_e (bulk.stable_time_step), so one flat tetrahedron among thousands sets the step
of the run. With ``time.mass_scaling = F`` (imex), a cell whose own step is below its target
F h / c_p (h = mesh.size in m, c_p = sqrt((lambda + 2 mu) / rho) its material's P-wave
speed in m/s) has its lumped mass multiplied by (target / step)^2: omega_e^2 scales as
1 / mass, so its step becomes the target exactly. A DG-P1 cell owns its vertex copies, so the
added mass stays in that cell: its inertia, kinetic energy, momentum and the star problems
use the heavier mass, and the energy balance closes as before. What changes is the wave
speed inside those cells, by 1 / sqrt(factor); summary.json reports the cells and the added
mass, and the run warns when the added mass passes ADDED_SHARE of the whole. Explicit codes
offer the same (LS-DYNA's DT2MS, Abaqus' variable mass scaling).
"""
import numpy as np

ADDED_SHARE = 0.01  # added mass above this share of the whole: one warning line


def factors(steps, targets):
    """Mass factors (-) that bring each cell's stable step (s) up to its target (s), 1 for
    the cells already at or above it."""
    return np.maximum(1.0, (targets / steps) ** 2)


def warning(added, total):
    """The one-line warning (or None) when the added mass (kg) passes ADDED_SHARE of the
    total (kg)."""
    if added <= ADDED_SHARE * total:
        return None
    return (f"dolfrag: warning: time.mass_scaling added {added:.4g} kg, {added / total:.1%} of the mass: "
            "the scaled cells carry waves slower by 1 / sqrt(their factor); lower time.mass_scaling or "
            "improve the mesh (mesh.optimize_threshold)")
