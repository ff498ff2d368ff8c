"""Command-line helpers shared by the ``msf-contact`` subcommands
(:mod:`experiments.cli`, :mod:`experiments.impact`,
:mod:`experiments.calibrate`, :mod:`experiments.engine_cli`,
:mod:`experiments.commands`): argparse types, checks of optional flags by
name, the ball's and plate's material from preset names and overriding
flags, and the JSON/table output.

Bad input is refused with a ValueError naming the flag, its value and the
bound (:mod:`msf_contact._validate`); argparse types raise
``argparse.ArgumentTypeError``. Only numpy/scipy (through msf_contact) are
imported here.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace

from msf_contact._validate import (DENSITY_MAX, DENSITY_MIN, E_MAX, E_MIN, check_between, check_finite,
                                   check_positive, check_range)
from msf_contact.materials import Material, preset, preset_names
from msf_contact.record import _clean

DEFAULT_BALL = "polyurethane"
DEFAULT_RADIUS = 0.01  # [m]
DEFAULT_SPEED = 1.0  # [m/s]
#: Base of a plate given only by --plate-E (no --plate NAME): nu and density
#: of steel, no damping. The density only enters the sound-speed check.
PLATE_BASE = dict(tan_delta=0.0, nu=0.3, density=7850.0)


# ------------------------------------------------------------ argparse types ---
def number(text: str) -> float:
    """argparse type: a float (NaN and inf are refused later, by name)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def numbers(text: str) -> tuple[float, ...]:
    """argparse type: comma-separated finite floats."""
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers") from None
    if not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r} has a non-finite number")
    return vals


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{v} must be >= 1")
    return v


def lower(text: str) -> str:
    """argparse type of preset names (matched case-insensitively, as ``preset``)."""
    return text.strip().lower()


# -------------------------------------------------------- flags checked by name ---
def flag(dest: str) -> str:
    """The flag of an argparse destination: ``hc_cor`` -> ``--hc-cor``."""
    return "--" + dest.replace("_", "-")


def finite_arg(args, dest):
    """``args.dest`` (None when not given), refused unless finite."""
    v = getattr(args, dest)
    if v is not None:
        check_finite(flag(dest), v)
    return v


def positive_arg(args, dest, unit):
    """``args.dest`` (None when not given), refused unless > 0 [unit]."""
    v = getattr(args, dest)
    if v is not None:
        check_positive(flag(dest), v, unit=unit)
    return v


# --------------------------------------------------------------------- materials ---
def add_material_arguments(p: argparse.ArgumentParser, role: str, default_help: str) -> None:
    """``--ROLE NAME``, ``--ROLE-E``, ``--ROLE-tan-delta``, ``--ROLE-nu`` and the
    density flag of the ball (``role`` "ball") or the plate ("plate")."""
    g = p.add_argument_group(f"{role} material")
    g.add_argument(f"--{role}", type=lower, choices=preset_names(), metavar="NAME",
                   help=f"preset material ({', '.join(preset_names())}); {default_help}")
    g.add_argument(f"--{role}-E", dest=f"{role}_E", type=number, metavar="PA",
                   help=f"{role} storage modulus E' [Pa] (overrides the preset's)")
    g.add_argument(f"--{role}-tan-delta", dest=f"{role}_tan_delta", type=number, metavar="TG",
                   help=f"{role} loss factor tg(beta) = E''/E' [-], valid in [0, 1/3] (100)")
    g.add_argument(f"--{role}-nu", dest=f"{role}_nu", type=number, metavar="NU",
                   help=f"{role} Poisson ratio [-], in (-1, 0.5)")
    if role == "ball":
        g.add_argument("--density", "--ball-density", dest="ball_density", type=number, metavar="KG_M3",
                       help="ball density [kg/m^3]; sets the mass 4/3 pi R^3 rho unless --mass is given")
    else:
        g.add_argument("--plate-density", dest="plate_density", type=number, metavar="KG_M3",
                       help="plate density [kg/m^3] (only the sound-speed check uses it)")


def material(args, role: str, default: str | None) -> Material:
    """The ball's or plate's material from the preset and the overriding flags.
    ``default`` None: no flags at all gives a rigid plate."""
    values = {
        "E_storage": getattr(args, f"{role}_E", None),
        "tan_delta": getattr(args, f"{role}_tan_delta", None),
        "nu": getattr(args, f"{role}_nu", None),
        "density": getattr(args, f"{role}_density", None),
    }
    flags = {"E_storage": f"--{role}-E", "tan_delta": f"--{role}-tan-delta", "nu": f"--{role}-nu",
             "density": f"--{role}-density" if role == "plate" else "--density"}
    if values["E_storage"] is not None:
        check_positive(flags["E_storage"], values["E_storage"], unit="Pa")
        check_between(flags["E_storage"], values["E_storage"], E_MIN, E_MAX, "Pa",
                      "bounds of plausibility, msf_contact._validate.E_MIN/E_MAX")
    if values["tan_delta"] is not None:
        check_finite(flags["tan_delta"], values["tan_delta"])
        if values["tan_delta"] < 0:
            raise ValueError(f"{flags['tan_delta']} = {values['tan_delta']!r} must be >= 0 (bound (100): [0, 1/3])")
    if values["nu"] is not None:
        check_range(flags["nu"], values["nu"], -1.0, 0.5, lo_open=True, hi_open=True)
    if values["density"] is not None:
        check_positive(flags["density"], values["density"], unit="kg/m^3")
        check_between(flags["density"], values["density"], DENSITY_MIN, DENSITY_MAX, "kg/m^3",
                      "bounds of plausibility, msf_contact._validate.DENSITY_MIN/MAX")
    name = getattr(args, role, None) or default
    given = {k: v for k, v in values.items() if v is not None}
    # labelled by the user's words: the preset (if any) and the flags as given
    words = " ".join(f"{flags[k]} {v:g}" for k, v in given.items())
    if name is None:
        if not given:
            return Material.rigid_body("rigid plate")
        if "E_storage" not in given:
            raise ValueError(f"{', '.join(flags[k] for k in given)} given without --{role}-E or --{role} NAME")
        return Material(words, given.pop("E_storage"), **{**PLATE_BASE, **given}, source="command line")
    base = preset(name)
    if not given:
        return base
    if base.rigid and "E_storage" not in given:
        raise ValueError(f"--{role} rigid has no finite modulus: {', '.join(flags[k] for k in given)} need --{role}-E")
    return replace(base, name=f"{base.name} {words}", source=f"command line, from the preset {base.name!r}", **given)


def material_dict(mat: Material) -> dict:
    """A material as the JSON of a command's output."""
    return {"name": mat.name, "E_storage": mat.E_storage, "tan_delta": mat.tan_delta, "nu": mat.nu,
            "density": mat.density, "source": mat.source}


# ------------------------------------------------------------------------ output ---
def to_json(d: dict) -> str:
    """Strict JSON (SI units): infinities (a rigid plate's modulus) and NaN become null."""
    return json.dumps(_clean(d), allow_nan=False)


def fmt(v) -> str:
    """A value of a human table: 6 significant digits, '-' for None."""
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def format_table(rows, title: str = "") -> str:
    """rows: (label, value, unit); an aligned plain-text table."""
    rows = [(str(a), fmt(b), str(c)) for a, b, c in rows]
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    lines = [title] if title else []
    lines += [f"  {a:<{w0}}  {b:>{w1}}  {c}".rstrip() for a, b, c in rows]
    return "\n".join(lines)
