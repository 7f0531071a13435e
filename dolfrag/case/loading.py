"""Reading a case: a TOML file or a built-in case, --set overrides, the concrete's values from
its strength class, the sections built and the rules checked."""
from __future__ import annotations

import math
import tomllib
from dataclasses import fields, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dolfrag import concrete
from dolfrag.interface.models import LAWS
from dolfrag.case.rules import _check
from dolfrag.case.schema import CaseError, _Spec, _convert, _section, _show
from dolfrag.case.sections import _PATH_KEYS, _SECTIONS, _TOP_KEYS, Case, Material

_CASES_DIR = Path(__file__).parent.parent / "cases"


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


_GRADE_KEYS = {"E": "E", "nu": "nu", "rho": "rho"}  # [material] key: Concrete field
# [interface] key: Concrete field, for the laws with that key (interface/models.LAWS)
_GRADE_STRENGTH = {"sigma_c": "f_ctm", "G_c": "G_F"}


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
        name = interface.get("law", "elastic")
        law = LAWS.get(name) if isinstance(name, str) else None  # a bad value is refused with its key later
        for key, field in _GRADE_STRENGTH.items():
            if law and key in law.keys and key not in interface and not (key == "sigma_c" and "w" in interface):
                interface[key] = getattr(values, field)
                sources[f"interface.{key}"] = f"{values.grade}: {concrete.SOURCES[field]}"
        if law and "tau_c" in law.keys:
            sources.update(_compressive_defaults(interface, values))
    rebar = raw.get("rebar")
    if (isinstance(material, dict) and material.get("grade") in concrete.GRADES and isinstance(rebar, dict)
            and rebar.get("bond") == "fib2010" and "bond_tau_max" not in rebar):
        values = concrete.concrete(material["grade"])
        rebar["bond_tau_max"] = concrete.bond_strength(values.f_cm)
        sources["rebar.bond_tau_max"] = f"{values.grade}: {concrete.SOURCES['bond_tau_max']}"
    return sources


def _compressive_defaults(interface: dict, values: concrete.Concrete) -> dict[str, str]:
    """A class's strength under compression for linear softening's intact links, mu_i and
    tau_c, where the case leaves them out; {dotted key: source} of what was filled."""
    sources = {}
    if "mu_i" not in interface:
        interface["mu_i"] = concrete.INTERNAL_FRICTION
        sources["interface.mu_i"] = concrete.SOURCES["mu_i"]
    mu_i = interface["mu_i"]
    if "tau_c" not in interface and isinstance(mu_i, (int, float)) and mu_i >= 0:
        interface["tau_c"] = concrete.shear_strength(values.f_cm, mu_i)
        sources["interface.tau_c"] = f"{values.grade}: {concrete.SOURCES['tau_c']}"
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
