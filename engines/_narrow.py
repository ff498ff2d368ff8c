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

import copy
import math
import warnings
from dataclasses import dataclass

import numpy as np

from msf_contact.curvature import SurfaceCurvature, relative_curvature, tangent_basis
from msf_contact import closed_forms as cf
from msf_contact._validate import SMALL_STRAIN_X_OVER_R, ValidityWarning
from msf_contact.geometry import Curvature, SideFootprint
from msf_contact.laws import MSFLaw, self_consistent_omega
from msf_contact.shapes import DEFAULT_EDGE_RADIUS, Box, Capsule, Cylinder, Ellipsoid, Mesh, Sphere

from . import _impact_kernel as _IK
from . import _kernel as _K

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

#: A mesh whose convex hull has a flat face (a hull triangle, or coplanar
#: hull facets merged) wider than this share of its bounding radius can
#: rest on that face, and the engines give one point of it (pybullet's
#: getClosestPoints) or its vertices (MuJoCo): its default number of slots
#: is COARSE_MESH_SLOTS, as a box's corners, not 1. With one slot the
#: point jumps between the face's vertices during a contact: pybullet_data's
#: duck_vhacd.obj (its flat face 41.5 mm on a 57 mm bounding radius) rocking
#: on that face had its point jump 30-40 mm within a contact and records
#: flagged "energy gained in a contact" (COR 1.4-2.1); with 4 none. A lone
#: hull triangle counts as much as a face of several (pybullet_data's
#: teddy2_VHACD_CHs.obj: 132 hull vertices, triangles up to 0.72 m on a
#: 0.85 m bounding radius, no 4 coplanar: it rests on such triangles, whose
#: vertices are its contacts, docs/engines.md). A smooth mesh (an
#: icosphere of 162 or more vertices, its hull triangles at most 0.33 of
#: its radius) keeps 1: its bottom vertices are samples of one contact
#: (several would each carry the sphere's whole law), carried at the
#: smooth surface's point (:func:`smooth_point`). The 42-vertex icosphere
#: (edges up to 0.62 r) is a polyhedron here: 4.
FLAT_FACE_SHARE = 0.5
COARSE_MESH_SLOTS = 4
#: Hull facets whose plane equations (unit normal, offset over the bounding
#: radius) agree to this are one flat face (float32 vertices: ~1e-7).
COPLANAR_TOL = 1e-5


def flat_face(vertices, corners: int = 4) -> tuple[float, np.ndarray | None]:
    """The widest flat face of the convex hull of ``vertices`` [m] (n, 3)
    among those of at least ``corners`` vertices (3: a hull triangle counts):
    (its width [m], the largest distance between two of its vertices; its
    outward unit normal (3,)), a face being coplanar hull facets merged
    (COPLANAR_TOL); (0, None) when there is none."""
    from scipy.spatial import ConvexHull

    V = np.asarray(vertices, dtype=float).reshape(-1, 3)
    hull = ConvexHull(V)
    scale = float(np.max(np.linalg.norm(V - V.mean(axis=0), axis=1)))
    key = np.round(np.column_stack([hull.equations[:, :3], hull.equations[:, 3] / scale]) / COPLANAR_TOL)
    faces: dict = {}
    normal: dict = {}
    for simplex, eq, k in zip(hull.simplices, hull.equations, map(tuple, key.astype(np.int64))):
        faces.setdefault(k, set()).update(int(v) for v in simplex)
        normal[k] = eq[:3]
    best, n = 0.0, None
    for k, verts in faces.items():
        if len(verts) >= corners:
            P = V[sorted(verts)]
            w = float(np.max(np.linalg.norm(P[:, None, :] - P[None, :, :], axis=2)))
            if w > best:
                best, n = w, np.asarray(normal[k], dtype=float)
    return best, n


def default_mesh_slots(vertices) -> int:
    """The contact slots of a mesh geom given no ``mesh_slots`` [-]:
    COARSE_MESH_SLOTS when its hull has a flat face, a triangle or more,
    wider than FLAT_FACE_SHARE of its bounding radius (:func:`flat_face`;
    vertices [m] (n, 3) in the geom's frame), else 1."""
    V = np.asarray(vertices, dtype=float).reshape(-1, 3)
    if V.shape[0] < 4:
        return 1
    r = float(np.max(np.linalg.norm(V, axis=1)))
    return COARSE_MESH_SLOTS if flat_face(V, 3)[0] > FLAT_FACE_SHARE * r else 1


#: The farthest a mesh's point is moved to the smooth surface it stands for
#: [m] (:func:`smooth_point`): a facet's sagitta (0.09 mm on a 642-vertex
#: icosphere of R 30 mm); a larger move is a fit the vertices do not
#: support (a wheel's hull gave a support point 1,024 m out), and the vertex
#: is kept. pybullet's getClosestPoints is asked this much further.
SMOOTH_REACH = 1e-3


def smooth_point(geom, pos, rot, point, outward) -> tuple[np.ndarray, float]:
    """A mesh's contact point moved from the vertex the engine found to the
    smooth convex surface the mesh stands for, and how far it moved outward
    along ``outward`` [m] (the approach grows by it): the fitted surface's
    point with that outward normal (:meth:`msf_contact.shapes.Mesh.support`,
    through ConvexMesh), or the exact point of an analytic surface given as
    the mesh's curvature (``point_of_normal``, pybullet's ellipsoid); any
    other shape, a move beyond SMOOTH_REACH, or a fit that does not
    determine the point: ``point`` as it is, 0. pos [m] (3,), rot (3, 3):
    the geom's frame in the world; point [m] (3,) on the geom's surface,
    outward (3,) its outward unit normal there, world axes.

    Why (issue 13): a faceted mesh touches a plane at a vertex, and as the
    body rolls the deepest vertex jumps by up to an edge (3-4 mm on a
    642-vertex icosphere of R 30 mm) while the smooth surface's point moves
    continuously under the centre of curvature; a contact carried at the
    jumping vertex changes its material point within the contact (the
    finite-difference a_ext of that step compares two points' velocities:
    60-75 m/s^2 at a rolling jump, MuJoCo) and its approach by the jump's
    depth difference, which the contact's own x never sees.

    The fit is made twice, the second centred on the first's point: fitted
    about a vertex 3.5 mm off the bottom (MuJoCo's point at a one-slot
    contact can lag so far) the stationary point lies at the patch's edge
    and is off by up to 0.37 mm along the surface and 37 um in depth (a
    sawtooth in x at every change of vertex); centred, within 1.9 um and
    0.9 um of the sphere's bottom from any of the 7 deepest vertices
    (300 random orientations of the 642-vertex icosphere)."""
    if not (hasattr(geom, "support") or hasattr(geom, "point_of_normal")):
        return np.asarray(point, dtype=float), 0.0
    rot = np.asarray(rot, dtype=float).reshape(3, 3)
    pos, point = np.asarray(pos, dtype=float), np.asarray(point, dtype=float)
    local, out = rot.T @ (point - pos), rot.T @ np.asarray(outward, dtype=float)
    if hasattr(geom, "support"):
        q, _ = geom.support(local, out)
        if np.any(q != local):  # once more, the fit centred on the point found (below)
            q, _ = geom.support(q, out)
    else:
        q = geom.point_of_normal(out)
    w = float((q - local) @ out)
    if not abs(w) <= SMOOTH_REACH:
        return point, 0.0
    return pos + rot @ q, w


def smooth_contact(geom1, pose1, geom2, pose2, x: float, point, normal) -> tuple[float, np.ndarray]:
    """An engine's contact (approach x [m], ``point`` [m] (3,) midway between
    the surfaces, unit ``normal`` (3,) from body 2 to body 1) with each mesh
    side's point moved to its smooth surface (:func:`smooth_point`): (the
    approach grown by both moves [m], the new midpoint [m] (3,)). Each
    side's tangential move is given to the other side's point too, so the
    two stay on one line along the normal (a plane: exact; a curved other
    body: to first order in the move). pose: (pos (3,), rot (3, 3)) of each
    geom's frame."""
    n = np.asarray(normal, dtype=float)
    p = np.asarray(point, dtype=float)
    p1, p2 = p - 0.5 * x * n, p + 0.5 * x * n  # each body's own surface point
    q1, w1 = smooth_point(geom1, *pose1, p1, -n)
    q2, w2 = smooth_point(geom2, *pose2, p2, n)
    if w1 == 0.0 and w2 == 0.0:
        return float(x), p
    t1, t2 = q1 - p1, q2 - p2
    t1, t2 = t1 - (t1 @ n) * n, t2 - (t2 @ n) * n
    return float(x + w1 + w2), 0.5 * ((q1 + t2) + (q2 + t1))


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


def bounding_curvature(shape) -> float:
    """1 / the radius of the smallest centred sphere that holds ``shape`` [1/m]
    (0: a plane): the flattest a closed convex surface of that size is
    taken to be where a contact leaves no point law (:func:`contact_law`)."""
    if isinstance(shape, Plane):
        return 0.0
    if isinstance(shape, Sphere):
        return 1.0 / shape.radius
    if isinstance(shape, Ellipsoid):
        return 1.0 / max(shape.semi_axes)
    if isinstance(shape, Capsule):
        return 1.0 / (shape.radius + shape.half_length)
    if isinstance(shape, Cylinder):
        return 1.0 / math.hypot(shape.radius, shape.half_length)
    if isinstance(shape, Box):
        return 1.0 / float(np.linalg.norm(shape.half_extents))
    if isinstance(shape, ConvexMesh):
        return shape.k_min
    if isinstance(shape, Mesh):
        return 1.0 / float(np.max(np.linalg.norm(shape.vertices, axis=1)))
    raise ValueError(f"no bounding curvature for {type(shape).__name__}")


def _raised(s: SurfaceCurvature, k_min: float) -> SurfaceCurvature:
    """``s`` with each principal curvature below ``k_min`` [1/m] raised to it."""
    return SurfaceCurvature(max(s.k1, k_min), max(s.k2, k_min), s.d1, s.d2)


def contact_curvature(shape1, pose1, shape2, pose2, point, normal, x: float = 0.0,
                      raised: bool = False) -> Curvature:
    """The pair's :class:`~msf_contact.geometry.Curvature` at a contact:
    body 1's surface (outward -normal) and body 2's (outward +normal)
    combined by :func:`msf_contact.curvature.relative_curvature`. pose: (pos
    (3,), rot (3, 3)); point [m] (3,) midway between the surfaces, as the
    engines give it; normal (3,) from body 2 to body 1; x [m] the approach
    (negative: a gap). Each shape is asked at its own surface point,
    ``point -+ x/2 normal``: across a gap of a few millimetres (the detection
    margin of a falling body) the midpoint is that far from either surface
    and would pick another feature of a shape with features (a box corner's
    midpoint read as an edge or a face: MuJoCo's user drop of a box raised
    "line contact" at t = 0.235 s, pybullet's "two planes touch").
    raised: each surface's principal curvatures below its
    :func:`bounding_curvature` raised to it (:func:`contact_law`)."""
    n = np.asarray(normal, dtype=float)
    p = np.asarray(point, dtype=float)
    s1 = shape_curvature(shape1, *pose1, p - 0.5 * x * n, -n)
    s2 = shape_curvature(shape2, *pose2, p + 0.5 * x * n, n)
    if raised:
        s1, s2 = _raised(s1, bounding_curvature(shape1)), _raised(s2, bounding_curvature(shape2))
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
        other points take free slots, deepest first. A pair of one slot
        takes the deepest point, busy or not, however far it moved: the
        engine's one point is the pair's contact (a hexagonal prism lying on
        a face: pybullet's closest point jumps between the face's four
        vertices, 45-50 mm apart; left out, the busy slot read "no point",
        x = -1 m, and the prism fell through the floor, pybullet and main
        alike).
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
        free = [s for s in range(self.n) if not taken[s] and (not busy[s] or self.n == 1)]
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


def contact_law(names: tuple, template, bank: "LawBank", shape1, pose1, shape2, pose2, point, normal, t: float,
                x: float = 0.0):
    """The law for a narrow-phase contact about to begin (both engines; a
    curvature per contact point): ``bank.law_for`` the pair's law
    ``template`` and the curvature of both surfaces at the point
    (:func:`contact_curvature`). names: the two geoms' (bodies', links')
    names for the messages; t [s] the engine time; x [m] the approach at the
    point (:func:`contact_curvature`).

    A contact that leaves no point law (a line: both surfaces straight along
    one direction, e.g. a cylinder standing on its flat end, its rim's top
    straight along the rim; a capsule's side on a box face; two flat faces,
    a box on a free box) is never refused mid-run: its surfaces' straight
    directions take their geom's :func:`bounding_curvature` (the sphere that
    holds the geom: the flattest a closed surface of that size is taken to
    be, as ConvexMesh's k_min), the point law of that curvature carries it,
    its records say so in outside_validity (the law's ``validity_note``,
    engines._contacts.records) and a ValidityWarning names both geoms, once
    per pair (the box and the capsule's or cylinder's side on a plane have
    their line laws: BoxOnPlane, SideLine). ValueError, naming both and what
    would make it work, for a curvature the pair's law cannot carry."""
    a, b = names
    note = None
    try:
        curv = contact_curvature(shape1, pose1, shape2, pose2, point, normal, x)
    except ValueError as exc:  # no point contact: the straight directions raised
        curv = contact_curvature(shape1, pose1, shape2, pose2, point, normal, x, raised=True)
        note = (f"{exc}: carried as the point law with each straight direction's curvature raised to its "
                f"geom's bounding sphere's, 1/({1.0 / max(bounding_curvature(shape1), 1e-300):.4g} m) and "
                f"1/({1.0 / max(bounding_curvature(shape2), 1e-300):.4g} m) (a line or flat contact between "
                "these shapes has no law in the engines): the force is the "
                "model's stand-in, not a line or flat-punch contact's")
        if (a, b) not in bank.noted:
            bank.noted.add((a, b))
            warnings.warn(f"pair ({a!r}, {b!r}) at t = {t:.6g} s: {note} (warned once per pair; each such "
                          "record carries it in outside_validity; for a line contact's law give the pair a box, "
                          "capsule or cylinder on a plane, or use the built-in contact for this pair)",
                          ValidityWarning, stacklevel=3)
    try:
        return bank.law_for(template, curv, curvature_tolerance(shape1, shape2), note)
    except ValueError as exc:
        raise ValueError(f"pair ({a!r}, {b!r}) at t = {t:.6g} s: {exc}; the engines have no law for it: use the "
                         "built-in contact for this pair") from None


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

    def __init__(self, kernel=None):
        self._laws: dict[tuple, object] = {}
        #: pairs (names) warned that a contact was carried by a raised curvature (contact_law)
        self.noted: set = set()
        #: law -> (code, constants) of the compiled kernel or None (engines._contacts.compiled.kernel_law):
        #: given, the MSF laws built here integrate their onsets compiled (KernelOnsetMSFLaw)
        self._kernel = kernel

    @staticmethod
    def _bin(r: float, tol: float):
        return None if math.isinf(r) else int(round(math.log(r) / math.log1p(tol)))

    def law_for(self, template, curv: Curvature, tol: float, note: str | None = None):
        """The law for a contact of curvature ``curv``: ``template`` (the
        pair's law) if its effective radii are within ``tol`` of the
        contact's, else a law of the same kind and options built for
        ``curv`` (one per bin; ValueError from the law for a curvature it
        cannot carry). note: the records' outside_validity note of a
        stand-in curvature (contact_law), kept on the law as
        ``validity_note`` (never the template: a law of its own)."""
        if note is None and curvature_mismatch(template.curvature, curv) <= tol:
            return template
        ra, rb = effective_radii(curv)
        key = (id(template), self._bin(ra, tol), self._bin(rb, tol), curv.footprint, note is not None)
        law = self._laws.get(key)
        if law is None or curvature_mismatch(law.curvature, curv) > tol:
            law = template.with_curvature(curv)
            known = self._kernel(law) if self._kernel is not None and type(law) is MSFLaw else None
            if known is not None:  # its onsets compiled (no table for a non-spherical msf contact)
                law = KernelOnsetMSFLaw.of(law, *known)
            if note is not None:
                law.validity_note = note
            law = self._laws[key] = law
        return law

    def __len__(self) -> int:
        return len(self._laws)

    def __iter__(self):
        """The laws built so far."""
        return iter(list(self._laws.values()))


# ------------------------------------------------------------ line contact ---
#: A capsule's or cylinder's side lying on a plane is carried as a *line
#: contact* (issue 13 item 3; :class:`SideEndLaw`) below this tilt of its
#: axis from the plane [rad]; above it by the engine's points (the end
#: spheres, the rim points) with their point laws. At a tilt theta the side
#: touches only once an end's approach exceeds e (1 - cos theta) (e: the
#: end's radius, a capsule's radius or a cylinder's edge radius); at
#: acos(1 - SMALL_STRAIN_X_OVER_R) = 25.8 deg that is the end's own
#: small-strain bound (x/e = 0.1, msf_contact._validate), so above it, for
#: every approach the model covers, an end's line law *is* its point law
#: (exactly): the hand-off changes no force.
LINE_TILT_MAX = math.acos(1.0 - SMALL_STRAIN_X_OVER_R)


@dataclass(frozen=True)
class SideEnds:
    """The two ends of a capsule's or cylinder's side against a plane (world
    frame), end 0 at the geom's -z end, end 1 at +z.

    x [m] (2,): each end's approach (its end sphere's or rim arc's lowest
    point; negative: a gap); lowest [m] (2, 3): those points; rise (2,):
    sin of the angle by which the side rises from each end toward the other
    (positive: that end is the lower); tilt [rad] = asin|rise|;
    normal (3,): the plane's unit normal, toward the body."""

    x: np.ndarray
    lowest: np.ndarray
    rise: np.ndarray
    tilt: float
    normal: np.ndarray


def side_ends(shape, pos, rot, plane_pos, plane_normal) -> SideEnds:
    """:class:`SideEnds` of ``shape`` (:class:`msf_contact.shapes.Capsule`
    or :class:`~msf_contact.shapes.Cylinder`; frame at ``pos`` [m] (3,),
    ``rot`` (3, 3), axis along its z) against the plane through
    ``plane_pos`` [m] (3,) with unit normal ``plane_normal`` (3,). A
    capsule's ends are the spheres of its radius at the segment's ends; a
    cylinder's, in the plane of the axis and the normal, the arcs of its rim
    torus (edge radius rho) centred R - rho from the axis and
    half_length - rho from the middle."""
    n = np.asarray(plane_normal, dtype=float)
    z = np.asarray(rot, dtype=float).reshape(3, 3)[:, 2]
    sin_t = min(max(float(z @ n), -1.0), 1.0)  # np.clip's value, without its cost on one number
    radial = -(n - sin_t * z)  # across the axis, toward the plane: |radial| = cos(tilt)
    cos_t = float(np.linalg.norm(radial))
    if isinstance(shape, Capsule):
        e, off, half = shape.radius, 0.0, shape.half_length
    elif isinstance(shape, Cylinder):
        e, off, half = shape.edge_radius, shape.radius - shape.edge_radius, shape.half_length - shape.edge_radius
    else:
        raise ValueError(f"a line contact needs a capsule or a cylinder, not {type(shape).__name__}")
    m = radial / cos_t if cos_t > 0.0 else np.zeros(3)
    centres = np.asarray(pos, dtype=float)[None, :] + np.array([-half, half])[:, None] * z[None, :] + off * m
    lowest = centres - e * n
    x = -((lowest - np.asarray(plane_pos, dtype=float)) @ n)
    rise = np.array([sin_t, -sin_t])  # from end 0 (at -z) toward end 1 the side rises by z.n
    return SideEnds(x, lowest, rise, math.asin(abs(sin_t)), n.copy())


def side_end_constants(shape) -> tuple[float, float, float]:
    """(e, off, half) [m] of :func:`side_ends` for ``shape`` (a capsule or a cylinder): the
    ends' radius, their centres' offset from the axis and from the middle."""
    if isinstance(shape, Capsule):
        return shape.radius, 0.0, shape.half_length
    if isinstance(shape, Cylinder):
        return shape.edge_radius, shape.radius - shape.edge_radius, shape.half_length - shape.edge_radius
    raise ValueError(f"a line contact needs a capsule or a cylinder, not {type(shape).__name__}")


def side_ends_many(e, off, half, pos, rot, plane_pos, plane_normal) -> list[SideEnds]:
    """:func:`side_ends` of k sides at once (issue 13, the walkers' rest cost): e, off,
    half (k,) their :func:`side_end_constants`, pos (k, 3), rot (k, 3, 3), plane_pos (k, 3),
    plane_normal (k, 3). The same float operations row by row, so the same values bit for
    bit (tests/test_rest_cost_paths.py): z . n and |radial| as the sums of three products
    in order (what numpy's dot and norm of one 3-vector give), the ends' heights by one
    stacked matmul (each (2, 3) @ (3,) as numpy computes it alone), asin by math.asin."""
    e, off, half = (np.asarray(a, dtype=float) for a in (e, off, half))
    n = np.asarray(plane_normal, dtype=float)
    z = np.asarray(rot, dtype=float).reshape(-1, 3, 3)[:, :, 2]
    sin_t = np.minimum(np.maximum(z[:, 0] * n[:, 0] + z[:, 1] * n[:, 1] + z[:, 2] * n[:, 2], -1.0), 1.0)
    radial = -(n - sin_t[:, None] * z)
    cos_t = np.sqrt(radial[:, 0] * radial[:, 0] + radial[:, 1] * radial[:, 1] + radial[:, 2] * radial[:, 2])
    pos_c = cos_t > 0.0
    m = np.where(pos_c[:, None], radial / np.where(pos_c, cos_t, 1.0)[:, None], 0.0)
    hz = half[:, None] * z
    pos = np.asarray(pos, dtype=float)
    off_m = off[:, None] * m
    centres = np.stack([pos + -hz, pos + hz], axis=1) + off_m[:, None, :]  # (k, 2, 3)
    lowest = centres - (e[:, None] * n)[:, None, :]
    x = -np.matmul(lowest - np.asarray(plane_pos, dtype=float)[:, None, :], n[:, :, None])[:, :, 0]
    return [SideEnds(x[i], lowest[i], np.array([s, -s]), math.asin(abs(s)), n[i].copy())
            for i, s in enumerate(sin_t.tolist())]


def kernel_onset_one(law: MSFLaw, code: int, lc, v: float, m: float, omega_h: float | None = None) -> dict:
    """MSFLaw.onset_one for a law the compiled kernel knows (code, constants
    lc (NLC,) of engines._kernel), each collision integrated by
    engines._impact_kernel.impact (the same DOP853 steps as
    msf_contact._normal.integrate_normal, tests/test_narrow_mujoco.py and
    tests/test_narrow_pybullet.py) and the self-consistent omega_x of (46) by
    msf_contact.laws.self_consistent_omega from omega_h [rad/s] (None: pi /
    the undamped contact's duration). v [m/s], m [kg]."""
    x_scale = float(np.asarray(law.hertz_scale(v, m)).reshape(-1)[0])
    x_limit = law.x_limit
    oc = np.zeros((1, _K.NOC))
    out = np.empty(_IK.NR)

    def solve(omega):
        """Integrate with eta'_E = E''/omega (omega 0: undamped); the moduli (out: the results)."""
        mod = law._moduli_at(omega) if omega > 0.0 else law.moduli
        oc[0, 0], oc[0, 1] = mod.E, (mod.E_loss / omega if omega > 0.0 else 0.0)
        status = _IK.impact(code, lc, oc, m, v, x_scale, x_limit if x_limit is not None else -1.0, out)
        if status == _IK.LIMIT:
            raise ValueError(
                f"the approach reached x = {x_limit:.6g} m = 2R before maximum compression: k_p = sqrt(2 - x/R) "
                "of (15) has no real value beyond; the impact is outside the msf geometry (lower the speed)")
        if status != _IK.OK:
            raise RuntimeError("normal impact integration failed" if status == _IK.FAILED
                               else "normal impact never reached maximum compression")
        return mod

    if isinstance(law.omega, float):
        omega = law.omega
    else:
        if omega_h is None:
            solve(0.0)
            omega_h = math.pi / out[_IK.R_TAU]
        omega = self_consistent_omega(omega_h, lambda w: (solve(w), out[_IK.R_TAU])[1], v, m)
    mod = solve(omega)
    return law._onset_dict(omega, mod, v, m, float(out[_IK.R_XMAX]))


class KernelOnsetMSFLaw(MSFLaw):
    """An MSFLaw whose engines' onset (:meth:`MSFLaw._onset_one_engine`, the
    laws with no dimensionless table: an elliptic contact's msf k_p, a
    frequency-dependent material) integrates each collision compiled
    (:func:`kernel_onset_one` with the kernel's constants of the law,
    engines._contacts.compiled.kernel_law); everything else is the law's.
    :meth:`onset_reference` keeps the Python integration. LawBank gives the
    laws it builds for a contact's curvature this onset (the pybullet duck:
    0.47 s per onset in Python, each a law of its own hull vertex's fit)."""

    @classmethod
    def of(cls, law: MSFLaw, code: int, lc) -> "KernelOnsetMSFLaw":
        """The same law (its state copied) with the compiled onset, code and
        constants lc (NLC,) its engines._kernel ones
        (engines._contacts.compiled.kernel_law); ``law`` itself unchanged."""
        new = object.__new__(cls)
        new.__dict__.update(law.__dict__)
        new._kernel_constants = (int(code), np.array(lc, dtype=float))
        return new

    def _onset_one_engine(self, v: float, m: float) -> dict:
        if self.omega == "paper":
            return self.onset_one(v, m)
        code, lc = self._kernel_constants
        return kernel_onset_one(self, code, lc, v, m,
                                math.pi / float(cf.hertz_tau(m, v, self.moduli.E, self.geom.R)))


class SideEndLaw(MSFLaw):
    """The MSF line law of a capsule's or cylinder's side on a plane, carried
    by its two ends (an extension of the paper, docs/theory.md 2a and
    docs/engines.md): each end is one contact at its own approach x, and
    this law is one end's share.

    The line law (37) with a footprint (``SideFootprint``) is
    F_n = W (2 eta'_E x' + 2/3 E' x) with W = (a + b)/2, a the contact's
    width, b its length. One end's share, at its own x and the side's
    current tilt theta:

        W_end = (w a + rho0 + max(rho0, l)) / 2,   w = 1 - l / L,

    where a = 2 sqrt(x (2 R_w - x)) is the width at the end's lowest point
    (R_w the side's radius R; a cylinder's rim torus at that point:
    (R - e + e cos theta) / cos theta), rho0 = sqrt(x (2 e - x)) the end
    arc's half chord (e the end's radius: a capsule's R, a cylinder's edge
    radius), L the side's straight length and l in [0, L/2] the length of
    the end's half of the side that is below the plane: the side's bottom
    line at s from the end (toward the middle) has the approach
    x - e (1 - cos theta) - s rise (rise = sin theta, positive when this end
    is the lower). Three properties make it the line law split over the
    ends: lying flat (l = L/2 at both ends) the two shares add up to the
    footprint's W = (a + L + 2 rho0)/2 at the common x, so a side falling
    flat is the line law with the whole mass (its ends are solved together,
    issue 10's islands); an end whose half of the side does not touch
    (l = 0) is that end's point contact, W = (a + 2 rho0)/2 = the sphere's
    or the rim torus' (13) with the msf k_p of (15); and it is continuous in
    x and theta in between. Not the single-footprint law at intermediate
    tilts: there each end carries its half at its own approach (two
    springs, a pitch stiffness (L/2)^2 per end where a distributed line has
    L^2/12 for the whole). The tilt and rise are the body's at each step
    (:meth:`set_pose`; frozen within a step as the engines' normals are);
    the onset constants are those of the pose at the contact's onset. The
    compiled kernel has it as CODE_SIDE (engines._kernel.forces, with the
    pose's constants: engines._contacts.compiled.kernel_law, refreshed after
    each set_pose by ContactManager.refresh_law), equal to these methods
    (tests/test_island_kernel.py); :meth:`psi` is the sphere of the side's
    radius, the bound the manager's onset-speed floor takes."""

    def __init__(self, template: MSFLaw, radius: float, end_radius: float, length: float, rounded: bool):
        if not isinstance(template, MSFLaw) or template.kp_mode != "msf" or template.omega == "paper":
            raise ValueError(f"a line contact has only the msf law with kp_mode 'msf' and omega not 'paper' "
                             f"(docs/theory.md 2a); the pair's law is {template.name!r} with kp_mode "
                             f"{template.kp_mode!r}")
        fp = SideFootprint(radius, length, 0.0, "rounded" if rounded else "sphere",
                           end_radius if rounded else None)
        super().__init__(template.pair, Curvature.side_on_plane(fp), omega=template.omega, kp_mode="msf",
                         separation=template.separation, mu=template.mu, temperature=template.temperature,
                         strict=template.strict)
        self.end_radius, self.length, self.rounded = float(end_radius), float(length), bool(rounded)
        self.tilt, self.rise = 0.0, 0.0
        self.mass_factor = 1.0

    def set_pose(self, tilt: float, rise: float, w_own: float = 0.0, w_other: float = 0.0,
                 dx_other: float = 0.0) -> None:
        """The side's tilt [rad] and this end's rise (sin, signed) from now
        on, and the onset mass: n.W.n [1/kg] of this end (w_own) and between
        the ends (w_other), dx_other [m] the other end's approach minus this
        one's (see :meth:`onset`)."""
        self.tilt, self.rise = float(tilt), float(rise)
        self.mass_factor = 1.0
        if w_own > 0.0:
            x_e = self._expected_depth(1.0 / w_own)
            mine = self._width_one(x_e)
            other = self._mirror_width(x_e + dx_other)
            beta = min(other / mine, 1.0) if mine > 0.0 else 0.0
            if w_own + beta * w_other > 0.0:
                self.mass_factor = w_own / (w_own + beta * w_other)

    def _expected_depth(self, m: float) -> float:
        """A scale of the approach this side's contact reaches [m]: the elastic
        x_max of the whole side at 1 m/s, W = L/2 (the ends' widths
        neglected): 1/2 m v^2 = 1/3 E' L x^2 (only the onset mass's blend
        uses it, to stay continuous in tilt)."""
        return math.sqrt(1.5 * m / (self.moduli.E * self.length))

    def _mirror_width(self, x: float) -> float:
        """The other end's share W [m] at its approach x: the same law with the rise reversed."""
        self.rise = -self.rise
        try:
            return self._width_one(x)
        finally:
            self.rise = -self.rise

    def fill_kernel_constants(self, lc: np.ndarray) -> None:
        """Write the LC_S* constants of engines._kernel (CODE_SIDE) of the
        current pose into lc (NLC,): the width radius R_w [m], the end
        radius e [m], L [m], e (1 - cos tilt) [m], the rise [-]
        (:meth:`_width_one`'s constants)."""
        e, c = self.end_radius, math.cos(self.tilt)
        lc[_K.LC_SRW] = (self.geom.R_a - e + e * c) / c if self.rounded else self.geom.R_a
        lc[_K.LC_SE], lc[_K.LC_SL], lc[_K.LC_SDROP], lc[_K.LC_SRISE] = e, self.length, e * (1.0 - c), self.rise

    def onset(self, v_n0, mass):
        """MSFLaw.onset with the end's onset mass m / (1 + beta W_ij / W_ii):
        the self-consistent omega_x of (46) is that of the collision the end
        takes part in. beta, the other end's share of the force against this
        one's at the expected depth (0: this end alone, its own mass; 1: the
        side lying flat, both ends alike: m/2 each of the body's m, so a side
        falling flat has the line law's constants with the whole mass), is
        set with the pose (:meth:`set_pose`)."""
        return super().onset(v_n0, np.asarray(mass, dtype=float) * self.mass_factor)

    def onset_reference(self, v_n0, mass):
        """:meth:`onset` by the Python integration (msf_contact._normal.integrate_normal, MSFLaw.onset_one)."""
        return super().onset_reference(v_n0, np.asarray(mass, dtype=float) * self.mass_factor)

    def _onset_one_engine(self, v: float, m: float) -> dict:
        """MSFLaw.onset_one with each collision integrated by the compiled
        twin of its integration (engines._impact_kernel.impact: the same
        DOP853 steps, ~2,000x cheaper than the Python one on a lying
        cylinder's end); the self-consistent root as MSFLaw's
        (msf_contact.laws.self_consistent_omega): :func:`kernel_onset_one`."""
        lc = np.zeros(_K.NLC)  # what engines._kernel.forces' CODE_SIDE needs of the normal force
        lc[_K.LC_FZ] = 1.0 if self.separation == "force-zero" else 0.0
        self.fill_kernel_constants(lc)
        return kernel_onset_one(self, _K.CODE_SIDE, lc, v, m)

    def _parts(self, x):
        """(w a, b) [m] of this end at the approach x [m] (n,) (see the class)."""
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        R, e, L, th = self.geom.R_a, self.end_radius, self.length, self.tilt
        R_w = (R - e + e * math.cos(th)) / math.cos(th) if self.rounded else R
        a = 2.0 * np.sqrt(np.maximum(x * (2.0 * R_w - x), 0.0))
        rho0 = np.sqrt(np.maximum(x * (2.0 * e - x), 0.0))
        d = x - e * (1.0 - math.cos(th))  # the bottom line's approach at the end
        half = 0.5 * L
        if self.rise > 0.0:
            ell = np.clip(d / self.rise, 0.0, half)
        elif self.rise < 0.0:
            ell = half - np.clip(d / self.rise, 0.0, half)  # the end's half descends toward the middle
        else:
            ell = np.where(d > 0.0, half, 0.0)
        ell = np.where(x > 0.0, ell, 0.0)  # an end not touching carries nothing of its half
        return (1.0 - ell / L) * a, rho0 + np.maximum(rho0, ell)

    def width(self, x):
        """W_end [m] (n,) of the class docstring."""
        x = np.asarray(x, dtype=float)
        if x.size == 1:  # the reference impact's integrator asks one value at a time
            return np.full(x.shape, self._width_one(float(x.reshape(-1)[0])))
        wa, b = self._parts(x)
        return 0.5 * (wa + b)

    def _width_one(self, x: float) -> float:
        """:meth:`width` of one approach, in scalar arithmetic (the same formulas as :meth:`_parts`)."""
        if x <= 0.0:
            return 0.0
        R, e, L, th = self.geom.R_a, self.end_radius, self.length, self.tilt
        R_w = (R - e + e * math.cos(th)) / math.cos(th) if self.rounded else R
        a = 2.0 * math.sqrt(max(x * (2.0 * R_w - x), 0.0))
        rho0 = math.sqrt(max(x * (2.0 * e - x), 0.0))
        d, half = x - e * (1.0 - math.cos(th)), 0.5 * L
        if self.rise > 0.0:
            ell = min(max(d / self.rise, 0.0), half)
        elif self.rise < 0.0:
            ell = half - min(max(d / self.rise, 0.0), half)
        else:
            ell = half if d > 0.0 else 0.0
        return 0.5 * ((1.0 - ell / L) * a + rho0 + max(rho0, ell))

    def hertz_scale(self, v_n0, mass):
        """A length of the order of the elastic x_max, never above it [m] (n,)
        (the reference impact's tolerances): the smaller of the whole side
        lying flat (W >= L/2: 1/2 m v^2 <= 1/3 E' L x^2) and the end alone
        (Hertz for the end's sphere or rim point, sqrt(e R_w))."""
        v, m = np.asarray(v_n0, dtype=float), np.asarray(mass, dtype=float)
        E = self.moduli.E
        R_w = self.geom.R_a
        if self.rounded:
            R_w = (R_w - self.end_radius + self.end_radius * math.cos(self.tilt)) / math.cos(self.tilt)
        x_line = np.sqrt(3.0 * m * v * v / (E * self.length))
        return np.minimum(x_line, cf.hertz_x_max(m, v, E, math.sqrt(self.end_radius * R_w)))

    def shear_lengths(self, x):
        """(36) with this end's axes: (P_bx, P_ax) = (k_ha x + b, k_hb x + w a) [m] (n,)."""
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        wa, b = self._parts(x)
        return self.geom.k_ha * x + b, self.geom.k_hb * x + wa

    def psi(self, x):
        """The sphere of the side's radius: 2 k_p sqrt(R) [m^1/2] (n,) (see the class)."""
        R = self.geom.R_a
        return 2.0 * self.kp(x, R) * math.sqrt(R)


class SideLine:
    """The line contact of one capsule's or cylinder's side against a plane,
    as both adapters carry it (a narrow geom pair; its slots 0 and 1 the
    side's ends, :class:`SideEndLaw` each): the mode, the two ends' laws and
    the side's ends at the current pose. The engine gives the poses and the
    ends' onset masses n.W.n; everything else is here.

    shape: :class:`msf_contact.shapes.Capsule` or
    :class:`~msf_contact.shapes.Cylinder`; names: the pair's two body (geom,
    link) names for the warning."""

    def __init__(self, shape, names: tuple):
        if not isinstance(shape, (Capsule, Cylinder)):
            raise ValueError(f"a line contact needs a capsule or a cylinder, not {type(shape).__name__}")
        self.shape, self.names = shape, tuple(names)
        #: "line" (the ends carry SideEndLaw) or "point" (the engine's end points, their point laws)
        self.mode = "point"
        #: the two ends' SideEndLaw; None: not built yet; False: the pair's law cannot carry a line
        self.law = None
        self.ends: SideEnds | None = None
        self._hold = np.zeros(2, bool)  # the ends whose pose stays (update's moving)

    def update(self, pos, rot, plane_pos, plane_normal, busy, template, moving=None, ends=None) -> bool:
        """The side's ends at the shape's pose (``pos`` [m] (3,), ``rot`` (3, 3))
        against the plane (``plane_pos`` [m] (3,), unit ``plane_normal`` (3,))
        and the mode: a contact in progress (any of the pair's slots ``busy``
        (n,) bool) keeps it (its law holds at any tilt: above LINE_TILT_MAX an
        end's line law is its point law); between contacts, the line below
        LINE_TILT_MAX. The ends' laws are built from the pair's law
        ``template`` on the first line; one that cannot carry a line (not msf
        with kp_mode 'msf') leaves the pair on the points, warned once.
        ``moving`` (n,) bool: the slots in contact and not settled (the
        manager's active and not settled): their ends keep their pose
        (:meth:`slots`); None: none. Returns True when the mode changed (the
        slots start afresh)."""
        # ends: side_ends at this pose if computed already (side_ends_many, the adapters' lying sides at once)
        self.ends = ends = side_ends(self.shape, pos, rot, plane_pos, plane_normal) if ends is None else ends
        self._hold = np.zeros(2, bool) if moving is None else np.asarray(moving, dtype=bool)[:2].copy()
        changed = False
        if not np.asarray(busy).any() and self.law is not False:
            mode = "line" if ends.tilt < LINE_TILT_MAX else "point"
            changed, self.mode = mode != self.mode, mode
        if self.mode == "line" and self.law is None:
            s = self.shape
            if isinstance(s, Cylinder):
                args = (s.radius, s.edge_radius, 2.0 * (s.half_length - s.edge_radius), True)
            else:
                args = (s.radius, s.radius, 2.0 * s.half_length, False)
            try:
                self.law = [SideEndLaw(template, *args) for _ in range(2)]
            except ValueError as exc:
                self.law, self.mode, changed = False, "point", False
                warnings.warn(f"pair ({self.names[0]!r}, {self.names[1]!r}): its side lies on the plane (tilt "
                              f"{math.degrees(ends.tilt):.3g} deg) but {exc}: its end points carry the contact "
                              "with their point laws instead (the straight side between them carries nothing)",
                              RuntimeWarning, stacklevel=3)
        return changed

    def slots(self, nWn, n_slots: int, refresh) -> list:
        """Slots 0 and 1 as the side's two ends, (x [m], point [m] (3,) midway
        between the surfaces, normal (3,)) each, the other slots None; each
        end's law takes the current pose (:meth:`SideEndLaw.set_pose`) and its
        onset mass from ``nWn`` (2, 2) [1/kg], n.W.n between the ends' lowest
        points (W the relative motion's inverse inertia along the plane's
        normal), except an end in a contact that has not settled (``moving``
        of :meth:`update`), which keeps its pose until the contact settles or
        ends. Why: an end's share W_end depends on the tilt, and the tilt on
        both ends' approaches (a capsule: sin tilt = (x0 - x1)/L), so with the
        pose following the body the ends' forces are no gradient of an
        energy of (x0, x1) (dF_0/dx_1 != dF_1/dx_0): a capsule dropped tilted
        0.8-1 deg turned flatter while its lower end was in contact, and that
        end pushed out harder than it was pushed in (an island step +2.24 mJ
        at 1 deg, MuJoCo and pybullet alike; docs/engines.md). Within a
        contact each end's law is then a function of its own approach alone.
        A settled contact follows the pose (a body at rest hardly turns;
        frozen there too, a capsule come to rest from 2 deg kept an end's
        share of 0.025 deg and rested 6.3 um deep at that end, 1.9 um at the
        other; a pose frozen at every onset had left the objects scenario's
        resting cylinder with a 3.4 mJ gain). ``refresh(law, before)`` is
        called after each change with the law as it was (the manager's
        ContactManager.refresh_law: the compiled constants follow, and a
        contact in progress keeps its elastic energy across the change, its
        approach moving instead: the pose taken up when Hopper-v5's foot
        settled raised an end's force at a fixed approach from 249 to 754 N,
        0.33 J no force worked for, before)."""
        ends = self.ends
        per = [None] * n_slots
        for i in range(2):
            if self._hold[i]:  # in a contact that has not settled: its pose stays
                x = float(ends.x[i])
                per[i] = (x, ends.lowest[i] + 0.5 * x * ends.normal, ends.normal.copy())
                continue
            before = copy.copy(self.law[i])  # the contact in progress keeps its energy (refresh_law)
            self.law[i].set_pose(ends.tilt, float(ends.rise[i]), float(nWn[i, i]), float(nWn[i, 1 - i]),
                                 float(ends.x[1 - i] - ends.x[i]))
            refresh(self.law[i], before)
            x = float(ends.x[i])
            per[i] = (x, ends.lowest[i] + 0.5 * x * ends.normal, ends.normal.copy())
        return per


# ------------------------------------------------------ cylinder on its end ---
#: The slots of a cylinder's rim ring (:class:`RimRing`) are placed anew
#: (slot 0 at the rim's lowest point) only between contacts, and only while
#: the ring's depth variation around it, 2 (R - rho) sin(tilt), is above this
#: share of the edge radius rho. Standing flat the lowest direction is
#: undefined (it turns at random with the last 1e-9 rad of tilt): slots that
#: followed it would jump around the rim; below the share the whole ring
#: lies within 1e-3 rho (1 um for the default 1 mm) of one height, so where
#: the slots sit changes no approach by more than that.
RING_FOLLOW_SHARE = 1e-3


class RimArcLaw(SideEndLaw):
    """One slot's share of the MSF line law of a cylinder's rim ring on a
    plane (an extension of the paper, docs/theory.md 2a and docs/engines.md):
    a cylinder of radius R on its end face touches with its rim, the torus
    of tube radius rho (the edge radius) around the circle of radius
    R_c = R - rho, a ring-shaped line contact of length 2 pi R_c and width
    2 rho0, rho0 = sqrt(x (2 rho - x)) the tube's half chord (the flat face
    inside it is a flat punch, which carries nothing here, as a box's face).
    The ring is carried by N slots (:class:`RimRing`), slot k at the angle
    psi_k from the rim's lowest point, each carrying the arc of its sector
    [psi_k - pi/N, psi_k + pi/N] that is below the plane, at its own
    approach x (as a lying side's end carries its half, SideEndLaw):

        F_n = W (2 eta'_E x' + 2/3 E' x),   W = (2 rho0 + Q A) / 2,

    A the angle of the sector within [-phi0, phi0] (the ring taken
    periodic), phi0 the half-angle of the ring below the plane: the ring's
    bottom at phi from the lowest point is c (1 - cos phi) above it,
    c = Q sin(tilt), Q = R_c + rho sin(tilt) the radius of the rim's bottom
    (tilt: the axis from the plane's normal), so with the lowest point at
    x0 = x + c (1 - cos psi_k), cos phi0 = 1 - x0/c (phi0 = pi for x0 >= 2c).
    Three properties: standing flat (c = 0) every slot carries its whole
    sector, W = (2 rho0 + 2 pi R_c / N)/2, the line law of
    ``SideFootprint(rho, 2 pi R_c / N, caps="flat")``, so the ring is N
    such arcs, each with m/N (the onset mass, :meth:`RimRing.slots`);
    tilted, the lowest slot carries the arc 2 Q phi0 ~ 2 sqrt(2 x R_w)
    with R_w = Q / sin(tilt) = (R - rho + rho sin(tilt)) / sin(tilt), the
    rim torus' radius along the rim at that point, i.e. the rim torus'
    point contact (13) with the msf k_p of (15) (its chord 2 sqrt(x (2 R_w -
    x))) to O(phi0^2 / 6) (the arc against the chord); and W is continuous
    in x and the tilt (a slot's W jumps at its own x = 0 only: the elastic
    force W x is continuous there, the viscous term is the line law's touch-
    down force, as every linear line law has). At x = 0 W is its right limit
    (x <= 0 read as 0+; the law is evaluated only for a contact in progress):
    the sub-cycle's first RK4 stage at an onset reads the law at x = 0, and
    with W(0) = 0 it missed the touch-down force 2 eta'_E x' W(0+) for that
    stage, first order in the internal step (the flat ring's COR +6.0e-4
    against the reference solver at 1 ms, tests/test_cylinder_on_plane.py).
    The compiled kernel has it as
    CODE_SIDE with lc[LC_SRING] set (engines._kernel._ring_parts), equal to
    these methods (tests/test_island_kernel.py). The pose (tilt, psi_k) is
    the body's at each step except in a contact that has not settled
    (SideEndLaw's reason: :meth:`SideLine.slots`)."""

    def __init__(self, template: MSFLaw, radius: float, edge_radius: float, n_slots: int):
        if not isinstance(template, MSFLaw) or template.kp_mode != "msf" or template.omega == "paper":
            raise ValueError(f"a line contact has only the msf law with kp_mode 'msf' and omega not 'paper' "
                             f"(docs/theory.md 2a); the pair's law is {template.name!r} with kp_mode "
                             f"{template.kp_mode!r}")
        if int(n_slots) != n_slots or n_slots < 3:
            raise ValueError(f"n_slots = {n_slots!r} must be a whole number >= 3 (a ring on fewer points tips)")
        self.ring_radius = float(radius) - float(edge_radius)
        self.half_angle = math.pi / int(n_slots)
        fp = SideFootprint(float(edge_radius), 2.0 * self.half_angle * self.ring_radius, 0.0, "flat")
        MSFLaw.__init__(self, template.pair, Curvature.side_on_plane(fp), omega=template.omega, kp_mode="msf",
                        separation=template.separation, mu=template.mu, temperature=template.temperature,
                        strict=template.strict)
        self.end_radius, self.length, self.rounded = float(edge_radius), fp.length, False
        self.tilt, self.rise, self.offset = 0.0, 0.0, 0.0
        self.mass_factor = 1.0

    def set_ring_pose(self, tilt: float, offset: float) -> None:
        """The cylinder's tilt [rad] (its axis from the plane's normal) and this
        slot's angle from the rim's lowest point [rad] (any sign; folded to [0, pi])."""
        self.tilt = float(tilt)
        self.offset = abs(math.remainder(float(offset), 2.0 * math.pi))

    def _ring(self) -> tuple[float, float]:
        """(Q, c) [m] at the current pose (the class docstring)."""
        s = math.sin(self.tilt)
        q = self.ring_radius + self.end_radius * s
        return q, q * s

    def fill_kernel_constants(self, lc: np.ndarray) -> None:
        """Write engines._kernel's ring constants (CODE_SIDE with LC_SRING) of the current pose into lc (NLC,)."""
        q, c = self._ring()
        lc[_K.LC_SRING] = 1.0
        lc[_K.LC_SRW], lc[_K.LC_SE], lc[_K.LC_SL], lc[_K.LC_SDROP], lc[_K.LC_SRISE] = (
            q, self.end_radius, self.half_angle, c, self.offset)

    def _parts(self, x):
        """(2 rho0, Q A) [m] (n,) at the approach x [m] (n,) (the class docstring)."""
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        q, c = self._ring()
        e, h, psi = self.end_radius, self.half_angle, self.offset
        rho0 = np.sqrt(np.maximum(x * (2.0 * e - x), 0.0))
        x0 = x + c * (1.0 - math.cos(psi))
        if c <= 0.0:
            phi0 = np.full(x.shape, math.pi)
        else:
            phi0 = np.where(x0 >= 2.0 * c, math.pi, np.arccos(np.clip(1.0 - x0 / c, -1.0, 1.0)))
        lo, hi, tp = psi - h, psi + h, 2.0 * math.pi
        ang = sum(np.maximum(0.0, np.minimum(hi, k * tp + phi0) - np.maximum(lo, k * tp - phi0)) for k in (-1, 0, 1))
        return 2.0 * rho0, q * ang

    def _width_one(self, x: float) -> float:
        """W [m] of one approach, in scalar arithmetic (engines._kernel._ring_parts' formulas)."""
        x = max(x, 0.0)
        q, c = self._ring()
        e, h, psi = self.end_radius, self.half_angle, self.offset
        rho0 = math.sqrt(max(x * (2.0 * e - x), 0.0))
        x0 = x + c * (1.0 - math.cos(psi))
        phi0 = math.pi if (c <= 0.0 or x0 >= 2.0 * c) else math.acos(1.0 - x0 / c)
        tp = 2.0 * math.pi
        ang = sum(max(0.0, min(psi + h, k * tp + phi0) - max(psi - h, k * tp - phi0)) for k in (-1, 0, 1))
        return 0.5 * (2.0 * rho0 + q * ang)

    def hertz_scale(self, v_n0, mass):
        """A length of the order of the elastic x_max, never above it [m] (n,):
        the smaller of the slot's whole sector touching (W >= S/2, S the
        sector's length: 1/2 m v^2 <= 1/3 E' S x^2) and the lowest point
        alone (Hertz for the rim torus' point, sqrt(rho R_w))."""
        v, m = np.asarray(v_n0, dtype=float), np.asarray(mass, dtype=float)
        E = self.moduli.E
        x_line = np.sqrt(3.0 * m * v * v / (E * self.length))
        s = math.sin(self.tilt)
        if s <= 0.0:
            return x_line
        q, _ = self._ring()
        return np.minimum(x_line, cf.hertz_x_max(m, v, E, math.sqrt(self.end_radius * q / s)))


@dataclass(frozen=True)
class RimPoints:
    """Points of a cylinder's rim against a plane (world frame): x [m] (k,)
    the approach of the rim's bottom in each slot's meridian (negative: a
    gap), lowest [m] (k, 3) those points, tilt [rad] of the axis from the
    plane's unit normal ``normal`` (3,) (toward the body), lowest_angle
    [rad] the angle about the axis, from the geom's x, of the direction in
    which the rim is lowest (nan standing exactly flat)."""

    x: np.ndarray
    lowest: np.ndarray
    tilt: float
    lowest_angle: float
    normal: np.ndarray


def rim_points(shape: Cylinder, pos, rot, plane_pos, plane_normal, angles) -> RimPoints:
    """:class:`RimPoints` of ``shape`` (:class:`msf_contact.shapes.Cylinder`,
    frame at ``pos`` [m] (3,), ``rot`` (3, 3), axis along its z) against the
    plane through ``plane_pos`` [m] (3,) with unit normal ``plane_normal``
    (3,), at the rim angles ``angles`` [rad] (k,) about the axis from the
    geom's x. The rim is the torus of the end toward the plane: its tube
    circle of radius rho in the meridian at angle phi is centred R - rho
    from the axis, half_length - rho from the middle; its lowest point lies
    on the rim's quarter arc between the end face and the side (at the
    face's edge where the face, tilted away, is lower)."""
    n = np.asarray(plane_normal, dtype=float)
    rot = np.asarray(rot, dtype=float).reshape(3, 3)
    xg, yg, z = rot[:, 0], rot[:, 1], rot[:, 2]
    zn = float(z @ n)
    a = -z if zn > 0.0 else z  # the end toward the plane: its outward axis
    radial = -(n - zn * z)  # across the axis, toward the plane: |radial| = sin(tilt)
    s = float(np.linalg.norm(radial))
    low = math.atan2(float(radial @ yg), float(radial @ xg)) if s > 0.0 else math.nan
    rho, rc = shape.edge_radius, shape.radius - shape.edge_radius
    ang = np.asarray(angles, dtype=float).reshape(-1)
    r = np.cos(ang)[:, None] * xg[None, :] + np.sin(ang)[:, None] * yg[None, :]
    centres = np.asarray(pos, dtype=float)[None, :] + (shape.half_length - rho) * a[None, :] + rc * r
    beta = np.clip(np.arctan2(-(r @ n), -float(n @ a)), 0.0, 0.5 * math.pi)
    lowest = centres + rho * (np.cos(beta)[:, None] * a[None, :] + np.sin(beta)[:, None] * r)
    x = -((lowest - np.asarray(plane_pos, dtype=float)) @ n)
    return RimPoints(x, lowest, math.asin(min(s, 1.0)), low, n.copy())


def _blended_mass_factors(laws, slots, x, nWn) -> None:
    """Set each law's onset mass_factor m / (sum_j beta_j n.W_ij.n / n.W_ii.n)
    for the slots ``slots`` (their laws ``laws[s]``), beta_j the share of slot
    j's force against slot s's at the expected depth (SideEndLaw.set_pose's
    beta, over every slot with a law): slots falling together in one
    collision share the mass by their forces. x [m] (n,) the slots'
    approaches; nWn (n, n) [1/kg] between their points."""
    for s in slots:
        law, w_own = laws[s], float(nWn[s, s])
        if w_own <= 0.0:
            continue
        x_e = law._expected_depth(1.0 / w_own)
        mine = law._width_one(x_e)
        total = w_own
        for j in range(len(laws)):
            if j != s and laws[j] is not None:
                beta = min(laws[j]._width_one(x_e + float(x[j] - x[s])) / mine, 1.0) if mine > 0.0 else 0.0
                total += beta * float(nWn[s, j])
        law.mass_factor = w_own / total if total > 0.0 else 1.0


class RimRing:
    """A cylinder's rim ring on a plane, as both adapters carry it (through
    :class:`CylinderOnPlane`): N slots (the pair's, 4) at material angles
    about the axis, slot k at 2 pi k / N from the rim's lowest point when it
    is placed, each carrying :class:`RimArcLaw` at its meridian's rim
    bottom (:func:`rim_points`). A slot in a moving contact (active, not
    settled) keeps its angle and its law's pose; the others follow the
    lowest point (above RING_FOLLOW_SHARE) and the tilt. Standing flat the N
    slots carry the ring's N arcs; tilted, the lowest slot the rim torus'
    point contact; and the force is continuous in between. With N >= 3
    equally spaced slots the ring's stiffness against tilting is the
    continuous ring's (sum_k cos^2(phi_k) = N/2), where a lying side's two
    ends carry three times a line's.

    shape: :class:`msf_contact.shapes.Cylinder`; n_slots: the pair's slots."""

    def __init__(self, shape: Cylinder, n_slots: int = 4):
        if not isinstance(shape, Cylinder):
            raise ValueError(f"a rim ring needs a msf_contact.shapes.Cylinder, not {type(shape).__name__}")
        if int(n_slots) != n_slots or n_slots < 3:
            raise ValueError(f"n_slots = {n_slots!r} must be a whole number >= 3 (a ring on fewer points tips)")
        self.shape, self.n = shape, int(n_slots)
        #: each slot's material angle about the axis, from the geom's x [rad] (n,)
        self.angle = 2.0 * math.pi * np.arange(self.n) / self.n
        self._base = 0.0  # the angle slot 0 is placed at
        #: the slots' RimArcLaw; None: not built yet; False: the pair's law cannot carry a line
        self.law = None
        self.rim: RimPoints | None = None
        self._free = np.ones(self.n, bool)

    def build(self, template) -> None:
        """The slots' laws from the pair's law ``template`` (ValueError if it cannot carry a line)."""
        s = self.shape
        self.law = [RimArcLaw(template, s.radius, s.edge_radius, self.n) for _ in range(self.n)]

    def update(self, pos, rot, plane_pos, plane_normal, moving, busy) -> np.ndarray:
        """The rim's slots at the cylinder's pose (``pos`` [m] (3,), ``rot``
        (3, 3)) against the plane (``plane_pos`` [m] (3,), unit
        ``plane_normal`` (3,)); ``moving`` (n,) bool: the slots in a contact
        that has not settled (their laws keep their pose); ``busy`` (n,)
        bool: the slots in contact or with a correction pending (while any
        is, every slot keeps its material point). Returns (n,) bool: the
        slots whose material point changed (their finite differences compare
        two material points)."""
        self._free = ~np.asarray(moving, dtype=bool)[:self.n]
        probe = rim_points(self.shape, pos, rot, plane_pos, plane_normal, self.angle[:0])
        follow = 2.0 * (self.shape.radius - self.shape.edge_radius) * math.sin(probe.tilt)
        old = self.angle.copy()
        if (not np.any(np.asarray(busy, dtype=bool)[:self.n]) and math.isfinite(probe.lowest_angle)
                and follow > RING_FOLLOW_SHARE * self.shape.edge_radius):
            self._base = probe.lowest_angle
            self.angle = self._base + 2.0 * math.pi * np.arange(self.n) / self.n
        self.rim = rim_points(self.shape, pos, rot, plane_pos, plane_normal, self.angle)
        return self.angle != old

    def points(self) -> np.ndarray:
        """The slots' rim points [m] (n, 3)."""
        return self.rim.lowest

    def slots(self, nWn, refresh) -> list:
        """Per slot (x [m], point [m] (3,) midway between the surfaces, normal
        (3,)). Each slot not in a moving contact takes the current pose
        (RimArcLaw.set_ring_pose) and its onset mass from ``nWn`` (n, n)
        [1/kg] between the slots' points (:func:`_blended_mass_factors`:
        standing flat, m/N each); ``refresh(law, before)`` after each change
        (ContactManager.refresh_law: a settled slot keeps its elastic energy)."""
        r = self.rim
        per = [(float(r.x[s]), r.lowest[s] + 0.5 * float(r.x[s]) * r.normal, r.normal.copy()) for s in range(self.n)]
        posed = [s for s in range(self.n) if self._free[s]]
        before = {s: copy.copy(self.law[s]) for s in posed}
        low = r.lowest_angle if math.isfinite(r.lowest_angle) else self._base
        for s in posed:
            self.law[s].set_ring_pose(r.tilt, float(self.angle[s]) - low)
        _blended_mass_factors(self.law, posed, r.x, np.asarray(nWn, dtype=float))
        for s in posed:
            refresh(self.law[s], before[s])
        return per


class CylinderOnPlane(SideLine):
    """A cylinder on a plane, as both adapters carry it (a narrow geom pair;
    its N slots): lying (the axis within LINE_TILT_MAX of the plane) its
    side's line law on slots 0 and 1 (:class:`SideLine`, mode "line"),
    otherwise its rim ring on all N slots (:class:`RimRing`, mode "ring"):
    standing on its end face or tilted on its rim. The mode changes between
    contacts only (SideLine.update). Above LINE_TILT_MAX the side cannot
    touch within the rim's small-strain range, so the side's end is its rim
    point, which the ring's lowest slot carries (to the arc's O(phi0^2/6)).
    A pair whose law cannot carry a line (not msf with kp_mode 'msf') stays
    on the engine's points ("point"), warned once.

    shape: :class:`msf_contact.shapes.Cylinder`; names: the pair's two body
    (geom, link) names for the warnings; n_slots: the pair's slots."""

    def __init__(self, shape: Cylinder, names: tuple, n_slots: int = 4):
        super().__init__(shape, names)
        if not isinstance(shape, Cylinder):
            raise ValueError(f"CylinderOnPlane needs a msf_contact.shapes.Cylinder, not {type(shape).__name__}")
        self.ring = RimRing(shape, n_slots)
        #: (n,) bool: the ring's slots whose material point changed at the last update (RimRing.update)
        self.moved = np.zeros(self.ring.n, bool)

    def update(self, pos, rot, plane_pos, plane_normal, busy, template, moving=None) -> bool:
        """SideLine.update, with the rim ring in place of the engine's points
        (mode "ring"); ``moving`` (n,) bool as there. Returns True when the
        mode changed (the slots start afresh)."""
        was = self.mode
        if was == "ring":
            self.mode = "point"
        super().update(pos, rot, plane_pos, plane_normal, busy, template, moving)
        if self.mode == "point" and self.ring.law is None:
            try:
                self.ring.build(template)
            except ValueError as exc:
                self.ring.law = False
                warnings.warn(f"pair ({self.names[0]!r}, {self.names[1]!r}): a cylinder on its end carries its rim "
                              f"ring with the msf line law, but {exc}: the engine's points carry the contact with "
                              "their point laws instead (standing flat: a stand-in, flagged)", RuntimeWarning,
                              stacklevel=3)
        self.moved = np.zeros(self.ring.n, bool)
        if self.mode == "point" and self.ring.law:
            self.mode = "ring"
            self.moved = self.ring.update(pos, rot, plane_pos, plane_normal,
                                          np.zeros(self.ring.n, bool) if moving is None else moving, busy)
        return self.mode != was

    def ring_slots(self, nWn, refresh) -> list:
        """The N slots as the rim ring's (RimRing.slots)."""
        return self.ring.slots(nWn, refresh)


# ------------------------------------------------------------- box on plane ---
#: A box's 8 corners as signs of its half-extents (3,) each, (8, 3).
BOX_CORNERS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)


@dataclass(frozen=True)
class BoxCorners:
    """The corners of a rounded box against a plane (world frame): x [m]
    (8,) each corner sphere's approach (negative: a gap); lowest [m] (8, 3)
    their lowest points; dots (3,) the box axes' components along the
    plane's unit normal (toward the body) ``normal`` (3,)."""

    x: np.ndarray
    lowest: np.ndarray
    dots: np.ndarray
    normal: np.ndarray


def box_corners(shape: Box, pos, rot, plane_pos, plane_normal) -> BoxCorners:
    """:class:`BoxCorners` of ``shape`` (:class:`msf_contact.shapes.Box`,
    frame at ``pos`` [m] (3,), ``rot`` (3, 3)) against the plane through
    ``plane_pos`` [m] (3,) with unit normal ``plane_normal`` (3,): the
    rounded box is the Minkowski sum of the box of half-extents h - rho and
    the sphere of the edge radius rho, so each corner is that sphere centred
    at the inner box's corner, and the box's faces are where the sharp
    box's are (a face lying flat is at the same height as the engine's)."""
    n = np.asarray(plane_normal, dtype=float)
    rot = np.asarray(rot, dtype=float).reshape(3, 3)
    inner = np.asarray(shape.half_extents, dtype=float) - shape.edge_radius
    centres = np.asarray(pos, dtype=float)[None, :] + (BOX_CORNERS * inner) @ rot.T
    lowest = centres - shape.edge_radius * n
    x = -((lowest - np.asarray(plane_pos, dtype=float)) @ n)
    return BoxCorners(x, lowest, rot.T @ n, n.copy())


def face_toward(half_extents, pos, rot, point) -> tuple[np.ndarray, np.ndarray]:
    """The face of a box (``half_extents`` [m] (3,), frame at ``pos`` [m]
    (3,), ``rot`` (3, 3)) that ``point`` [m] (3,) lies furthest outside of,
    as a plane: (a point on it [m] (3,), its outward unit normal (3,)). A
    fixed box the other body rests on (pybullet's ``plane.urdf`` is a box
    200 x 200 x 10 m) acts through its top face; its own edges are not
    seen (a box over the edge of a fixed box is carried as if the face went
    on)."""
    rot = np.asarray(rot, dtype=float).reshape(3, 3)
    h = np.asarray(half_extents, dtype=float)
    d = rot.T @ (np.asarray(point, dtype=float) - np.asarray(pos, dtype=float))
    k = int(np.argmax(np.abs(d) - h))
    n = rot[:, k] * (1.0 if d[k] >= 0.0 else -1.0)
    return np.asarray(pos, dtype=float) + h[k] * n, n


class BoxOnPlane:
    """A box with rounded edges (edge radius rho) on a plane, as both
    adapters carry it (issue 13): its slots are the box's lowest corners,
    each the end of one rounded edge, and each carries that end's share of
    the edge's line law (:class:`SideEndLaw` of a capsule of radius rho
    whose straight part is the edge's, 2 (h - rho), with the corners its end
    spheres). One law thus covers the three cases with the force continuous
    between them as the box tilts:

    - on a corner (its edges steeper than the corner's approach reaches:
      l = 0 in SideEndLaw) a slot's law is the sphere of the edge radius
      with the msf k_p of (15) exactly (the corner sphere's (13));
    - on an edge, that edge's two corners carry the line law of the rounded
      edge, a cylinder of radius rho and the edge's length (SideFootprint),
      split over its ends as a lying capsule's side is;
    - on a face, its four corners carry two parallel edges of the face (a
      flat face is a flat punch, which msf_contact has no law for: the face
      carries its contact at its rounded edges, as MuJoCo's narrow phase
      gives a face's contact at its corners). Which two: each corner's edge
      is the most level of its three, the same pair for the four corners of
      a face.

    Beyond the edge radius (x > rho(1 - cos tilt)) an end's share grows with
    the length of its edge below the plane, so a corner hit hard (a rubber
    cube from 0.3 m at 2.3 m/s) is stopped by its edge where the sphere's
    force alone vanishes at x = 2 rho (k_p of (15)); such a contact is
    beyond the small-strain model and its record is flagged.

    A slot keeps its corner, its edge and, while its contact moves (active,
    not settled), its pose (tilt, rise and onset mass: the reason is
    :meth:`SideLine.slots`'); a free slot takes the deepest corner no busy
    slot holds. The corners' geometry is the rounded box's in closed form
    (:func:`box_corners`), not the engine's points (pybullet lists one point
    for a face; MuJoCo's are the sharp corners).

    shape: :class:`msf_contact.shapes.Box`; names: the pair's two body (geom,
    link) names; n_slots: the corners managed (4: a face)."""

    def __init__(self, shape: Box, names: tuple, n_slots: int = 4):
        if not isinstance(shape, Box):
            raise ValueError(f"BoxOnPlane needs a msf_contact.shapes.Box, not {type(shape).__name__}")
        self.shape, self.names, self.n = shape, tuple(names), int(n_slots)
        h = np.asarray(shape.half_extents, dtype=float)
        #: each axis' edge: its straight part [m] (3,)
        self.lengths = 2.0 * (h - shape.edge_radius)
        #: the corner (0-7) each slot holds (-1: none) and the edge axis of its law (-1: none yet)
        self.corner = np.full(self.n, -1)
        self.axis = np.full(self.n, -1)
        #: the law of each slot's next or current contact (a SideEndLaw of its corner's edge)
        self.law: list = [None] * self.n
        self._laws: dict[tuple, SideEndLaw] = {}
        self.corners: BoxCorners | None = None
        #: whether the pair's law carries the edges' line law (check); else the corners' spheres
        self.lines = True

    def _end_law(self, slot: int, axis: int, template) -> SideEndLaw:
        key = (slot, axis)
        law = self._laws.get(key)
        if law is None:
            rho = self.shape.edge_radius
            law = self._laws[key] = SideEndLaw(template, rho, rho, max(float(self.lengths[axis]), 0.0), False)
        return law

    def check(self, template) -> None:
        """At construction: whether the pair's law ``template`` can carry the
        box's edges (the line law is the msf law with kp_mode 'msf' and omega
        not 'paper', SideEndLaw). One that cannot (a 'hertz' law, kp_mode
        'hertz') leaves the box on its corners, each the sphere of the edge
        radius with the pair's law (an edge or a face lying flat then rests
        on two or four such spheres), warned here once."""
        try:
            self._end_law(0, 0, template)
            self.lines = True
        except ValueError as exc:
            self.lines = False
            warnings.warn(f"pair ({self.names[0]!r}, {self.names[1]!r}): a box on a plane carries its contact at "
                          f"its rounded edges with the msf line law, but {exc}: its corners carry the contact as "
                          f"spheres of the edge radius {self.shape.edge_radius:g} m with the pair's law instead "
                          "(an edge or a face lying flat rests on its corners' spheres)", RuntimeWarning,
                          stacklevel=3)

    def update(self, pos, rot, plane_pos, plane_normal, busy, template, bank: "LawBank") -> np.ndarray:
        """The corners at the box's pose (``pos`` [m] (3,), ``rot`` (3, 3))
        against the plane (``plane_pos`` [m] (3,), unit ``plane_normal``
        (3,)) and each slot's corner: a busy slot (``busy`` (n,) bool: in
        contact or a correction pending) keeps its corner and edge, the
        others take the deepest corners left (a slot keeps its corner while
        it stays among them), each with the most level of its three edges
        and that edge's end law built from the pair's law ``template`` (a
        law that cannot carry a line, :meth:`check`: the sphere of the edge
        radius from ``bank``, LawBank).
        Returns (n,) bool: the slots whose corner changed (their finite
        differences compare two material points)."""
        self.corners = c = box_corners(self.shape, pos, rot, plane_pos, plane_normal)
        busy = np.asarray(busy, dtype=bool)[:self.n]
        held = set(int(k) for k in self.corner[busy] if k >= 0)
        want = [int(k) for k in np.argsort(-c.x, kind="stable") if int(k) not in held][:self.n - len(held)]
        old = self.corner.copy()
        for s in range(self.n):
            if not busy[s] and int(self.corner[s]) not in want:
                self.corner[s] = -1
        free = [s for s in range(self.n) if not busy[s] and self.corner[s] < 0]
        for k in want:
            if k not in self.corner and free:
                self.corner[free.pop(0)] = k
        level = int(np.argmin(np.abs(c.dots)))
        point = None
        for s in range(self.n):
            if not busy[s] and self.corner[s] >= 0:
                self.axis[s] = level
                if self.lines:
                    self.law[s] = self._end_law(s, level, template)
                else:
                    if point is None:
                        point = bank.law_for(template, Curvature.sphere_on_plane(self.shape.edge_radius),
                                             CURVATURE_RTOL)
                    self.law[s] = point
        return self.corner != old

    def _pose(self, s: int) -> tuple[float, float]:
        """(tilt [rad], rise [-]) of slot s's edge at the current pose."""
        k, j = int(self.corner[s]), int(self.axis[s])
        c = self.corners
        sign = BOX_CORNERS[k, j]
        rise = float(-sign * c.dots[j])  # from this corner toward the other end of its edge (+: this end lower)
        return math.asin(min(abs(rise), 1.0)), rise

    def points(self) -> np.ndarray:
        """The lowest points [m] (n, 3) of the slots' corners (a free slot: its row of corner 0)."""
        return self.corners.lowest[np.maximum(self.corner, 0)]

    def slots(self, nWn, moving, refresh) -> list:
        """Per slot (x [m], point [m] (3,) midway between the surfaces, normal
        (3,)) of its corner, None for a free slot. Each slot's law not in a
        moving contact (``moving`` (n,) bool: active and not settled) takes
        the current pose of its edge and its onset mass m / (sum_j beta_j
        n.W_ij.n / n.W_ii.n): ``nWn`` (n, n) [1/kg] between the slots'
        lowest points (:meth:`points`), beta_j the share of slot j's force
        against this one's at the expected depth (SideEndLaw.set_pose's
        beta, over every corner that can touch with it: a face falling flat
        has its four corners in one collision, each with a quarter of the
        mass by symmetry, as the line law with the whole mass needs).
        ``refresh(law, before)`` after each change with the law as it was
        (ContactManager.refresh_law: a settled corner's contact keeps its
        elastic energy across the change, as SideLine.slots' ends do)."""
        c = self.corners
        moving = np.asarray(moving, dtype=bool)[:self.n]
        per = [None] * self.n
        nWn = np.asarray(nWn, dtype=float)
        for s in range(self.n):
            k = int(self.corner[s])
            if k < 0:
                continue
            x = float(c.x[k])
            per[s] = (x, c.lowest[k] + 0.5 * x * c.normal, c.normal.copy())
        if not self.lines:  # the corners' sphere laws: no pose
            return per
        posed = [s for s in range(self.n) if self.corner[s] >= 0 and not moving[s]]
        before = {s: copy.copy(self.law[s]) for s in posed}  # a settled corner keeps its energy (refresh_law)
        for s in posed:
            self.law[s].set_pose(*self._pose(s))
        for s in posed:
            law = self.law[s]
            w_own = float(nWn[s, s])
            if w_own > 0.0:
                x_e = law._expected_depth(1.0 / w_own)
                mine = law._width_one(x_e)
                total = w_own
                for j in range(self.n):
                    if j == s or self.corner[j] < 0:
                        continue
                    other = self.law[j]._width_one(x_e + float(c.x[self.corner[j]] - c.x[self.corner[s]]))
                    beta = min(other / mine, 1.0) if mine > 0.0 else 0.0
                    total += beta * float(nWn[s, j])
                law.mass_factor = w_own / total if total > 0.0 else 1.0
            refresh(law, before[s])
        return per


# ------------------------------------------------------------ sphere on box ---
#: The rounded box's curvature under a sphere is blended over a band each
#: side of the line where a face turns into its rounded edge
#: (:func:`rounded_box_curvature`): each of the box's axes counts as rounded
#: by the share of a patch of this half-width, EDGE_BLEND rho, that lies past
#: that line. A fixed share of the edge radius, not the patch's own width
#: sqrt(R_s x): the law is then a function of the contact point alone (a
#: blend that followed x jumped when a contact ended, x -> 0, and the
#: contact resumed with another law). 0.2 rho = 0.2 mm at rho = 1 mm: the
#: order of a rubber ball's patch resting on the edge (R 10 mm, 4.6 g:
#: a = sqrt(0.91 mm x 37 um) = 0.18 mm), a fifth of the edge's arc
#: (pi rho / 2 = 1.6 mm) at each end, so its middle is the cylinder of rho.
EDGE_BLEND = 0.2


def rounded_box_contact(center, radius: float, box_pos, box_rot, shape: Box):
    """A sphere (centre ``center`` [m] (3,), ``radius`` [m]) against a box
    with rounded edges (:class:`msf_contact.shapes.Box` ``shape``: the
    Minkowski sum of the box of half-extents h - rho and the sphere of the
    edge radius rho; frame at ``box_pos`` [m] (3,), ``box_rot`` (3, 3)).
    Returns (x [m] approach, negative a gap; n (3,) unit normal from the box
    to the sphere, world; n_local (3,) the same in the box's frame; local
    (3,) the sphere's centre in the box's frame): x = R + rho - |c - q|, q
    the inner box's closest point to the centre (a centre inside the inner
    box: its nearest face). The face contact is the sharp box's (same x and
    normal) wherever the centre projects inside the face's flat part."""
    rot = np.asarray(box_rot, dtype=float).reshape(3, 3)
    local = rot.T @ (np.asarray(center, dtype=float) - np.asarray(box_pos, dtype=float))
    g = np.asarray(shape.half_extents, dtype=float) - shape.edge_radius
    d = local - np.clip(local, -g, g)
    dist = float(np.linalg.norm(d))
    if dist > 0.0:
        n_local = d / dist
        x = radius + shape.edge_radius - dist
    else:  # the centre inside the inner box: its nearest face
        k = int(np.argmin(g - np.abs(local)))
        n_local = np.zeros(3)
        n_local[k] = 1.0 if local[k] >= 0.0 else -1.0
        x = radius + shape.edge_radius + float(g[k] - abs(local[k]))
    return x, rot @ n_local, n_local, local


def rounded_box_curvature(shape: Box, local, n_local, half_width: float) -> SurfaceCurvature:
    """The box's principal curvatures (its frame) under a sphere's contact
    whose centre is at ``local`` [m] (3,) with the box's outward normal
    ``n_local`` (3,) (:func:`rounded_box_contact`), blended over the
    patch's ``half_width`` [m]: (1/rho) P (sum_i w_i e_i e_i^T) P, P the
    projection on the tangent plane, w_i in [0, 1] the share of the patch
    past the line where axis i's face turns into its rounded edge (u_i: the
    distance along the surface past that line, rho asin|n_i| on the rounded
    part, the centre's |c_i| - (h_i - rho) <= 0 on the flat part;
    w_i = (u_i + a) / 2a clipped). Deep in a face: flat; on an edge: 1/rho
    across it, 0 along it; on a corner: the sphere of rho (as
    msf_contact.shapes.Box.curvature), and continuous in the centre's
    position in between: the law the contact gets changes with no step as
    a ball rolls from a face onto an edge (an extension of the paper: a
    patch straddling a face and its rounded edge is no Hertz contact; its
    curvature is the patch's share on each)."""
    rho, a = shape.edge_radius, max(float(half_width), 1e-300)
    g = np.asarray(shape.half_extents, dtype=float) - rho
    loc = np.abs(np.asarray(local, dtype=float))
    n = np.asarray(n_local, dtype=float)
    u = np.where(loc > g, rho * np.arcsin(np.clip(np.abs(n), 0.0, 1.0)), loc - g)
    w = np.clip((u + a) / (2.0 * a), 0.0, 1.0)
    P = np.eye(3) - np.outer(n, n)
    K = P @ np.diag(w / rho) @ P
    t1, t2 = tangent_basis(n)
    T = np.stack([t1, t2])
    k2d = T @ K @ T.T
    vals, vecs = np.linalg.eigh(k2d)  # ascending
    d1 = vecs[0, 1] * t1 + vecs[1, 1] * t2
    d1 /= np.linalg.norm(d1)
    d2 = np.cross(n, d1)
    return SurfaceCurvature(max(float(vals[1]), 0.0), max(float(vals[0]), 0.0), tuple(d1), tuple(d2))


class SphereOnBox:
    """A sphere on a box with rounded edges (edge radius rho), as both
    adapters carry it (issue 13): the contact in closed form on the rounded
    box (:func:`rounded_box_contact`), its law the pair's law for the
    curvature at the point (:func:`rounded_box_curvature`: a face flat, an
    edge a cylinder of rho, a corner a sphere of rho, blended over the
    patch), so a ball rolls from a face over an edge or a corner on MSF, with
    nothing handed to the engine's own contact (before: handed to it from
    1 mm off an edge, ``edge_handoffs``).

    The pair keeps one law object of its own (:attr:`law`, given to the
    manager once, ContactManager.set_law) whose curvature follows the
    point's every step (:meth:`update`): between contacts freely; inside a
    contact through ``refresh(law, before)`` (ContactManager.refresh_law),
    so the contact keeps its elastic energy across the change (its approach
    moves instead) and onset constants stay the onset's, as a side's end
    (SideLine.slots) and a box's corner (BoxOnPlane.slots) do. A change
    below CURVATURE_RTOL of the effective radii is not taken (a ball on a
    face keeps its law).

    radius [m]: the sphere's; shape: :class:`msf_contact.shapes.Box`;
    template: the pair's law (a sphere on a plane, its materials and
    options); kernel: engines._contacts.compiled.kernel_law or None (an
    MSF law then integrates its onsets compiled, KernelOnsetMSFLaw); flip:
    the pair's body 1 is the box (the Curvature's radii swapped; the normal
    stays from the box to the sphere)."""

    def __init__(self, radius: float, shape: Box, template, kernel=None, flip: bool = False):
        if not isinstance(shape, Box):
            raise ValueError(f"SphereOnBox needs a msf_contact.shapes.Box, not {type(shape).__name__}")
        self.radius, self.shape, self.template, self._kernel = float(radius), shape, template, kernel
        self.flip = bool(flip)
        #: the centre's coordinates within these [m] (3,) on all axes but one: over a face's flat part,
        #: clear of its blend band (the face's curvature, no blend to compute)
        self._band = np.asarray(shape.half_extents, dtype=float) - shape.edge_radius * (1.0 + EDGE_BLEND)
        self.sphere = Sphere(self.radius)
        self.law = self._build(template.curvature)
        #: the box's curvature at the last update (world frame) and the contact's combined Curvature
        self.curvature = template.curvature
        #: law changes taken inside a contact (refresh with the energy kept) and between contacts
        self.changes = 0

    def _build(self, curv: Curvature):
        law = self.template.with_curvature(curv)
        known = self._kernel(law) if self._kernel is not None and type(law) is MSFLaw else None
        if known is not None:
            law = KernelOnsetMSFLaw.of(law, *known)
        return law

    def contact(self, center, box_pos, box_rot):
        """(x [m], normal (3,) box -> sphere, Curvature of the pair at the
        point) at the current poses (the blend's half-width EDGE_BLEND rho)."""
        x, n, n_local, local = rounded_box_contact(center, self.radius, box_pos, box_rot, self.shape)
        band = self._band
        if np.count_nonzero(np.abs(local) > band) <= 1:  # over a face's flat part, clear of the blend: flat
            return x, n, self.template.curvature
        rot = np.asarray(box_rot, dtype=float).reshape(3, 3)
        s2 = rounded_box_curvature(self.shape, local, n_local, EDGE_BLEND * self.shape.edge_radius)
        s1 = SurfaceCurvature.umbilic(1.0 / self.radius, -n)
        c = relative_curvature(s1, s2.rotated(rot)).curvature
        return x, n, (Curvature(c.R2a, c.R2b, c.R1a, c.R1b) if self.flip else c)

    def update(self, curv: Curvature, active: bool, refresh) -> bool:
        """Give :attr:`law` the curvature ``curv`` if its effective radii
        differ by more than CURVATURE_RTOL; ``active``: the pair is in
        contact (the change goes through ``refresh(law, before)`` with the
        law as it was, ContactManager.refresh_law: the contact keeps its
        elastic energy), else ``refresh(law, None)`` (the compiled
        constants). Returns True when the law changed."""
        if curvature_mismatch(self.law.curvature, curv) <= CURVATURE_RTOL:
            return False
        before = copy.copy(self.law) if active else None
        fresh = self._build(curv)
        self.law.__dict__.clear()
        self.law.__dict__.update(fresh.__dict__)
        self.curvature = curv
        self.changes += 1
        refresh(self.law, before)
        return True


# -------------------------------------------------------------- box on box ---
#: Two face separations (SAT, :func:`box_box_axes`) within this many edge
#: radii of each other are a tie, broken toward the lower box's face (the
#: face whose outward normal points most against gravity): a box lying flat
#: on another (within ~2 deg for 25 mm cubes with 1 mm edges) rests with its
#: corners on the lower box's top face, whichever of the pair is body 1.
FACE_TIE_EDGE_RADII = 1.0


def _face_separations(hf, cf, Rf, hc, cc, Rc) -> tuple[np.ndarray, np.ndarray]:
    """Separating-axis test along the face normals of box F (half-extents
    ``hf`` [m] (3,), centre ``cf`` [m] (3,), rotation ``Rf`` (3, 3)) against
    box C: per axis k of F, the separation [m] (3,) of C from F's face on
    C's side (negative: overlap) and that face's outward unit normal (3, 3)
    (rows). The sharp boxes' separation (the rounded boxes' faces are the
    sharp ones'; their corners are rho (sqrt(3) - 1) inside)."""
    d = Rf.T @ (cc - cf)
    s = np.where(d >= 0.0, 1.0, -1.0)
    normals = (Rf * s[None, :]).T  # (3, 3) rows: s_k Rf[:, k]
    support = np.abs(normals @ Rc) @ hc  # C's extent along each normal
    return np.abs(d) - hf - support, normals


def box_box_axes(h1, c1, R1, h2, c2, R2) -> dict:
    """The separating-axis test of two boxes (half-extents [m] (3,), centres
    [m] (3,), rotations (3, 3)): ``face1``/``face2`` (3,) the separations [m]
    along each box's own face normals (box 1's: box 2 from box 1's faces;
    negative: overlap), ``normal1``/``normal2`` (3, 3) those faces' outward
    normals (rows), and ``edge`` [m] the largest separation along the nine
    cross products of their edges (-inf when all are parallel), ``edge_axes``
    (i, j) its edges' axes. The largest of all is the boxes' separation
    along the best axis; it is an edge axis when edges cross edges."""
    h1, h2 = np.asarray(h1, float), np.asarray(h2, float)
    c1, c2 = np.asarray(c1, float), np.asarray(c2, float)
    R1, R2 = np.asarray(R1, float).reshape(3, 3), np.asarray(R2, float).reshape(3, 3)
    f1, n1 = _face_separations(h1, c1, R1, h2, c2, R2)
    f2, n2 = _face_separations(h2, c2, R2, h1, c1, R1)
    best, axes = -math.inf, (-1, -1)
    d = c1 - c2
    for i in range(3):
        for j in range(3):
            a = np.cross(R1[:, i], R2[:, j])
            na = float(np.linalg.norm(a))
            if na < 1e-6:  # parallel edges: the faces' axes cover them
                continue
            a /= na
            sep = abs(float(d @ a)) - float(np.abs(a @ R1) @ h1) - float(np.abs(a @ R2) @ h2)
            if sep > best:
                best, axes = sep, (i, j)
    return {"face1": f1, "normal1": n1, "face2": f2, "normal2": n2, "edge": best, "edge_axes": axes}


def segment_closest(p0, p1, q0, q1) -> tuple[np.ndarray, np.ndarray]:
    """The closest points [m] (3,) each of the segments p0-p1 and q0-q1
    (Ericson, Real-Time Collision Detection, 5.1.9: the clamped parameters
    of the two lines' closest points)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    c, b = float(d1 @ r), float(d1 @ d2)
    den = a * e - b * b
    s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-30 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return p0 + s * d1, q0 + t * d2


def box_edge(shape: Box, pos, rot, axis: int, signs) -> tuple[np.ndarray, np.ndarray]:
    """The ends [m] (3,) each of the rounded box's edge along ``axis`` at
    the signs (3,) of the other two coordinates: the segment of the inner
    box (half-extents h - rho) that the edge's cylinder of radius rho is
    around (:func:`box_corners`' Minkowski sum)."""
    inner = np.asarray(shape.half_extents, dtype=float) - shape.edge_radius
    rot = np.asarray(rot, dtype=float).reshape(3, 3)
    a, b = np.array(signs, dtype=float) * inner, np.array(signs, dtype=float) * inner
    a[axis], b[axis] = -inner[axis], inner[axis]
    pos = np.asarray(pos, dtype=float)
    return pos + rot @ a, pos + rot @ b


class BoxOnBox:
    """A box with rounded edges on another free (or moving) box, as both
    adapters carry it (issue 13: stacking): the lower box's face is the
    plane of :class:`BoxOnPlane` for the upper box's corners, taken at both
    bodies' current poses each step (the face moves with its box; the
    adapters compute each slot's relative motion from both bodies at its
    point and apply its force to both). Which box's corners and which face:
    the separating-axis test along the six face normals
    (:func:`box_box_axes`), the least overlapping face, a tie
    (FACE_TIE_EDGE_RADII) going to the face that looks up (``up``, against
    gravity: the lower box's top face), so either box may be body 1. The
    choice is held while any slot is busy (in contact or a correction
    pending): within a contact each corner's law is a function of its own
    approach against one face (as BoxOnPlane's poses, :meth:`SideLine.slots`),
    and re-chosen when all are free.

    Edges crossing edges (the best separating axis a cross product of two
    edges, by more than the tie) are one contact, slot 0, the crossing of
    the two rounded edges (:meth:`_crossing`), held the same way.

    The face is bounded (issue 13; :meth:`_bounded`): a corner whose lowest
    point's foot on the face's plane lies beyond the face's edge touches
    nothing there; its slot is carried at the face's nearest point under
    the corners' box's own face instead (the foot clamped into the face's
    rectangle, raised or lowered onto the plane of the corners' box's face
    through the corner): a vertex of the two faces' overlap where the face
    box's edge or corner meets the other box's face. An upper box set flat
    over the lower one's edge, its centre 20 mm off, rests on its two
    corners over the face and on the face's edge at its two ends, the
    overlap's corners; a point that falls outside the corners' box's face
    (the two faces do not overlap there) gives no point (None: a gap).
    Before, the face was an unbounded plane (as :func:`face_toward` still
    takes a fixed box's face) and such an upper box stood on two corners in
    the air, the edge under it carrying nothing. Stated approximations: a
    moved slot keeps its corner's edge law and pose; the overlap's other
    vertices (its edges crossing, with a turn between the boxes) are not
    slots of their own; and while one choice's contact lasts the other
    features are not looked at.

    shape1, shape2: :class:`msf_contact.shapes.Box` of body 1 and body 2;
    names: their names; n_slots: the corners managed (4: a face)."""

    def __init__(self, shape1: Box, shape2: Box, names: tuple, n_slots: int = 4):
        for which, s in (("shape1", shape1), ("shape2", shape2)):
            if not isinstance(s, Box):
                raise ValueError(f"BoxOnBox needs msf_contact.shapes.Box shapes, {which} is {type(s).__name__}")
        self.names = tuple(names)
        self.n = int(n_slots)
        #: per "which" (1: body 1's corners on body 2's face; 2: body 2's on body 1's): its BoxOnPlane
        self.on = {1: BoxOnPlane(shape1, self.names, self.n), 2: BoxOnPlane(shape2, self.names[::-1], self.n)}
        self.shapes = {1: shape1, 2: shape2}
        self.which = 1
        #: the face (its box's axis 0-2, sign +-1) the corners rest on, chosen when all slots are free
        self.face = (2, 1.0)
        #: whether the last choice found edges crossing edges (slot 0 their crossing, :meth:`_crossing`)
        self.crossing = False
        #: the contact normal (from body 2 toward body 1) [-] (3,) at the last update
        self.normal = np.array([0.0, 0.0, 1.0])
        #: while edges cross edges: (box 1's edge axis, its signs (3,), box 2's edge axis, its signs (3,))
        self.edges = None
        #: the crossing's (x [m], point [m] (3,), normal (3,)) at the last update, and its law
        self.cross = None
        self.cross_law = None
        #: per slot at the last update: None (its corner over the face), or the corner moved onto the face's
        #: edge (:meth:`_bounded`): (x [m], point [m] (3,) on the corners' box's face) or False (no overlap)
        self.moved: list = [None] * self.n

    @property
    def box(self) -> BoxOnPlane:
        """The BoxOnPlane of the corners in use."""
        return self.on[self.which]

    @property
    def corners(self) -> BoxCorners | None:
        return self.box.corners

    @property
    def corner(self) -> np.ndarray:
        return self.box.corner

    @property
    def law(self) -> list:
        """Each slot's law (BoxOnPlane.law of the corners in use; crossing edges: slot 0's the crossing's)."""
        if self.crossing:
            return [self.cross_law] + [None] * (self.n - 1)
        return self.box.law

    def check(self, template) -> None:
        """BoxOnPlane.check of both boxes (a law that cannot carry a line: the corners' spheres)."""
        self.on[1].check(template)
        self.on[2].check(template)

    def choose(self, pos1, rot1, pos2, rot2, up=None) -> None:
        """The corners' box and face at the current poses (class docstring);
        ``up`` (3,) the direction against gravity (None: no preference)."""
        s1, s2 = self.shapes[1], self.shapes[2]
        ax = box_box_axes(s1.half_extents, pos1, rot1, s2.half_extents, pos2, rot2)
        seps = np.concatenate([ax["face2"], ax["face1"]])  # 0-2: body 1's corners on body 2's faces
        normals = np.concatenate([ax["normal2"], ax["normal1"]])
        best = float(np.max(seps))
        tie = FACE_TIE_EDGE_RADII * max(s1.edge_radius, s2.edge_radius)
        pick = int(np.argmax(seps))
        if up is not None and np.linalg.norm(up) > 0.0:
            cand = np.flatnonzero(seps >= best - tie)
            pick = int(cand[np.argmax(normals[cand] @ np.asarray(up, float))])
        self.which = 1 if pick < 3 else 2
        rot = np.asarray(rot2 if self.which == 1 else rot1, float).reshape(3, 3)
        k = pick % 3
        self.face = (k, float(np.sign(normals[pick] @ rot[:, k])))
        self.crossing = bool(ax["edge"] > best + tie)
        self.edges = None
        if self.crossing:  # the two edges nearest each other along the edges' axis (from box 2 toward box 1)
            i, j = ax["edge_axes"]
            R1, R2 = np.asarray(rot1, float).reshape(3, 3), np.asarray(rot2, float).reshape(3, 3)
            a = np.cross(R1[:, i], R2[:, j])
            a /= np.linalg.norm(a)
            if float((np.asarray(pos1, float) - np.asarray(pos2, float)) @ a) < 0.0:
                a = -a
            s1 = np.where(R1.T @ a > 0.0, -1.0, 1.0)  # box 1's edge on its side toward box 2
            s2 = np.where(R2.T @ a > 0.0, 1.0, -1.0)  # box 2's toward box 1
            self.edges = (int(i), s1, int(j), s2)

    def _frame(self, pos1, rot1, pos2, rot2) -> tuple:
        """(corners' box centre [m] (3,), its rotation (3, 3), a point of the
        chosen face [m] (3,), the face's outward unit normal (3,)) at the poses."""
        pose = {1: (np.asarray(pos1, float), np.asarray(rot1, float).reshape(3, 3)),
                2: (np.asarray(pos2, float), np.asarray(rot2, float).reshape(3, 3))}
        cpos, crot = pose[self.which]
        fpos, frot = pose[3 - self.which]
        k, s = self.face
        n_face = s * frot[:, k]
        return cpos, crot, fpos + float(self.shapes[3 - self.which].half_extents[k]) * n_face, n_face

    def corners_at(self, pos1, rot1, pos2, rot2) -> BoxCorners:
        """:func:`box_corners` of the corners' box against the chosen face at these poses (no slot changes)."""
        return box_corners(self.shapes[self.which], *self._frame(pos1, rot1, pos2, rot2))

    def update(self, pos1, rot1, pos2, rot2, busy, template, bank: "LawBank", up=None,
               t: float = 0.0) -> np.ndarray:
        """The slots at both boxes' poses (``pos`` [m] (3,), ``rot`` (3, 3)
        each): the corners' box and face (or the crossing edges) re-chosen
        when no slot is busy (``busy`` (n,) bool), then BoxOnPlane.update of
        those corners against that face at its current pose (or the
        crossing, :meth:`_crossing`; t [s] the engine time for its
        messages). Returns (n,) bool: the slots whose corner changed (all of
        them when the choice changed)."""
        busy = np.asarray(busy, dtype=bool)[:self.n]
        before = (self.which, self.face, self.crossing)
        if not np.any(busy):
            self.choose(pos1, rot1, pos2, rot2, up)
        if self.crossing:
            self.moved = [None] * self.n
            if before[2] is not True:
                self.on[1].corner[:] = -1
                self.on[2].corner[:] = -1
            self._crossing(pos1, rot1, pos2, rot2, busy, template, bank, t)
            return np.ones(self.n, bool) if before[2] is not True else np.zeros(self.n, bool)
        cpos, crot, fpoint, n_face = self._frame(pos1, rot1, pos2, rot2)
        changed = self.box.update(cpos, crot, fpoint, n_face, busy, template, bank)
        self.normal = n_face if self.which == 1 else -n_face
        self._bounded(pos1, rot1, pos2, rot2, n_face)
        if (self.which, self.face, self.crossing) != before:
            other = self.on[3 - self.which]
            other.corner[:] = -1
            changed = np.ones(self.n, bool)
        return changed

    def _bounded(self, pos1, rot1, pos2, rot2, n_face) -> None:
        """:attr:`moved` of each slot at these poses (class docstring): a
        corner whose lowest point's foot lies beyond the face (the face box's
        half-extents along its two other axes) is moved to the foot clamped
        into the face, taken onto the plane through the corner's lowest point
        normal to the corners' box's axis most against the face normal
        (x: that point's depth below the face's plane [m]); False when that
        point lies outside the corners' box's face (its half-extents)."""
        pose = {1: (np.asarray(pos1, float), np.asarray(rot1, float).reshape(3, 3)),
                2: (np.asarray(pos2, float), np.asarray(rot2, float).reshape(3, 3))}
        cpos, crot = pose[self.which]
        fpos, frot = pose[3 - self.which]
        k, sign = self.face
        hf = np.asarray(self.shapes[3 - self.which].half_extents, dtype=float)
        hc = np.asarray(self.shapes[self.which].half_extents, dtype=float)
        j = int(np.argmax(np.abs(crot.T @ n_face)))  # the corners' box's face against this one
        n_own = crot[:, j] * (-1.0 if float(crot[:, j] @ n_face) > 0.0 else 1.0)  # its outward normal
        c = self.box.corners
        self.moved = [None] * self.n
        for s_, corner in enumerate(self.box.corner):
            if corner < 0:
                continue
            low = c.lowest[int(corner)]
            local = frot.T @ (low - fpos)
            clamped = np.clip(local, -hf, hf)
            clamped[k] = sign * hf[k]
            if np.all(np.abs(local - clamped)[[i for i in range(3) if i != k]] == 0.0):
                continue  # over the face
            q = fpos + frot @ clamped  # on the face's plane
            t = float((low - q) @ n_own) / float(n_face @ n_own)  # q + t n_face on the corners' box's face
            p = q + t * n_face
            own = crot.T @ (p - cpos)
            inside = all(abs(own[i]) <= hc[i] for i in range(3) if i != j)
            self.moved[s_] = (-t, p) if inside else False

    def _crossing(self, pos1, rot1, pos2, rot2, busy, template, bank, t) -> None:
        """Slot 0 as the crossing of the two rounded edges (:attr:`edges`,
        each a cylinder of its box's edge radius about its inner edge,
        :func:`box_edge`): x = rho1 + rho2 - the edges' distance
        (:func:`segment_closest`), the normal along their common
        perpendicular, the point midway between the surfaces; before its
        onset (slot 0 free) the law of the curvature of both surfaces there
        (:func:`contact_law`: two cylinders of rho at the edges' angle,
        msf_contact's Hertz combination, (13)-(24) with the relative angle;
        edges near parallel, a line, carried flagged by the stand-in)."""
        i, s1, j, s2 = self.edges
        sh1, sh2 = self.shapes[1], self.shapes[2]
        p1, p2 = segment_closest(*box_edge(sh1, pos1, rot1, i, s1), *box_edge(sh2, pos2, rot2, j, s2))
        gap = p1 - p2
        dist = float(np.linalg.norm(gap))
        n = gap / dist if dist > 0.0 else self.normal.copy()
        x = sh1.edge_radius + sh2.edge_radius - dist
        point = 0.5 * ((p1 - sh1.edge_radius * n) + (p2 + sh2.edge_radius * n))
        self.normal, self.cross = n, (float(x), point, n.copy())
        if not busy[0] or self.cross_law is None:
            self.cross_law = contact_law(self.names, template, bank, sh1, (np.asarray(pos1, float),
                                         np.asarray(rot1, float).reshape(3, 3)), sh2,
                                         (np.asarray(pos2, float), np.asarray(rot2, float).reshape(3, 3)),
                                         point, n, t, max(float(x), 0.0))

    def points(self) -> np.ndarray:
        """BoxOnPlane.points of the corners in use [m] (n, 3) (crossing edges: the crossing's point)."""
        if self.crossing:
            return np.tile(self.cross[1], (self.n, 1))
        pts = self.box.points().copy()
        for s_, mv in enumerate(self.moved):
            if mv:
                pts[s_] = mv[1]
        return pts

    def slots(self, nWn, moving, refresh) -> list:
        """BoxOnPlane.slots (nWn (n, n) [1/kg] along :attr:`normal`), each
        slot's normal from body 2 toward body 1 (body 2's corners on body
        1's face: the face's outward normal reversed)."""
        if self.crossing:  # slot 0 the crossing, a point law: no pose
            return [(self.cross[0], self.cross[1].copy(), self.cross[2].copy())] + [None] * (self.n - 1)
        per = self.box.slots(nWn, moving, refresh)
        for s_, mv in enumerate(self.moved):  # a corner beyond the face's edge: at the face's edge (_bounded)
            if mv is False:
                per[s_] = None
            elif mv is not None and per[s_] is not None:
                x, p = mv
                per[s_] = (x, p + 0.5 * x * per[s_][2], per[s_][2])
        if self.which == 2:
            per = [None if q is None else (q[0], q[1], -q[2]) for q in per]
        return per
