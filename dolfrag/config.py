"""Case files: a TOML file in, validated frozen dataclasses out.

A case file describes one run. SI units everywhere (m, Pa, kg/m^3, s, Pa/m).
Example::

    name = "bar"                 # optional, default: the file name without .toml
    description = "plane wave through a layered bar"

    [geometry]
    kind = "rectangle"           # "rectangle" | "box" | "file"
    length = 1.0                 # m (x extent)
    width = 0.1                  # m (y extent)

    [mesh]
    size = 0.01                  # m, target element size

    [material]
    E = 3.0e10                   # Pa
    nu = 0.2
    rho = 2400.0                 # kg/m^3

    [interface]
    law = "elastic"              # C_N = C_T = stiffness_ratio * E / mesh.size unless given

    [load]
    boundary = "left"
    signal = "triangular"        # | "friedlander" | "deflagration" | "detonation" | "h2-air" | "table" | "charge"
    peak = 1.0e6                 # Pa, positive pushes into the body
    rise = 1.0e-5                # s
    duration = 2.0e-5            # s
    # optional local over-pressure: factor x p(t) on the part of the boundary in a box
    # region_min = [0.0, 0.01]   # m, lower corner (one coordinate per axis)
    # region_max = [0.0, 0.03]   # m, upper corner
    # region_factor = 2.0

    [supports]
    rollers = ["bottom", "top"]

    [time]
    end = 4.0e-4                 # s

The sections and keys are the fields of the dataclasses below; each field's comment gives
its unit, range and default. Relative paths (geometry.file, load.file) are relative to the
case file's directory (in --set overrides: to the current directory).

``load_case(path_or_builtin_name, overrides)`` is the entry point; overrides are
"section.key=value" strings (the CLI's --set). Every bad input raises CaseError with a
one-line message naming the dotted key.
"""
from __future__ import annotations

import math
import operator
import tomllib
from dataclasses import MISSING, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dolfrag import bunker, concrete, mixture
from dolfrag.interface.models import LAWS as _LAW_REGISTRY, law as _law
from dolfrag.loads.charge import BURSTS
from dolfrag.loads.explosives import EQUIVALENCES, EQUIVALENTS, EXPLOSIVES, SOURCE as EXPLOSIVES_SOURCE

GEOMETRY_KINDS = ("rectangle", "box", "bunker", "file")
HYPOTHESES = ("plane_strain", "plane_stress")
SIGNALS = ("triangular", "friedlander", "deflagration", "detonation", "h2-air", "table", "charge")
REGIMES = ("deflagration", "detonation")  # of an h2-air explosion
OXIDIZERS = tuple(mixture.OXIDIZERS)  # of an h2-air explosion's hydrogen
DILUENTS = tuple(mixture.DILUENTS)    # of an oxygen mixture
LOAD_KINDS = ("pressure", "stretch")
SCHEMES = ("imex", "theta")
RATE_EFFECTS = ("none", "fib2010")
LAWS = tuple(_LAW_REGISTRY)
RECTANGLE_BOUNDARIES = ("left", "right", "bottom", "top")
BOX_BOUNDARIES = RECTANGLE_BOUNDARIES + ("front", "back")
BUNKER_BOUNDARIES = bunker.BOUNDARIES

_CASES_DIR = Path(__file__).parent / "cases"


class CaseError(ValueError):
    """Bad user input; str(err) is one line naming the key, the value and what is allowed."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).splitlines()))


# ---------------------------------------------------------------- field specs
_REQ = object()  # spec default meaning "required"
_OPS = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le}
_NOUNS = {"float": "a number", "int": "an integer", "str": "a string",
          "bool": "true or false", "names": "a list of strings", "path": "a path to a file",
          "numbers": "a list of numbers", "point": "a list of 2 or 3 numbers", "sizes": "a list of {count} numbers"}
_TYPES = {"float": (int, float), "int": (int, float), "str": str, "bool": bool, "names": list,
          "path": str, "numbers": list, "point": list, "sizes": list}


@dataclass(frozen=True)
class _Spec:
    kind: str                 # one of _NOUNS
    default: Any = _REQ
    bounds: str = ""          # e.g. "> 0" or ">= 0, < 0.5"
    unit: str = ""
    choices: tuple = ()
    when: tuple = ()          # (discriminator field, values...): the key exists only then
    optional_for: tuple = ()  # discriminator values for which the key may be absent (None)
    suffixes: tuple = ()      # allowed file suffixes for kind "path"
    count: int = 0            # how many numbers kind "sizes" holds

    def describe(self) -> str:
        if self.choices:
            return "must be one of " + ", ".join(map(repr, self.choices))
        noun = _NOUNS[self.kind].format(count=self.count)
        if self.suffixes:
            noun = f"a path to a {' or '.join(self.suffixes)} file"
        text = f"must be {noun}"
        if self.bounds:
            text += " " + self.bounds.replace(",", " and")
        return text + (f" ({self.unit})" if self.unit else "")

    def admits(self, number: float) -> bool:
        pairs = (part.split() for part in self.bounds.split(",") if part)
        return all(_OPS[op](number, float(limit)) for op, limit in pairs)

    def condition(self, prefix: str) -> str:
        return f"{prefix}.{self.when[0]} is " + " or ".join(map(repr, self.when[1:]))


def _f(kind: str, default: Any = _REQ, bounds: str = "", unit: str = "", **kw) -> Any:
    """A dataclass field carrying its validation spec (conditional fields default to None)."""
    spec = _Spec(kind, default, bounds, unit, **kw)
    if default is _REQ:
        default = None if spec.when else MISSING
    return field(default=default, metadata={"spec": spec})


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _convert(key: str, value: Any, spec: _Spec, base: Path) -> Any:
    """Check one value against its spec; return it converted (float, int, tuple, Path)."""
    bad = CaseError(f"{key} = {_show(value)}: {spec.describe()}")
    kind = spec.kind
    if not isinstance(value, _TYPES[kind]) or (isinstance(value, bool) and kind != "bool"):
        raise bad
    if kind in ("float", "int"):
        if not math.isfinite(value) or (kind == "int" and not float(value).is_integer()):
            raise bad
        value = int(value) if kind == "int" else float(value)
        if not spec.admits(value):
            raise bad
    if kind == "names":
        if not all(isinstance(name, str) for name in value):
            raise bad
        value = tuple(value)
    if kind == "numbers":
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                   and spec.admits(x) for x in value):
            raise bad
        value = tuple(sorted(float(x) for x in value))
    if kind == "sizes":
        if len(value) != spec.count or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and spec.admits(x)
                for x in value):
            raise bad
        value = tuple(float(x) for x in value)
    if kind == "point":
        if len(value) not in (2, 3) or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value):
            raise bad
        value = tuple(float(x) for x in value)
    if spec.choices and value not in spec.choices:
        raise bad
    if kind == "path":
        path = (base / value).resolve()
        if not value or (spec.suffixes and path.suffix not in spec.suffixes):
            raise bad
        if not path.is_file():
            raise CaseError(f"{key} = {_show(value)}: file not found ({path})")
        value = path
    return value


def _section(cls: type, raw: Any, prefix: str, base: Path) -> Any:
    """Validate the table `raw` against the specs in the fields of dataclass `cls`."""
    if not isinstance(raw, dict):
        raise CaseError(f"{prefix} = {_show(raw)}: must be a table [{prefix}]")
    specs = {f.name: f.metadata["spec"] for f in fields(cls) if "spec" in f.metadata}
    for name in raw:
        if name not in specs:
            raise CaseError(f"unknown key '{prefix}.{name}'; allowed: {', '.join(specs)}")
    out: dict[str, Any] = {}
    for name, spec in specs.items():
        key = f"{prefix}.{name}"
        if spec.when and out[spec.when[0]] not in spec.when[1:]:
            if name in raw:
                raise CaseError(f"{key} = {_show(raw[name])}: only allowed when "
                                f"{spec.condition(prefix)} (--set {key}= removes it)")
            out[name] = None
        elif name in raw:
            out[name] = _convert(key, raw[name], spec, base)
        elif spec.optional_for and out[spec.when[0]] in spec.optional_for:
            out[name] = None
        elif spec.default is _REQ:
            needed = f" (required when {spec.condition(prefix)})" if spec.when else ""
            raise CaseError(f"missing key {key}{needed}: {spec.describe()}")
        else:
            out[name] = spec.default
    return cls(**out)


# ---------------------------------------------------------------- sections
_PLANAR = ("kind", "rectangle", "box")   # `when` conditions shared by several fields
_IMPORTED = ("kind", "file")
_BUNKER = ("kind", "bunker")
_PRESSURE = ("kind", "pressure")
_SHAPED = ("signal", "triangular", "friedlander", "deflagration", "detonation")
_TIMED = _SHAPED + ("h2-air",)
_RISING = ("signal", "triangular", "deflagration", "h2-air")
_OSCILLATING = ("signal", "deflagration", "detonation")
_DETONATION = ("signal", "detonation")
_H2_AIR = ("signal", "h2-air")
_REVERBERATING = _DETONATION + ("h2-air",)
_OXYGEN = ("oxidizer", "oxygen")
_CHARGE = ("signal", "charge")
_GAS = ("h2-air",)  # optional_for: keys an h2-air load may leave out (its regime decides, loads.h2_air_shape)
_RCCM = ("law", "rccm")
_STRENGTH = ("law", "rccm", "rccm_decoupled", "linear_softening")
_FRICTIONAL = ("law", "rccm", "rccm_decoupled", "threshold", "linear_softening")


@dataclass(frozen=True)
class Geometry:
    """[geometry]: the domain, generated (rectangle, box, bunker) or imported (file).

    bunker (dolfrag/bunker.py): a closed room, ``inner`` (x, y, z up) inside, walls and roof
    ``wall`` thick on a rigid foundation, a ``door`` (width, height) in the wall at y = 0,
    closed by a panel ``door_thickness`` thick (0: a hole); every length times ``scale``."""
    kind: str = _f("str", choices=GEOMETRY_KINDS)                     # one of GEOMETRY_KINDS
    length: float | None = _f("float", bounds="> 0", unit="m", when=_PLANAR)   # x extent > 0
    width: float | None = _f("float", bounds="> 0", unit="m", when=_PLANAR)    # y extent > 0
    thickness: float | None = _f("float", bounds="> 0", unit="m", when=("kind", "box"))  # z > 0
    file: Path | None = _f("path", when=_IMPORTED, suffixes=(".geo", ".msh"))  # absolute Path
    dim: int | None = _f("int", 2, choices=(2, 3), when=_IMPORTED)      # 2 | 3, default 2
    inner: tuple[float, ...] | None = _f("sizes", (3.0, 2.0, 2.0), bounds="> 0", unit="m", when=_BUNKER, count=3)
    wall: float | None = _f("float", 0.20, bounds="> 0", unit="m", when=_BUNKER)
    door: tuple[float, ...] | None = _f("sizes", (0.9, 2.0), bounds="> 0", unit="m", when=_BUNKER, count=2)
    door_thickness: float | None = _f("float", 0.0, bounds=">= 0", unit="m", when=_BUNKER)
    scale: float | None = _f("float", 1.0, bounds="> 0", when=_BUNKER)
    # rectangle meshed as a regular grid of squares cut in triangles (grid lines are facets)
    structured: bool | None = _f("bool", False, when=("kind", "rectangle"))

    @property
    def boundaries(self) -> tuple[str, ...] | None:
        """Boundary names known before meshing (None for imported meshes)."""
        return {"rectangle": RECTANGLE_BOUNDARIES, "box": BOX_BOUNDARIES, "bunker": BUNKER_BOUNDARIES}.get(self.kind)

    @property
    def tdim(self) -> int:
        """Topological dimension of the cells: 2 or 3."""
        return {"rectangle": 2, "box": 3, "bunker": 3}.get(self.kind, self.dim)


@dataclass(frozen=True)
class Mesh:
    """[mesh]"""
    size: float = _f("float", bounds="> 0", unit="m")           # target element size h [m], > 0


@dataclass(frozen=True)
class Material:
    """[material] (every cell) and [materials.NAME] (cells of physical group NAME).

    ``grade`` (a strength class of EN 1992-1-1 Table 3.1, e.g. "C30/37") gives E, nu and
    rho the class's values (dolfrag/concrete.py, docs/materials.md) and [interface] its
    sigma_c = f_ctm and G_c = G_F; a key given explicitly overrides its value."""
    E: float = _f("float", bounds="> 0", unit="Pa")             # Young's modulus [Pa], > 0
    nu: float = _f("float", bounds=">= 0, < 0.5")               # Poisson's ratio [-], [0, 0.5)
    rho: float = _f("float", bounds="> 0", unit="kg/m^3")       # density [kg/m^3], > 0
    hypothesis: str = _f("str", "plane_strain", choices=HYPOTHESES)  # 2D only, ignored in 3D
    # artificial bulk viscosity in compression (viscosity.py; imex only: theta damps with
    # theta > 1/2); off by default: a linear elastic bulk carries no shock to spread
    bulk_viscosity: bool = _f("bool", False)
    grade: str | None = _f("str", None, choices=tuple(concrete.GRADES))  # EN 1992-1-1 class


@dataclass(frozen=True)
class Interface:
    """[interface]: cohesive law of every inter-element facet.

    When C_N / C_T are not given, C = stiffness_ratio * E / mesh.size (the reference paper's C = 10 E / h).
    """
    law: str = _f("str", "elastic", choices=LAWS)                   # one of LAWS
    C_N: float | None = _f("float", None, bounds="> 0", unit="Pa/m")   # normal [Pa/m], > 0
    C_T: float | None = _f("float", None, bounds="> 0", unit="Pa/m")   # tangential [Pa/m], > 0
    stiffness_ratio: float = _f("float", 10.0, bounds="> 0")        # [-], > 0
    # C_T = shear_ratio * C_N on every mesh (instead of C_T); the RCCM shear strength is then
    # sqrt(shear_ratio) sigma_c
    shear_ratio: float | None = _f("float", None, bounds="> 0")     # [-], > 0
    # rccm: give sigma_c (peak tensile traction, then w = sigma_c^2 / C_N) or w, not both;
    # rccm_decoupled: sigma_c and G_c independent of C_N; linear_softening: sigma_c (rigid up
    # to it) and G_c
    sigma_c: float | None = _f("float", None, bounds="> 0", unit="Pa", when=_STRENGTH)
    w: float | None = _f("float", None, bounds="> 0", unit="J/m^2", when=_RCCM)
    b: float | None = _f("float", 0.0, bounds=">= 0", unit="J s/m^2", when=_RCCM)  # 0: rate-independent
    G_c: float | None = _f("float", bounds="> 0", unit="J/m^2", when=("law", "rccm_decoupled", "linear_softening"))
    # threshold: rigid, tension up to R_c while the gap stays below W_eth
    R_c: float | None = _f("float", bounds="> 0", unit="Pa", when=("law", "threshold"))
    W_eth: float | None = _f("float", bounds="> 0", unit="m", when=("law", "threshold"))
    # Coulomb friction; rccm: mu (1 - beta) acts; threshold, linear_softening: on the cone
    # shifted by the cohesion while the link holds
    mu: float | None = _f("float", 0.0, bounds=">= 0", when=_FRICTIONAL)
    # rccm, rccm_decoupled: internal friction of the intact material; shear drives damage
    # only above mu_i times the contact pressure (Mohr-Coulomb type; 0: the reference paper's law)
    mu_i: float | None = _f("float", 0.0, bounds=">= 0", when=("law", "rccm", "rccm_decoupled"))
    # strength at the strain rate of the bulk beside each link (interface/rate.py):
    # "fib2010" sigma_c x the fib Model Code 2010 tensile factor, "none" sigma_c alone
    rate_effect: str | None = _f("str", "none", choices=RATE_EFFECTS, when=("law", "linear_softening"))

    def adhesion_energy(self, C_N: float) -> float:
        """RCCM adhesion energy w (J/m^2): given, or sigma_c^2 / C_N (docs/method.md)."""
        return self.w if self.w is not None else self.sigma_c**2 / C_N

    def stiffness(self, E: float, h: float) -> tuple[float, float]:
        """(C_N, C_T) [Pa/m]: the given values, else stiffness_ratio * E / h; C_T is
        shear_ratio * C_N if shear_ratio is given."""
        rule = self.stiffness_ratio * E / h
        C_N = rule if self.C_N is None else self.C_N
        if self.shear_ratio is not None:
            return C_N, self.shear_ratio * C_N
        return C_N, rule if self.C_T is None else self.C_T


@dataclass(frozen=True)
class Load:
    """[load]: pressure p(t) on one boundary, positive pushes into the body (the formulas:
    dolfrag/loads/, docs/loads.md), or a uniform stretch along x.

    kind "stretch" (the expanding bar, docs/method.md): the body starts unstressed with
    the velocity v_x = strain_rate (x - x_mid), v_y = 0 (x_mid: the middle of its x extent
    L), and the x velocity of the boundaries ``left`` and ``right`` is held at
    -/+ strain_rate L / 2 from t = 0 (imex, nonsmooth interface laws).

    triangular: linear 0 -> peak over [0, rise], then linear back to 0 at `duration`.
    friedlander: peak (1 - t/duration) exp(-alpha t/duration), positive phase only.
    deflagration: mean pressure rising as t^3 to `peak` at `rise`, half-cosine decay to 0
    at `duration`, times (1 + amplitude sin(2 pi frequency t)).
    detonation: spike `peak` at t = 0 decaying (e-folding time `decay`) to `plateau`, with
    reverberations (frequency, amplitude relative to plateau, damping time) and an optional
    local peak, all times (1 - t/duration).
    h2-air: a hydrogen explosion (docs/loads.md), the deflagration or detonation shape
    (`regime`) with its levels computed from the mixture (dolfrag/gas.py: h2_fraction in air
    or in oxygen, `oxidizer`, an oxygen mixture's optional `diluent`, T0, p0),
    the overpressures reduced by `heat_loss`, the acoustic frequency c_b / (2 room_length);
    `rise` (deflagration), `duration`, and optionally `amplitude`, `decay`, `damping`
    (detonation; defaults loads.h2_air_shape).
    table: p(t) from a CSV file (columns t [s], p [Pa]), parsed into `t` and `p`.
    charge: `mass` kg of `explosive` at `position`, a free-air or surface `burst`: every
    loaded facet its own Friedlander positive phase from the Kingery-Bulmash fits at its
    distance and angle of incidence (dolfrag/loads/charge.py, docs/loads.md).
    Spatial profile (all but charge): uniform, or region_factor x p(t) on the facets whose midpoint is in the
    box [region_min, region_max] (give all three keys or none).
    """
    kind: str = _f("str", "pressure", choices=LOAD_KINDS)            # one of LOAD_KINDS
    strain_rate: float | None = _f("float", bounds="> 0", unit="1/s", when=("kind", "stretch"))
    boundary: str | None = _f("str", when=_PRESSURE)                 # a geometry boundary
    signal: str | None = _f("str", "triangular", choices=SIGNALS, when=_PRESSURE)  # one of SIGNALS
    peak: float | None = _f("float", bounds=">= 0", unit="Pa", when=_SHAPED)      # >= 0
    rise: float | None = _f("float", 0.0, bounds=">= 0", unit="s", when=_RISING, optional_for=_GAS)   # >= 0
    duration: float | None = _f("float", bounds="> 0", unit="s", when=_TIMED)     # >= rise
    # friedlander decay coefficient; >= -1 keeps the maximum at t = 0 (loads.friedlander_alpha
    # gives it from the impulse ratio i / (peak duration), docs/loads.md)
    alpha: float | None = _f("float", bounds=">= -1", when=("signal", "friedlander"))
    # oscillations; amplitude relative to the mean pressure (deflagration) or to the plateau
    # (detonation), <= 1 keeps p >= 0
    frequency: float | None = _f("float", bounds="> 0", unit="Hz", when=_OSCILLATING)
    amplitude: float | None = _f("float", bounds=">= 0, <= 1", when=_OSCILLATING + ("h2-air",),
                                   optional_for=_GAS)
    plateau: float | None = _f("float", bounds=">= 0", unit="Pa", when=_DETONATION)  # <= peak
    # spike e-folding, oscillation e-folding
    decay: float | None = _f("float", bounds="> 0", unit="s", when=_REVERBERATING, optional_for=_GAS)
    damping: float | None = _f("float", bounds="> 0", unit="s", when=_REVERBERATING, optional_for=_GAS)
    # detonation's local peak: extra height (0: none), centre time and full width, in [0, duration]
    local_peak: float | None = _f("float", 0.0, bounds=">= 0", unit="Pa", when=_DETONATION)
    local_time: float | None = _f("float", None, bounds=">= 0", unit="s", when=_DETONATION)
    local_width: float | None = _f("float", None, bounds="> 0", unit="s", when=_DETONATION)
    # h2-air: H2 volume fraction in H2 and its oxidiser, air (O2:N2 = 1:3.76) or oxygen,
    # within the oxidiser's limits (mixture.H2_LIMITS, checked in _check_h2_air); the
    # explosion's regime
    h2_fraction: float | None = _f("float", bounds="> 0, < 1", when=_H2_AIR)
    regime: str | None = _f("str", choices=REGIMES, when=_H2_AIR)
    oxidizer: str | None = _f("str", "air", choices=OXIDIZERS, when=_H2_AIR)
    # an oxygen mixture's inert diluent, its volume fraction of the whole mixture (at most
    # mixture.DILUENT_PER_O2 moles per mole of O2, checked in _check_h2_air)
    diluent: str | None = _f("str", "N2", choices=DILUENTS, when=_OXYGEN)
    diluent_fraction: float | None = _f("float", 0.0, bounds=">= 0, < 1", when=_OXYGEN)
    # initial (ambient) state of the mixture: a room's air; within these bounds every state
    # computed for an air mixture (the reflected shock's is the hottest) stays below 3500 K,
    # the upper end of the thermodynamic data's fits; an oxygen mixture's reach 4,184 K,
    # where the extrapolated fits still hold (gas.compute)
    T0: float | None = _f("float", 293.15, bounds=">= 250, <= 400", unit="K", when=_H2_AIR)
    p0: float | None = _f("float", 101325.0, bounds=">= 5e4, <= 2e5", unit="Pa", when=_H2_AIR)
    # share of the AICC overpressure lost to the walls (0: the adiabatic bound)
    heat_loss: float | None = _f("float", 0.0, bounds=">= 0, < 1", when=_H2_AIR)
    # length of the room along which the burnt gas resonates, f = c_b / (2 room_length)
    room_length: float | None = _f("float", bounds="> 0", unit="m", when=_H2_AIR)
    file: Path | None = _f("path", when=("signal", "table"))         # absolute Path of the CSV
    # charge: its mass, explosive (TNT equivalent by peak pressure or impulse, loads.explosives),
    # centre (gdim coordinates) and burst (free_air: spherical; surface: hemispherical on the ground)
    mass: float | None = _f("float", bounds="> 0", unit="kg", when=_CHARGE)
    explosive: str | None = _f("str", "TNT", choices=EXPLOSIVES, when=_CHARGE)
    equivalence: str | None = _f("str", "pressure", choices=EQUIVALENCES, when=_CHARGE)
    position: tuple[float, ...] | None = _f("point", unit="m", when=_CHARGE)
    burst: str | None = _f("str", choices=BURSTS, when=_CHARGE)
    region_min: tuple[float, ...] | None = _f("point", None, unit="m", when=_PRESSURE)  # lower corner of the box
    region_max: tuple[float, ...] | None = _f("point", None, unit="m", when=_PRESSURE)  # upper corner
    region_factor: float | None = _f("float", None, bounds=">= 0", when=_PRESSURE)      # p inside / p outside
    # parsed from `file` (table only; left out of ==, which compares `file`):
    t: np.ndarray | None = field(default=None, compare=False)  # [s] increasing, read-only f8
    p: np.ndarray | None = field(default=None, compare=False)  # [Pa], read-only float64

    @property
    def region(self) -> tuple | None:
        """(region_min, region_max, region_factor) for loads.unit_pressure_vector, or None."""
        return None if self.region_factor is None else \
            (self.region_min, self.region_max, self.region_factor)


@dataclass(frozen=True)
class Supports:
    """[supports]: boundary names; a boundary may be in one list only."""
    rollers: tuple[str, ...] = _f("names", ())   # zero normal displacement
    clamped: tuple[str, ...] = _f("names", ())   # zero displacement (never the load boundary)
    # simply supported: zero displacement along the last axis (y in 2D, z in 3D: a wall's
    # thickness), free rotation and sliding
    simple: tuple[str, ...] = _f("names", ())


@dataclass(frozen=True)
class Rebar:
    """[rebar]: steel bars in tension only (rebar/cables.py), as layers parallel to faces of a
    rectangle, box or bunker, or behind face groups of a 3D mesh file (rebar/faces.py). No
    faces: no bars. In 2D a layer is one bar standing for bars
    ``spacing`` apart across the depth (area pi d^2 / 4 / spacing per metre)."""
    faces: tuple[str, ...] = _f("names", ())      # a layer near each of these faces
    cover: float | None = _f("float", None, bounds="> 0", unit="m")       # face to bar axis
    diameter: float | None = _f("float", None, bounds="> 0", unit="m")
    spacing: float | None = _f("float", None, bounds="> 0", unit="m")     # between bars of a layer
    # bar axes (3D); "both": the two axes along each face (a bunker's walls and roof)
    direction: str = _f("str", "x", choices=("x", "y", "z", "xy", "xz", "yz", "both"))
    E: float = _f("float", 2.0e11, bounds="> 0", unit="Pa")
    f_y: float | None = _f("float", None, bounds="> 0", unit="Pa")        # none: elastic
    # rupture strain, total engineering strain (B500: A_gt >= 0.05); none: never ruptures
    eps_u: float | None = _f("float", None, bounds="> 0", unit="-")
    rho: float = _f("float", 7850.0, bounds="> 0", unit="kg/m^3")


@dataclass(frozen=True)
class Time:
    """[time]"""
    end: float = _f("float", bounds="> 0", unit="s")              # final time [s], > 0
    scheme: str = _f("str", "imex", choices=SCHEMES)              # one of SCHEMES
    cfl: float = _f("float", 0.9, bounds="> 0, <= 1")             # imex: safety factor on bulk dt, (0, 1]
    # theta (Moreau-Jean, unconditionally stable): the step, default set by accuracy (the
    # load's shortest feature / 20), and theta (1/2 conserves energy, > 1/2 damps)
    dt: float | None = _f("float", None, bounds="> 0", unit="s", when=("scheme", "theta"))
    theta: float | None = _f("float", 0.5, bounds=">= 0.5, <= 1", when=("scheme", "theta"))


@dataclass(frozen=True)
class Output:
    """[output]"""
    every: int = _f("int", 10, bounds=">= 1")     # steps between rows of history.csv, >= 1
    fields: int = _f("int", 10, bounds=">= 0")    # field snapshots over the run, >= 0 (0 = none)
    figures: bool = _f("bool", True)              # write figures at the end
    # times at which the fragments are also reported (summary.json "fragments_at")
    fragments_at: tuple[float, ...] = _f("numbers", (), bounds=">= 0", unit="s")
    # wall time between checkpoints (and one at the end): `dolfrag run --resume` continues from the last
    checkpoint_every: float = _f("float", 900.0, bounds="> 0", unit="s")


@dataclass(frozen=True)
class Run:
    """[run]: limits checked before meshing (dolfrag/guards.py), sized for a 2-core, 24 GB
    machine; raise them for a bigger one."""
    max_cells: float = _f("float", 2.0e6, bounds="> 0")     # estimated cells, > 0
    max_steps: float = _f("float", 1.0e7, bounds="> 0")     # estimated time steps, > 0


@dataclass(frozen=True)
class Debris:
    """[debris]: the throw of the fragments of a 3D run (z up) after its end, as point masses
    under gravity and air drag (post/debris.py, docs/fragments.md). Ignored in 2D (no debris)."""
    enabled: bool = _f("bool", True)                                     # debris.csv, debris_map.png
    C_D: float = _f("float", 1.0, bounds="> 0")                          # drag coefficient [-] of a tumbling chunk
    air_density: float = _f("float", 1.225, bounds=">= 0", unit="kg/m^3")  # 0: no drag
    ground_z: float | None = _f("float", None, unit="m")                 # default: the body's lowest point
    hazard_energy: float = _f("float", 79.0, bounds="> 0", unit="J")     # a fragment landing with this is hazardous
    hazard_area: float = _f("float", 55.7, bounds="> 0", unit="m^2")     # one hazardous fragment per this: the limit
    ring_width: float = _f("float", 1.0, bounds="> 0", unit="m")         # annuli of the hazard density


@dataclass(frozen=True)
class Case:
    name: str
    description: str
    geometry: Geometry
    mesh: Mesh
    material: Material
    materials: dict[str, Material]   # per-physical-group overrides of `material`
    interface: Interface
    load: Load
    supports: Supports
    rebar: Rebar
    time: Time
    output: Output
    run: Run
    debris: Debris
    source: Path | None = None       # the case file this came from
    # where each value a strength class filled in came from ({"material.E": "EN 1992-1-1 ..."})
    sources: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict:
        """Plain JSON-serialisable dict (paths as str, arrays and tuples as lists)."""
        return _plain(self)


_SECTIONS = {"geometry": Geometry, "mesh": Mesh, "material": Material, "interface": Interface,
             "load": Load, "supports": Supports, "rebar": Rebar, "time": Time, "output": Output, "run": Run,
             "debris": Debris}
_TOP_KEYS = ("name", "description", *_SECTIONS, "materials")
_PATH_KEYS = {f"{s}.{f.name}" for s, cls in _SECTIONS.items() for f in fields(cls)
              if "spec" in f.metadata and f.metadata["spec"].kind == "path"}


def _plain(x: Any) -> Any:
    if is_dataclass(x):
        return {f.name: _plain(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return str(x) if isinstance(x, Path) else x


# ---------------------------------------------------------------- loading
def _read_table(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Parse a 't, p' CSV (optional header line); CaseError names the file and the line."""
    where = f"load.file = '{path}'"
    try:
        lines = [(n, s.strip()) for n, s in enumerate(path.read_text("utf-8").splitlines(), 1)]
    except (OSError, UnicodeDecodeError) as err:
        raise CaseError(f"{where}: cannot read: {err}") from None
    rows: list[tuple[float, float]] = []
    for i, (number, line) in enumerate(s for s in lines if s[1]):
        try:
            t, p = (float(cell) for cell in line.split(","))
            if not (math.isfinite(t) and math.isfinite(p)):
                raise ValueError
        except ValueError:
            if i == 0:  # header line
                continue
            raise CaseError(f"{where}: line {number}: {_show(line)} is not two finite "
                            "comma-separated numbers 't, p'") from None
        if rows and t <= rows[-1][0]:
            raise CaseError(f"{where}: line {number}: t = {t!r} s is not greater than the "
                            f"previous t = {rows[-1][0]!r} s (t must be strictly increasing)")
        rows.append((t, p))
    if len(rows) < 2:
        raise CaseError(f"{where}: needs at least 2 rows 't, p', found {len(rows)}")
    t_arr, p_arr = np.array(rows, dtype=np.float64).T.copy()
    for arr in (t_arr, p_arr):
        arr.setflags(write=False)
    return t_arr, p_arr


def _check(case: Case) -> None:
    """Rules linking several keys or sections."""
    load, sup, known = case.load, case.supports, case.geometry.boundaries
    law = case.interface
    if law.law == "rccm" and (law.sigma_c is None) == (law.w is None):
        raise CaseError(f"interface.sigma_c = {law.sigma_c!r}, interface.w = {law.w!r}: "
                        "rccm needs exactly one of them (Pa, J/m^2)")
    if law.C_T is not None and law.shear_ratio is not None:
        raise CaseError(f"interface.C_T = {law.C_T:g} Pa/m, interface.shear_ratio = {law.shear_ratio!r}: "
                        "give one of them (C_T in Pa/m, or shear_ratio = C_T / C_N)")
    if case.time.scheme == "theta" and load.signal == "charge" and case.time.dt is None:
        raise CaseError("time.dt: missing (required when time.scheme is 'theta' and load.signal is 'charge': "
                        "the charge's shortest positive phase is known only on the mesh), s")
    if case.time.scheme == "theta" and not _law(law).theta:
        raise CaseError(f"time.scheme = 'theta' with interface.law = {law.law!r}: not available yet "
                        "(the rigid laws run with 'imex')")
    if law.law in ("linear_softening", "rccm_decoupled") and law.sigma_c is None:
        raise CaseError(f"interface.sigma_c: missing (required when interface.law is "
                        f"{law.law!r}), Pa")
    if law.law == "rccm_decoupled":
        C_N = law.stiffness(case.material.E, case.mesh.size)[0]
        if C_N <= law.sigma_c**2 / (2 * law.G_c):
            raise CaseError(f"interface.G_c = {law.G_c!r}: rccm_decoupled needs C_N > sigma_c^2 / "
                            f"(2 G_c), i.e. G_c > {law.sigma_c**2 / (2 * C_N):.3g} J/m^2 with C_N = "
                            f"{C_N:.3g} Pa/m (or raise interface.C_N / stiffness_ratio)")
    if load.signal == "triangular" and load.duration < load.rise:
        raise CaseError(f"load.duration = {load.duration!r}: "
                        f"must be >= load.rise = {load.rise!r} (s)")
    _check_load(load, case.geometry)
    if load.kind == "stretch":
        _check_stretch(case)
    named = {**({"load.boundary": load.boundary} if load.kind == "pressure" else {}),
             "supports.rollers": list(sup.rollers),
             "supports.clamped": list(sup.clamped), "supports.simple": list(sup.simple),
             "rebar.faces": list(case.rebar.faces)}
    for key, value in named.items():
        for name in [value] if isinstance(value, str) else value:
            if known is not None and name not in known:
                raise CaseError(f"{key} = {_show(value)}: unknown boundary {name!r}; "
                                f"allowed: {', '.join(known)}")
    kinds = {"rollers": sup.rollers, "clamped": sup.clamped, "simple": sup.simple}
    for kind, names in kinds.items():
        for other, others in kinds.items():
            both = sorted(set(names) & set(others))
            if kind < other and both:
                raise CaseError(f"supports.{kind} = {_show(list(names))}: {both[0]!r} is also in "
                                f"supports.{other} (a boundary may be in one list only)")
    if case.geometry.kind == "bunker":
        _check_bunker(case.geometry)
    _check_rebar(case.rebar, case.geometry)
    _check_groups(case)
    late = [t for t in case.output.fragments_at if t > case.time.end]
    if late:
        raise CaseError(f"output.fragments_at = {_show(list(case.output.fragments_at))}: {late[0]!r} s is past "
                        f"time.end = {case.time.end!r} s; every time must be in [0, time.end]")
    bars = case.rebar
    if bars.faces:
        if case.geometry.kind == "file" and case.geometry.tdim == 2:
            raise CaseError(f"rebar.faces = {_show(list(bars.faces))}: layers need a rectangle, box, bunker or "
                            "a 3D mesh file (geometry.dim = 3)")
        for key in ("cover", "diameter", "spacing"):
            if getattr(bars, key) is None:
                raise CaseError(f"rebar.{key}: missing (required when rebar.faces is given), m")
        geometry = case.geometry
        thinnest = (geometry.scale * geometry.wall if geometry.kind == "bunker" else np.inf if geometry.kind == "file"
                    else min(x for x in (geometry.length, geometry.width, geometry.thickness) if x))
        if not bars.cover < thinnest / 2:
            raise CaseError(f"rebar.cover = {bars.cover!r}: must be < {thinnest / 2:g} m (half the body's "
                            "smallest extent), or the layers cross")
    if load.boundary in sup.clamped:
        raise CaseError(f"supports.clamped = {_show(list(sup.clamped))}: {load.boundary!r} is the "
                        "load.boundary (the loaded boundary may not be clamped)")


BUILT_GROUP = "concrete"  # the material group of every cell of a generated rectangle or box (mesh.py)


def _check_bunker(geometry: Geometry) -> None:
    """The door fits its wall: narrower than the room, no higher than it, its panel thinner
    than the wall."""
    (L_x, _, H), (width, height) = geometry.inner, geometry.door
    for key, value, limit, what in (("door", width, L_x, "< geometry.inner[0], the room's length"),
                                    ("door", height, H, "<= geometry.inner[2], the room's height"),
                                    ("door_thickness", geometry.door_thickness, geometry.wall, "< geometry.wall")):
        if value > limit or (value == limit and what.startswith("< ")):
            shown = list(geometry.door) if key == "door" else value
            raise CaseError(f"geometry.{key} = {_show(shown)}: {value:g} m must be {what} = {limit:g} m")


def _built_groups(geometry: Geometry) -> tuple[str, ...]:
    """The material groups a generated geometry names (mesh.py, bunker.py)."""
    if geometry.kind == "bunker":
        return bunker.PIECES + (("door",) if geometry.door_thickness > 0 else ())
    return (BUILT_GROUP,)


def _check_groups(case: Case) -> None:
    """[materials.NAME] of a generated geometry: NAME is one of its groups (an imported
    mesh's groups are checked once it is read, bulk.material_fields)."""
    if case.geometry.kind == "file":
        return
    allowed = _built_groups(case.geometry)
    for name in case.materials:
        if name not in allowed:
            raise CaseError(f"materials.{name}: not a material group of the {case.geometry.kind}; allowed: "
                            f"{', '.join(map(repr, allowed))} (other groups need geometry.kind = 'file')")


def _check_rebar(bars: Rebar, geometry: Geometry) -> None:
    """[rebar] keys among themselves and against the geometry's dimension (the layers
    themselves: rebar/layout.layer_polylines)."""
    optional = ("cover", "diameter", "spacing", "f_y", "eps_u")
    if not bars.faces:
        for key in optional:
            if getattr(bars, key) is not None:
                raise CaseError(f"rebar.{key} = {getattr(bars, key)!r}: only allowed when rebar.faces is given "
                                "(a list of faces to lay bars along)")
        return
    dim = geometry.tdim
    if geometry.kind == "bunker":
        if set(bars.faces) - {"inner", "outer"}:
            raise CaseError(f"rebar.faces = {_show(list(bars.faces))}: in a bunker must be among 'inner', 'outer' "
                            "(layers near that face of every wall and the roof)")
        if bars.direction != "both":
            raise CaseError(f"rebar.direction = {bars.direction!r}: in a bunker must be 'both' (a layer along "
                            "each in-plane axis of every wall and the roof)")
    if geometry.kind == "file" and dim == 3 and bars.direction != "both":
        raise CaseError(f"rebar.direction = {bars.direction!r}: on a mesh file must be 'both' (a layer along "
                        "each in-plane axis behind every flat part of each face group)")
    if dim == 2 and bars.direction not in ("x", "y"):
        raise CaseError(f"rebar.direction = {bars.direction!r}: in 2D must be 'x' or 'y' (the bar axis)")
    for face in (f for f in bars.faces if f in BOX_BOUNDARIES):
        normal = "xyz"[BOX_BOUNDARIES.index(face) // 2]
        if not set(bars.direction) - {normal}:
            raise CaseError(f"rebar.direction = {bars.direction!r}: no axis along face {face!r} of rebar.faces "
                            f"(its normal is {normal}); allowed: axes other than {normal!r}")
    if bars.diameter is not None and bars.spacing is not None and bars.diameter >= bars.spacing:
        raise CaseError(f"rebar.diameter = {bars.diameter!r}: must be < rebar.spacing = {bars.spacing!r} m "
                        "(neighbouring bars would overlap)")
    if bars.diameter is not None and bars.cover is not None and bars.diameter / 2 > bars.cover:
        raise CaseError(f"rebar.diameter = {bars.diameter!r}: must be <= 2 x rebar.cover = {2 * bars.cover:g} m "
                        "(the cover is measured face to bar axis: a thicker bar sticks out of the body)")
    if bars.eps_u is not None and bars.f_y is not None and bars.eps_u <= bars.f_y / bars.E:
        raise CaseError(f"rebar.eps_u = {bars.eps_u!r}: must be > the yield strain rebar.f_y / rebar.E = "
                        f"{bars.f_y / bars.E:.3g} (the bar yields before it ruptures)")


STRETCHED = ("left", "right")  # the boundaries a stretch pulls apart along x


def _check_stretch(case: Case) -> None:
    """What a stretch needs: the imex star solve (Imex.impose holds the end velocities as
    supports) with a nonsmooth law. (Rectangles and boxes have the STRETCHED boundaries;
    the runner checks an imported mesh.)"""
    where = "load.kind = 'stretch' with"
    if case.time.scheme != "imex":
        raise CaseError(f"{where} time.scheme = {case.time.scheme!r}: not available (the imposed end "
                        "velocities need the imex star solve); use time.scheme = 'imex'")
    if _law(case.interface).springs:
        raise CaseError(f"{where} interface.law = {case.interface.law!r}: not available (its inverted star blocks "
                        "cannot move prescribed components); use a nonsmooth law, e.g. 'linear_softening'")


def _check_load(load: Load, geometry: Geometry) -> None:
    """Rules linking the keys of [load] (and the region to the geometry's dimension)."""
    if load.signal == "h2-air":
        _check_h2_air(load)
    if load.signal == "charge":
        _check_charge(load, geometry)
    if load.signal == "deflagration" or (load.signal == "h2-air" and load.regime == "deflagration"):
        if load.rise <= 0:
            raise CaseError(f"load.rise = {load.rise!r}: must be > 0 for a deflagration (s)")
        if load.duration <= load.rise:
            raise CaseError(f"load.duration = {load.duration!r}: must be > load.rise = "
                            f"{load.rise!r} for a deflagration (s)")
    if load.signal == "detonation":
        if load.plateau > load.peak:
            raise CaseError(f"load.plateau = {load.plateau!r}: must be <= load.peak = "
                            f"{load.peak!r} (Pa; the spike decays to the plateau)")
        local = {"local_time": load.local_time, "local_width": load.local_width}
        if load.local_peak == 0:
            for name, value in local.items():
                if value is not None:
                    raise CaseError(f"load.{name} = {value!r}: only allowed when load.local_peak > 0")
        else:
            for name, value in local.items():
                if value is None:
                    raise CaseError(f"missing key load.{name} (required when load.local_peak > 0): "
                                    "must be a number (s)")
            start, stop = load.local_time - load.local_width / 2, load.local_time + load.local_width / 2
            if start < 0 or stop > load.duration:
                raise CaseError(f"load.local_time = {load.local_time!r}, load.local_width = "
                                f"{load.local_width!r}: the local peak [{start:.3g}, {stop:.3g}] s "
                                f"must lie inside [0, load.duration = {load.duration!r}] s")
    corners = {"region_min": load.region_min, "region_max": load.region_max}
    keys = {**corners, "region_factor": load.region_factor}
    given = [name for name, value in keys.items() if value is not None]
    if given and len(given) < len(keys):
        missing = ", ".join(f"load.{name}" for name in keys if name not in given)
        raise CaseError(f"load.{given[0]} = {_show(keys[given[0]])}: the region needs "
                        f"load.region_min, load.region_max and load.region_factor; missing {missing}")
    if given:
        for name, corner in corners.items():
            if geometry.tdim is not None and len(corner) != geometry.tdim:
                raise CaseError(f"load.{name} = {_show(list(corner))}: must have {geometry.tdim} "
                                f"coordinates (m), one per axis of the {geometry.tdim}D geometry")
        if not all(lo < hi for lo, hi in zip(load.region_min, load.region_max)):
            raise CaseError(f"load.region_max = {_show(list(load.region_max))}: every coordinate must "
                            f"be > load.region_min = {_show(list(load.region_min))} (m)")


def _check_charge(load: Load, geometry: Geometry) -> None:
    """A charge: its centre has the geometry's dimension, its explosive the equivalence
    asked, and no region (its own distances shape the load)."""
    if geometry.tdim is not None and len(load.position) != geometry.tdim:
        raise CaseError(f"load.position = {_show(list(load.position))}: must have {geometry.tdim} coordinates (m), "
                        f"one per axis of the {geometry.tdim}D geometry")
    if EQUIVALENTS[load.explosive][EQUIVALENCES.index(load.equivalence)] is None:
        raise CaseError(f"load.equivalence = {load.equivalence!r}: {load.explosive} has no {load.equivalence} "
                        f"equivalence in {EXPLOSIVES_SOURCE}; allowed: 'pressure'")
    if load.region_factor is not None:
        raise CaseError(f"load.region_factor = {load.region_factor!r}: a charge's pressure follows from each "
                        "facet's distance and angle; remove the region keys")


def _check_h2_air(load: Load) -> None:
    """The mixture of an h2-air load within its limits (mixture.py), and the keys that
    belong to one regime only."""
    _check_mixture(load)
    only = {"deflagration": ("rise",), "detonation": ("decay", "damping")}
    for regime, names in only.items():
        for name in names:
            value = getattr(load, name)
            if regime != load.regime and value is not None:
                raise CaseError(f"load.{name} = {value!r}: only allowed when load.regime is {regime!r} "
                                f"(--set load.{name}= removes it)")
    if load.regime == "deflagration" and load.rise is None:
        raise CaseError("missing key load.rise (required when load.regime is 'deflagration'): "
                        "must be a number > 0 (s)")


def _check_mixture(load: Load) -> None:
    """h2_fraction within its oxidiser's limits; a diluted oxygen mixture no more diluted
    than air and of an equivalence ratio within air's limits (mixture.py's docstring)."""
    low, high = mixture.H2_LIMITS[load.oxidizer]
    if not low <= load.h2_fraction <= high:
        raise CaseError(f"load.h2_fraction = {load.h2_fraction!r}: with load.oxidizer = {load.oxidizer!r} must be "
                        f">= {low:g} and <= {high:g} (-, H2 by volume in H2-{load.oxidizer}: "
                        f"{'its detonation limits' if load.oxidizer == 'oxygen' else 'a complete burn'})")
    if load.oxidizer != "oxygen" or load.diluent_fraction == 0:
        return
    given = mixture.Mixture(load.h2_fraction, load.oxidizer, load.diluent, load.diluent_fraction)
    phi = mixture.equivalence_ratio(load.h2_fraction, "oxygen")
    phi_low, phi_high = (mixture.equivalence_ratio(x, "air") for x in mixture.H2_LIMITS["air"])
    if not phi_low <= phi <= phi_high:
        x_low, x_high = (2 * p / (2 * p + 1) for p in (phi_low, phi_high))  # x = 2 phi / (2 phi + 1) in oxygen
        raise CaseError(f"load.h2_fraction = {load.h2_fraction!r}: with load.diluent_fraction > 0 must be >= "
                        f"{x_low:.3f} and <= {x_high:.3f} (-, the equivalence ratios {phi_low:.3g}-{phi_high:.3g} "
                        f"of H2-air's limits)")
    per_o2 = mixture.diluent_per_o2(given)
    if per_o2 > mixture.DILUENT_PER_O2:
        most = mixture.DILUENT_PER_O2 * (1 - load.h2_fraction) / (1 + mixture.DILUENT_PER_O2 * (1 - load.h2_fraction))
        raise CaseError(f"load.diluent_fraction = {load.diluent_fraction!r}: {per_o2:.3g} moles of {load.diluent} "
                        f"per mole of O2; at most {mixture.DILUENT_PER_O2:g} (air's N2) allowed, i.e. "
                        f"<= {most:.4f} with load.h2_fraction = {load.h2_fraction!r} (-, of the whole mixture)")


_GRADE_KEYS = {"E": "E", "nu": "nu", "rho": "rho"}  # [material] key: Concrete field
# [interface] key: Concrete field, for the laws with that key
_GRADE_STRENGTH = {"sigma_c": ("f_ctm", ("rccm", "rccm_decoupled", "linear_softening")),
                   "G_c": ("G_F", ("rccm_decoupled", "linear_softening"))}


def _grade_defaults(raw: dict) -> dict[str, str]:
    """Fill in the keys a strength class gives (Material's docstring) where the case leaves
    them out; return {dotted key: source} of what was filled."""
    sources = {}
    tables = [("material", raw.get("material"))]
    if isinstance(raw.get("materials"), dict):
        tables += [(f"materials.{name}", t) for name, t in raw["materials"].items()]
    grade_spec = next(f.metadata["spec"] for f in fields(Material) if f.name == "grade")
    for prefix, table in tables:
        if not isinstance(table, dict) or "grade" not in table:
            continue
        _convert(f"{prefix}.grade", table["grade"], grade_spec, Path("."))
        values = concrete.concrete(table["grade"])
        for key, name in _GRADE_KEYS.items():
            if key not in table:
                table[key] = getattr(values, name)
                sources[f"{prefix}.{key}"] = f"{values.grade}: {concrete.SOURCES[key]}"
    material, interface = raw.get("material"), raw.setdefault("interface", {})
    if isinstance(material, dict) and material.get("grade") in concrete.GRADES and isinstance(interface, dict):
        values = concrete.concrete(material["grade"])
        law = interface.get("law", "elastic")
        for key, (name, laws) in _GRADE_STRENGTH.items():
            if law in laws and key not in interface and not (key == "sigma_c" and "w" in interface):
                interface[key] = getattr(values, name)
                sources[f"interface.{key}"] = f"{values.grade}: {concrete.SOURCES[name]}"
    return sources


def _build(raw: dict, source: Path) -> Case:
    base = source.parent
    for key, value in raw.items():
        if key not in _TOP_KEYS:
            kind = "section" if isinstance(value, dict) else "key"
            raise CaseError(f"unknown {kind} '{key}'; allowed: {', '.join(_TOP_KEYS)}")
    sources = _grade_defaults(raw)
    parts = {s: _section(cls, raw.get(s, {}), s, base) for s, cls in _SECTIONS.items()}
    mats = raw.get("materials", {})
    if not isinstance(mats, dict):
        raise CaseError(f"materials = {_show(mats)}: must be a table of tables [materials.NAME]")
    inherit = {"hypothesis": parts["material"].hypothesis}
    materials = {name: _section(Material, {**inherit, **tbl} if isinstance(tbl, dict) else tbl,
                                f"materials.{name}", base) for name, tbl in mats.items()}
    if parts["load"].signal == "table":
        t, p = _read_table(parts["load"].file)
        parts["load"] = replace(parts["load"], t=t, p=p)
    case = Case(name=_convert("name", raw.get("name", source.stem), _Spec("str"), base),
                description=_convert("description", raw.get("description", ""), _Spec("str"), base),
                materials=materials, source=source, sources=sources, **parts)
    _check(case)
    return case


def _apply_override(raw: dict, item: str) -> None:
    """Apply one "section.key=value" string; the value is TOML if it parses, else a bare
    string; no value ("section.key=") removes the key, which takes its default again (e.g.
    time.dt when switching a theta case to time.scheme=imex)."""
    key, sep, text = item.partition("=")
    parts = [part.strip() for part in key.split(".")]
    if not sep or not all(parts):
        raise CaseError(f"--set {_show(item)}: expected section.key=value")
    if not text.strip():
        section = raw
        for part in parts[:-1]:
            section = section.get(part, {}) if isinstance(section, dict) else {}
        if isinstance(section, dict):
            section.pop(parts[-1], None)
        return
    try:
        value = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = text.strip()
    if ".".join(parts) in _PATH_KEYS and isinstance(value, str) and value:
        value = str(Path(value).resolve())  # a path given on the command line: relative to cwd
    table = raw
    for depth, part in enumerate(parts[:-1], 1):
        table = table.setdefault(part, {})
        if not isinstance(table, dict):
            raise CaseError(f"--set {_show(item)}: {'.'.join(parts[:depth])} is not a table")
    table[parts[-1]] = value


def builtin_cases() -> list[str]:
    """Sorted names of the built-in cases (dolfrag/cases/*.toml); [] if there are none."""
    return sorted(p.stem for p in _CASES_DIR.glob("*.toml")) if _CASES_DIR.is_dir() else []


def _unknown_case(source: Any) -> CaseError:
    names = ", ".join(builtin_cases()) or "(none)"
    return CaseError(f"case {str(source)!r}: no such file or built-in case; "
                     f"built-in cases: {names}")


def builtin_case_text(name: str) -> str:
    """Full TOML text of the built-in case `name`."""
    if name not in builtin_cases():
        raise _unknown_case(name)
    return (_CASES_DIR / f"{name}.toml").read_text(encoding="utf-8")


def load_case(source: str | Path, overrides: Sequence[str] = ()) -> Case:
    """Read a case from a .toml path or a built-in case name, apply overrides, validate."""
    path = Path(source).expanduser()
    if not path.is_file():
        if str(source) not in builtin_cases():
            raise _unknown_case(source)
        path = _CASES_DIR / f"{source}.toml"
    path = path.resolve()
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise CaseError(f"{path}: invalid TOML: {err}") from None
    for item in overrides:
        _apply_override(raw, item)
    return _build(raw, path)
