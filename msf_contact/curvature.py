"""Curvature of two surfaces at a contact point and its combination: an
extension of the paper's section 2.3 (``docs/theory.md`` section 2a).

The paper's (13) combines principal radii whose planes coincide,
R_a = R_1a R_2a/(R_1a + R_2a). Two bodies touching in an arbitrary
orientation have their principal planes at an angle phi. The gap between
the undeformed surfaces is then h = A u^2 + B v^2 in the principal axes of
the *relative* curvature, with (Johnson 1985, Contact Mechanics, section 4.1)

    A + B = 1/2 (k_1a + k_1b + k_2a + k_2b),
    B - A = 1/2 sqrt((k_1a - k_1b)^2 + (k_2a - k_2b)^2 + 2 (k_1a - k_1b)(k_2a - k_2b) cos 2 phi),

k = 1/R the principal curvatures [1/m] of each body (convex: k >= 0). The
effective radii of (13) are then R_a = 1/(2B), R_b = 1/(2A) (a: the larger
relative curvature, so R_a <= R_b and the contact ellipse's major axis lies
along b). :func:`relative_curvature` returns them as a
:class:`~msf_contact.geometry.Curvature` whose per-body radii are each
body's normal radius along a and b (Euler's theorem), so that (13) gives
exactly 1/(2B), 1/(2A) and (24) has the harder body's radius along each
axis.

:func:`hertz_elliptic` is Hertz's exact elliptic contact (elliptic
integrals), the reference the paper's (37) is measured against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

from ._validate import check_finite, check_positive
from .geometry import Curvature, SideFootprint

#: A principal curvature below this share of the pair's largest one is a
#: straight direction (a cylinder's generator, a box edge): rounding in a
#: rotated frame leaves ~1e-16 there, a real curvature is far above.
FLAT_REL = 1e-9


@dataclass(frozen=True)
class SurfaceCurvature:
    """One surface's principal curvatures at a point, with their directions.

    k1, k2: principal curvatures [1/m], >= 0 for a convex surface (0: straight
    along that direction); d1, d2: their unit directions (3,), tangent to the
    surface, in the frame of the caller (a body's frame from
    :mod:`msf_contact.shapes`, the world after :meth:`rotated`).
    """

    k1: float
    k2: float
    d1: tuple
    d2: tuple

    def __post_init__(self):
        for name in ("k1", "k2"):
            check_finite(f"principal curvature {name} [1/m]", getattr(self, name))
        d1, d2 = np.asarray(self.d1, float), np.asarray(self.d2, float)
        if d1.shape != (3,) or d2.shape != (3,):
            raise ValueError(f"principal directions d1, d2 must have shape (3,), got {d1.shape}, {d2.shape}")
        for name, d in (("d1", d1), ("d2", d2)):
            if abs(np.linalg.norm(d) - 1.0) > 1e-9:
                raise ValueError(f"principal direction {name} = {d} must be a unit vector")
        if abs(float(d1 @ d2)) > 1e-9:
            raise ValueError(f"principal directions d1 = {d1}, d2 = {d2} must be orthogonal")

    @staticmethod
    def umbilic(k: float, normal) -> "SurfaceCurvature":
        """The same curvature k [1/m] in every direction (a sphere; 0: a plane),
        directions any pair orthogonal to ``normal`` (3,)."""
        d1, d2 = tangent_basis(normal)
        return SurfaceCurvature(float(k), float(k), tuple(d1), tuple(d2))

    def rotated(self, rot) -> "SurfaceCurvature":
        """The same curvature with directions rotated by ``rot`` (3, 3) (body -> world)."""
        rot = np.asarray(rot, dtype=float)
        return SurfaceCurvature(self.k1, self.k2, tuple(rot @ np.asarray(self.d1)), tuple(rot @ np.asarray(self.d2)))

    def normal_curvature(self, e) -> float:
        """Euler's theorem: k(e) = k1 (e.d1)^2 + k2 (e.d2)^2 [1/m] along the unit tangent e (3,)."""
        e = np.asarray(e, dtype=float)
        return self.k1 * float(e @ np.asarray(self.d1)) ** 2 + self.k2 * float(e @ np.asarray(self.d2)) ** 2


def tangent_basis(normal):
    """Two unit vectors (3,), (3,) completing ``normal`` to a right-handed frame."""
    n = np.asarray(normal, dtype=float)
    norm = np.linalg.norm(n)
    if not norm > 0:
        raise ValueError(f"normal = {n} must be a non-zero vector")
    n = n / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def johnson_AB(k1a: float, k1b: float, k2a: float, k2b: float, phi: float) -> tuple[float, float]:
    """(A, B) [1/m] of the gap h = A u^2 + B v^2, A <= B (Johnson 1985, section 4.1).

    k1a, k1b: body 1's principal curvatures; k2a, k2b: body 2's [1/m];
    phi [rad]: angle between the directions of k1a and k2a.
    """
    s = 0.5 * (k1a + k1b + k2a + k2b)
    d1, d2 = k1a - k1b, k2a - k2b
    diff = 0.5 * math.sqrt(max(d1 * d1 + d2 * d2 + 2.0 * d1 * d2 * math.cos(2.0 * phi), 0.0))
    return 0.5 * (s - diff), 0.5 * (s + diff)


@dataclass(frozen=True)
class RelativeCurvature:
    """The pair's curvature at a contact point.

    curvature: per-body normal radii along the common axes a, b [m] (the input
    of the paper's (13), (24)); e_a, e_b: the axes (3,) (a: the larger relative
    curvature); A, B [1/m]: Johnson's gap coefficients (R_a = 1/2B, R_b = 1/2A).
    """

    curvature: Curvature
    e_a: np.ndarray
    e_b: np.ndarray
    A: float
    B: float


def _radius(k: float, scale: float, what: str) -> float:
    if k < -FLAT_REL * scale:
        raise ValueError(f"{what} has a normal curvature {k:.6g} 1/m < 0 (concave): Hertz/MSF contact needs "
                         "convex surfaces at the contact point")
    return math.inf if k <= FLAT_REL * scale else 1.0 / k


def relative_curvature(s1: SurfaceCurvature, s2: SurfaceCurvature,
                       footprint: SideFootprint | None = None) -> RelativeCurvature:
    """Combine body 1's and body 2's principal curvatures at one contact
    point (both in the same frame, each measured with its own outward normal)
    as Hertz does (module docstring): Johnson's A, B, the axes of the relative
    curvature, and each body's normal radius along them (Euler's theorem).

    A line contact (A = 0: both bodies straight along b) needs ``footprint``.
    """
    d11, d12 = np.asarray(s1.d1), np.asarray(s1.d2)
    d21 = np.asarray(s2.d1)
    phi = math.atan2(float(d21 @ d12), float(d21 @ d11))
    A, B = johnson_AB(s1.k1, s1.k2, s2.k1, s2.k2, phi)
    # principal axis of the larger relative curvature in body 1's (d1, d2) frame:
    # the sum of the two curvature tensors [[p, q], [q, r]] has it at 1/2 atan2(2q, p - r)
    c, s = math.cos(phi), math.sin(phi)
    p = s1.k1 + s2.k1 * c * c + s2.k2 * s * s
    r = s1.k2 + s2.k1 * s * s + s2.k2 * c * c
    q = (s2.k1 - s2.k2) * s * c
    beta = 0.5 * math.atan2(2.0 * q, p - r)
    e_a = math.cos(beta) * d11 + math.sin(beta) * d12
    e_b = -math.sin(beta) * d11 + math.cos(beta) * d12
    scale = max(abs(s1.k1), abs(s1.k2), abs(s2.k1), abs(s2.k2))
    if not scale > 0:
        raise ValueError("two planes touch (every principal curvature is 0): there is no point contact; "
                         "a flat face carries its contact at its corners or rounded edges (shapes.Box)")
    radii = [_radius(body.normal_curvature(e), scale, f"body {i} along {name}")
             for i, body in ((1, s1), (2, s2)) for name, e in (("a", e_a), ("b", e_b))]
    if B <= FLAT_REL * scale:
        raise ValueError("the relative curvature is 0 in both directions: there is no point contact")
    if A <= FLAT_REL * scale:
        radii[1] = radii[3] = math.inf  # straight along b: a line contact
        if footprint is None:
            raise ValueError(
                f"line contact: body 1 (k = {s1.k1:.6g}, {s1.k2:.6g} 1/m) and body 2 (k = {s2.k1:.6g}, "
                f"{s2.k2:.6g} 1/m) are both straight along one direction; give a footprint "
                "(geometry.SideFootprint: the side's radius, length and tilt)")
    curv = Curvature(radii[0], radii[1], radii[2], radii[3], footprint=footprint if A <= FLAT_REL * scale else None)
    return RelativeCurvature(curv, e_a, e_b, A, B)


#: B/A - 1 below which the ellipse is Hertz's circle: K - E ~ pi e^2/4 loses
#: digits to cancellation as e -> 0, the circle's error is of order (B/A - 1).
NEAR_CIRCLE = 1e-8


@dataclass(frozen=True)
class HertzEllipse:
    """Hertz's elastic elliptic contact at an approach delta [m]: force P [N],
    semi-axes a >= b [m] (a along the smaller relative curvature A), peak
    pressure p0 [Pa]."""

    P: float
    a: float
    b: float
    p0: float


def hertz_elliptic(A: float, B: float, delta: float, E_star: float) -> HertzEllipse:
    """Hertz's exact elliptic contact (Johnson 1985, sections 3.6 and 4.2).

    The ellipsoidal pressure p0 sqrt(1 - x^2/a^2 - y^2/b^2) displaces the
    surface by u = L - M x^2 - N y^2 with, e^2 = 1 - b^2/a^2 and K, E the
    complete elliptic integrals of modulus e,

        L = b p0 K / E*,  M = b p0 (K - E)/(E* e^2 a^2),  N = b p0 (a^2 E/b^2 - K)/(E* e^2 a^2);

    contact requires delta = L, A = M, B = N, so B/A fixes e, and
    P = 2/3 pi a b p0. A, B [1/m] the gap coefficients (h = A x^2 + B y^2,
    A <= B), delta [m] the approach, E_star [Pa] the contact modulus.
    """
    check_positive("A [1/m]", A)
    check_positive("B [1/m]", B)
    check_positive("delta [m]", delta)
    check_positive("E_star [Pa]", E_star)
    if A > B:
        raise ValueError(f"A = {A!r} 1/m must be <= B = {B!r} 1/m")
    if B - A <= NEAR_CIRCLE * B:  # a circle: Hertz's sphere, a^2 = R delta with R = 1/2A
        a = math.sqrt(delta / (2.0 * A))
        p0 = 2.0 * E_star * a / (math.pi / (2.0 * A))
        return HertzEllipse(2.0 / 3.0 * math.pi * a * a * p0, a, a, p0)

    def excess(m):  # N/M - B/A as a function of m = e^2
        K, E = ellipk(m), ellipe(m)
        return (E / (1.0 - m) - K) / (K - E) - B / A

    m = brentq(excess, 1e-12, 1.0 - 1e-15, xtol=1e-18, rtol=1e-15)
    K, E = float(ellipk(m)), float(ellipe(m))
    a2 = delta * (K - E) / (K * m * A)
    a, b = math.sqrt(a2), math.sqrt(a2 * (1.0 - m))
    p0 = delta * E_star / (K * b)
    return HertzEllipse(2.0 / 3.0 * math.pi * a * b * p0, a, b, p0)
