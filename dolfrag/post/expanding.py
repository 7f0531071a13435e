"""The expanding bar's block of summary.json (``expanding_bar``; the scales: docs/method.md, "Expanding bar").

Rule for the fragment count: a fragment is a piece (post/fragments.py) holding at least
MASS_SHARE of the body's mass; smaller pieces are debris (a corner chip, a lone triangle
freed where cracks branch), which the 1D theories have no room for. The mean fragment size
is L / count, L the bar's length: the definition of the 1D closed forms, where N
fragments share the bar. Each counted fragment's x extent (reference configuration) is
listed too, which shows how far the pieces are from the 1D picture of slices.
"""
import numpy as np

from dolfrag.reference import analytic

# 1 %: an order of magnitude below the share of the tens of fragments the case aims at, and
# ~30 cells of the case's 2 mm mesh, larger than the chips cracks branch off (measured).
MASS_SHARE = 0.01


def block(frags, length, rate, material, interface):
    """JSON-ready dict: fragment counts, mean size (m), each counted fragment's x extent
    (m) and the closed forms at this rate (analytic.py), for a linear-softening-type law
    (interface.sigma_c, G_c given; else ``closed_forms`` is None).

    frags: Fragments in the reference configuration; length (m); rate eps_dot (1/s);
    material, interface: case.Material, case.Interface.
    """
    counted = frags.mass >= MASS_SHARE * frags.mass.sum()
    count = int(np.count_nonzero(counted))
    extent = (frags.bbox_max[counted, 0] - frags.bbox_min[counted, 0]).tolist()
    out = {"strain_rate_1_s": rate, "pieces": len(frags), "fragments": count, "mass_share_min": MASS_SHARE,
           "mean_size_m": length / count if count else None, "extent_x_m": extent, "closed_forms": None}
    if interface.sigma_c is not None and interface.G_c is not None:
        E, sigma_c, G_c = material.E, interface.sigma_c, interface.G_c
        L0 = analytic.fragmentation_length(E, G_c, sigma_c)
        rate_0 = analytic.fragmentation_strain_rate(E, material.rho, G_c, sigma_c)
        x = rate / rate_0
        out["closed_forms"] = {
            "L0_m": L0, "strain_rate_0_1_s": rate_0, "strain_rate_ratio": x,
            "time_to_strength_s": sigma_c / (E * rate),
            "mean_size_m": {"zhou_molinari_ramesh": float(L0 * analytic.zhou_molinari_ramesh_size(x)),
                            "glenn_chudnovsky": float(L0 * analytic.glenn_chudnovsky_size(x)),
                            "grady": float(L0 * analytic.grady_size(x))}}
    return out
