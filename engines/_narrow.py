"""Contacts from an engine's own narrow phase, with the curvature the MSF law
needs at each point (issue 13; engine-agnostic part).

An engine's collision code finds, for any pair of geoms it can collide,
one or several contact points (a box face on a plane: its four corners)
with a signed distance and a normal. :class:`SlotMatcher` gives each point
of a geom pair a stable *slot* (one managed contact of the
:class:`engines._contacts.ContactManager`) from step to step, by the
point's position in body 1's frame: a corner stays the same slot while it
touches. :func:`shape_curvature` turns each point into the principal
curvatures of both surfaces (:mod:`msf_contact.shapes`) and
:func:`contact_curvature` combines them as Hertz does
(:func:`msf_contact.curvature.relative_curvature`).

Conventions of :mod:`engines.base`: the normal points from body 2 toward
body 1; body 1's outward normal at the point is -n, body 2's is +n.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from msf_contact.curvature import SurfaceCurvature, relative_curvature
from msf_contact.geometry import Curvature
from msf_contact.shapes import DEFAULT_EDGE_RADIUS, Box, Capsule, Cylinder, Ellipsoid, Mesh, Sphere

#: The law's effective radii must match the contact's to this share: an
#: engine's normal and point carry float32-level noise (mesh normals), and a
#: body that turned during the approach changes them a little.
CURVATURE_RTOL = 1e-3
#: ... and for a mesh, whose curvature is a local fit (msf_contact.shapes.Mesh:
#: within 0.4 % of the sphere on a 1,280-face icosphere, more on coarser
#: meshes): a law built for the smooth surface the mesh stands for passes.
MESH_CURVATURE_RTOL = 1e-2


def curvature_tolerance(shape1, shape2) -> float:
    """How far a law's effective radii may be from the contact's [-]."""
    return MESH_CURVATURE_RTOL if isinstance(shape1, Mesh) or isinstance(shape2, Mesh) else CURVATURE_RTOL

#: A point of the engine's list continues a slot when it is within this
#: share of the body's size (its geom's largest half-extent) of the slot's
#: last point in body 1's frame; a box's corners are a size apart.
MATCH_SHARE = 0.25


@dataclass(frozen=True)
class Plane:
    """A half-space: flat everywhere."""

    def curvature(self, point, normal) -> SurfaceCurvature:
        return SurfaceCurvature.umbilic(0.0, normal)


def make_shape(kind: str, size, *, edge_radius: float | None = None, vertices=None):
    """The :mod:`msf_contact.shapes` object of an engine geom. kind: sphere,
    plane, ellipsoid, capsule, cylinder, box, mesh; size: MuJoCo's geom size
    (radius; semi-axes; radius and half-length; half-extents); vertices (n, 3)
    [m] in the geom's frame for a mesh; edge_radius [m] of a box or cylinder
    (default ``msf_contact.shapes.DEFAULT_EDGE_RADIUS``)."""
    rho = DEFAULT_EDGE_RADIUS if edge_radius is None else float(edge_radius)
    size = np.asarray(size, dtype=float)
    if kind == "sphere":
        return Sphere(float(size[0]))
    if kind == "plane":
        return Plane()
    if kind == "ellipsoid":
        return Ellipsoid(tuple(size[:3]))
    if kind == "capsule":
        return Capsule(float(size[0]), float(size[1]))
    if kind == "cylinder":
        return Cylinder(float(size[0]), float(size[1]), min(rho, float(size[0]), float(size[1])))
    if kind == "box":
        return Box(tuple(size[:3]), min(rho, float(np.min(size[:3]))))
    if kind == "mesh":
        if vertices is None:
            raise ValueError("a mesh geom needs its vertices for the curvature's local fit")
        return Mesh(np.asarray(vertices, dtype=float), min(30, len(vertices)))
    raise ValueError(f"geom kind {kind!r} has no curvature model (sphere, plane, ellipsoid, capsule, cylinder, "
                     "box and mesh have)")


def shape_curvature(shape, pos, rot, point, outward) -> SurfaceCurvature:
    """The principal curvatures (world frame) of ``shape`` with its frame at
    ``pos`` [m] (3,), ``rot`` (3, 3) (columns: the geom's axes), at the world
    ``point`` [m] (3,) with the world outward unit normal ``outward`` (3,)."""
    rot = np.asarray(rot, dtype=float).reshape(3, 3)
    local = shape.curvature(rot.T @ (np.asarray(point, float) - np.asarray(pos, float)),
                            rot.T @ np.asarray(outward, float))
    return local.rotated(rot)


def contact_curvature(shape1, pose1, shape2, pose2, point, normal) -> Curvature:
    """The pair's :class:`~msf_contact.geometry.Curvature` at a contact:
    body 1's surface (outward -normal) and body 2's (outward +normal)
    combined by :func:`msf_contact.curvature.relative_curvature`. pose: (pos
    (3,), rot (3, 3)); point [m] (3,); normal (3,) from body 2 to body 1."""
    n = np.asarray(normal, dtype=float)
    s1 = shape_curvature(shape1, *pose1, point, -n)
    s2 = shape_curvature(shape2, *pose2, point, n)
    return relative_curvature(s1, s2).curvature


def effective_radii(curv: Curvature) -> tuple[float, float]:
    """(R_a, R_b) of (13) [m], sorted (smaller first), of a Curvature."""
    def series(r1, r2):
        if math.isinf(r1):
            return r2
        if math.isinf(r2):
            return r1
        return r1 * r2 / (r1 + r2)

    a, b = series(curv.R1a, curv.R2a), series(curv.R1b, curv.R2b)
    return (a, b) if a <= b else (b, a)


def curvature_mismatch(law_curv: Curvature, contact: Curvature) -> float:
    """Largest relative difference of the effective radii (13) [-] (0: the same)."""
    got, want = effective_radii(contact), effective_radii(law_curv)
    worst = 0.0
    for g, w in zip(got, want):
        if math.isinf(g) or math.isinf(w):
            worst = max(worst, 0.0 if math.isinf(g) and math.isinf(w) else math.inf)
        else:
            worst = max(worst, abs(g - w) / w)
    return worst


class SlotMatcher:
    """Stable slots for the contact points of one geom pair.

    n_slots: how many points of the pair are managed (the engine's deepest
    ones when it gives more); size [m]: body 1's geom size (its largest
    half-extent) for the matching distance ``MATCH_SHARE * size``.
    """

    def __init__(self, n_slots: int, size: float):
        if n_slots < 1:
            raise ValueError(f"n_slots = {n_slots!r} must be >= 1")
        self.n = int(n_slots)
        self.tol = MATCH_SHARE * float(size)
        #: each slot's last point in body 1's frame [m] (n, 3); nan: free
        self.anchor = np.full((self.n, 3), np.nan)

    def assign(self, local_points, depth, busy) -> np.ndarray:
        """Slot of each engine point (k,) int, -1 for points left out.

        local_points: the points in body 1's frame [m] (k, 3); depth: their
        approach [m] (k,) (deepest first when slots run out); busy: (n,) bool,
        slots the manager still holds (in contact, or a correction pending).
        A busy slot keeps its nearest point within the matching distance; the
        other points take free slots, deepest first.
        """
        pts = np.asarray(local_points, dtype=float).reshape(-1, 3)
        k = pts.shape[0]
        out = np.full(k, -1)
        order = np.argsort(-np.asarray(depth, dtype=float), kind="stable")
        taken = np.zeros(self.n, bool)
        known = ~np.isnan(self.anchor[:, 0])
        # continuing points first: each known slot takes its nearest unassigned point
        if k and np.any(known):
            dist = np.linalg.norm(pts[:, None, :] - self.anchor[None, :, :], axis=2)
            dist[:, ~known] = np.inf
            for flat in np.argsort(dist, axis=None, kind="stable"):
                i, s = divmod(int(flat), self.n)
                if not np.isfinite(dist[i, s]) or dist[i, s] > self.tol:
                    break
                if out[i] < 0 and not taken[s]:
                    out[i], taken[s] = s, True
        free = [s for s in range(self.n) if not taken[s] and not busy[s]]
        for i in order:
            if out[i] < 0 and free:
                out[i] = free.pop(0)
                taken[out[i]] = True
        for i in range(k):
            if out[i] >= 0:
                self.anchor[out[i]] = pts[i]
        # a slot neither matched nor busy forgets its point
        self.anchor[~taken & ~np.asarray(busy, bool)] = np.nan
        return out


def check_contact_law(names: tuple, law_curvature: Curvature, shape1, pose1, shape2, pose2, point, normal,
                      t: float) -> Curvature:
    """The curvature of a narrow-phase contact about to begin, checked
    against the pair's law (both engines: one law per pair). names: the two
    geoms' (bodies', links') names for the message; the rest as
    :func:`contact_curvature`; t [s] the engine time. ValueError, naming
    both and what would make it work, for a contact the law cannot carry (a
    line contact, two flat faces) or one whose effective radii (13) differ
    from the law's by more than :func:`curvature_tolerance`."""
    a, b = names
    try:
        curv = contact_curvature(shape1, pose1, shape2, pose2, point, normal)
    except ValueError as exc:
        raise ValueError(f"pair ({a!r}, {b!r}) at t = {t:.6g} s: {exc}; the engines have no law for it yet (a "
                         "line contact's footprint law is in msf_contact only): use the built-in contact for this "
                         "pair") from None
    bad, tol = curvature_mismatch(law_curvature, curv), curvature_tolerance(shape1, shape2)
    if bad > tol:
        raise ValueError(
            f"pair ({a!r}, {b!r}) at t = {t:.6g} s: the contact's curvature {curv} differs from the law's "
            f"{law_curvature} by {bad:.3g} (> {tol}); the engines keep one law per pair: build the law with the "
            "curvature at the contact (engines._narrow.contact_curvature / msf_contact.curvature.relative_curvature)")
    return curv
