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
    meshes = (Mesh, ConvexMesh)
    return MESH_CURVATURE_RTOL if isinstance(shape1, meshes) or isinstance(shape2, meshes) else CURVATURE_RTOL


@dataclass(frozen=True)
class ConvexMesh:
    """A mesh geom as the engines collide it: its convex hull, standing for a
    smooth convex surface. The curvature is the local fit of
    :class:`msf_contact.shapes.Mesh`, where a principal curvature of the fit
    below ``k_min`` [1/m] (a coarse hull's flat facet, or a concave fit of
    an object made of several convex parts, e.g. ``duck_vhacd.obj``) is
    raised to ``k_min`` = 1 / (the largest vertex distance from the geom's
    centre): the flattest the smooth surface is taken to be, the sphere
    that holds the mesh. Otherwise it is the Mesh (its other methods too)."""

    mesh: Mesh
    k_min: float

    def curvature(self, point, normal) -> SurfaceCurvature:
        s = self.mesh.curvature(point, normal)
        if s.k2 >= self.k_min:
            return s
        return SurfaceCurvature(max(s.k1, self.k_min), self.k_min, s.d1, s.d2)

    def __getattr__(self, name):
        if name.startswith("__") or name == "mesh":  # copy/pickle look these up before mesh is set
            raise AttributeError(name)
        return getattr(self.mesh, name)

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
        v = np.asarray(vertices, dtype=float)
        return ConvexMesh(Mesh(v, min(30, len(v))), 1.0 / float(np.max(np.linalg.norm(v, axis=1))))
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


def contact_law(names: tuple, template, bank: "LawBank", shape1, pose1, shape2, pose2, point, normal, t: float):
    """The law for a narrow-phase contact about to begin (both engines; a
    curvature per contact point): ``bank.law_for`` the pair's law
    ``template`` and the curvature of both surfaces at the point
    (:func:`contact_curvature`). names: the two geoms' (bodies', links')
    names for the message; t [s] the engine time. ValueError, naming both
    and what would make it work, for a contact no law here carries (a line
    contact, two flat faces, a concave fit)."""
    a, b = names
    try:
        curv = contact_curvature(shape1, pose1, shape2, pose2, point, normal)
        return bank.law_for(template, curv, curvature_tolerance(shape1, shape2))
    except ValueError as exc:
        raise ValueError(f"pair ({a!r}, {b!r}) at t = {t:.6g} s: {exc}; the engines have no law for it yet (a "
                         "line contact's footprint law is in msf_contact only): use the built-in contact for this "
                         "pair") from None


class LawBank:
    """A law per contact curvature (issue 13: a curvature per contact point).

    A pair's law is built for one curvature; an engine's narrow phase finds
    the pair's contacts wherever the bodies touch (a tumbling ellipsoid or
    mesh, a cylinder's rim at another tilt, a box's corner or edge). At each
    onset the adapter asks :meth:`law_for` for the law of the contact's
    curvature: the pair's own law when its effective radii (13) are within
    the tolerance, else the same law (materials, options) rebuilt for the
    contact's curvature (:meth:`msf_contact.laws.ForceLaw.with_curvature`),
    kept per bin of the effective radii (log bins of the tolerance's width)
    so a resting or rocking body reuses its few laws (the manager's law
    groups and the compiled kernel's constants stay few)."""

    def __init__(self):
        self._laws: dict[tuple, object] = {}

    @staticmethod
    def _bin(r: float, tol: float):
        return None if math.isinf(r) else int(round(math.log(r) / math.log1p(tol)))

    def law_for(self, template, curv: Curvature, tol: float):
        """The law for a contact of curvature ``curv``: ``template`` (the
        pair's law) if its effective radii are within ``tol`` of the
        contact's, else a law of the same kind and options built for
        ``curv`` (one per bin; ValueError from the law for a curvature it
        cannot carry)."""
        if curvature_mismatch(template.curvature, curv) <= tol:
            return template
        ra, rb = effective_radii(curv)
        key = (id(template), self._bin(ra, tol), self._bin(rb, tol), curv.footprint)
        law = self._laws.get(key)
        if law is None or curvature_mismatch(law.curvature, curv) > tol:
            law = self._laws[key] = template.with_curvature(curv)
        return law

    def __len__(self) -> int:
        return len(self._laws)
