"""Contact points of the pybullet pairs that are not the analytic ones
(issue 13): box, capsule, cylinder and mesh shapes, with the curvature the
MSF law needs at each point (:mod:`engines._narrow`, :mod:`msf_contact.shapes`).

Where the points come from, per pair of shapes (body 1 first):

- **shape on a plane** (box, capsule, cylinder; the robot-floor case): the
  shape's support features in closed form, all of them within the candidate
  reach: a box's 8 corners, a capsule's 2 end spheres, a cylinder's rim
  points (per cap the rim point nearest the plane; 4 points 90 degrees apart
  when the cap lies flat). A capsule's or cylinder's side tilted less than
  ``engines._narrow.LINE_TILT_MAX`` from the plane between contacts is a
  line contact instead: its slots 0 and 1 are the side's two ends, each
  with its share of the line law (``engines._narrow.SideLine`` and
  ``SideEndLaw``, as MuJoCo's adapter; the adapter's ``_line_points``). pybullet's ``getClosestPoints`` lists only the
  deepest point of such a pair (measured: one corner of a box lying on a
  face, one end of a capsule lying flat), where a box face rests on four
  corners; MuJoCo's narrow phase lists them all, and these are the same
  points. A corner's distance is the sharp box's (what pybullet collides);
  its curvature is the sphere of the edge radius, as in the MuJoCo adapter.
- **a mesh on a plane whose hull vertices are contacts** (a coarse hull
  such as ``duck_vhacd.obj``, given several slots:
  ``PybulletAdapter(mesh_slots={link: 4})``): every hull vertex within the
  reach, as a box's corners, the deepest first; the curvature at a vertex
  is the mesh's local fit (engines._narrow.ConvexMesh), as MuJoCo's
  ``mesh_slots``. With one slot the deepest vertex jumps to the next as the
  body rolls, and a new vertex already below the plane began as a deep
  onset: the duck tumbling on steel stopped at x = 2R of its 70 mm law
  (docs/engines.md).
- **a sphere on a capsule or a cylinder** (either way round): the sphere
  centre's closest point on the segment or on the solid cylinder, exact.
  pybullet's GJK answer for a sphere on a cylinder's side is off by up to
  1e-5 m in distance and 3e-3 rad in normal (measured against the exact
  distance at -0.5 to 1 mm overlap), 1-2 % of the approach of a rubber
  impact (tests/test_narrow_pybullet.py).
- **everything else** (a mesh, box on box, capsule on box, ...): pybullet's
  own narrow phase, ``getClosestPoints`` with the candidate reach as its
  distance threshold, one point per pair. A convex-hull mesh is inflated by
  its collision margin (``getDynamicsInfo`` item 11, 1 mm by default;
  measured: a vertex 0.5 mm above a plane is reported at -0.5 mm): the
  distance and the points are corrected by it.

pybullet has no ellipsoid: an ellipsoid is a convex-hull mesh whose
vertices lie on the ellipsoid (:func:`ellipsoid_vertices`, a "cubed
sphere" with a vertex at each of the six tips), with the analytic
:class:`msf_contact.shapes.Ellipsoid` given as its curvature
(``PybulletAdapter(..., curvature={link: Ellipsoid(...)})``); without that
a mesh's curvature is the local fit of :class:`msf_contact.shapes.Mesh`.

Conventions of :mod:`engines.base`: the normal points from body 2 toward
body 1; x > 0 is overlap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet as pb

from engines._narrow import SMOOTH_REACH, Plane, SlotMatcher, make_shape
from engines._narrow import smooth_contact
from msf_contact.curvature import tangent_basis

#: Shapes this module finds contacts for (with the analytic sphere pairs of
#: engines._geometry, everything pybullet's createCollisionShape makes).
NARROW_KINDS = ("sphere", "plane", "box", "capsule", "cylinder", "mesh")
#: Points managed per pair: a box face on a plane rests on 4 corners, a
#: cylinder's cap on 4 rim points, a capsule lying flat on its 2 end spheres;
#: a mesh is one smooth convex surface (its deepest point only), as in the
#: MuJoCo adapter (engines.mujoco.adapter.NARROW_SLOTS).
NARROW_SLOTS = {"box": 4, "cylinder": 4, "capsule": 2}
#: A cylinder's cap lies flat on a plane when the plane normal's component
#: across the axis is below this [-]: its rim is then listed as 4 points.
FLAT_CAP = 1e-6
#: Smallest candidate reach [m] (float rounding of a resting contact, and
#: pybullet's getClosestPoints threshold): as engines.mujoco.narrow's floor
#: of 1 mm for the detection margin.
REACH_FLOOR = 1e-3


@dataclass(frozen=True)
class LinkShape:
    """One collision shape of a link, in the link's inertial frame.

    kind: sphere, plane, box, capsule, cylinder or mesh. size: sphere
    (radius,); box half-extents (3,); plane its unit normal (3,); capsule
    and cylinder (radius, half-length of the segment / of the height), the
    axis along the shape frame's z; mesh its scale (3,) [m]. pos (3,) [m],
    rot (3, 3): the shape frame in the link's inertial frame. vertices (n, 3)
    [m]: a mesh's convex-hull vertices in the shape frame; margin [m]: the
    distance by which pybullet inflates the shape in getClosestPoints (a
    convex hull's collision margin; 0 for the primitives).
    """

    kind: str
    size: np.ndarray
    pos: np.ndarray
    rot: np.ndarray
    vertices: np.ndarray | None = field(default=None, repr=False)
    margin: float = 0.0
    #: a plane that is a box's face (:func:`floor_face`): the box's half-extents
    #: along the shape frame's axes (3,) [m], inf along the normal; points whose
    #: foot on the plane lies beyond them touch nothing. None: an unbounded plane.
    face: np.ndarray | None = None

    def extent(self) -> float:
        """The shape's bounding radius about its frame's origin [m] (slot matching, reach bounds)."""
        s = np.asarray(self.size, dtype=float)
        if self.kind == "sphere":
            return float(s[0])
        if self.kind == "capsule":
            return float(s[0] + s[1])
        if self.kind == "cylinder":
            return float(math.hypot(s[0], s[1]))
        if self.kind == "mesh" and self.vertices is not None:
            return float(np.max(np.linalg.norm(self.vertices, axis=1)))
        return float(np.linalg.norm(s))


def ellipsoid_vertices(semi_axes, n: int = 12) -> np.ndarray:
    """Vertices (V, 3) [m] on the ellipsoid of ``semi_axes`` (a, b, c) [m]:
    a cube's faces divided in n x n squares (n even), projected on the unit
    sphere and scaled. The six face centres are the ellipsoid's tips, so a
    drop along a principal axis touches first at a vertex that is exactly
    the tip. n = 12: 866 vertices, 1,728 hull faces."""
    if int(n) != n or n < 2 or n % 2:
        raise ValueError(f"n = {n!r} must be an even whole number >= 2 (a vertex at each face centre)")
    t = np.linspace(-1.0, 1.0, int(n) + 1)
    u, v = (g.ravel() for g in np.meshgrid(t, t))
    one = np.ones_like(u)
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.empty((u.size, 3))
            p[:, axis] = sign * one
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = u, v
            faces.append(p)
    p = np.unique(np.round(np.concatenate(faces), 12), axis=0)
    p /= np.linalg.norm(p, axis=1)[:, None]
    return p * np.asarray(semi_axes, dtype=float)


#: pybullet's URDF loader makes a ``<cylinder>`` collision (without
#: ``URDF_USE_IMPLICIT_CYLINDER``) a convex hull of two rings of vertices at
#: z = +-length/2, radius r, about the shape frame's z (measured on
#: pybullet_data's racecar.urdf wheels, r 0.05 m, length 0.045 m: 64 vertices,
#: 32 a ring, radii 0.0499875-0.05 m in float32, collision margin 1 mm).
#: :func:`ring_prism` recognises it when every vertex lies on one of the two
#: rings within this share of r [-] (float32 rounding is 2.5e-4 of r there;
#: a coarser polygon or an off-axis vertex is 1e-2 of r or more away).
RING_RTOL = 1e-3
#: ... and with at least this many vertices a ring [-] (an octagonal prism
#: and finer: its facets lie within r (1 - cos(pi/8)) = 0.08 r of the circle).
RING_MIN = 8


def ring_prism(vertices) -> tuple[float, float] | None:
    """(radius [m], half-length [m]) when ``vertices`` (n, 3) [m] are a
    cylinder's two rings about the frame's z (pybullet's convex hull of a
    URDF cylinder, ``RING_RTOL``, ``RING_MIN``): each ring the same polygon
    (same angles) at z = -h and +h, all at radius r; else None. The radius
    is the rings' largest (the cylinder's: the vertices lie on it)."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    n = v.shape[0]
    if n < 2 * RING_MIN or n % 2:
        return None
    rho = np.hypot(v[:, 0], v[:, 1])
    r = float(rho.max())
    h = float(np.abs(v[:, 2]).max())
    if not (r > 0.0 and h > 0.0):
        return None
    tol = RING_RTOL * r
    if np.any(np.abs(rho - r) > tol) or np.any(np.abs(np.abs(v[:, 2]) - h) > tol):
        return None
    top, bottom = v[v[:, 2] > 0.0], v[v[:, 2] < 0.0]
    if top.shape[0] != bottom.shape[0]:
        return None
    # the same polygon on both rings: each top vertex has a bottom one above it
    gap = np.linalg.norm(top[:, None, :2] - bottom[None, :, :2], axis=2).min(axis=1)
    if np.any(gap > tol):
        return None
    return r, h


def as_cylinder(shape: LinkShape) -> LinkShape:
    """``shape`` itself, or, when it is a mesh whose hull is a URDF cylinder's
    rings (:func:`ring_prism`), the cylinder it stands for (same frame).
    Why: a lying cylinder's hull touches a plane along a facet's edge or on a
    whole facet, where the mesh's local fit has only two rings of vertices
    and cannot tell the curvature along the axis: the fit of the racecar's
    wheel gave a support point 1,024 m beyond its vertex (a contact found
    1,024 m deep) and launched the car at 64 m/s (docs/engines.md). The
    cylinder's side carries the line law, its rims the rim points, as a
    cylinder geom (URDF_USE_IMPLICIT_CYLINDER) does."""
    if shape.kind != "mesh" or shape.vertices is None:
        return shape
    found = ring_prism(shape.vertices)  # getMeshData's vertices are scaled already
    if found is None:
        return shape
    return LinkShape("cylinder", np.array(found), shape.pos, shape.rot)


#: A fixed box is a floor for a narrow pair (:func:`floor_face`) when both
#: half-extents of its face toward body 1 are at least this many times body
#: 1's bounding radius [-]: pybullet_data's plane.urdf is a 200 x 200 x 10 m
#: box (its collision is no plane), the racecar's wheels 0.067 m.
FLOOR_SHARE = 10.0


def floor_face(box: LinkShape, box_pose, other: LinkShape, other_pose) -> LinkShape:
    """``box`` itself, or, when it is a box whose face toward ``other`` (its
    shape frame's origin at setup) is a floor for it (``FLOOR_SHARE``), that
    face as a bounded plane (``LinkShape.face``): a shape's support features
    on it in closed form (:func:`features_on_plane`, a lying side's line
    contact) instead of pybullet's one closest point of the pair, whose
    curvature on a flat face and a cylinder's side is a line contact no point
    law carries. pose: (com (3,), rot (3, 3)) of each link at setup."""
    if box.kind != "box":
        return box
    c_box, R_box = _world(box, box_pose)
    c_other, _ = _world(other, other_pose)
    half = np.asarray(box.size, dtype=float)
    d = R_box.T @ (c_other - c_box)
    axis = int(np.argmax(np.abs(d) - half))  # the face the other shape lies beyond
    sign = 1.0 if d[axis] >= 0.0 else -1.0
    inface = [a for a in range(3) if a != axis]
    if float(np.min(half[inface])) < FLOOR_SHARE * other.extent():
        return box
    normal = np.zeros(3)
    normal[axis] = sign
    face = half.copy()
    face[axis] = math.inf
    return LinkShape("plane", normal, box.pos + box.rot @ (sign * half[axis] * normal), box.rot, face=face)


def on_face(plane: LinkShape, c2, R2, points) -> np.ndarray:
    """(k,) bool: the points (k, 3) [m] (world) whose foot on ``plane`` (frame
    ``c2``, ``R2`` in the world) lies on its face (all True for an unbounded plane)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if plane.face is None:
        return np.ones(pts.shape[0], bool)
    local = (pts - c2) @ R2
    return np.all(np.abs(local) <= plane.face, axis=1)


def msf_shape(shape: LinkShape, edge_radius: float | None = None):
    """The :mod:`msf_contact.shapes` object of a pybullet shape (MuJoCo's size
    conventions, which LinkShape uses)."""
    if shape.kind == "plane":
        return Plane()
    return make_shape(shape.kind, shape.size, edge_radius=edge_radius, vertices=shape.vertices)


def _world(shape: LinkShape, pose) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), rotation (3, 3)) of the shape frame in the world; pose: (com, rot) of the link."""
    com, rot = pose
    return com + rot @ shape.pos, rot @ shape.rot


def features_on_plane(shape: LinkShape, pos, rot, p0, nz):
    """The support features of a box, capsule or cylinder (frame ``pos``,
    ``rot`` in the world) against the plane through ``p0`` with unit normal
    ``nz`` (world): (x (k,) approach [m], the shape's surface points (k, 3)
    [m] in the world). Box: its 8 corners; capsule: the lowest point of each
    end sphere; cylinder: per cap the rim point nearest the plane, or 4 rim
    points when the cap lies flat (FLAT_CAP); mesh: its hull vertices."""
    s = np.asarray(shape.size, dtype=float)
    if shape.kind == "box":
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
        pts = pos + (signs * s) @ rot.T
    elif shape.kind == "capsule":
        ends = pos + np.outer([-s[1], s[1]], rot[:, 2])
        pts = ends - s[0] * nz
    elif shape.kind == "cylinder":
        a = rot[:, 2]
        across = nz - (nz @ a) * a
        na = np.linalg.norm(across)
        if na > FLAT_CAP:
            dirs = (-across / na)[None]
        else:
            t1, t2 = tangent_basis(a)
            dirs = np.array([t1, t2, -t1, -t2])
        pts = np.concatenate([pos + h * a + s[0] * dirs for h in (-s[1], s[1])])
    elif shape.kind == "mesh" and shape.vertices is not None:
        pts = pos + np.asarray(shape.vertices, dtype=float) @ rot.T
    else:
        raise ValueError(f"shape kind {shape.kind!r} has no closed-form features on a plane")
    return -((pts - p0) @ nz), pts


def sphere_closest(shape: LinkShape, pos, rot, centre):
    """The closest point of a capsule or a solid cylinder (frame ``pos``,
    ``rot``) to the point ``centre`` (3,) (a sphere's centre), all in the
    world: (signed distance [m] (negative inside), surface point (3,),
    outward unit normal (3,))."""
    s = np.asarray(shape.size, dtype=float)
    p = rot.T @ (np.asarray(centre, float) - pos)
    r, h = float(s[0]), float(s[1])
    rho = math.hypot(p[0], p[1])
    radial = np.array([p[0], p[1], 0.0]) / rho if rho > 0.0 else np.array([1.0, 0.0, 0.0])
    axial = np.array([0.0, 0.0, 1.0 if p[2] >= 0.0 else -1.0])
    if shape.kind == "capsule":
        seg = np.array([0.0, 0.0, min(max(p[2], -h), h)])
        d = p - seg
        L = float(np.linalg.norm(d))
        n = d / L if L > 0.0 else radial
        dist, q = L - r, seg + r * n
    elif shape.kind == "cylinder":
        dr, dz = rho - r, abs(p[2]) - h
        if dr > 0.0 and dz > 0.0:  # beyond the rim
            dist = math.hypot(dr, dz)
            n = (dr * radial + dz * axial) / dist
            q = r * radial + h * axial
        elif dr >= dz:  # the side is nearer (or the only one outside)
            dist, n = dr, radial
            q = np.array([r * radial[0], r * radial[1], p[2]])
        else:
            dist, n = dz, axial
            q = np.array([p[0], p[1], h * axial[2]])
    else:
        raise ValueError(f"shape kind {shape.kind!r} has no closed-form closest point")
    return float(dist), pos + rot @ q, rot @ n


@dataclass
class NarrowPair:
    """One PairSpec carried by several managed contacts (slots): its links,
    shapes, the msf_contact shapes for the curvature, and the slot matcher."""

    first: int  # index of the first slot among the adapter's pairs
    link1: tuple  # (body unique id, link index)
    link2: tuple
    shape1: LinkShape
    shape2: LinkShape
    geom1: object  # msf_contact.shapes of each (curvature)
    geom2: object
    matcher: SlotMatcher
    method: str  # "plane" (features on a plane), "sphere" (a sphere on a capsule/cylinder), "engine"
    #: a capsule's or cylinder's side on a plane: its line contact (engines._narrow.SideLine), else None
    line: object = None
    #: a box on a plane: its rounded corners and edges (engines._narrow.BoxOnPlane), else None
    box: object = None

    @property
    def n(self) -> int:
        return self.matcher.n


def assign_plane_slots(matcher: SlotMatcher, local, x, busy, reach: float, same: float):
    """Slots for the features of a shape on a plane (features_on_plane, all
    of them): (slot per feature (k,) int, -1 left out; changed (n,) bool,
    the slots that now hold another feature than at the last step).

    A busy slot (in contact, or a timing correction pending) keeps the
    feature nearest its last point within the matcher's distance, however
    far it now is: its contact is followed until the manager ends it
    (listing only the features within the reach left an active contact of
    the ant's foot without a point, taken as 1 m away: the foot then sank
    0.1 m into the floor unseen). The other slots take the deepest features
    within ``reach`` [m], deepest first, a slot keeping its own feature
    (within ``same`` [m] of its last point in body 1's frame) when that is
    among them: a free slot held by a feature that lifts away while a deeper
    one comes (a mesh's hull vertices, a few mm apart) left the deeper one
    unmanaged until it was 8.8 mm deep (the duck). local (k, 3) [m] in body
    1's frame, x (k,) [m] the approach, busy (n,) bool."""
    pts = np.asarray(local, dtype=float).reshape(-1, 3)
    x = np.asarray(x, dtype=float).reshape(-1)
    busy = np.asarray(busy, dtype=bool)
    k, n = pts.shape[0], matcher.n
    out = np.full(k, -1)
    taken = np.zeros(n, bool)
    before = matcher.anchor.copy()
    known = ~np.isnan(before[:, 0])

    def claim(slots, rows, tol):
        if not slots.size or not rows.size:
            return
        dist = np.linalg.norm(pts[rows][:, None, :] - before[slots][None, :, :], axis=2)
        for flat in np.argsort(dist, axis=None, kind="stable"):
            r, c = divmod(int(flat), slots.size)
            if dist[r, c] > tol:
                break
            if out[rows[r]] < 0 and not taken[slots[c]]:
                out[rows[r]], taken[slots[c]] = slots[c], True

    claim(np.flatnonzero(busy & known), np.arange(k), matcher.tol)
    free = int(np.count_nonzero(~taken))
    order = [int(i) for i in np.argsort(-x, kind="stable") if out[i] < 0 and x[i] > -reach][:free]
    cand = np.array(order, dtype=int)
    claim(np.flatnonzero(~taken & known), cand, same)
    open_slots = [s for s in range(n) if not taken[s]]
    for i in cand:
        if out[i] < 0 and open_slots:
            out[i] = open_slots.pop(0)
            taken[out[i]] = True
    anchor = np.where(busy[:, None], before, np.nan)
    for i in np.flatnonzero(out >= 0):
        anchor[out[i]] = pts[i]
    moved = np.linalg.norm(np.where(known[:, None] & taken[:, None], anchor - before, 0.0), axis=1)
    changed = taken & (~known | (~busy & (moved > same)))
    matcher.anchor = anchor
    return out, changed


def pair_method(kind1: str, kind2: str, slots: int = 1) -> str:
    """How the points of a pair of shape kinds are found (module docstring);
    slots: the pair's managed points (a mesh on a plane with more than one:
    its hull vertices)."""
    if kind2 == "plane" and (kind1 in ("box", "capsule", "cylinder") or (kind1 == "mesh" and slots > 1)):
        return "plane"
    if {kind1, kind2} in ({"sphere", "capsule"}, {"sphere", "cylinder"}):
        return "sphere"
    return "engine"


def slots_of(kind1: str, kind2: str, mesh_slots: tuple[int, int] = (1, 1)) -> int:
    """Managed points of a pair of shape kinds (NARROW_SLOTS; a mesh: its
    ``mesh_slots`` entry, body 1's and body 2's)."""
    k1 = mesh_slots[0] if kind1 == "mesh" else NARROW_SLOTS.get(kind1, 1)
    k2 = mesh_slots[1] if kind2 == "mesh" else NARROW_SLOTS.get(kind2, 1)
    return max(k1, k2 if kind2 != "plane" else 1)


def detect(np_: NarrowPair, pose1, pose2, reach: float, client: int):
    """The pair's contact points within ``reach`` [m] at the poses ((com,
    rot) of each link): (x (k,) approach [m], point (k, 3) midway between the
    surfaces [m], normal (k, 3) from body 2 to body 1)."""
    s1, s2 = np_.shape1, np_.shape2
    c1, R1 = _world(s1, pose1)
    c2, R2 = _world(s2, pose2)
    if np_.method == "plane":
        nz = R2 @ (np.asarray(s2.size, float) / np.linalg.norm(s2.size))
        x, p1 = features_on_plane(s1, c1, R1, c2, nz)
        keep = (x > -reach) & on_face(s2, c2, R2, p1)
        x, p1 = x[keep], p1[keep]
        normal = np.repeat(nz[None], x.size, axis=0)
        return x, p1 + 0.5 * x[:, None] * normal, normal
    if np_.method == "sphere":
        if s1.kind == "sphere":
            centre, r = c1, float(s1.size[0])
            dist, q, n_out = sphere_closest(s2, c2, R2, centre)
            n = n_out  # body 2's outward normal points to body 1
        else:
            centre, r = c2, float(s2.size[0])
            dist, q, n_out = sphere_closest(s1, c1, R1, centre)
            n = -n_out
        x = r - dist
        if not x > -reach:
            return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        # q on the capsule/cylinder; the sphere's point nearest it is centre - r n_out
        mid = 0.5 * (q + centre - r * n_out)
        return np.array([x]), mid[None], n[None]
    (u1, l1), (u2, l2) = np_.link1, np_.link2
    rows = pb.getClosestPoints(u1, u2, reach + s1.margin + s2.margin + SMOOTH_REACH, l1, l2, physicsClientId=client)
    if not rows:
        return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
    x = np.array([-(r[8] + s1.margin + s2.margin) for r in rows])
    n = np.array([r[7] for r in rows], dtype=float)
    pa = np.array([r[5] for r in rows], dtype=float) + s1.margin * n  # A's surface inside its margin
    pb_ = np.array([r[6] for r in rows], dtype=float) - s2.margin * n
    mid = 0.5 * (pa + pb_)
    g1 = np_.geom1 if s1.kind == "mesh" else None  # a mesh's vertex -> the smooth surface it stands for
    g2 = np_.geom2 if s2.kind == "mesh" else None
    if g1 is not None or g2 is not None:
        for k in range(x.size):
            x[k], mid[k] = smooth_contact(g1, (c1, R1), g2, (c2, R2), x[k], mid[k], n[k])
    keep = x > -reach
    return x[keep], mid[keep], n[keep]


__all__ = ["LinkShape", "NarrowPair", "NARROW_KINDS", "NARROW_SLOTS", "as_cylinder", "assign_plane_slots", "detect",
           "ellipsoid_vertices", "floor_face", "on_face", "ring_prism",
           "features_on_plane", "msf_shape", "pair_method", "slots_of", "sphere_closest"]
