"""Contact detection for the smooth primitive pairs the MSF law can describe.

The MSF law (spec sections 3-4) needs a contact between smooth surfaces
with known principal radii of curvature at the contact point. Supported:

- sphere-plane (the plane is a half-space: infinite radii),
- sphere-box *face* (the sphere's centre projects inside one face's
  rectangle; the face is a plane there),
- sphere-sphere.

Anything else (a box edge or corner, box-box, capsule, cylinder, mesh,
ellipsoid) is refused here with ``ValueError``: a sharp edge has no finite
curvature. The adapters carry a sphere on a box as the box rounded by its
edge radius (faces, edges and corners: engines._narrow.SphereOnBox) and
the other shapes through the engines' narrow phases (engines._narrow).

Every detector is vectorised over n pairs and returns a :class:`Detection`
with the conventions of :mod:`engines.base`: ``x`` the approach of the
undeformed surfaces [m] (negative: a gap), ``normal`` from body 2 toward
body 1, ``point`` in the middle of the overlap. Body 1 is the first shape
named in the function (the sphere).

Across a gap (x < 0) the contact will begin at different material points of
the two bodies: ``point1`` on body 1's surface and ``point2`` on body 2's,
both equal to ``point`` once x >= 0. An adapter evaluates each body's
Jacobian (hence W and v_rel) at its own point and applies each body's force
there: with the single mid-gap point the lever arms would be off by half
the gap (up to v dt / 2), which at a 1-2 ms step changes the spin of a
sub-cycled impact by several percent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from msf_contact.geometry import Curvature

#: Shapes a pair may be built from, and the pairs that are smooth.
SHAPES = ("sphere", "plane", "box", "capsule", "cylinder", "ellipsoid", "mesh", "hfield")
SUPPORTED_PAIRS = {
    ("sphere", "plane"): "sphere-plane",
    ("plane", "sphere"): "sphere-plane",
    ("sphere", "sphere"): "sphere-sphere",
    ("sphere", "box"): "sphere-box",
    ("box", "sphere"): "sphere-box",
}

#: Centres closer than this share of the radii sum have no defined normal.
COINCIDENT_RTOL = 1e-12


@dataclass
class Detection:
    """Detected contacts of n pairs.

    x: approach [m] (n,); negative: the gap between the surfaces.
    normal: unit normal from body 2 toward body 1 (n, 3).
    point: contact point, the middle of the overlap (of the gap if x < 0) [m] (n, 3).
    point1, point2: the contact point on body 1's / body 2's surface [m] (n, 3);
        both equal ``point`` when x >= 0 (see the module docstring).
    radii1: principal radii of body 1's surface at the point [m] (n, 2), inf for a plane.
    radii2: principal radii of body 2's surface [m] (n, 2).
    """

    x: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    point1: np.ndarray
    point2: np.ndarray
    radii1: np.ndarray
    radii2: np.ndarray

    @staticmethod
    def of_sphere(center, R, x, normal, radii2) -> "Detection":
        """Body 1 a sphere (centre, radius R): its surface point at the overlap's middle."""
        point1 = center - (R - 0.5 * np.maximum(x, 0.0))[:, None] * normal
        point2 = point1 + np.minimum(x, 0.0)[:, None] * normal
        return Detection(x, normal, 0.5 * (point1 + point2), point1, point2,
                         np.repeat(R[:, None], 2, axis=1), radii2)

    def curvature(self, i: int = 0) -> Curvature:
        """The :class:`msf_contact.geometry.Curvature` of contact i (body 1 first)."""
        return Curvature(float(self.radii1[i, 0]), float(self.radii1[i, 1]),
                         float(self.radii2[i, 0]), float(self.radii2[i, 1]))

    def swapped(self) -> "Detection":
        """The same contacts with the roles of body 1 and body 2 exchanged."""
        return Detection(self.x.copy(), -self.normal, self.point.copy(), self.point2.copy(), self.point1.copy(),
                         self.radii2.copy(), self.radii1.copy())


def cross_rows(a, b) -> np.ndarray:
    """Row-wise a x b for (..., 3) arrays, written out (np.cross costs more
    than the arithmetic at these sizes)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def check_pair_supported(shape1: str, shape2: str) -> str:
    """The canonical kind ("sphere-plane", "sphere-sphere", "sphere-box") of a
    pair of shapes, or ValueError naming both shapes when it is not smooth."""
    a, b = str(shape1).strip().lower(), str(shape2).strip().lower()
    try:
        return SUPPORTED_PAIRS[(a, b)]
    except KeyError:
        pass
    raise ValueError(
        f"shape pair ({shape1!r}, {shape2!r}) is not supported: the MSF law needs two smooth surfaces with "
        "known curvature at the contact; supported pairs are sphere-plane, sphere-sphere and sphere-box "
        "(on a face only)"
    )


def _vec(name, a, n=None):
    arr = np.asarray(a, dtype=float)
    arr = arr.reshape(-1, 3) if arr.ndim <= 2 else arr
    if n is not None and arr.shape[0] != n:
        if arr.shape[0] != 1:
            raise ValueError(f"{name} has {arr.shape[0]} rows; expected {n} (or 1 to broadcast)")
        arr = np.repeat(arr, n, axis=0)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} = {arr!r} must be finite")
    return arr


def _radius(name, r, n):
    arr = np.atleast_1d(np.asarray(r, dtype=float))
    if arr.shape[0] != n:
        if arr.shape[0] != 1:
            raise ValueError(f"{name} has {arr.shape[0]} values; expected {n} (or 1 to broadcast)")
        arr = np.repeat(arr, n)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} = {arr!r} m must be finite and > 0")
    return arr


def _unit(name, v):
    nrm = np.linalg.norm(v, axis=1)
    if np.any(nrm <= 0):
        raise ValueError(f"{name} has a zero vector; a direction is required")
    return v / nrm[:, None]


def sphere_plane(center, radius, plane_point, plane_normal) -> Detection:
    """Sphere (body 1) on a plane (body 2, the half-space below ``plane_normal``).

    center [m] (n, 3), radius [m] (n,), plane_point [m] (n, 3),
    plane_normal (n, 3) (normalised here; points out of the half-space).
    x = R - (c - p0).n; point = c - (R - x/2) n.
    """
    c = _vec("center", center)
    n = c.shape[0]
    R = _radius("radius", radius, n)
    p0 = _vec("plane_point", plane_point, n)
    nrm = _unit("plane_normal", _vec("plane_normal", plane_normal, n))
    dist = np.einsum("ij,ij->i", c - p0, nrm)
    return Detection.of_sphere(c, R, R - dist, nrm, np.full((n, 2), math.inf))


def sphere_sphere(center1, radius1, center2, radius2) -> Detection:
    """Sphere 1 on sphere 2. x = R1 + R2 - |c1 - c2|; normal (c1 - c2)/|c1 - c2|;
    point halfway between the two surfaces along the normal (the middle of the overlap)."""
    c1 = _vec("center1", center1)
    n = c1.shape[0]
    c2 = _vec("center2", center2, n)
    R1 = _radius("radius1", radius1, n)
    R2 = _radius("radius2", radius2, n)
    d = c1 - c2
    dist = np.linalg.norm(d, axis=1)
    if np.any(dist <= COINCIDENT_RTOL * (R1 + R2)):
        raise ValueError("sphere-sphere: the centres coincide, the contact normal is undefined")
    nrm = d / dist[:, None]
    return Detection.of_sphere(c1, R1, R1 + R2 - dist, nrm, np.repeat(R2[:, None], 2, axis=1))


def sphere_box_face(center, radius, box_center, box_rotation, half_sizes, margin: float = math.inf) -> Detection:
    """Sphere (body 1) on a face of a box (body 2).

    center [m] (n, 3), radius [m] (n,), box_center [m] (n, 3), box_rotation
    (n, 3, 3) whose columns are the box axes in the world frame, half_sizes
    [m] (n, 3). The face is the one whose rectangle contains the projection
    of the sphere's centre (with the centre inside the box: the nearest
    face). If the box's closest point to the centre is on an edge or a
    corner, ValueError: the contact is not smooth. ``margin`` [m]: only
    pairs with x > -margin are checked for that (default: all of them), so
    an adapter may pass its closing distance and ignore far-away spheres.
    """
    c = _vec("center", center)
    n = c.shape[0]
    R = _radius("radius", radius, n)
    bc = _vec("box_center", box_center, n)
    rot = np.asarray(box_rotation, dtype=float).reshape(-1, 3, 3)
    if rot.shape[0] != n:
        if rot.shape[0] != 1:
            raise ValueError(f"box_rotation has {rot.shape[0]} matrices; expected {n}")
        rot = np.repeat(rot, n, axis=0)
    if not np.allclose(np.einsum("nji,njk->nik", rot, rot), np.eye(3), atol=1e-9):
        raise ValueError("box_rotation must be orthonormal (columns = box axes in the world frame)")
    h = _vec("half_sizes", half_sizes, n)
    if np.any(h <= 0):
        raise ValueError(f"half_sizes = {h!r} m must be > 0")
    local = np.einsum("nji,nj->ni", rot, c - bc)  # R^T (c - bc)
    outside = np.abs(local) > h
    n_out = outside.sum(axis=1)
    # axis of the face: the only coordinate outside, or (centre inside) the nearest face
    depth_in = h - np.abs(local)
    axis = np.where(n_out >= 1, np.argmax(outside, axis=1), np.argmin(depth_in, axis=1))
    rows = np.arange(n)
    sign = np.where(local[rows, axis] >= 0, 1.0, -1.0)
    dist = np.abs(local[rows, axis]) - h[rows, axis]  # centre's distance to the face plane (neg inside)
    x = R - dist
    bad = (n_out >= 2) & (x > -margin)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        where = "a corner" if n_out[i] == 3 else "an edge"
        raise ValueError(
            f"sphere-box contact on an edge/corner is not smooth: MSF needs smooth curvature "
            f"(pair {i}: the sphere's centre projects outside every face, the closest point of the box is on {where})"
        )
    nrm = rot[rows, :, axis] * sign[:, None]
    return Detection.of_sphere(c, R, x, nrm, np.full((n, 2), math.inf))
