"""A hydrogen explosion in a closed room: the gas states that set its pressure load.

Pure functions of the mixture (a mixture.Mixture: x the volume (mole) fraction of H2 in H2 and
its oxidiser, air O2:N2 = 1:3.76 by volume or pure oxygen, the latter optionally diluted by N2
or Ar) and of its initial state T0 (K), p0 (Pa), computed with Cantera's chemical equilibrium
solver and the thermodynamic data of GRI-Mech 3.0 (``gri30.yaml``, bundled with Cantera; an
equilibrium needs no reaction rates). Only its species made of the mixture's elements take
part (``unburnt``: 18 made of H, O, N for H2-air, 8 made of H, O for H2-O2, and AR with
argon): a carbon-free mixture forms none of the others, and their data are fitted from 300 K
to 3500 K, where the full set stops at 3000 K (CH3O). H2-O2's burnt gas is hotter, up to
about 4,200 K: there the fits are extrapolated (``compute``).

* AICC, adiabatic isochoric complete combustion: the equilibrium at the initial internal
  energy and volume (``equilibrate("UV")``): P_AICC (Pa, absolute), T_AICC (K) and the burnt
  gas's equilibrium sound speed c_b (m/s, ``equilibrium_sound_speed``);
* the Chapman–Jouguet (CJ) detonation (``chapman_jouguet``): the steady front whose burnt gas,
  in chemical equilibrium, leaves it at its equilibrium sound speed: speed D_CJ (m/s), state
  P_CJ (Pa), T_CJ (K), and the burnt gas's velocity u_CJ (m/s, in the room's frame);
* the reflected pressure (``reflected_shock``): the equilibrium shock that brings the CJ gas
  to rest at a rigid wall, P_r (Pa), T_r (K);
* the Taylor plateau (``taylor_plateau``): the pressure of the gas brought to rest by the
  Taylor–Zeldovich expansion behind a planar CJ front started at a closed end (Pa).

The jump conditions across a steady front (or shock) from state 1 to state 2, in its frame
(w the gas speed relative to it, v = 1/rho the specific volume, h the specific enthalpy):

    rho1 w1 = rho2 w2                              (mass)
    p2 - p1 = rho1^2 w1^2 (v1 - v2)                (momentum: the Rayleigh line)
    h2 - h1 = (p2 - p1) (v1 + v2) / 2              (energy: the Hugoniot)

``explosion`` returns all of them for one mixture, from a JSON file cached per mixture
(docs/loads.md).
"""
import hashlib
import json
import math
import os
import tempfile
import warnings
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import cantera as ct
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from dolfrag.loads.mixture import composition

MECHANISM = "gri30.yaml"
# the numbers of `explosion` change only with this, the mixture, Cantera and the mechanism:
# it is part of each cache file's key (raise it when a computation below changes)
METHOD = 1
# central-difference step of the equilibrium sound speed: a relative density change large
# enough that the equilibrium solver's residuals (~1e-9 relative) stay far below it, small
# enough that the truncation error (~ step^2) is negligible
_SOUND_STEP = 1e-4
# the temperatures (K) between which an equilibrium Hugoniot's state is sought: the burnt
# gas of any of these mixtures lies between a room's temperature and fully dissociated gas
_T_BRACKET = (200.0, 7000.0)
# published values for the stoichiometric mixture of each oxidiser, beside which `dolfrag
# loads` prints the computed ones (docs/loads.md): H2-air (29.6 % H2) at 1 atm and 298 K;
# H2-O2 at 1 bar and 298.15 K, NASA CEA's CJ detonation (McBride & Gordon, NASA RP-1311
# part II, 1996, example 6, its first column); the reflected pressure's and the
# Taylor plateau's usual estimates, as ratios to P_CJ
PUBLISHED = {
    "air": {"state": "stoichiometric at 1 atm", "P_AICC_Pa": 8.0e5, "D_CJ_m_s": 1970.0, "P_CJ_Pa": 15.8e5,
            "reflected_per_P_CJ": "2.5", "Taylor_per_P_CJ": "0.34-0.4"},
    "oxygen": {"state": "stoichiometric at 1 bar, NASA CEA", "D_CJ_m_s": 2835.5, "P_CJ_Pa": 18.768e5,
               "T_CJ_K": 3674.3, "reflected_per_P_CJ": "2.5", "Taylor_per_P_CJ": "0.34-0.4"}}


def unburnt(mixture, T0, p0):
    """A Cantera ideal gas of the GRI-Mech 3.0 species made of the Mixture's elements, the
    unburnt mixture at T0 (K), p0 (Pa)."""
    moles = composition(mixture)
    every = ct.Species.list_from_file(MECHANISM)
    elements = set().union(*(s.composition for s in every if s.name in moles))
    gas = ct.Solution(thermo="ideal-gas", species=[s for s in every if set(s.composition) <= elements])
    gas.TPX = T0, p0, moles
    return gas


def equilibrium_sound_speed(gas):
    """The equilibrium sound speed (m/s) of ``gas`` in chemical equilibrium, sqrt((dp/drho)_s)
    with the composition re-equilibrated at each density (the speed of waves slower than the
    chemistry); central difference. Leaves ``gas`` as it found it."""
    state, s, v = gas.state, gas.s, gas.v
    pressures = []
    for factor in (1.0 + _SOUND_STEP, 1.0 - _SOUND_STEP):
        gas.SV = s, v / factor
        gas.equilibrate("SV")
        pressures.append(gas.P)
    gas.state = state
    return math.sqrt((pressures[0] - pressures[1]) / (2.0 * _SOUND_STEP / v))


def aicc(gas):
    """(P_AICC Pa, T_AICC K, c_b m/s) of the unburnt ``gas``: its equilibrium at constant
    internal energy and volume, and that burnt gas's equilibrium sound speed. ``gas`` is
    left burnt."""
    gas.equilibrate("UV")
    return gas.P, gas.T, equilibrium_sound_speed(gas)


def hugoniot_state(gas, v1, p1, h1, v2):
    """Put ``gas`` (its element composition) into the equilibrium state of specific volume
    ``v2`` (m^3/kg) on the Hugoniot of the state v1 (m^3/kg), p1 (Pa), h1 (J/kg):
    h2 - h1 = (p2 - p1) (v1 + v2) / 2, solved for the temperature. Returns p2 (Pa)."""
    def energy_gap(T):
        gas.TD = T, 1.0 / v2
        gas.equilibrate("TV")
        return gas.enthalpy_mass - h1 - 0.5 * (gas.P - p1) * (v1 + v2)
    brentq(energy_gap, *_T_BRACKET, xtol=1e-9, rtol=1e-13)
    return gas.P


@dataclass(frozen=True)
class ChapmanJouguet:
    """A CJ detonation: D (m/s) the front's speed, p (Pa), T (K), v (m^3/kg) the burnt gas
    at the front, u (m/s) its velocity in the room's frame, D (1 - v / v1), and s (J/kg/K)
    its entropy."""
    D: float
    p: float
    T: float
    v: float
    u: float
    s: float


def chapman_jouguet(gas):
    """The CJ detonation (ChapmanJouguet) into the unburnt ``gas``: the point of the
    equilibrium Hugoniot where the burnt gas leaves the front at its equilibrium sound speed,
    w2 = D v2 / v1 = c_eq(2), with D from the Rayleigh line, D = v1 sqrt((p2 - p1) / (v1 - v2)).
    Below the CJ volume (the strong branch) the burnt gas is subsonic, above it (the weak
    branch, up to the AICC state at v2 = v1) supersonic, so w2 - c_eq changes sign once: a
    root in v2 / v1. ``gas`` is left in the CJ state."""
    v1, p1, h1 = gas.v, gas.P, gas.enthalpy_mass

    def front_speed(v2):
        return v1 * math.sqrt((hugoniot_state(gas, v1, p1, h1, v2) - p1) / (v1 - v2))

    def sonic_gap(ratio):
        D = front_speed(ratio * v1)
        return D * ratio - equilibrium_sound_speed(gas)

    ratio = brentq(sonic_gap, 0.45, 0.9, xtol=1e-12, rtol=1e-12)
    D = front_speed(ratio * v1)
    return ChapmanJouguet(D, gas.P, gas.T, gas.v, D * (1.0 - ratio), gas.s)


def reflected_shock(gas, cj):
    """(P_r Pa, T_r K): the equilibrium shock reflected from a rigid wall by the burnt gas
    of the ChapmanJouguet ``cj`` (``gas`` in its state) arriving at u = cj.u. Behind the
    shock the gas is at rest; in the shock's frame the mass and momentum jumps give
    u^2 = (p3 - p2)(v2 - v3), the energy jump the Hugoniot of the CJ state; solved for v3.
    ``gas`` is left in the reflected state."""
    v2, p2, h2 = gas.v, gas.P, gas.enthalpy_mass

    def velocity_gap(ratio):
        v3 = ratio * v2
        return (hugoniot_state(gas, v2, p2, h2, v3) - p2) * (v2 - v3) - cj.u**2

    # at v3 = v2 the gap is -u^2; a strong compression to 0.2 v2 stops far more than u
    ratio = brentq(velocity_gap, 0.2, 1.0 - 1e-9, xtol=1e-13, rtol=1e-13)
    return hugoniot_state(gas, v2, p2, h2, ratio * v2), gas.T


def taylor_plateau(gas, cj):
    """The Taylor plateau pressure (Pa): behind a planar CJ front started at a closed end the
    burnt gas expands isentropically (equilibrium isentrope s = cj.s) from u = cj.u to rest
    through a centred simple wave, along which the Riemann invariant
    u - int dp / (rho c_eq) is constant; so the plateau p3 solves
    int_{p3}^{P_CJ} dp / (rho c_eq) = u_CJ, integrated in ln p. ``gas`` is left on the
    isentrope."""
    def slowdown(log_p, u):
        gas.SP = cj.s, math.exp(log_p)
        gas.equilibrate("SP")
        return [gas.P / (gas.density * equilibrium_sound_speed(gas))]  # du / d(ln p)

    def at_rest(log_p, u):
        return u[0]
    at_rest.terminal = True
    # u falls as p does: integrate ln p downward from the CJ state until u = 0, which every
    # mixture reaches near 0.35-0.4 P_CJ, far above the lower end of the interval
    solution = solve_ivp(slowdown, (math.log(cj.p), math.log(0.02 * cj.p)), [cj.u], events=at_rest,
                         rtol=1e-10, atol=1e-8)
    if not solution.t_events[0].size:
        raise RuntimeError(f"taylor_plateau: the burnt gas (u_CJ = {cj.u:.6g} m/s) does not come to rest")
    return math.exp(solution.t_events[0][0])


@dataclass(frozen=True)
class Explosion:
    """The gas states of one Mixture (absolute pressures): AICC (P Pa, T K, c_b the
    burnt gas's equilibrium sound speed m/s); the CJ detonation (D m/s, P Pa, T K, u m/s the
    burnt gas's velocity); the reflected pressure and temperature at a rigid wall (Pa, K);
    the Taylor plateau (Pa)."""
    P_AICC_Pa: float
    T_AICC_K: float
    c_b_m_s: float
    D_CJ_m_s: float
    P_CJ_Pa: float
    T_CJ_K: float
    u_CJ_m_s: float
    P_reflected_Pa: float
    T_reflected_K: float
    P_Taylor_Pa: float


def compute(mixture, T0, p0):
    """The Explosion of the Mixture at T0 (K), p0 (Pa): some hundreds of Cantera
    equilibria, a fraction of a second to a few seconds."""
    with warnings.catch_warnings():
        # H2-O2's burnt states (3,500-4,200 K) lie past the end of GRI-Mech's fits, 3500 K,
        # and Cantera warns at each of their equilibria; there the extrapolated fits give the
        # numbers of NASA Glenn's data (fitted to 6000 K) within 3e-4 (tests/test_h2_oxygen.py)
        warnings.filterwarnings("ignore", message="ChemEquil.*outside valid range", category=UserWarning)
        P, T, c_b = aicc(unburnt(mixture, T0, p0))
        gas = unburnt(mixture, T0, p0)
        cj = chapman_jouguet(gas)
        P_r, T_r = reflected_shock(gas, cj)
        return Explosion(P, T, c_b, cj.D, cj.p, cj.T, cj.u, P_r, T_r, taylor_plateau(gas, cj))


def cache_key(mixture, T0, p0):
    """What the numbers of a Mixture depend on (the cache file's key)."""
    return {"h2_fraction": float(mixture.h2_fraction), "oxidizer": mixture.oxidizer, "diluent": mixture.diluent,
            "diluent_fraction": float(mixture.diluent_fraction), "T0_K": float(T0), "p0_Pa": float(p0),
            "mechanism": MECHANISM, "cantera": ct.__version__, "method": METHOD}


def cache_folder():
    """$XDG_CACHE_HOME/dolfrag, or ~/.cache/dolfrag when XDG_CACHE_HOME is unset or empty."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "dolfrag"


def cache_file(key):
    """The JSON file of a cache key: h2-air-<digest of the key>.json in cache_folder()."""
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]
    return cache_folder() / f"h2-air-{digest}.json"


def _read(path, key):
    """The Explosion stored in ``path`` for ``key``, or None: no file, unreadable, not JSON,
    another key, missing or non-finite numbers."""
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
        numbers = {f.name: float(stored["numbers"][f.name]) for f in fields(Explosion)}
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None
    if stored.get("key") != key or not all(map(math.isfinite, numbers.values())):
        return None
    return Explosion(**numbers)


def _write(path, key, explosion):
    """Store ``explosion`` for ``key`` in ``path``: a temporary file in the same folder
    renamed over it (readers see the whole old file or the whole new one); silently nothing
    if the folder cannot be written (the numbers are then recomputed next time)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, name = tempfile.mkstemp(suffix=".tmp", dir=path.parent)
    except OSError:
        return
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as tmp:
            json.dump({"key": key, "numbers": asdict(explosion)}, tmp, indent=1)
        os.replace(name, path)
    except OSError:
        Path(name).unlink(missing_ok=True)


_KNOWN = {}  # this process's Explosions by cache file


def explosion(mixture, T0, p0, comm=None):
    """The Explosion of the Mixture at T0 (K), p0 (Pa): from this process's memory, else from its cache file (``cache_file``), else computed and written
    there. With ``comm`` (collective): rank 0 reads or computes and every rank receives its
    numbers, so all ranks hold the same; later calls, with or without comm, reuse them."""
    key = cache_key(mixture, T0, p0)
    path = cache_file(key)
    if path not in _KNOWN:
        found = None
        if comm is None or comm.rank == 0:
            found = _read(path, key)
            if found is None:
                found = compute(mixture, T0, p0)
                _write(path, key, found)
        _KNOWN[path] = found if comm is None else comm.bcast(found, root=0)
    return _KNOWN[path]
