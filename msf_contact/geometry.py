"""Geometry of the contact, paper section 2.3, equations (13)-(26), (41)-(42).

Arrays: ``x`` is the approach of the undeformed surfaces [m], shape (n,) or
scalar; all functions broadcast.

Line contacts (a cylinder's or capsule's side on a plane, one relative radius
infinite) carry a :class:`SideFootprint`: the contact axis b of (26) is then
the length of the overlap along the body's axis instead of 2 k_pb sqrt(R_b x)
(an extension of the paper, ``docs/theory.md`` section 2a).

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

from ._validate import check_choice, check_positive, check_range
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
class SideFootprint:
    """The overlap of a capsule's or a cylinder's side with a plane, along the
    body's axis: the contact axis b of a line contact (extension of the paper,
    ``docs/theory.md`` section 2a).

    radius [m] of the side, length [m] of its straight part (a capsule's
    segment, a cylinder's height between its rims), tilt [rad] between the
    axis and the plane (0 = lying flat), caps: ``"sphere"`` (a capsule's
    hemispherical ends), ``"flat"`` (a sharp-edged cylinder; only tilt = 0,
    the rim is then a separate contact) or ``"rounded"`` (a cylinder whose
    rim is a torus of tube radius ``end_radius``, any tilt below pi/2).

    The contact is measured exactly, as (13) is: the axis point at s along
    the segment (s = 0 the lowest end) is at the height h(s) = R - x + s sin(tilt)
    above the plane and its sphere of radius R cuts the plane in a disc of
    radius rho(s) = sqrt(R^2 - h(s)^2). :meth:`axes` returns the width
    a = 2 rho(0) (= 2 k_p sqrt(R x) of (26) with the msf k_p of (15)) and the
    length b of the union of the discs along the axis.

    ``"rounded"``: in the plane of the axis and the normal the cylinder's
    bottom is its side's straight line of ``length`` ended by the rim's
    arcs of radius rho = ``end_radius`` (the rim torus' meridian circle), so
    b is the same union of discs with rho in place of R (centres at
    R - rho from the axis), and the width a is the chord of the rim torus at
    its lowest point, whose radius along the rim is
    R_w = (R - rho + rho cos(tilt)) / cos(tilt) (``shapes.Cylinder``; R at
    tilt 0): a = 2 sqrt(x (2 R_w - x)). While the side does not touch
    (x <= rho (1 - cos(tilt))) this is the rim point's own contact, the
    curvature (rho, R_w) of (13) with the msf k_p of (15), exactly.
    """

    radius: float
    length: float
    tilt: float = 0.0
    caps: str = "sphere"
    end_radius: float | None = None

    def __post_init__(self):
        check_positive("footprint radius", self.radius, unit="m")
        check_positive("footprint length", self.length, unit="m")
        check_range("footprint tilt [rad]", self.tilt, 0.0, math.pi / 2)
        check_choice("footprint caps", self.caps, ("sphere", "flat", "rounded"))
        if self.caps == "flat" and self.tilt != 0.0:
            raise ValueError(f"footprint tilt = {self.tilt!r} rad with flat caps: a tilted cylinder touches with "
                             "its rim (a point contact: shapes.Cylinder.curvature at the rim), not its side; "
                             "caps='rounded' with the rim's end_radius carries both")
        if self.caps == "rounded":
            if self.end_radius is None:
                raise ValueError("footprint caps = 'rounded' needs end_radius (the rim's edge radius) [m]")
            check_range("footprint end_radius", self.end_radius, 0.0, self.radius)
            check_positive("footprint end_radius", self.end_radius, unit="m")
            if self.tilt >= math.pi / 2:
                raise ValueError(f"footprint tilt = {self.tilt!r} rad with rounded caps: a cylinder standing on "
                                 "its end face is a flat punch, no line contact")
        elif self.end_radius is not None:
            raise ValueError(f"footprint end_radius = {self.end_radius!r} m is for caps = 'rounded' only "
                             f"(got caps = {self.caps!r})")

    def axes(self, x):
        """Contact axes (a, b) [m] at the approach x [m] of the lowest point, (n,)."""
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        R, L, th = self.radius, self.length, self.tilt
        if self.caps == "rounded":  # the rim's width at its lowest point, then discs of the rim's radius
            R_w = (R - self.end_radius + self.end_radius * math.cos(th)) / math.cos(th)
            a = 2.0 * np.sqrt(np.maximum(x * (2.0 * R_w - x), 0.0))
            R = self.end_radius
        h0 = R - x
        rho0 = np.sqrt(np.maximum(x * (2.0 * R - x), 0.0))  # R^2 - h0^2 without cancellation
        if self.caps != "rounded":
            a = 2.0 * rho0
        if self.caps == "flat":  # at x = 0 its right limit, as the other caps': a contact in progress there
            return a, np.full(x.shape, float(L))  # carries its touch-down width (docs/theory.md 2a)
        if th == 0.0:
            return a, 2.0 * rho0 + L
        s_t, c_t = math.sin(th), math.cos(th)
        # farthest reach along the axis, max over s of s cos(tilt) + rho(s): the
        # side's bottom line (h = R cos(tilt)) if it touches within the segment
        s_star = (R * c_t - h0) / s_t
        hL = h0 + L * s_t
        reach_end = L * c_t + np.sqrt(np.maximum((R - hL) * (R + hL), 0.0))
        reach = np.where(s_star <= 0.0, rho0, np.where(s_star >= L, reach_end, s_star * c_t + R * s_t))
        return a, rho0 + reach


@dataclass(frozen=True)
class Curvature:
    """Principal radii of curvature at the contact point [m]; inf for a plane.

    ``R1a, R1b`` belong to ``ContactPair.body1``, ``R2a, R2b`` to ``body2``;
    a and b are common principal directions of both surfaces (for surfaces at
    an angle, :func:`msf_contact.curvature.relative_curvature` returns them).
    A line contact (R1b = R2b = inf, both straight along b) needs a
    ``footprint`` (:class:`SideFootprint`) giving the contact's length.
    """

    R1a: float
    R1b: float
    R2a: float = math.inf
    R2b: float = math.inf
    footprint: SideFootprint | None = None

    def __post_init__(self):
        for name in ("R1a", "R1b", "R2a", "R2b"):
            check_positive(f"radius {name}", getattr(self, name), allow_inf=True, unit="m")
        flat_a = math.isinf(self.R1a) and math.isinf(self.R2a)
        flat_b = math.isinf(self.R1b) and math.isinf(self.R2b)
        if flat_a and flat_b:
            raise ValueError("two planes have no finite effective radius: at least one surface must be curved")
        if self.footprint is None and (flat_a or flat_b):
            raise ValueError(
                f"line contact (R1a, R1b, R2a, R2b) = ({self.R1a}, {self.R1b}, {self.R2a}, {self.R2b}) m: both "
                "surfaces are straight along one axis and the contact's length is the body's; give "
                "footprint=SideFootprint(...) with the axis b along the line")
        if self.footprint is not None and not flat_b:
            raise ValueError(
                f"footprint given but R1b = {self.R1b} m, R2b = {self.R2b} m: a footprint is the length of a "
                "line contact along b, where both radii are infinite")

    @staticmethod
    def sphere_on_plane(R: float) -> "Curvature":
        return Curvature(R, R)

    @staticmethod
    def two_spheres(R1: float, R2: float) -> "Curvature":
        return Curvature(R1, R1, R2, R2)

    @staticmethod
    def side_on_plane(footprint: SideFootprint) -> "Curvature":
        """A capsule's or cylinder's side (radius and length of the footprint) on a plane."""
        return Curvature(footprint.radius, math.inf, footprint=footprint)


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
    footprint: SideFootprint | None = None

    @property
    def sphere(self) -> bool:
        return self.R_a == self.R_b

    @property
    def R(self) -> float:
        """Equivalent radius sqrt(R_a R_b) [m] (the radius for a sphere; R_a, the
        side's radius, for a line contact, where it is only a length scale)."""
        if self.footprint is not None:
            return self.R_a
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
        return ContactGeometry(R_a, R_b, max(k_ha, 0.0), max(k_hb, 0.0), k_ha, k_hb, curv.footprint)


def contact_radius_exact(x, R):
    """(13): r^2 = 2 R x - x^2 [m]."""
    return np.sqrt(2.0 * R * x - np.asarray(x) ** 2)


def contact_radius(x, R, mode: str = "msf"):
    """(14): r = k_p sqrt(R x) [m]."""
    return kp(x, R, mode) * np.sqrt(R * np.asarray(x, dtype=float))


def contact_axes(x, geom: ContactGeometry, mode: str = "msf"):
    """(26): full axes a = 2 k_pa sqrt(R_a x), b = 2 k_pb sqrt(R_b x) [m]; a line
    contact's from its footprint (``msf`` mode only: the footprint is exact geometry)."""
    if geom.footprint is not None:
        check_choice("kp_mode (a line contact's footprint is the exact geometry of (13))", mode, ("msf",))
        return geom.footprint.axes(x)
    return 2.0 * contact_radius(x, geom.R_a, mode), 2.0 * contact_radius(x, geom.R_b, mode)


def width(x, geom: ContactGeometry, mode: str = "msf"):
    """W = psi sqrt(x) = (a + b)/2 [m] of (29) with (26), so that (37) reads
    F_n = W (2 eta'_E x' + 2/3 E' x); a line contact's from its footprint. (n,)."""
    if geom.footprint is not None:
        a, b = contact_axes(x, geom, mode)
        return 0.5 * (a + b)
    return psi(x, geom, mode) * np.sqrt(np.asarray(x, dtype=float))


def psi(x, geom: ContactGeometry, mode: str = "msf"):
    """(29): curvature parameter psi = k_pa sqrt(R_a) + k_pb sqrt(R_b) [m^1/2]
    (infinite for a line contact: use :func:`width`)."""
    return kp(x, geom.R_a, mode) * math.sqrt(geom.R_a) + kp(x, geom.R_b, mode) * math.sqrt(geom.R_b)


def depth(x, geom: ContactGeometry):
    """(24): depths of the contact surface h_xa = k_ha x, h_xb = k_hb x [m]."""
    x = np.asarray(x, dtype=float)
    return geom.k_ha * x, geom.k_hb * x


def shear_lengths(x, geom: ContactGeometry, mode: str = "msf"):
    """(36): P_bx = k_ha x + 2 k_pb sqrt(R_b x), P_ax = k_hb x + 2 k_pa sqrt(R_a x) [m].

    P_bx multiplies the force along Y (the plane XAY of axis a), P_ax along Z.
    A line contact: 2 k_pb sqrt(R_b x) and 2 k_pa sqrt(R_a x) are its axes b, a.
    """
    x = np.asarray(x, dtype=float)
    if geom.footprint is not None:
        a, b = contact_axes(x, geom, mode)
        return geom.k_ha * x + b, geom.k_hb * x + a
    P_bx = geom.k_ha * x + 2.0 * kp(x, geom.R_b, mode) * np.sqrt(geom.R_b * x)
    P_ax = geom.k_hb * x + 2.0 * kp(x, geom.R_a, mode) * np.sqrt(geom.R_a * x)
    return P_bx, P_ax


def area(x, geom: ContactGeometry, mode: str = "msf"):
    """(41): S_x = pi k_pa k_pb sqrt(R_a R_b) x [m^2] (= pi a b / 4 with (26);
    a line contact's with its footprint's axes)."""
    x = np.asarray(x, dtype=float)
    if geom.footprint is not None:
        a, b = contact_axes(x, geom, mode)
        return 0.25 * math.pi * a * b
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
