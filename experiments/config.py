"""Scenario configuration files (TOML) and their validation.

Every error names the file, the key and the bound, and is raised before any
simulation starts. A schema is a dict ``section -> {key: Field}``; the top
level is the section ``""``.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from msf_contact.materials import Material, preset


class ConfigError(ValueError):
    """A configuration file is malformed, has an unknown key or a value out of range."""


@dataclass(frozen=True)
class Field:
    """One key: its type (``float``, ``int``, ``str``, ``bool``, ``list[float]``,
    ``list[str]``, ``list[int]``), bounds (inclusive unless ``lo_open``/``hi_open``),
    choices, default (``REQUIRED`` if none) and help text."""

    type: str
    default: Any = None
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: Sequence[str] | None = None
    required: bool = False
    help: str = ""


def _fail(path, key, msg) -> ConfigError:
    return ConfigError(f"{path}: [{key}] {msg}")


def _check_number(path, key, v, f: Field):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _fail(path, key, f"= {v!r} must be a number")
    v = float(v) if f.type.endswith("float") else v
    if isinstance(v, float) and not math.isfinite(v):
        raise _fail(path, key, f"= {v!r} must be finite")
    if f.type.endswith("int") and not isinstance(v, int):
        raise _fail(path, key, f"= {v!r} must be a whole number")
    if f.lo is not None and (v <= f.lo if f.lo_open else v < f.lo):
        raise _fail(path, key, f"= {v!r} is below the bound {'>' if f.lo_open else '>='} {f.lo:g}")
    if f.hi is not None and (v >= f.hi if f.hi_open else v > f.hi):
        raise _fail(path, key, f"= {v!r} is above the bound {'<' if f.hi_open else '<='} {f.hi:g}")
    return v


def _check_value(path, key, v, f: Field):
    t = f.type
    if t.startswith("list["):
        if not isinstance(v, list) or not v:
            raise _fail(path, key, f"= {v!r} must be a non-empty list")
        inner = Field(t[5:-1], lo=f.lo, hi=f.hi, lo_open=f.lo_open, hi_open=f.hi_open, choices=f.choices)
        return [_check_value(path, f"{key}[{i}]", x, inner) for i, x in enumerate(v)]
    if t in ("float", "int"):
        return _check_number(path, key, v, f)
    if t == "str":
        if not isinstance(v, str):
            raise _fail(path, key, f"= {v!r} must be a string")
        if f.choices is not None and v not in f.choices:
            raise _fail(path, key, f"= {v!r} is not one of {', '.join(map(repr, f.choices))}")
        return v
    if t == "bool":
        if not isinstance(v, bool):
            raise _fail(path, key, f"= {v!r} must be true or false")
        return v
    if t == "float|str":  # e.g. omega: "self-consistent" | number
        if isinstance(v, str):
            if f.choices is not None and v not in f.choices:
                raise _fail(path, key, f"= {v!r} is not a number nor one of {', '.join(map(repr, f.choices))}")
            return v
        return _check_number(path, key, v, Field("float", lo=f.lo, lo_open=f.lo_open))
    raise AssertionError(f"unknown field type {t}")


def validate(raw: dict, schema: dict[str, dict[str, Field]], path: str) -> dict[str, dict[str, Any]]:
    """Check ``raw`` (parsed TOML) against ``schema``; fill defaults."""
    out: dict[str, dict[str, Any]] = {}
    top = {k: v for k, v in raw.items() if not isinstance(v, dict)}
    sections = {k: v for k, v in raw.items() if isinstance(v, dict)}
    for name in sections:
        if name not in schema or name == "":
            valid = ", ".join(sorted(s for s in schema if s))
            raise _fail(path, name, f"is not a known section; valid sections: {valid}")
    for sec, fields in schema.items():
        given = top if sec == "" else sections.get(sec, {})
        for k in given:
            if k not in fields:
                where = k if sec == "" else f"{sec}.{k}"
                raise _fail(path, where, f"is not a known key; valid keys: {', '.join(sorted(fields))}")
        vals = {}
        for k, f in fields.items():
            where = k if sec == "" else f"{sec}.{k}"
            if k in given:
                vals[k] = _check_value(path, where, given[k], f)
            elif f.required:
                raise _fail(path, where, "is required")
            else:
                vals[k] = f.default
        out[sec] = vals
    return out


def load_toml(path: str | Path) -> tuple[dict, str]:
    """Parse a TOML file; a missing or malformed file is a ConfigError naming it."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such configuration file")
    text = p.read_text(encoding="utf-8")
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: malformed TOML: {exc}") from None


# --------------------------------------------------------- shared pieces ---
def material_fields(role: str) -> dict[str, Field]:
    return {
        "material": Field("str", help=f"preset name of the {role} (msf_contact.materials.preset)"),
        "E": Field("float", lo=0.0, lo_open=True, help="storage modulus E' [Pa]"),
        "tan_delta": Field("float", lo=0.0, hi=1.0 / 3.0, help="loss factor tg(beta) [-], <= 1/3 (100)"),
        "nu": Field("float", lo=-1.0, hi=0.5, lo_open=True, hi_open=True, help="Poisson ratio [-]"),
        "density": Field("float", lo=0.0, lo_open=True, help="[kg/m^3]"),
    }


def build_material(sec: dict, path: str, role: str, default: str | None) -> Material:
    """A Material from a validated section: a preset, optionally overridden."""
    name = sec.get("material") or default
    if name is None and sec.get("E") is None:
        raise _fail(path, f"{role}.material", "or E is required")
    try:
        base = preset(name) if name else Material(role, 1e6, 0.0, 0.3, 1000.0)  # E is given: it replaces 1e6
    except ValueError as exc:
        raise _fail(path, f"{role}.material", str(exc)) from None
    over = {k2: sec[k1] for k1, k2 in (("E", "E_storage"), ("tan_delta", "tan_delta"), ("nu", "nu"),
                                        ("density", "density")) if sec.get(k1) is not None}
    if not over:
        return base
    from dataclasses import replace

    try:
        # labelled by the user's words: the preset (if any) and the keys as given
        words = ", ".join(f"{role}.{k} = {sec[k]:g}" for k in ("E", "tan_delta", "nu", "density")
                          if sec.get(k) is not None)
        return replace(base, name=f"{base.name} ({words})" if name else words, **over)
    except ValueError as exc:
        raise _fail(path, role, str(exc)) from None
