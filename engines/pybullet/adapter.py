"""The pybullet adapter: force laws between pairs of bodies through
``applyExternalForce`` (the contract is in :mod:`engines.base`).

(Over 600 lines because the candidate search, the kinematics and the force
application share one client's per-step caches, and the engine-path issues
are reworking the step: its split waits for that rework.)

What it does each engine step (``step``):

1. Read every body of the pairs once (``getBasePositionAndOrientation`` and
   ``getBaseVelocity``, or ``getLinkState(computeLinkVelocity=1)`` for a
   link; pybullet has no call that reads several bodies), find the contact
   of the two smooth shapes (sphere-plane, sphere-box face, sphere-sphere)
   and the inverse effective inertia at the contact point: free bodies from
   their world inertia, links of multibodies from pybullet's own
   ``calculateJacobian`` and ``calculateMassMatrix`` (W = J M^-1 J^T).
   Pairs of a free sphere and a plane, a fixed sphere or another free
   sphere are done for all of them at once (detection, velocities, W in
   closed form), compiled in :mod:`engines.pybullet._kernels` or, with
   ``compiled=False``, in numpy; box faces and links go pair by pair. Masses
   and inertias are read once, at construction (``changeDynamics``
   afterwards is not seen).
2. Hand the pairs that touch or may touch within the step to the contact
   manager, which integrates the law over the step and returns the
   step-averaged force.
3. Apply it with ``applyExternalForce(..., WORLD_FRAME)`` at the contact
   point on body 1 and the opposite on body 2 (a fixed body, mass 0, takes
   none), then ``stepSimulation``. pybullet clears external forces after
   every step, so they are applied every step. A free body in several
   touching pairs takes one call: the forces' sum at its centre of mass and
   their torque about it (``applyExternalTorque``), the same force and
   torque pybullet makes of forces at points.

Per step and body this is two reads and one force, the floor of pybullet's
Python API (~0.5 us a call; there is no call that reads or pushes several
bodies); the array work between them is compiled.

pybullet's own response for the pairs is switched off with
``setCollisionFilterPair(..., enableCollision=0)``, so nothing is counted
twice, and switched back on by :meth:`PybulletAdapter.close`, which never
disconnects the client. pybullet has no force callback: while the adapter
is open, :meth:`PybulletAdapter.step` replaces ``stepSimulation``; a step
taken without it, or a body reset, is seen at the next step start (a free
body's centre of mass is not the last one plus dt times its velocity) and
interrupts the pairs' contacts, with a warning unless declared with
:meth:`PybulletAdapter.placed`.

The relative acceleration of the contact points from everything but the
managed contacts (``a_ext``) is measured: the change of v_rel over the last
step minus the change the impulses of the pairs applied in that step caused
(each including the manager's timing correction), over dt. That change is
sum_q W_pq P_q with the cross inverse inertia W_pq = J_p M^-1 J_q^T between
the contact points of pairs p and q (zero when they share no moving body):
for free bodies in closed form (each body's impulse and angular impulse
about its centre of mass summed over its pairs, then 1/m and I^-1), for
links of a multibody through its Jacobians and mass matrix. Subtracting only
the pair's own impulse counted a body's other contacts as outside
acceleration one step late: a bead-bead impulse entered the bead's plate
contact as a huge a_ext. The pairs whose force is held into the next step
(:func:`held_forces`: resting contacts, and contacts the step resolves) are
the exception: their step-averaged force is the best prediction of their
force over the next step, so it is left in the other pairs' a_ext (without
it a resting stack rests too deep, e.g. 80% at dt = 1 ms for rubber balls).
Before the first step a_ext is gravity for free bodies (a link's first-step
acceleration from gravity and motors is not known and taken as zero; it is
measured from the second step on).
"""

from __future__ import annotations

import gc
import math
import time
import warnings
from dataclasses import dataclass
from itertools import chain, repeat

import numpy as np
import pybullet as pb

from engines import _geometry
from engines._geometry import cross_rows
from engines._kinematic import interrupt_placements
from engines._contacts import SETTLE_AFTER_DURATIONS, _skew, closing_distance, effective_inverse_inertia_free
from engines._contacts.islands import TOUCH_TOL, push_reach
from engines._contacts.balance import DeepOnsets
from engines._contacts import snapshot as _snapshot
from engines._contacts.state import CENTRED_RTOL, lever_terms_free
from engines.pybullet.scenes import MAX_COORDINATE_VELOCITY
from engines.base import STEPS_PER_CONTACT_MIN, ContactKinematics, EngineAdapter, PairSpec, check_law_curvature
from engines.pybullet import narrow as _narrow
from engines.pybullet.narrow import LinkShape

#: A free body's centre of mass at a step start must be the last one plus dt
#: times its velocity to ADVANCE_ATOL + ADVANCE_RTOL (|com| + dt |v|) [m]
#: (pybullet's semi-implicit Euler, exact to round-off: 1e-17 m measured at
#: dt = 1 ms); otherwise the simulation advanced without the adapter, or a
#: body was placed.
ADVANCE_ATOL = 1e-12
ADVANCE_RTOL = 1e-9

#: Candidates are handed to the manager while x > -CANDIDATE_FACTOR times
#: the distance the surfaces can close in one step: a safety factor 2 on the
#: constant-acceleration prediction, since a_ext is an estimate.
CANDIDATE_FACTOR = 2.0
#: A sphere through a box is handed back to MSF beyond this gap [m] plus what a step closes (EngineAdapter._through).
THROUGH_REACH = 1e-3

#: A link held by a user constraint (``createConstraint``) is solved rigidly by
#: pybullet at the step, while the MSF sub-cycle sees only the link's inertia:
#: the contact impulse of a step reaches the constraint one step late. The
#: first-bounce COR of a rubber ball (R = 20 mm, 2 m/s) on a constraint-held
#: paddle (tests/test_held_link_pybullet.py), against dt = 0.2 ms: -1.8 % at 0.5 ms
#: (4.8 steps per contact), -7.3 % at 1 ms (2.4 steps), -5.3 % at 2 ms (1.2
#: steps). The result holds (2 %) from 4.8 steps per contact and fails at 2.4:
#: below this many steps per contact a held pair's records are flagged and
#: warned about, dt_max = tau / HELD_MIN_STEPS (docs/engines.md).
HELD_MIN_STEPS = 4.0

#: A joint that moved into a limit faster than this at the last step start
#: and is now at the limit was stopped there by pybullet's rigid limit (an
#: impulse in its multibody's finite-difference a_ext) [rad/s or m/s]: a
#: joint resting on its limit moves into it at ~0 (no position correction,
#: robots.LIMIT_ERP); 0.01 rad/s on a 0.3 m leg is a velocity change of
#: 3 mm/s, g dt / 6 at 2 ms.
LIMIT_STOP_SPEED = 1e-2

#: A mesh's slot keeps its hull vertex while the vertex's point in the body's
#: frame stays within this share of the mesh's size (a vertex's coordinates
#: are exact; hull vertices lie a few mm apart) [-] (narrow.assign_plane_slots).
SAME_VERTEX = 1e-6

#: A joint within this of a limit of its range [rad or m] is held there by
#: pybullet's limit constraint: the contact's inverse inertia treats it as
#: locked (PybulletAdapter._minv). pybullet lets a loaded joint sit slightly
#: beyond its limit; 1e-3 rad is far below a joint's travel in one step.
JOINT_LIMIT_TOL = 1e-3

#: A joint's end speed in the trial step (PybulletAdapter._limit_trial)
#: within this of one of its limit rows' bounds was held by that limit
#: [rad/s or m/s]: measured on pybullet_data's ant under random torques at 10
#: ms, held joints end 0-2.5e-5 rad/s from the bound (pybullet's iterative
#: solver), free ones >= 0.1 rad/s from both.
ENGAGED_ATOL = 1e-3

_SHAPE_NAMES = {pb.GEOM_SPHERE: "sphere", pb.GEOM_BOX: "box", pb.GEOM_CAPSULE: "capsule",
                pb.GEOM_CYLINDER: "cylinder", pb.GEOM_PLANE: "plane", pb.GEOM_MESH: "mesh",
                pb.GEOM_HEIGHTFIELD: "heightfield"}
_SUPPORTED = ("sphere", "plane", "box", "capsule", "cylinder", "mesh")
#: One collision shape in its link's inertial frame (engines.pybullet.narrow.LinkShape).
_Shape = LinkShape


@dataclass
class _Pose:
    """A body's world state at the start of a step."""

    com: np.ndarray  # (3,) [m]
    rot: np.ndarray  # (3, 3) inertial frame to world
    v: np.ndarray  # (3,) [m/s] centre-of-mass velocity
    w: np.ndarray  # (3,) [rad/s]
    frame: np.ndarray  # (3,) [m] origin of the link (URDF/joint) frame; the centre of mass for a base


#: joint types pybullet's calculateJacobian refuses ("Spherical joints are not supported in the pybullet binding")
_JOINT_NAMES = {pb.JOINT_SPHERICAL: "spherical", pb.JOINT_PLANAR: "planar"}


def _mat(quat) -> np.ndarray:
    return np.array(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)


def _mats(q) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of unit quaternions (x, y, z, w) (n, 4), as getMatrixFromQuaternion."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def held_forces(manager, pair, t_next: float) -> np.ndarray:
    """Which of the pairs ``pair`` (k,) hold their force into the next step:
    :meth:`engines._contacts.ContactManager.held` (one rule for both adapters)."""
    return manager.held(pair, t_next)


@dataclass
class _Bodies:
    """The world state of every body of the pairs at the start of a step, read
    once per body; arrays over the adapter's body list."""

    com: np.ndarray  # (B, 3) [m]
    rot: np.ndarray  # (B, 3, 3) inertial frame to world
    v: np.ndarray  # (B, 3) [m/s]
    w: np.ndarray  # (B, 3) [rad/s]
    frame: np.ndarray  # (B, 3) [m] link frame origin (the centre of mass for a base)

    def pose(self, j: int) -> "_Pose":
        return _Pose(self.com[j], self.rot[j], self.v[j], self.w[j], self.frame[j])


def check_client_params(par: dict, dt: float) -> None:
    """ValueError for client settings the adapter cannot step right
    (``pb.getPhysicsEngineParameters``' dict ``par``; dt [s] the step the
    adapter was made with): ``numSubSteps`` > 1 (pybullet splits each
    ``stepSimulation`` into sub-steps that move a body by other than
    dt v_end: every step reads as a jump, every contact is interrupted with
    no record; measured: a rubber ball bounced on plane.urdf with
    numSubSteps = 4 gave 0 records and 421 warnings in 3 s),
    ``useRealTimeSimulation`` (pybullet steps by itself, between the
    adapter's forces), and a time step changed since the adapter was made
    (the sub-cycle would integrate the wrong dt)."""
    if int(par["numSubSteps"]) > 1:
        raise ValueError(f"pybullet's numSubSteps = {int(par['numSubSteps'])} (setPhysicsEngineParameter): the adapter "
                         "needs one integration per stepSimulation (0 or 1); for a finer step call "
                         f"setTimeStep({dt:g} / {int(par['numSubSteps'])}) and adapter.step that many times instead")
    if int(par["useRealTimeSimulation"]):
        raise ValueError("pybullet's useRealTimeSimulation is on (setRealTimeSimulation(1)): pybullet then steps by "
                         "itself, between the adapter's forces; switch it off and call adapter.step()")
    if float(par["fixedTimeStep"]) != dt:
        raise ValueError(f"pybullet's time step changed to {float(par['fixedTimeStep']):g} s since the adapter was "
                         f"made with {dt:g} s (setTimeStep): make a new adapter for the new step")


class PybulletAdapter(EngineAdapter):
    """Force laws between pairs of pybullet bodies.

    client: a pybullet physics client id (DIRECT or GUI). The adapter never
        owns it (never disconnects it). While the adapter is open,
        :meth:`step` replaces ``stepSimulation()`` (pybullet has no force
        callback: it applies the forces, then steps); a step taken without it
        is detected at the next :meth:`step` and warned about (a jump: the
        pairs' contacts are interrupted). :meth:`close` (or leaving the
        ``with`` block) gives the pairs back to pybullet's own contact.
    pairs: PairSpec with ``body1``/``body2`` = (body unique id, link index),
        link -1 the base, or (body unique id, link index, k) for the k-th of
        a link's shapes given in ``link_shapes``. A sphere on a plane, a
        sphere or a box face is solved in closed form (:mod:`engines._geometry`);
        every other pair of sphere, plane, box, capsule, cylinder and mesh
        shapes through :mod:`engines.pybullet.narrow` (several contact points
        per pair, the curvature at each point from :mod:`msf_contact.shapes`;
        the law's curvature is checked at each contact's onset). body1 is the
        curved body (not a plane).
    edge_radii: {(body unique id, link index): edge radius [m]} of boxes and
        cylinders (``msf_contact.shapes.DEFAULT_EDGE_RADIUS`` otherwise).
    curvature: {(body unique id, link index): an msf_contact.shapes object}
        whose curvature replaces the shape's own (an ellipsoid made as a mesh:
        ``Ellipsoid(semi_axes)``; the mesh's own is a local fit).
    mesh_slots: {(body unique id, link index): k} contact points managed for a
        mesh link on a plane (1-8; default engines._narrow.default_mesh_slots:
        4 for a hull with a flat face it can rest on, whose vertices are
        contacts as a box's corners, 1 for a smooth mesh, its deepest point;
        engines.pybullet.narrow; MuJoCo's ``MujocoAdapter(mesh_slots=...)``).
    link_shapes: {(body unique id, link index): [LinkShape, ...]} the link's
        collision shapes, given where pybullet cannot report them
        (``getCollisionShapeData`` ends the process on a loadMJCF capsule made
        with fromto: engines.pybullet.robots gives them from the MJCF).
    limit_trial: find which joint limits hold a multibody of the pairs over
        each step by trying the step (:meth:`_limit_trial`): pybullet's
        state saved, the last step's MSF loads applied again (and, for a
        contact closing within the step, at least the force that stops it:
        :meth:`_trial_loads`), one ``stepSimulation``, the joints whose end speed is their limit row's
        bound taken as held, the state restored. A contact on a link beyond
        a held joint moves with it locked (W = J M^-1 J^T with those joints
        held) and the multibody's resting contacts are solved together.
        Without it a joint within JOINT_LIMIT_TOL of a limit is taken as
        held, which pybullet's one-sided limit is not when the loads pull it
        off (the ant landing on its ankle limits: its contacts' own balance
        rose 2.45 J in two steps; with the trial 0.003 J,
        tests/test_robots_pybullet.py). Costs one more ``stepSimulation``
        and a ``saveState`` per step (~1.3 ms on the ant; two with
        ``limit_retrial``). Set the joint
        torques through :meth:`set_joint_torques`: a TORQUE_CONTROL torque
        set with pybullet's own call acts for one ``stepSimulation``, the
        trial's, and is lost (pybullet cannot report it to be set again), as
        is a force of ``applyExternalForce`` given before :meth:`step`.
    limit_retrial: with ``limit_trial``, try the step a second time with the
        forces the contacts gave in it (:meth:`_limit_retrial`); where that
        trial holds other joints than the first, the contacts' step is taken
        again with them (the manager's state put back,
        engines._contacts.snapshot). Default True; False: one trial, as
        before (for comparison).
    anchor_depth: a contact on a link of a multibody whose internal approach
        x lies deeper than the engine's geometry allows (x_e plus the
        semi-implicit lead since its onset) is brought up to it at the step
        start, never deeper (:meth:`_anchor_depths`): default True; False
        keeps the internal x as integrated (as before, for comparison).
    trial_a_ext: with ``limit_trial``, a link contact's a_ext (the contact
        point's acceleration from everything but the contacts) taken from the
        trial step's own velocity change less its MSF loads' (:meth:`_trial_a_ext`),
        this step's, instead of the finite difference of the last step's
        velocities. Default True: given the held joints pybullet's step is
        affine in the loads to a few 1e-5 (measured: the real step's
        generalized velocity against the trial's plus dt M_H^-1 (Q - Q_trial),
        within 3e-8 with no joint held, median 9e-6 with the ant's four
        ankles held at rest), so a_ext is the step's own; the finite
        difference (False) is the last step's, and left the ant's rest after
        its torques single steps of 0.03-0.73 J above RestEnergy's bound
        (docs/engines.md). No effect without ``limit_trial``.
    compiled: do the per-step array work of the fast pairs (detection,
        velocities, a_ext, W, the cross-pair correction, the forces summed
        per body) in the numba kernels of :mod:`engines.pybullet._kernels`
        (default); False: in numpy (the reference the kernels are tested
        against, tests/test_pybullet_kernels.py).
    """

    name = "pybullet"

    def __init__(self, client: int, pairs: list[PairSpec], compiled: bool = True, *, edge_radii: dict | None = None,
                 curvature: dict | None = None, link_shapes: dict | None = None, mesh_slots: dict | None = None,
                 limit_trial: bool = False, limit_retrial: bool = True, anchor_depth: bool = True,
                 trial_a_ext: bool = True):
        if not isinstance(client, int) or not pb.isConnected(client):
            raise ValueError(f"client = {client!r} is not a connected pybullet physics client")
        if not isinstance(compiled, bool):
            raise ValueError(f"compiled = {compiled!r} must be True or False")
        if not isinstance(limit_trial, bool):
            raise ValueError(f"limit_trial = {limit_trial!r} must be True or False")
        if not isinstance(limit_retrial, bool):
            raise ValueError(f"limit_retrial = {limit_retrial!r} must be True or False")
        if not isinstance(anchor_depth, bool):
            raise ValueError(f"anchor_depth = {anchor_depth!r} must be True or False")
        if not isinstance(trial_a_ext, bool):
            raise ValueError(f"trial_a_ext = {trial_a_ext!r} must be True or False")
        #: with limit_trial, a link contact's a_ext from the trial's own velocity change (_trial_a_ext)
        self.trial_a_ext = trial_a_ext
        self._trial_end: dict[int, tuple] = {}  # the last trial's end state per multibody slot (_try_step)
        self._trial_used = None  # the loads the last trial applied ((pairs, forces, points) or None)
        self.client = client
        #: a link contact's internal approach kept no deeper than the engine's geometry (_anchor_depths)
        self.anchor_depth = anchor_depth
        self.limit_retrial = limit_retrial  #: a second trial with the step's own forces (_limit_retrial)
        self.limit_retrials = 0  #: steps whose contacts were solved again after the second trial (_limit_retrial)
        self.anchored = 0  #: contact-steps whose internal approach was brought up to the engine's (_anchor_depths)
        self.anchor_released = 0.0  #: elastic energy those moves released [J] (a loss in the contacts' balance)
        #: which joint limits hold a multibody found by a trial step (_limit_trial), not by the joints' positions
        self.limit_trial = limit_trial
        self.limit_trials = 0  #: trial steps taken (_limit_trial)
        self.limit_trial_s = 0.0  #: wall time spent in them [s] (benchmarks/robots_pybullet.py reports its share)
        #: steps whose real step held a joint the trial left free, and left free one it held, per multibody
        #: (_count_trial_misses)
        self.limit_trial_misses = [0, 0]
        self._engaged: dict[int, np.ndarray] = {}  # per multibody: its movable joints a limit held in the trial
        self._engaged_at = -1  # the step whose trial _engaged is from
        self.compiled = compiled
        if compiled:
            from engines.pybullet import _kernels  # numba: imported only when used
            self._k = _kernels
        self._fixed_cache: dict[int, bool] = {}  # body unique id -> base has mass 0 (read once)
        par = pb.getPhysicsEngineParameters(physicsClientId=client)
        self._dt = float(par["fixedTimeStep"])
        if not self._dt > 0:
            raise ValueError(f"the client's time step = {self._dt!r} s must be > 0 (setTimeStep)")
        check_client_params(par, self._dt)
        pairs = list(pairs)
        self.edge_radii = {self._link_key(k, "edge_radii"): float(v) for k, v in (edge_radii or {}).items()}
        self.curvature_shapes = {self._link_key(k, "curvature"): v for k, v in (curvature or {}).items()}
        self._link_shapes = {self._link_key(k, "link_shapes"): list(v) for k, v in (link_shapes or {}).items()}
        self.mesh_slots = {self._link_key(k, "mesh_slots"): v for k, v in (mesh_slots or {}).items()}
        for key, k in self.mesh_slots.items():
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 8:
                raise ValueError(f"mesh_slots[{key!r}] = {k!r} must be a whole number in [1, 8]")
        self._bodies: list[tuple[tuple[int, int], tuple[int, int]]] = []
        self._shapes: list[tuple[_Shape, _Shape]] = []
        #: the pairs carried by several contact slots (engines.pybullet.narrow); per slot (pair, slot) or (-1, 0)
        self._narrow: list[_narrow.NarrowPair] = []
        self._narrow_of: list[tuple[int, int]] = []
        #: per sphere-box pair (its index): the sphere on the rounded box (engines._narrow.SphereOnBox)
        self._sphere_box: dict = {}
        expanded = []
        for i, p in enumerate(pairs):
            if not isinstance(p, PairSpec):
                raise ValueError(f"pairs[{i}] = {p!r} is not a PairSpec")
            b1, b2 = self._check_body(p.body1, f"pairs[{i}].body1"), self._check_body(p.body2, f"pairs[{i}].body2")
            if b1 == b2:
                raise ValueError(f"pairs[{i}]: body1 and body2 are the same link {b1}")
            s1, s2 = self._shape(p.body1, f"pairs[{i}].body1"), self._shape(p.body2, f"pairs[{i}].body2")
            if self._fixed(b1) and self._fixed(b2):
                raise ValueError(f"pairs[{i}]: both {b1} and {b2} are fixed (mass 0)")
            try:
                _geometry.check_pair_supported(s1.kind, s2.kind)
                analytic = b1 not in self.curvature_shapes and b2 not in self.curvature_shapes
            except ValueError:
                analytic = False
            if analytic:  # the closed-form paths (engines._geometry), kept as they are
                _check_curvature(i, p, s1, s2)
                if "box" in (s1.kind, s2.kind):  # the box rounded by its edge radius (engines._narrow.SphereOnBox)
                    from engines._contacts.compiled import kernel_law
                    from engines._narrow import SphereOnBox

                    sph, (bb, box) = (s1, (b2, s2)) if s1.kind == "sphere" else (s2, (b1, s1))
                    self._sphere_box[len(self._bodies)] = SphereOnBox(
                        float(sph.size[0]), _narrow.msf_shape(box, self.edge_radii.get(bb)), p.law, kernel_law,
                        flip=s1.kind != "sphere")
                self._bodies.append((b1, b2))
                self._shapes.append((s1, s2))
                self._narrow_of.append((-1, 0))
                expanded.append(p)
                continue
            for q in range(self._add_narrow(i, p, b1, b2, s1, s2)):
                self._bodies.append((b1, b2))
                self._shapes.append((s1, s2))
                self._narrow_of.append((len(self._narrow) - 1, q))
                expanded.append(p)
        self._check_compounds(pairs)
        super().__init__(expanded)
        for i, sb in self._sphere_box.items():  # each sphere-box pair's own law, its curvature following the point
            self.manager.set_law(i, sb.law)
        for (u1, l1), (u2, l2) in self._bodies:
            pb.setCollisionFilterPair(u1, u2, l1, l2, enableCollision=0, physicsClientId=client)
        self._setup_batches()
        n = len(self.pairs)
        self._last_v_rel = np.zeros((n, 3))
        #: the change of each pair's v_rel the last step's impulses caused (held forces excepted) [m/s] (n, 3)
        self._last_dv = np.zeros((n, 3))
        self._pt = np.zeros((n, 3))  #: each pair's contact point at the last step start [m] (n, 3)
        self._have_last = np.zeros(n, bool)
        self._last_a_ext = np.zeros((n, 3))
        #: total impulse this adapter applied on body 1 of each pair [N s] (n, 3)
        self.impulse = np.zeros((n, 3))
        self._steps = 0
        self._closed = False
        self.manager.set_body_probe(self._probe)
        self.manager.set_orientation_free([[self._orientation_free(b, s) for b, s in zip(bb, ss)]
                                           for bb, ss in zip(self._bodies, self._shapes)])
        self.pair_names = [(self._body_name(b1), self._body_name(b2)) for b1, b2 in self._bodies]
        self.manager.pair_names = self.pair_names
        # contacts sharing a moving body are solved together (engines._islands): a free body's key
        # is its slot, the links of one multibody share one key, a fixed body has none (-1)
        B = len(self._body_list)
        key = np.where(self._b_free, np.arange(B), -1)
        key = np.where(self._b_art, B + self._b_uid, key)
        self._keys = key[self._slot].astype(np.int64)
        self._push = np.full(n, TOUCH_TOL)  # extra candidate reach from the bodies' other contacts [m] (_islands.push_reach)
        self._gaps = np.full(n, np.nan)  # every pair's x read in the last step [m] (push_reach's paths; NaN: not read)
        self._pushed = False  # push_reach has run (the first step lists again with its own push: _first_push)
        self._cur_bodies: _Bodies | None = None
        #: the loads the last step applied (pairs (k,), forces (k, 3) [N] on body 1 at points (k, 3) [m],
        #: couples (k, 3) [N m] or None, the bodies' state at the step start) or None: last_step_work
        self._last_loads = None
        self._last_kin = None  # the last step's ContactKinematics (_trial_loads)
        #: joint torques set through set_joint_torques for the coming step, and those of the last step,
        #: per multibody: {uid: (movable joints' torques [N m or N] (m,))} (_torque_dq)
        self._tau: dict[int, np.ndarray] = {}
        self._tau_last: dict[int, np.ndarray] = {}
        self.manager.set_coupling(self._keys, self._coupling_blocks)
        self.manager.set_energy_probe(self._energy_probe)  # islands' energy balance (engines._contacts.balance)
        # the free bodies' centres of mass at the last step start (B, 3): pybullet integrates
        # positions with the new velocity, com_k = com_{k-1} + dt v_k to round-off (1e-17 m
        # measured), so anything else is a step taken without the adapter or a body placed
        self._last_com = np.zeros((len(self._body_list), 3))
        self._have_com = False
        self._declared: set[int] = set()  # body slots placed by the caller (placed())
        #: the pairs' mass-0 bases, which only the user moves (resetBasePositionAndOrientation): each
        #: moves at the twist of its last pose change (engines._kinematic); None: no such body
        self._kin = self._driven_bodies()
        self._kin_R = None  # their base poses (position, quaternion x y z w) at the last step start (b, 7)
        #: jumps seen (bodies that moved other than by one adapter step), contacts they interrupted
        self.jumps = 0
        self.interrupted = 0
        # run-time switch per pair (set_mode): 0 MSF, 1 pybullet's own contact, 2 both off;
        # _handoff: a sphere through a box handed to pybullet's contact while it lasts (EngineAdapter._through)
        self._mode = np.zeros(n, np.int8)
        self._handoff = np.zeros(n, bool)
        #: sphere-box contacts handed to pybullet's own contact, the sphere deeper than its radius (count; a
        #: box's edges and corners are rounded and stay on MSF since issue 13, engines._narrow.SphereOnBox)
        self.edge_handoffs = 0
        self.edge_handoffs_of: dict[int, int] = {}
        self._held_warned: set[int] = set()  # held pairs warned about a too coarse step (_flag_held)
        self._mb_cache: dict = {}  # per step: a multibody's joint state and inverse mass matrix (_multibody)
        self._movable: dict[int, list[int]] = {}  # a multibody's movable joints
        self._limits: dict[int, np.ndarray] = {}  # their (lower, upper) limits [rad or m]
        self._qd_last: dict[int, np.ndarray] = {}  # a multibody's joint speeds at the last step start (_limits_engaged)
        #: steps at which a joint was stopped at a limit (its multibody's a_ext kept, _limits_engaged)
        self.limit_stops = 0
        self._stopped = np.zeros(n, bool)  # pairs whose a_ext is last step's this step (_limits_engaged)
        #: pairs seen in contact while a motor on one of their links' joint chains acted
        #: (appliedJointMotorTorque != 0; pybullet cannot report the motor settings): pair -> joint
        self._motor_held: dict[int, str] = {}
        self._chains: dict[int, list[tuple[int, int]]] = {}  # pair -> [(body uid, joint)] of its links' chains
        # the narrow pairs' points of this step, per slot (x, point, normal) or None (beyond the reach)
        self._narrow_found: list = [None] * n
        from engines._contacts.compiled import kernel_law
        from engines._narrow import LawBank

        #: a law per contact curvature, built from the PairSpec's (engines._narrow.LawBank, _narrow_law)
        self.laws = LawBank(kernel_law)
        #: contacts found deep at their onset (engines._contacts.balance.DeepOnsets): the pairs on a link of
        #: a multibody (the island energy check sees them a step late) and the narrow-phase pairs
        self._deep = DeepOnsets()
        self._unchecked_said = False  # _say_unchecked
        #: per multibody (uid): the work the MSF contacts' own impulses did on it since the start [J]
        #: (_account_multibody_work; its islands' energy check, _energy_probe)
        self.multibody_work: dict[int, float] = {}
        self._mb_dyn: dict[int, list] = {}  # per multibody: [(mass, principal inertia (3,))] of base and links
        self._last_gen = None  # per multibody: (generalized force of the last step's loads, u at its start)
        self._u_now: dict = {}  # per multibody: its generalized velocity at this step's start
        self._deep_mask = (self._b_art[self._slot].any(axis=1)
                           | np.array([k >= 0 for k, _ in self._narrow_of], bool).reshape(n))

    # -- validation ---------------------------------------------------------
    def _check_body(self, b, label):
        c = self.client
        try:
            uid, link = int(b[0]), int(b[1])
            if len(b) not in (2, 3):
                raise ValueError
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"{label} = {b!r}: give (body unique id, link index) or (body unique id, link index, "
                             "shape index in link_shapes)") from None
        ids = [pb.getBodyUniqueId(k, physicsClientId=c) for k in range(pb.getNumBodies(physicsClientId=c))]
        if uid not in ids:
            raise ValueError(f"{label}: body unique id {uid} is not in the model (bodies: {ids})")
        nj = pb.getNumJoints(uid, physicsClientId=c)
        if not -1 <= link < nj:
            raise ValueError(f"{label}: link index {link} is outside [-1, {nj - 1}] of body {uid}")
        articulated = link >= 0 or (nj > 0 and not self._base_fixed(uid))
        odd = [(j, pb.getJointInfo(uid, j, physicsClientId=c)) for j in range(nj if articulated else 0)]
        odd = [(j, info[1].decode(), _JOINT_NAMES[info[2]]) for j, info in odd if info[2] in _JOINT_NAMES]
        if odd:
            raise ValueError(f"{label}: body {uid} has {len(odd)} {'/'.join(sorted({k for _, _, k in odd}))} joint(s) "
                             f"({', '.join(f'{j} {n!r}' for j, n, _ in odd[:4])}{' ...' if len(odd) > 4 else ''}): "
                             "pybullet's calculateJacobian, which the contact's inverse inertia W = J M^-1 J^T of a "
                             "multibody needs, supports revolute, prismatic and fixed joints only; load the model "
                             "with those (e.g. a spherical joint as three revolute ones) or leave its contacts to "
                             "pybullet's own contact")
        return uid, link

    def _body_name(self, b) -> str:
        """"body name/link name" of a (body unique id, link index) (the base: its base link's name)."""
        uid, link = b
        base, body = (n.decode() for n in pb.getBodyInfo(uid, physicsClientId=self.client))
        name = body or f"body{uid}"
        if link < 0:
            return f"{name}/{base}" if base else name
        return f"{name}/{pb.getJointInfo(uid, link, physicsClientId=self.client)[12].decode()}"

    def _base_fixed(self, uid):
        return pb.getDynamicsInfo(uid, -1, physicsClientId=self.client)[0] == 0.0

    def _fixed(self, b):
        uid, link = b
        if link == -1:
            if uid not in self._fixed_cache:
                self._fixed_cache[uid] = self._base_fixed(uid)
            return self._fixed_cache[uid]
        return False

    def _setup_batches(self):
        """The body list (each body read once per step), its cached dynamics,
        and the pairs done all at once: a free sphere (a base without joints)
        on a plane, a fixed sphere or another free sphere."""
        c = self.client
        body_list = sorted({b for pair in self._bodies for b in pair})
        self._body_list = body_list
        slot = {b: j for j, b in enumerate(body_list)}
        self._slot = np.array([[slot[b1], slot[b2]] for b1, b2 in self._bodies], int).reshape(-1, 2)
        B = len(body_list)
        self._b_link = np.array([b[1] >= 0 for b in body_list], bool).reshape(B)  # read with getLinkState
        #: moved through the multibody's joints (a link, or the floating base of a multibody with joints):
        #: W = J M^-1 J^T from calculateJacobian and calculateMassMatrix
        self._b_art = np.array([self._articulated(b) for b in body_list], bool).reshape(B)
        self._art_slots = np.flatnonzero(self._b_art).tolist()
        self._base_slots = np.flatnonzero(~self._b_link)
        self._base_uids = [body_list[j][0] for j in self._base_slots]
        self._link_slots = np.flatnonzero(self._b_link).tolist()
        self._b_fixed = np.array([self._fixed(b) for b in body_list], bool)
        self._b_inv_m = np.zeros(B)
        self._b_inv_I = np.zeros((B, 3))  # principal inverse inertia [1/(kg m^2)]
        for j, b in enumerate(body_list):
            if not self._b_fixed[j] and not self._b_art[j]:
                info = pb.getDynamicsInfo(b[0], b[1], physicsClientId=c)
                self._b_inv_m[j] = 1.0 / info[0]
                I = np.asarray(info[2], float)
                self._b_inv_I[j] = np.where(I > 0, 1.0 / np.where(I > 0, I, 1.0), 0.0)
        self._b_free = ~self._b_fixed & ~self._b_art
        # pybullet clamps every coordinate speed of a multibody, a base's spin included, at
        # changeDynamics(maxJointVelocity) (btMultiBody::m_maxCoordinateVelocity, 100 rad/s by
        # default in 3.2.x; measured: a torque impulse for 1,000 rad/s leaves 100 rad/s). A bead
        # leaves an oblique impact spinning at ~1e5 rad/s, so the free bodies the adapter manages
        # get MAX_COORDINATE_VELOCITY (engines.pybullet.scenes), far above any valid impact.
        for j in np.flatnonzero(self._b_free):
            pb.changeDynamics(int(body_list[j][0]), -1, maxJointVelocity=MAX_COORDINATE_VELOCITY, physicsClientId=c)
        fast = []
        for i, ((s1, s2), (b1, b2)) in enumerate(zip(self._shapes, self._bodies)):
            j1, j2 = slot[b1], slot[b2]
            if (s1.kind == "sphere" and s2.kind in ("plane", "sphere") and self._b_free[j1]
                    and (self._b_free[j2] or self._b_fixed[j2])
                    and pb.getNumJoints(b1[0], physicsClientId=c) == 0):
                fast.append(i)
        self._fast = np.array(fast, int)
        self._x_last = np.zeros(len(self._bodies))  # max(x, 0) of each pair in the last step (0: not a candidate) [m]
        self._is_fast = np.zeros(len(self._bodies), bool)
        self._is_fast[self._fast] = True
        self.manager.own_gap[:] = self._is_fast  # free spheres: the manager's gaps are second order (_own_gaps)
        # a free rigid body's narrow points on a fixed body (a box's corners, a side's ends, a mesh's vertices
        # on a plane) keep the manager's gap too, as MuJoCo's (engines.mujoco.adapter): the engine's gap leads
        # the integrated one by dt |dv| / 2 (the objects scenario's cylinder on its side: its ends, chattering
        # at 1 ms, began deep; 0.69 mJ gained at rest, 15 records flagged)
        narrow = np.array([k >= 0 for k, _ in self._narrow_of], bool)
        self.manager.own_gap[narrow & self._b_free[self._slot[:, 0]] & self._b_fixed[self._slot[:, 1]]] = True
        # two moving bodies of which one at least is a multibody's link (balls on slide or hinge joints,
        # a cradle): the manager's gap too, as MuJoCo's links (engines.mujoco.adapter). The timing
        # correction leaves the engine's gap ahead of the integrated one by dt |dv| / 2 (a cradle on slide
        # joints at 1 ms, 1 mm gaps: the third ball found 0.47 mm deep at its onset, the cradle at 1,600
        # times its energy); a larger difference (a joint limit's force) still takes the engine's gap
        moving = ~self._b_fixed[self._slot]
        self.manager.own_gap[moving.all(axis=1) & self._b_art[self._slot].any(axis=1)] = True
        self._slow = [i for i in range(len(self._bodies)) if not self._is_fast[i]]
        f = self._fast
        self._f_s1 = np.array([self._shapes[i][0].pos for i in f], float).reshape(-1, 3)
        self._f_r1 = np.array([self._shapes[i][0].size[0] for i in f], float)
        self._f_plane = np.array([self._shapes[i][1].kind == "plane" for i in f], bool)
        self._f_s2 = np.array([self._shapes[i][1].pos for i in f], float).reshape(-1, 3)
        # plane: the normal in body 2's inertial axes; sphere: radius in column 0
        self._f_size2 = np.array([self._shapes[i][1].rot @ self._shapes[i][1].size if self._shapes[i][1].kind == "plane"
                                  else np.array([self._shapes[i][1].size[0], 0.0, 0.0]) for i in f],
                                 float).reshape(-1, 3)
        self._f_rot1 = np.array([self._shapes[i][0].rot for i in f], float).reshape(-1, 3, 3)
        self._f_j1 = np.ascontiguousarray(self._slot[f, 0]).astype(np.int64)
        self._f_j2 = np.ascontiguousarray(self._slot[f, 1]).astype(np.int64)
        self._f64 = f.astype(np.int64)
        self._slot64 = np.ascontiguousarray(self._slot, dtype=np.int64)
        self._b_uid = np.array([b[0] for b in body_list], int).reshape(B)
        #: (slots, their body unique ids as a list) of the last step's bodies with one force
        self._one_cache = (np.zeros(0, int), [])

    def _read_bodies(self) -> _Bodies:
        """Every body of the pairs, one read each (module docstring, step 1)."""
        c = self.client
        uids = self._base_uids
        nb = len(uids)
        # bases: one call per body and quantity, mapped from C with the client id positional (the
        # keyword costs ~0.1 us a call), the tuples flattened by itertools and converted once
        po = np.fromiter(chain.from_iterable(chain.from_iterable(
            map(pb.getBasePositionAndOrientation, uids, repeat(c)))), float, 7 * nb).reshape(nb, 7)
        vw = np.fromiter(chain.from_iterable(chain.from_iterable(
            map(pb.getBaseVelocity, uids, repeat(c)))), float, 6 * nb).reshape(nb, 6)
        B = len(self._body_list)
        com, q, v, w = np.empty((B, 3)), np.empty((B, 4)), np.empty((B, 3)), np.empty((B, 3))
        jb = self._base_slots
        com[jb], q[jb], v[jb], w[jb] = po[:, 0:3], po[:, 3:7], vw[:, 0:3], vw[:, 3:6]
        frame = com.copy()
        for j in self._link_slots:
            uid, link = self._body_list[j]
            st = pb.getLinkState(uid, link, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=c)
            com[j], q[j], frame[j], v[j], w[j] = st[0], st[1], st[4], st[6], st[7]
        return _Bodies(com, self._k.rotations(q) if self.compiled else _mats(q), v, w, frame)

    def _articulated(self, b):
        """A link of a multibody, or the base of a floating-base multibody with
        joints. A floating multibody whose joints are all fixed is refused:
        pybullet's calculateJacobian needs a movable joint."""
        c = self.client
        nj = pb.getNumJoints(b[0], physicsClientId=c)
        if nj and not self._base_fixed(b[0]) and all(pb.getJointInfo(b[0], j, physicsClientId=c)[2] == pb.JOINT_FIXED
                                                     for j in range(nj)):
            raise ValueError(f"body {b[0]} is a floating multibody whose {nj} joints are all fixed: pybullet's "
                             "calculateJacobian (the contact's inverse inertia) needs a movable joint; make it one "
                             "body with a compound collision shape, or leave it to pybullet's own contact")
        if b[1] >= 0:
            return True
        return nj > 0 and not self._fixed(b)

    def _link_key(self, k, what) -> tuple[int, int]:
        try:
            return int(k[0]), int(k[1])
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"{what}: key {k!r} must be (body unique id, link index)") from None

    def _n_shapes(self, b) -> int:
        """How many collision shapes link ``b`` (uid, link) has: its link_shapes, else pybullet's."""
        if b in self._link_shapes:
            return len(self._link_shapes[b])
        return len(pb.getCollisionShapeData(b[0], b[1], physicsClientId=self.client))

    def _check_compounds(self, pairs) -> None:
        """ValueError unless the pairs of two links with several shapes (a
        compound: a tray, a table, a robot link of several geoms) cover every
        shape of one against every shape of the other: pybullet's own
        collision is switched off for the whole link pair (setCollisionFilterPair),
        so a shape with no pair would collide with nothing, silently; and unless
        each such pair's points are found by the adapter itself (pybullet's
        getClosestPoints answers for the whole link, every shape at once)."""
        covered: dict = {}
        for i, p in enumerate(pairs):
            key = ((int(p.body1[0]), int(p.body1[1])), (int(p.body2[0]), int(p.body2[1])))
            k = (int(p.body1[2]) if len(p.body1) == 3 else 0, int(p.body2[2]) if len(p.body2) == 3 else 0)
            covered.setdefault(key, {})[k] = i
        for (b1, b2), ks in covered.items():
            n1, n2 = self._n_shapes(b1), self._n_shapes(b2)
            if n1 * n2 == 1:
                continue
            missing = [(k1, k2) for k1 in range(n1) for k2 in range(n2) if (k1, k2) not in ks]
            if missing:
                names = self._body_name(b1), self._body_name(b2)
                raise ValueError(
                    f"pairs between {names[0]} ({n1} collision shapes) and {names[1]} ({n2}) cover {len(ks)} of their "
                    f"{n1 * n2} shape pairs (missing (k1, k2) = {missing[:6]}{' ...' if len(missing) > 6 else ''}): "
                    "pybullet's own collision is switched off for the link pair, so the shapes left out would "
                    "collide with nothing; give a PairSpec for each, bodies (uid, link, k)")
        for np_ in self._narrow:
            if np_.method == "engine" and np_.box is None and (self._n_shapes(np_.link1) > 1
                                                               or self._n_shapes(np_.link2) > 1):
                names = self._body_name(np_.link1), self._body_name(np_.link2)
                raise ValueError(
                    f"pair ({names[0]}, {names[1]}): a {np_.shape1.kind} against a {np_.shape2.kind} on a link of "
                    "several collision shapes: its points come from pybullet's getClosestPoints, which answers for "
                    "the whole link (every shape at once), so each shape's pair would take the others' points; "
                    "supported on a compound link: a sphere on any of its primitives, a box on its boxes, a shape "
                    "on a plane or on a fixed box whose face toward it is wide enough to be its floor "
                    "(engines.pybullet.narrow.floor_face); else use pybullet's own contact for this link pair")

    def _shape(self, spec, label) -> _Shape:
        """The collision shape of a pair's body ``spec`` ((uid, link) or (uid,
        link, k)): from ``link_shapes`` if given for the link, else pybullet's
        getCollisionShapeData (exactly one shape)."""
        b = (int(spec[0]), int(spec[1]))
        if b in self._link_shapes:
            shapes = self._link_shapes[b]
            k = int(spec[2]) if len(spec) == 3 else None
            if k is None and len(shapes) != 1:
                raise ValueError(f"{label} {b}: the link has {len(shapes)} shapes in link_shapes; give "
                                 "(body unique id, link index, k), one pair per shape")
            k = 0 if k is None else k
            if not 0 <= k < len(shapes):
                raise ValueError(f"{label} {spec}: shape index {k} is outside [0, {len(shapes) - 1}]")
            shape = shapes[k]
            if not isinstance(shape, LinkShape) or shape.kind not in _SUPPORTED:
                raise ValueError(f"{label} {spec}: link_shapes entries must be engines.pybullet.narrow.LinkShape of "
                                 f"kind {', '.join(_SUPPORTED)}, got {shape!r}")
            return shape
        data = pb.getCollisionShapeData(b[0], b[1], physicsClientId=self.client)
        if not data:
            raise ValueError(f"{label} {b}: pybullet reports no collision shape for it (getCollisionShapeData is "
                             "empty: a height field, or no collision shape); MSF needs the curvature at the contact: "
                             "give the link's shapes in link_shapes, or use pybullet's own contact for this pair")
        if len(spec) == 3:  # one child of a compound shape (a URDF link with several <collision>), as pybullet reports it
            k = int(spec[2])
            if not 0 <= k < len(data):
                raise ValueError(f"{label} {spec}: shape index {k} is outside [0, {len(data) - 1}] (pybullet reports "
                                 f"{len(data)} collision shapes for the link)")
        elif len(data) != 1:
            kinds = ", ".join(f"{k}: {_SHAPE_NAMES.get(d[2], f'geometry type {d[2]}')}" for k, d in enumerate(data))
            raise ValueError(f"{label} {b}: has {len(data)} collision shapes ({kinds}); give one pair per shape, "
                             f"body (uid, link, k) for k in 0..{len(data) - 1} (read from pybullet), or the shapes in "
                             "link_shapes (engines.pybullet.narrow.LinkShape)")
        else:
            k = 0
        _, _, gtype, dims, _, lpos, lorn = data[k]
        kind = _SHAPE_NAMES.get(gtype, f"geometry type {gtype}")
        if kind not in _SUPPORTED:
            raise ValueError(f"{label} {spec}: collision shape {kind!r} has no curvature model (MSF needs the "
                             f"curvature at the contact); supported: {', '.join(_SUPPORTED)}; use pybullet's own "
                             "contact for this pair")
        vertices, margin = None, 0.0
        if kind == "sphere":
            size = np.array([dims[0]])
        elif kind == "box":
            size = 0.5 * np.asarray(dims, dtype=float)  # getCollisionShapeData gives full extents
        elif kind in ("capsule", "cylinder"):
            size = np.array([dims[1], 0.5 * dims[0]])  # (height, radius) -> (radius, half-length)
        elif kind == "mesh":
            size = np.asarray(dims, dtype=float)  # the scale
            vertices = np.asarray(pb.getMeshData(b[0], b[1], collisionShapeIndex=k if len(data) > 1 else -1,
                                                 physicsClientId=self.client)[1], dtype=float)
            # a convex hull is inflated by its collision margin in getClosestPoints (engines.pybullet.narrow)
            margin = float(pb.getDynamicsInfo(b[0], b[1], physicsClientId=self.client)[11])
        else:
            size = np.asarray(dims, dtype=float) / np.linalg.norm(dims)
        # a URDF <cylinder> loaded without URDF_USE_IMPLICIT_CYLINDER is a hull of two rings: the cylinder
        return _narrow.as_cylinder(_Shape(kind, size, np.asarray(lpos, dtype=float), _mat(lorn), vertices, margin))

    def _add_narrow(self, i, p: PairSpec, b1, b2, s1: _Shape, s2: _Shape) -> int:
        """Set pair i up for engines.pybullet.narrow; return its number of slots."""
        from engines._narrow import BoxOnBox, BoxOnPlane, CylinderOnPlane, SideLine, SlotMatcher, default_mesh_slots
        from msf_contact.shapes import Box, Capsule, Cylinder

        if s1.kind == "plane":
            raise ValueError(f"pairs[{i}]: body1 = {b1} is a plane; body1 must be the curved body (the normal points "
                             "from body2 to body1): swap body1 and body2")
        if self._fixed(b2):  # a large fixed box (pybullet_data's plane.urdf): its face toward body 1 as a floor
            s2 = _narrow.floor_face(s2, (self._pose(b2).com, self._pose(b2).rot), s1,
                                    (self._pose(b1).com, self._pose(b1).rot))
        geoms = []
        for b, s in ((b1, s1), (b2, s2)):
            geoms.append(self.curvature_shapes.get(b) or _narrow.msf_shape(s, self.edge_radii.get(b)))
        mesh = [int(self.mesh_slots.get(b, default_mesh_slots(s.vertices) if s.kind == "mesh" else 1))
                for b, s in ((b1, s1), (b2, s2))]
        n = _narrow.slots_of(s1.kind, s2.kind, tuple(mesh))
        line = None
        if s2.kind == "plane" and isinstance(geoms[0], Capsule):  # a side lying on it: one line
            line = SideLine(geoms[0], (self._body_name(b1), self._body_name(b2)))
        if s2.kind == "plane" and isinstance(geoms[0], Cylinder):  # lying: its side's line; else its rim ring
            line = CylinderOnPlane(geoms[0], (self._body_name(b1), self._body_name(b2)), n)
        box = None
        if isinstance(geoms[0], Box) and (s2.kind == "plane" or (s2.kind == "box" and self._fixed(b2))):
            # its rounded corners and edges on the plane, or on a fixed box's face (plane.urdf is a box)
            box = BoxOnPlane(geoms[0], (self._body_name(b1), self._body_name(b2)), n)
            box.check(p.law)
        elif isinstance(geoms[0], Box) and isinstance(geoms[1], Box) and s2.kind == "box":
            # a box on a free box: the lower box's face at its current pose (engines._narrow.BoxOnBox)
            box = BoxOnBox(geoms[0], geoms[1], (self._body_name(b1), self._body_name(b2)), n)
            box.check(p.law)
        self._narrow.append(_narrow.NarrowPair(len(self._bodies), b1, b2, s1, s2, geoms[0], geoms[1],
                                               SlotMatcher(n, s1.extent()), _narrow.pair_method(s1.kind, s2.kind, n),
                                               line, box))
        return n

    # -- held links (issue 11, item 6) ---------------------------------------
    def held_pairs(self) -> set[int]:
        """Indices of the pairs one of whose bodies is held by a pybullet user
        constraint (``createConstraint``, read through ``getConstraintInfo``:
        a constraint on any link of the body's multibody holds the link) or
        was seen in contact while a joint motor on its link's chain to the
        base acted (``setJointMotorControl2`` in any mode; read as a non-zero
        ``appliedJointMotorTorque``, pybullet cannot report a motor's settings)."""
        return set(self._constraint_held()) | set(self._motor_held)

    def _constraint_held(self) -> set[int]:
        c = self.client
        uids = set()
        for k in range(pb.getNumConstraints(physicsClientId=c)):
            info = pb.getConstraintInfo(pb.getConstraintUniqueId(k, physicsClientId=c), physicsClientId=c)
            uids.update(u for u in (info[0], info[2]) if u >= 0)
        return {i for i, (b1, b2) in enumerate(self._bodies) if b1[0] in uids or b2[0] in uids}

    def _see_motors(self, pairs) -> None:
        """Note the pairs in contact whose links' joint chains have a motor acting (_motor_held)."""
        c = self.client
        for i in pairs:
            i = int(i)
            if i in self._motor_held:
                continue
            chain = self._chains.get(i)
            if chain is None:
                chain = []
                for uid, link in self._bodies[i]:
                    while link >= 0:
                        info = pb.getJointInfo(uid, link, physicsClientId=c)
                        if info[2] != pb.JOINT_FIXED:
                            chain.append((uid, link))
                        link = info[16]
                self._chains[i] = chain
            for uid, j in chain:
                if pb.getJointState(uid, j, physicsClientId=c)[3] != 0.0:
                    name = pb.getJointInfo(uid, j, physicsClientId=c)[1].decode()
                    self._motor_held[i] = f"the motor of joint {j} ({name!r}) of body {uid}"
                    break

    def _flag_held(self, records: list) -> list:
        """Flag (``outside_validity``) the records of constraint-held pairs
        resolved with fewer than HELD_MIN_STEPS steps per contact, and warn
        once per pair (RuntimeWarning: pair, dt, dt_max and what to change)."""
        if not records or not pb.isConnected(self.client):
            return records
        by_constraint = self._constraint_held()
        for r in records:
            i = r.inputs.get("pair")
            if not (i in by_constraint or i in self._motor_held) or not r.tau < HELD_MIN_STEPS * self._dt:
                continue
            dt_max = r.tau / HELD_MIN_STEPS
            holder = "a pybullet constraint" if i in by_constraint else self._motor_held[i]
            note = (f"held link: pair {i} {self.pair_names[i]} is held by {holder} and its contact "
                    f"(tau = {r.tau:.3g} s) spans {r.tau / self._dt:.2g} < {HELD_MIN_STEPS:g} steps of dt = "
                    f"{self._dt:g} s: the COR is outside 2 % (measured -7 % at 2.4 steps); "
                    f"use dt <= dt_max = {dt_max:.3g} s (setTimeStep)")
            if note not in r.outside_validity:
                r.outside_validity.append(note)
            if i not in self._held_warned:
                self._held_warned.add(i)
                warnings.warn(note, RuntimeWarning, stacklevel=3)
        return records

    @property
    def records(self) -> list:
        """Finished impacts (msf_contact.ImpactRecord), oldest first; a
        constraint-held pair's records flagged when the step is too coarse."""
        return self._flag_held(self.manager.records)

    def pop_records(self) -> list:
        """Finished impacts since the last call, and forget them; flagged as :attr:`records`."""
        return self._flag_held(self.manager.pop_records())

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
            # the garbage collector paused within a step: the reads' result tuples and the forces'
            # lists (~10 per body) would trigger collections that traverse them (~0.1 us a body)
            gc_was = gc.isenabled()
            gc.disable()
            try:
                self._step_once()
            finally:
                if gc_was:
                    gc.enable()

    def close(self) -> None:
        """Give the pairs back to pybullet's own contact
        (``setCollisionFilterPair(..., enableCollision=1)``: pybullet has no
        getter for the filter, so a pair you had disabled yourself is enabled
        again). The client stays connected: the adapter never owns it, and a
        plain ``stepSimulation()`` afterwards runs pybullet's contact for the
        pairs. Records stay readable; ``step`` raises afterwards."""
        if self._closed:
            return
        self._closed = True
        if pb.isConnected(self.client):
            for (u1, l1), (u2, l2) in self._bodies:
                pb.setCollisionFilterPair(u1, u2, l1, l2, enableCollision=1, physicsClientId=self.client)

    def set_mode(self, which, mode: str) -> None:
        """Switch a pair at run time: ``"msf"`` (this adapter's law, pybullet's
        contact off for the pair), ``"engine"`` (pybullet's own contact, no
        MSF force) or ``"off"`` (neither), through
        ``setCollisionFilterPair``. ``which``: an index into ``adapter.pairs``
        or the pair's (body1, body2) as given. Contacts in progress under MSF
        end without a record; ``close()`` enables pybullet's contact for every pair."""
        code = {"msf": 0, "engine": 1, "off": 2}.get(mode)
        if code is None:
            raise ValueError(f"mode = {mode!r} must be 'msf', 'engine' or 'off'")
        for i in self._slots_of(self._pair_index(which)):  # every contact slot of the pair
            if self._mode[i] == 0 and code != 0:
                self.manager.interrupt([i], f"switched to {mode!r} by set_mode")
            self._have_last[i] = False
            self._mode[i] = code
            self._filter(i)

    def _slots_of(self, i: int) -> list[int]:
        """The contact slots of the PairSpec that pair i belongs to."""
        k = self._narrow_of[i][0]
        if k < 0:
            return [i]
        return list(range(self._narrow[k].first, self._narrow[k].first + self._narrow[k].n))

    def mode(self, which) -> str:
        """The pair's mode ("msf", "engine" or "off"; a sphere through a box handed over counts as "engine")."""
        i = self._pair_index(which)
        return ("msf", "engine", "off")[1 if self._handoff[i] and self._mode[i] == 0 else int(self._mode[i])]

    def _pair_index(self, which) -> int:
        if isinstance(which, (int, np.integer)) and not isinstance(which, bool):
            if not 0 <= int(which) < len(self._bodies):
                raise ValueError(f"which = {which!r} is outside [0, {len(self._bodies) - 1}]")
            return int(which)
        try:
            b = (tuple(int(v) for v in which[0]), tuple(int(v) for v in which[1]))
            return self._bodies.index(b)
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"which = {which!r}: give a pair index or the pair's (body1, body2)") from None

    def _filter(self, i: int) -> None:
        """pybullet's contact for pair i on exactly when its mode (or a hand-over, _through) says so."""
        (u1, l1), (u2, l2) = self._bodies[i]
        on = self._mode[i] == 1 or (self._mode[i] == 0 and self._handoff[i])
        pb.setCollisionFilterPair(u1, u2, l1, l2, enableCollision=int(on), physicsClientId=self.client)

    def _engine_contact_changed(self, i: int) -> None:
        self._filter(i)

    @property
    def now(self) -> float:
        return self.time

    def _driven_bodies(self):
        """The pairs' bodies with a mass-0 base (fixed in pybullet, moved only by the user with
        resetBasePositionAndOrientation), as engines._kinematic.KinematicBodies over those bases'
        unique ids: the base itself (an infinite mass moving at its twist) and the links of a
        multibody on such a base (their getLinkState velocities carry only the joints' motion:
        the base's twist at the contact point is added). None when there is none."""
        from engines._kinematic import KinematicBodies

        uids = []
        for b in self._body_list:
            if self._base_fixed(b[0]) and b[0] not in uids:
                uids.append(b[0])
        if not uids:
            return None
        at = {u: k for k, u in enumerate(uids)}
        sides = np.array([[at.get(b1[0], -1), at.get(b2[0], -1)] for b1, b2 in self._bodies],
                         np.int64).reshape(-1, 2)
        reach = np.zeros(len(uids))
        c = self.client
        for k, u in enumerate(uids):  # the farthest point of its shapes from the base's frame (a bound)
            for i, (s1, s2) in enumerate(self._shapes):
                for side, sh, b in ((0, s1, self._bodies[i][0]), (1, s2, self._bodies[i][1])):
                    if sides[i, side] != k:
                        continue
                    r = float(np.linalg.norm(sh.pos)) + _shape_reach(sh)
                    if b[1] >= 0:  # a link: its frame's distance from the base's now
                        st = pb.getLinkState(u, b[1], physicsClientId=c)
                        r += float(np.linalg.norm(np.subtract(st[0], pb.getBasePositionAndOrientation(
                            u, physicsClientId=c)[0])))
                    reach[k] = max(reach[k], r)
        names = [(pb.getBodyInfo(u, physicsClientId=c)[1].decode() or f"body{u}") for u in uids]
        kin = KinematicBodies(uids, sides, reach, names)
        kin.uids = [int(u) for u in uids]
        return kin

    def _drive(self, bodies: _Bodies) -> None:
        """At a step's start: the driven (mass-0) bases' twist for the step from their
        pose change (engines._kinematic), their contacts interrupted at an undeclared
        placement, and their pairs' candidate reach for the step."""
        kin, c = self._kin, self.client
        raw = list(map(pb.getBasePositionAndOrientation, kin.uids, repeat(c)))  # ((x, y, z), (qx, qy, qz, qw))
        declared = [k for k, u in enumerate(kin.uids) if any(self._body_list[j][0] == u for j in self._declared)] \
            if self._declared else []
        if not declared and not kin.moving and raw == self._kin_R:
            return  # nothing moved (the usual case: a floor; ~1 us a base, compared as Python tuples)
        self._kin_R = raw
        po = np.array([[*p, *q] for p, q in raw], float).reshape(-1, 7)
        quat = po[:, [6, 3, 4, 5]]  # pybullet's (x, y, z, w) as (w, x, y, z)
        jumped = kin.update(po[:, :3], quat, self._dt, declared=declared)
        interrupt_placements(self, kin, jumped, declared, self.time, "mass-0", "resetting")
        if kin.moving:
            self._push = self._push.copy()
            self._push[kin.rows] += kin.push(self._dt, CANDIDATE_FACTOR)

    def _mask(self, kin: ContactKinematics) -> ContactKinematics:
        """The driven bodies' velocities added to the rows (engines._kinematic), then
        EngineAdapter._mask."""
        drv = self._kin
        if drv is not None and drv.moving and kin.pair.size and not getattr(kin, "driven", False):
            kin.driven = True  # once per kinematics (the limit retrial steps the manager on them again)
            pair = np.asarray(kin.pair, dtype=np.int64)
            sel = np.flatnonzero(np.any(drv.sides[pair] >= 0, axis=1))
            if sel.size:
                q = pair[sel]
                com = self._cur_bodies.com
                pt = np.asarray(kin.point, dtype=float)[sel]
                v, vc = drv.adjust(q, kin.v_rel[sel], kin.v_com_rel[sel], pt, pt, com[self._slot[q, 0]],
                                   com[self._slot[q, 1]])
                kin.v_rel = np.array(kin.v_rel, dtype=float)
                kin.v_com_rel = np.array(kin.v_com_rel, dtype=float)
                kin.v_rel[sel], kin.v_com_rel[sel] = v, vc
        return super()._mask(kin)

    def _drive_work(self, out) -> None:
        """The work the driven bodies did on their partners in the step (the islands' energy probe)."""
        kin = self._kin
        if kin is None or not kin.moving:
            return
        pair = np.asarray(out.pair, dtype=np.int64)
        sel = np.flatnonzero(np.any(kin.sides[pair] >= 0, axis=1))
        if sel.size:
            pt = np.asarray(out.point, dtype=float)[sel]
            kin.credit(pair[sel], np.asarray(out.force, dtype=float)[sel], pt, pt, self._dt)

    def placed(self, bodies) -> None:
        """Say that ``bodies`` ((body unique id, link index) or body unique ids)
        were placed (``resetBasePositionAndOrientation``, ``resetBaseVelocity``)
        since the last step: their pairs' contacts are interrupted quietly
        instead of with the warning an undeclared jump gives (:meth:`step`)."""
        for b in bodies:
            uid = int(b[0]) if isinstance(b, (tuple, list)) else int(b)
            self._declared.update(j for j, bb in enumerate(self._body_list) if bb[0] == uid)

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

    def _multibody(self, uid) -> list:
        """[q, qd, M^-1 or None, the base's rotation (3, 3)] of a multibody's
        movable joints at this step (read once per step: a robot's contacts
        share them), and once computed, [4] the torques' dq (_torque_dq)."""
        cache = self._mb_cache
        if cache.get("step") != self._steps:
            cache.clear()
            cache["step"] = self._steps
        if uid not in cache:
            c = self.client
            if uid not in self._movable:
                self._movable[uid] = [j for j in range(pb.getNumJoints(uid, physicsClientId=c))
                                      if pb.getJointInfo(uid, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
            states = pb.getJointStates(uid, self._movable[uid], physicsClientId=c) if self._movable[uid] else []
            # the base's orientation: calculateJacobian answers in the base's frame (_jacobian)
            rot = _mat(pb.getBasePositionAndOrientation(uid, physicsClientId=c)[1])
            cache[uid] = [[s[0] for s in states], [s[1] for s in states], None, rot]
        return cache[uid]

    def _joint_state(self, uid):
        q, qd = self._multibody(uid)[:2]
        return q, qd

    def _minv(self, uid) -> np.ndarray:
        """The multibody's inverse inertia in joint space at this step (cached):
        M^-1, with the joints at or beyond a limit (JOINT_LIMIT_TOL) held
        (M^-1 - M^-1 A^T (A M^-1 A^T)^-1 A M^-1, A the rows of those dofs):
        pybullet holds a joint at its limit with a rigid constraint inside the
        step, so a contact on a link beyond it moves what the held joint lets
        move (measured: a foot of pybullet_data's ant with its ankles beyond
        their limits moved 10-30 % less than J M^-1 J^T said; with its joints
        inside their ranges J M^-1 J^T P dt is the velocity change pybullet
        gives, tests/test_robots_pybullet.py). Which joints: :meth:`_held_dofs`
        (with ``limit_trial`` the ones pybullet's one-sided limit holds in a
        trial of the step; else the ones at a limit, an approximation)."""
        mb = self._multibody(uid)
        if mb[2] is None:
            Minv = np.linalg.inv(self._mass_matrix(uid))
            held = self._held_dofs(uid, mb[0])
            if held.size:
                MA = Minv[:, held]
                Minv = Minv - MA @ np.linalg.solve(Minv[np.ix_(held, held)], MA.T)
            mb[2] = Minv
        return mb[2]

    def set_joint_torques(self, uid: int, joints, torques) -> None:
        """Set the joint torques [N m, or N for a prismatic joint] of
        multibody ``uid``'s ``joints`` (joint indices) for the next step,
        through pybullet (``setJointMotorControlArray(TORQUE_CONTROL)``, which
        applies them for one ``stepSimulation``: measured, a torque set once
        accelerates its joint in one step only), and tell the contacts; joints
        not set have none. The contacts' outside
        acceleration a_ext is measured from the last step (its finite
        difference holds the last step's torques): a torque changed at this
        step would reach them a step late, the whole change of the torque's
        acceleration J M^-1 dtau missing from the step it acts in (random
        torques at every 10 ms step of pybullet's ant: the feet's internal
        approach and the engine's drifted apart by up to 4 mm; the torques
        switched off, the humanoid's contacts gained 52.6 J in one step,
        docs/engines.md). With the change told, each contact point of the
        multibody gets J M^-1 (tau - tau_last) (M^-1 with the joints at a
        limit held, as its W) added to its a_ext in the step the change acts
        in. Torques set with pybullet's own call are seen a step late, as
        before."""
        uid = int(uid)
        slots = [j for j in self._art_slots if int(self._b_uid[j]) == uid]
        if not slots:
            raise ValueError(f"uid = {uid}: no link of a multibody with that body unique id is in the adapter's pairs")
        if uid not in self._movable:
            self._multibody(uid)
        movable = self._movable[uid]
        joints = [int(j) for j in np.atleast_1d(joints)]
        tau = np.asarray(torques, dtype=float).reshape(-1)
        if tau.size != len(joints):
            raise ValueError(f"torques has {tau.size} values for {len(joints)} joints")
        if not np.all(np.isfinite(tau)):
            raise ValueError(f"torques = {tau!r} must be finite")
        bad = [j for j in joints if j not in movable]
        if bad:
            raise ValueError(f"joints {bad} of body {uid} are not movable joints (movable: {movable})")
        pb.setJointMotorControlArray(uid, joints, pb.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=self.client)
        cur = self._tau.setdefault(uid, np.zeros(len(movable)))
        cur[[movable.index(j) for j in joints]] = tau

    def _torque_dq(self, uid) -> np.ndarray | None:
        """M^-1 (tau - tau_last) over the multibody's coordinates [1/s^2 per coordinate] (cached per step)
        for the torques set through set_joint_torques; None when they did not change."""
        tau, last = self._tau.get(uid), self._tau_last.get(uid)
        if tau is None and last is None:
            return None
        tau = np.zeros_like(last) if tau is None else tau
        last = np.zeros_like(tau) if last is None else last
        if np.array_equal(tau, last):
            return None
        mb = self._multibody(uid)
        if len(mb) < 5:
            base = 0 if self._base_fixed(uid) else 6
            gen = np.zeros(base + tau.size)
            gen[base:] = tau - last
            mb.append(self._minv(uid) @ gen)
        return mb[4]

    def _limits_engaged(self) -> None:
        """A joint stopped at a limit of its range within the last step was
        stopped by pybullet's rigid limit constraint: an impulse (a knee of
        the humanoid stopped from 38 rad/s in one 2 ms step) that the
        finite-difference a_ext of the multibody's contact points takes for
        an acceleration (3,100 m/s^2 at a foot, whose contact then began with
        the onset-speed floor of that acceleration, 15.4 m/s, past the law's
        2R, while the foot closed at 3.8 m/s). A joint at a limit now that
        moved into it faster than LIMIT_STOP_SPEED at the last step start and
        less than half that now was stopped; the pairs on its multibody
        keep their last step's a_ext for this step (the load the structure put
        on them; restarting it from zero unloaded resting feet for a step)."""
        self._stopped[:] = False
        seen = set()
        for j in self._art_slots:
            uid = int(self._b_uid[j])
            if uid in seen:
                continue
            seen.add(uid)
            q, qd = self._multibody(uid)[:2]
            q, qd = np.asarray(q, float), np.asarray(qd, float)
            last = self._qd_last.get(uid)
            self._qd_last[uid] = qd
            if last is None or not q.size:
                continue
            lim = self._limits_of(uid)
            on = lim[:, 0] < lim[:, 1]
            lower = on & (q <= lim[:, 0] + JOINT_LIMIT_TOL)
            upper = on & (q >= lim[:, 1] - JOINT_LIMIT_TOL)
            into_last = np.where(lower, -last, np.where(upper, last, 0.0))
            into_now = np.where(lower, -qd, np.where(upper, qd, 0.0))
            if np.any((into_last > LIMIT_STOP_SPEED) & (into_now < 0.5 * into_last)):
                side = self._b_art[self._slot] & (self._b_uid[self._slot] == uid)
                self._stopped[side[:, 0] | side[:, 1]] = True
                self.limit_stops += 1

    def _rest_together(self) -> None:
        """The contacts on a multibody one of whose joints is at a limit are
        held apart at rest (ContactManager.set_together): when all of their
        connected contacts rest they take the settled path one by one; every
        other set of resting contacts is one island (the manager's default,
        issue 13). The settled path steps each resting foot alone, the others'
        forces entering its a_ext a step late: pybullet's ant put down on its
        feet (free hinges) at 10 ms rose 1.31 J above its running minimum,
        0.51 J solved together (scripts/pybullet_robots.py ant). With a joint
        at a limit the coupled solve takes it as held (_minv), which
        pybullet's one-sided limit is not: the ant resting on its ankle limits
        after its torques rocked by ~80 J in one island, and rose 2.2 J where
        the settled path rose 0.36 J (benchmarks robots_pybullet). With
        ``limit_trial`` the held joints are the ones pybullet holds over the
        step (:meth:`_limit_trial`) and every multibody's contacts are one
        island also at rest (the ant landing on its ankle limits: its
        contacts' own balance 0.003 J above its running minimum, 2.45 J
        without the trial, scripts/pybullet_robots.py landing)."""
        together = np.ones(len(self.pairs), bool)
        for uid in {int(self._b_uid[j]) for j in self._art_slots}:
            if self._engaged_at == self._steps:  # the held joints are the ones pybullet holds: solved together
                continue
            q = self._multibody(uid)[0]
            if self._held_dofs(uid, q).size:
                side = self._b_art[self._slot] & (self._b_uid[self._slot] == uid)
                together &= ~(side[:, 0] | side[:, 1])
        self.manager.set_together(together)

    def _limit_trial(self, bodies: _Bodies) -> None:
        """Which joint limits hold each multibody of the pairs over this step,
        found by trying it (the class docstring, ``limit_trial``): pybullet's state saved, the last
        step's MSF loads applied again (the prediction of this step's, as the
        held forces of a_ext; an impact's from its closing speed, :meth:`_trial_loads`),
        one ``stepSimulation``, each movable joint's end
        speed compared with its limit rows' bounds, the state restored and the
        torques told (:meth:`set_joint_torques`) set again (TORQUE_CONTROL acts
        for one step: the trial used them). Into ``_engaged`` for :meth:`_held_dofs`."""
        t0 = time.perf_counter()
        uids = sorted({int(self._b_uid[j]) for j in self._art_slots})
        for uid in uids:
            self._multibody(uid)  # this step's joint state, before the trial moves it
        self._engaged.update(self._try_step(bodies, self._trial_loads(bodies), uids))
        self._engaged_at = self._steps
        self.limit_trials += 1
        self.limit_trial_s += time.perf_counter() - t0

    def _try_step(self, bodies: _Bodies, loads, uids) -> dict:
        """{uid: (m,) bool held joints} of the multibodies ``uids`` over one
        ``stepSimulation`` with ``loads`` ((pairs, forces, points) or None)
        applied, pybullet's state restored after it and the told torques set
        again (:meth:`_limit_trial`)."""
        c = self.client
        sid = pb.saveState(physicsClientId=c)
        try:
            if loads is not None:
                self._apply(bodies, *loads)
            pb.stepSimulation(physicsClientId=c)
            if self.trial_a_ext:
                self._trial_end = {j: self._pose(self._body_list[j]) for j in self._art_slots}
                self._trial_used = loads
            return {uid: self._held_over_step(uid) for uid in uids}
        finally:
            pb.restoreState(sid, physicsClientId=c)
            pb.removeState(sid, physicsClientId=c)
            for uid, tau in self._tau.items():
                pb.setJointMotorControlArray(uid, self._movable[uid], pb.TORQUE_CONTROL, forces=tau.tolist(),
                                             physicsClientId=c)

    def _limit_retrial(self, bodies: _Bodies, kin: ContactKinematics, out) -> bool:
        """The second trial (``limit_retrial``): this step tried again with the
        forces the contacts just gave (``out``, step-averaged, at their
        points) instead of the first trial's prediction. Where it holds other
        joints than the first, those are taken (``_engaged``), the
        multibody's inverse inertia is made again and the rows of ``kin`` on
        its links get their W, W_com and the torque change's share of a_ext
        from it (the caller then puts the manager's state back and steps the
        contacts again); True then. The first trial's prediction (the last
        step's loads, an impact's stopping force) missed about one step in
        ten on the ant and the humanoid: a force of 10x the predicted one
        holds a joint the trial left free (the humanoid's forearm, seed 4:
        +6.05 J in one step, docs/engines.md)."""
        t0 = time.perf_counter()
        pair = np.asarray(out.pair, int)
        force = np.asarray(out.force, float)
        hit = np.flatnonzero(np.any(force != 0.0, axis=1))
        uids = sorted(self._engaged)
        loads = (pair[hit], force[hit], np.asarray(out.point, float)[hit]) if hit.size else None
        held = self._try_step(bodies, loads, uids)
        changed = [u for u in uids if not np.array_equal(held[u], self._engaged[u])]
        if changed:
            old = {u: self._torque_dq(u) for u in changed}
            for u in changed:
                self._engaged[u] = held[u]
                mb = self._multibody(u)
                del mb[4:]
                mb[2] = None  # M^-1 with the new held joints (_minv), the torque change through it (_torque_dq)
            kp = np.asarray(kin.pair, int)
            tcache: dict = {}
            for r, i in enumerate(kp.tolist()):
                j1, j2 = self._slot[i]
                uid_r = {int(self._b_uid[j]) for j in (j1, j2) if self._b_art[j]}
                if not uid_r & set(changed):
                    continue
                poses = (bodies.pose(j1), bodies.pose(j2))
                kin.W[r], kin.W_com[r] = self._inverse_inertia(i, poses, kin.point[r])
                if self._trial_a_ext_ok(i):  # from the second trial, whose held set is now H (_trial_a_ext)
                    kin.a_ext[r] = self._trial_a_ext(bodies, i, kin.point[r], tcache)
                    self._last_a_ext[i] = kin.a_ext[r]
                    continue
                for b, pose, j, sign in ((self._bodies[i][0], poses[0], j1, 1.0),
                                         (self._bodies[i][1], poses[1], j2, -1.0)):
                    if not (self._b_art[j] and b[0] in old):
                        continue
                    dq0, dq1 = old[b[0]], self._torque_dq(b[0])
                    if dq0 is None and dq1 is None:
                        continue
                    diff = (0.0 if dq1 is None else dq1) - (0.0 if dq0 is None else dq0)
                    kin.a_ext[r] = kin.a_ext[r] + sign * (self._jacobian(b, pose, kin.point[r]) @ diff)
                    self._last_a_ext[i] = kin.a_ext[r]
        self.limit_trial_s += time.perf_counter() - t0
        return bool(changed)

    def _trial_a_ext_ok(self, i) -> bool:
        """Pair i's a_ext can be taken from this step's trial (_trial_a_ext):
        with ``trial_a_ext``, a trial taken this step, and each body of the
        pair a link of a multibody or fixed (a free body's finite difference
        is exact: nothing but the pairs moves it)."""
        if not (self.trial_a_ext and self._engaged_at == self._steps and self._trial_end):
            return False
        j1, j2 = self._slot[i]
        return bool((self._b_art[j1] or self._b_art[j2]) and (self._b_art[j1] or self._b_fixed[j1])
                    and (self._b_art[j2] or self._b_fixed[j2]))

    def _trial_a_ext(self, bodies: _Bodies, i, point, cache: dict) -> np.ndarray:
        """Pair i's a_ext [m/s^2] (3,) from this step's trial (``trial_a_ext``):
        the velocity change of the material points at ``point`` over the
        trial's ``stepSimulation`` (pybullet's own step: gravity, this step's
        torques, the velocity terms, the limits it held), less the change the
        trial's MSF loads F_q caused, dt J_p M_H^-1 sum_q J_q^T F_q through
        the held joints' inverse inertia (:meth:`_minv`, the trial's held set
        H), over dt; plus, as the finite difference keeps them
        (:meth:`_cross_dv`), the other pairs' forces the manager holds into
        this step (``ContactManager._held_force``: an island takes them out
        of its rows' a_ext again and couples them explicitly; left out, they
        were taken out twice: the ant put down on its feet sank into the floor
        at 36 mm/s while its internal approach stood still, +13.4 J). Given H
        pybullet's step is linear in the loads, so this is the step's own
        acceleration from everything but the contacts; the finite difference
        of the last step's velocities (the default without the trial) is the
        last step's, and missed the change within one step of the velocity
        terms, the Jacobians of turning legs and the limits (docs/engines.md).
        ``cache`` holds the loads' dq per multibody for one step (and one
        trial)."""
        dt = self._dt
        out = np.zeros(3)
        held = self.manager._held_force
        for side, sign in ((0, 1.0), (1, -1.0)):
            j = int(self._slot[i, side])
            if not self._b_art[j]:
                continue
            b = self._body_list[j]
            uid = b[0]
            r0 = point - bodies.com[j]
            e = self._trial_end[j]
            v0 = bodies.v[j] + np.cross(bodies.w[j], r0)
            v1 = e.v + np.cross(e.w, e.rot @ (bodies.rot[j].T @ r0))
            if uid not in cache:
                cache[uid] = self._loads_dq(bodies, uid, self._trial_used, held)
            Jp = self._jacobian(b, bodies.pose(j), point)
            a = (v1 - v0) / dt - Jp @ cache[uid]
            if np.any(held[i] != 0.0):  # the pair's own held force is no outside load (_cross_dv: add_own_dv)
                own = self._loads_dq(bodies, uid, None, held, only=i)
                a = a - Jp @ own
            out += sign * a
        return out

    def _loads_dq(self, bodies: _Bodies, uid, loads, held, only=None) -> np.ndarray:
        """M_H^-1 (sum_q J_q^T F_q - sum_h J_h^T H_h) of multibody ``uid`` [per
        coordinate, /s^2]: loads ((pairs, forces (k, 3) [N], points (k, 3)) or
        None) at their points, H the manager's held forces (P, 3) [N] at the
        pairs' last contact points (``_pt``), +F on body 1 and -F on body 2
        (:meth:`_trial_a_ext`); ``only``: just pair ``only``'s held force,
        with the opposite sign (its own, to be taken out)."""
        Q = np.zeros(self._minv(uid).shape[0])
        terms = []
        if loads is not None and only is None:
            terms += [(int(k), np.asarray(F, float), np.asarray(pt, float), 1.0)
                      for k, F, pt in zip(np.asarray(loads[0], int).tolist(), loads[1], loads[2])]
        hp = [only] if only is not None else np.flatnonzero(np.any(held != 0.0, axis=1)).tolist()
        terms += [(int(k), held[k], self._pt[k], 1.0 if only is not None else -1.0) for k in hp]
        for k, F, pt, g in terms:
            for sd, sg in ((0, 1.0), (1, -1.0)):
                jj = int(self._slot[k, sd])
                bb = self._body_list[jj]
                if self._b_art[jj] and bb[0] == uid:
                    Q += g * sg * (self._jacobian(bb, bodies.pose(jj), pt).T @ F)
        return self._minv(uid) @ Q

    def _held_over_step(self, uid) -> np.ndarray:
        """(m,) bool: the movable joints of multibody ``uid`` a limit held over
        the step just taken from this step's start state (:meth:`_multibody`):
        pybullet's limit row (btMultiBodyJointLimitConstraint) bounds the end
        speed, >= (lo - q)/dt while q > lo (speculative: it ends on the limit),
        >= 0 beyond it (no position correction, robots.LIMIT_ERP); a joint
        ending within ENGAGED_ATOL of a bound was held."""
        q0 = np.asarray(self._multibody(uid)[0], float)
        qd1 = np.array([s[1] for s in pb.getJointStates(uid, self._movable[uid], physicsClientId=self.client)], float)
        lim = self._limits_of(uid)
        b_lo = np.where(q0 > lim[:, 0], (lim[:, 0] - q0) / self._dt, 0.0)
        b_hi = np.where(q0 < lim[:, 1], (lim[:, 1] - q0) / self._dt, 0.0)
        return (lim[:, 0] < lim[:, 1]) & ((np.abs(qd1 - b_lo) <= ENGAGED_ATOL) | (np.abs(qd1 - b_hi) <= ENGAGED_ATOL))

    def _count_trial_misses(self) -> None:
        """After the real step: a multibody whose step held a joint the trial
        left free (``limit_trial_misses[0]``) or left free one the trial held
        (``[1]``), by the trial's own criterion (:meth:`_held_over_step`): that
        step's contacts had a W = J M^-1 J^T with the wrong joints held."""
        for uid, tried in self._engaged.items():
            real = self._held_over_step(uid)
            self.limit_trial_misses[0] += int(np.any(real & ~tried))
            self.limit_trial_misses[1] += int(np.any(tried & ~real))

    def _trial_loads(self, bodies: _Bodies):
        """(pairs, forces (k, 3) [N], points (k, 3) [m]) the trial step applies
        (:meth:`_limit_trial`), or None: the last step's MSF loads (the
        prediction of this step's for a resting contact), and for a pair on a
        multibody whose contact point, at the last step's point and normal,
        closes now at v_n > 0 and reaches the floor within the step
        (x + dt v_n > 0, x the last step's x advanced by dt v_n), at least
        the force that stops that closing within the step, v_n / (n.W.n dt)
        along n (the rigid impulse; the last step's W): the last step's loads
        alone missed an impact onto a limit, the step's contact force holding
        a joint the trial left free (the humanoid's forearm striking the floor
        at 5.3 m/s with its elbow free in the trial, W 7x the engine's
        response, +5.3 J; the capped ant landing on its ankle limits, +18.1 J;
        docs/engines.md)."""
        loads, kin = self._last_loads, self._last_kin
        ph = [] if loads is None else [int(i) for i in loads[0]]
        F = [] if loads is None else [f for f in np.asarray(loads[1], float)]
        pts = [] if loads is None else [q for q in np.asarray(loads[2], float)]
        if kin is not None:
            dt = self._dt
            for r, i in enumerate(np.asarray(kin.pair, int).tolist()):
                j1, j2 = self._slot[i]
                if not (self._b_art[j1] or self._b_art[j2]):
                    continue
                n, pt = kin.normal[r], kin.point[r]
                v1 = bodies.v[j1] + np.cross(bodies.w[j1], pt - bodies.com[j1])
                v2 = bodies.v[j2] + np.cross(bodies.w[j2], pt - bodies.com[j2])
                vn = -float((v1 - v2) @ n)
                w = float(n @ kin.W[r] @ n)
                if not (vn > 0.0 and w > 0.0 and kin.x[r] + 2.0 * dt * vn > 0.0):
                    continue
                stop = vn / (w * dt)
                if i in ph:
                    q = ph.index(i)
                    fn = float(F[q] @ n)
                    if fn < stop:
                        F[q] = F[q] + (stop - fn) * n
                else:
                    ph.append(i)
                    F.append(stop * n)
                    pts.append(pt)
        if not ph:
            return None
        return np.array(ph, int), np.array(F, float).reshape(-1, 3), np.array(pts, float).reshape(-1, 3)

    def _limits_of(self, uid) -> np.ndarray:
        """(lower, upper) limits of the multibody's movable joints (m, 2) [rad or m] (cached)."""
        if uid not in self._limits:
            c = self.client
            info = [pb.getJointInfo(uid, j, physicsClientId=c) for j in self._movable[uid]]
            self._limits[uid] = np.array([[i[8], i[9]] for i in info], float).reshape(-1, 2)
        return self._limits[uid]

    def _held_dofs(self, uid, q) -> np.ndarray:
        """Columns of the mass matrix (a floating base's 6 first) of the movable
        joints held by a limit: with ``limit_trial``, those a limit held in
        this step's trial (:meth:`_limit_trial`); else those at or beyond a
        limit of their range (JOINT_LIMIT_TOL)."""
        base = 0 if self._base_fixed(uid) else 6
        if self._engaged_at == self._steps and uid in self._engaged:
            return np.flatnonzero(self._engaged[uid]) + base
        lim = self._limits_of(uid)
        q = np.asarray(q, float)
        on = (lim[:, 0] < lim[:, 1]) & ((q <= lim[:, 0] + JOINT_LIMIT_TOL) | (q >= lim[:, 1] - JOINT_LIMIT_TOL))
        return np.flatnonzero(on) + base

    def _jacobian(self, b, pose, point):
        """Translational Jacobian (3, ndof) of the material point of link b at ``point``."""
        uid, link = b
        q, qd = self._joint_state(uid)
        # calculateJacobian's localPosition is measured from the link (URDF) frame's origin but
        # expressed in the inertial frame's axes, not "around the centre of mass" as documented
        # (bulletphysics/bullet3 #4668; checked in tests/test_pybullet.py against the hinge inertia)
        local = pose.rot.T @ (point - pose.frame)
        Jt, _ = pb.calculateJacobian(uid, link, local.tolist(), q, qd, [0.0] * len(q), physicsClientId=self.client)
        # ... and it answers in the base's frame, a floating base's six velocities too (its angular then linear
        # velocity in the base's axes, as calculateMassMatrix's coordinates): the point's world velocity is
        # R_base J [R_base^T w; R_base^T v; qd] (measured on pybullet 3.2.7: cartpole.urdf with its fixed base
        # turned, ant.xml and humanoid.xml with the torso turned; tests/test_robots_pybullet.py). So the world
        # Jacobian of the coordinates pybullet's M uses is R_base J; W = R J M^-1 J^T R^T.
        return self._multibody(uid)[3] @ np.asarray(Jt, float).reshape(3, -1)

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
            Minv = self._minv(b1[0])
            J = self._jacobian(b1, poses[0], point) - self._jacobian(b2, poses[1], point)
            Jc1 = self._jacobian(b1, poses[0], poses[0].com)
            Jc2 = self._jacobian(b2, poses[1], poses[1].com)
            return J @ Minv @ J.T, (Jc1 - Jc2) @ Minv @ J.T
        # +P on body 1 and -P on body 2: both bodies' terms add to the relative change
        for b, pose in ((b1, poses[0]), (b2, poses[1])):
            if self._articulated(b):
                Minv = self._minv(b[0])
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

    def _detect(self, i, poses):
        """(x, n body2->body1, point mid-overlap) of pair i (:mod:`engines._geometry`; a sphere on a
        box: on the box rounded by its edge radius, engines._narrow.SphereOnBox, whose law takes the
        curvature at the point); against a plane or a box, the sphere's surface point at a gap."""
        if self._narrow_of[i][0] >= 0:
            return self._narrow_slot(i, poses)
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
            sb, mgr = self._sphere_box[i], self.manager
            x, n, curv = sb.contact(c1, c2, R2)
            deep = max(x, float(mgr.x[i]) if mgr.active[i] else x)  # the engine's or the contact's
            if deep > r1 or self._handoff[i]:  # the reach: what the surfaces can close in a step
                self._through(i, deep > r1, x, self._closing_bound(i, poses, self._gravity()) + THROUGH_REACH)
            sb.update(curv, bool(mgr.active[i]), mgr.refresh_law)
            det = _geometry.Detection.of_sphere(np.asarray(c1, dtype=float)[None], np.array([r1]), np.array([x]),
                                                n[None], np.full((1, 2), math.inf))
        if flip:
            det = det.swapped()
        if s2.kind == "sphere":
            return float(det.x[0]), det.normal[0], det.point[0]
        # on a plane or a box face, the sphere's own point (mid-overlap; its surface point at a
        # gap), as the fast rows and MuJoCo's adapter: the lever arm R - max(x, 0)/2 (LEVER_DOC)
        return float(det.x[0]), det.normal[0], (det.point2 if flip else det.point1)[0]

    def _gravity(self) -> np.ndarray:
        par = pb.getPhysicsEngineParameters(physicsClientId=self.client)
        return np.array([par[k] for k in ("gravityAccelerationX", "gravityAccelerationY", "gravityAccelerationZ")])

    def _kinematics(self, bodies: _Bodies, grav, required):
        """Rows of the pairs done one by one (box faces, links, the narrow pairs)."""
        if self._art_slots:
            if self.limit_trial:
                self._limit_trial(bodies)
            self._limits_engaged()
            self._rest_together()
        if self._narrow:
            self._narrow_points(bodies, grav, required)
        rows = []
        tcache: dict = {}  # the trial loads' dq per multibody (_trial_a_ext)
        for i in self._slow:
            b1, b2 = self._bodies[i]
            j1, j2 = self._slot[i]
            poses = (bodies.pose(j1), bodies.pose(j2))
            x, nrm, point = self._detect(i, poses)
            v1 = poses[0].v + np.cross(poses[0].w, point - poses[0].com)
            v2 = poses[1].v + np.cross(poses[1].w, point - poses[1].com)
            v_rel = v1 - v2
            v_com_rel = poses[0].v - poses[1].v
            trial = self._trial_a_ext_ok(i)
            if trial:  # this step's own, from the trial (_trial_a_ext): its torques and limits are in it
                a_ext = self._trial_a_ext(bodies, i, point, tcache)
            elif self._stopped[i]:  # a joint stopped at a limit: its impulse is no acceleration (_limits_engaged)
                a_ext = self._last_a_ext[i].copy()
            elif self._have_last[i]:
                a_ext = (v_rel - self._last_v_rel[i] - self._last_dv[i]) / self._dt
            else:
                a_ext = grav * (self._free(b1) - self._free(b2))
            for b, pose, sign in ((b1, poses[0], 1.0), (b2, poses[1], -1.0)):
                if trial:
                    break
                dq = self._torque_dq(b[0]) if self._b_art[self._slot[i, 0 if sign > 0 else 1]] else None
                if dq is not None:  # this step's change of the joint torques (set_joint_torques)
                    a_ext = a_ext + sign * (self._jacobian(b, pose, point) @ dq)
            self._last_a_ext[i] = a_ext
            rows.append((i, x, nrm, point, v_rel, v_com_rel, a_ext, poses))
        return rows

    def _narrow_points(self, bodies: _Bodies, grav, required) -> None:
        """The points of every narrow pair at this step's poses
        (engines.pybullet.narrow.detect), each given a slot
        (engines._narrow.SlotMatcher: a corner keeps its slot while it
        touches), into ``_narrow_found``. The reach: what the surfaces can
        close in a step at the bodies' speeds (x CANDIDATE_FACTOR), at least
        narrow.REACH_FLOOR."""
        for np_ in self._narrow:
            i0 = np_.first
            j1, j2 = self._slot[i0]
            poses = (bodies.pose(j1), bodies.pose(j2))
            reach = max(self._closing_bound(i0, poses, grav), _narrow.REACH_FLOOR)
            if np_.box is not None:
                self._box_points(np_, poses, required)
                continue
            if np_.line is not None and self._line_points(np_, poses, required):
                continue
            plane = np_.method == "plane"  # every feature, slots by narrow.assign_plane_slots
            x, pts, nrm = _narrow.detect(np_, (poses[0].com, poses[0].rot), (poses[1].com, poses[1].rot),
                                         math.inf if plane else reach, self.client)
            local = (pts - poses[0].com) @ poses[0].rot
            if plane:
                same = np_.matcher.tol if np_.shape1.kind != "mesh" else SAME_VERTEX * np_.shape1.extent()
                slots, changed = _narrow.assign_plane_slots(np_.matcher, local, x, required[i0:i0 + np_.n], reach,
                                                            same)
                # a slot on another feature: its a_ext finite difference would compare two material points
                self._have_last[i0 + np.flatnonzero(changed)] = False
            else:
                slots = np_.matcher.assign(local, x, required[i0:i0 + np_.n])
            for q in range(np_.n):
                self._narrow_found[i0 + q] = None
            for k, q in enumerate(slots):
                if q >= 0:
                    self._narrow_found[i0 + q] = (float(x[k]), pts[k], nrm[k])

    def _line_points(self, np_: _narrow.NarrowPair, poses, required) -> bool:
        """A capsule's or cylinder's side on a plane (engines._narrow.SideLine,
        as the MuJoCo adapter): below LINE_TILT_MAX its slots 0 and 1 are the
        side's two ends carrying the line law, put into ``_narrow_found``
        (True); else False (the end points, by narrow.detect). A change of
        mode restarts the slots' matching and their a_ext."""
        i0, n = np_.first, np_.n
        c1, R1 = self._world_shape(np_.shape1, poses[0])
        c2, R2 = self._world_shape(np_.shape2, poses[1])
        normal = R2 @ (np.asarray(np_.shape2.size, float) / np.linalg.norm(np_.shape2.size))
        mgr = self.manager
        moving = mgr.active[i0:i0 + n] & ~mgr.settled[i0:i0 + n]
        if np_.line.update(c1, R1, c2, normal, required[i0:i0 + n], self.pairs[i0].law, moving):
            np_.matcher.anchor[:] = np.nan
            self._have_last[i0:i0 + n] = False
        if np_.line.mode == "ring":  # a cylinder on its rim (engines._narrow.RimRing)
            ring = np_.line.ring
            if not np.all(_narrow.on_face(np_.shape2, c2, R2, ring.points())):  # past a floor's edge: the points
                return False
            self._have_last[i0 + np.flatnonzero(np_.line.moved)] = False
            nWn = self._normal_coupling(i0, poses, ring.points(), ring.rim.normal)
            self._narrow_found[i0:i0 + n] = np_.line.ring_slots(nWn, self.manager.refresh_law)
            return True
        if np_.line.mode != "line":
            return False
        ends = np_.line.ends
        if not np.all(_narrow.on_face(np_.shape2, c2, R2, ends.lowest)):  # an end past a floor's edge: the points
            return False
        nWn = self._normal_coupling(i0, poses, ends.lowest, ends.normal)
        self._narrow_found[i0:i0 + n] = np_.line.slots(nWn, n, self.manager.refresh_law)
        return True

    def _box_points(self, np_: _narrow.NarrowPair, poses, required) -> None:
        """A box on a plane or a fixed box's face (engines._narrow.BoxOnPlane,
        as the MuJoCo adapter), or on a free box's face (BoxOnBox, at both
        boxes' poses): its slots are its lowest rounded corners, put
        into ``_narrow_found``; a slot given another corner restarts its a_ext."""
        from engines._narrow import BoxOnBox
        from engines._narrow import face_toward as _face_toward

        i0, n = np_.first, np_.n
        c1, R1 = self._world_shape(np_.shape1, poses[0])
        c2, R2 = self._world_shape(np_.shape2, poses[1])
        mgr = self.manager
        if isinstance(np_.box, BoxOnBox):  # a box on a free box: its face at its current pose
            moving = mgr.active[i0:i0 + n] & ~mgr.settled[i0:i0 + n]
            up = -np.asarray(self._gravity(), dtype=float)
            changed = np_.box.update(c1, R1, c2, R2, required[i0:i0 + n], self.pairs[i0].law, self.laws, up,
                                     self.time)
            self._have_last[i0 + np.flatnonzero(changed)] = False
            nWn = self._normal_coupling(i0, poses, np_.box.points(), np_.box.normal)
            self._narrow_found[i0:i0 + n] = np_.box.slots(nWn, moving, mgr.refresh_law)
            return
        if np_.shape2.kind == "plane":
            normal = R2 @ (np.asarray(np_.shape2.size, float) / np.linalg.norm(np_.shape2.size))
        else:  # a fixed box: its face toward the box
            c2, normal = _face_toward(np_.shape2.size, c2, R2, c1)
        mgr = self.manager
        moving = mgr.active[i0:i0 + n] & ~mgr.settled[i0:i0 + n]
        changed = np_.box.update(c1, R1, c2, normal, required[i0:i0 + n], self.pairs[i0].law, self.laws)
        self._have_last[i0 + np.flatnonzero(changed)] = False
        nWn = self._normal_coupling(i0, poses, np_.box.points(), normal)
        self._narrow_found[i0:i0 + n] = np_.box.slots(nWn, moving, mgr.refresh_law)

    def _normal_coupling(self, i, poses, points, normal) -> np.ndarray:
        """n.W_jk.n (k, k) [1/kg] of pair i between its material points
        ``points`` (k, 3) [m] along ``normal`` (3,): the relative normal speed
        at point j that a unit impulse along n at point k gives (+ on body 1,
        - on body 2), through each body's inverse inertia (free: 1/m +
        (r_j x n).I^-1 (r_k x n); links: J_j M^-1 J_k^T, both links' Jacobians
        together when they share a multibody)."""
        pts = np.asarray(points, float).reshape(-1, 3)
        n = np.asarray(normal, float)
        out = np.zeros((pts.shape[0], pts.shape[0]))
        rows: dict[int, np.ndarray] = {}  # a multibody's n.J (k, ndof), both links' (signed) summed
        for sign, b, pose in ((1.0, self._bodies[i][0], poses[0]), (-1.0, self._bodies[i][1], poses[1])):
            if self._articulated(b):
                Jn = np.stack([n @ self._jacobian(b, pose, p) for p in pts])
                rows[b[0]] = rows.get(b[0], 0.0) + sign * Jn
            elif not self._fixed(b):
                info = pb.getDynamicsInfo(b[0], b[1], physicsClientId=self.client)
                u = np.cross(pts - pose.com, n) @ pose.rot  # principal axes
                out += 1.0 / info[0] + (u / np.asarray(info[2], float)) @ u.T
        for uid, Jn in rows.items():
            out += Jn @ self._minv(uid) @ Jn.T
        return out

    def _narrow_slot(self, i, poses):
        """(x, n, point) of narrow slot i from this step's points; a slot
        without a point is far (x = -1 m, as the MuJoCo adapter)."""
        found = self._narrow_found[i]
        if found is None:
            return -1.0, np.array([0.0, 0.0, 1.0]), poses[0].com.copy()
        x, point, n = found
        return x, n.copy(), point.copy()

    def _narrow_law(self, i, poses, point, n, x: float = 0.0) -> None:
        """Give narrow slot i, a candidate not in contact, the law for the
        curvature at its point (engines._narrow.contact_law: a law per contact
        point; a lying side's ends their share of the line law). Only the
        candidates a contact can begin in this step need it (the others' laws
        are never read before they are candidates): the duck's 4 slots took
        2.5 ms per step with a mesh fit for every free slot every step."""
        from engines._narrow import contact_law

        k, slot = self._narrow_of[i]
        np_ = self._narrow[k]
        if np_.box is not None:  # a box's corner: its edge's end law (engines._narrow.BoxOnPlane)
            if np_.box.law[slot] is not None:
                self.manager.set_law(i, np_.box.law[slot])
            return
        if np_.line is not None and np_.line.mode == "line":  # its ends' share of the line law
            self.manager.set_law(i, np_.line.law[slot])
            return
        if np_.line is not None and np_.line.mode == "ring":  # a slot of a cylinder's rim ring
            self.manager.set_law(i, np_.line.ring.law[slot])
            return
        pose1 = self._world_shape(np_.shape1, poses[0])
        pose2 = self._world_shape(np_.shape2, poses[1])
        self.manager.set_law(i, contact_law(self.pair_names[i], self.pairs[i].law, self.laws, np_.geom1, pose1,
                                            np_.geom2, pose2, point, n, self.time, x))

    def _closing_bound(self, i, poses, grav) -> float:
        """A bound on the distance the surfaces of pair i can close within one step [m]."""
        ext = [float(s.size[0]) if s.kind == "sphere" else float(np.linalg.norm(s.pos)) + s.extent()
               for s in self._shapes[i]]
        vb = (np.linalg.norm(poses[0].v - poses[1].v) + np.linalg.norm(poses[0].w) * ext[0]
              + np.linalg.norm(poses[1].w) * ext[1])
        ab = np.linalg.norm(self._last_a_ext[i]) if self._have_last[i] else 2.0 * np.linalg.norm(grav)
        return CANDIDATE_FACTOR * (vb * self._dt + 0.5 * ab * self._dt**2)

    def _free(self, b) -> float:
        return 1.0 if (not self._articulated(b) and not self._fixed(b)) else 0.0

    def _fast_rows(self, bodies: _Bodies, grav, required) -> dict:
        """Candidate rows of the pairs done all at once (a dict of
        ContactKinematics fields) and the a_ext bookkeeping of all of them.
        Same quantities as the pair-by-pair path: the contact point mid-overlap
        for velocities and W (:meth:`_free_inverse_inertia` in closed form)."""
        f = self._fast
        j1, j2 = self._slot[f, 0], self._slot[f, 1]
        rot1, rot2 = bodies.rot[j1], bodies.rot[j2]
        c1 = bodies.com[j1] + np.einsum("kij,kj->ki", rot1, self._f_s1)
        c2 = bodies.com[j2] + np.einsum("kij,kj->ki", rot2, self._f_s2)
        k = f.size
        x, nrm, point = np.empty(k), np.empty((k, 3)), np.empty((k, 3))
        pl, sp = np.flatnonzero(self._f_plane), np.flatnonzero(~self._f_plane)
        if pl.size:
            det = _geometry.sphere_plane(c1[pl], self._f_r1[pl], c2[pl],
                                         np.einsum("kij,kj->ki", rot2[pl], self._f_size2[pl]))
            # body 1's own point (mid-overlap; its surface point at a gap), as the compiled fast_rows
            x[pl], nrm[pl], point[pl] = det.x, det.normal, det.point1
        if sp.size:
            det = _geometry.sphere_sphere(c1[sp], self._f_r1[sp], c2[sp], self._f_size2[sp, 0])
            x[sp], nrm[sp], point[sp] = det.x, det.normal, det.point
        r1, r2 = point - bodies.com[j1], point - bodies.com[j2]
        v_rel = (bodies.v[j1] + cross_rows(bodies.w[j1], r1)) - (bodies.v[j2] + cross_rows(bodies.w[j2], r2))
        free1, free2 = self._b_free[j1], self._b_free[j2]
        a0 = grav * (free1.astype(float) - free2.astype(float))[:, None]
        a_ext = np.where(self._have_last[f][:, None], (v_rel - self._last_v_rel[f] - self._last_dv[f]) / self._dt,
                         a0)
        self._last_a_ext[f] = a_ext
        self._last_v_rel[f], self._last_dv[f], self._have_last[f] = v_rel, 0.0, True
        self._pt[f] = point
        reach = closing_distance(-np.einsum("ij,ij->i", v_rel, nrm), -np.einsum("ij,ij->i", a_ext, nrm), self._dt,
                                 CANDIDATE_FACTOR)
        self._gaps[f] = x
        c = np.flatnonzero((x > -(reach + self._push[f])) | required[f])
        j1c, j2c = j1[c], j2[c]
        W = self._free_W(bodies, j1c, r1[c])
        f2 = self._b_free[j2c]
        if np.any(f2):
            W[f2] += self._free_W(bodies, j2c[f2], r2[c][f2])
        W_com = (self._b_inv_m[j1c] + self._b_inv_m[j2c])[:, None, None] * np.eye(3)
        return dict(pair=f[c], x=x[c], normal=nrm[c], point=point[c], v_rel=v_rel[c],
                    v_com_rel=bodies.v[j1c] - bodies.v[j2c], W=W, W_com=W_com, a_ext=a_ext[c])

    def _first_push(self, rows: dict) -> bool:
        """In the first step (no last step's rows to take the push from: islands.push_reach) the
        push of the free pairs' own candidate rows and gaps; True when it reaches farther than the
        push the rows were listed with (they are listed again: a strike in the very first step
        along a row of balls 0.1 mm apart, otherwise found 0.4 mm deep a step later)."""
        push = push_reach(self._keys, np.asarray(rows["pair"], np.int64), rows["x"], rows["v_rel"], self._dt,
                          CANDIDATE_FACTOR, self._gaps)
        more = bool(np.any(push > self._push))
        self._push = np.maximum(self._push, push)
        return more

    def _free_W(self, bodies: _Bodies, j, r):
        """1/m Id - [r]x I^-1 [r]x (k, 3, 3) of free bodies j at lever arms r (k, 3),
        I^-1 = R diag(1/I) R^T in world axes (the inertial frame's axes are the principal ones)."""
        R = bodies.rot[j]
        Iinv = (R * self._b_inv_I[j][:, None, :]) @ R.transpose(0, 2, 1)
        rx = _skew(r)
        return self._b_inv_m[j][:, None, None] * np.eye(3) - rx @ Iinv @ rx

    def _fast_rows_compiled(self, bodies: _Bodies, grav, required) -> dict:
        """:meth:`_fast_rows` in :func:`engines.pybullet._kernels.fast_rows`."""
        k_all = self._fast.size
        out = dict(pair=np.empty(k_all, np.int64), x=np.empty(k_all), normal=np.empty((k_all, 3)),
                   point=np.empty((k_all, 3)), v_rel=np.empty((k_all, 3)), v_com_rel=np.empty((k_all, 3)),
                   W=np.empty((k_all, 3, 3)), W_com=np.empty((k_all, 3, 3)), a_ext=np.empty((k_all, 3)))
        k, status, q = self._k.fast_rows(
            self._f64, self._f_j1, self._f_j2, self._f_s1, self._f_r1, self._f_plane, self._f_s2, self._f_size2,
            bodies.com, bodies.rot, bodies.v, bodies.w, self._b_free, self._b_inv_m, self._b_inv_I,
            self._last_v_rel, self._last_dv, self._have_last, self._last_a_ext, self._pt, required,
            np.asarray(grav, float), self._dt, CANDIDATE_FACTOR, self._push, self._gaps, *out.values())
        if status == self._k.COINCIDENT:
            raise ValueError(f"pairs[{int(self._fast[q])}]: sphere-sphere: the centres coincide, the contact "
                             "normal is undefined")
        return {key: val[:k] for key, val in out.items()}

    # -- one step -------------------------------------------------------------
    def _step_once(self):
        dt = self._dt
        required = np.zeros(len(self.pairs), bool)
        required[self.manager.required_pairs] = True  # in contact, or a timing correction to remove
        bodies = self._read_bodies()
        if self._kin is not None:
            self._drive(bodies)
        self._check_advance(bodies)
        self._cur_bodies = bodies
        if self._art_slots:
            self._account_multibody_work(bodies)
        bal = self.manager._balance
        if bal is not None:  # the last step's islands, before the anchoring moves any x
            bal.close(self.manager, self.time - dt)
        par = pb.getPhysicsEngineParameters(physicsClientId=self.client)
        check_client_params(par, dt)  # (the user may have changed them between steps)
        grav = np.array([par[k] for k in ("gravityAccelerationX", "gravityAccelerationY", "gravityAccelerationZ")])
        blocks = []
        if self._fast.size:
            fast_rows = self._fast_rows_compiled if self.compiled else self._fast_rows
            first = not self._pushed
            saved = self._have_last.copy() if first else None
            rows = fast_rows(bodies, grav, required)
            if first and self._first_push(rows):  # the push of this step's own rows lists more pairs: again
                self._have_last[:] = saved
                rows = fast_rows(bodies, grav, required)
            blocks.append(rows)
        cand = []
        late = []  # the first step's pairs beyond the reach (_first_push)

        def take(i, x, nrm, point, v_rel, v_com_rel, a_ext, poses):
            if self._narrow_of[i][0] >= 0 and not self.manager.active[i]:
                self._narrow_law(i, poses, point, nrm, x)
            W, Wc = self._inverse_inertia(i, poses, point)
            cand.append((i, x, nrm, point, v_rel, v_com_rel, W, Wc, a_ext))

        for i, x, nrm, point, v_rel, v_com_rel, a_ext, poses in self._kinematics(bodies, grav, required):
            closing = float(closing_distance(-(v_rel @ nrm), -(a_ext @ nrm), dt, CANDIDATE_FACTOR))
            if x > -(closing + self._push[i]) or required[i]:
                take(i, x, nrm, point, v_rel, v_com_rel, a_ext, poses)
            elif not self._pushed:
                late.append((closing, (i, x, nrm, point, v_rel, v_com_rel, a_ext, poses)))
            self._last_v_rel[i] = v_rel
            self._last_dv[i] = 0.0
            self._have_last[i] = True
            self._pt[i] = point
            self._gaps[i] = x
        if late and (cand or blocks):
            # the first step: the push of this step's own rows lists the pairs it reaches too
            # (_first_push; links on slide joints 0.1 mm apart struck in the first step)
            rows = [dict(pair=np.array([c[0] for c in cand], np.int64), x=np.array([c[1] for c in cand], float),
                         v_rel=np.array([c[4] for c in cand], float).reshape(-1, 3))] + blocks
            self._first_push({key: np.concatenate([np.asarray(r[key]) for r in rows]) for key in ("pair", "x", "v_rel")})
            for closing, args in late:
                if args[1] > -(closing + self._push[args[0]]):
                    take(*args)
            cand.sort(key=lambda c: c[0])  # in pair order
        shapes = dict(pair=(), x=(), normal=(3,), point=(3,), v_rel=(3,), v_com_rel=(3,), W=(3, 3), W_com=(3, 3),
                      a_ext=(3,))
        if cand or not blocks:
            blocks.append({key: np.array([r[q] for r in cand], float).reshape((-1,) + shp)
                           for q, (key, shp) in enumerate(shapes.items())})
        if len(blocks) == 1:
            cat = blocks[0]  # one block's rows are in pair order already
        else:
            cat = {key: np.concatenate([b[key] for b in blocks]) for key in shapes}
            order = np.argsort(cat["pair"], kind="stable")
            cat = {key: val[order] for key, val in cat.items()}
        # the manager steps every engine step, also with no candidate: it
        # completes finished records once their timing correction is gone
        kin = ContactKinematics(t=self.time, **{key: np.reshape(val, (-1,) + shapes[key])
                                                for key, val in cat.items()})
        kin.pair = np.asarray(kin.pair, int)
        kin.lever = self._lever(bodies, kin)
        self._cur_bodies = bodies
        if self.anchor_depth and self._art_slots:
            self._anchor_depths(kin)
        again = self.limit_trial and self.limit_retrial and self._engaged_at == self._steps
        saved = _snapshot.save(self.manager) if again else None
        out = self.manager.step(self._mask(kin))
        if again and self._limit_retrial(bodies, kin, out):
            _snapshot.restore(self.manager, saved)
            out = self.manager.step(self._mask(kin))
            self.limit_retrials += 1
        self._check_deep_onsets(float(kin.t))
        self._say_unchecked()
        self._last_kin, self._last_out = kin, out
        if self._kin is not None:
            self._drive_work(out)
        self._push = push_reach(self._keys, kin.pair, kin.x, kin.v_rel, dt, CANDIDATE_FACTOR, self._gaps)
        self._pushed = True
        pair = np.asarray(out.pair, int)
        force = np.asarray(out.force, float)
        hit = np.flatnonzero(np.any(force != 0.0, axis=1))
        self._last_loads = None
        if hit.size:
            ph, F = pair[hit], force[hit]
            self._cross_dv(bodies, ph, F * dt, kin.W[hit])
            self.impulse[ph] += F * dt
            self._apply(bodies, ph, F, np.asarray(out.point, float)[hit])
            if self._art_slots:
                self._keep_generalized_loads(bodies, ph, F, np.asarray(out.point, float)[hit])
            couples = None
            if out.torque is not None:
                couples = np.asarray(out.torque, float)[hit]
                self._apply_couples(bodies, ph, couples)
            self._last_loads = (ph, F, np.asarray(out.point, float)[hit], couples, bodies)
        pb.stepSimulation(self.client)
        if self._engaged_at == self._steps:
            self._count_trial_misses()
        self._steps += 1
        self._tau_last, self._tau = self._tau, {}  # pybullet applies TORQUE_CONTROL torques for one step
        # pairs in contact or that exerted a force this step (a contact may begin and end inside it)
        touched = np.union1d(self.manager.active_pairs, pair[hit])
        if touched.size:
            self._see_motors(touched)

    def _anchor_depths(self, kin: ContactKinematics) -> None:
        """Bring the internal approach x of the contacts in progress on a link
        of a multibody up to the engine's geometry where it lies deeper, at the
        step start: x <= max(x_e - (dt/2)(x'_e - x'_0), 0), x_e the engine's
        approach now, x'_e its approach rate now (less the timing correction's
        offset), x'_0 the closing speed at the contact's onset. Why that bound
        (state.RELAX_DOC): the engine's semi-implicit Euler moves a body by dt
        v_end, so over a sub-cycled step x_e advances (dt/2)(x'_end -
        x'_start) more than the integrated x; from the onset (x = x_e then)
        x_e - x = (dt/2)(x' - x'_0) while the steps' W and a_ext are right,
        and over a settled step it stays (x' ~ 0: x = x_e + (dt/2) x'_0).
        Deeper than that is drift: a link's a_ext is the last step's (the
        finite difference), its W may hold the wrong joints (limit_trial's
        misses), and a step's error of the contact point's velocity change
        moves x and x_e apart. Under the benchmark's random torques the ant's
        feet's x - x_e was 2.2 mm (median; 90 % 6.1 mm, up to 24.5 mm, seed
        3), the internal x the deeper in 86 % of the contact-steps: a foot
        the engine held 3.05 mm above the floor was pushed as from 2.1 mm
        inside it, and the step's error F (dx - dx_e) was a gain of 2.29 J
        (seed 3's first rest step, docs/engines.md). A move to a smaller
        approach releases the elastic energy between the two (a loss,
        ``anchor_released``; the tangential W_t - Q_t is kept); x is never
        moved deeper (that would store energy no force worked for: the
        resting relaxation does it, energy-funded, state.relax). A bound of 0
        ends the contact in the step (it opens from touching)."""
        from engines._contacts.balance import IslandBalance

        mgr = self.manager
        pair = np.asarray(kin.pair, int)
        j1, j2 = self._slot[pair, 0], self._slot[pair, 1]
        on = mgr.active[pair] & (self._b_art[j1] | self._b_art[j2])
        if not np.any(on):
            return
        r = np.flatnonzero(on)
        p = pair[r]
        n = np.asarray(kin.normal, float)[r]
        rate = -np.einsum("ij,ij->i", np.asarray(kin.v_rel, float)[r] - mgr.dv_corr[p], n)
        target = np.maximum(np.asarray(kin.x, float)[r] - 0.5 * self._dt * (rate - mgr.v_n_in[p]), 0.0)
        deep = mgr.x[p] > target
        if not np.any(deep):
            return
        q = p[deep]
        before = IslandBalance.stored_rows(mgr, q)
        mgr.x[q] = target[deep]
        self.anchor_released += float(np.sum(before - IslandBalance.stored_rows(mgr, q)))
        self.anchored += int(q.size)

    def _check_deep_onsets(self, t0: float) -> None:
        """Never silent: a contact on a link of a multibody or from a narrow
        phase that began in this step already overlapping with more elastic
        energy than ENERGY_GAIN_RTOL of its approach energy is flagged in its
        outside_validity and warned once per pair, in this step
        (engines._contacts.balance.DeepOnsets; ``deep_onsets`` counts them).
        The island energy check sees a multibody's contacts only from the
        step after (it closes an island at the next step start) and the
        single contact's COR check comes at the contact's end. Measured: the
        racecar's wheels, pybullet's 64-vertex hulls before they were taken
        for cylinders (narrow.as_cylinder), were found 1,024 m deep 5.8 mm
        above the floor and launched the car at 64 m/s with no warning."""
        if not self._deep_mask.any():
            return
        why = ("the body was loaded, reset or placed overlapping the other (start it clear), or "
               "the contact point found for it lies that far inside the other body (a narrow phase's point or "
               "fitted surface beyond the shape's own, a link moved into overlap by its joints within a step: "
               "a drive, a limit engaging); check the pair's shapes (link_shapes, curvature) or take a smaller "
               "time step")
        self._deep.check(self.manager, self._deep_mask, t0, why, self.pair_names, stacklevel=5)

    def _say_unchecked(self) -> None:
        """Never silent (issue 13): an island the energy check
        (engines._contacts.balance) leaves out because :meth:`_energy_probe`
        gives no value (NaN) for one of its bodies is said: the first time, a
        RuntimeWarning names its pairs and what still checks them;
        ``island_energy_unchecked`` lists every such pair and
        ``manager._balance.unchecked`` counts the island steps. Until issue
        13's multibody account (:meth:`_account_multibody_work`) every island
        holding a link of a multibody was left out; none is now."""
        bal = self.manager._balance
        if bal is None or self._unchecked_said or not bal.unchecked_pairs:
            return
        self._unchecked_said = True
        names = ", ".join(f"{p} {self.pair_names[p]}" for p in sorted(bal.unchecked_pairs))
        warnings.warn(f"island energy check left out at t = {self.time:.6g} s: the islands of pairs {names} hold a "
                      "link of a multibody, whose kinetic and potential energy the adapter cannot account for (its "
                      "joint motors, torques and limits do work it does not see), so a gain there is not flagged by "
                      "that check; each contact's COR is still checked at its end and a contact found deep at its "
                      "onset is flagged (deep_onsets); adapter.island_energy_unchecked lists the pairs (warned "
                      "once)", RuntimeWarning, stacklevel=4)

    @property
    def island_energy_unchecked(self) -> list[int]:
        """The pairs whose islands the energy check left out (:meth:`_say_unchecked`), sorted."""
        bal = self.manager._balance
        return [] if bal is None else sorted(bal.unchecked_pairs)

    @property
    def deep_onsets(self) -> int:
        """Contacts found deep at their onset and flagged (:meth:`_check_deep_onsets`)."""
        return self._deep.count

    def last_step_work(self, bodies=None) -> float:
        """Work [J] the MSF forces (and the couples of moving contact points)
        of the last :meth:`step` did on the moving bodies in pybullet's step,
        of ``bodies`` (body unique ids; default all): for each load and body,
        +-F . (v_start + v_end) / 2 dt at the material point it acted on
        (+-tq . (w_start + w_end) / 2 dt for a couple), v_start from the
        step's start and v_end read now (call it right after ``step``). With
        the mass matrix fixed over a step this is the kinetic energy the loads
        gave (semi-implicit Euler: exact for a body that does not turn). A
        turning body's step gives it up to a few % of this more or less: its
        new orientation, from the new velocity, enters its inertia and its
        links' Jacobians (measured on one step of a box spinning at 5 rad/s:
        2.4 % of a force's work; on the ant's legs turning at 5 rad/s with an
        ankle on its limit: 5-7 %). 0 when the last step applied no load."""
        if self._last_loads is None:
            return 0.0
        ph, F, point, couples, b0 = self._last_loads
        keep = None if bodies is None else {int(u) for u in bodies}
        c, work, end = self.client, 0.0, {}
        for q, i in enumerate(ph.tolist()):
            for side, sign in ((0, 1.0), (1, -1.0)):
                j = int(self._slot[i, side])
                uid, link = self._body_list[j]
                if self._b_fixed[j] or (keep is not None and uid not in keep):
                    continue
                if j not in end:
                    end[j] = self._pose((uid, link))
                e = end[j]
                local = b0.rot[j].T @ (point[q] - b0.com[j])  # the material point, in the body's frame
                v0 = b0.v[j] + np.cross(b0.w[j], point[q] - b0.com[j])
                v1 = e.v + np.cross(e.w, e.rot @ local)
                work += sign * float(F[q] @ (v0 + v1)) * 0.5 * self._dt
                if couples is not None and self._b_free[j]:  # on both free bodies alike (_apply_couples)
                    work += float(couples[q] @ (b0.w[j] + e.w)) * 0.5 * self._dt
        return work

    def _lever(self, bodies: _Bodies, kin: ContactKinematics) -> np.ndarray | None:
        """The moving contact point of the rows of free bodies (engines._contacts.state.LEVER_DOC,
        lever_terms_free: W01, W11, g0 (k, 21) from the lever arms point - com, the world inverse
        inertias R diag(1/I) R^T and the angular velocities); zeros (the point frozen over the
        step) for rows with a link of a multibody and for the rows the manager settled in the last
        step (a resting contact's overlap does not move within a step; the resting path stays as
        cheap). A fixed body turns with neither.
        The finite-difference a_ext of these rows, (v_rel - last v_rel - last dv)/dt, compares
        velocities at two different points when the overlap changed: it loses that part,
        g0 (max(x, 0) - max(x_last, 0))/dt, which the manager now integrates itself (d' g)."""
        pair = np.asarray(kin.pair, int)
        j1, j2 = self._slot[pair, 0], self._slot[pair, 1]
        live = ~self.manager.settled[pair] & ~self._b_art[j1] & ~self._b_art[j2] & (
            self._b_free[j1] | self._b_free[j2])
        xpos = np.maximum(np.asarray(kin.x, dtype=float), 0.0)
        x_last = self._x_last[pair]
        self._x_last[:] = 0.0
        self._x_last[pair] = xpos
        if not np.any(live):
            return None
        out = np.zeros((pair.size, 21))
        j1, j2 = j1[live], j2[live]
        pt = np.asarray(kin.point)[live]

        def inv_inertia(j):
            R = bodies.rot[j]
            Iinv = (R * self._b_inv_I[j][:, None, :]) @ R.transpose(0, 2, 1)
            return np.where(self._b_free[j][:, None, None], Iinv, 0.0)

        w1 = np.where(self._b_free[j1][:, None], bodies.w[j1], 0.0)
        w2 = np.where(self._b_free[j2][:, None], bodies.w[j2], 0.0)
        out[live] = lever_terms_free(np.asarray(kin.normal)[live], pt - bodies.com[j1], inv_inertia(j1), w1,
                                     pt - bodies.com[j2], inv_inertia(j2), w2)
        kin.a_ext = np.array(kin.a_ext, dtype=float)
        kin.a_ext[live] -= out[live, 18:21] * ((xpos - x_last)[live] / self._dt)[:, None]
        return out

    def _apply_couples(self, bodies: _Bodies, ph, torque) -> None:
        """Apply the couples of the moving contact points (ContactForces.torque (k, 3) [N m],
        world axes, on body 1 and body 2 alike) to the free bodies of the pairs ph (k,), and add
        their change of each pair's own contact-point velocity to the next step's a_ext
        bookkeeping (dw_i = I_i^-1 tq dt, dv = dw_1 x r_1 - dw_2 x r_2)."""
        on = np.flatnonzero(np.any(torque != 0.0, axis=1))
        if on.size == 0:
            return
        c, world = self.client, pb.WORLD_FRAME
        for q in on.tolist():
            i = int(ph[q])
            tq = torque[q]
            dv = np.zeros(3)
            for side, sign in ((0, 1.0), (1, -1.0)):
                j = int(self._slot[i, side])
                if not self._b_free[j] or self._b_art[j]:
                    continue
                pb.applyExternalTorque(int(self._b_uid[j]), -1, tq.tolist(), world, c)
                R = bodies.rot[j]
                dw = R @ (self._b_inv_I[j] * (R.T @ tq)) * self._dt
                dv += sign * np.cross(dw, self._pt[i] - bodies.com[j])
            self._last_dv[i] += dv

    def _generalized_velocity(self, uid) -> np.ndarray:
        """The multibody's velocity in the coordinates of calculateJacobian and
        calculateMassMatrix now: a floating base's angular and linear velocity
        in its own frame, then the movable joints' speeds (u, (6 +) m)."""
        c = self.client
        qd = [s[1] for s in pb.getJointStates(uid, self._movable[uid], physicsClientId=c)] if self._movable[uid] else []
        if self._base_fixed(uid):
            return np.asarray(qd, float)
        R = _mat(pb.getBasePositionAndOrientation(uid, physicsClientId=c)[1])
        v, w = pb.getBaseVelocity(uid, physicsClientId=c)
        return np.concatenate([R.T @ np.asarray(w, float), R.T @ np.asarray(v, float), qd])

    def _account_multibody_work(self, bodies: _Bodies) -> None:
        """At a step start: add the work the last step's MSF loads did on each
        multibody in pybullet's step to ``multibody_work`` [J], in its own
        coordinates: Q . (u_start + u_end)/2 dt, Q = sum +-J^T F the loads'
        generalized force (J at the step start, :meth:`_jacobian`), u the
        generalized velocity (:meth:`_generalized_velocity`): pybullet's step
        changes u by dt M^-1 (all forces) with M at the step start, so this is
        exactly the kinetic energy the loads gave. The islands' energy check
        of a multibody (:meth:`_energy_probe`) is the contacts' own balance:
        this work less the energy of the timing corrections' velocity offset
        (:meth:`_correction_energy`), plus their stored energy."""
        u_now = {}
        for uid in {int(self._b_uid[j]) for j in self._art_slots}:
            if uid in self._movable:
                u_now[uid] = self._generalized_velocity(uid)
        loads, last = self._last_loads, self._last_gen
        if loads is not None and last is not None:
            ph, F, point, _couples, b0 = loads
            for uid, (Q, u0) in last.items():
                if uid in u_now and Q is not None:
                    self.multibody_work[uid] = (self.multibody_work.get(uid, 0.0)
                                                + float(Q @ (u0 + u_now[uid])) * 0.5 * self._dt)
        self._last_gen = None
        self._u_now = u_now

    def _keep_generalized_loads(self, bodies: _Bodies, ph, F, point) -> None:
        """Before pybullet's step: each multibody's generalized force of the
        loads about to be applied and its velocity now (:meth:`_account_multibody_work`)."""
        out = {}
        for q, i in enumerate(np.asarray(ph, int).tolist()):
            for side, sign in ((0, 1.0), (1, -1.0)):
                j = int(self._slot[i, side])
                if not self._b_art[j]:
                    continue
                uid = int(self._b_uid[j])
                Qj = sign * (self._jacobian(self._body_list[j], bodies.pose(j), point[q]).T @ F[q])
                out[uid] = Qj if uid not in out else out[uid] + Qj
        self._last_gen = {uid: (Q, self._u_now.get(uid)) for uid, Q in out.items() if self._u_now.get(uid) is not None}

    def _correction_energy(self, uid, bodies: _Bodies) -> float:
        """The kinetic energy the manager's timing corrections J (a velocity
        offset for one step, engines._contacts) add to multibody ``uid`` now
        [J]: T(u) - T(u - du) = g . u - 1/2 g^T M^-1 g, g = sum_p +-J_p(point)^T J_p;
        the free bodies' probe takes the same offset out of their velocities.
        Returns (that energy [J], sum_p J_p . a_ext,p [W]): the island check's
        semi-implicit allowance dt/2 |change of the second| (balance module:
        the offset is removed at the next step's velocity, after a_ext acted
        for a step, as a free body's probe allows dt/2 |m g . dv|)."""
        mgr = self.manager
        on = np.flatnonzero(np.any(mgr.J != 0.0, axis=1))
        g, power = None, 0.0
        for p in on.tolist():
            for side, sign in ((0, 1.0), (1, -1.0)):
                j = int(self._slot[p, side])
                if not (self._b_art[j] and int(self._b_uid[j]) == uid):
                    continue
                gj = sign * (self._jacobian(self._body_list[j], bodies.pose(j), self._pt[p]).T @ mgr.J[p])
                g = gj if g is None else g + gj
                power += float(mgr.J[p] @ self._last_a_ext[p])
        if g is None or uid not in self._u_now:
            return 0.0, 0.0
        return float(g @ self._u_now[uid]) - 0.5 * float(g @ np.linalg.solve(self._mass_matrix(uid), g)), power

    def _multibody_kinetic(self, uid) -> tuple[float, float]:
        """(kinetic energy [J], mass [kg]) of multibody ``uid`` now (every link:
        1/2 m v^2 + 1/2 w.I w in its principal axes)."""
        c = self.client
        nj = pb.getNumJoints(uid, physicsClientId=c)
        if uid not in self._mb_dyn:
            self._mb_dyn[uid] = [(float(d[0]), np.asarray(d[2], float)) for d in
                                 (pb.getDynamicsInfo(uid, link, physicsClientId=c) for link in range(-1, nj))]
        _pos, orn = pb.getBasePositionAndOrientation(uid, physicsClientId=c)
        v, w = pb.getBaseVelocity(uid, physicsClientId=c)
        states = [(orn, v, w)]
        if nj:
            states += [(st[1], st[6], st[7]) for st in
                       pb.getLinkStates(uid, list(range(nj)), computeLinkVelocity=1, physicsClientId=c)]
        T = M = 0.0
        for (m, I), (orn, v, w) in zip(self._mb_dyn[uid], states):
            v, wb = np.asarray(v, float), _mat(orn).T @ np.asarray(w, float)
            T += 0.5 * m * float(v @ v) + 0.5 * float(wb @ (I * wb))
            M += m
        return T, M

    def _energy_probe(self, keys, bodies=None):
        """Kinetic and potential energy [J], gravity's power m g . v [W] and mass [kg] (b,) each of
        the free bodies ``keys`` (slots), the manager's timing corrections J taken out
        of their velocities (+J on body 1, -J on body 2 at the pair's point). A multibody's
        key (B + uid; its motors, torques, limits and gravity do work the contacts do not
        see): T its kinetic energy (the tolerance's scale), T + U the work its MSF loads did
        on it (multibody_work, _account_multibody_work) less the energy of the timing
        corrections' velocity offset, q sum J . a_ext (_correction_energy): the island's
        E + S is then the contacts' own balance (engines._contacts.balance). bodies: the
        state read (default: this step's, read at its start)."""
        bodies, mgr = self._cur_bodies if bodies is None else bodies, self.manager
        k = np.asarray(keys, dtype=np.int64)
        B = len(self._body_list)
        link = k >= B
        j = np.where(link, 0, k)
        g = self._gravity()
        inv_m = self._b_inv_m[j]
        mass = np.where(inv_m > 0, 1.0 / np.where(inv_m > 0, inv_m, 1.0), 0.0)
        v, w = bodies.v[j].copy(), bodies.w[j].copy()
        R = bodies.rot[j]
        where = {int(kk): i for i, kk in enumerate(k)}
        for p in np.flatnonzero(np.any(mgr.J != 0.0, axis=1)):
            for side, sgn in ((0, 1.0), (1, -1.0)):
                i = where.get(int(self._keys[p, side]), -1)
                if i < 0 or link[i]:
                    continue
                Jb = sgn * mgr.J[p]
                v[i] -= Jb * inv_m[i]
                L = np.cross(self._pt[p] - bodies.com[j[i]], Jb)
                w[i] -= R[i] @ (self._b_inv_I[j[i]] * (R[i].T @ L))
        wl = np.einsum("kji,kj->ki", R, w)  # principal axes
        I = np.where(self._b_inv_I[j] > 0, 1.0 / np.where(self._b_inv_I[j] > 0, self._b_inv_I[j], 1.0), 0.0)
        T = 0.5 * mass * np.einsum("ki,ki->k", v, v) + 0.5 * np.einsum("ki,ki->k", wl * I, wl)
        U = -mass * (bodies.com[j] @ g)
        q = mass * (v @ g)
        if np.any(link):  # a multibody: its kinetic energy, and its account the work its contacts did on it
            for r in np.flatnonzero(link).tolist():
                uid = int(k[r]) - B
                T[r], mass[r] = self._multibody_kinetic(uid)
                O, q[r] = self._correction_energy(uid, bodies)
                U[r] = self.multibody_work.get(uid, 0.0) - O - T[r]
        if self._kin is not None:  # the driven bodies' work on them (engines._kinematic)
            U = U - self._kin.work_on(k, self._keys, mgr.J, self._pt, self._pt)
        return T, U, q, mass

    def _coupling_blocks(self, pp, pq):
        """The manager's coupling blocks (ContactManager.set_coupling) for free
        bodies in closed form: for each body b shared by pairs p and q, with
        signs s = +1 (body 1) or -1 (body 2) and lever arms r from its centre
        of mass to each pair's contact point, W_pq += s_p s_q (1/m - [r_p]x
        I^-1 [r_q]x) and Wc_pq += s_p s_q / m (the centre of mass does not
        turn); for links of one multibody (a robot's feet), s_p s_q J_p M^-1 J_q^T
        and s_p s_q J_c,p M^-1 J_q^T through its Jacobians and mass matrix.
        (b, 3, 3) each [1/kg]."""
        bodies = self._cur_bodies
        W = np.zeros((pp.size, 3, 3))
        Wc = np.zeros((pp.size, 3, 3))
        eye = np.eye(3)
        for sp, gp in ((0, 1.0), (1, -1.0)):
            for sq, gq in ((0, 1.0), (1, -1.0)):
                jp, jq = self._slot[pp, sp], self._slot[pq, sq]
                on = (jp == jq) & self._b_free[jp]
                if np.any(on):
                    j = jp[on]
                    R = bodies.rot[j]
                    Iinv = (R * self._b_inv_I[j][:, None, :]) @ R.transpose(0, 2, 1)
                    rp = _skew(self._pt[pp[on]] - bodies.com[j])
                    rq = _skew(self._pt[pq[on]] - bodies.com[j])
                    inv_m = self._b_inv_m[j][:, None, None]
                    W[on] += gp * gq * (inv_m * eye - rp @ Iinv @ rq)
                    Wc[on] += gp * gq * inv_m * eye
                art = np.flatnonzero(self._b_art[jp] & self._b_art[jq] & (self._b_uid[jp] == self._b_uid[jq]))
                for k in art.tolist():  # links of one multibody: J_p M^-1 J_q^T through its joints
                    a, b = int(jp[k]), int(jq[k])
                    Jq = self._jacobian(self._body_list[b], bodies.pose(b), self._pt[pq[k]])
                    MJq = self._minv(int(self._b_uid[a])) @ Jq.T
                    Jp = self._jacobian(self._body_list[a], bodies.pose(a), self._pt[pp[k]])
                    Jc = self._jacobian(self._body_list[a], bodies.pose(a), bodies.com[a])
                    W[k] += gp * gq * (Jp @ MJq)
                    Wc[k] += gp * gq * (Jc @ MJq)
        return W, Wc

    def _check_advance(self, bodies: _Bodies) -> None:
        """Compare the free bodies with the last step start (``_last_com``):
        a body that moved other than by one step of pybullet's integrator is a
        jump: its pairs' contacts are interrupted (no record; not integrated
        across the jump) and their a_ext restarts from gravity; undeclared
        (not :meth:`placed`), it warns, naming the fix."""
        free = self._b_free
        com = bodies.com
        if self._have_com:
            r = np.abs(com - self._last_com - self._dt * bodies.v).max(axis=1)
            tol = ADVANCE_ATOL + ADVANCE_RTOL * (np.abs(com).max(axis=1) + self._dt * np.abs(bodies.v).max(axis=1))
            moved = free & (r > tol)
            declared = np.zeros_like(moved)
            declared[list(self._declared)] = True
            moved |= declared
            if np.any(moved):
                self._jump(moved, np.any(moved & ~declared))
        self._declared.clear()
        self._last_com[:] = com
        self._have_com = True

    def _jump(self, moved, warn: bool) -> None:
        pairs = np.flatnonzero(moved[self._slot[:, 0]] | moved[self._slot[:, 1]])
        if not pairs.size:
            return
        self.jumps += 1
        why = (f"pybullet's bodies {sorted({self._body_list[j] for j in np.flatnonzero(moved)})} moved between "
               f"adapter.step() calls other than by one step (t = {self.time:.6g} s)")
        n = self.manager.interrupt(pairs, why)
        self.interrupted += n
        self._have_last[pairs] = False
        self._last_dv[pairs] = 0.0
        if warn:
            warnings.warn(f"{why}: pybullet was stepped without the adapter, or a body was reset. While MSF is "
                          "on, call adapter.step() instead of p.stepSimulation() (pybullet has no force callback: "
                          "adapter.step() applies the forces and steps), or adapter.close() first to give the pairs "
                          "back to pybullet's contact; declare bodies you place with adapter.placed(). "
                          f"{n} MSF contact(s) in progress were interrupted without a record", RuntimeWarning,
                          stacklevel=4)

    def _apply(self, bodies: _Bodies, ph, F, point) -> None:
        """Apply the forces F (k, 3) at ``point`` (k, 3) on body 1 of the pairs ph
        (k,), the opposite on body 2, fixed bodies taking none (module
        docstring, step 3), with one call per free body: a body with one
        force takes it at its point; a body with several, their sum at its
        centre of mass and their torque about it (``applyExternalTorque``),
        which is what pybullet makes of forces at points (the base's torque
        is (point - centre of mass) x F). A link of a multibody takes each of
        its forces at its point."""
        c = self.client
        if self.compiled:
            one, F1, P1, many, Fm, Tm = self._k.body_loads(ph.astype(np.int64), F, point, self._slot64, bodies.com,
                                                           self._b_free)
        else:
            one, F1, P1, many, Fm, Tm = self._body_loads(bodies, ph, F, point)
        push, world = pb.applyExternalForce, pb.WORLD_FRAME
        if not np.array_equal(one, self._one_cache[0]):  # mostly the same bodies step after step
            self._one_cache = (one, self._b_uid[one].tolist())
        for u, f, p in zip(self._one_cache[1], F1.tolist(), P1.tolist()):
            push(u, -1, f, p, world, c)  # the client id positional: a keyword costs ~0.1 us a call
        for u, f, p, t in zip(self._b_uid[many].tolist(), Fm.tolist(), bodies.com[many].tolist(), Tm.tolist()):
            push(u, -1, f, p, world, c)
            pb.applyExternalTorque(u, -1, t, world, c)
        if self._art_slots:
            on_link = self._b_art[self._slot[ph]]
            for q in np.flatnonzero(on_link[:, 0] | on_link[:, 1]).tolist():
                (u1, l1), (u2, l2) = self._bodies[ph[q]]
                f, p = F[q].tolist(), point[q].tolist()
                if on_link[q, 0]:
                    push(u1, l1, f, p, world, c)
                if on_link[q, 1]:
                    push(u2, l2, [-f[0], -f[1], -f[2]], p, world, c)

    def _body_loads(self, bodies: _Bodies, ph, F, point):
        """numpy :func:`engines.pybullet._kernels.body_loads`: the free bodies
        with one force (slots, force, point) and with several (slots, summed
        force, summed torque about the centre of mass)."""
        B = len(self._body_list)
        count, force, torque, at = np.zeros(B, int), np.zeros((B, 3)), np.zeros((B, 3)), np.zeros((B, 3))
        for side, sign in ((0, 1.0), (1, -1.0)):
            j = self._slot[ph, side]
            on = self._b_free[j]
            j, f, p = j[on], sign * F[on], point[on]
            np.add.at(count, j, 1)
            np.add.at(force, j, f)
            np.add.at(torque, j, cross_rows(p - bodies.com[j], f))
            at[j] = p
        one, many = np.flatnonzero(count == 1), np.flatnonzero(count > 1)
        return one, force[one], at[one], many, force[many], torque[many]

    def _cross_dv(self, bodies: _Bodies, ph, P, W_own) -> None:
        """Keep, for the next step's a_ext, the change of every pair's v_rel
        that the impulses P (k, 3) on body 1 of the pairs ph (k,) cause:
        sum_q W_pq P_q over the pairs whose force is not held
        (:func:`held_forces`), plus a held pair's own W_pp P_p (module
        docstring). Free bodies in closed form, all pairs at once; links of
        multibodies through J M^-1 J^T."""
        keep = held_forces(self.manager, ph, self.time + self._dt)
        W_own_keep = W_own[keep]
        P_keep, ph_keep = P[keep], ph[keep]
        ph, P = ph[~keep], P[~keep]
        if ph.size and self.compiled:
            moved = np.zeros(len(self._body_list), bool)
            self._k.cross_dv_free(ph.astype(np.int64), np.ascontiguousarray(P), self._slot64, self._pt, bodies.com,
                                  bodies.rot, self._b_inv_m, self._b_inv_I, self._b_free, self._b_art,
                                  self._last_dv, moved)
            links = moved & self._b_art
            if np.any(links):
                self._cross_dv_links(bodies, ph, P, links)
        elif ph.size:
            B = len(self._body_list)
            s1, s2 = self._slot[ph, 0], self._slot[ph, 1]
            pt = self._pt[ph]
            # impulse and angular impulse about the centre of mass on every body (+P on 1, -P on 2)
            lin, ang = np.zeros((B, 3)), np.zeros((B, 3))
            np.add.at(lin, s1, P)
            np.add.at(lin, s2, -P)
            np.add.at(ang, s1, cross_rows(pt - bodies.com[s1], P))
            np.add.at(ang, s2, -cross_rows(pt - bodies.com[s2], P))
            moved = np.any(lin != 0.0, axis=1) | np.any(ang != 0.0, axis=1)
            free = moved & self._b_free
            dv_b, dw_b = np.zeros((B, 3)), np.zeros((B, 3))
            if np.any(free):
                j = np.flatnonzero(free)
                R = bodies.rot[j]
                dv_b[j] = lin[j] * self._b_inv_m[j][:, None]
                dw_b[j] = np.einsum("kij,kj->ki", R, self._b_inv_I[j] * np.einsum("kji,kj->ki", R, ang[j]))
                q = np.flatnonzero(free[self._slot[:, 0]] | free[self._slot[:, 1]])
                a1, a2 = self._slot[q, 0], self._slot[q, 1]
                self._last_dv[q] = ((dv_b[a1] + cross_rows(dw_b[a1], self._pt[q] - bodies.com[a1]))
                                    - (dv_b[a2] + cross_rows(dw_b[a2], self._pt[q] - bodies.com[a2])))
            links = moved & self._b_art
            if np.any(links):
                self._cross_dv_links(bodies, ph, P, links)
        if self.compiled:
            self._k.add_own_dv(ph_keep.astype(np.int64), np.ascontiguousarray(W_own_keep),
                               np.ascontiguousarray(P_keep), self._last_dv)
        else:
            for q, i in enumerate(ph_keep.tolist()):
                self._last_dv[i] += W_own_keep[q] @ P_keep[q]

    def _cross_dv_links(self, bodies: _Bodies, ph, P, links) -> None:
        """The links' share of :meth:`_cross_dv`: for each multibody hit,
        dq = M^-1 sum_q J_q^T P_q, then J_p dq for every pair with a link of it."""
        uids = {self._body_list[j][0] for j in np.flatnonzero(links)}
        for uid in uids:
            Q = None
            for q, i in enumerate(ph.tolist()):
                for side, sign in ((0, 1.0), (1, -1.0)):
                    j = self._slot[i, side]
                    b = self._body_list[j]
                    if self._b_art[j] and b[0] == uid:
                        JtP = sign * self._jacobian(b, bodies.pose(j), self._pt[i]).T @ P[q]
                        Q = JtP if Q is None else Q + JtP
            if Q is None:
                continue
            dq = self._minv(uid) @ Q
            for i in range(len(self._bodies)):
                for side, sign in ((0, 1.0), (1, -1.0)):
                    j = self._slot[i, side]
                    b = self._body_list[j]
                    if self._b_art[j] and b[0] == uid:
                        self._last_dv[i] += sign * self._jacobian(b, bodies.pose(j), self._pt[i]) @ dq

    # -- records ----------------------------------------------------------------
    def _probe(self, i) -> dict:
        """Body-level quantities for the manager's records (its body probe):
        body 1's angular velocity gives spin_in/spin_out about n x t; both
        bodies' give their rotation per step [rad/s] (3,)."""
        b1, b2 = self._bodies[i]
        out = {"omega1": self._pose(b1).w, "omega2": np.zeros(3) if self._fixed(b2) else self._pose(b2).w}
        kin = self._kin
        if kin is not None:  # a driven body's twist (engines._kinematic)
            for s in (0, 1):
                j = int(kin.sides[i, s])
                if j >= 0:
                    out[f"omega{s + 1}"] = kin.w[j].copy()
        return out

    def _orientation_free(self, b, s: _Shape) -> bool:
        """The contact of shape s does not depend on its body b's orientation:
        b is fixed, or a multibody's base whose shape is a sphere centred on
        its centre of mass (CENTRED_RTOL; engines._contacts.state.ROTATION_PER_STEP_MAX)."""
        if self._fixed(b):
            return True
        return (not self._articulated(b) and s.kind == "sphere"
                and float(np.linalg.norm(s.pos)) <= CENTRED_RTOL * float(s.size[0]))

    @property
    def time(self) -> float:
        """Engine time since the adapter was made [s]."""
        return self._steps * self._dt

    def body_state(self, b) -> _Pose:
        """World pose and velocities of a (body, link) [SI]."""
        return self._pose(b)


def _shape_reach(s: _Shape) -> float:
    """The farthest point of shape s from its own frame's origin [m] (a plane: 0, unbounded)."""
    if s.kind == "sphere":
        return float(s.size[0])
    if s.kind == "box":
        return float(np.linalg.norm(s.size[:3]))
    if s.kind in ("capsule", "cylinder"):
        r, h = float(s.size[0]), float(s.size[1])
        return r + h if s.kind == "capsule" else math.hypot(r, h)
    if s.kind == "mesh" and s.vertices is not None and len(s.vertices):
        return float(np.max(np.linalg.norm(s.vertices, axis=1)))
    return 0.0


def _check_curvature(i, p: PairSpec, s1: _Shape, s2: _Shape) -> None:
    """The law's radii must be the shapes' (body 1's radii are R1a, R1b)."""
    R1 = float(s1.size[0]) if s1.kind == "sphere" else math.inf
    R2 = float(s2.size[0]) if s2.kind == "sphere" else math.inf
    check_law_curvature(f"pairs[{i}]", p, R1, R2)
