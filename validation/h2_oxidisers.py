"""The gas states of stoichiometric hydrogen in air and in oxygen beside published values
(docs/loads.md, "The oxidiser"): P_AICC, c_b, D_CJ, P_CJ, T_CJ, the reflected CJ spike and
the Taylor plateau, computed by dolfrag/loads/gas.py at each published value's initial state.

    python validation/h2_oxidisers.py

Prints a markdown table (SI: Pa as bar, m/s, K). The published values and their sources are
gas.PUBLISHED's: H2-air at 1 atm and 298 K; H2-O2 at 1 bar and 298.15 K, NASA CEA (McBride &
Gordon, NASA RP-1311 part II, 1996, example 6). The reflected and Taylor ratios are the usual
ideal-gas estimates. Each mixture's numbers come from the cache when there (gas.explosion).
"""
from dolfrag.loads import gas
from dolfrag.loads.mixture import Mixture

# (column title, Mixture, T0 K, p0 Pa): the published values' mixtures and initial states
MIXTURES = [("H2-air, 29.6 % H2, 298.15 K, 1 atm", Mixture(2 / 6.76), 298.15, 101325.0),
            ("H2-O2, 66.7 % H2, 298.15 K, 1 bar", Mixture(2 / 3, "oxygen"), 298.15, 1e5)]


def rows(state, published):
    """(quantity, computed, published) of one Explosion beside its PUBLISHED entry."""
    bar = 1e-5

    def given(key, scale=1.0, unit=""):
        return f"{published[key] * scale:.5g}{unit}" if key in published else ""
    P_CJ = state.P_CJ_Pa
    return [("P_AICC (bar)", f"{state.P_AICC_Pa * bar:.4g}", given("P_AICC_Pa", bar)),
            ("c_b (m/s)", f"{state.c_b_m_s:.5g}", ""),
            ("D_CJ (m/s)", f"{state.D_CJ_m_s:.5g}", given("D_CJ_m_s")),
            ("P_CJ (bar)", f"{P_CJ * bar:.4g}", given("P_CJ_Pa", bar)),
            ("T_CJ (K)", f"{state.T_CJ_K:.5g}", given("T_CJ_K")),
            ("reflected P_r (bar)", f"{state.P_reflected_Pa * bar:.4g} = {state.P_reflected_Pa / P_CJ:.3g} P_CJ",
             f"≈ {published['reflected_per_P_CJ']} P_CJ"),
            ("Taylor plateau (bar)", f"{state.P_Taylor_Pa * bar:.4g} = {state.P_Taylor_Pa / P_CJ:.3g} P_CJ",
             f"{published['Taylor_per_P_CJ']} P_CJ")]


if __name__ == "__main__":
    tables = [rows(gas.explosion(m, T0, p0), gas.PUBLISHED[m.oxidizer]) for _, m, T0, p0 in MIXTURES]
    print("| | " + " | ".join(f"{title} | published" for title, *_ in MIXTURES) + " |")
    print("|---|" + "---|---|" * len(MIXTURES))
    for i, (quantity, *_) in enumerate(tables[0]):
        print(f"| {quantity} | " + " | ".join(f"{t[i][1]} | {t[i][2]}" for t in tables) + " |")
