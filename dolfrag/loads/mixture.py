"""The unburnt hydrogen mixture of an explosion load: its composition, and the limits within
which it detonates. Pure Python, no Cantera (case/rules.py checks a case with it; gas.py burns it).

A Mixture is x = ``h2_fraction`` (-), the volume (mole) fraction of H2 in H2 and its
oxidiser, air (O2:N2 = 1:3.76 by volume) or oxygen; an oxygen mixture may be diluted by
``diluent_fraction`` (-, of the whole mixture) of N2 or Ar. Its equivalence ratio is
phi = (H2 / O2) / 2 (2 H2 + O2 -> 2 H2O): stoichiometric x = 2 / 6.76 = 0.296 in air, 2 / 3 in
oxygen.

Limits on x (1 atm, room temperature; ``H2_LIMITS``):

* air, 0.10-0.60: below 10 % H2 a flame does not burn all the hydrogen (it rises in separate
  cells), so a complete-combustion pressure would overstate the load; 60 % is well past
  stoichiometric, towards the rich flammability limit (75 %);
* oxygen, 0.15-0.90: the detonation limits of H2-O2 (Lewis & von Elbe, Combustion, Flames and
  Explosions of Gases, 3rd ed. 1987, the table of detonation limits of gases; Moyle, Morrison &
  Churchill, AIChE J. 6 (1960) 92-96, measured detonations over 25-75 % H2);
* a diluted oxygen mixture: at most ``DILUENT_PER_O2`` = 3.76 moles of diluent per mole of O2
  (air's N2) and phi within the air limits' (``equivalence_ratio``: 0.26-3.57). Such a mixture
  lies between H2-O2 and H2-air of the same phi, both inside their limits; argon, of lower
  heat capacity than N2, leaves its burnt gas hotter than N2 would.
"""
from dataclasses import dataclass

N2_PER_O2 = 3.76  # air, by volume
# the oxidisers, moles of each species per mole of O2
OXIDIZERS = {"air": {"O2": 1.0, "N2": N2_PER_O2}, "oxygen": {"O2": 1.0}}
# the inert diluents of an oxygen mixture: their GRI-Mech 3.0 species
DILUENTS = {"N2": "N2", "Ar": "AR"}
H2_LIMITS = {"air": (0.10, 0.60), "oxygen": (0.15, 0.90)}  # h2_fraction, module docstring
DILUENT_PER_O2 = N2_PER_O2  # the most diluent per mole of O2 in a diluted oxygen mixture


@dataclass(frozen=True)
class Mixture:
    """An unburnt hydrogen mixture: ``h2_fraction`` (-) of H2 in H2 and its ``oxidizer`` (a
    key of OXIDIZERS); an oxygen mixture may be diluted by ``diluent_fraction`` (-, of the
    whole mixture) of the inert ``diluent`` (a key of DILUENTS)."""
    h2_fraction: float
    oxidizer: str = "air"
    diluent: str = "N2"
    diluent_fraction: float = 0.0


def composition(mixture):
    """Mole fractions {GRI-Mech species: -} of the Mixture, only those > 0. Stoichiometric
    H2-O2 diluted by 3.76 / 6.76 of N2 is stoichiometric H2-air."""
    x, diluted = mixture.h2_fraction, mixture.diluent_fraction
    oxidizer = OXIDIZERS[mixture.oxidizer]
    per_mole = sum(oxidizer.values())
    moles = {"H2": (1.0 - diluted) * x}
    for species, count in oxidizer.items():
        moles[species] = (1.0 - diluted) * (1.0 - x) * count / per_mole
    if diluted > 0:
        species = DILUENTS[mixture.diluent]
        moles[species] = moles.get(species, 0.0) + diluted
    return moles


def equivalence_ratio(h2_fraction, oxidizer):
    """phi = (H2 / O2) / 2 (-) of ``h2_fraction`` (-) of H2 in H2 and the ``oxidizer``."""
    return h2_fraction / (1.0 - h2_fraction) * sum(OXIDIZERS[oxidizer].values()) / 2.0


def diluent_per_o2(mixture):
    """Moles of diluent per mole of O2 (-) of an oxygen Mixture."""
    moles = composition(mixture)
    return moles.get(DILUENTS[mixture.diluent], 0.0) / moles["O2"]
