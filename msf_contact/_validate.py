"""Input checks shared by the whole package.

Every check raises ``ValueError`` naming the parameter, its value and the
bound, before any work is done (never ``assert``: it vanishes under -O).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

#: Largest loss factor for which the MSF damped-oscillation solution exists,
#: tg(beta) <= 1/3, equivalently k_x >= (pi - 1)/(pi + 1), paper (100).
TAN_DELTA_MAX = 1.0 / 3.0

# Bounds of plausibility (not of the model), so that no derived scale (R^5,
# m R^2, the Hertz time and pressure) overflows or leaves meaning; refused by
# name with the bound, before any work.
#: Storage modulus E' [Pa]: 10 Pa (softer than any gel that holds its shape)
#: to 1e13 Pa (ten times diamond's 1.05e12 Pa).
E_MIN, E_MAX = 10.0, 1e13
#: Density [kg/m^3] of a material: 1e-2 (100 times below air) to 1e5 (four
#: times osmium, 22,590 kg/m^3).
DENSITY_MIN, DENSITY_MAX = 1e-2, 1e5
#: Mean density m / (4/3 pi R^3) of a body [kg/m^3]: as DENSITY_MIN up to
#: 1e8 (a heavy core under a soft skin is allowed, a point mass is not).
MEAN_DENSITY_MAX = 1e8
#: Radius of a finite body [m]: 1e-9 (below, continuum contact mechanics
#: does not hold) to 1e6 (an impact body, not a planet; R^5 stays ~1e30).
RADIUS_MIN, RADIUS_MAX = 1e-9, 1e6
#: Impact speed [m/s]: from 1e-12 (a nanometre in a quarter hour; far below,
#: v^2 in the Hertz scale (m v^2/K)^(2/5) underflows at ~1e-154 and the
#: integrator's error scales divide by zero) upward; the top is the sound speed.
SPEED_MIN = 1e-12


#: Small-strain bound of the contact geometry on the approach, x_max/R (R the
#: effective radius (13)): the contact radius is a = sqrt(R x) in (29), so at
#: x/R = 0.1 a/R = 0.32. Hertz's half-space and the linear viscoelastic
#: moduli assume a << R (Johnson, Contact Mechanics, 1985, section 4.2; the
#: spec's validity list: "x/R small"); MSF's k_p (15) extends the geometry
#: toward 2R but not the material's small strain. Beyond it a record says
#: so in ``outside_validity`` (issue 10).
SMALL_STRAIN_X_OVER_R = 0.1


class ValidityWarning(UserWarning):
    """The inputs leave the range in which the paper's model is valid."""


def _as_array(name: str, value) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a number, got {value!r}") from exc
    return arr


def _show(value) -> str:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return repr(float(arr))
    return np.array2string(arr, threshold=6)


def check_finite(name: str, value, allow_inf: bool = False) -> np.ndarray:
    """Refuse NaN (always) and infinities (unless ``allow_inf``)."""
    arr = _as_array(name, value)
    if np.any(np.isnan(arr)):
        raise ValueError(f"{name} = {_show(value)} is NaN; a finite number is required")
    if not allow_inf and np.any(np.isinf(arr)):
        raise ValueError(f"{name} = {_show(value)} is infinite; a finite number is required")
    return arr


def check_positive(name: str, value, allow_inf: bool = False, unit: str = "") -> np.ndarray:
    """Refuse values that are not > 0 (and NaN, and inf unless allowed)."""
    arr = _as_array(name, value)
    # one pass for the common case (NaN fails both comparisons); the checks below name the fault
    if (arr > 0).all() if allow_inf else ((arr > 0) & (arr < np.inf)).all():
        return arr
    arr = check_finite(name, value, allow_inf=allow_inf)
    if np.any(arr <= 0):
        u = f" {unit}" if unit else ""
        raise ValueError(f"{name} = {_show(value)}{u} must be > 0")
    return arr


def check_range(name: str, value, lo: float, hi: float, lo_open=False, hi_open=False) -> np.ndarray:
    """Refuse values outside [lo, hi] (or the open variants)."""
    arr = check_finite(name, value)
    bad_lo = arr <= lo if lo_open else arr < lo
    bad_hi = arr >= hi if hi_open else arr > hi
    if np.any(bad_lo) or np.any(bad_hi):
        lb = "(" if lo_open else "["
        hb = ")" if hi_open else "]"
        raise ValueError(f"{name} = {_show(value)} is outside {lb}{lo:g}, {hi:g}{hb}")
    return arr


def check_between(name: str, value, lo: float, hi: float, unit: str = "", why: str = "") -> np.ndarray:
    """Refuse values outside [lo, hi] (and NaN, inf), naming the bound and why it exists."""
    arr = check_finite(name, value)
    if np.any(arr < lo) or np.any(arr > hi):
        u = f" {unit}" if unit else ""
        w = f" ({why})" if why else ""
        raise ValueError(f"{name} = {_show(value)}{u} is outside [{lo:g}, {hi:g}]{u}{w}")
    return arr


def check_tan_delta(name: str, value, strict: bool = False) -> np.ndarray:
    """Loss factor tg(beta) >= 0; above 1/3 the model leaves its validity (100).

    With ``strict`` the violation is an error, otherwise a ``ValidityWarning``.
    """
    arr = check_finite(name, value)
    if np.any(arr < 0):
        raise ValueError(f"{name} = {_show(value)} must be >= 0")
    if np.any(arr > TAN_DELTA_MAX * (1 + 1e-12)):
        msg = (
            f"{name} = {_show(value)} exceeds 1/3: outside the validity of the MSF "
            "damped-oscillation solution, paper (100) (tg(beta) <= 1/3, "
            "k_x >= (pi-1)/(pi+1))"
        )
        if strict:
            raise ValueError(msg)
        warnings.warn(msg, ValidityWarning, stacklevel=3)
    return arr


def small_strain_note(x_max: float, R: float) -> str | None:
    """The ``outside_validity`` reason for a contact whose x_max [m] exceeds
    SMALL_STRAIN_X_OVER_R of the effective radius R [m], else None."""
    if not math.isfinite(R) or R <= 0 or x_max <= SMALL_STRAIN_X_OVER_R * R:
        return None
    return (f"x_max/R = {x_max / R:.3g} above the small-strain bound {SMALL_STRAIN_X_OVER_R:g} "
            f"(a/R = {math.sqrt(x_max / R):.2f}): Hertz's half-space and linear viscoelasticity need a << R; "
            "the result is the model's, not necessarily the material's (lower the speed or use a larger radius)")


def check_choice(name: str, value: str, choices) -> str:
    choices = tuple(choices)
    if value not in choices:
        raise ValueError(f"{name} = {value!r} is not one of {', '.join(map(repr, choices))}")
    return value


def is_inf(value) -> bool:
    return isinstance(value, (int, float)) and math.isinf(value)
