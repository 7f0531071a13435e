"""The schema of a case file's keys: each field's spec (kind, default, bounds, unit, the
conditions under which it is allowed) and the conversion of a TOML value into it, with a
CaseError naming the dotted key."""
from __future__ import annotations

import math
import operator
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any, Callable




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
    # (discriminator field, values...): the key exists only then; or a function returning
    # that tuple when a case is read (a registry's answer, which may grow after import)
    when: tuple | Callable[[], tuple] = ()
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

    def gate(self) -> tuple:
        """``when`` as a tuple (discriminator field, values...), () for a key always allowed."""
        return self.when() if callable(self.when) else self.when

    def condition(self, prefix: str) -> str:
        discriminator, *values = self.gate()
        return f"{prefix}.{discriminator} is " + " or ".join(map(repr, values))


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
        when = spec.gate()
        if when and out[when[0]] not in when[1:]:
            if name in raw:
                raise CaseError(f"{key} = {_show(raw[name])}: only allowed when "
                                f"{spec.condition(prefix)} (--set {key}= removes it)")
            out[name] = None
        elif name in raw:
            out[name] = _convert(key, raw[name], spec, base)
        elif spec.optional_for and out[when[0]] in spec.optional_for:
            out[name] = None
        elif spec.default is _REQ:
            needed = f" (required when {spec.condition(prefix)})" if when else ""
            raise CaseError(f"missing key {key}{needed}: {spec.describe()}")
        else:
            out[name] = spec.default
    return cls(**out)


