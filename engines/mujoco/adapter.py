"""The MuJoCo adapter: force laws between pairs of geoms through the
``mjcb_passive`` hook (the contract is in :mod:`engines.base`).

(Over 600 lines because the hook, the candidate search and the kinematics
read one MjModel/MjData and share its per-step caches, and the engine-path
issues are reworking the hook: its split waits for that rework.)

The hook is the integration: while it is installed (:func:`installed`),
every ``mj_step`` of the adapter's MjData gets the contact forces, whoever
calls it (a user's loop, ``mj_step(..., nstep=n)``, the passive viewer's
loop, gymnasium's ``MujocoEnv.do_simulation``, ``mj_step1``/``mj_step2``),
under Euler, RK4, implicit and implicitfast; :meth:`MujocoAdapter.step` is a
convenience that runs ``mj_step`` and checks MuJoCo's bad-acceleration
reset. Each hook call is classified (:mod:`engines.mujoco._stepping`): the
contact state advances once per step, at the step's first call; RK4's stage
calls and repeated ``mj_forward`` at the same state reuse the step's force
(so ``mj_forward`` and ``mj_rnePostConstraint`` between steps change
nothing, and after ``mj_forward`` ``qfrc_passive``/``qacc`` include the
contact). A state that is not the integrator's image of the last one (a
jump: ``mj_resetData``, qpos or qvel written, time set) interrupts the
contacts in progress, with no record and a RuntimeWarning
(``adapter.jumps``, ``adapter.interrupted``), instead of integrating the
jump as a contact; a_ext restarts from gravity.

What it does each engine step:

1. At the first call of the passive hook inside the step (positions,
   velocities, the inertia matrix and its factorisation are then current),
   read for every pair the contact of the two smooth shapes (sphere-plane,
   sphere-box face, sphere-sphere; :mod:`engines._geometry`): approach x,
   normal n (body 2 -> body 1), the contact point mid-overlap, and the
   translational point Jacobians of both bodies (``mj_jac``), each at its
   own surface point (the two differ across a gap), J = J_1 - J_2. From them
   v_rel = J qvel, W = J M^-1 J^T (``mj_solveM``), and with the centre-of-mass
   Jacobians J_c, v_com_rel = J_c qvel, W_com = J_c M^-1 J^T. This works for
   links of articulated chains as for free bodies.
2. Hand the pairs with x > -(closing distance in one step), and the
   manager's ``required_pairs``, to the contact manager ONCE per step (also
   when there are none: it completes records then); it integrates the law
   over the step (sub-cycling) and returns the step-averaged force.
3. Add that force to ``qfrc_passive`` with ``mj_applyFT`` (+F on body 1 at
   its point, -F on body 2 at its point; a body welded to the world takes
   none) in EVERY call of the hook during the step: RK4 calls it four
   times per step, and all stages see the same force and the same moment
   (the lever arm from each body's centre of mass is held fixed in world
   axes, as the contact point stays under the ball and the manager's W
   assumes; a world-fixed point would give the moved stages a spurious
   moment F_n times the distance travelled, several % of the spin at 2 ms).

MuJoCo's own contact for a managed pair must be off. The one mechanism used
here is ``<contact><exclude body1=... body2=.../>`` between the two bodies
(the scenes in :mod:`engines.mujoco.scenes` write it); the adapter refuses a
model in which MuJoCo would still make a contact for the pair (contype /
conaffinity match without an exclude, or an explicit ``<pair>``), rather
than editing the caller's model behind its back.

Records are the manager's (:class:`msf_contact.ImpactRecord`); its body
probe reads body 1's angular velocity (spin_in, spin_out about n x t) and
the relative centre-of-mass velocity from MuJoCo.

The relative acceleration of the contact points from everything but the
managed contacts (``a_ext``) is an estimate: the change of v_rel over the
last step minus the change the impulses of ALL the pairs applied in that
step caused (each pair's impulse including the manager's timing
correction), over dt. That change is J_p dq with dq = M^-1 sum_q J_q^T P_q
(``mj_solveM``, one solve per step), i.e. sum_q W_pq P_q with the cross
inverse inertia W_pq = J_p M^-1 J_q^T between the contact points of pairs p
and q (zero when they share no moving body). Subtracting only the pair's
own impulse would count a body's other contacts as outside acceleration,
one step late: a bead-bead impulse on a bead would enter the bead's plate
contact as a huge a_ext. The exception are the pairs whose force is held
into the next step (:func:`held_forces`: resting contacts, and contacts the
step resolves): their step-averaged force is the best prediction of their
force over the next step, so it stays in the other pairs' a_ext (without it
a resting stack of rubber balls rests 80% too deep at dt = 1 ms). For the
first step a_ext is gravity acting on the bodies that are not welded to the
world. The pairs read through Jacobians (links of chains, box faces) add
J M^-1 (change of the actuator, user and constraint forces since the last
step) in the step they act, and their W, couplings and impulses use the
inverse inertia with the joint limits active at the step start responding
(:mod:`engines.mujoco._known`, under every integrator, RK4's four stages
weighted as RK4 weighs them): a policy's new torque each step is not seen a
step late (the MSF ant under RK4 hopped to 6 m on that lag), nor a limit
that engages or a user's qfrc_applied / xfrc_applied.

The per-step work of the free group (pairs of a free sphere and a plane, a
fixed body or another free sphere: detection, v_rel, W, the a_ext
bookkeeping, the forces) is compiled with numba
(:mod:`engines.mujoco._kernels`, reading the MjData arrays directly); the
numpy implementation it follows stays reachable with
``MujocoAdapter(..., compiled=False)``, and tests/test_mujoco_kernels.py
holds the two to round-off. Pairs read through Jacobians (box faces, links
of chains) take the same path either way.

The hook is process-global: :func:`installed` puts ONE dispatching hook in
place (dispatch by the MjData object), chains the previously installed
Python hook and restores it in ``finally``, also when ``mj_step`` raises.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import math
import warnings
from types import SimpleNamespace

import mujoco
import numpy as np

from engines._contacts import SETTLE_AFTER_DURATIONS, _skew, closing_distance
from engines._contacts.state import CENTRED_RTOL, lever_terms_free
from engines._contacts.balance import DeepOnsets
from engines._contacts.islands import TOUCH_TOL, push_reach
from engines._kinematic import interrupt_placements
from engines._geometry import COINCIDENT_RTOL, Detection, cross_rows, sphere_plane, sphere_sphere
from engines._sweep import sweep
from engines._narrow import smooth_contact
from engines.base import (
    STEPS_PER_CONTACT_MIN,
    ContactForces,
    ContactKinematics,
    EngineAdapter,
    PairSpec,
    check_law_curvature,
)
from engines.mujoco import _broadphase, _held, _native, _resting
from engines.mujoco._known import SCRATCH_IDS, KnownForces, StepResponse
from engines.mujoco._stepping import StepTracker
from msf_contact._validate import ValidityWarning

#: Candidates are handed to the manager while x > -CANDIDATE_FACTOR times the
#: distance the surfaces can close in one step (closing speed dt plus the
#: external acceleration's share; engines._contacts.closing_distance): a
#: safety factor on a prediction that uses an estimated a_ext. The manager's
#: required_pairs (in contact, or with a timing correction to remove) are
#: always listed.
CANDIDATE_FACTOR = 2.0
#: A sphere through a box is handed back to MSF beyond this gap [m] plus what a step closes (EngineAdapter._through).
THROUGH_REACH = 1e-3

_GEOM_NAMES = {
    mujoco.mjtGeom.mjGEOM_PLANE: "plane", mujoco.mjtGeom.mjGEOM_HFIELD: "hfield",
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere", mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid", mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box", mujoco.mjtGeom.mjGEOM_MESH: "mesh", mujoco.mjtGeom.mjGEOM_SDF: "sdf",
}
#: A box's corner contact (engines._narrow.BoxOnPlane, BoxOnBox) on a free
#: body turning more than this [rad] per engine step, |omega| dt at the step
#: start, is flagged and warned (:meth:`MujocoAdapter._check_fast_turns`): the
#: sub-cycle holds the step-start geometry (the corner's lever arm and W, its
#: normal velocity's change by the turn left to the next step's a_ext), and a
#: corner moves through its contact by the turn. Measured (issue 13; a 1 kg
#: box 0.10 x 0.06 x 0.04 m dropped from 0.2 m under Euler at dt = 5 and 10
#: ms, spinning at 5, 15 and 25 rad/s about 10 random axes, natural rubber on
#: steel, scripts/spin_drop.py): of 615 contact steps with |omega| dt below
#: 0.15 none rose above dt/2 |dP_g| + 1e-3 of the energy by more than 1e-3 of
#: the drop's energy; of 236 between 0.15 and 0.5, 16 did (up to 3.7 times
#: it), and from 0.5 on 26 of 42. The gain spins the box up, and MuJoCo's Euler then integrates the
#: fast tumble's gyroscopic term explicitly, which gains energy by itself:
#: the box at 20 rad/s about (1, 1, 1) went from 24 to 89 rad/s in one corner
#: contact (0.25 rad per step) and MuJoCo reset a NaN acceleration 45 steps later.
BOX_TURN_PER_STEP_MAX = 0.15
#: A cylinder's rim ring in contact (engines._narrow.CylinderOnPlane, RimRing)
#: whose lowest rim point lies an angle D from its nearest slot sinks up to
#: c (1 - cos D) below what the slots carry (c = Q sin(tilt), the ring's
#: drop across its diameter / 2: the slots keep their material points while
#: any is in contact, and each law keeps its pose while its contact moves);
#: above this share of the edge radius the contacts are flagged and warned
#: (:meth:`MujocoAdapter._check_ring_sink`): the small-strain bound x/rho = 0.1
#: of the rim tube, against static overlaps of um. Measured (issue 13): the
#: user's cylinder (R 50 mm, rho 1 mm, 0.1 kg) set on its rim 40 deg from the
#: normal, spun at 15 rad/s: at 16 deg its lowest point 44.7 deg from the
#: nearest slot lay 4.0 mm deep (c (1 - cos D) = 3.98 mm).
RING_SINK_MAX = 0.1
#: A contact on a link begun where the step's implicit damping (MuJoCo's
#: Euler with dof_damping, implicit, implicitfast: engines.mujoco._known,
#: StepResponse) leaves less than this share of an impulse's velocity change
#: along the normal (n.W n / n.W_0 n, KnownForces.damped_share; I / (I + h B)
#: for one hinge) is flagged and warned (MujocoAdapter._check_damped_onsets):
#: the contact's sub-cycle takes the damper for added inertia h B and holds
#: its force at the step start, which pushes the link back out after a
#: bounce inside the step. Measured (scripts/damped_impact.py, a hinged arm
#: into the floor at 10 ms): share 0.81 (h B / I = 0.23) no step above
#: RestEnergy's bound; 0.69, 0.47, 0.31 (h B / I = 0.45, 1.13, 2.26) one
#: step 5.6, 34, 59 mJ above it. Not corrected (docs/engines.md, gymnasium's
#: walkers: the undamped frame tried).
DAMPED_SHARE_MIN = 0.75
#: MuJoCo's divergence threshold on |qacc| (mjMAXVAL in mujoco/mjmodel.h).
MJ_MAXVAL = 1e10
#: A managed force explains a bad acceleration when its own estimate reaches
#: this share of MJ_MAXVAL (the estimate F R / I_min bounds the torque's
#: effect; a factor 10 of margin for the lever arm and the other dofs).
MJ_MAXVAL_SHARE = 0.1
_SECOND = ("sphere", "plane", "box")
#: Geoms MuJoCo's narrow phase collides and msf_contact.shapes has a curvature for.
_NARROW = ("sphere", "plane", "box", "capsule", "cylinder", "ellipsoid", "mesh")
#: Points managed per geom pair from MuJoCo's narrow phase (its deepest ones
#: when it lists more): a box face or a cylinder end on a plane gives 4, a
#: capsule 2. A mesh is one smooth convex surface: one contact, at the smooth
#: surface's point found from its deepest vertex (engines._narrow.smooth_point;
#: its vertices near the bottom are samples of one contact, not contacts);
#: a coarse hull whose vertices are contacts, as a box's corners are (the
#: duck_vhacd.obj hull rolls from vertex to vertex: with one slot a new vertex
#: already below the plane took the slot as a deep onset, COR 22 in a step),
#: takes engines._narrow.COARSE_MESH_SLOTS by default when its hull has a
#: flat face it can rest on (engines._narrow.default_mesh_slots), or the
#: adapter's ``mesh_slots``.
NARROW_SLOTS = {"box": 4, "cylinder": 4, "capsule": 2}
_ZERO3 = np.zeros(3)  # what body 2 may be; body 1 is a sphere


@dataclasses.dataclass
class _Pair:
    """One managed pair resolved in the model."""

    index: int
    geom1: int
    geom2: int
    body1: int
    body2: int
    kind2: str  # "sphere", "plane", "box", or "narrow" (MuJoCo's narrow phase, engines.mujoco.narrow)
    radius1: float  # body 1's radius [m] (a narrow pair: its geom's bounding radius, a lever-arm bound)
    fixed1: bool
    fixed2: bool
    narrow: int = -1  # a narrow pair: its geom pair's index in the adapter's NarrowPhase
    slot: int = 0  # a narrow pair: which of the geom pair's points (engines._narrow.SlotMatcher)


def geom_type_name(model: mujoco.MjModel, g: int) -> str:
    return _GEOM_NAMES.get(int(model.geom_type[g]), f"type {int(model.geom_type[g])}")


def _mujoco_contact_on(model: mujoco.MjModel, g1: int, g2: int, excluded: set | None = None) -> str | None:
    """Why MuJoCo would make its own contact between geoms g1 and g2, or None.
    ``excluded``: the model's exclude signatures, if already collected."""
    for k in range(model.npair):
        if {int(model.pair_geom1[k]), int(model.pair_geom2[k])} == {g1, g2}:
            return f"an explicit <contact><pair> (pair {k})"
    if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT:
        return None
    b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
    if b1 == b2:
        return None
    if int(model.body_weldid[b1]) == 0 and int(model.body_weldid[b2]) == 0:
        return None  # MuJoCo never collides two bodies welded to the world
    t1, a1 = int(model.geom_contype[g1]), int(model.geom_conaffinity[g1])
    t2, a2 = int(model.geom_contype[g2]), int(model.geom_conaffinity[g2])
    if not ((t1 & a2) or (t2 & a1)):
        return None
    signature = (min(b1, b2) << 16) + max(b1, b2)
    if excluded is None:
        excluded = set(int(s) for s in model.exclude_signature)
    if signature in excluded:
        return None
    return "contype/conaffinity match and no <contact><exclude> between the bodies"


#: both disable bits that make MuJoCo skip mj_passive (check_passive_runs)
_NO_PASSIVE = int(mujoco.mjtDisableBit.mjDSBL_SPRING) | int(mujoco.mjtDisableBit.mjDSBL_DAMPER)


def check_passive_runs(model: mujoco.MjModel) -> None:
    """ValueError if MuJoCo would never call mjcb_passive, where the MSF force
    enters: with both springs and dampers disabled (``<flag spring="disable"
    damper="disable"/>``) mj_passive returns before its callback (MuJoCo 4.0
    src/engine/engine_passive.c, mj_passive), so the MSF pairs would have no
    force at all (a rubber ball fell through its floor, no record, no word)."""
    if model.opt.disableflags & _NO_PASSIVE == _NO_PASSIVE:
        raise ValueError(
            "model.opt.disableflags disables both spring and damper (<flag spring=\"disable\" damper=\"disable\"/>): "
            "MuJoCo then skips mj_passive and its mjcb_passive, where the MSF force enters, so the MSF pairs would "
            "have no contact at all. Enable either flag; to keep the joints' springs and dampers off, zero them "
            "instead (model.jnt_stiffness[:] = 0, model.dof_damping[:] = 0)")


def _driven(model: mujoco.MjModel, b: int) -> bool:
    """Body b is driven by the user: a mocap body or a body welded to one (no joint between;
    MuJoCo's body_weldid of a mocap body is the body itself)."""
    w = int(model.body_weldid[b])
    return w > 0 and int(model.body_mocapid[w]) >= 0


def _simple_free_body(model: mujoco.MjModel, b: int) -> bool:
    """A body whose only joint is a free joint, with no child bodies and no
    armature: its inverse inertia at a point is the rigid body's, in closed form."""
    if b <= 0 or int(model.body_jntnum[b]) != 1:
        return False
    j = int(model.body_jntadr[b])
    if int(model.jnt_type[j]) != mujoco.mjtJoint.mjJNT_FREE or int(model.body_dofnum[b]) != 6:
        return False
    a = int(model.body_dofadr[b])
    if np.any(model.dof_armature[a:a + 6] != 0.0):
        return False
    return not np.any(model.body_parentid[1:] == b)


def _orientation_free(model: mujoco.MjModel, g: int, b: int, fixed: bool) -> bool:
    """The contact of geom g does not depend on its body b's orientation: b is
    welded to the world, or a free body whose geom g is a sphere centred on
    its centre of mass (CENTRED_RTOL; engines._contacts.state.ROTATION_PER_STEP_MAX)."""
    if fixed:
        return True
    if geom_type_name(model, g) != "sphere" or int(model.body_jntnum[b]) != 1:
        return False
    if int(model.jnt_type[int(model.body_jntadr[b])]) != mujoco.mjtJoint.mjJNT_FREE:
        return False
    return float(np.linalg.norm(model.geom_pos[g] - model.body_ipos[b])) <= CENTRED_RTOL * float(model.geom_size[g, 0])


def _vectorisable(model: mujoco.MjModel, p: _Pair) -> bool:
    """Pairs read in one batch: a free sphere on a plane or a sphere that is
    welded to the world or itself a free body (box faces and chain links go
    through mj_jac pair by pair)."""
    if p.kind2 not in ("plane", "sphere") or p.fixed1 or not _simple_free_body(model, p.body1):
        return False
    return p.fixed2 or _simple_free_body(model, p.body2)


@dataclasses.dataclass
class _FreeGroup:
    """The pairs whose bodies are free rigid bodies (or fixed), read and
    pushed all at once: detection with the vectorised :mod:`engines._geometry`
    functions, point velocities from ``cvel`` (v + w x (p - subtree com),
    what J qvel gives), W in closed form
    (:func:`engines._contacts.effective_inverse_inertia_free`: 1/m - [r]x I^-1 [r]x,
    what J M^-1 J^T gives for a free body without armature), W_com = sum 1/m,
    and the force as the free joints' generalised force (force; torque about
    the joint anchor in body axes, what mj_applyFT gives), accumulated with
    ``np.add.at``. All arrays (k,) or (k, 3) over the group's pairs."""

    index: np.ndarray  # pair indices
    g1: np.ndarray
    g2: np.ndarray
    b1: np.ndarray
    b2: np.ndarray
    R1: np.ndarray  # body 1's radius [m]
    R2: np.ndarray  # body 2's radius [m] (nan: plane)
    plane: np.ndarray  # bool
    free2: np.ndarray  # bool: body 2 is a free body (else welded to the world)
    a0: np.ndarray  # first-step a_ext: gravity on the free bodies [m/s^2] (k, 3)
    inv_m1: np.ndarray  # [1/kg]
    inv_m2: np.ndarray  # [1/kg] (0 for a fixed body)
    dof1: np.ndarray  # first dof of body 1's free joint
    dof2: np.ndarray
    jnt1: np.ndarray
    jnt2: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, pairs: list[_Pair]) -> "_FreeGroup":
        k = len(pairs)
        i = lambda f: np.array([f(p) for p in pairs], dtype=int).reshape(k)  # noqa: E731
        b1, b2 = i(lambda p: p.body1), i(lambda p: p.body2)
        free2 = np.array([not p.fixed2 for p in pairs], dtype=bool).reshape(k)
        g = np.array(model.opt.gravity, dtype=float)
        if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY:
            g = np.zeros(3)
        jnt1 = model.body_jntadr[b1].astype(int)
        jnt2 = np.where(free2, model.body_jntadr[b2], 0).astype(int)
        return cls(
            index=i(lambda p: p.index), g1=i(lambda p: p.geom1), g2=i(lambda p: p.geom2), b1=b1, b2=b2,
            R1=np.array([p.radius1 for p in pairs], dtype=float).reshape(k),
            R2=np.array([float(model.geom_size[p.geom2, 0]) if p.kind2 == "sphere" else math.nan for p in pairs],
                        dtype=float).reshape(k),
            plane=np.array([p.kind2 == "plane" for p in pairs], dtype=bool).reshape(k), free2=free2,
            a0=g - free2[:, None] * g, inv_m1=1.0 / model.body_mass[b1],
            inv_m2=np.where(free2, 1.0 / np.where(free2, model.body_mass[b2], 1.0), 0.0),
            dof1=model.jnt_dofadr[jnt1].astype(int), dof2=np.where(free2, model.jnt_dofadr[jnt2], 0).astype(int),
            jnt1=jnt1, jnt2=jnt2)

    def packed(self, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
        """The group's constants for :mod:`engines.mujoco._kernels`: (gi (k, NGI)
        int64, gf (k, NGF) float64), columns as named there."""
        from engines.mujoco import _kernels as K

        k = self.index.size
        gi = np.zeros((k, K.NGI), np.int64)
        for col, v in ((K.I_G1, self.g1), (K.I_G2, self.g2), (K.I_B1, self.b1), (K.I_B2, self.b2),
                       (K.I_ROOT1, model.body_rootid[self.b1]), (K.I_ROOT2, model.body_rootid[self.b2]),
                       (K.I_JNT1, self.jnt1), (K.I_JNT2, self.jnt2), (K.I_DOF1, self.dof1), (K.I_DOF2, self.dof2),
                       (K.I_PLANE, self.plane), (K.I_FREE2, self.free2), (K.I_PAIR, self.index)):
            gi[:, col] = v
        gf = np.zeros((k, K.NGF))
        gf[:, K.F_R1], gf[:, K.F_R2] = self.R1, self.R2
        gf[:, K.F_INV_M1], gf[:, K.F_INV_M2] = self.inv_m1, self.inv_m2
        gf[:, K.F_A0:K.F_A0 + 3] = self.a0
        gf[:, K.F_INVI1:K.F_INVI1 + 3] = 1.0 / model.body_inertia[self.b1]
        I2 = np.where(self.free2[:, None], model.body_inertia[self.b2], 1.0)
        gf[:, K.F_INVI2:K.F_INVI2 + 3] = np.where(self.free2[:, None], 1.0 / I2, 0.0)
        return gi, gf

    def kinematics(self, m, d, dt, required, last_v, last_dv, have_last, push, last_r, last_gap, hold, hold_n,
                   hold_x) -> dict:
        """Candidate rows of the group (a dict of ContactKinematics fields) and
        the a_ext bookkeeping of every pair of the group."""
        k = self.index.size
        c1 = d.geom_xpos[self.g1]
        x = np.empty(k)
        nrm, point, p1, p2 = (np.empty((k, 3)) for _ in range(4))
        for sel, det in self._detect(d, c1):
            x[sel], nrm[sel], point[sel], p1[sel], p2[sel] = det.x, det.normal, det.point, det.point1, det.point2
        cvel, com = d.cvel, d.subtree_com
        w1, w2 = cvel[self.b1, :3], cvel[self.b2, :3]  # a welded body's cvel is 0
        c1c, c2c = com[m.body_rootid[self.b1]], com[m.body_rootid[self.b2]]
        held = ~self.plane & hold[self.index]
        gap = np.flatnonzero(~self.plane & (x < 0.0) & ~held)
        if np.any(held):  # a sub-step contact in progress: the normal of its onset (MujocoAdapter._held_geometry)
            g = np.flatnonzero(held)
            q = self.index[g]
            x[g], nrm[g] = hold_x[q], hold_n[q]
            s = 0.5 * np.maximum(x[g], 0.0)
            p1[g] = c1[g] - (self.R1[g] - s)[:, None] * nrm[g]
            p2[g] = d.geom_xpos[self.g2[g]] + (self.R2[g] - s)[:, None] * nrm[g]
            point[g] = 0.5 * (p1[g] + p2[g])
        if gap.size:  # spheres closing within the step: the geometry at first touch (engines._sweep)
            c2 = d.geom_xpos[self.g2[gap]]
            w = ((cvel[self.b1[gap], 3:] + cross_rows(w1[gap], c1[gap] - c1c[gap]))
                 - (cvel[self.b2[gap], 3:] + cross_rows(w2[gap], c2 - c2c[gap])))
            sw, n_sw, x_sw = sweep(c1[gap] - c2, w, self.R1[gap] + self.R2[gap], dt)
            g, n_sw, x_sw = gap[sw], n_sw[sw], x_sw[sw]
            x[g], nrm[g] = x_sw, n_sw
            p1[g] = c1[g] - self.R1[g][:, None] * n_sw
            p2[g] = c2[sw] + self.R2[g][:, None] * n_sw
            point[g] = 0.5 * (p1[g] + p2[g])
        r1, r2 = p1 - c1c, p2 - c2c
        v_rel = (cvel[self.b1, 3:] + cross_rows(w1, r1)) - (cvel[self.b2, 3:] + cross_rows(w2, r2))
        idx = self.index
        dv = v_rel - last_v[idx] - last_dv[idx]
        gap = ~self.plane & (x < 0.0)
        moved = gap & last_gap[idx] & have_last[idx]
        if np.any(moved):  # last step's v_rel read at this step's points (the adapter's _last_r)
            q = idx[moved]
            dv[moved] -= (cross_rows(w1[moved], r1[moved] - last_r[q, :3])
                          - cross_rows(w2[moved], r2[moved] - last_r[q, 3:]))
        a_ext = np.where(have_last[idx][:, None], dv / dt, self.a0)
        last_v[idx], last_dv[idx], have_last[idx] = v_rel, 0.0, True
        last_gap[idx] = gap
        last_r[idx[gap], :3], last_r[idx[gap], 3:] = r1[gap], r2[gap]
        xd = -np.einsum("ij,ij->i", v_rel, nrm)
        xdd = -np.einsum("ij,ij->i", a_ext, nrm)
        reach = closing_distance(xd, xdd, dt, CANDIDATE_FACTOR)
        c = np.flatnonzero((x > -(reach + push[idx])) | required[idx])
        b1, b2 = self.b1[c], self.b2[c]
        xi1, xi2 = d.xipos[b1], d.xipos[b2]
        W = self._inverse_inertia(m, d, b1, p1[c] - xi1, self.inv_m1[c])
        f2 = self.free2[c]
        if np.any(f2):
            W[f2] += self._inverse_inertia(m, d, b2[f2], p2[c][f2] - xi2[f2], self.inv_m2[c][f2])
        W_com = (self.inv_m1[c] + self.inv_m2[c])[:, None, None] * np.eye(3)
        v_com = (cvel[b1, 3:] + cross_rows(w1[c], xi1 - c1c[c])) - (cvel[b2, 3:] + cross_rows(w2[c], xi2 - c2c[c]))
        rows = dict(pair=idx[c], x=x[c], normal=nrm[c], point=point[c], v_rel=v_rel[c], v_com_rel=v_com, W=W,
                    W_com=W_com, a_ext=a_ext[c])
        pos = np.full(len(last_v), -1)
        pos[idx[c]] = np.arange(c.size)
        return {"rows": rows, "pos": pos, "p1": p1[c], "p2": p2[c], "p1_all": p1, "p2_all": p2, "x_all": x}

    def _detect(self, d, c1):
        pl, sp = np.flatnonzero(self.plane), np.flatnonzero(~self.plane)
        if pl.size:
            g2 = self.g2[pl]
            yield pl, sphere_plane(c1[pl], self.R1[pl], d.geom_xpos[g2], d.geom_xmat[g2][:, 2::3])
        if sp.size:
            yield sp, sphere_sphere(c1[sp], self.R1[sp], d.geom_xpos[self.g2[sp]], self.R2[sp])

    @staticmethod
    def _inverse_inertia(m, d, b, r, inv_m):
        """1/m Id - [r]x I^-1 [r]x (k, 3, 3), I^-1 = R diag(1/I) R^T in world axes."""
        R = d.ximat[b].reshape(-1, 3, 3)
        Iinv = (R * (1.0 / m.body_inertia[b])[:, None, :]) @ R.transpose(0, 2, 1)
        rx = _skew(r)
        return inv_m[:, None, None] * np.eye(3) - rx @ Iinv @ rx

    def forces(self, d, pair, F, blk):
        """What the hook applies for the rows with a force (pair indices
        ``pair``, forces on body 1 F (k, 3) [N])."""
        rows = blk["pos"][pair]
        gi = np.searchsorted(self.index, pair)
        b1, b2 = self.b1[gi], self.b2[gi]
        r1 = blk["p1"][rows] - d.xipos[b1]
        r2 = blk["p2"][rows] - d.xipos[b2]
        f2 = self.free2[gi]
        return (b1, self.jnt1[gi], self.dof1[gi], F, r1, b2[f2], self.jnt2[gi][f2], self.dof2[gi][f2], -F[f2], r2[f2])

    @staticmethod
    def apply(d, b1, j1, a1, F1, r1, b2, j2, a2, F2, r2, out=None) -> None:
        """Add the forces to qfrc_passive (or to ``out`` (nv,)); the lever arms
        r from each body's centre of mass are held fixed in world axes over
        the step."""
        q = d.qfrc_passive if out is None else out
        for b, j, a, F, r in ((b1, j1, a1, F1, r1), (b2, j2, a2, F2, r2)):
            if not b.size:
                continue
            arm = d.xipos[b] + r - d.xanchor[j]
            tq = np.einsum("kji,kj->ki", d.xmat[b].reshape(-1, 3, 3), cross_rows(arm, F))
            np.add.at(q, a[:, None] + np.arange(3), F)
            np.add.at(q, a[:, None] + np.arange(3, 6), tq)

    def velocity_change(self, d, dq, blk, sel) -> np.ndarray:
        """J_p dq for the group's pairs at positions ``sel`` (k,): the change of
        v_rel that the change of the generalised velocities dq (nv,) gives,
        each body at its own contact point. A free joint's dofs are the
        anchor's linear velocity (world axes) and the angular velocity in body
        axes: v(point) = dq_lin + (xmat dq_ang) x (point - anchor), the
        transpose of :meth:`apply`."""
        out = np.zeros((sel.size, 3))
        for b, j, a, pts, sign, on in ((self.b1[sel], self.jnt1[sel], self.dof1[sel], blk["p1_all"][sel], 1.0,
                                        np.ones(sel.size, bool)),
                                       (self.b2[sel], self.jnt2[sel], self.dof2[sel], blk["p2_all"][sel], -1.0,
                                        self.free2[sel])):
            if not np.any(on):
                continue
            b, j, a, pts = b[on], j[on], a[on], pts[on]
            lin = dq[a[:, None] + np.arange(3)]
            ang = np.einsum("kij,kj->ki", d.xmat[b].reshape(-1, 3, 3), dq[a[:, None] + np.arange(3, 6)])
            out[on] += sign * (lin + cross_rows(ang, pts - d.xanchor[j]))
        return out


def held_forces(manager, pair, t_next: float) -> np.ndarray:
    """Which of the pairs ``pair`` (k,) hold their force into the next step:
    :meth:`engines._contacts.ContactManager.held` (one rule for both adapters)."""
    return manager.held(pair, t_next)


def _per_geom(table: dict, model, g: int, default=None):
    """A per-geom setting (edge_radii, mesh_slots) of geom g: keyed by its name, or by its id (an unnamed
    geom, e.g. one a body-name PairSpec reaches)."""
    name = model.geom(g).name
    if name and name in table:
        return table[name]
    return table.get(g, default)


class MujocoAdapter(EngineAdapter):
    """Force laws between pairs of MuJoCo geoms; see the module docstring.

    model, data: the MuJoCo model and its data. pairs: PairSpec whose
    ``body1`` and ``body2`` are each a geom name, a geom id or a body name
    (standing for each of the body's geoms that can collide: one pair per
    geom pair); body1 the curved one (a sphere, capsule, cylinder,
    ellipsoid, box or mesh), body2 any of those or a plane. edge_radii,
    mesh_slots: per geom name or id. compiled: the free group's per-step
    work in :mod:`engines.mujoco._kernels` (default) or in numpy (the
    reference implementation; the same results to round-off).
    """

    name = "mujoco"

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, pairs: list[PairSpec], compiled: bool = True,
                 edge_radii: dict | None = None, mesh_slots: dict | None = None):
        if not isinstance(model, mujoco.MjModel) or not isinstance(data, mujoco.MjData):
            raise ValueError(f"model, data must be mujoco.MjModel and mujoco.MjData, got "
                             f"{type(model).__name__}, {type(data).__name__}")
        self.model, self.data = model, data
        if not pairs:
            raise ValueError("pairs is empty: give at least one PairSpec")
        check_passive_runs(model)
        self._excluded = set(int(s) for s in model.exclude_signature)
        self._own_on: set[tuple[int, int]] = set()  # geom pairs MuJoCo would collide (no <exclude>)
        #: edge radius [m] per box or cylinder geom name (msf_contact.shapes.DEFAULT_EDGE_RADIUS otherwise)
        self.edge_radii = dict(edge_radii or {})
        #: contact points managed per mesh geom name (default engines._narrow.default_mesh_slots: 4 for a
        #: hull with a flat face it can rest on, 1 for a smooth mesh; NARROW_SLOTS)
        self.mesh_slots = dict(mesh_slots or {})
        for name, k in self.mesh_slots.items():
            if int(k) != k or not 1 <= k <= 8:
                raise ValueError(f"mesh_slots[{name!r}] = {k!r} must be a whole number in [1, 8]")
        self._narrow_pairs: list = []  # per narrow geom pair: (geom1, geom2, shape1, shape2, SlotMatcher)
        #: per narrow geom pair of a capsule or cylinder on a plane: its line contact (engines._narrow.SideLine)
        self._line: dict = {}
        #: per narrow geom pair of a box on a plane: its corners and edges (engines._narrow.BoxOnPlane)
        self._box: dict = {}
        #: per sphere-box pair (its index): the sphere on the rounded box (engines._narrow.SphereOnBox)
        self._sphere_box: dict = {}
        self._pairs = []
        expanded = []
        for i, p in enumerate(pairs):
            for pg in self._geom_pairs(i, p):
                for q in self._resolve(i, pg, len(self._pairs)):
                    self._pairs.append(q)
                    expanded.append(pg)
        self._narrow = None
        if self._narrow_pairs:
            from engines.mujoco.narrow import NarrowPhase

            self._narrow = NarrowPhase(model, [(g1, g2) for g1, g2, *_ in self._narrow_pairs])
            self._narrow_key = None
            self._narrow_nb = None  # _narrow_consts
            self._pose_due: list = []  # _pose_lines
            self._lazy_pose = True  # False: every line pair's ends posed in _narrow_points (tests compare the two)
            self._narrow_found: list = []
            from engines._contacts.compiled import kernel_law
            from engines._narrow import LawBank

            #: a law per contact curvature, built from the PairSpec's (engines._narrow.LawBank, _narrow_law)
            self.laws = LawBank(kernel_law)
        super().__init__(expanded)
        nv = model.nv
        self._jac = np.zeros((3, nv))
        self._jac2 = np.zeros((3, nv))
        self._in_hook = False  # inside the passive hook (derived quantities are current)
        self._sides = None  # the capsule sides' constants for _side_ends_all, made on first use
        #: _slow_rows all the pairs at once (False: pair by pair, _slow_rows_each, the reference)
        self._batched_rows = True
        self._step_jac: dict = {}  # the step's (J, J_c, M_eff^-1 J^T) of the slow candidate rows (_slow_rows)
        self._installed = False
        #: classifies every hook call: a new step, the same step again, an RK4 stage, a jump
        self._tracker = StepTracker(model)
        # the kinematic tree of each pair's two bodies (P, 2); -1: welded to the world
        self._trees = np.array([[model.body_treeid[p.body1], model.body_treeid[p.body2]] for p in self._pairs],
                               int).reshape(-1, 2)
        self._by_tree = None  # _tree_pairs' table
        self._jump_t = np.full(len(self._pairs), np.nan)  # when each pair's bodies last jumped (engine time [s])
        self._jumped = (math.nan, None)  # (engine time [s], trees or None: all) of the last jump
        #: velocity_offset() by replaying the last step without its timing corrections (exact under
        #: every integrator, one more mj_step a call) instead of M^-1 J^T J at the end pose; the hook
        #: then keeps each step's start state (engines.mujoco.robots.RestEnergy sets it)
        self.exact_offset = False
        self._step_start = None
        #: state jumps seen between steps (mj_resetData, qpos/qvel written, time set; _stepping)
        self.jumps = 0
        #: contacts a jump interrupted (no record)
        self.interrupted = 0
        self._forces_before_jump: ContactForces | None = None
        # (body1, body2, body2 fixed, force on body 1 [N], lever arms [m] (3,) from each
        # body's centre of mass to its contact point, world axes, at the step start)
        self._apply: list[tuple[int, int, bool, np.ndarray, np.ndarray, np.ndarray]] = []
        # a_ext estimate per pair: last step's v_rel [m/s] (P, 3) and the change of v_rel
        # the impulses of all pairs in that step caused, sum_q W_pq P_q [m/s] (P, 3)
        P = len(self._pairs)
        self._last_v = np.zeros((P, 3))
        self._last_dv = np.zeros((P, 3))
        self._have_last = np.zeros(P, bool)
        # a sphere-sphere pair at a gap: its lever arms (body 1's, body 2's contact point from the
        # root's centre of mass) [m] (P, 6) at the last step, and whether it was at a gap then: the
        # points move on the spheres as the line of first touch turns (engines._sweep), and v_rel
        # of the last step is read at this step's points for a_ext
        self._last_r = np.zeros((P, 6))
        self._last_gap = np.zeros(P, bool)
        self._fast = _FreeGroup.of(model, [p for p in self._pairs if _vectorisable(model, p)])
        self._pp_idx = np.sort(self._fast.index[~self._fast.plane])  # the free group's sphere-sphere pairs
        self._is_pp = np.zeros(P, bool)
        self._is_pp[self._pp_idx] = True
        self._no_hold = np.zeros(P, bool)  # (_held_geometry)
        self._is_fast = np.zeros(P, bool)
        self._is_fast[self._fast.index] = True
        self.manager.own_gap[:] = self._is_fast  # free spheres: the manager's gaps are second order (_own_gaps)
        # a free rigid body's narrow-phase points on a fixed body (box corners, a side's ends on a plane):
        # each a point of the body's surface whose gap, n and W frozen over a step, is second order too; the
        # engine's gap taken instead leads the integrated one by dt |dv| / 2 (the objects scenario's cylinder
        # resting on its side, its ends chattering at 1 ms: ends begun 14 um deep, 0.28 mJ a step, issue 13)
        for q in self._pairs:
            if q.kind2 == "narrow" and q.fixed2 and not q.fixed1 and _simple_free_body(model, q.body1):
                self.manager.own_gap[q.index] = True
        self._slow = [p for p in self._pairs if not self._is_fast[p.index]]
        self._slow_index = np.array([p.index for p in self._slow], dtype=np.int64)  # pair index of each slow pair
        #: the actuator, user and constraint forces' change between steps, seen by the pairs read through
        #: Jacobians in the step it acts (engines.mujoco._known); None without such pairs
        self._known = KnownForces(model, data) if self._slow else None
        self._apply_fast: tuple | None = None
        self._apply_couple: tuple | None = None  # (bodies (b,), dofs (b,), world torques (b, 3)) of the step
        self._x_last = np.zeros(P)  # max(x, 0) of each pair in the last step (0: not a candidate) [m]
        #: the free group's per-step work compiled (engines.mujoco._kernels) or in numpy
        self.compiled = bool(compiled)
        if self.compiled:
            from engines.mujoco import _kernels

            self._kernels = _kernels
            self._gi, self._gf = self._fast.packed(model)
            self._group_of = np.full(P, -1, np.int64)  # position in the free group of each pair (-1: slow)
            self._group_of[self._fast.index] = np.arange(self._fast.index.size)
            self._no_points = np.zeros((0, 3))  # p1, p2 when there is no free group
            self._lever_scratch = np.empty((9, 3, 3))
            # the free group's pairs as an index: a slice when they are consecutive (cheaper to assign)
            idx = self._fast.index
            span = idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size))
            self._fast_at = slice(int(idx[0]), int(idx[0]) + idx.size) if span else idx
        #: the broad phase of the free group's sphere-sphere pairs (engines.mujoco._broadphase; compiled
        #: only): None (automatic: on with at least BROAD_MIN_PAIRS such pairs), True or False
        self.broad_phase: bool | None = None
        #: sphere-sphere pairs that were a candidate in the step the broad phase first listed them (their
        #: first a_ext the first-step value, not the last step's difference: engines.mujoco._broadphase)
        self.broad_late = 0
        #: candidate sphere-sphere pairs the broad phase left out (its bound failed; warned)
        self.broad_missed = 0
        self._broad = None
        self._broad_wanted = None  # (any sphere-sphere row, the automatic choice)
        self._rows = (None, -1)  # the free group's rows read this step (rows, n; n = -1: all)
        self.manager.set_body_probe(self._probe, batch=self._probe_batch)
        self.manager.set_orientation_free([[_orientation_free(model, p.geom1, p.body1, p.fixed1),
                                            _orientation_free(model, p.geom2, p.body2, p.fixed2)]
                                           for p in self._pairs])
        self.pair_names = [(self._side_name(p.body1), self._side_name(p.body2)) for p in self.pairs]  # per slot
        self.manager.pair_names = self.pair_names
        self._sensors = self._msf_sensors()
        #: the MSF geoms' shape as the adapter was made (_check_geoms): their size, their pose in their body
        g = sorted({int(x) for q in self._pairs for x in (q.geom1, q.geom2) if geom_type_name(model, x) != "plane"})
        self._geom_ids = np.array(g, dtype=np.int64)
        self._geom_shape0 = self._geom_shape()
        # run-time switch per pair (set_mode): 0 MSF, 1 the engine's own contact, 2 both off;
        # _handoff: a sphere through a box handed to MuJoCo's contact while it lasts (EngineAdapter._through)
        self._mode = np.zeros(P, np.int8)
        self._handoff = np.zeros(P, bool)
        #: sphere-box contacts handed to MuJoCo's own contact, the sphere deeper than its radius (count; a
        #: box's edges and corners are rounded and stay on MSF since issue 13, engines._narrow.SphereOnBox)
        self.edge_handoffs = 0
        self.edge_handoffs_of: dict[int, int] = {}  # per pair
        self._gkeys = [(min(p.geom1, p.geom2), max(p.geom1, p.geom2)) for p in self._pairs]
        self._excl_saved = np.array(model.exclude_signature, copy=True)
        self._lifted: set[int] = set()  # body-pair signatures whose <exclude> is lifted for the engine
        self._filter_map: dict[tuple[int, int], int] = {}  # geom pair -> mjcb_contactfilter's answer
        self._filtering = False  # the adapter's mjcb_contactfilter is installed
        # contacts sharing a moving body are solved together (engines._islands): a body's key is
        # its tree's root (the links of one chain are one island), -1 for a body welded to the world
        keys = np.array([[-1 if p.fixed1 else int(model.body_rootid[p.body1]),
                          -1 if p.fixed2 else int(model.body_rootid[p.body2])] for p in self._pairs], dtype=np.int64)
        self._p1, self._p2 = np.zeros((P, 3)), np.zeros((P, 3))  # this step's contact points on body 1, 2
        self._keys = keys
        # the coupling blocks in closed form where both sides of a pair are fixed or simple free bodies
        # (_coupling_blocks): each side's body and whether it moves as a free rigid body
        simple = np.array([_simple_free_body(model, b) for b in range(model.nbody)])
        self._side_body = np.array([[p.body1, p.body2] for p in self._pairs], dtype=np.int64).reshape(P, 2)
        self._side_free = np.array([[not p.fixed1 and simple[p.body1], not p.fixed2 and simple[p.body2]]
                                    for p in self._pairs], dtype=bool).reshape(P, 2)
        self._closed_pair = np.array([(p.fixed1 or simple[p.body1]) and (p.fixed2 or simple[p.body2])
                                      for p in self._pairs], dtype=bool)
        self._push = np.full(P, TOUCH_TOL)  # extra candidate reach from the bodies' other contacts [m] (_islands.push_reach)
        self._gaps = np.full(P, np.nan)  # every pair's x read in the last step [m] (push_reach's paths; NaN: not read)
        self._pushed = False  # push_reach has run (the first step lists again with its own push: _first_push)
        self._push_budget = np.zeros(0)  # push_reach's budget of each body key [m] (the broad phase's)
        # islands need a moving body in two pairs (or two slots of one pair); without one (N spheres on a plate,
        # the jet without particle-particle contacts) every contact is alone: no coupling, no push reach
        moving = keys[keys >= 0]
        self._shared = bool(moving.size != np.unique(moving).size)
        if self._shared:
            self.manager.set_coupling(keys, self._coupling_blocks)
        # islands' energy balance (engines._contacts.balance): free bodies only (a tree of one body on a
        # free joint); a link's drives and joint springs do work the probe does not see
        one = np.bincount(model.body_rootid, minlength=model.nbody) == 1
        self._free_body = np.array([bool(one[b]) and model.body_jntnum[b] == 1
                                    and model.jnt_type[model.body_jntadr[b]] == mujoco.mjtJoint.mjJNT_FREE
                                    for b in range(model.nbody)])
        self.manager.set_energy_probe(self._energy_probe)
        #: pairs with a body that is a link of a chain (neither welded nor a single free body): their
        #: island contacts are checked for an onset found deep (_check_deep_onsets)
        self._link_pairs = np.array([any(not self._free_body[b] and int(model.body_weldid[b]) != 0
                                         for b in (p.body1, p.body2)) for p in self._pairs], dtype=bool)
        # the manager's own gaps (own_gap, as for free bodies above) also for a link of a chain on a fixed
        # body (a robot's foot on the floor). Its gap, read from the
        # engine, leads the integrated one by the step's velocity change (Euler: dt |dv| / 2; RK4: the
        # timing correction's position change, half in each of its two steps), and a foot chattering at
        # rest began each touch-down that deep (the MSF ant at 10 ms, 1,000 steps of torques then 1,000
        # at rest: 53 contacts found deep under RK4, 95 under Euler; with its own gaps 6 and 6, RK4's
        # 0.3-3 um deep, and no energy rise at rest; scripts/ant_integrators.py --deep). A larger
        # difference (a force the contact did not see: a joint limit's, a user's qfrc_applied) still
        # takes the engine's gap.
        for q in self._pairs:
            if not q.fixed1 and self._link_pairs[q.index]:
                self.manager.own_gap[q.index] = True
        self._required = np.zeros(len(self._pairs), bool)  # _compute_compiled's scratch
        self._fk_bufs = None  # the free group's kinematics arrays (_compute_compiled)
        #: a resting step in one compiled call (engines.mujoco._resting; compiled only); False: the
        #: general path, which it is tested against
        self.fused = self.compiled
        self._rest_args = None  # its arguments (engines.mujoco._resting._args)
        #: the native mjcb_passive's entry of this adapter (engines.mujoco._native; made by the first step())
        self._native = None
        self._native_result = None  # the resting kernel's results of a call the native hook began
        self._rested = False  # the last step computed was a resting one done in full (_resting.finish)
        # (mjNWARNING,) a view of MjData's warning counters (one attribute per step through the
        # MjWarningStat wrapper costs ~1-3 us): step() reads mjWARN_BADQACC's
        self._warning_counts = data.warning.number
        self._all_msf = True  # every pair on MSF (set_mode)
        self._last_kin = None  # the kinematics of the last step (_compute, _compute_rest, _resting.step)
        for i, sb in self._sphere_box.items():  # each sphere-box pair's own law, its curvature following the point
            self.manager.set_law(i, sb.law)
        self.manager.settle_rigid[:] = ~self._link_pairs  # links keep the RK4 island at rest (resting.py)
        self._any_link = bool(self._link_pairs.any())
        #: pairs whose contacts come from MuJoCo's narrow phase (a mesh's, a box's, a capsule's points):
        #: checked for an onset found deep, as links are (_check_deep_onsets)
        self._narrow_slots = np.array([q.narrow >= 0 for q in self._pairs], dtype=bool).reshape(P)
        self._any_deep_check = self._any_link or bool(self._narrow_slots.any())  # else nothing to look at
        # the adapter's own conditions for the resting step in one call (engines.mujoco._resting.eligible)
        self._fused_static = bool(self.compiled and not self._slow and self._fast.index.size and not self._shared
                                  and not self._any_link)
        #: the bodies the user drives kinematically (mocap bodies and bodies welded to one) in the pairs,
        #: moving at the twist of their last pose change (engines._kinematic); None: none
        self._kin = self._driven_bodies()
        if self._kin is not None:
            self._fused_static = False  # the resting step in one call reads no driven body's motion
            # the free group's driven sides (body 2, fixed): their twist is put in cvel for the group's kernel
            # (_drive_cvel), which then reads the contact as the engine's velocities would give it, the
            # first-touch sweep of two spheres (engines._sweep) included
            fb = sorted({int(p.body2) for p in self._pairs if self._is_fast[p.index] and self._kin.sides[p.index, 1] >= 0})
            self._kin_fast_b = np.array(fb, dtype=np.int64)
            self._kin_fast_j = np.array([self._kin.sides[next(p.index for p in self._pairs if p.body2 == b
                                                               and self._is_fast[p.index]), 1] for b in fb],
                                        dtype=np.int64)
            self._kin_fast_rows = np.array([self._is_fast[p.index] and self._kin.sides[p.index, 1] >= 0
                                            for p in self._pairs], dtype=bool)
            self._kin_had_last = np.zeros(len(self._pairs), bool)
        self._kin_declared: set[int] = set()  # driven bodies placed by the user since the last step (placed)
        self._kin_push = None  # the candidate reach with the driven bodies' motion, this step's (_drive)
        #: bodies welded to the world (not the world itself, no mocap) in the pairs: taken as static; one the
        #: user moves (model.body_pos edited) is warned once (_watch_static), not driven: make it a mocap body
        self._static_watch = np.array(sorted({b for p in self._pairs for b, f in ((p.body1, p.fixed1),
                                                                                  (p.body2, p.fixed2))
                                              if f and b != 0 and not _driven(model, b)}), dtype=np.int64)
        self._static_pose = None
        self._static_warned: set[int] = set()
        #: contacts found deep at their onset on a link (flagged; _check_deep_onsets, engines._contacts.balance)
        self._deep = DeepOnsets()
        #: box corner contacts on a free body turning more than BOX_TURN_PER_STEP_MAX a step (_check_fast_turns)
        self._box_free = np.array([q.narrow in self._box and not self._link_pairs[q.index] for q in self._pairs],
                                  dtype=bool).reshape(P)
        self.fast_turns = 0  #: such contacts, flagged (each once)
        self.ring_sinks = 0  #: rim-ring contacts flagged for a lowest point between slots (_check_ring_sink)
        self.damped_onsets = 0  #: link contacts begun under a strong implicit damper, flagged (_check_damped_onsets)
        self._damped_share = np.ones(P)  # each slow pair's KnownForces.damped_share at this step (1: not read)
        self._damped_warned: set[int] = set()
        self._sink_flagged: dict[int, float] = {}
        self._sink_warned: set[int] = set()
        self._turn_flagged: dict[int, float] = {}
        self._turn_warned: set[int] = set()
        if model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP:
            warnings.warn("MuJoCo's sleeping islands are enabled (<flag sleep=\"enable\"/>): the MSF adapter does "
                          "not support them; a body put to sleep or woken inside a step reads as a jump (its MSF "
                          "contacts in progress are interrupted without a record, warned each time). Disable sleep "
                          "for a model with MSF pairs", RuntimeWarning, stacklevel=2)
        #: number of engine steps run through :meth:`step`
        self.steps = 0
        #: the manager's step-averaged forces of the last step (None: no candidate)
        self.last_forces: ContactForces | None = None
        #: pairs moving with a joint held by a servo too stiff for dt (engines.mujoco._held): their
        #: records are flagged (outside_validity), one RuntimeWarning per servo here
        #: (and pairs on a body an equality constraint ties too stiffly for dt: _held.EqualityHold)
        self.stiff_servo_pairs = _held.stiff_pairs(_held.servos(model, data) + _held.equality_holds(model, data),
                                                   [(p.body1, p.body2) for p in self._pairs], self.manager.dt)
        for s in {id(s): s for s in self.stiff_servo_pairs.values()}.values():
            names = [f"{i} {self.pair_names[i]}" for i, t in self.stiff_servo_pairs.items() if t is s]
            warnings.warn(s.note(self.manager.dt, ", ".join(names)), RuntimeWarning, stacklevel=2)

    # -- set-up ----------------------------------------------------------------
    def _geom(self, name, which: str, i: int) -> int:
        """The geom id of a PairSpec side: a geom name or a geom id (:meth:`_geom_pairs` has turned a body
        name into its geoms' ids)."""
        m = self.model
        if isinstance(name, (int, np.integer)) and not isinstance(name, bool):
            if not 0 <= int(name) < m.ngeom:
                raise ValueError(f"pair {i}: {which} = {name!r} is not a geom id of the model (0 <= id < "
                                 f"ngeom = {m.ngeom})")
            return int(name)
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, str(name)) if isinstance(name, str) else -1
        if g < 0:
            names = [m.geom(k).name for k in range(m.ngeom)]
            bodies = [m.body(k).name for k in range(1, m.nbody)]
            raise ValueError(f"pair {i}: {which} = {name!r} is neither a geom name, a geom id nor a body name of "
                             f"the model (geoms: {', '.join(repr(n) for n in names if n) or 'none named'}; bodies: "
                             f"{', '.join(repr(n) for n in bodies if n) or 'none named'})")
        return g

    def _geom_pairs(self, i: int, p: PairSpec) -> list[PairSpec]:
        """PairSpec i with each side a geom: a geom name or id is kept; a body name (that is no geom's name)
        stands for each of the body's geoms that can collide (contype or conaffinity nonzero), so a model
        whose geoms carry no names (gymnasium's, most robot files) is reachable by its body names: one pair
        per geom pair, in the body's geom order, with the PairSpec's law and tangential mode."""
        m = self.model
        sides = []
        for which, name in (("body1", p.body1), ("body2", p.body2)):
            if isinstance(name, str) and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name) < 0:
                b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
                if b >= 0:
                    gs = [g for g in range(int(m.body_geomadr[b]), int(m.body_geomadr[b]) + int(m.body_geomnum[b]))
                          if m.geom_contype[g] or m.geom_conaffinity[g]]
                    if not gs:
                        raise ValueError(f"pair {i}: {which} = {name!r} is a body with no geom that can collide "
                                         f"({int(m.body_geomnum[b])} geom(s), all with contype = conaffinity = 0): "
                                         "name a geom instead")
                    sides.append([m.geom(g).name or g for g in gs])
                    continue
            sides.append([name])
        if sides == [[p.body1], [p.body2]]:
            return [p]
        return [dataclasses.replace(p, body1=g1, body2=g2) for g1 in sides[0] for g2 in sides[1]]

    def _side_name(self, side) -> str:
        """A pair side's name in warnings and records: its geom name, or for an unnamed geom (given by id
        or through its body) "body/geom id"."""
        if isinstance(side, (int, np.integer)) and not isinstance(side, bool):
            g = int(side)
            return self.model.geom(g).name or f"{self.model.body(int(self.model.geom_bodyid[g])).name or 'body'}/geom {g}"
        return str(side)

    def _resolve(self, i: int, p: PairSpec, first: int) -> list[_Pair]:
        """The managed contacts of PairSpec i (``first``: the index of the
        first): one for the analytic pairs (a sphere on a sphere, a plane or a
        box face), one per point of MuJoCo's narrow phase for the others."""
        m = self.model
        g1, g2 = self._geom(p.body1, "body1", i), self._geom(p.body2, "body2", i)
        if g1 == g2:
            raise ValueError(f"pair {i}: body1 and body2 are the same geom {p.body1!r}")
        t1, t2 = geom_type_name(m, g1), geom_type_name(m, g2)
        for name, t in ((p.body1, t1), (p.body2, t2)):
            if t not in _NARROW:
                raise ValueError(f"pair {i} ({p.body1!r}, {p.body2!r}): geom {name!r} is a {t}; the MSF contact "
                                 f"needs the curvature at the contact point, which msf_contact.shapes has for "
                                 f"{', '.join(_NARROW)} geoms (make it one of those, or use the built-in contact)")
        why = _mujoco_contact_on(m, g1, g2, self._excluded)
        if why is not None and why.startswith("an explicit"):
            raise ValueError(f"pair {i} ({p.body1!r}, {p.body2!r}): MuJoCo's own contact is on ({why}), which "
                             "no run-time switch reaches; remove the <pair> so the force is not counted twice")
        if why is not None:  # switched off by the adapter's mjcb_contactfilter while installed (set_mode)
            self._own_on.add((min(g1, g2), max(g1, g2)))
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        # a body driven by the user (a mocap body, or welded to one: engines._kinematic) is taken as fixed,
        # an infinite mass, moving at the twist of its last pose change (MujocoAdapter._drive)
        fixed1, fixed2 = int(m.body_weldid[b1]) == 0 or _driven(m, b1), int(m.body_weldid[b2]) == 0 or _driven(m, b2)
        if fixed1 and fixed2:
            raise ValueError(f"pair {i}: both {p.body1!r} and {p.body2!r} are welded to the world or driven "
                             "by the user (mocap bodies): neither can move under the contact force; give one "
                             "of them a joint")
        if t1 == "sphere" and t2 in _SECOND:  # the analytic paths (engines._geometry), kept as they are
            R1 = float(m.geom_size[g1, 0])
            R2 = float(m.geom_size[g2, 0]) if t2 == "sphere" else math.inf
            check_law_curvature(f"pair {i}", p, R1, R2)
            if t2 == "box":  # the box rounded by its edge radius: faces, edges, corners (engines._narrow.SphereOnBox)
                from engines._contacts.compiled import kernel_law
                from engines._narrow import SphereOnBox, make_shape

                self._sphere_box[first] = SphereOnBox(R1, make_shape(
                    "box", m.geom_size[g2], edge_radius=_per_geom(self.edge_radii, m, g2)), p.law, kernel_law)
            return [_Pair(first, g1, g2, b1, b2, t2, R1, fixed1, fixed2)]
        if t1 == "plane":
            raise ValueError(f"pair {i}: body1 = {p.body1!r} is a plane; body1 must be the curved body "
                             f"(the normal points from body2 to body1): swap body1 and body2")
        from engines._narrow import SlotMatcher, default_mesh_slots, make_shape

        shapes = []
        for g, t in ((g1, t1), (g2, t2)):
            verts = None
            if t == "mesh":
                k = int(m.geom_dataid[g])
                verts = m.mesh_vert[int(m.mesh_vertadr[k]):int(m.mesh_vertadr[k]) + int(m.mesh_vertnum[k])]
            shapes.append(make_shape(t, m.geom_size[g], edge_radius=_per_geom(self.edge_radii, m, g),
                                     vertices=verts))
        slots = [NARROW_SLOTS.get(t, 1) if t != "mesh" else int(_per_geom(
                     self.mesh_slots, m, g, default_mesh_slots(s.vertices)))
                 for g, t, s in ((g1, t1, shapes[0]), (g2, t2, shapes[1]))]
        n_slots = max(slots[0], slots[1] if t2 != "plane" else 1)
        k = len(self._narrow_pairs)
        self._narrow_pairs.append((g1, g2, shapes[0], shapes[1], SlotMatcher(n_slots, float(m.geom_rbound[g1]))))
        if t1 == "capsule" and t2 == "plane":  # a side lying on the plane: one line contact
            from engines._narrow import SideLine

            self._line[k] = SideLine(shapes[0], (p.body1, p.body2))
        if t1 == "cylinder" and t2 == "plane":  # lying: its side's line; else its rim ring (CylinderOnPlane)
            from engines._narrow import CylinderOnPlane

            self._line[k] = CylinderOnPlane(shapes[0], (p.body1, p.body2), n_slots)
        if t1 == "box" and t2 == "plane":  # its rounded corners and edges (engines._narrow.BoxOnPlane)
            from engines._narrow import BoxOnPlane

            self._box[k] = BoxOnPlane(shapes[0], (p.body1, p.body2), n_slots)
            self._box[k].check(p.law)
        if t1 == "box" and t2 == "box":  # a box on a box: the lower one's face (engines._narrow.BoxOnBox)
            from engines._narrow import BoxOnBox

            self._box[k] = BoxOnBox(shapes[0], shapes[1], (p.body1, p.body2), n_slots)
            self._box[k].check(p.law)
        return [_Pair(first + s, g1, g2, b1, b2, "narrow", float(m.geom_rbound[g1]), fixed1, fixed2, k, s)
                for s in range(n_slots)]

    def _driven_bodies(self):
        """The mocap bodies that carry the pairs' bodies (engines._kinematic): a side's nearest
        mocap ancestor (itself included). A body welded to it (no joint between) is taken as
        fixed and moves with its twist; a body on joints below it moves with its twist plus its
        own joints' motion (MuJoCo's cvel and Jacobians carry only the joints': the mocap body
        has no dofs). None when no pair has one."""
        m = self.model
        driven = {}
        sides = np.full((len(self._pairs), 2), -1, np.int64)
        for p in self._pairs:
            for s, b in enumerate((p.body1, p.body2)):
                a = b
                while a > 0 and int(m.body_mocapid[a]) < 0:
                    a = int(m.body_parentid[a])
                if a > 0:
                    sides[p.index, s] = driven.setdefault(a, len(driven))
        if not driven:
            return None
        from engines._kinematic import KinematicBodies

        bodies = list(driven)
        # each mocap body's farthest geom point in its subtree, bounded along the chain of body offsets
        up = np.zeros(m.nbody)  # |path| from the body's frame up to its mocap ancestor's (a bound)
        for b in range(1, m.nbody):
            if int(m.body_mocapid[b]) < 0 and int(m.body_parentid[b]) > 0:
                up[b] = up[int(m.body_parentid[b])] + float(np.linalg.norm(m.body_pos[b]))
        reach = np.zeros(len(bodies))
        for g in range(m.ngeom):
            a = int(m.geom_bodyid[g])
            while a > 0 and int(m.body_mocapid[a]) < 0:
                a = int(m.body_parentid[a])
            if a in driven:
                b = int(m.geom_bodyid[g])
                r = up[b] + float(np.linalg.norm(m.geom_pos[g])) + float(m.geom_rbound[g])
                reach[driven[a]] = max(reach[driven[a]], r)
        return KinematicBodies(bodies, sides, reach, [m.body(b).name or f"body {b}" for b in bodies])

    def placed(self, bodies) -> None:
        """Say that the driven (mocap) bodies ``bodies`` (body names or ids) were
        placed since the last step, not driven there: their pose change is
        taken as a placement (no velocity in the next step; their contacts in
        progress end without a record, quietly) instead of the velocity it
        implies (engines._kinematic)."""
        kin = self._kin
        for b in bodies:
            bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, b) if isinstance(b, str) else int(b)
            if kin is None or bid not in kin.bodies:
                raise ValueError(f"placed: body {b!r} is not a driven (mocap) body of an MSF pair "
                                 f"({', '.join(kin.names) if kin is not None else 'there is none'})")
            self._kin_declared.add(kin.bodies.index(bid))

    def _drive(self, kind: str) -> None:
        """At a step's first hook call: the driven bodies' twist for the step
        (engines._kinematic), their contacts interrupted at an undeclared
        placement, and their pairs' candidate reach for the step."""
        kin, d = self._kin, self.data
        b = kin.bodies
        declared, self._kin_declared = self._kin_declared, set()
        # a reset or a time set (every tree jumped) restarts the poses; a qpos/qvel write of some tree does not
        reset = kind == "first" or (kind == "jump" and self._tracker.jumped is None)
        jumped = kin.update(d.xpos[b], d.xquat[b], self.timestep, reset=reset, declared=sorted(declared))
        interrupt_placements(self, kin, jumped, declared, float(d.time), "driven (mocap)", "setting")
        if kin.moving:
            self._kin_push = self._push.copy()
            self._kin_push[kin.rows] += kin.push(self.timestep, CANDIDATE_FACTOR)
            self._push = self._kin_push

    def _watch_static(self) -> None:
        """Warn once per body when a body welded to the world (no mocap) moved since the last
        step the hook computed: the adapter takes it as static, so its motion is a jump of its
        pose that MSF does not see (a partner it moves into is found deep, one it moves away from
        is left). Driving a body is done with a mocap body (engines._kinematic)."""
        d, w = self.data, self._static_watch
        pose = np.concatenate([d.xpos[w], d.xquat[w]], axis=1)
        last, self._static_pose = self._static_pose, pose
        if last is None or np.array_equal(pose, last):
            return
        for k in np.flatnonzero(np.any(pose != last, axis=1)).tolist():
            b = int(w[k])
            if b in self._static_warned:
                continue
            self._static_warned.add(b)
            warnings.warn(f"body {self.model.body(b).name or b!r} of an MSF pair is welded to the world but moved "
                          f"between steps (t = {float(d.time):.6g} s; model.body_pos or body_quat edited?): the "
                          "adapter takes it as static, so its motion is a jump MSF does not integrate (a partner "
                          "it moves into begins deep, the contact is not a drive). To drive a body, make it a "
                          "mocap body (<body mocap=\"true\">) and set data.mocap_pos / mocap_quat each step: it "
                          "then moves at the velocity of its pose change (docs/engines.md, \"Bodies you drive "
                          "yourself\"). Warned once per body", RuntimeWarning, stacklevel=4)

    def _drive_cvel(self):
        """Put the driven twist of the free group's driven bodies in ``data.cvel`` (MuJoCo's
        com-based [omega, v at the root's subtree com]) for the group's kernel; return the rows
        it replaced (None: nothing to put). Restored right after the kernel, inside the hook:
        MuJoCo never sees it."""
        kin, d = self._kin, self.data
        self._kin_had_last[:] = self._have_last
        if not kin.moving or not self._kin_fast_b.size:
            return None
        b, j = self._kin_fast_b, self._kin_fast_j
        saved = d.cvel[b].copy()
        com = d.subtree_com[self.model.body_rootid[b]]
        d.cvel[b, :3] = kin.w[j]
        d.cvel[b, 3:] = kin.velocity_at(j, com)
        return saved

    def _drive_work(self) -> None:
        """The work the driven bodies did on their partners in the step (the islands' energy probe)."""
        out, kin = self.last_forces, self._kin
        if out is None or not kin.moving:
            return
        pair = np.asarray(out.pair, dtype=np.int64)
        sel = np.flatnonzero(np.any(kin.sides[pair] >= 0, axis=1))
        if sel.size:
            q = pair[sel]
            kin.credit(q, np.asarray(out.force, dtype=float)[sel], self._p1[q], self._p2[q], self.timestep)

    def _mask(self, kin: ContactKinematics) -> ContactKinematics:
        """The driven bodies' velocities added to the rows (engines._kinematic), then
        EngineAdapter._mask."""
        drv = self._kin
        if drv is not None and drv.moving and kin.pair.size and not getattr(kin, "driven", False):
            kin.driven = True  # once per kinematics (a second manager.step on them must not add it again)
            pair = np.asarray(kin.pair, dtype=np.int64)
            fast = self._kin_fast_rows[pair]
            sel = np.flatnonzero(np.any(drv.sides[pair] >= 0, axis=1) & ~fast)
            if sel.size:  # read through Jacobians: the driven velocity added here
                q = pair[sel]
                d = self.data
                b1 = np.array([self._pairs[i].body1 for i in q], dtype=np.int64)
                b2 = np.array([self._pairs[i].body2 for i in q], dtype=np.int64)
                v, vc = drv.adjust(q, kin.v_rel[sel], kin.v_com_rel[sel], self._p1[q], self._p2[q], d.xipos[b1],
                                   d.xipos[b2])
                kin.v_rel = np.array(kin.v_rel, dtype=float)
                kin.v_com_rel = np.array(kin.v_com_rel, dtype=float)
                kin.v_rel[sel], kin.v_com_rel[sel] = v, vc
        if drv is not None and kin.pair.size and not getattr(kin, "driven_a", False) and (drv.moving or drv.was_moving):
            kin.driven_a = True
            pair = np.asarray(kin.pair, dtype=np.int64)
            # the free group's driven rows read the twist from cvel (_drive_cvel): their finite-difference a_ext
            # saw its change since the last step, which the step's extrapolated twist already holds (held over
            # the step, engines._kinematic): taken out
            sel = np.flatnonzero(self._kin_fast_rows[pair] & self._kin_had_last[pair])
            if sel.size:
                q = pair[sel]
                j = drv.sides[q, 1]
                du = drv.v[j] - drv.v_prev[j] + np.cross(drv.w[j] - drv.w_prev[j], self._p2[q] - drv.origin[j])
                kin.a_ext = np.array(kin.a_ext, dtype=float)
                kin.a_ext[sel] += du / self.timestep
        return super()._mask(kin)

    # -- contract --------------------------------------------------------------
    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def step(self, n: int = 1) -> None:
        """Run ``mj_step`` n times (a convenience: with the hook installed any
        ``mj_step`` gets the contact forces, see :func:`installed`); installs
        the hook for the call if it is not installed already, and raises
        RuntimeError if MuJoCo reset a blown-up state."""
        if int(n) != n or n < 0:
            raise ValueError(f"n = {n!r} steps must be a whole number >= 0")
        # the adapter's fields through its __dict__: none is one a native step leaves stale, and a watched
        # adapter's attribute reads and writes would go through engines.mujoco._native (module docstring)
        st = object.__getattribute__(self, "__dict__")
        if not st["_installed"]:
            with installed(self):  # (resting steps in MuJoCo's raw mjcb_passive: engines.mujoco._native)
                return self.step(n)
        m, d = st["model"], st["data"]
        check_passive_runs(m)
        self._check_geoms()
        counts = st["_warning_counts"]
        for _ in range(int(n)):
            resets = counts.item(_BADQACC)
            mujoco.mj_step(m, d)
            st["steps"] += 1
            if counts.item(_BADQACC) != resets:
                self._bad_acceleration()

    def _bad_acceleration(self) -> None:
        """MuJoCo flagged a NaN, inf or |qacc| > mjMAXVAL in the step just taken
        (``mjWARN_BADQACC``). With ``<flag autoreset="disable"/>`` MuJoCo keeps
        the state: a finite state is a real acceleration (a light body's
        impulse in a short step) and the run goes on; otherwise, or when
        MuJoCo reset the simulation, raise naming the dof, the body, the
        managed forces on it and what to change (never continue silently)."""
        m, d = self.model, self.data
        bad = int(mujoco.mjtWarning.mjWARN_BADQACC)
        dof = int(d.warning[bad].lastinfo)
        autoreset = not (m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        finite = bool(np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)))
        if not autoreset and finite:
            return
        body = int(m.dof_bodyid[dof]) if 0 <= dof < m.nv else -1
        jnt = int(m.dof_jntid[dof]) if body >= 0 else -1
        angular = jnt >= 0 and (m.jnt_type[jnt] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_BALL) or (
            m.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_FREE and dof - int(m.jnt_dofadr[jnt]) >= 3))
        where = f"dof {dof} ({'angular' if angular else 'linear'}) of body {m.body(body).name!r}" if body >= 0 else \
            f"dof {dof}"
        # the managed forces of the step on that body and the acceleration they give
        acc, pairs = 0.0, []
        # with the autoreset, MuJoCo's mj_resetData + mj_forward inside the step was a jump:
        # the forces of the step that diverged are those from before it
        out = self.last_forces if not autoreset else self._forces_before_jump
        if out is not None and body >= 0:
            for k, i in enumerate(np.asarray(out.pair, dtype=int)):
                p = self._pairs[int(i)]
                if body not in (p.body1, p.body2):
                    continue
                F = float(np.linalg.norm(out.force[k]))
                if angular:  # a force at the surface of the sphere: torque <= F R about any axis
                    R = p.radius1 if body == p.body1 else float(m.geom_size[p.geom2, 0])
                    a = F * R / float(np.min(m.body_inertia[body]))
                else:
                    a = F / float(m.body_mass[body])
                acc = max(acc, a)
                pairs.append(f"pair {int(i)} (|F| = {F:.3g} N)")
        state = ("MuJoCo reset the simulation" if autoreset else "the state is no longer finite")
        head = f"MuJoCo reported a bad acceleration at t = {d.time:.6g} s (step {self.steps}, {where}) and {state}: "
        if out is not None:
            bad = [int(i) for k, i in enumerate(np.asarray(out.pair, dtype=int))
                   if not np.all(np.isfinite(out.force[k]))]
            if bad:  # MSF's own solve failed: say so, not that the model diverged
                raise RuntimeError(
                    head + f"the MSF force of {', '.join(f'pair {i} {self.pair_names[i]}' for i in bad)} is not "
                    f"finite: the contact solve of that step failed (dt = {self.timestep:g} s), not the model. Known "
                    "case: a small bead struck by a heavy one against a soft plate within one step (five glass "
                    "beads on polyurethane at 1 ms). Take a smaller dt, and report the scene")
        if acc > MJ_MAXVAL_SHARE * MJ_MAXVAL and autoreset:
            raise RuntimeError(
                head + f"the step-averaged force of {', '.join(pairs)} over dt = {self.timestep:g} s gives it "
                f"~{acc:.3g} {'rad/s^2' if angular else 'm/s^2'}, above MuJoCo's divergence threshold mjMAXVAL = "
                f"{MJ_MAXVAL:g}: a real acceleration of a light body in a short step, not a divergence. Set "
                "<flag autoreset=\"disable\"/> in the model's <option> (the adapter then checks that the state "
                "stays finite) or use a larger dt (the step-averaged force falls as 1/dt)")
        raise RuntimeError(
            head + (f"the managed contacts give that body at most ~{acc:.3g} ({', '.join(pairs)}), " if pairs else
                    "no managed contact acts on that body, ") +
            "so the model itself diverged: the time step is too large for the model's other forces, or a body is "
            "too light for MuJoCo's inertia floor")

    def _non_finite(self, pair, force) -> None:
        """Never write NaN silently: RuntimeError naming the pairs whose step force (k, 3) is not finite,
        raised in the hook before anything is applied (it propagates from mj_step, a user's loop too)."""
        bad = [int(i) for i, f in zip(pair, force) if not np.all(np.isfinite(f))]
        raise RuntimeError(
            f"the MSF force of {', '.join(f'pair {i} {self.pair_names[i]}' for i in bad)} is not finite at t = "
            f"{float(self.data.time):.6g} s: the contact solve of that step failed (dt = {self.timestep:g} s), not "
            "the model, and nothing was applied. Known case: a small bead struck by a heavy one against a soft "
            "plate within one step (glass beads of 0.5 and 2 mm on polyurethane at 1 ms). Take a smaller dt, and "
            "report the scene")

    def __enter__(self):
        self._ctx = installed(self)
        return self._ctx.__enter__()

    def __exit__(self, *exc):
        ctx, self._ctx = self._ctx, None
        return ctx.__exit__(*exc)

    # -- records -----------------------------------------------------------------
    @property
    def records(self) -> list:
        """Finished impacts (msf_contact.ImpactRecord), oldest first; a pair
        moving with a servo too stiff for the step flagged (engines.mujoco._held)."""
        return self._flag_stiff(self.manager.records)

    def pop_records(self) -> list:
        """Finished impacts since the last call, and forget them; flagged as :attr:`records`."""
        return self._flag_stiff(self.manager.pop_records())

    def _flag_stiff(self, records: list) -> list:
        if self.stiff_servo_pairs:
            for r in records:
                s = self.stiff_servo_pairs.get(r.inputs.get("pair"))
                if s is not None:
                    note = s.note(self.manager.dt, f"{r.inputs['pair']} {self.pair_names[r.inputs['pair']]}")
                    if note not in r.outside_validity:
                        r.outside_validity.append(note)
        return records

    def _geom_shape(self) -> np.ndarray:
        """(k, 10): size (3), pos (3) and quat (4) in their body of the MSF geoms that are not planes."""
        m, g = self.model, self._geom_ids
        return np.hstack([m.geom_size[g], m.geom_pos[g], m.geom_quat[g]])

    def _check_geoms(self) -> None:
        """RuntimeError if an MSF geom's size or its pose in its body changed since the adapter was made
        (domain randomisation between episodes: a ball's radius set from 0.02 to 0.03 m kept the contact at
        0.02 m, the ball resting 10 mm inside the floor, with no word): its law's curvature, the analytic
        paths' radius and the narrow phase's shapes were taken from the geom then."""
        if self.compiled:  # (the common case in one compiled pass: no copy of the k geoms' shapes)
            m = self.model
            if self._kernels.geom_changed(m.geom_size, m.geom_pos, m.geom_quat, self._geom_ids,
                                          self._geom_shape0) < 0:
                return
        now = self._geom_shape()
        if np.array_equal(now, self._geom_shape0):
            return
        k = int(np.flatnonzero(np.any(now != self._geom_shape0, axis=1))[0])
        g = int(self._geom_ids[k])
        j = int(np.flatnonzero(now[k] != self._geom_shape0[k])[0])
        what, cols = ("size", slice(0, 3)) if j < 3 else ("pos", slice(3, 6)) if j < 6 else ("quat", slice(6, 10))
        raise RuntimeError(f"model.geom_{what} of the MSF geom {self._side_name(g)!r} changed from "
                           f"{self._geom_shape0[k, cols].tolist()} to {now[k, cols].tolist()} after the adapter was "
                           "made: its contact geometry and its law's curvature were taken then; make a new adapter "
                           "(with a law for the new shape) after changing a geom")

    # -- the hook ----------------------------------------------------------------
    def _passive(self, model, data, kind: str | None = None) -> None:
        """The hook: classify the call (engines.mujoco._stepping), compute the
        step's force once per step, apply it in every call of the step. kind:
        the call's class when already known (engines.mujoco._native, which
        calls this for an adapter that has a native entry)."""
        if kind is None:
            if self._native is not None:
                return self._native.passive(self, model, data)
            kind = self._tracker.classify(data)
        known = self._known
        if known is not None:
            known.read(kind, self._tracker.stage)
        computed = kind not in ("same", "stage")
        if computed:
            if self._tracker.h != self.manager.dt:  # model.opt.timestep, read by classify in this call
                raise RuntimeError(f"model.opt.timestep = {float(model.opt.timestep)!r} s changed after the adapter "
                                   f"was made for dt = {self.manager.dt!r} s: make a new adapter")
            if kind == "jump":
                self._check_geoms()  # (a reset is where a model is randomised)
                self._jump()
            push = self._push
            if self._kin is not None:
                self._drive(kind)
            if self._static_watch.size:
                self._watch_static()
            self._in_hook = True
            self._rested = False  # a resting step done in full (engines.mujoco._resting.finish) arms the native hook
            self._unheld = None  # the generalised force of the step's forces not held (set by _compute)
            self._step_start = self._start_state(data) if self.exact_offset else None
            try:
                if self._compute():
                    self._step_start = None  # applied by the resting step itself: not replayable
                    return  # the resting step applied its forces itself (engines.mujoco._resting: no pair
                    # read through Jacobians, so no known forces to tell)
                if self._kin is not None:
                    self._drive_work()
            finally:
                self._in_hook = False
                if self._kin is not None and self._push is not push and self._push is self._kin_push:
                    self._push = push  # the driven bodies' reach was for this step's candidates only
        before = data.qfrc_passive.copy() if computed and known is not None else None
        self._apply_forces(model, data)
        if before is not None:
            known.applied(before, self._unheld)

    def _apply_forces(self, model, data) -> None:
        """Add the step's forces (kept by :meth:`_compute`) to ``data.qfrc_passive``."""
        # the lever arm from each body's centre of mass is held fixed in world axes
        # over the step (the contact point stays under the ball; the manager's W
        # assumes it), so every RK4 stage gets the same force and moment
        if self._apply_fast is not None:
            if self.compiled:
                self._kernels.apply(data.qfrc_passive, data.xipos, data.xanchor, data.xmat, *self._apply_fast)
            else:
                self._fast.apply(data, *self._apply_fast)
        if self._apply_couple is not None:
            self._add_couples(data, data.qfrc_passive, *self._apply_couple)
        for b1, b2, fixed2, F, r1, r2 in self._apply:
            mujoco.mj_applyFT(model, data, F, _ZERO3, data.xipos[b1] + r1, b1, data.qfrc_passive)
            if not fixed2:
                mujoco.mj_applyFT(model, data, -F, _ZERO3, data.xipos[b2] + r2, b2, data.qfrc_passive)

    # -- the run-time switch per pair -----------------------------------------------
    def set_mode(self, which, mode: str) -> None:
        """Switch a pair at run time: ``"msf"`` (this adapter's law, MuJoCo's
        contact off), ``"engine"`` (MuJoCo's own contact, no MSF force) or
        ``"off"`` (neither). ``which``: an index into ``adapter.pairs`` or
        (body1, body2) geom names; every contact slot of that geom pair
        switches. Nothing in the model is edited for good: the adapter lifts
        the model's ``<exclude>`` (``exclude_signature``) or answers MuJoCo's
        ``mjcb_contactfilter`` while installed, and restores both on exit.
        Contacts in progress under MSF end without a record."""
        code = {"msf": 0, "engine": 1, "off": 2}.get(mode)
        if code is None:
            raise ValueError(f"mode = {mode!r} must be 'msf', 'engine' or 'off'")
        key = self._key_of(which)
        slots = np.array([i for i, k in enumerate(self._gkeys) if k == key], dtype=int)
        leaving = slots[(self._mode[slots] == 0) & (code != 0)]
        if leaving.size:
            self.manager.interrupt(leaving, f"switched to {mode!r} by set_mode")
        self._have_last[slots] = False
        self._mode[slots] = code
        self._all_msf = not self._mode.any()
        if self._installed:
            self._apply_modes()

    def mode(self, which) -> str:
        """The pair's mode ("msf", "engine" or "off"; a sphere through a box handed over counts as "engine")."""
        key = self._key_of(which)
        i = self._gkeys.index(key)
        return ("msf", "engine", "off")[1 if self._handoff[i] and self._mode[i] == 0 else int(self._mode[i])]

    def _key_of(self, which) -> tuple[int, int]:
        if isinstance(which, (int, np.integer)) and not isinstance(which, bool):
            if not 0 <= int(which) < len(self._gkeys):
                raise ValueError(f"which = {which!r} is outside [0, {len(self._gkeys) - 1}]")
            return self._gkeys[int(which)]
        try:
            a, b = which
        except (TypeError, ValueError):
            raise ValueError(f"which = {which!r}: give a pair index or (body1, body2) geom names") from None
        g1, g2 = self._geom(a, "body1", -1), self._geom(b, "body2", -1)
        key = (min(g1, g2), max(g1, g2))
        if key not in self._gkeys:
            raise ValueError(f"which = {which!r} is not a pair of this adapter")
        return key

    def _engine_keys(self) -> set:
        on = (self._mode == 1) | ((self._mode == 0) & self._handoff)
        return {self._gkeys[i] for i in np.flatnonzero(on)}

    def _apply_modes(self) -> None:
        """Make MuJoCo's own contact follow the modes (installed only): lift the
        model's exclusion of a body pair with a geom pair on the engine's contact
        (an exclude_signature entry takes its sorted neighbour's value, so the
        array stays sorted), and answer mjcb_contactfilter for the managed geom
        pairs MuJoCo would otherwise collide or must now collide."""
        m = self.model
        sig = m.exclude_signature
        sig[:] = self._excl_saved
        self._lifted = set()
        engine = self._engine_keys()
        self._filter_map = {}
        for key in set(self._gkeys):
            b1, b2 = int(m.geom_bodyid[key[0]]), int(m.geom_bodyid[key[1]])
            bsig = (min(b1, b2) << 16) + max(b1, b2)
            if key in engine:
                for i in np.flatnonzero(self._excl_saved == bsig):
                    sig[i] = sig[i - 1] if i > 0 else -1
                    self._lifted.add(bsig)
                self._filter_map[key] = 0
            else:
                self._filter_map[key] = 1
        need = bool(self._own_on) or bool(self._lifted) or bool(engine)
        if need and not self._filtering:
            _install_filter(self)
        elif not need and self._filtering:
            _uninstall_filter(self)

    def _engine_contact_changed(self, i: int) -> None:
        self._apply_modes()

    @property
    def now(self) -> float:
        return float(self.data.time)

    def _restore_modes(self) -> None:
        self.model.exclude_signature[:] = self._excl_saved
        if self._filtering:
            _uninstall_filter(self)

    def _contact_filter(self, g1: int, g2: int) -> int:
        """mjcb_contactfilter for this adapter's model: 1 discards the geom pair."""
        key = (g1, g2) if g1 < g2 else (g2, g1)
        ans = self._filter_map.get(key)
        if ans is not None:
            return ans
        m = self.model
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        if ((min(b1, b2) << 16) + max(b1, b2)) in self._lifted:
            return 1  # excluded by the model: only the switched geom pair is let through
        t1, a1, t2, a2 = m.geom_contype[g1], m.geom_conaffinity[g1], m.geom_contype[g2], m.geom_conaffinity[g2]
        return 0 if ((t1 & a2) or (t2 & a1)) else 1  # MuJoCo's own bitmask rule

    def _msf_sensors(self) -> list[tuple[int, int, int, int]]:
        """The model's user sensors on a managed geom (``<sensor><user objtype="geom"
        objname=GEOM dim="1|3" needstage="pos|vel|acc"/>``): (sensordata address,
        dim, geom, stage). dim 1 reads the normal force on the geom [N], dim 3
        the MSF force on it [N] (world axes), of the step that starts at the
        state of the mj_forward (after mj_step: the step just taken)."""
        m = self.model
        geoms = {g for p in self._pairs for g in (p.geom1, p.geom2)}
        out = []
        for s in range(m.nsensor):
            if (int(m.sensor_type[s]) != int(mujoco.mjtSensor.mjSENS_USER)
                    or int(m.sensor_objtype[s]) != int(mujoco.mjtObj.mjOBJ_GEOM)
                    or int(m.sensor_objid[s]) not in geoms):
                continue
            dim = int(m.sensor_dim[s])
            if dim not in (1, 3):
                raise ValueError(f"user sensor {m.sensor(s).name!r} on the MSF geom "
                                 f"{m.geom(int(m.sensor_objid[s])).name!r} has dim = {dim}; give dim 1 (normal "
                                 "force [N]) or 3 (force vector [N])")
            out.append((int(m.sensor_adr[s]), dim, int(m.sensor_objid[s]), int(m.sensor_needstage[s])))
        return out

    def _sensor(self, stage: int) -> None:
        """mjcb_sensor: fill the MSF user sensors of this stage (:meth:`_msf_sensors`)."""
        reports = self.contact_forces()
        d = self.data
        for adr, dim, g, need in self._sensors:
            if need != stage:
                continue
            F, Fn = np.zeros(3), 0.0
            for r in reports:
                p = self._pairs[r.pair]
                if g in (p.geom1, p.geom2):
                    sign = 1.0 if g == p.geom1 else -1.0
                    F += sign * r.force
                    Fn += r.F_n
            d.sensordata[adr:adr + dim] = Fn if dim == 1 else F

    def _jump(self) -> None:
        """The state jumped between steps (engines.mujoco._stepping): the
        contacts of the pairs with a body in a kinematic tree that jumped are
        interrupted, not integrated across the jump (ContactManager.interrupt),
        and their a_ext restarts from gravity; the other pairs step on."""
        self._forces_before_jump = self.last_forces
        trees = self._tracker.jumped
        if trees is None:
            hit = np.arange(len(self._pairs))
        else:  # np.isin(self._trees, trees).any(axis=1): the pairs of each tree that jumped (_tree_pairs)
            hit = self._tree_pairs(np.asarray(trees, dtype=np.int64))
        if not hit.size:
            return
        self.jumps += 1
        why = f"MuJoCo's state jumped at t = {float(self.data.time):.6g} s: {self._tracker.why}"
        if self.model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP:
            why += (" (MuJoCo's sleeping islands are enabled, <flag sleep=\"enable\"/>: a body put to sleep or "
                    "woken inside a step reads as such a jump; the adapter does not support them: disable sleep, "
                    "or take the interrupted contacts' records as lost)")
        n = self.manager.interrupt(hit, why)
        self._jump_t[hit] = float(self.data.time)  # (_broad_late: their a_ext restarts anyway)
        self._jumped = (float(self.data.time), None if trees is None else np.asarray(trees, dtype=np.int64))
        self._have_last[hit] = False
        self._last_dv[hit] = 0.0
        if n:
            self.interrupted += n
            warnings.warn(f"{why}; {n} MSF contact(s) in progress were interrupted without a record "
                          f"(adapter.interrupted = {self.interrupted})", RuntimeWarning, stacklevel=2)

    def _tree_pairs(self, trees: np.ndarray) -> np.ndarray:
        """The pairs (ascending indices) with a body in one of the kinematic trees ``trees`` (-1: the
        world), from a table of each tree's pairs built on first use (the jet's pool places a few beads a
        step, each in 266 of its 35,511 pairs: a test over all pairs cost ~1.5 ms a step)."""
        if self._by_tree is None:
            t = self._trees.reshape(-1) + 1  # (2P,) tree ids + 1 of both sides
            pair = np.repeat(np.arange(len(self._pairs)), 2)
            order = np.argsort(t, kind="stable")
            start = np.searchsorted(t[order], np.arange(int(self.model.ntree) + 2))
            self._by_tree = (pair[order], start)
        pairs, start = self._by_tree
        trees = trees + 1
        if trees.size == 1:  # ascending already (a stable sort of repeated ascending pairs): drop repeats only
            out = pairs[start[trees[0]]:start[trees[0] + 1]]
            return out[np.concatenate(([True], out[1:] != out[:-1]))] if out.size > 1 else out
        return np.unique(np.concatenate([pairs[start[k]:start[k + 1]] for k in trees.tolist()]))

    def _geometry(self, p: _Pair, law: bool = True) -> Detection:
        """The contact of pair p from the current poses (engines._geometry;
        a sphere on a box: on the box rounded by its edge radius,
        engines._narrow.SphereOnBox, whose law takes the curvature at the
        point when ``law``)."""
        m, d = self.model, self.data
        if p.kind2 == "narrow":
            return self._narrow_detection(p)
        c1 = d.geom_xpos[p.geom1]
        if p.kind2 == "sphere":
            return sphere_sphere(c1, p.radius1, d.geom_xpos[p.geom2], float(m.geom_size[p.geom2, 0]))
        rot = d.geom_xmat[p.geom2].reshape(3, 3)
        if p.kind2 == "plane":
            return sphere_plane(c1, p.radius1, d.geom_xpos[p.geom2], rot[:, 2])
        sb = self._sphere_box[p.index]
        mgr = self.manager
        x, n, curv = sb.contact(c1, d.geom_xpos[p.geom2], rot)
        if law:
            deep = max(x, float(mgr.x[p.index]) if mgr.active[p.index] else x)  # the engine's or the contact's
            if deep > p.radius1 or self._handoff[p.index]:  # the reach: the centre's relative speed over a step
                v_c = (self._jacobian(p.body1, c1, self._jac) @ d.qvel
                       - self._jacobian(p.body2, c1, self._jac2) @ d.qvel)
                reach = CANDIDATE_FACTOR * float(np.linalg.norm(v_c)) * self.timestep + THROUGH_REACH
                self._through(p.index, deep > p.radius1, x, reach)
            sb.update(curv, bool(mgr.active[p.index]), mgr.refresh_law)
        return Detection.of_sphere(np.asarray(c1, dtype=float)[None], np.array([p.radius1]), np.array([x]),
                                   n[None], np.array([[curv.R2a, curv.R2b]]))

    def _narrow_points(self) -> list:
        """MuJoCo's narrow-phase points of every narrow geom pair at the
        current state, assigned to slots (engines._narrow.SlotMatcher): per
        geom pair a list over slots of (x, point, normal) or None; computed
        once per state."""
        d = self.data
        key = (float(d.time), d.qpos.tobytes())
        if key == self._narrow_key:
            return self._narrow_found
        m = self.model
        nb = self._narrow_consts()
        # margin: what the surfaces can close in a step at the bodies' speeds (x2), at least 1 mm
        # (pair by pair, elementwise: the same float operations as one pair at a time)
        lin, ang = np.linalg.norm(d.cvel[:, 3:], axis=1), np.linalg.norm(d.cvel[:, :3], axis=1)
        v = lin[nb.b1] + ang[nb.b1] * nb.rb1 + lin[nb.b2] + ang[nb.b2] * nb.rb2
        reach = np.maximum(CANDIDATE_FACTOR * (v * self.timestep + float(np.linalg.norm(m.opt.gravity))
                                               * self.timestep ** 2), 1e-3)
        margin = np.zeros(self._narrow.geoms.size)
        np.maximum.at(margin, nb.j1, reach)
        np.maximum.at(margin, nb.j2, reach)
        raw = self._narrow.detect(d, margin, columns=self._batched_rows)
        busy = np.zeros(len(self._pairs), bool)
        busy[self.manager.required_pairs] = True
        out = []
        # the line pairs whose ends' poses (and onset masses) wait for _slow_rows: only the ends of a
        # candidate row need them this step (_pose_lines); outside the hook (separating) at once
        lazy = self._in_hook and self._lazy_pose
        self._pose_due = []
        ends = self._side_ends_all()
        for k, ((g1, g2, s1, s2, match), (x, pts, nrm)) in enumerate(zip(self._narrow_pairs, raw)):
            first = nb.first[k]
            if match.n == 1 and x.size and (s1 is not None and hasattr(s1, "support")
                                            or s2 is not None and hasattr(s2, "support")):
                # a smooth mesh's one contact: the smooth surface's point, not the deepest vertex's
                # (engines._narrow.smooth_point)
                # from the deepest of MuJoCo's points (several vertices of one contact), as one point
                j = int(np.argmax(x))
                xj, pj = smooth_contact(s1, (d.geom_xpos[g1], d.geom_xmat[g1].reshape(3, 3)),
                                        s2, (d.geom_xpos[g2], d.geom_xmat[g2].reshape(3, 3)), float(x[j]), pts[j],
                                        nrm[j])
                x, pts, nrm = np.array([xj]), pj[None], nrm[j:j + 1]
            if k in self._box:
                out.append(self._box_slots(k, first, busy[first:first + match.n]))
                continue
            mode = self._line_mode(k, busy[first:first + match.n], ends.get(k)) if k in self._line else None
            if mode == "line":
                if lazy:
                    out.append(self._line_points(k, match.n))
                    self._pose_due.append(k)
                else:
                    out.append(self._line_slots(k, match.n))
                continue
            if mode == "ring":  # a cylinder on its rim (engines._narrow.RimRing)
                out.append(self._ring_slots(k, first))
                continue
            rot1 = d.geom_xmat[g1].reshape(3, 3)
            local = (pts - d.geom_xpos[g1]) @ rot1
            slots = match.assign(local, x, busy[first:first + match.n])
            per = [None] * match.n
            for j, s_ in enumerate(slots):
                if s_ >= 0:
                    per[s_] = (float(x[j]), pts[j], nrm[j])
            out.append(per)
        self._narrow_key, self._narrow_found = key, out
        return out

    def _check_fast_turns(self, t0: float) -> None:
        """Never silent: a box's corner contact on a free body (in progress or
        begun in the step from t0) whose body turns more than
        BOX_TURN_PER_STEP_MAX per step at this step's start is flagged in its
        outside_validity (each contact once) and warned once per pair, in the
        step: the energy such contacts gain (see the constant) comes in the
        same step, and the blow-up after it. ``fast_turns`` counts them."""
        if not self._box_free.any():
            return
        mgr, d, dt = self.manager, self.data, self.timestep
        began = (mgr.x_max > 0.0) & (mgr.t_onset >= t0) & (mgr.t_onset < t0 + dt)  # and ended in the step
        on = self._box_free & (mgr.active | began)
        for p in np.flatnonzero(on).tolist():
            t_on = float(mgr.t_onset[p])
            if self._turn_flagged.get(p) == t_on:
                continue
            q = self._pairs[p]
            w, b = max((float(np.linalg.norm(d.cvel[b, :3])), b) for b in (q.body1, q.body2)
                       if int(self.model.body_weldid[b]) != 0)
            if w * dt <= BOX_TURN_PER_STEP_MAX:
                continue
            self._turn_flagged[p] = t_on
            self.fast_turns += 1
            name = self.model.body(b).name or f"body {b}"
            note = (f"fast turn: {name} turns |omega| dt = {w * dt:.3g} rad per engine step in a corner contact "
                    f"(|omega| = {w:.4g} rad/s, dt = {dt:g} s), above {BOX_TURN_PER_STEP_MAX:g}: the sub-cycle holds "
                    f"the step-start corner geometry, and such contacts gained up to several times the body's energy "
                    f"(MuJoCo's Euler then integrating the fast tumble explicitly may blow up); take dt <= "
                    f"{BOX_TURN_PER_STEP_MAX / w:.3g} s (or a slower spin)")
            mgr.flag_contact(p, note, t_on)
            if p not in self._turn_warned:
                self._turn_warned.add(p)
                warnings.warn(f"pair {p} {self.pair_names[p]}: {note} (warned once per pair; adapter.fast_turns "
                              "counts them)", ValidityWarning, stacklevel=5)

    def _check_damped_onsets(self, t0: float) -> None:
        """Never silent: a contact on a link that began in the step from t0
        where the step's implicit damping leaves less than DAMPED_SHARE_MIN of
        an impulse's velocity change along its normal is flagged (that
        contact) and warned once per pair; ``damped_onsets`` counts them."""
        mgr, dt = self.manager, self.timestep
        began = (self._damped_share < DAMPED_SHARE_MIN) & (mgr.x_max > 0.0) & (mgr.t_onset >= t0) & (
            mgr.t_onset < t0 + dt)
        for p in np.flatnonzero(began).tolist():
            share = float(self._damped_share[p])
            note = (f"damped link: the step's implicit damping leaves {share:.3g} of an impulse's velocity change "
                    f"along the contact's normal (below {DAMPED_SHARE_MIN:g}; 1 / (1 + h B / I) for one joint, "
                    f"dt = {dt:g} s): the contact takes the damper for added inertia and holds its force at the "
                    "step's start, and an impact that bounces inside the step gains energy (a hinged arm: up to "
                    "59 mJ in a step at 0.31); take a smaller timestep (or less joint damping)")
            mgr.flag_contact(p, note, float(mgr.t_onset[p]))
            self.damped_onsets += 1
            if p not in self._damped_warned:
                self._damped_warned.add(p)
                warnings.warn(f"pair {p} {self.pair_names[p]}: {note} (warned once per pair; "
                              "adapter.damped_onsets counts them)", ValidityWarning, stacklevel=5)

    def _check_ring_sink(self) -> None:
        """Never silent: a cylinder's rim ring in contact whose lowest rim
        point lies an angle D from the nearest of its slots, with c (1 - cos
        D) above RING_SINK_MAX of the edge radius (c = Q sin(tilt),
        engines._narrow.RimArcLaw), flags its slots' contacts in progress
        (each once) and warns once per pair: the ring there sinks up to that
        depth. ``ring_sinks`` counts the flagged contacts."""
        from engines._narrow import CylinderOnPlane

        mgr = self.manager
        for k, st in self._line.items():
            if not isinstance(st, CylinderOnPlane) or st.mode != "ring":
                continue
            ring = st.ring
            rim = getattr(ring, "rim", None)
            if rim is None or not math.isfinite(rim.lowest_angle):
                continue
            first = next(q.index for q in self._pairs if q.narrow == k)
            slots = np.arange(first, first + ring.n)
            on = slots[mgr.active[slots]]
            if on.size == 0:
                continue
            D = float(np.min(np.abs(np.remainder(ring.angle - rim.lowest_angle + math.pi, 2 * math.pi) - math.pi)))
            shape = ring.shape
            s_t = math.sin(rim.tilt)
            c = (shape.radius - shape.edge_radius + shape.edge_radius * s_t) * s_t
            sink = c * (1.0 - math.cos(D))
            if sink <= RING_SINK_MAX * shape.edge_radius:
                continue
            note = (f"ring sink: the rim's lowest point lies {math.degrees(D):.3g} deg from the nearest of the "
                    f"ring's {ring.n} slots (tilt {math.degrees(rim.tilt):.3g} deg): the ring there sinks up to "
                    f"c (1 - cos D) = {sink:.3g} m, above {RING_SINK_MAX:g} of the edge radius {shape.edge_radius:g} m "
                    "(the slots keep their material points while any is in contact: a cylinder rolling on its rim); "
                    "not corrected")
            for p in on.tolist():
                t_on = float(mgr.t_onset[p])
                if self._sink_flagged.get(p) == t_on:
                    continue
                self._sink_flagged[p] = t_on
                self.ring_sinks += 1
                mgr.flag_contact(p, note, t_on)
            if first not in self._sink_warned:
                self._sink_warned.add(first)
                warnings.warn(f"pair {first} {self.pair_names[first]}: {note} (warned once per pair; "
                              "adapter.ring_sinks counts them)", ValidityWarning, stacklevel=5)

    def _check_deep_onsets(self, t0: float) -> None:
        """Never silent: a contact from MuJoCo's narrow phase (its point has
        no closed form behind it: a mesh's point was found 23.6 mm deep at a
        1.17 m/s onset, pybullet_data's teddy2_VHACD_CHs.obj dropped from
        0.3 m, which then left at 36 m/s with no warning), or on a link of a
        chain (not a single free body) solved in an island, that began in this step already
        overlapping by an x whose elastic energy int_0^x F_n(x', 0) dx' (never
        worked for: engines._contacts.balance) exceeds ENERGY_GAIN_RTOL of its
        approach energy 1/2 m v_n^2 (at least 1/2 m V_ONSET_MIN^2) is flagged
        in its outside_validity and warned once per pair. The island energy
        check leaves such contacts out (a link's drives and joint limits do
        work its probe does not see), the single contact's COR check too.
        Measured: the MSF ant under RK4 at 10 ms (scripts/ant_integrators.py)
        had an ankle found 26 mm inside the floor at 7 m/s, COR 3.9, before
        its drives entered a_ext in their own step (engines.mujoco._known)."""
        if not self._any_deep_check:
            return
        mgr = self.manager
        integ = int(self.model.opt.integrator)
        why = ("the model was loaded, reset or placed overlapping (start it clear), or "
               "MuJoCo's RK4 moved the link into overlap within a step the contact's free flight did not "
               "predict (the other forces' change inside the step, which RK4's stages follow and the free "
               "flight holds at the step start: a joint limit engaging, a fast-turning link; a control "
               "written by mjcb_control); take a smaller timestep"
               if integ == int(mujoco.mjtIntegrator.mjINT_RK4) else
               "the model was loaded, reset or placed overlapping (start it clear), or "
               "the engine moved the bodies into overlap within a step the contact's free flight did not "
               "predict (semi-implicit Euler moves a body by dt v_end, dt^2/2 a further than the free flight; "
               "the other forces' change inside the step: a joint limit engaging, a fast-turning link; a "
               "control written by mjcb_control); take a smaller timestep")
        if self._narrow_slots.any():
            why = ("the contact point MuJoCo's narrow phase gave lies that far inside the other body (a mesh's "
                   "point or fitted surface beyond the shape's own, two geoms meeting where the fit has no "
                   "support), or " + why)
        self._deep.check(mgr, (self._link_pairs & mgr._island_contact) | self._narrow_slots, t0, why,
                         self.pair_names, stacklevel=5)

    @property
    def deep_onsets(self) -> int:
        """Contacts found deep at their onset on a link, flagged (:meth:`_check_deep_onsets`)."""
        return self._deep.count

    def _side_ends_all(self) -> dict:
        """{narrow geom pair k: its side's ends at the current state} for the capsules on a
        plane (engines._narrow.SideLine, not a cylinder's), all at once
        (engines._narrow.side_ends_many: the values side_ends gives each, bit for bit)."""
        if not self._batched_rows:  # the reference: side_ends pair by pair (SideLine.update)
            return {}
        sides = self._sides
        if sides is None:
            from engines._narrow import SideLine, side_end_constants

            ks = [k for k, st in self._line.items() if type(st) is SideLine]
            c = np.array([side_end_constants(self._line[k].shape) for k in ks], dtype=float).reshape(-1, 3)
            g = np.array([self._narrow_pairs[k][:2] for k in ks], dtype=np.int64).reshape(-1, 2)
            sides = self._sides = (ks, c[:, 0].copy(), c[:, 1].copy(), c[:, 2].copy(), g[:, 0].copy(), g[:, 1].copy())
        ks, e, off, half, g1, g2 = sides
        if not ks:
            return {}
        from engines._narrow import side_ends_many

        d = self.data
        return dict(zip(ks, side_ends_many(e, off, half, d.geom_xpos[g1], d.geom_xmat[g1], d.geom_xpos[g2],
                                           d.geom_xmat[g2].reshape(-1, 3, 3)[:, :, 2])))

    def _line_mode(self, k: int, busy, ends=None) -> str:
        """Line or point contacts for narrow geom pair k (a capsule or
        cylinder on a plane) at the current state (engines._narrow.SideLine.update;
        ends: its side's ends at this state if known, :meth:`_side_ends_all`)."""
        st = self._line[k]
        d = self.data
        g1, g2, s1, _, match = self._narrow_pairs[k]
        rot2 = d.geom_xmat[g2].reshape(3, 3)
        first = self._narrow_consts().first[k]
        mgr = self.manager
        moving = mgr.active[first:first + match.n] & ~mgr.settled[first:first + match.n]
        if st.update(d.geom_xpos[g1], d.geom_xmat[g1].reshape(3, 3), d.geom_xpos[g2], rot2[:, 2], busy,
                     self.pairs[first].law, moving, **({} if ends is None else {"ends": ends})):
            match.anchor[:] = np.nan  # the slots start afresh in the other mode
        return st.mode

    def _narrow_consts(self) -> SimpleNamespace:
        """Per narrow geom pair, fixed with the model: its first pair index (first), its
        bodies (b1, b2), bounding radii (rb1, rb2) and geoms' places in the narrow phase's
        geoms (j1, j2); built on first use."""
        nb = self._narrow_nb
        if nb is None:
            m = self.model
            g1 = np.array([q[0] for q in self._narrow_pairs], dtype=np.int64)
            g2 = np.array([q[1] for q in self._narrow_pairs], dtype=np.int64)
            first = [next(q.index for q in self._pairs if q.narrow == k) for k in range(len(self._narrow_pairs))]
            nb = self._narrow_nb = SimpleNamespace(
                first=first, b1=m.geom_bodyid[g1], b2=m.geom_bodyid[g2], rb1=m.geom_rbound[g1].copy(),
                rb2=m.geom_rbound[g2].copy(), j1=np.searchsorted(self._narrow.geoms, g1),
                j2=np.searchsorted(self._narrow.geoms, g2))
        return nb

    def _line_points(self, k: int, n_slots: int) -> list:
        """:meth:`_line_slots`' slots (x, point, normal) without the ends' poses, which
        :meth:`_pose_lines` gives the pairs that need them (SideLine.slots: the same
        arithmetic)."""
        ends = self._line[k].ends
        per = [None] * n_slots
        for i in range(2):
            x = float(ends.x[i])
            per[i] = (x, ends.lowest[i] + 0.5 * x * ends.normal, ends.normal.copy())
        return per

    def _pose_lines(self, rows) -> None:
        """The ends' poses and onset masses (:meth:`_line_slots`) of the line pairs found
        by this step's :meth:`_narrow_points` of which a slot is among the candidate
        ``rows`` (pair indices): a law whose row is not a candidate is read by nothing in
        this step (the kernel's constants and the onset are those of candidate rows; a
        contact in progress is one), and SideEndLaw.set_pose depends on the pose alone, so
        the next step that needs it gives it the same constants. Saves the Jacobians,
        the mass matrix solve and the law refresh of every end away from the floor."""
        due, self._pose_due = self._pose_due, []
        if not due:
            return
        nb = self._narrow_nb
        for k in due:
            n = self._narrow_pairs[k][4].n
            if any(nb.first[k] + s in rows for s in range(min(n, 2))):
                self._line_slots(k, n)

    def _line_slots(self, k: int, n_slots: int) -> list:
        """Slots 0 and 1 of narrow geom pair k as its side's two ends
        (engines._narrow.SideLine.slots), their onset masses from MuJoCo's
        Jacobians and mass matrix; the other slots free."""
        st = self._line[k]
        ends = st.ends
        m, d = self.model, self.data
        g1, g2 = self._narrow_pairs[k][:2]
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        # n.W_ij.n between the ends (W = J M^-1 J^T of the relative motion along n): each end's onset mass
        ja, jb = np.zeros((3, m.nv)), np.zeros((3, m.nv))  # not self._jac: a caller may hold it
        Jn = np.stack([(self._jacobian(b1, ends.lowest[i], ja) - self._jacobian(b2, ends.lowest[i], jb)).T
                       @ ends.normal for i in range(2)])
        MJ = np.empty_like(Jn)
        mujoco.mj_solveM(m, d, MJ, Jn)
        return st.slots(Jn @ MJ.T, n_slots, self.manager.refresh_law)

    def _ring_slots(self, k: int, first: int) -> list:
        """The slots of narrow geom pair k (its first pair index ``first``), a
        cylinder on its rim, as its rim ring's
        (engines._narrow.CylinderOnPlane.ring_slots), their onset masses from
        MuJoCo's Jacobians and mass matrix; a slot placed at another rim
        point restarts its a_ext (its last velocity was another point's)."""
        ring = self._line[k].ring
        self._have_last[first + np.flatnonzero(self._line[k].moved)] = False
        m, d = self.model, self.data
        g1, g2 = self._narrow_pairs[k][:2]
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        ja, jb = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        Jn = np.stack([(self._jacobian(b1, q, ja) - self._jacobian(b2, q, jb)).T @ ring.rim.normal
                       for q in ring.points()])
        MJ = np.empty_like(Jn)
        mujoco.mj_solveM(m, d, MJ, Jn)
        return self._line[k].ring_slots(Jn @ MJ.T, self.manager.refresh_law)

    def _box_slots(self, k: int, first: int, busy) -> list:
        """The slots of narrow geom pair k, a box on a plane, as its corners
        (engines._narrow.BoxOnPlane.update and slots; a box on a box:
        BoxOnBox, the other box's face at its current pose), their onset
        masses from MuJoCo's Jacobians and mass matrix."""
        from engines._narrow import BoxOnBox

        bx = self._box[k]
        m, d, mgr = self.model, self.data, self.manager
        g1, g2 = self._narrow_pairs[k][:2]
        moving = mgr.active[first:first + bx.n] & ~mgr.settled[first:first + bx.n]
        if isinstance(bx, BoxOnBox):  # the other box's face at its current pose
            up = -np.asarray(m.opt.gravity, dtype=float)
            bx.update(d.geom_xpos[g1], d.geom_xmat[g1].reshape(3, 3), d.geom_xpos[g2], d.geom_xmat[g2].reshape(3, 3),
                      busy, self.pairs[first].law, self.laws, up, float(d.time))
            normal = bx.normal
        else:
            bx.update(d.geom_xpos[g1], d.geom_xmat[g1].reshape(3, 3), d.geom_xpos[g2],
                      d.geom_xmat[g2].reshape(3, 3)[:, 2], busy, self.pairs[first].law, self.laws)
            normal = bx.corners.normal
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        ja, jb = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        Jn = np.stack([(self._jacobian(b1, q, ja) - self._jacobian(b2, q, jb)).T @ normal
                       for q in bx.points()])
        MJ = np.empty_like(Jn)
        mujoco.mj_solveM(m, d, MJ, Jn)
        return bx.slots(Jn @ MJ.T, moving, mgr.refresh_law)

    def _narrow_detection(self, p: _Pair) -> Detection:
        """Detection of narrow pair p's slot from MuJoCo's narrow phase (:meth:`_narrow_row`)."""
        x, n, point, p1, p2 = self._narrow_row(p)
        return Detection(np.array([x]), n[None], point[None], p1[None], p2[None],
                         np.full((1, 2), math.inf), np.full((1, 2), math.inf))

    def _narrow_row(self, p: _Pair) -> tuple:
        """(x [m], normal (3,), point [m] (3,), point1, point2 [m] (3,)) of narrow pair p's
        slot from MuJoCo's narrow phase, each array the caller's own; until the contact's
        onset the slot's law follows the curvature at its point (:meth:`_narrow_law`); a
        slot MuJoCo no longer lists is a gap beyond the detection margin."""
        found = self._narrow_points()[p.narrow][p.slot]
        if found is None:  # beyond the detection margin: a gap larger than a step can close
            point = self.data.geom_xpos[p.geom1].copy()
            return -1.0, np.array([0.0, 0.0, 1.0]), point, point.copy(), point.copy()
        x, point, n = found
        half = 0.5 * max(-x, 0.0)  # across a gap each body's point is on its own surface
        p1, p2 = point + half * n, point - half * n
        if not self.manager.active[p.index]:  # about to touch: the law for the curvature there
            self._narrow_law(p, point, n, x)
        return x, n.copy(), point.copy(), p1, p2

    def _narrow_law(self, p: _Pair, point, n, x: float = 0.0) -> None:
        """Give narrow pair p's slot the law for the curvature of both surfaces
        at ``point`` (normal ``n``) before its onset (engines._narrow.LawBank:
        the PairSpec's law if it fits, else the same law for this curvature;
        issue 13). A contact no law here can carry (a line contact, two flat
        faces) raises ValueError naming both geoms and what to do."""
        from engines._narrow import contact_law

        d = self.data
        g1, g2, s1, s2, _ = self._narrow_pairs[p.narrow]
        spec = self.pairs[p.index]
        box = self._box.get(p.narrow)
        if box is not None:  # a box's corner: its edge's end law (engines._narrow.BoxOnPlane)
            if box.law[p.slot] is not None:
                self.manager.set_law(p.index, box.law[p.slot])
            return
        line = self._line.get(p.narrow)
        if line is not None and line.mode == "line":
            self.manager.set_law(p.index, line.law[p.slot])
            return
        if line is not None and line.mode == "ring":  # a slot of a cylinder's rim ring (RimRing)
            self.manager.set_law(p.index, line.ring.law[p.slot])
            return
        law = contact_law((spec.body1, spec.body2), spec.law, self.laws,
                          s1, (d.geom_xpos[g1], d.geom_xmat[g1].reshape(3, 3)),
                          s2, (d.geom_xpos[g2], d.geom_xmat[g2].reshape(3, 3)), point, n, float(d.time), x)
        self.manager.set_law(p.index, law)

    def _jacobian(self, body: int, point, out) -> np.ndarray:
        if int(self.model.body_weldid[body]) == 0:
            out[:] = 0.0
        else:
            mujoco.mj_jac(self.model, self.data, out, None, point, body)
        return out

    def _first_step_a_ext(self, p: _Pair) -> np.ndarray:
        g = np.array(self.model.opt.gravity, dtype=float)
        if self.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY:
            g = np.zeros(3)
        return (0.0 if p.fixed1 else 1.0) * g - (0.0 if p.fixed2 else 1.0) * g

    def _compute(self) -> bool:
        """Read the kinematics of every candidate pair, call the manager once,
        and keep the forces to apply in every hook call of this step. Pairs of
        a free sphere and a plane, a fixed body or another free sphere are
        read for all of them at once (:class:`_FreeGroup`, or compiled:
        :meth:`_compute_compiled`); the others (links of chains, box faces)
        through MuJoCo's Jacobians pair by pair. Returns True when the step's
        forces were also applied to qfrc_passive for this hook call (a resting
        step in one compiled call, engines.mujoco._resting)."""
        if self.compiled:
            return self._compute_compiled()
        m, d = self.model, self.data
        dt = self.timestep
        P = len(self._pairs)
        required = np.zeros(P, bool)
        required[self.manager.required_pairs] = True  # in contact, or a correction to remove
        blocks = []
        W_fast = None
        if self._fast.index.size:
            cv_saved = self._drive_cvel() if self._kin is not None else None  # driven twists in cvel
            try:
                first = self._shared and not self._pushed
                saved = self._have_last.copy() if first else None
                blk = self._fast.kinematics(m, d, dt, required, self._last_v, self._last_dv, self._have_last,
                                            self._push, self._last_r, self._last_gap, *self._held_geometry(required))
                if first and self._first_push(blk["rows"], self._fast.index, blk["x_all"]):
                    self._have_last[:] = saved  # listed again with the push of this step's own rows
                    blk = self._fast.kinematics(m, d, dt, required, self._last_v, self._last_dv, self._have_last,
                                                self._push, self._last_r, self._last_gap,
                                                *self._held_geometry(required))
            finally:
                if cv_saved is not None:
                    d.cvel[self._kin_fast_b] = cv_saved
            W_fast = blk
            self._p1[self._fast.index], self._p2[self._fast.index] = blk["p1_all"], blk["p2_all"]
            self._gaps[self._fast.index] = blk["x_all"]
            blocks.append(blk["rows"])
        slow, points, jacs = self._slow_rows(required)
        self._keep_points(points)
        if slow is not None:
            blocks.append(slow)
        self._apply = []
        self._apply_fast = None
        self._apply_couple = None
        # the manager is called every step, also without candidates (it completes records then)
        kin = self._assemble(blocks)
        kin.lever = self._lever(kin)
        out: ContactForces = self.manager.step(self._mask(kin))
        self._check_fast_turns(float(d.time))
        if self._known is not None:
            self._check_damped_onsets(float(d.time))
        if self._line:
            self._check_ring_sink()
        self._last_kin, self._last_out = kin, out
        Qc = self._couples(out)
        if self._shared:
            self._push = push_reach(self._keys, kin.pair, kin.x, kin.v_rel, dt, CANDIDATE_FACTOR, self._gaps)
            self._pushed = True
        self.last_forces = out if kin.pair.size else None
        pair = np.asarray(out.pair, dtype=int)
        force = np.asarray(out.force, dtype=float)
        if not np.isfinite(force).all():
            self._non_finite(pair, force)
        hit = np.any(force != 0.0, axis=1)
        if not np.any(hit):
            return False
        # what the next step's a_ext leaves out (module docstring): the generalised impulse
        # J_q^T P_q of every pair's force of this step, except the held forces (held_forces),
        # which stay in the other pairs' a_ext as their prediction for the next step; the
        # couples of the moving contact points (LEVER_DOC) all leave it
        keep = hit & held_forces(self.manager, pair, float(d.time) + dt)
        Q = np.zeros(m.nv) if Qc is None else Qc
        fast = hit & self._is_fast[pair]
        if np.any(fast):
            self._apply_fast = self._fast.forces(d, pair[fast], force[fast], W_fast)
            sub = fast & ~keep
            if np.any(sub):
                self._fast.apply(d, *self._fast.forces(d, pair[sub], force[sub], W_fast), out=Q)
        self._slow_forces(pair, force, hit, keep, points, Q)
        self._unheld = Q
        self._cross_dv(Q * dt, W_fast, jacs)
        # a held pair's own force is the manager's, not a prediction: leave it out too
        for k in np.flatnonzero(keep):
            i = int(pair[k])
            self._last_dv[i] += kin.W[k] @ (force[k] * dt)
        return False

    def _compute_compiled(self) -> bool:
        """:meth:`_compute` with the free group's work in :mod:`engines.mujoco._kernels`
        (the same arithmetic, tests/test_mujoco_kernels.py), reading the MjData
        arrays directly; the slow pairs as in :meth:`_compute`."""
        if self._native_result is not None or (self.fused and _resting.eligible(self)):
            # the resting step in one compiled call (engines.mujoco._resting); if the step is not a
            # resting one it stops after the free group's kinematics and the general path goes on
            self._rows = (None, -1)
            if self._broad is not None:
                self._broad.reset()
            done, applied, n = _resting.step(self, CANDIDATE_FACTOR)
            if done:
                return applied
            self._compute_rest(self._fast_rows(n), self._fk_bufs[9], self._fk_bufs[10])
            return False
        K = self._kernels
        m, d, mgr = self.model, self.data, self.manager
        dt = self.timestep
        required = self._required  # in contact, or a correction to remove (a mask of required_pairs)
        K.required_mask(mgr.active, mgr.J, required)
        f = self._fast
        fast = p1 = p2 = None
        if f.index.size:
            # into the group's arrays kept from step to step (nothing allocated or freed per step:
            # the rows are this step's until the next _compute, which is all the manager and
            # contact_forces read them for)
            b = self._fk_buffers()
            bp = self._broad_phase()
            rows, nrows = bp.rows(self, required, CANDIDATE_FACTOR) if bp is not None else (self._gi[:, 0], -1)
            self._rows = (rows, nrows)
            cv_saved = self._drive_cvel() if self._kin is not None else None  # driven twists in cvel
            try:
                first = self._shared and not self._pushed  # (the broad phase reads every row in its first step)
                saved = self._have_last.copy() if first else None
                hold = self._held_geometry(required)
                err, n = K.free_kinematics_rows_into(
                    self._gi, self._gf, rows, nrows, d.geom_xpos, d.geom_xmat, d.cvel, d.subtree_com, d.xipos,
                    d.ximat, required, self._last_v, self._last_dv, self._have_last, dt, CANDIDATE_FACTOR,
                    COINCIDENT_RTOL, self._push, self._last_r, self._last_gap, *hold, *b)
                if first and nrows < 0 and err == K.ERR_NONE and self._first_push(self._fast_rows(n),
                                                                                  self._fast.index, b[11][:, 0]):
                    self._have_last[:] = saved  # listed again with the push of this step's own rows
                    err, n = K.free_kinematics_rows_into(
                        self._gi, self._gf, rows, nrows, d.geom_xpos, d.geom_xmat, d.cvel, d.subtree_com, d.xipos,
                        d.ximat, required, self._last_v, self._last_dv, self._have_last, dt, CANDIDATE_FACTOR,
                        COINCIDENT_RTOL, self._push, self._last_r, self._last_gap, *hold, *b)
            finally:
                if cv_saved is not None:
                    d.cvel[self._kin_fast_b] = cv_saved
            if nrows >= 0:
                bp.call = (n, hold, self._push)  # for the rows read after the manager's step (_broad_extra)
            p1, p2 = b[9], b[10]
            if err != K.ERR_NONE:
                self._detection_failed(err)
            fast = self._fast_rows(n)
            if nrows < 0:
                self._p1[self._fast_at], self._p2[self._fast_at] = p1, p2
                if self._shared:
                    self._gaps[self._fast_at] = b[11][:, 0]  # every pair's detected x (the kernel's scratch)
            else:
                r = rows[:nrows]
                at = self._fast.index[r]
                self._p1[at], self._p2[at] = p1[r], p2[r]
                if self._shared:  # the pairs not read: no gap for push_reach's paths (NaN)
                    self._gaps[self._fast_at] = np.nan
                    self._gaps[at] = b[11][r, 0]
                late = bp.new[self._group_of[fast["pair"]]]
                if late.any():
                    self._broad_late(fast["pair"][late])
        self._compute_rest(fast, p1, p2)
        return False

    def _first_push(self, rows: dict, index, x_all) -> bool:
        """In the first step (no last step's rows to take the push from: islands.push_reach) the
        push of the free group's own candidate rows and its pairs' gaps x_all (in the order of
        index); True when it reaches farther than the push the rows were listed with (they are
        listed again: a strike in the very first step along a row of balls 0.1 mm apart was
        otherwise found 0.4 mm deep a step later, the cradle at 18,000 times its energy)."""
        self._gaps[index] = x_all
        push = push_reach(self._keys, np.asarray(rows["pair"], np.int64), rows["x"], rows["v_rel"], self.timestep,
                          CANDIDATE_FACTOR, self._gaps)
        more = bool(np.any(push > self._push))
        self._push = np.maximum(self._push, push)
        return more

    def _broad_phase(self):
        """The broad phase to use this step (engines.mujoco._broadphase.BroadPhase), or None: every
        row of the free group is read (``broad_phase`` False, or None with fewer than
        BROAD_MIN_PAIRS sphere-sphere pairs or BROAD_PAIRS_PER_SPHERE per sphere)."""
        on = self.broad_phase
        bp = self._broad
        if on is False:
            if bp is not None:
                bp.reset()
            return None
        if bp is None:
            if self._broad_wanted is None:
                self._broad_wanted = (bool(np.any(_broadphase.sphere_pairs(self._gi, self._gf))),
                                      _broadphase.wanted(self._gi, self._gf))
            some, auto = self._broad_wanted
            if not some or (on is None and not auto):
                return None
            bp = self._broad = _broadphase.BroadPhase(self.model, self._gi, self._gf, len(self._pairs))
        return bp

    def _broad_extra(self, n2: int) -> None:
        """After the manager's step: read this step's kinematics of the rows the broad phase added
        (engines.mujoco._broadphase.BroadPhase.gap_rows: the pairs a push can cross, whose gaps
        push_reach takes; .ahead: the pairs the next step's push and this step's forces can bring
        within reach, whose a_ext state the next step needs), rows[nrows:n2] of ``_rows``. None of
        them can be a candidate in this step (the broad phase's bound, with this step's push); one
        that is (``broad_missed``, warned) was not handed to the manager."""
        K, d, bp = self._kernels, self.data, self._broad
        rows, nrows = self._rows
        if n2 == nrows:
            return
        n, hold, push = bp.call
        b = self._fk_bufs
        extra = rows[nrows:n2]
        err, found = K.free_kinematics_rows_into(
            self._gi, self._gf, extra, extra.size, d.geom_xpos, d.geom_xmat, d.cvel, d.subtree_com, d.xipos, d.ximat,
            self._required, self._last_v, self._last_dv, self._have_last, self.timestep, CANDIDATE_FACTOR,
            COINCIDENT_RTOL, push, self._last_r, self._last_gap, *hold, *(a[n:] for a in b[:9]), *b[9:])
        if err != K.ERR_NONE:
            self._detection_failed(err)
        at = self._fast.index[extra]
        self._p1[at], self._p2[at] = b[9][extra], b[10][extra]
        self._gaps[at] = b[11][extra, 0]
        self._rows = (rows, n2)
        if found:
            self.broad_missed += found
            missed = b[0][n:n + found]
            warnings.warn(f"the broad phase left out {found} sphere-sphere pair(s) that were candidates at t = "
                          f"{float(d.time):.6g} s (pairs {missed.tolist()}): their contact was not handed to the "
                          "contact manager in this step (adapter.broad_missed; engines.mujoco._broadphase). "
                          "Set adapter.broad_phase = False", RuntimeWarning, stacklevel=2)

    def _broad_late(self, pairs: np.ndarray) -> None:
        """Count the sphere-sphere pairs that are candidates in the step the broad phase first listed
        them (module engines.mujoco._broadphase), but for those whose bodies jumped at this step's
        start (a bead placed by the jet's pool): their a_ext restarts from the first-step value
        whatever the broad phase."""
        self.broad_late += int(np.count_nonzero(self._jump_t[pairs] != float(self.data.time)))

    def _fast_rows(self, n: int) -> dict:
        """The free group's n candidate rows in its kinematics buffers, as ContactKinematics fields."""
        pair, x, nrm, point, v_rel, v_com, W, W_com, a_ext = (a[:n] for a in self._fk_bufs[:9])
        return dict(pair=pair, x=x, normal=nrm, point=point, v_rel=v_rel, v_com_rel=v_com, W=W, W_com=W_com,
                    a_ext=a_ext)

    def _detection_failed(self, err: int) -> None:
        """Raise for the free-group detection's error code ``err``: the numpy detection says what
        is wrong."""
        f, d = self._fast, self.data
        for _ in f._detect(d, d.geom_xpos[f.g1]):
            pass
        raise RuntimeError(f"free-group detection failed (code {err}) where the numpy detection passes")

    def _fk_buffers(self) -> tuple:
        """The free group's kinematics arrays, kept from step to step (nothing allocated or
        freed per step: the rows are this step's until the next _compute, which is all the
        manager and contact_forces read them for)."""
        b = self._fk_bufs
        if b is None:
            k = self._gi.shape[0]
            b = self._fk_bufs = (np.empty(k, np.int64), np.empty(k), np.empty((k, 3)), np.empty((k, 3)),
                                 np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3, 3)), np.empty((k, 3, 3)),
                                 np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 4)))
        return b

    def _compute_rest(self, fast: dict | None, p1, p2) -> None:
        """:meth:`_compute_compiled` after the free group's kinematics (``fast``: its candidate
        rows, None without a free group; p1, p2: its contact points)."""
        K = self._kernels
        m, d, mgr = self.model, self.data, self.manager
        dt = self.timestep
        required = self._required
        slow, points, jacs = self._slow_rows(required) if self._slow else (None, {}, [])
        self._keep_points(points)
        self._apply = []
        self._apply_fast = None
        self._apply_couple = None
        if slow is None and fast is not None:
            kin = ContactKinematics(t=float(d.time), **fast)  # the group's rows are in pair order
        else:
            kin = self._assemble([b for b in (fast, slow) if b is not None])
        kin.lever = self._lever(kin)
        out: ContactForces = mgr.step(self._mask(kin))
        self._check_deep_onsets(float(d.time))
        self._check_fast_turns(float(d.time))
        if self._known is not None:
            self._check_damped_onsets(float(d.time))
        if self._line:
            self._check_ring_sink()
        self._last_kin, self._last_out = kin, out
        Qc = self._couples(out)
        if self._shared:
            if self._rows[1] >= 0:  # the broad phase: the gaps a push can cross, read (_broad_gaps)
                self._broad_extra(self._broad.gap_rows(self, kin))
            self._push, self._push_budget = push_reach(self._keys, kin.pair, kin.x, kin.v_rel, dt, CANDIDATE_FACTOR,
                                                       self._gaps, budgets=True)
            self._pushed = True
        if self._rows[1] >= 0:
            self._broad_extra(self._broad.ahead(self, kin, out))
        self.last_forces = out if kin.pair.size else None
        pair = np.asarray(out.pair, dtype=np.int64)
        force = np.asarray(out.force, dtype=float).reshape(-1, 3)
        if not np.isfinite(force).all():
            self._non_finite(pair, force)
        # held_forces, the free group's forces to apply, and the held pairs' own share of
        # the next a_ext if no impulse leaves it (_compute's bookkeeping)
        # the manager's one rule (held_forces) as the kernel's active and settled masks: kept = hit & hold
        hold = np.zeros(mgr.active.size, bool)
        hold[pair] = held_forces(mgr, pair, float(d.time) + dt)
        hit, keep, n_hit, n_unheld, *todo = K.after_step(
            self._gi, self._group_of, pair, force, hold, hold, mgr.t_onset, mgr.tau_est,
            float(d.time) + dt, SETTLE_AFTER_DURATIONS, STEPS_PER_CONTACT_MIN, mgr.dt,
            p1 if p1 is not None else self._no_points, p2 if p2 is not None else self._no_points, d.xipos,
            kin.W, self._last_dv, dt)
        self._after_forces(kin, fast is not None, p1, p2, points, jacs, Qc, pair, force, hit, keep, n_hit, n_unheld,
                           todo)

    def _after_forces(self, kin, fast: bool, p1, p2, points, jacs, Qc, pair, force, hit, keep, n_hit, n_unheld,
                      todo) -> None:
        """:meth:`_compute_rest` after ``after_step`` (its outputs hit, keep, n_hit, n_unheld and
        todo, the free group's forces to apply; fast: the adapter has a free group): what the hook
        applies in every call of the step, and the next step's a_ext bookkeeping (the impulses that
        leave it)."""
        K = self._kernels
        m, d = self.model, self.data
        dt = self.timestep
        if not n_hit:
            return
        if todo[0].shape[0]:
            self._apply_fast = tuple(todo)
        if not n_unheld and Qc is None:
            if self._slow:
                self._slow_forces(pair, force, hit, keep, points, None)
            return
        if not n_unheld:
            # every force held, but couples to apply: after_step took the held pairs' own share W P out
            # already; velocity_change below overwrites the rows whose bodies the couples move and the
            # held_dv after it adds the share to every held row: start them from zero (it was counted
            # twice on the rows the couples did not move, their own force read as outside acceleration)
            self._last_dv[pair[keep]] = 0.0
        # the impulses that leave the next step's a_ext (with the couples of the moving contact points)
        Q = np.zeros(m.nv) if Qc is None else Qc
        if fast:
            sub = K.free_forces(self._gi, self._group_of, pair, force, hit, keep, True, p1, p2, d.xipos)
            K.apply(Q, d.xipos, d.xanchor, d.xmat, *sub)
        if self._slow:
            self._slow_forces(pair, force, hit, keep, points, Q)
        self._unheld = Q
        Qdt = Q * dt
        if np.any(Qdt):  # _cross_dv
            dq = np.zeros((1, m.nv))
            self._solve_m(dq, Qdt.reshape(1, -1))
            dq = dq[0]
            if fast:
                rows, nrows = self._rows
                if nrows < 0:
                    K.velocity_change(self._gi, dq, d.xmat, d.xanchor, p1, p2, self._last_dv)
                else:
                    K.velocity_change_rows(self._gi, rows, nrows, dq, d.xmat, d.xanchor, p1, p2, self._last_dv)
                if self._broad is not None:  # the next step's bound on a_ext (BroadPhase.rows)
                    self._broad.dq[:] = dq
                    self._broad.dq_set = True
            for i, J in jacs:
                self._last_dv[i] = J @ dq
        K.held_dv(self._last_dv, pair, keep, kin.W, force, dt)

    def _world_inverse_inertia(self, b) -> np.ndarray:
        """I^-1 = R diag(1/I) R^T in world axes (k, 3, 3) of the bodies b (k,)."""
        R = self.data.ximat[b].reshape(-1, 3, 3)
        return (R * (1.0 / self.model.body_inertia[b])[:, None, :]) @ R.transpose(0, 2, 1)

    def _held_geometry(self, required: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(hold (P,) bool, normal (P, 3), x (P,) [m]): the sphere-sphere pairs of the free group
        whose contact is shorter than a step (the manager's duration estimate) and is in progress
        or has a timing correction to remove keep the normal of its onset (the normal of first
        touch, engines._sweep) and the manager's own approach. The engine has moved both spheres
        by a whole step's travel meanwhile (two beads passing at 30 m/s: 3 mm in 0.1 ms, 12
        radii), so its line of centres is no normal for them: a contact that straddled a step
        start read it (cor_n 0.979 instead of 0.993), and the correction of a contact inside one
        step was taken back at its point, with the wrong angular impulse (spin 10 % low).
        Not a resting contact (older than SETTLE_AFTER_DURATIONS estimated durations at this step's
        start, the manager's own test): it is no impact inside a step, and held it never read the
        engine's geometry again: in a pile the spheres shift and roll, the onset normal and the
        manager's x went stale, and steel pairs carried their static force across a gap of up to
        68.7 um between the engine's spheres (scripts/pile.py --n 32 --side 4, docs/engines.md)."""
        mgr = self.manager
        if self._pp_idx.size == 0:
            return self._no_hold, mgr.n_in, mgr.x
        hold = np.zeros(len(self._pairs), bool)
        # only a required pair can hold (the jet's 35,245 sphere-sphere pairs, ~20 required: the masks over
        # all of them cost ~1.5 ms a step)
        q = np.flatnonzero(required)
        q = q[self._is_pp[q]]
        resting = mgr.active[q] & ((float(self.data.time) - mgr.t_onset[q]) > SETTLE_AFTER_DURATIONS * mgr.tau_est[q])
        hold[q] = ((mgr.tau_est[q] < self.timestep) & ~resting
                   & (mgr.active[q] | np.any(mgr.J[q] != 0.0, axis=1)))
        return hold, mgr.n_in, mgr.x

    def _lever(self, kin: ContactKinematics) -> np.ndarray | None:
        """The moving contact point of the free group's rows (engines._contacts.state.LEVER_DOC,
        lever_terms_free: W01, W11, g0 (k, 21) from the lever arms p_i - xipos_i, the world
        inverse inertias and cvel's angular velocities); zeros (a point frozen over the step)
        for the slow rows and for the rows the manager settled in the last step (a resting
        contact's overlap does not move within a step, and the resting path stays as cheap).
        The finite-difference a_ext of these rows, (v_rel - last v_rel - last dv)/dt, compares
        velocities at two different points when the overlap changed: it loses that part,
        g0 (max(x, 0) - max(x_last, 0))/dt, which the manager now integrates itself (d' g)."""
        pair = np.asarray(kin.pair, dtype=int)
        if self.compiled:  # the same in one compiled pass (engines.mujoco._kernels.lever_free)
            # (kin's arrays are this step's own, made by _compute_compiled: a_ext is changed in place)
            d = self.data
            out = np.empty((pair.size, 21))
            kin.a_ext = np.asarray(kin.a_ext, dtype=float)
            live = self._kernels.lever_free(self._gi, self._gf, self._group_of, pair, np.asarray(kin.x, dtype=float),
                                            np.asarray(kin.normal, dtype=float), kin.a_ext, self.manager.settled,
                                            self._x_last, d.cvel, d.xipos, d.ximat, self._p1, self._p2,
                                            self.timestep, out, self._lever_scratch)
            return out if live else None
        live = self._is_fast[pair] & ~self.manager.settled[pair]
        xpos = np.maximum(np.asarray(kin.x, dtype=float), 0.0)
        x_last = self._x_last[pair]
        self._x_last[:] = 0.0
        self._x_last[pair] = xpos
        if not np.any(live):
            return None
        f, d = self._fast, self.data
        out = np.zeros((pair.size, 21))
        q = pair[live]
        gi = np.searchsorted(f.index, q)
        b1, b2, free2 = f.b1[gi], f.b2[gi], f.free2[gi]
        I1 = self._world_inverse_inertia(b1)
        I2 = np.zeros_like(I1)
        if np.any(free2):
            I2[free2] = self._world_inverse_inertia(b2[free2])
        w2 = np.where(free2[:, None], d.cvel[b2, :3], 0.0)
        out[live] = lever_terms_free(np.asarray(kin.normal)[live], self._p1[q] - d.xipos[b1], I1, d.cvel[b1, :3],
                                     self._p2[q] - d.xipos[b2], I2, w2)
        kin.a_ext = np.array(kin.a_ext, dtype=float)
        kin.a_ext[live] -= out[live, 18:21] * ((xpos - x_last)[live] / self.timestep)[:, None]
        return out

    def _couples(self, out: ContactForces) -> np.ndarray | None:
        """Keep the step's couples of the moving contact points (ContactForces.torque, on body 1
        and body 2 alike) for the hook, and return their generalised force (nv,) [N m] (None:
        no couple)."""
        if out.torque is None:
            return None
        pair = np.asarray(out.pair, dtype=int)
        on = np.flatnonzero(self._is_fast[pair] & np.any(out.torque != 0.0, axis=1))
        if on.size == 0:
            return None
        f = self._fast
        gi = np.searchsorted(f.index, pair[on])
        tq = np.asarray(out.torque, dtype=float)[on]
        free2 = f.free2[gi]
        b = np.concatenate([f.b1[gi], f.b2[gi][free2]])
        dof = np.concatenate([f.dof1[gi], f.dof2[gi][free2]])
        tq = np.concatenate([tq, tq[free2]])
        self._apply_couple = (b, dof, tq)
        Q = np.zeros(self.model.nv)
        self._add_couples(self.data, Q, b, dof, tq)
        return Q

    def _add_couples(self, d, q, b, dof, tq) -> None:
        """Add world torques tq (b, 3) on free bodies b to q (nv,): a free joint's angular dofs
        take the torque in body axes, xmat^T tq (as _FreeGroup.apply); compiled when the adapter
        is (engines.mujoco._kernels.add_couples, the same sums in the same order)."""
        if self.compiled:
            self._kernels.add_couples(q, d.xmat, np.asarray(b, dtype=np.int64), np.asarray(dof, dtype=np.int64),
                                      np.asarray(tq, dtype=float))
        else:
            self._add_couples_numpy(d, q, b, dof, tq)

    @staticmethod
    def _add_couples_numpy(d, q, b, dof, tq) -> None:
        """Add world torques tq (b, 3) on free bodies b to q (nv,): a free joint's angular dofs
        take the torque in body axes, xmat^T tq (as _FreeGroup.apply)."""
        np.add.at(q, dof[:, None] + np.arange(3, 6), np.einsum("kji,kj->ki", d.xmat[b].reshape(-1, 3, 3), tq))

    def _solve_m(self, out: np.ndarray, rows: np.ndarray) -> None:
        """out = M^-1 applied to each row of rows (k, nv), with the constraint rows active at the step start
        responding (engines.mujoco._known: M_eff^-1) when there are pairs read through Jacobians."""
        if self._known is not None:
            self._known.solve(out, rows)
        else:
            mujoco.mj_solveM(self.model, self.data, out, rows)

    def _slow_rows(self, required) -> tuple[dict | None, dict, list]:
        """The candidate rows of the pairs read through Jacobians (a dict of
        ContactKinematics fields, None: no candidate), their points and
        Jacobians {pair: (point1, point2, J)}, and (pair, J (3, nv)) of every
        slow pair for the a_ext bookkeeping, which is done here for them.
        Each pair's contact first (in pair order: the laws and hand-offs it
        sets), then the Jacobians, v_rel, a_ext and the candidate test of all
        the pairs at once (stacked matmuls: each pair's J @ qvel as numpy
        computes it alone; tests/test_rest_cost_paths.py), then the
        candidates' inverse inertias pair by pair."""
        if not self._batched_rows:
            return self._slow_rows_each(required)
        m, d = self.model, self.data
        dt = self.timestep
        rows = []
        points = {}
        dq_known = self._known.change() if self._known is not None else None
        held = self.manager._held_force
        weld = self.model.body_weldid
        # this step's J, J_c and M_eff^-1 J^T of each candidate row, which _coupling_blocks_jac
        # takes for the same points in the same step (the same calls: the same values)
        step_jac = self._step_jac = {}
        slow = self._slow
        k = len(slow)
        X = np.empty(k)
        N, PT, P1, P2 = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
        for r, p in enumerate(slow):
            if p.kind2 == "narrow":
                X[r], N[r], PT[r], P1[r], P2[r] = self._narrow_row(p)
            else:
                det = self._geometry(p)
                X[r], N[r], PT[r], P1[r], P2[r] = float(det.x[0]), det.normal[0], det.point[0], det.point1[0], \
                    det.point2[0]
        # each body's Jacobian at its own surface point (they differ across a gap); a body
        # welded to the world has none (J - 0 = J: left out)
        J = np.empty((k, 3, m.nv))
        for r, p in enumerate(slow):
            self._jacobian(p.body1, P1[r], J[r])
            if weld[p.body2]:
                J[r] -= self._jacobian(p.body2, P2[r], self._jac2)
        idx = self._slow_index
        v_rel = np.matmul(J, d.qvel)
        have = self._have_last[idx]
        a_ext = (v_rel - self._last_v[idx] - self._last_dv[idx]) / dt
        for r in np.flatnonzero(~have).tolist():
            a_ext[r] = self._first_step_a_ext(slow[r])
        if dq_known is not None and np.any(have):  # this step's drives, user and constraint forces
            h = np.flatnonzero(have)
            a_ext[h] = a_ext[h] + np.matmul(J[h], dq_known)
            for r in h[np.any(held[idx[h]] != 0.0, axis=1)].tolist():
                # its own held force left its a_ext: not the rows' change of its response
                a_ext[r] = a_ext[r] - J[r] @ self._known.held_change(J[r].T @ held[idx[r]])
        self._last_v[idx], self._last_dv[idx], self._have_last[idx] = v_rel, 0.0, True
        jacs = [(p.index, J[r]) for r, p in enumerate(slow)]
        # closing_distance (the same operations as in Python floats, the dots as three products in order)
        vn = v_rel[:, 0] * N[:, 0] + v_rel[:, 1] * N[:, 1] + v_rel[:, 2] * N[:, 2]
        an = a_ext[:, 0] * N[:, 0] + a_ext[:, 1] * N[:, 1] + a_ext[:, 2] * N[:, 2]
        reach = CANDIDATE_FACTOR * (np.maximum(-vn, 0.0) * dt + 0.5 * np.maximum(-an, 0.0) * dt * dt)
        self._gaps[idx] = X
        cand = (X > -(reach + self._push[idx])) | required[idx]
        for r in np.flatnonzero(cand).tolist():
            p = slow[r]
            self._slow_row(p, p.index, X[r], N[r], PT[r], P1[r], P2[r], J[r], v_rel[r], a_ext[r], rows, points, step_jac)
        late = np.flatnonzero(~cand) if self._shared and not self._pushed else ()
        if len(late) and rows:
            # the first step: the push of this step's own rows lists the pairs it reaches too
            # (_slow_rows_each; islands.push_reach)
            cols = list(zip(*rows))
            push = push_reach(self._keys, np.array(cols[0], dtype=np.int64), np.array(cols[1], dtype=float),
                              np.array(cols[4], dtype=float), dt, CANDIDATE_FACTOR, self._gaps)
            self._push = np.maximum(self._push, push)
            for r in late.tolist():
                p = slow[r]
                if X[r] > -(reach[r] + self._push[p.index]):
                    self._slow_row(p, p.index, X[r], N[r], PT[r], P1[r], P2[r], J[r], v_rel[r], a_ext[r], rows, points,
                                   step_jac)
        return self._rows_out(rows, points, jacs)

    def _slow_rows_each(self, required) -> tuple[dict | None, dict, list]:
        """The candidate rows of the pairs read through Jacobians (a dict of
        ContactKinematics fields, None: no candidate), their points and
        Jacobians {pair: (point1, point2, J)}, and (pair, J (3, nv)) of every
        slow pair for the a_ext bookkeeping, which is done here for them.
        Pair by pair: the reference of :meth:`_slow_rows` (``_batched_rows`` False;
        tests/test_rest_cost_paths.py), with no Jacobians kept for _coupling_blocks_jac."""
        self._step_jac = {}
        m, d = self.model, self.data
        dt = self.timestep
        rows = []
        points = {}
        jacs = []
        dq_known = self._known.change() if self._known is not None else None
        held = self.manager._held_force
        weld = self.model.body_weldid
        first = self._shared and not self._pushed
        late = []

        def row(*a):
            self._slow_row(*a, rows, points)

        for p in self._slow:
            if p.kind2 == "narrow":
                x, n, point, p1, p2 = self._narrow_row(p)
            else:
                det = self._geometry(p)
                x, n, point = float(det.x[0]), det.normal[0], det.point[0]
                p1, p2 = det.point1[0].copy(), det.point2[0].copy()
            # each body's Jacobian at its own surface point (they differ across a gap); a body
            # welded to the world has none (J - 0 = J: left out)
            J = self._jacobian(p.body1, p1, self._jac).copy()
            if weld[p.body2]:
                J -= self._jacobian(p.body2, p2, self._jac2)
            v_rel = J @ d.qvel
            i = p.index
            self._gaps[i] = x
            jacs.append((i, J))
            if self._have_last[i]:
                a_ext = (v_rel - self._last_v[i] - self._last_dv[i]) / dt
            else:
                a_ext = self._first_step_a_ext(p)
            if dq_known is not None and self._have_last[i]:  # this step's drives, user and constraint forces
                a_ext = a_ext + J @ dq_known
                Fh = held[i]
                if Fh.any():  # its own held force left its a_ext: not the rows' change of its response
                    a_ext = a_ext - J @ self._known.held_change(J.T @ Fh)
            self._last_v[i], self._last_dv[i], self._have_last[i] = v_rel, 0.0, True
            # closing_distance in Python floats (the same operations)
            reach = CANDIDATE_FACTOR * (max(-float(v_rel @ n), 0.0) * dt + 0.5 * max(-float(a_ext @ n), 0.0) * dt * dt)
            if x <= -(reach + self._push[i]) and not required[i]:
                if first:
                    late.append((p, i, x, n, point, p1, p2, J, v_rel, a_ext, reach))
                continue
            row(p, i, x, n, point, p1, p2, J, v_rel, a_ext)
        if late and rows:
            # the first step (no last step's rows to take the push from: islands.push_reach): the push
            # of this step's own rows lists the pairs it reaches too (a strike in the very first step
            # along a row of balls on slide joints 0.1 mm apart, otherwise found 0.4 mm deep a step later)
            cols = list(zip(*rows))
            push = push_reach(self._keys, np.array(cols[0], dtype=np.int64), np.array(cols[1], dtype=float),
                              np.array(cols[4], dtype=float), dt, CANDIDATE_FACTOR, self._gaps)
            self._push = np.maximum(self._push, push)
            for p, i, x, n, point, p1, p2, J, v_rel, a_ext, reach in late:
                if x > -(reach + self._push[i]):
                    row(p, i, x, n, point, p1, p2, J, v_rel, a_ext)
        return self._rows_out(rows, points, jacs)

    def _rows_out(self, rows: list, points: dict, jacs: list) -> tuple[dict | None, dict, list]:
        """:meth:`_slow_rows`' return from its rows (pair, x, n, point, v_rel, v_com, W, W_com,
        a_ext) each, after the line pairs' poses (_pose_lines)."""
        if self._narrow is not None:
            self._pose_lines(points)
        if not rows:
            return None, points, jacs
        cols = list(zip(*rows))
        return (dict(pair=np.array(cols[0], dtype=int), x=np.array(cols[1], dtype=float),
                     normal=np.array(cols[2], dtype=float), point=np.array(cols[3], dtype=float),
                     v_rel=np.array(cols[4], dtype=float), v_com_rel=np.array(cols[5], dtype=float),
                     W=np.array(cols[6], dtype=float), W_com=np.array(cols[7], dtype=float),
                     a_ext=np.array(cols[8], dtype=float)), points, jacs)

    def _slow_row(self, p, i, x, n, point, p1, p2, J, v_rel, a_ext, rows, points, keep=None) -> None:
        """A candidate row of slow pair p (index i) into rows, its points and Jacobian into points
        (:meth:`_slow_rows`); keep: a dict to keep its (J, J_c, M_eff^-1 J^T) in under i, or None."""
        m, d = self.model, self.data
        weld = self.model.body_weldid
        # W = J M^-1 J^T, W_com = J_c M^-1 J^T
        MinvJT = np.zeros((3, m.nv))
        self._solve_m(MinvJT, np.ascontiguousarray(J))
        W = J @ MinvJT.T
        if self._known is not None and not self.manager.active[i]:  # a possible onset (_check_damped_onsets)
            self._damped_share[i] = self._known.damped_share(J, n)
        Jc = self._jacobian(p.body1, d.xipos[p.body1], self._jac).copy()
        if weld[p.body2]:
            Jc -= self._jacobian(p.body2, d.xipos[p.body2], self._jac2)
        v_com = Jc @ d.qvel
        W_com = Jc @ MinvJT.T
        rows.append((i, x, n, point, v_rel, v_com, W, W_com, a_ext))
        points[i] = (p1, p2, J)
        if keep is not None:
            keep[i] = (J, Jc, MinvJT)

    def _keep_points(self, points: dict) -> None:
        for i, (p1, p2, _J) in points.items():
            self._p1[i], self._p2[i] = p1, p2

    def _energy_probe(self, keys):
        """Kinetic and potential energy [J], gravity's power m g . v [W] and mass [kg] (b,) each of
        the bodies ``keys`` (root body ids), the manager's timing corrections J taken out
        of their velocities (+J at body 1's point, -J at body 2's, as applied); NaN
        for a body that is not a free body (engines._contacts.balance)."""
        m, d, mgr = self.model, self.data, self.manager
        b = np.asarray(keys, dtype=np.int64)
        if not self._free_body[b].any():  # a robot's links: nothing to account for (what the end gives)
            nan = np.full(b.size, np.nan)
            return nan, nan.copy(), nan.copy(), m.body_mass[b]
        g = np.array(m.opt.gravity, dtype=float)
        if m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY:
            g = np.zeros(3)
        mass = m.body_mass[b]
        v = d.cvel[b, 3:].copy()  # a single free body: the velocity of its centre of mass, world axes
        w = d.cvel[b, :3].copy()
        R = d.ximat[b].reshape(-1, 3, 3)
        I = m.body_inertia[b]
        where = np.full(m.nbody + 1, -1, np.int64)  # body key -> its position in b (-1: not asked; [-1]: fixed)
        where[b] = np.arange(b.size)
        p = mgr.required_pairs  # the pairs with a timing correction are among them (any(axis=1) over all P is slow)
        p = p[np.any(mgr.J[p] != 0.0, axis=1)]
        for side, sgn, pts in ((0, 1.0, self._p1), (1, -1.0, self._p2)):
            i = where[self._keys[p, side]]
            on = i >= 0
            if not np.any(on):
                continue
            i, q = i[on], p[on]
            J = sgn * mgr.J[q]
            np.subtract.at(v, i, J / mass[i][:, None])
            L = np.cross(pts[q] - d.xipos[b[i]], J)  # angular impulse about the centre of mass
            np.subtract.at(w, i, np.einsum("kij,kj->ki", R[i], np.einsum("kji,kj->ki", R[i], L) / I[i]))
        wl = np.einsum("kji,kj->ki", R, w)  # body axes
        T = 0.5 * mass * np.einsum("ki,ki->k", v, v) + 0.5 * np.einsum("ki,ki->k", wl * I, wl)
        if self._kin is not None:  # the driven bodies' work on them (engines._kinematic)
            T = T - self._kin.work_on(b, self._keys, mgr.J, self._p1, self._p2)
        U = -mass * (d.xipos[b] @ g)
        q = mass * (v @ g)
        bad = ~self._free_body[b]
        return np.where(bad, np.nan, T), np.where(bad, np.nan, U), np.where(bad, np.nan, q), mass

    def _coupling_blocks(self, pp, pq):
        """The manager's coupling blocks (ContactManager.set_coupling): W_pq =
        J_p M^-1 J_q^T and Wc_pq = J_c,p M^-1 J_q^T (b, 3, 3) [1/kg] between the
        step's contact points of pairs pp and pq (b,). Where both pairs' sides
        are fixed or simple free bodies (one free joint, no armature, no
        children: _simple_free_body) in closed form, as the pybullet adapter:
        for each body b shared by p and q, with signs s = +1 (body 1) or -1
        (body 2) and lever arms r from its centre of mass to each pair's
        contact point, W_pq += s_p s_q (1/m - [r_p]x I^-1 [r_q]x) and Wc_pq +=
        s_p s_q / m (I^-1 in world axes from ximat and body_inertia; equal to
        the Jacobian route to round-off, tests/test_island_kernel.py); the
        others through the Jacobians (:meth:`_coupling_blocks_jac`)."""
        closed = self._closed_pair[pp] & self._closed_pair[pq]
        W = np.zeros((pp.size, 3, 3))
        Wc = np.zeros((pp.size, 3, 3))
        if not np.all(closed):
            o = np.flatnonzero(~closed)
            W[o], Wc[o] = self._coupling_blocks_jac(pp[o], pq[o])
        c = np.flatnonzero(closed)
        if c.size == 0:
            return W, Wc
        m, d = self.model, self.data
        a, b = pp[c], pq[c]
        pts = (self._p1, self._p2)
        eye = np.eye(3)
        for sp, gp in ((0, 1.0), (1, -1.0)):
            for sq, gq in ((0, 1.0), (1, -1.0)):
                bp = self._side_body[a, sp]
                on = (bp == self._side_body[b, sq]) & self._side_free[a, sp] & self._side_free[b, sq]
                if not np.any(on):
                    continue
                j = bp[on]
                R = d.ximat[j].reshape(-1, 3, 3)
                Iinv = (R / m.body_inertia[j][:, None, :]) @ R.transpose(0, 2, 1)
                rp = _skew(pts[sp][a[on]] - d.xipos[j])
                rq = _skew(pts[sq][b[on]] - d.xipos[j])
                inv_m = (1.0 / m.body_mass[j])[:, None, None]
                W[c[on]] += gp * gq * (inv_m * eye - rp @ Iinv @ rq)
                Wc[c[on]] += gp * gq * inv_m * eye
        return W, Wc

    def _coupling_blocks_jac(self, pp, pq):
        """The coupling blocks of :meth:`_coupling_blocks` through each body's
        Jacobian at its own point (``mj_jac``, ``mj_solveM``): exact for free
        bodies and links of chains alike. Called inside the hook (the state is current)."""
        m, d = self.model, self.data
        J, Jc, MJ = {}, {}, {}
        kept = self._step_jac if self._in_hook else {}
        for i in np.unique(np.concatenate([pp, pq])).tolist():
            if i in kept:  # _slow_rows' of this step, at the same points (_keep_points)
                J[i], Jc[i], MJ[i] = kept[i]
                continue
            p = self._pairs[i]
            Ji = self._jacobian(p.body1, self._p1[i], self._jac).copy()
            Ji -= self._jacobian(p.body2, self._p2[i], self._jac2)
            Jci = self._jacobian(p.body1, d.xipos[p.body1], self._jac).copy()
            Jci -= self._jacobian(p.body2, d.xipos[p.body2], self._jac2)
            J[i], Jc[i] = Ji, Jci
        for i in np.unique(pq).tolist():
            if i in MJ:
                continue
            out = np.zeros((3, m.nv))
            self._solve_m(out, np.ascontiguousarray(J[i]))
            MJ[i] = out
        W = np.array([J[a] @ MJ[b].T for a, b in zip(pp.tolist(), pq.tolist())]).reshape(-1, 3, 3)
        Wc = np.array([Jc[a] @ MJ[b].T for a, b in zip(pp.tolist(), pq.tolist())]).reshape(-1, 3, 3)
        return W, Wc

    _SHAPES = dict(pair=(), x=(), normal=(3,), point=(3,), v_rel=(3,), v_com_rel=(3,), W=(3, 3), W_com=(3, 3),
                   a_ext=(3,))

    def _assemble(self, blocks: list[dict]) -> ContactKinematics:
        """One ContactKinematics from blocks of rows, in pair order."""
        shapes = self._SHAPES
        if len(blocks) == 1:
            cat = blocks[0]
        else:
            cat = {k: np.concatenate([b[k] for b in blocks]) if blocks else np.zeros((0,) + s)
                   for k, s in shapes.items()}
            cat["pair"] = cat["pair"].astype(int)
        order = np.argsort(cat["pair"], kind="stable")  # rows in pair order
        return ContactKinematics(t=float(self.data.time), **{k: np.reshape(v[order], (-1,) + shapes[k])
                                                             for k, v in cat.items()})

    def _slow_forces(self, pair, force, hit, keep, points, Q) -> None:
        """Queue the slow pairs' forces for the hook (``mj_applyFT``) and add
        the generalised impulse rate J^T F of those not held to Q (nv,)."""
        d = self.data
        for k in np.flatnonzero(hit & ~self._is_fast[pair]):
            i = int(pair[k])
            F = np.array(force[k], dtype=float)
            p = self._pairs[i]
            p1, p2, J = points[i]
            if not keep[k]:  # Q is not None then
                Q += J.T @ F
            self._apply.append((p.body1, p.body2, p.fixed2, F, p1 - d.xipos[p.body1], p2 - d.xipos[p.body2]))

    def _cross_dv(self, Qdt, blk, jacs) -> None:
        """The change of every pair's v_rel that this step's impulses cause,
        sum_q W_pq P_q = J_p M^-1 sum_q J_q^T P_q (``mj_solveM``), kept for the
        next step's a_ext (module docstring). Qdt: the generalised impulse (nv,)."""
        m, d = self.model, self.data
        if not np.any(Qdt):
            return
        dq = np.zeros((1, m.nv))
        self._solve_m(dq, Qdt.reshape(1, -1))
        dq = dq[0]
        if blk is not None:
            # only the pairs whose bodies moved (a free body's block of M^-1 is its own)
            moved = dq != 0.0
            f = self._fast
            on1 = np.any(moved[f.dof1[:, None] + np.arange(6)], axis=1)
            on2 = f.free2 & np.any(moved[f.dof2[:, None] + np.arange(6)], axis=1)
            sel = np.flatnonzero(on1 | on2)
            if sel.size:
                self._last_dv[f.index[sel]] = f.velocity_change(d, dq, blk, sel)
        for i, J in jacs:
            self._last_dv[i] = J @ dq

    def velocity_offset(self) -> np.ndarray:
        """What the pending timing corrections add to ``data.qvel`` (nv,)
        (engines._contacts: an impulse pair J, -J over two steps; for one step
        after a contact step the engine's velocities carry M^-1 J_p^T J). The
        physical velocities are ``data.qvel - adapter.velocity_offset()``:
        read energies and momenta from those (the positions are already where
        the impulse's timing puts them). Zeros when no correction is pending.
        Computed on a private MjData at the current qpos, each body's Jacobian
        at the point of the step that applied the correction.

        With :attr:`exact_offset` set before the step, right after an
        ``mj_step``: the step replayed from its start state on a private
        MjData with the same forces less the corrections J / dt
        (:meth:`_replayed_offset`), data.qvel minus the replay's. The end-pose
        formula above holds to first order in the step's motion; under RK4 the
        four stages apply J / dt at their own poses (a torso turning with its
        legs swinging), and every integrator's constraint rows answer the
        impulse too (a leg on its limit). gymnasium's Ant-v5 (RK4) seed 3,
        the torso landing at 2.7 m/s: the end-pose offset read its rest step
        97 0.24 J high (issue 13)."""
        m = self.model
        on = np.flatnonzero(np.any(self.manager.J != 0.0, axis=1))
        out = np.zeros(m.nv)
        if on.size == 0:
            return out
        st = self._step_start
        if self.exact_offset and st is not None and float(self.data.time) == st["time"] + self.timestep:
            return self._replayed_offset(on)
        if getattr(self, "_scratch", None) is None:
            self._scratch = mujoco.MjData(m)
        s = self._scratch
        s.qpos[:] = self.data.qpos
        if m.nmocap:
            s.mocap_pos[:], s.mocap_quat[:] = self.data.mocap_pos, self.data.mocap_quat
        mujoco.mj_kinematics(m, s)
        mujoco.mj_comPos(m, s)
        mujoco.mj_makeM(m, s)
        mujoco.mj_factorM(m, s)
        Q = np.zeros(m.nv)
        jac = np.zeros((3, m.nv))
        for i in on.tolist():
            p = self._pairs[i]
            for body, point, sign in ((p.body1, self._p1[i], 1.0), (p.body2, self._p2[i], -1.0)):
                if int(m.body_weldid[body]) != 0:
                    mujoco.mj_jac(m, s, jac, None, point, body)
                    Q += sign * (jac.T @ self.manager.J[i])
        dq = np.zeros((1, m.nv))
        mujoco.mj_solveM(m, s, dq, Q.reshape(1, -1))
        if getattr(self, "_step_response", None) is None:
            self._step_response = StepResponse(m)
        # the step applied the correction through its own A (Euler's implicit damping, the implicit integrators' D)
        S = self._step_response(s, self.data)
        return dq[0] if S is None else S @ dq[0]

    #: the MjData fields a step starts from (besides the derived quantities mj_step recomputes)
    _START_FIELDS = ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "qfrc_applied", "xfrc_applied", "mocap_pos",
                     "mocap_quat", "xipos")

    def _start_state(self, data) -> dict:
        """The step's start state (in the hook of the step's first call): the fields
        :meth:`_replayed_offset` starts its replay from, and xipos (the lever arms' origin)."""
        st = {k: getattr(data, k).copy() for k in self._START_FIELDS}
        st["time"] = float(data.time)
        return st

    def _replayed_offset(self, on: np.ndarray) -> np.ndarray:
        """data.qvel minus the velocities of the last step replayed without the
        timing corrections of pairs ``on`` (:meth:`velocity_offset`): a private
        MjData at the step's start state, ``mj_step`` with a passive hook that
        applies this step's forces (:meth:`_apply_forces`, at each call's own
        poses, as the real step) less J / dt at each side's contact point (its
        lever arm from the centre of mass held in world axes, as the forces'),
        and MuJoCo's contact filter as this adapter answers it. The process's
        other hooks (a previous mjcb_passive, mjcb_control) are not called in
        the replay. Replayed with the corrections kept, the step is the real
        one to round-off (tests/test_gymnasium_ant.py)."""
        m, d, st = self.model, self.data, self._step_start
        if getattr(self, "_replay", None) is None:
            self._replay = mujoco.MjData(m)
        s = self._replay
        for k in self._START_FIELDS[:-1]:
            getattr(s, k)[:] = st[k]
        s.time = st["time"]
        dt = self.timestep
        corr = []
        for i in on.tolist():
            p, J = self._pairs[i], self.manager.J[i] / dt
            corr.append((p.body1, -J, self._p1[i] - st["xipos"][p.body1]))
            if int(m.body_weldid[p.body2]) != 0:
                corr.append((p.body2, J, self._p2[i] - st["xipos"][p.body2]))

        def replay(model, data):
            self._apply_forces(model, data)
            for b, F, r in corr:
                mujoco.mj_applyFT(model, data, F, _ZERO3, data.xipos[b] + r, b, data.qfrc_passive)

        hooks = mujoco.get_mjcb_passive(), mujoco.get_mjcb_control(), mujoco.get_mjcb_contactfilter()
        mujoco.set_mjcb_passive(replay)
        mujoco.set_mjcb_control(None)
        if self._filtering:
            mujoco.set_mjcb_contactfilter(lambda model, data, g1, g2: self._contact_filter(int(g1), int(g2)))
        try:
            mujoco.mj_step(m, s)
        finally:
            mujoco.set_mjcb_passive(hooks[0])
            mujoco.set_mjcb_control(hooks[1])
            mujoco.set_mjcb_contactfilter(hooks[2])
        return d.qvel - s.qvel

    def _angular_velocity(self, body: int) -> np.ndarray:
        """The body's angular velocity in world axes [rad/s] (3,): cvel's angular part, which
        is what mj_objectVelocity(..., flg_local=0) copies (MuJoCo's mju_transformSpatial
        moves only the linear part), without its call and (6,) buffer."""
        return self.data.cvel[body, :3].copy()

    def _com_velocity(self, body: int) -> np.ndarray:
        """Velocity of the body's centre of mass [m/s] (3,): from cvel, the
        body's spatial velocity (omega; v at its root's subtree centre of
        mass), v + omega x (xipos - subtree_com): what J(xipos) qvel gives,
        without forming the (3, nv) Jacobian (nv is large in a jet)."""
        return np.array(_com_velocity_floats(self.model, self.data, body))

    def separating(self, i: int) -> bool:
        """True if body 1 of pair i moves away from body 2 along the contact
        normal at the current state (after a step)."""
        p = self._pairs[i]
        self._refresh()
        det = self._geometry(p, law=False)
        n = det.normal[0]
        J = self._jacobian(p.body1, det.point1[0], self._jac).copy()
        J -= self._jacobian(p.body2, det.point2[0], self._jac2)
        return float((J @ self.data.qvel) @ n) > 0.0

    def _refresh(self) -> None:
        """Positions and velocities of the current state (after mj_step the
        derived quantities are those of the step's start)."""
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        mujoco.mj_comVel(self.model, self.data)

    # -- records -----------------------------------------------------------------
    def _probe(self, i: int) -> dict:
        """Body-level quantities of pair i for the manager's records (at onset,
        inside the hook, and after the step that ended the contact): body 1's
        angular velocity in world axes (spin_in/spin_out about n x t), body
        2's (the rotation per step of both is checked) [rad/s] and the
        relative centre-of-mass velocity [m/s]."""
        if not self._in_hook:
            self._refresh()
        return self._probe_now(i)

    def _probe_now(self, i: int) -> dict:
        """_probe from the derived quantities as they are (no refresh)."""
        p = self._pairs[i]
        m, d = self.model, self.data
        b1, b2 = p.body1, p.body2
        # _angular_velocity and _com_velocity of both bodies, inlined (twice per impact in a jet);
        # the difference on Python floats is numpy's elementwise one
        c1, c2 = _com_velocity_floats(m, d, b1), _com_velocity_floats(m, d, b2)
        out = {"omega1": d.cvel[b1, :3].copy(), "omega2": d.cvel[b2, :3].copy(),
               "v_com_rel": np.array([c1[0] - c2[0], c1[1] - c2[1], c1[2] - c2[2]])}
        kin = self._kin
        if kin is not None and (kin.sides[i] >= 0).any():  # a driven body's twist (engines._kinematic)
            for s, b, sign in ((0, b1, 1.0), (1, b2, -1.0)):
                j = int(kin.sides[i, s])
                if j >= 0:
                    out[f"omega{s + 1}"] = kin.w[j].copy()
                    out["v_com_rel"] += sign * kin.velocity_at(np.array([j]), d.xipos[b][None])[0]
        return out

    def _probe_batch(self):
        """The manager's batch probe: one refresh for all the records it
        completes between two steps (nothing changes the state in between)."""
        if not self._in_hook:
            self._refresh()
        return self._probe_now


def _com_velocity_floats(model, data, body: int) -> tuple[float, float, float]:
    """MujocoAdapter._com_velocity as three Python floats [m/s]: v + omega x (xipos -
    subtree_com) from cvel (the same float arithmetic); zeros for a body welded to the world."""
    if int(model.body_weldid[body]) == 0:
        return 0.0, 0.0, 0.0
    w0, w1, w2, v0, v1, v2 = data.cvel[body].tolist()
    x0, x1, x2 = data.xipos[body].tolist()
    s0, s1, s2 = data.subtree_com[model.body_rootid[body]].tolist()
    r0, r1, r2 = x0 - s0, x1 - s1, x2 - s2  # numpy's elementwise difference, on Python floats
    return v0 + (w1 * r2 - w2 * r1), v1 + (w2 * r0 - w0 * r2), v2 + (w0 * r1 - w1 * r0)


# -- the one global hook ------------------------------------------------------------
_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)
_REGISTRY: dict[int, MujocoAdapter] = {}
_PREVIOUS: list = []  # the hook that was installed before ours (one entry while installed)
_PREVIOUS_SENSOR: list = []  # the mjcb_sensor before ours (one entry while an adapter with MSF sensors is installed)


_FILTERING: dict[int, MujocoAdapter] = {}  # adapters (by MjData) that answer mjcb_contactfilter
_PREVIOUS_FILTER: list = []


def _dispatch_filter(model, data, g1, g2) -> int:
    """The mjcb_contactfilter of this process while an adapter needs it
    (set_mode, a model without <exclude>): the adapter of this MjData answers;
    other data get the previous Python filter or MuJoCo's bitmask rule."""
    adapter = _FILTERING.get(id(data))
    if adapter is not None and adapter.data is data:
        return adapter._contact_filter(int(g1), int(g2))
    if _PREVIOUS_FILTER and _PREVIOUS_FILTER[0] is not None:
        return int(_PREVIOUS_FILTER[0](model, data, g1, g2))
    t1, a1, t2, a2 = (model.geom_contype[g1], model.geom_conaffinity[g1], model.geom_contype[g2],
                      model.geom_conaffinity[g2])
    return 0 if ((t1 & a2) or (t2 & a1)) else 1


def _install_filter(adapter) -> None:
    if not _FILTERING:
        prev = mujoco.get_mjcb_contactfilter()
        if isinstance(prev, ctypes._CFuncPtr):
            raise ValueError("a native (ctypes) mjcb_contactfilter is installed; it cannot be chained from Python")
        _PREVIOUS_FILTER[:] = [prev]
        mujoco.set_mjcb_contactfilter(_dispatch_filter)
    _FILTERING[id(adapter.data)] = adapter
    adapter._filtering = True


def _uninstall_filter(adapter) -> None:
    _FILTERING.pop(id(adapter.data), None)
    adapter._filtering = False
    if not _FILTERING:
        prev = _PREVIOUS_FILTER[0] if _PREVIOUS_FILTER else None
        _PREVIOUS_FILTER.clear()
        mujoco.set_mjcb_contactfilter(prev)


def _dispatch_sensor(model, data, stage) -> None:
    """The mjcb_sensor of this process while an adapter with MSF user sensors
    is installed: chain the previous Python hook, then fill the adapter's sensors."""
    if _PREVIOUS_SENSOR and _PREVIOUS_SENSOR[0] is not None:
        _PREVIOUS_SENSOR[0](model, data, stage)
    adapter = _REGISTRY.get(id(data))
    if adapter is not None and adapter.data is data and adapter._sensors:
        adapter._sensor(int(stage))


def _dispatch(model, data) -> None:
    """The one mjcb_passive of this process: chain the previous Python hook,
    then the adapter of this MjData, if any (another MjData of a model an
    installed adapter manages: :func:`_unmanaged`)."""
    if _PREVIOUS and _PREVIOUS[0] is not None:
        _PREVIOUS[0](model, data)
    adapter = _REGISTRY.get(id(data))
    if adapter is not None and adapter.data is data:
        adapter._passive(model, data)
    elif id(data) not in _UNMANAGED and id(data) not in SCRATCH_IDS:  # (an adapter's own scratch: no MSF, no word)
        _unmanaged(model, data)


#: ids of the MjData stepped under the hook with no adapter of their own, already looked at (_unmanaged)
_UNMANAGED: set[int] = set()


def _unmanaged(model, data) -> None:
    """Never silent: an MjData with no adapter, stepped while an adapter of
    the same model is installed (``mujoco.rollout.rollout(model, [d, d2],
    ...)``, whose threads step each MjData of the list; a copy made with
    ``mj_copyData`` or ``copy.copy(data)``), has no MSF contact: its MSF
    pairs step with whatever the model gives them (measured: a rubber ball
    rolled out on the adapter's MjData and on a second one bounced at
    z = 19.4 mm on the first, sank to 10.8 mm in MuJoCo's own soft contact
    on the second, with no word). Warned once per MjData, naming the fix."""
    _UNMANAGED.add(id(data))
    addr = getattr(model, "_address", None)
    owners = [a for a in _REGISTRY.values() if getattr(a.model, "_address", None) == addr]
    if addr is None or not owners:
        return
    warnings.warn(
        f"mjcb_passive was called for an MjData that has no MSF adapter, of the model whose {len(owners[0].pairs)} "
        "MSF pair(s) an installed MujocoAdapter manages on another MjData (mujoco.rollout with several MjData, a "
        "copy of the MjData): this MjData steps those pairs without MSF (MuJoCo's own contact, or none). Give "
        "each MjData its own adapter, installed (MujocoAdapter(model, data_k, pairs); with installed(...)), or "
        "step the one MjData the adapter has", RuntimeWarning, stacklevel=2)


@contextlib.contextmanager
def installed(adapter: MujocoAdapter):
    """Install the dispatching ``mjcb_passive`` for ``adapter`` for the
    duration of the block; restore the previous hook in ``finally`` (also
    when the step or the hook raises). Several adapters (different MjData)
    may be installed at once; the previous hook is restored when the last
    one leaves. Build models before entering: MuJoCo 4.0's Python bindings
    fail to compile a model (``MjModel.from_xml_string``: "Python exception
    raised") while any Python ``mjcb_passive`` is installed, since the
    compiler calls the hook with a data object that has no Python wrapper.
    While installed, the adapter's resting steps run in a native
    ``mjcb_passive`` in front of the Python hook when it can take them
    (:mod:`engines.mujoco._native`: whoever calls ``mj_step``, the same
    results bit for bit)."""
    key = id(adapter.data)
    if key in _REGISTRY:
        raise ValueError("an adapter for this MjData is already installed")
    check_passive_runs(adapter.model)  # (the flags may have changed since the adapter was made)
    adapter._check_geoms()
    if not _REGISTRY:
        prev = mujoco.get_mjcb_passive()
        if isinstance(prev, ctypes._CFuncPtr):
            raise ValueError("a native (ctypes) mjcb_passive is installed; it cannot be chained from Python")
        _PREVIOUS[:] = [prev]
        mujoco.set_mjcb_passive(_dispatch)
    _REGISTRY[key] = adapter
    adapter._installed = True
    sensing = False
    try:
        adapter._apply_modes()
        sensing = bool(adapter._sensors) and not _PREVIOUS_SENSOR
        if sensing:
            prev = mujoco.get_mjcb_sensor()
            _PREVIOUS_SENSOR[:] = [prev]
            mujoco.set_mjcb_sensor(_dispatch_sensor)
        # the native mjcb_passive for the resting steps of this MjData (engines.mujoco._native)
        _native.attach(adapter, _dispatch, _PREVIOUS)
        yield adapter
    finally:
        _native.detach(adapter)
        adapter._installed = False
        adapter._restore_modes()
        _REGISTRY.pop(key, None)
        if sensing:
            prev = _PREVIOUS_SENSOR[0]
            _PREVIOUS_SENSOR.clear()
            mujoco.set_mjcb_sensor(prev)
        if not _REGISTRY:
            prev = _PREVIOUS[0] if _PREVIOUS else None
            _PREVIOUS.clear()
            mujoco.set_mjcb_passive(prev)
