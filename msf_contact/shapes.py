"""Principal curvatures of a robot model's geoms at a contact point
(``docs/theory.md`` section 2a).

Each shape is a frozen dataclass in its own frame (MuJoCo's conventions: the
capsule's and cylinder's axis is z, sizes are half-lengths) with one method,
``curvature(point, normal) -> SurfaceCurvature``: ``point`` [m] (3,) the
contact point on (or within a penetration of) the surface and ``normal``
(3,) the surface's outward unit normal there, both in the shape's frame.
Smooth shapes use the normal (the point of a convex surface with that
normal is unique and does not move with the penetration); shapes with
features (edges, corners, caps) use the point to find the feature.

Real parts have rounded edges: a box's edges and corners and a cylinder's
rim carry an edge radius [m], ``DEFAULT_EDGE_RADIUS`` unless given per geom.
A box corner is then a sphere of the edge radius, an edge a cylinder of it,
a cylinder's rim a torus.

Meshes: :class:`Mesh` fits a quadric to the vertices around the contact
point (least squares in the tangent frame) and returns its principal
curvatures; the error on an icosphere is measured in the tests and
``docs/theory.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._validate import check_positive
from .curvature import SurfaceCurvature, tangent_basis

#: Edge radius of boxes and cylinder rims when a geom gives none [m]: the
#: order of a machined part's edge break (0.1-1 mm) and of a moulded part's
#: fillet; a sharp edge has no finite curvature, so some radius is needed.
DEFAULT_EDGE_RADIUS = 1e-3

#: A normal component below this is zero (a side's normal, a face's): the
#: engines' normals of a face contact are exact to ~1e-15 in the body frame.
NORMAL_TOL = 1e-9


def _unit(v, name="normal"):
    v = np.asarray(v, dtype=float)
    if v.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {v.shape}")
    n = np.linalg.norm(v)
    if not n > 0 or not np.isfinite(n):
        raise ValueError(f"{name} = {v} must be a finite non-zero vector")
    return v / n


def _sc(k1, k2, d1, d2) -> SurfaceCurvature:
    return SurfaceCurvature(float(k1), float(k2), tuple(float(c) for c in d1), tuple(float(c) for c in d2))


def _line(k, across, n) -> SurfaceCurvature:
    """Curvature k [1/m] across the unit tangent ``across``, 0 along n x across."""
    return _sc(k, 0.0, across, np.cross(n, across))


@dataclass(frozen=True)
class Sphere:
    """radius [m]: k = 1/radius in every direction."""

    radius: float

    def __post_init__(self):
        check_positive("sphere radius", self.radius, unit="m")

    def curvature(self, point, normal) -> SurfaceCurvature:
        return SurfaceCurvature.umbilic(1.0 / self.radius, _unit(normal))


@dataclass(frozen=True)
class Ellipsoid:
    """semi_axes (a, b, c) [m] along x, y, z.

    Principal curvatures from the shape operator of the implicit surface
    F = p^T D p - 1, D = diag(1/a^2, 1/b^2, 1/c^2): S = P (2D) P / |grad F|
    with P = I - n n^T, at the point whose outward normal is n,
    p = D^-1 n / sqrt(n^T D^-1 n). At the tip of the a axis they are a/b^2
    and a/c^2.
    """

    semi_axes: tuple

    def __post_init__(self):
        check_positive("ellipsoid semi_axes", self.semi_axes, unit="m")
        if np.shape(self.semi_axes) != (3,):
            raise ValueError(f"ellipsoid semi_axes must be 3 lengths, got {self.semi_axes!r}")

    def point_of_normal(self, normal) -> np.ndarray:
        """The surface point (3,) [m] whose outward normal is ``normal``."""
        n = _unit(normal)
        s2 = np.asarray(self.semi_axes, dtype=float) ** 2
        return s2 * n / math.sqrt(float(n @ (s2 * n)))

    def curvature(self, point, normal) -> SurfaceCurvature:
        n = _unit(normal)
        p = self.point_of_normal(n)
        D = 1.0 / np.asarray(self.semi_axes, dtype=float) ** 2
        grad = 2.0 * D * p
        P = np.eye(3) - np.outer(n, n)
        S = P @ np.diag(2.0 * D) @ P / np.linalg.norm(grad)
        w, v = np.linalg.eigh(S)
        # the eigenvector along n has eigenvalue 0; keep the two tangent ones
        tangent = np.argsort(np.abs(v.T @ n))[:2]
        (k1, k2), (d1, d2) = w[tangent], v[:, tangent].T
        return _sc(k1, k2, d1, np.cross(n, d1)) if k1 >= k2 else _sc(k2, k1, d2, np.cross(n, d2))


@dataclass(frozen=True)
class Capsule:
    """radius [m], half_length [m] of the segment along z. Side: 1/radius
    around the axis, 0 along it; caps: the sphere of the radius. A point at
    or beyond the segment's end (|z| >= half_length) is on a cap whatever
    the normal: engines report a capsule lying on a plane as its two end
    spheres' contacts, on the seam between cap and side."""

    radius: float
    half_length: float

    def __post_init__(self):
        check_positive("capsule radius", self.radius, unit="m")
        check_positive("capsule half_length", self.half_length, unit="m")

    def curvature(self, point, normal) -> SurfaceCurvature:
        n = _unit(normal)
        on_cap = point is not None and abs(float(np.asarray(point, dtype=float)[2])) >= self.half_length * (1 - 1e-9)
        if on_cap or abs(n[2]) > NORMAL_TOL:  # a cap (the side's normal is perpendicular to the axis)
            return SurfaceCurvature.umbilic(1.0 / self.radius, n)
        return _line(1.0 / self.radius, _unit(np.cross(np.array([0.0, 0.0, 1.0]), n), "side tangent"), n)


@dataclass(frozen=True)
class Cylinder:
    """radius [m], half_length [m] along z, edge_radius [m] of the rim.

    Side: 1/radius around the axis, 0 along it. Flat ends: 0. The rim is a
    torus of tube radius rho = edge_radius around the circle of radius
    radius - rho: where the normal makes the angle alpha with the radial
    direction, 1/rho in the meridian plane and cos(alpha)/(radius - rho + rho cos alpha)
    along the rim. A point with a radial normal at or beyond the rim's
    start (|z| >= half_length - edge_radius) is on the rim (alpha = 0: 1/rho
    and 1/radius), whatever the side would say: engines report a cylinder
    lying on a plane as the two ends of its bottom line (MuJoCo), on the
    seam of side and rim, as they report a capsule by its end spheres; the
    straight side between them is left out (docs/engines.md).
    """

    radius: float
    half_length: float
    edge_radius: float = DEFAULT_EDGE_RADIUS

    def __post_init__(self):
        check_positive("cylinder radius", self.radius, unit="m")
        check_positive("cylinder half_length", self.half_length, unit="m")
        check_positive("cylinder edge_radius", self.edge_radius, unit="m")
        if self.edge_radius > min(self.radius, self.half_length):
            raise ValueError(f"cylinder edge_radius = {self.edge_radius!r} m must be <= min(radius, half_length) "
                             f"= {min(self.radius, self.half_length)!r} m")

    def curvature(self, point, normal) -> SurfaceCurvature:
        n = _unit(normal)
        p = np.asarray(point, dtype=float)
        rho = self.edge_radius
        nr = math.hypot(n[0], n[1])
        if nr <= NORMAL_TOL:  # normal along the axis: the flat end, or the rim's top if the point is out there
            r_xy = math.hypot(p[0], p[1])
            if r_xy <= self.radius - rho:
                return SurfaceCurvature.umbilic(0.0, n)
            radial = np.array([p[0], p[1], 0.0]) / r_xy
            return _line(1.0 / rho, radial, n)
        radial = np.array([n[0], n[1], 0.0]) / nr
        on_rim = abs(float(p[2])) >= self.half_length - rho
        if abs(n[2]) <= NORMAL_TOL and not on_rim:  # the side
            return _line(1.0 / self.radius, np.cross(np.array([0.0, 0.0, 1.0]), radial), n)
        if abs(n[2]) <= NORMAL_TOL:  # the seam of side and rim (cos alpha = 1): engines report a
            # cylinder lying on a plane as the two ends of its bottom line, as a capsule's end spheres
            return _sc(1.0 / rho, 1.0 / self.radius, np.array([0.0, 0.0, 1.0]), np.cross(n, [0.0, 0.0, 1.0]))
        # the rim torus: meridian direction in the (radial, z) plane, perpendicular to n
        cos_a = nr
        meridian = _unit(np.cross(np.cross(radial, np.array([0.0, 0.0, 1.0])), n), "meridian")
        k_par = cos_a / (self.radius - rho + rho * cos_a)
        return _sc(1.0 / rho, k_par, meridian, np.cross(n, meridian))


@dataclass(frozen=True)
class Box:
    """half_extents (3,) [m], edge_radius [m]: the box with its edges and
    corners rounded by the edge radius (the Minkowski sum of a box of
    half-extents - edge_radius and a sphere of it). A point's coordinates
    beyond half_extent - edge_radius pick the feature: one (a face: flat),
    two (an edge: 1/edge_radius across it, 0 along it), three (a corner:
    the sphere of the edge radius)."""

    half_extents: tuple
    edge_radius: float = DEFAULT_EDGE_RADIUS

    def __post_init__(self):
        check_positive("box half_extents", self.half_extents, unit="m")
        if np.shape(self.half_extents) != (3,):
            raise ValueError(f"box half_extents must be 3 lengths, got {self.half_extents!r}")
        check_positive("box edge_radius", self.edge_radius, unit="m")
        if self.edge_radius > min(self.half_extents):
            raise ValueError(f"box edge_radius = {self.edge_radius!r} m must be <= the smallest half-extent "
                             f"{min(self.half_extents)!r} m")

    def feature(self, point) -> np.ndarray:
        """(3,) bool: the coordinates of ``point`` [m] in the rounded zone."""
        p = np.abs(np.asarray(point, dtype=float))
        return p > np.asarray(self.half_extents, dtype=float) - self.edge_radius

    def curvature(self, point, normal) -> SurfaceCurvature:
        n = _unit(normal)
        out = self.feature(point)
        k = 1.0 / self.edge_radius
        if out.sum() >= 3:
            return SurfaceCurvature.umbilic(k, n)
        if out.sum() == 2:
            along = np.zeros(3)
            along[int(np.flatnonzero(~out)[0])] = 1.0
            return _line(k, _unit(np.cross(along, n), "edge tangent"), n)
        return SurfaceCurvature.umbilic(0.0, n)


#: Vertices used in a mesh's local fit: a quartic height field has 15
#: coefficients; on an icosphere of 1,280 faces 30 neighbours (about three
#: rings) give principal curvatures within 0.4 % of 1/R, a quadratic fit
#: over the same vertices 5 % (its neglected x^4/8R^3 term biases it).
MESH_FIT_NEIGHBOURS = 30
#: A quartic fit needs its 15 coefficients' worth of vertices; below, quadratic.
_QUARTIC_MIN = 15
#: Singular values of the fit's design matrix (monomials of u / reach,
#: v / reach) below this share of the largest are cut [-]: neighbours that
#: do not spread over the tangent plane (a prism's two rings of vertices,
#: pybullet's hull of a URDF cylinder lying on a plane) leave monomials the
#: vertices cannot tell apart. Measured on the racecar wheel's rings (32 a
#: ring, float32 vertices): the undetermined directions at 5e-9-1.3e-7 of
#: the largest, the determined ones at 2e-2 and above; kept, they fitted a
#: slope of 2.7e5 and a support point 1,024 m out.
FIT_RCOND = 1e-6


@dataclass(frozen=True)
class Mesh:
    """vertices (n, 3) [m] of a closed triangle mesh in its frame.

    Curvature at a point: the ``neighbours`` vertices nearest to the point,
    in the tangent frame (u, v, w = height along the outward normal), fitted
    by least squares with the height field w(u, v) = sum c_ij u^i v^j,
    i + j <= 4 (i + j <= 2 with fewer than 15 neighbours); its second-order
    coefficients are the surface's at the point, unbiased by the fourth-order
    terms a quadric fit would fold into them. The principal curvatures are the
    eigenvalues of the graph's shape operator -(I + g g^T)^-1 H / sqrt(1 + |g|^2),
    H = [[2 c_20, c_11], [c_11, 2 c_02]], g = (c_10, c_01). A plane touches a
    surface on its convex hull, where a negative fitted curvature is fitting
    noise: it is set to 0 (flat).
    """

    vertices: np.ndarray = field(repr=False)
    neighbours: int = MESH_FIT_NEIGHBOURS

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"mesh vertices must have shape (n, 3), got {v.shape}")
        if self.neighbours < 6 or self.neighbours > v.shape[0]:
            raise ValueError(f"mesh neighbours = {self.neighbours!r} must be >= 6 (a quadric has 6 coefficients) "
                             f"and <= the {v.shape[0]} vertices")
        object.__setattr__(self, "vertices", v)

    def _fit(self, point, n):
        """The height field's tangent frame (t1, t2), coefficients c (columns
        1, u, v, u^2, u v, v^2, then the higher orders) about ``point``, the
        fitted vertices' largest distance from it in the tangent plane [m] and
        whether the vertices determine every coefficient (full rank). The
        monomials are of u and v scaled by that distance, and the
        least-squares solution cuts singular values below FIT_RCOND of the
        largest (the smallest-norm fit over what the vertices determine)."""
        p = np.asarray(point, dtype=float)
        t1, t2 = tangent_basis(n)
        d = self.vertices - p
        near = np.argpartition(np.einsum("ij,ij->i", d, d), self.neighbours - 1)[: self.neighbours]
        u, v, w = d[near] @ t1, d[near] @ t2, d[near] @ n
        reach = float(np.sqrt(np.max(u * u + v * v)))
        s = reach if reach > 0.0 else 1.0
        degree = 4 if self.neighbours >= _QUARTIC_MIN else 2
        powers = [(i, k - i) for k in range(degree + 1) for i in range(k, -1, -1)]
        M = np.stack([(u / s) ** i * (v / s) ** j for i, j in powers], axis=1)
        c, _, rank, _ = np.linalg.lstsq(M, w, rcond=FIT_RCOND)
        c = c / s ** np.array([i + j for i, j in powers], dtype=float)
        return t1, t2, c, reach, rank == len(powers)

    def curvature(self, point, normal) -> SurfaceCurvature:
        n = _unit(normal)
        t1, t2, c, _, _ = self._fit(point, n)
        g = c[1:3]
        H = np.array([[2.0 * c[3], c[4]], [c[4], 2.0 * c[5]]])
        S = -np.linalg.solve(np.eye(2) + np.outer(g, g), H) / math.sqrt(1.0 + g @ g)
        k, vec = np.linalg.eig(S)
        k, vec = np.real(k), np.real(vec)
        order = np.argsort(k)[::-1]
        k1, k2 = np.maximum(k[order], 0.0)
        e1 = _unit(vec[0, order[0]] * t1 + vec[1, order[0]] * t2, "fitted principal direction")
        return _sc(k1, k2, e1, np.cross(n, e1))

    def support(self, point, normal) -> tuple[np.ndarray, float]:
        """The smooth surface's point whose outward normal is ``normal``, near
        ``point`` (a vertex the engine found deepest), and how much further out
        along the normal it is [m]: the fitted height field's stationary point
        (u, v) = -H^-1 g (its second-order part). A faceted mesh touches a
        plane at a vertex that jumps across the bottom facet as the body turns
        (a lever arm of up to an edge); the smooth surface the mesh stands for
        touches under its centre of curvature. Falls back to ``point`` (offset
        0) where the fit is not convex, the vertices do not determine it (a
        prism's two rings: FIT_RCOND) or the stationary point lies outside
        the fitted vertices."""
        n = _unit(normal)
        p = np.asarray(point, dtype=float)
        t1, t2, c, reach, determined = self._fit(p, n)
        H = np.array([[2.0 * c[3], c[4]], [c[4], 2.0 * c[5]]])
        if not determined or not np.all(np.linalg.eigvalsh(H) < 0.0):
            return p.copy(), 0.0
        uv = -np.linalg.solve(H, c[1:3])
        if not np.linalg.norm(uv) <= reach:
            return p.copy(), 0.0
        w = float(c[0] + c[1:3] @ uv + 0.5 * uv @ H @ uv)
        return p + uv[0] * t1 + uv[1] * t2 + w * n, w


SHAPES = {"sphere": Sphere, "ellipsoid": Ellipsoid, "capsule": Capsule, "cylinder": Cylinder, "box": Box,
          "mesh": Mesh}
