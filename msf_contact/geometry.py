"""Geometry of the contact, paper section 2.3, equations (13)-(26), (41)-(42).

Arrays: ``x`` is the approach of the undeformed surfaces [m], shape (n,) or
scalar; all functions broadcast.

Correlation-coefficient modes (one setting for every law that has k_p):

- ``"hertz"``: k_p = 1, Hertz's r^2 = R x, (30);
- ``"msf-small"``: k_p = sqrt(2), small-deformation MSF, (25);
- ``"msf"``: k_p = sqrt(2 - x/R) at the current x, (15) (default).

x >= 2R has no real k_p in ``msf`` mode: :func:`kp` raises, never returns NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._validate import check_choice, check_positive
from .materials import ContactPair

KP_MODES = ("msf", "msf-small", "hertz")


def kp(x, R, mode: str = "msf"):
    """Correlation coefficient k_p [-], (15)/(25)/(30). x [m], R [m]; (n,)."""
    if mode == "msf":
        ratio = np.asarray(x, dtype=float) / R
        if np.any(ratio >= 2.0):
            worst = float(np.max(ratio))
            raise ValueError(
                f"approach x/R = {worst:.6g} >= 2: k_p = sqrt(2 - x/R) of (15) has no real value "
                "(the overlap exceeds the body); the contact is outside the model"
            )
        return np.sqrt(2.0 - ratio)
    if mode == "msf-small":
        return np.full(np.shape(x), math.sqrt(2.0)) if np.ndim(x) else math.sqrt(2.0)
    if mode == "hertz":
        return np.ones(np.shape(x)) if np.ndim(x) else 1.0
    check_choice("kp_mode", mode, KP_MODES)
    raise AssertionError("unreachable")


def kp_clamped(x, R, mode: str = "msf"):
    """k_p for engines: in ``msf`` mode x/R is clamped just below 2 and a flag
    array says where (the state is outside the model, reported by the caller).

    Returns (k_p (n,), outside (n,) bool).
    """
    x = np.asarray(x, dtype=float)
    if mode != "msf":
        return np.broadcast_to(np.asarray(kp(x, R, mode), dtype=float), x.shape), np.zeros(x.shape, bool)
    ratio = x / R
    outside = ratio >= 2.0
    return np.sqrt(2.0 - np.minimum(ratio, 2.0 - 1e-12)), outside


@dataclass(frozen=True)
class Curvature:
    """Principal radii of curvature at the contact point [m]; inf for a plane.

    ``R1a, R1b`` belong to ``ContactPair.body1``, ``R2a, R2b`` to ``body2``.
    """

    R1a: float
    R1b: float
    R2a: float = math.inf
    R2b: float = math.inf

    def __post_init__(self):
        for name in ("R1a", "R1b", "R2a", "R2b"):
            check_positive(f"radius {name}", getattr(self, name), allow_inf=True, unit="m")
        if all(math.isinf(getattr(self, n)) for n in ("R1a", "R2a")) or all(
            math.isinf(getattr(self, n)) for n in ("R1b", "R2b")
        ):
            raise ValueError("two planes have no finite effective radius: at least one surface must be curved")

    @staticmethod
    def sphere_on_plane(R: float) -> "Curvature":
        return Curvature(R, R)

    @staticmethod
    def two_spheres(R1: float, R2: float) -> "Curvature":
        return Curvature(R1, R1, R2, R2)


def _series_radius(r1: float, r2: float) -> float:
    """(13): R = R1 R2/(R1 + R2); a plane (inf) gives the other radius."""
    if math.isinf(r1):
        return r2
    if math.isinf(r2):
        return r1
    return r1 * r2 / (r1 + r2)


@dataclass(frozen=True)
class ContactGeometry:
    """Effective geometric constants of a pair (scalars).

    R_a, R_b: effective radii (13) [m]; k_ha, k_hb: depth coefficients (24),
    clamped at >= 0 (a soft ball on a harder plane gives a negative value: the
    contact is flat there).
    """

    R_a: float
    R_b: float
    k_ha: float
    k_hb: float
    k_ha_raw: float
    k_hb_raw: float

    @property
    def sphere(self) -> bool:
        return self.R_a == self.R_b

    @property
    def R(self) -> float:
        """Equivalent radius sqrt(R_a R_b) [m] (the radius for a sphere)."""
        return math.sqrt(self.R_a * self.R_b)

    @staticmethod
    def of(pair: ContactPair, curv: Curvature) -> "ContactGeometry":
        mod = pair.moduli()
        R_a = _series_radius(curv.R1a, curv.R2a)
        R_b = _series_radius(curv.R1b, curv.R2b)
        # harder body's radii (paper's index 2)
        if pair.body1_is_softer:
            Rh_a, Rh_b = curv.R2a, curv.R2b
        else:
            Rh_a, Rh_b = curv.R1a, curv.R1b
        # (24): k_h = (R - D2 R_2)/R_2 = R/R_2 - D2; R_2 = inf -> -D2
        k_ha = (0.0 if math.isinf(Rh_a) else R_a / Rh_a) - mod.D2
        k_hb = (0.0 if math.isinf(Rh_b) else R_b / Rh_b) - mod.D2
        return ContactGeometry(R_a, R_b, max(k_ha, 0.0), max(k_hb, 0.0), k_ha, k_hb)


def contact_radius_exact(x, R):
    """(13): r^2 = 2 R x - x^2 [m]."""
    return np.sqrt(2.0 * R * x - np.asarray(x) ** 2)


def contact_radius(x, R, mode: str = "msf"):
    """(14): r = k_p sqrt(R x) [m]."""
    return kp(x, R, mode) * np.sqrt(R * np.asarray(x, dtype=float))


def contact_axes(x, geom: ContactGeometry, mode: str = "msf"):
    """(26): full axes a = 2 k_pa sqrt(R_a x), b = 2 k_pb sqrt(R_b x) [m]."""
    return 2.0 * contact_radius(x, geom.R_a, mode), 2.0 * contact_radius(x, geom.R_b, mode)


def psi(x, geom: ContactGeometry, mode: str = "msf"):
    """(29): curvature parameter psi = k_pa sqrt(R_a) + k_pb sqrt(R_b) [m^1/2]."""
    return kp(x, geom.R_a, mode) * math.sqrt(geom.R_a) + kp(x, geom.R_b, mode) * math.sqrt(geom.R_b)


def depth(x, geom: ContactGeometry):
    """(24): depths of the contact surface h_xa = k_ha x, h_xb = k_hb x [m]."""
    x = np.asarray(x, dtype=float)
    return geom.k_ha * x, geom.k_hb * x


def shear_lengths(x, geom: ContactGeometry, mode: str = "msf"):
    """(36): P_bx = k_ha x + 2 k_pb sqrt(R_b x), P_ax = k_hb x + 2 k_pa sqrt(R_a x) [m].

    P_bx multiplies the force along Y (the plane XAY of axis a), P_ax along Z.
    """
    x = np.asarray(x, dtype=float)
    P_bx = geom.k_ha * x + 2.0 * kp(x, geom.R_b, mode) * np.sqrt(geom.R_b * x)
    P_ax = geom.k_hb * x + 2.0 * kp(x, geom.R_a, mode) * np.sqrt(geom.R_a * x)
    return P_bx, P_ax


def area(x, geom: ContactGeometry, mode: str = "msf"):
    """(41): S_x = pi k_pa k_pb sqrt(R_a R_b) x [m^2]."""
    x = np.asarray(x, dtype=float)
    return math.pi * kp(x, geom.R_a, mode) * kp(x, geom.R_b, mode) * math.sqrt(geom.R_a * geom.R_b) * x


def mean_pressure(F_n, x, geom: ContactGeometry, mode: str = "msf"):
    """(41): P_m = F_n / S_x [Pa]."""
    return np.asarray(F_n) / area(x, geom, mode)


def peak_pressure(F_n, x, geom: ContactGeometry, mode: str = "msf"):
    """(20): P_c = 1.5 P_m [Pa] (parabolic pressure distribution (17))."""
    return 1.5 * mean_pressure(F_n, x, geom, mode)


def peak_pressure_closed(x, xdot, E, eta_E, geom: ContactGeometry, mode: str = "msf"):
    """(42): P_c = psi (3 eta' xdot + E' x) / (pi k_pa k_pb sqrt(R_a R_b) sqrt(x)) [Pa].

    Diverges as x -> 0+ while xdot > 0 (viscous stress over a vanishing area).
    """
    x = np.asarray(x, dtype=float)
    num = psi(x, geom, mode) * (3.0 * eta_E * np.asarray(xdot) + E * x)
    den = math.pi * kp(x, geom.R_a, mode) * kp(x, geom.R_b, mode) * math.sqrt(geom.R_a * geom.R_b) * np.sqrt(x)
    return num / den
