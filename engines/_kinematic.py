"""Bodies the user drives kinematically in MSF pairs (both adapters): MuJoCo's
mocap bodies (and bodies welded to one), pybullet's mass-0 bases moved with
``resetBasePositionAndOrientation`` (every mass-0 base of a pair is watched:
pybullet moves none itself); the standard way to drive a gripper, a racket or
a paddle. A body on joints below such a body (a finger on a mocap hand, a
link of a multibody on a moved mass-0 base) moves with its twist too, plus
its joints' motion: the engines' velocities of it carry only the joints'.

Such a body has no velocity in the engine (MuJoCo's ``cvel`` of a mocap body
is zero; a mass-0 pybullet body moved with ``resetBasePositionAndOrientation``
has none): its motion is a jump of its pose between two steps. Read as a
static body, it passes straight through an MSF partner (a mocap paddle at
1 m/s through a resting rubber ball at 1 ms: no contact, the ball left at
-0.317 m/s, /work/usercheck/mj_mocap.py on e6aa1f1).

The convention (docs/engines.md, "Your own loop"): the twist a pose change
implies,

    v_k = (p_k - p_{k-1}) / dt,   omega_k = axis-angle(q_k q_{k-1}^-1) / dt

(p the body frame's origin, q its orientation, world axes, at the starts of
two consecutive steps), is the body's mean twist over the step before; over
the coming step it moves at the linear extrapolation of the last two,
2 v_k - v_{k-1} (and 2 omega_k - omega_{k-1}), held constant over the step:
for a constant acceleration a that is the coming step's mean velocity
exactly, where v_k alone lags by a dt (a paddle accelerating at 100 and 300
m/s^2 through its strike at dt = 1 ms: the ball's exit speed -7.5 % and
-11.8 % off the dt = 1e-5 s run with v_k alone, -0.02 % and -0.12 % with
the extrapolation; /tmp-free script: scripts/kinematic_paddle.py
``accelerating``). The first pose change after a placement moves at v_k.
The body is an infinite mass (W takes nothing from it) moving at that
twist inside the contact's sub-cycle, so the contact's approach rate and
slip include it (v_rel, the relative centre-of-mass velocity, the records'
probe). The work it does on its partners (F . v at the contact point, F dt
the step's impulse) is credited in the islands' energy balance
(engines._contacts.balance): the balance of an island touched by a driven
body is E + S minus that work. A drive whose velocity jumps (a start, a
stop) is followed a step late and overshoots one step (the overlap is off
by dt |dv_n| for a step, then back). A pose left as it was is at rest
(no extrapolation: a drive that stops holds still at once; a paddle pressing
a ball onto the floor at 5 mm/s and stopping rests at the geometry's
overlaps to 7e-11 m, where the extrapolation's one step of retreat left
them 2.5 um short: the settled path relaxes the overlaps toward the
engine's from one side only).

Not motion: the first step (no last pose), a jump of the engine's state
(MuJoCo: mj_resetData, time set; the adapters' jump detection), and a pose
change whose implied velocity differs from the last one by more than
KINEMATIC_ACCEL_MAX dt (at its farthest geom point) -- a placement, not a
drive. Such a step moves the body at zero velocity; its contacts in progress
are interrupted without a record and warned (as the adapters do for other
jumps), unless the user declared the placement (``adapter.placed``).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

#: A driven body's pose change whose implied velocity (at its farthest geom
#: point, linear plus |d omega| times that reach) differs from the last
#: step's by more than this times dt [m/s^2] is a placement, not motion
#: (module docstring). 1e4 m/s^2 (~1,000 g) is above what a user's drive
#: gives (a tennis racket's swing peaks at a few hundred g; a paddle started
#: from rest at 1 m/s in one 1 ms step is 1e3 m/s^2) and below a teleport (a
#: paddle put 10 cm away in one 1 ms step: 1e5 m/s^2). A smooth drive set
#: each step never reaches it; a pose set only every n-th step (a policy at a
#: lower rate) moves in jerks n times the drive's speed.
KINEMATIC_ACCEL_MAX = 1e4


def quat_twist(q_new: np.ndarray, q_old: np.ndarray) -> np.ndarray:
    """The rotation vector (k, 3) [rad] in world axes taking orientations
    q_old to q_new (k, 4), quaternions (w, x, y, z): axis-angle of
    q_new q_old^-1, the shorter way round."""
    w1, v1 = q_new[:, :1], q_new[:, 1:]
    w0, v0 = q_old[:, :1], -q_old[:, 1:]  # the conjugate of q_old
    w = w1 * w0 - np.sum(v1 * v0, axis=1, keepdims=True)
    v = w1 * v0 + w0 * v1 + np.cross(v1, v0)
    flip = w < 0.0
    w, v = np.where(flip, -w, w), np.where(flip, -v, v)
    s = np.linalg.norm(v, axis=1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(s > 0.0, v * (angle / np.where(s > 0.0, s, 1.0)), 2.0 * v)
    return out


def rot_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (k, 4) (w, x, y, z) of rotation matrices R (k, 3, 3)
    (Shepperd's method: the largest of the four squared components first)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = np.trace(R, axis1=1, axis2=2)
    d = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    big = np.argmax(d, axis=1)
    q = np.empty((R.shape[0], 4))
    for k in range(R.shape[0]):
        m, i = R[k], int(big[k])
        if i == 0:
            r = math.sqrt(max(1.0 + tr[k], 0.0))
            q[k] = [0.5 * r, (m[2, 1] - m[1, 2]) / (2 * r), (m[0, 2] - m[2, 0]) / (2 * r), (m[1, 0] - m[0, 1]) / (2 * r)]
        else:
            a, b, c = (i - 1), i % 3, (i + 1) % 3
            r = math.sqrt(max(1.0 + m[a, a] - m[b, b] - m[c, c], 0.0))
            v = np.zeros(3)
            v[a] = 0.5 * r
            v[b] = (m[b, a] + m[a, b]) / (2 * r)
            v[c] = (m[c, a] + m[a, c]) / (2 * r)
            q[k] = [(m[c, b] - m[b, c]) / (2 * r), *v]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


class KinematicBodies:
    """The driven bodies of an adapter's pairs and their twists.

    bodies: the driven bodies' keys (any ints; the adapter's own ids);
    sides (P, 2) int: each pair side's position in ``bodies`` (-1: not a
    driven body); reach (b,) [m]: each body's farthest geom point from its
    frame's origin (the jump test and the candidate reach)."""

    def __init__(self, bodies, sides: np.ndarray, reach, names):
        self.bodies = list(bodies)
        self.names = list(names)
        nb = len(self.bodies)
        self.sides = np.asarray(sides, dtype=np.int64).reshape(-1, 2)
        self.rows = np.flatnonzero(np.any(self.sides >= 0, axis=1))  # pairs with a driven side
        self.reach = np.asarray(reach, dtype=float).reshape(nb)
        self.pos = np.zeros((nb, 3))  # the pose at the last step's start
        self.quat = np.zeros((nb, 4))
        self.have = np.zeros(nb, bool)
        self.v = np.zeros((nb, 3))  # the twist held over this step [m/s], [rad/s], world axes
        self.w = np.zeros((nb, 3))
        self.v_implied = np.zeros((nb, 3))  # the last pose change's twist (the jump test's base)
        self.w_implied = np.zeros((nb, 3))
        self.trust = np.zeros(nb, bool)  # that twist was motion (not a placement): the test applies
        self.origin = np.zeros((nb, 3))  # the frame's origin now
        #: work the driven bodies did on each pair's other body, summed over the run [J] (P,)
        self.work = np.zeros(self.sides.shape[0])
        self.placements = 0  #: pose changes taken as placements (module docstring)
        self.moving = False  # any driven body with a non-zero twist this step
        self.was_moving = False  # ... in the last step
        self.v_prev = np.zeros((nb, 3))  # the last step's twist
        self.w_prev = np.zeros((nb, 3))
        self.uids = None  # pybullet: the bases' unique ids
        self.credited = False  # any work credited yet (work_on is zero until then)

    def update(self, pos, quat, dt: float, reset: bool = False, declared=()) -> list[int]:
        """Read the bodies' poses (b, 3), (b, 4) at a new step's start; set the
        step's twist. reset: the engine's state jumped (all taken as placed,
        quietly: the adapter warns for its jump). declared: body positions the
        user declared placed. Returns the positions taken as undeclared
        placements (the adapter interrupts and warns)."""
        pos = np.asarray(pos, dtype=float).reshape(-1, 3)
        quat = np.asarray(quat, dtype=float).reshape(-1, 4)
        self.origin[:] = pos
        if reset or not self.have.all():
            fresh = np.ones(len(self.bodies), bool) if reset else ~self.have
        else:
            fresh = np.zeros(len(self.bodies), bool)
        v = (pos - self.pos) / dt
        w = quat_twist(quat, self.quat) / dt
        dv = (np.linalg.norm(v - self.v_implied, axis=1)
              + np.linalg.norm(w - self.w_implied, axis=1) * self.reach)
        placed = fresh.copy()
        placed[list(declared)] = True
        # tested against the last step's implied twist where that was motion; the first pose change after
        # a placement (or a jump) is taken as motion untested (a drive started, or resumed, at speed)
        jump = ~placed & self.trust & (dv > KINEMATIC_ACCEL_MAX * dt)
        still = placed | jump
        # the step's twist: the last two pose changes' linear extrapolation where both were motion (module
        # docstring: exact for a constant acceleration), else the last one's; a pose left as it was is at rest
        moved = np.any(pos != self.pos, axis=1) | np.any(quat != self.quat, axis=1)
        two = (self.trust & ~still & moved)[:, None]
        self.v_prev, self.w_prev = self.v.copy(), self.w.copy()  # the last step's (engines.mujoco: a_ext)
        self.was_moving = self.moving
        self.v = np.where(still[:, None], 0.0, np.where(two, 2.0 * v - self.v_implied, v))
        self.w = np.where(still[:, None], 0.0, np.where(two, 2.0 * w - self.w_implied, w))
        self.trust = ~still
        self.v_implied, self.w_implied = v, w
        self.pos[:], self.quat[:] = pos, quat
        self.have[:] = True
        jumped = [int(j) for j in np.flatnonzero(jump)]
        self.placements += len(jumped) + int(np.count_nonzero(placed & ~fresh))
        self.moving = bool(np.any(self.v) or np.any(self.w))
        return jumped

    def velocity_at(self, j: np.ndarray, points: np.ndarray) -> np.ndarray:
        """The driven bodies' (positions j (k,)) velocity at points (k, 3) [m/s]."""
        return self.v[j] + np.cross(self.w[j], points - self.origin[j])

    def push(self, dt: float, factor: float) -> np.ndarray:
        """Extra candidate reach [m] (len(rows),) of the pairs with a driven side:
        factor times what the body's farthest point moves in the step."""
        s = np.linalg.norm(self.v, axis=1) + np.linalg.norm(self.w, axis=1) * self.reach
        extra = np.zeros(self.rows.size)
        for side in (0, 1):
            j = self.sides[self.rows, side]
            on = j >= 0
            extra[on] += factor * s[j[on]] * dt
        return extra

    def adjust(self, pair: np.ndarray, v_rel: np.ndarray, v_com: np.ndarray, p1: np.ndarray, p2: np.ndarray,
               c1: np.ndarray, c2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """v_rel and v_com_rel (k, 3) of the rows ``pair`` with the driven
        bodies' velocities added (body 1's at its contact point p1 and centre
        of mass c1, minus body 2's at p2, c2; all (k, 3))."""
        v_rel, v_com = np.array(v_rel, dtype=float), np.array(v_com, dtype=float)
        for side, sign, p, c in ((0, 1.0, p1, c1), (1, -1.0, p2, c2)):
            j = self.sides[pair, side]
            on = np.flatnonzero(j >= 0)
            if on.size:
                v_rel[on] += sign * self.velocity_at(j[on], p[on])
                v_com[on] += sign * self.velocity_at(j[on], c[on])
        return v_rel, v_com

    def credit(self, pair: np.ndarray, force: np.ndarray, p1: np.ndarray, p2: np.ndarray, dt: float) -> None:
        """Add the step's work of the driven bodies on the other bodies of the
        rows ``pair`` (force (k, 3) on body 1, step-averaged, at p1 / p2)."""
        for side, sign, p in ((0, -1.0, p1), (1, 1.0, p2)):
            j = self.sides[pair, side]
            on = np.flatnonzero(j >= 0)
            if on.size:  # body 2 driven: its force -F at velocity u does -(-F) . u on the contact
                u = self.velocity_at(j[on], p[on])
                self.work[pair[on]] += sign * np.einsum("ki,ki->k", force[on], u) * dt
                self.credited = True

    def work_on(self, keys: np.ndarray, pair_keys: np.ndarray, J: np.ndarray, p1: np.ndarray,
                p2: np.ndarray) -> np.ndarray:
        """The work (b,) [J] the driven bodies did on the moving bodies ``keys`` (b,) (distinct;
        the adapter's island keys), summed over the run, their rows' outstanding timing
        corrections' share taken out (the energy probes take J out of the velocities).
        pair_keys (P, 2): each pair side's key (-1: fixed or driven); J (P, 3): the manager's
        outstanding corrections; p1, p2 (P, 3): each pair's contact points."""
        keys = np.asarray(keys, dtype=np.int64).reshape(-1)
        out = np.zeros(keys.size)
        if not self.credited or not keys.size:
            return out
        rows = self.rows
        A = self.work[rows] - self.correction_work(rows, J[rows], p1[rows], p2[rows])
        order = np.argsort(keys)
        ks = keys[order]
        for side in (0, 1):  # credited to the pair's other (moving) side
            other = pair_keys[rows, 1 - side]
            on = (self.sides[rows, side] >= 0) & (other >= 0)
            i = np.minimum(np.searchsorted(ks, other[on]), ks.size - 1)
            hit = ks[i] == other[on]
            np.add.at(out, order[i[hit]], A[on][hit])
        return out

    def correction_work(self, pair: np.ndarray, J: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
        """The work (k,) [J] the rows' outstanding timing corrections J (k, 3)
        (impulses on body 1) carry at the driven bodies' velocities (taken out
        as the energy probes take J out of the velocities)."""
        out = np.zeros(pair.size)
        for side, sign, p in ((0, -1.0, p1), (1, 1.0, p2)):
            j = self.sides[pair, side]
            on = np.flatnonzero(j >= 0)
            if on.size:
                out[on] += sign * np.einsum("ki,ki->k", J[on], self.velocity_at(j[on], p[on]))
        return out


def interrupt_placements(adapter, kin: KinematicBodies, jumped, declared, t: float, what: str, how: str) -> None:
    """The contacts of the driven bodies ``jumped`` (KinematicBodies.update's) and ``declared``
    (adapter.placed) interrupted, for both adapters: a declared placement quietly; an undeclared one
    (a pose change implying an acceleration above KINEMATIC_ACCEL_MAX) counted in ``adapter.jumps`` and
    ``adapter.interrupted`` and warned when it interrupted a contact. t: the step's time [s]; what: the
    body's kind in the warning ("driven (mocap)", "mass-0"); how: how the user sets its pose."""
    for j in sorted(set(jumped) | set(declared)):
        rows = kin.rows[np.any(kin.sides[kin.rows] == j, axis=1)]
        if j in declared:
            adapter.manager.interrupt(rows, f"driven body {kin.names[j]!r} placed (adapter.placed)")
            continue
        why = (f"the {what} body {kin.names[j]!r} jumped at t = {t:.6g} s: its pose change implies a velocity "
               "change above KINEMATIC_ACCEL_MAX dt (engines._kinematic), so it is taken as a placement (no velocity "
               "this step), not as motion")
        n = adapter.manager.interrupt(rows, why)
        adapter.jumps += 1
        adapter.interrupted += n
        if n:
            warnings.warn(f"{why}; {n} MSF contact(s) in progress were interrupted without a record "
                          f"(adapter.interrupted = {adapter.interrupted}; drive the body smoothly, {how} its pose "
                          "every step, or declare a placement with adapter.placed([...]))", RuntimeWarning, stacklevel=5)
