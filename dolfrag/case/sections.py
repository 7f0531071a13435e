"""The sections of a case file as frozen dataclasses, their fields' specs (schema.py), and
the names each key may take."""
from __future__ import annotations

from dataclasses import dataclass, field, fields, is_dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from dolfrag import bunker, concrete
from dolfrag.interface.models import LAWS as _LAWS, owning
from dolfrag.loads import mixture
from dolfrag.loads.charge import BURSTS
from dolfrag.loads.explosives import EQUIVALENCES, EXPLOSIVES
from dolfrag.case.schema import _f

GEOMETRY_KINDS = ("rectangle", "box", "bunker", "file")
HYPOTHESES = ("plane_strain", "plane_stress")
SIGNALS = ("triangular", "friedlander", "deflagration", "detonation", "h2-air", "table", "charge")
REGIMES = ("deflagration", "detonation")  # of an h2-air explosion
OXIDIZERS = tuple(mixture.OXIDIZERS)  # of an h2-air explosion's hydrogen
DILUENTS = tuple(mixture.DILUENTS)    # of an oxygen mixture
LOAD_KINDS = ("pressure", "stretch")
SCHEMES = ("imex", "theta")
RATE_EFFECTS = ("none", "fib2010")
RECTANGLE_BOUNDARIES = ("left", "right", "bottom", "top")
BOX_BOUNDARIES = RECTANGLE_BOUNDARIES + ("front", "back")
BUNKER_BOUNDARIES = bunker.BOUNDARIES


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
_GAS = ("h2-air",)  # optional_for: keys an h2-air load may leave out (its regime decides, loads.applied)


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
    # gmsh's Mesh.OptimizeThreshold in 3D: tetrahedra of lower quality are optimised (the
    # worst one sets the explicit step); default gmsh's 0.3 for boxes and .geo, 0.8 for a bunker
    optimize_threshold: float | None = _f("float", None, bounds="> 0, <= 1")


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
    # one of interface/models.LAWS (a live view: a law added to the registry is a choice)
    law: str = _f("str", "elastic", choices=_LAWS.keys())
    C_N: float | None = _f("float", None, bounds="> 0", unit="Pa/m")   # normal [Pa/m], > 0
    C_T: float | None = _f("float", None, bounds="> 0", unit="Pa/m")   # tangential [Pa/m], > 0
    stiffness_ratio: float = _f("float", 10.0, bounds="> 0")        # [-], > 0
    # C_T = shear_ratio * C_N on every mesh (instead of C_T); the RCCM shear strength is then
    # sqrt(shear_ratio) sigma_c
    shear_ratio: float | None = _f("float", None, bounds="> 0")     # [-], > 0
    # rccm: give sigma_c (peak tensile traction, then w = sigma_c^2 / C_N) or w, not both;
    # rccm_decoupled: sigma_c and G_c independent of C_N; linear_softening: sigma_c (rigid up
    # to it) and G_c
    sigma_c: float | None = _f("float", None, bounds="> 0", unit="Pa", when=partial(owning, "sigma_c"))
    w: float | None = _f("float", None, bounds="> 0", unit="J/m^2", when=partial(owning, "w"))
    b: float | None = _f("float", 0.0, bounds=">= 0", unit="J s/m^2", when=partial(owning, "b"))  # 0: rate-independent
    G_c: float | None = _f("float", bounds="> 0", unit="J/m^2", when=partial(owning, "G_c"))
    # threshold: rigid, tension up to R_c while the gap stays below W_eth
    R_c: float | None = _f("float", bounds="> 0", unit="Pa", when=partial(owning, "R_c"))
    W_eth: float | None = _f("float", bounds="> 0", unit="m", when=partial(owning, "W_eth"))
    # Coulomb friction; rccm: mu (1 - beta) acts; threshold, linear_softening: on the cone
    # shifted by the cohesion while the link holds
    mu: float | None = _f("float", 0.0, bounds=">= 0", when=partial(owning, "mu"))
    # internal friction of the intact material (Mohr-Coulomb type). rccm, rccm_decoupled: shear
    # drives damage only above mu_i times the contact pressure (not given: 0, the reference
    # paper's law); linear_softening: the intact link's shear strength is mu_i r_N + tau_c under
    # the pressure r_N (not given: mu, the Camacho-Ortiz cone; with a grade: 0.75)
    mu_i: float | None = _f("float", None, bounds=">= 0", when=partial(owning, "mu_i"))
    # linear_softening: the intact link's shear strength at zero pressure (not given: (1 + mu_i)
    # sigma_c, the Camacho-Ortiz cone; with a grade: from f_cm, docs/materials.md)
    tau_c: float | None = _f("float", None, bounds="> 0", unit="Pa", when=partial(owning, "tau_c"))
    # strength at the strain rate of the bulk beside each link (interface/rate.py):
    # "fib2010" sigma_c x the fib Model Code 2010 tensile factor, "none" sigma_c alone
    rate_effect: str | None = _f("str", "none", choices=RATE_EFFECTS, when=partial(owning, "rate_effect"))

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
    (`regime`) with its levels computed from the mixture (dolfrag/loads/gas.py: h2_fraction in air
    or in oxygen, `oxidizer`, an oxygen mixture's optional `diluent`, T0, p0),
    the overpressures reduced by `heat_loss`, the acoustic frequency c_b / (2 room_length);
    `rise` (deflagration), `duration`, and optionally `amplitude`, `decay`, `damping`
    (detonation; defaults loads.applied).
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
    # "exact": the strain |c| / L - 1 of the current chord, the force along it; "small_strain":
    # t0.(u_b - u_a) / L along the reference direction t0, as the linear bulk beside the bars,
    # which the exact chords read as a stretch theta^2 / 2 where it turns by theta (cables.py)
    kinematics: str = _f("str", "exact", choices=("exact", "small_strain"))
    # "perfect": each bar point moves with the cell it lies in; "fib2010": the bars have nodes
    # of their own and slip along the concrete by the fib Model Code 2010 bond-slip law
    # (pull-out, good bond; rebar/bond.py), imex only
    bond: str = _f("str", "perfect", choices=("perfect", "fib2010"))
    # fib2010: the bond strength (none: 2.5 sqrt(f_cm) of material.grade) and s3, the clear
    # rib spacing, where the bond has fallen to its residual 0.4 tau_max
    bond_tau_max: float | None = _f("float", None, bounds="> 0", unit="Pa", when=("bond", "fib2010"))
    bond_s3: float | None = _f("float", 0.01, bounds="> 0.002", unit="m", when=("bond", "fib2010"))


@dataclass(frozen=True)
class Time:
    """[time]"""
    end: float = _f("float", bounds="> 0", unit="s")              # final time [s], > 0
    scheme: str = _f("str", "imex", choices=SCHEMES)              # one of SCHEMES
    cfl: float = _f("float", 0.9, bounds="> 0, <= 1")             # imex: safety factor on bulk dt, (0, 1]
    # imex: a cell whose stable step is below mass_scaling x mesh.size / c_p gets the mass
    # that brings it there (mass_scaling.py); none: off
    mass_scaling: float | None = _f("float", None, bounds="> 0, <= 1", when=("scheme", "imex"))
    # how the bars' stiffness enters the stable step (rebar/stable_step.py): "coupled", the
    # largest eigenvalue of the bulk and bars together; "weyl", the bulk's plus a bound of
    # the bars' (shorter; the step of results made before "coupled"). Under theta it only
    # sets the reported dt_crit_s
    bars_step: str = _f("str", "coupled", choices=("coupled", "weyl"))
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


