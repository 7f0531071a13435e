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

The package: schema.py (a key's spec and conversion), sections.py (the sections),
rules.py (the rules between keys), loading.py (files, overrides, built-in cases).
"""
from dolfrag.case.loading import builtin_case_text, builtin_cases, load_case  # noqa: F401
from dolfrag.case.rules import STRETCHED  # noqa: F401
from dolfrag.case.schema import CaseError  # noqa: F401
from dolfrag.case.sections import (Case, Debris, Geometry, Interface, Load, Material, Mesh, Output, Rebar,  # noqa: F401
                                   Run, Supports, Time)
