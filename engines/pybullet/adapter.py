"""The pybullet adapter: force laws between pairs of bodies through
``applyExternalForce`` (the contract is in :mod:`engines.base`).

What it does each engine step (``step``):

1. For every pair, read the poses (``getBasePositionAndOrientation``, or
   ``getLinkState`` for a link) and velocities (``getBaseVelocity``, or
   ``getLinkState(computeLinkVelocity=1)``), find the contact of the two
   smooth shapes (sphere-plane, sphere-box face, sphere-sphere) and the
   inverse effective inertia at the contact point: free bodies from their
   world inertia, links of multibodies from pybullet's own
   ``calculateJacobian`` and ``calculateMassMatrix`` (W = J M^-1 J^T).
2. Hand the pairs that touch or may touch within the step to the contact
   manager, which integrates the law over the step and returns the
   step-averaged force.
3. Apply it with ``applyExternalForce(..., WORLD_FRAME)`` at the contact
   point on body 1 and the opposite on body 2 (a fixed body, mass 0, takes
   none), then ``stepSimulation``. pybullet clears external forces after
   every step, so they are applied every step.

pybullet's own response for the pairs is switched off with
``setCollisionFilterPair(..., enableCollision=0)``, so nothing is counted twice.

The relative acceleration of the contact points from everything but these
contacts (``a_ext``) is measured: the change of v_rel over the last step
minus W times the impulse this adapter applied, over dt. Before the first
step it is gravity for free bodies (a link's first-step acceleration from
gravity and motors is not known and taken as zero; it is measured from the
second step on).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as pb

from engines import _geometry
from engines._contacts import closing_distance, effective_inverse_inertia_free
from engines.base import ContactKinematics, EngineAdapter, PairSpec

#: Candidates are handed to the manager while x > -CANDIDATE_FACTOR times
#: the distance the surfaces can close in one step: a safety factor 2 on the
#: constant-acceleration prediction, since a_ext is an estimate.
CANDIDATE_FACTOR = 2.0
#: A law's curvature and the shapes' radii must agree to this relative
#: tolerance (a law built for another ball would give wrong forces silently).
RADIUS_RTOL = 1e-9

_SHAPE_NAMES = {pb.GEOM_SPHERE: "sphere", pb.GEOM_BOX: "box", pb.GEOM_CAPSULE: "capsule",
                pb.GEOM_CYLINDER: "cylinder", pb.GEOM_PLANE: "plane", pb.GEOM_MESH: "mesh"}
_SUPPORTED = ("sphere", "plane", "box")


@dataclass(frozen=True)
class _Shape:
    """One collision shape in its link's inertial frame."""

    kind: str  # "sphere", "plane", "box"
    size: np.ndarray  # sphere: (radius,); box: half extents (3,); plane: unit normal (3,)
    pos: np.ndarray  # (3,) [m] relative to the link's centre of mass
    rot: np.ndarray  # (3, 3)


@dataclass
class _Pose:
    """A body's world state at the start of a step."""

    com: np.ndarray  # (3,) [m]
    rot: np.ndarray  # (3, 3) inertial frame to world
    v: np.ndarray  # (3,) [m/s] centre-of-mass velocity
    w: np.ndarray  # (3,) [rad/s]
    frame: np.ndarray  # (3,) [m] origin of the link (URDF/joint) frame; the centre of mass for a base


def _mat(quat) -> np.ndarray:
    return np.array(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)


class PybulletAdapter(EngineAdapter):
    """Force laws between pairs of pybullet bodies.

    client: a pybullet physics client id (DIRECT or GUI), stepped only
        through this adapter while it is in use.
    pairs: PairSpec with ``body1``/``body2`` = (body unique id, link index),
        link -1 the base; each link must carry exactly one collision shape,
        a sphere, plane or box (a box is met on its faces only).
    """

    name = "pybullet"

    def __init__(self, client: int, pairs: list[PairSpec]):
        if not isinstance(client, int) or not pb.isConnected(client):
            raise ValueError(f"client = {client!r} is not a connected pybullet physics client")
        self.client = client
        self._dt = float(pb.getPhysicsEngineParameters(physicsClientId=client)["fixedTimeStep"])
        if not self._dt > 0:
            raise ValueError(f"the client's time step = {self._dt!r} s must be > 0 (setTimeStep)")
        pairs = list(pairs)
        self._bodies: list[tuple[tuple[int, int], tuple[int, int]]] = []
        self._shapes: list[tuple[_Shape, _Shape]] = []
        for i, p in enumerate(pairs):
            if not isinstance(p, PairSpec):
                raise ValueError(f"pairs[{i}] = {p!r} is not a PairSpec")
            b1, b2 = self._check_body(p.body1, f"pairs[{i}].body1"), self._check_body(p.body2, f"pairs[{i}].body2")
            if b1 == b2:
                raise ValueError(f"pairs[{i}]: body1 and body2 are the same link {b1}")
            s1, s2 = self._shape(b1, f"pairs[{i}].body1"), self._shape(b2, f"pairs[{i}].body2")
            try:
                _geometry.check_pair_supported(s1.kind, s2.kind)
            except ValueError as e:
                raise ValueError(f"pairs[{i}] ({b1}, {b2}): {e}") from None
            if self._fixed(b1) and self._fixed(b2):
                raise ValueError(f"pairs[{i}]: both {b1} and {b2} are fixed (mass 0)")
            _check_curvature(i, p, s1, s2)
            self._bodies.append((b1, b2))
            self._shapes.append((s1, s2))
        super().__init__(pairs)
        for (u1, l1), (u2, l2) in self._bodies:
            pb.setCollisionFilterPair(u1, u2, l1, l2, enableCollision=0, physicsClientId=client)
        n = len(self.pairs)
        self._last_v_rel = np.zeros((n, 3))
        self._last_dv_own = np.zeros((n, 3))
        self._have_last = np.zeros(n, bool)
        self._last_a_ext = np.zeros((n, 3))
        #: total impulse this adapter applied on body 1 of each pair [N s] (n, 3)
        self.impulse = np.zeros((n, 3))
        self._steps = 0
        self._closed = False
        self.manager.set_body_probe(self._probe)

    # -- validation ---------------------------------------------------------
    def _check_body(self, b, label):
        c = self.client
        try:
            uid, link = int(b[0]), int(b[1])
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"{label} = {b!r}: give (body unique id, link index)") from None
        ids = [pb.getBodyUniqueId(k, physicsClientId=c) for k in range(pb.getNumBodies(physicsClientId=c))]
        if uid not in ids:
            raise ValueError(f"{label}: body unique id {uid} is not in the model (bodies: {ids})")
        nj = pb.getNumJoints(uid, physicsClientId=c)
        if not -1 <= link < nj:
            raise ValueError(f"{label}: link index {link} is outside [-1, {nj - 1}] of body {uid}")
        if nj > 0 and not self._base_fixed(uid):
            raise ValueError(f"{label}: body {uid} is a floating-base multibody with joints; links of fixed-base "
                             "multibodies and free single bodies are supported")
        return uid, link

    def _base_fixed(self, uid):
        return pb.getDynamicsInfo(uid, -1, physicsClientId=self.client)[0] == 0.0

    def _fixed(self, b):
        uid, link = b
        if link == -1:
            return self._base_fixed(uid)
        return False

    def _articulated(self, b):
        return b[1] >= 0

    def _shape(self, b, label) -> _Shape:
        data = pb.getCollisionShapeData(b[0], b[1], physicsClientId=self.client)
        if len(data) != 1:
            raise ValueError(f"{label} {b}: has {len(data)} collision shapes; exactly one (sphere, plane or box) "
                             "is supported")
        _, _, gtype, dims, _, lpos, lorn = data[0]
        kind = _SHAPE_NAMES.get(gtype, f"geometry type {gtype}")
        if kind not in _SUPPORTED:
            raise ValueError(f"{label} {b}: collision shape {kind!r} is not supported (MSF needs smooth "
                             f"curvature); supported: {', '.join(_SUPPORTED)}")
        if kind == "sphere":
            size = np.array([dims[0]])
        elif kind == "box":
            size = 0.5 * np.asarray(dims, dtype=float)  # getCollisionShapeData gives full extents
        else:
            size = np.asarray(dims, dtype=float) / np.linalg.norm(dims)
        return _Shape(kind, size, np.asarray(lpos, dtype=float), _mat(lorn))

    # -- contract -------------------------------------------------------------
    @property
    def timestep(self) -> float:
        return self._dt

    def step(self, n: int = 1) -> None:
        if int(n) != n or n < 0:
            raise ValueError(f"n = {n!r} steps must be a non-negative integer")
        if self._closed:
            raise RuntimeError("the adapter is closed")
        for _ in range(int(n)):
            self._step_once()

    def close(self) -> None:
        """Disconnect the client (the adapter owns it from construction on)."""
        if not self._closed and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    # -- reading the engine ---------------------------------------------------
    def _pose(self, b) -> _Pose:
        uid, link = b
        c = self.client
        if link == -1:
            pos, orn = pb.getBasePositionAndOrientation(uid, physicsClientId=c)
            v, w = pb.getBaseVelocity(uid, physicsClientId=c)
            frame = pos
        else:
            st = pb.getLinkState(uid, link, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=c)
            pos, orn, frame, v, w = st[0], st[1], st[4], st[6], st[7]
        return _Pose(np.asarray(pos, float), _mat(orn), np.asarray(v, float), np.asarray(w, float),
                     np.asarray(frame, float))

    def _joint_state(self, uid):
        c = self.client
        movable = [j for j in range(pb.getNumJoints(uid, physicsClientId=c))
                   if pb.getJointInfo(uid, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
        states = pb.getJointStates(uid, movable, physicsClientId=c)
        return [s[0] for s in states], [s[1] for s in states]

    def _jacobian(self, b, pose, point):
        """Translational Jacobian (3, ndof) of the material point of link b at ``point``."""
        uid, link = b
        q, qd = self._joint_state(uid)
        # calculateJacobian's localPosition is measured from the link (URDF) frame's origin but
        # expressed in the inertial frame's axes, not "around the centre of mass" as documented
        # (bulletphysics/bullet3 #4668; checked in tests/test_pybullet.py against the hinge inertia)
        local = pose.rot.T @ (point - pose.frame)
        Jt, _ = pb.calculateJacobian(uid, link, local.tolist(), q, qd, [0.0] * len(q), physicsClientId=self.client)
        return np.asarray(Jt, float).reshape(3, -1)

    def _mass_matrix(self, uid):
        q, _ = self._joint_state(uid)
        return np.asarray(pb.calculateMassMatrix(uid, q, physicsClientId=self.client), float)

    def _free_inverse_inertia(self, b, pose, point):
        """(W, W_com) contributions of a free (or fixed) single body."""
        if self._fixed(b):
            return np.zeros((3, 3)), np.zeros((3, 3))
        info = pb.getDynamicsInfo(b[0], b[1], physicsClientId=self.client)
        m, Idiag = info[0], np.asarray(info[2], float)
        # getBasePositionAndOrientation gives the inertial frame: its axes are the principal ones
        I_world = pose.rot @ np.diag(Idiag) @ pose.rot.T
        W = effective_inverse_inertia_free(m, I_world, point - pose.com, math.inf, None, np.zeros(3))
        return W, np.eye(3) / m

    def _inverse_inertia(self, i, poses, point):
        """W and W_com of pair i at ``point`` (module docstring, contract item 3)."""
        b1, b2 = self._bodies[i]
        art1, art2 = self._articulated(b1), self._articulated(b2)
        W = np.zeros((3, 3))
        Wc = np.zeros((3, 3))
        if art1 and art2 and b1[0] == b2[0]:
            # two links of one chain: J = J1 - J2 over the shared coordinates
            Minv = np.linalg.inv(self._mass_matrix(b1[0]))
            J = self._jacobian(b1, poses[0], point) - self._jacobian(b2, poses[1], point)
            Jc1 = self._jacobian(b1, poses[0], poses[0].com)
            Jc2 = self._jacobian(b2, poses[1], poses[1].com)
            return J @ Minv @ J.T, (Jc1 - Jc2) @ Minv @ J.T
        # +P on body 1 and -P on body 2: both bodies' terms add to the relative change
        for b, pose in ((b1, poses[0]), (b2, poses[1])):
            if self._articulated(b):
                Minv = np.linalg.inv(self._mass_matrix(b[0]))
                J = self._jacobian(b, pose, point)
                Jc = self._jacobian(b, pose, pose.com)
                W += J @ Minv @ J.T
                Wc += Jc @ Minv @ J.T
            else:
                w, wc = self._free_inverse_inertia(b, pose, point)
                W += w
                Wc += wc
        return W, Wc

    def _world_shape(self, shape: _Shape, pose: _Pose):
        return pose.com + pose.rot @ shape.pos, pose.rot @ shape.rot

    def _detect(self, i, poses, margin=math.inf):
        """(x, n body2->body1, point mid-overlap) of pair i (:mod:`engines._geometry`)."""
        (s1, s2) = self._shapes[i]
        c1, R1 = self._world_shape(s1, poses[0])
        c2, R2 = self._world_shape(s2, poses[1])
        flip = s1.kind != "sphere"
        if flip:  # the detectors take the sphere first; the roles are swapped back below
            s1, s2, c1, c2, R1, R2 = s2, s1, c2, c1, R2, R1
        r1 = float(s1.size[0])
        if s2.kind == "sphere":
            det = _geometry.sphere_sphere(c1, r1, c2, float(s2.size[0]))
        elif s2.kind == "plane":
            det = _geometry.sphere_plane(c1, r1, c2, R2 @ s2.size)
        else:
            det = _geometry.sphere_box_face(c1, r1, c2, R2, s2.size, margin=margin)
        if flip:
            det = det.swapped()
        return float(det.x[0]), det.normal[0], det.point[0]

    def _kinematics(self):
        n = len(self.pairs)
        rows = []
        par = pb.getPhysicsEngineParameters(physicsClientId=self.client)
        grav = np.array([par[k] for k in ("gravityAccelerationX", "gravityAccelerationY", "gravityAccelerationZ")])
        for i in range(n):
            b1, b2 = self._bodies[i]
            poses = (self._pose(b1), self._pose(b2))
            x, nrm, point = self._detect(i, poses, self._edge_margin(i, poses, grav))
            v1 = poses[0].v + np.cross(poses[0].w, point - poses[0].com)
            v2 = poses[1].v + np.cross(poses[1].w, point - poses[1].com)
            v_rel = v1 - v2
            v_com_rel = poses[0].v - poses[1].v
            if self._have_last[i]:
                a_ext = (v_rel - self._last_v_rel[i] - self._last_dv_own[i]) / self._dt
            else:
                a_ext = grav * (self._free(b1) - self._free(b2))
            self._last_a_ext[i] = a_ext
            rows.append((i, x, nrm, point, v_rel, v_com_rel, a_ext, poses))
        return rows

    def _edge_margin(self, i, poses, grav) -> float:
        """Gap below which a sphere over a box edge is refused: a bound on the
        distance the surfaces can close within one step (inf while in contact)."""
        if i in self._required():
            return math.inf
        ext = [float(s.size[0]) if s.kind == "sphere" else float(np.linalg.norm(s.pos) + np.linalg.norm(s.size))
               for s in self._shapes[i]]
        vb = (np.linalg.norm(poses[0].v - poses[1].v) + np.linalg.norm(poses[0].w) * ext[0]
              + np.linalg.norm(poses[1].w) * ext[1])
        if self._have_last[i]:
            ab = np.linalg.norm((self._last_a_ext[i]))
        else:
            ab = 2.0 * np.linalg.norm(grav)
        return CANDIDATE_FACTOR * (vb * self._dt + 0.5 * ab * self._dt**2)

    def _free(self, b) -> float:
        return 1.0 if (not self._articulated(b) and not self._fixed(b)) else 0.0

    def _required(self) -> set:
        """Pairs the manager needs listed this step whatever their gap (in
        contact, or with a timing correction to remove)."""
        return set(int(i) for i in self.manager.required_pairs)

    # -- one step -------------------------------------------------------------
    def _step_once(self):
        dt = self._dt
        c = self.client
        cand = []
        W_of = {}
        required = self._required()
        for i, x, nrm, point, v_rel, v_com_rel, a_ext, poses in self._kinematics():
            closing = float(closing_distance(-(v_rel @ nrm), -(a_ext @ nrm), dt, CANDIDATE_FACTOR))
            if x > -closing or i in required:
                W, Wc = self._inverse_inertia(i, poses, point)
                W_of[i] = W
                cand.append((i, x, nrm, point, v_rel, v_com_rel, W, Wc, a_ext))
            self._last_v_rel[i] = v_rel
            self._last_dv_own[i] = 0.0
            self._have_last[i] = True
        # the manager steps every engine step, also with no candidate: it
        # completes finished records once their timing correction is gone
        kin = ContactKinematics(
            pair=np.array([r[0] for r in cand], int),
            x=np.array([r[1] for r in cand], float),
            normal=np.array([r[2] for r in cand], float).reshape(-1, 3),
            point=np.array([r[3] for r in cand], float).reshape(-1, 3),
            v_rel=np.array([r[4] for r in cand], float).reshape(-1, 3),
            v_com_rel=np.array([r[5] for r in cand], float).reshape(-1, 3),
            W=np.array([r[6] for r in cand], float).reshape(-1, 3, 3),
            W_com=np.array([r[7] for r in cand], float).reshape(-1, 3, 3),
            a_ext=np.array([r[8] for r in cand], float).reshape(-1, 3),
            t=self.time,
        )
        out = self.manager.step(kin)
        for k, i in enumerate(np.asarray(out.pair, int)):
            F = np.asarray(out.force[k], float)
            if not np.any(F):
                continue
            P = np.asarray(out.point[k], float)
            (u1, l1), (u2, l2) = self._bodies[i]
            if not self._fixed((u1, l1)):
                pb.applyExternalForce(u1, l1, F.tolist(), P.tolist(), pb.WORLD_FRAME, physicsClientId=c)
            if not self._fixed((u2, l2)):
                pb.applyExternalForce(u2, l2, (-F).tolist(), P.tolist(), pb.WORLD_FRAME, physicsClientId=c)
            self._last_dv_own[i] = W_of[i] @ (F * dt)
            self.impulse[i] += F * dt
        pb.stepSimulation(physicsClientId=c)
        self._steps += 1

    # -- records ----------------------------------------------------------------
    def _probe(self, i) -> dict:
        """Body-level quantities for the manager's records (its body probe):
        body 1's angular velocity gives spin_in/spin_out about n x t."""
        b1, _ = self._bodies[i]
        return {"omega1": self._pose(b1).w}

    @property
    def time(self) -> float:
        """Engine time since the adapter was made [s]."""
        return self._steps * self._dt

    def body_state(self, b) -> _Pose:
        """World pose and velocities of a (body, link) [SI]."""
        return self._pose(b)


def _check_curvature(i, p: PairSpec, s1: _Shape, s2: _Shape) -> None:
    """The law's radii must be the shapes' (body 1's radii are R1a, R1b)."""
    R1 = float(s1.size[0]) if s1.kind == "sphere" else math.inf
    R2 = float(s2.size[0]) if s2.kind == "sphere" else math.inf
    curv = p.law.curvature
    for label, want, got in (("R1a", R1, curv.R1a), ("R1b", R1, curv.R1b),
                             ("R2a", R2, curv.R2a), ("R2b", R2, curv.R2b)):
        same = (math.isinf(want) and math.isinf(got)) or (
            math.isfinite(want) and math.isfinite(got) and abs(got - want) <= RADIUS_RTOL * want)
        if not same:
            raise ValueError(f"pairs[{i}]: the law's curvature {label} = {got!r} m does not match the collision "
                             f"shape's radius {want!r} m of {p.body1 if label[1] == '1' else p.body2}")
