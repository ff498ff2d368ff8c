"""Links held by stiff position servos in MuJoCo (issue 11, item 6).

The MSF sub-cycle sees a link's inertia only (W = J M^-1 J^T); a servo
holding the link (a MuJoCo actuator with an affine bias, i.e. ``<position>``
or a ``<general>`` with ``biastype="affine"``, on a hinge or slide joint),
and the joint's own spring, act on it through MuJoCo's step, one step late
for the contact (as ``a_ext``). The error that makes grows with the servo's
frequency against the engine step,

    omega = sqrt(k / M_dd),  k = sum_a (-biasprm_a[1]) gear_a^2 + jnt_stiffness

(M_dd the joint's diagonal of the joint-space inertia matrix, ``mj_fullM``
at the adapter's construction; k in N m/rad or N/m).

Measured (docs/engines.md, ``.venv/bin/python scripts/held_links.py mujoco``): a 0.5 kg paddle on a
hinge (M_dd = 6.7e-3 kg m^2) struck by a rubber ball (R = 20 mm, 2 m/s,
contact 2.3-2.5 ms), kp = 1e2-1e5 N m/rad, dt = 0.2-2 ms, Euler, RK4 and
implicitfast, first-bounce COR against the 0.1 ms run: within 2 % wherever
omega dt <= 0.35; the first results outside 2 % are at omega dt = 0.38
(kp 2000, 0.7 ms: +2.1 %), 0.47 (kp 3000: +3.1 %), 0.49 (kp 1e4, 0.4 ms:
-2.0 %); kp 1e4 reaches +14 % at omega dt = 1.2, kp 3e4 -37 % at 1.7,
and kp 1e5 diverges from omega dt = 2.3 on (Euler: MuJoCo's own
integration of the servo, unstable for omega dt > 2 without any contact;
the run ends in a ValueError at a ~1500 m/s impact). A softer servo can stay within 2 % above the bound (kp
1000: 1.9 % at omega dt = 0.77) because it moves the paddle little within
the contact; the bound is the one that held for every kp measured.
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

#: Largest servo frequency times step [-] at which the held link's COR was
#: measured within 2 % of the 0.1 ms run for every kp (1e2-1e5 N m/rad) and
#: integrator (Euler, RK4, implicitfast) tried; the first result outside 2 %
#: is at 0.38 (module docstring), 0.3 keeps a 20 % margin in dt.
SERVO_OMEGA_DT_MAX = 0.3


@dataclasses.dataclass(frozen=True)
class Servo:
    """A hinge or slide joint held by position servos and/or its spring."""

    joint: str  # the joint's name (or "joint <id>")
    actuators: tuple[str, ...]  # the affine-bias actuators acting on it
    kp: float  # the actuators' stiffness through their gear, sum of -biasprm[1] gear^2 [N m/rad or N/m]
    stiffness: float  # the joint's own spring (jnt_stiffness) [N m/rad or N/m]
    M_dd: float  # the joint's diagonal of the joint-space inertia matrix [kg m^2 or kg]
    bodies: frozenset  # the bodies it moves: the joint's body and its subtree

    @property
    def omega(self) -> float:
        """sqrt((kp + stiffness) / M_dd) [rad/s]."""
        return math.sqrt((self.kp + self.stiffness) / self.M_dd)

    @property
    def dt_max(self) -> float:
        """The largest step [s] within the bound: SERVO_OMEGA_DT_MAX / omega."""
        return SERVO_OMEGA_DT_MAX / self.omega

    def note(self, dt: float, pair: str) -> str:
        acts = ", ".join(repr(a) for a in self.actuators) or "none"
        return (f"stiff servo: pair {pair} moves with joint {self.joint!r} held by actuator(s) {acts} "
                f"(kp = {self.kp:.4g}, joint stiffness = {self.stiffness:.4g}, M_dd = {self.M_dd:.4g}): "
                f"omega = {self.omega:.4g} rad/s, omega dt = {self.omega * dt:.3g} > {SERVO_OMEGA_DT_MAX:g} at "
                f"dt = {dt:g} s; the contact sees the servo one step late and its COR is not within 2 % "
                f"(measured: +14 % at omega dt = 1.2, a diverging servo from 2.3): use dt <= dt_max = "
                f"{self.dt_max:.3g} s (model.opt.timestep), or a softer servo")


def _name(model, obj, i: int, kind: str) -> str:
    n = mujoco.mj_id2name(model, obj, i)
    return n if n else f"{kind} {i}"


def servos(model: mujoco.MjModel, data: mujoco.MjData) -> list[Servo]:
    """Every hinge or slide joint with a positive servo or spring stiffness,
    M_dd at data's qpos (a scratch MjData: data is not touched)."""
    hinge_slide = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    kp = np.zeros(model.njnt)
    acts: dict[int, list[str]] = {}
    for a in range(model.nu):
        if (int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT)
                or int(model.actuator_biastype[a]) != int(mujoco.mjtBias.mjBIAS_AFFINE)):
            continue
        j = int(model.actuator_trnid[a, 0])
        k = -float(model.actuator_biasprm[a, 1]) * float(model.actuator_gear[a, 0]) ** 2
        if j < 0 or int(model.jnt_type[j]) not in hinge_slide or k <= 0:
            continue
        kp[j] += k
        acts.setdefault(j, []).append(_name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator"))
    stiff = np.array(model.jnt_stiffness, dtype=float)
    held = [j for j in range(model.njnt)
            if int(model.jnt_type[j]) in hinge_slide and kp[j] + max(stiff[j], 0.0) > 0]
    if not held:
        return []
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = data.qpos
    mujoco.mj_kinematics(model, scratch)
    mujoco.mj_comPos(model, scratch)
    mujoco.mj_crb(model, scratch)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, scratch, M)
    parent = model.body_parentid
    out = []
    for j in held:
        root = int(model.jnt_bodyid[j])
        sub = set()
        for b in range(model.nbody):
            c = b
            while c > 0 and c != root:
                c = int(parent[c])
            if c == root:
                sub.add(b)
        d = int(model.jnt_dofadr[j])
        out.append(Servo(_name(model, mujoco.mjtObj.mjOBJ_JOINT, j, "joint"), tuple(acts.get(j, ())),
                         float(kp[j]), float(max(stiff[j], 0.0)), float(M[d, d]), frozenset(sub)))
    return out


#: Largest equality-constraint frequency times step [-] for a held body's
#: contact. Measured (EqualityHold's docstring): a rubber ball (R = 20 mm,
#: 31 g) welded to a 1 kg free block, solref (2 ms, 1), dropped 50 mm on
#: steel, first-bounce COR and the block's rebound against dt = 50 us:
#: +0.4 % at omega dt = 0.051, +0.9 % (the block; the COR 0.0 %) at 0.077,
#: +2.1 % at 0.103, +10 % at 0.26, +39 % at 0.51 (the most MuJoCo's
#: refsafe allows: timeconst >= 2 dt); 0.08 keeps both within 1 %. Tighter
#: than a servo's: a weld ties the body in all six directions.
EQUALITY_OMEGA_DT_MAX = 0.08


@dataclasses.dataclass(frozen=True)
class EqualityHold:
    """A MuJoCo equality constraint (weld, connect, joint) that ties a body
    to another body (or the world, or a mocap body).

    MSF's sub-cycle sees the body's own tree's inertia; MuJoCo's constraint
    solver applies the equality's force in the step, held constant by the
    sub-cycle as a_ext, so a contact on a tree the equality ties stiffly
    comes out too bouncy (the weld's spring acts a step late). Its
    frequency, mass-normalised as MuJoCo's soft constraints are (MuJoCo 4.0
    engine_core_constraint.c, mj_makeImpedance: aref = -B v - K imp r with
    K = 1 / (dmax^2 timeconst^2 dampratio^2), or -solref[0] / dmax^2 in the
    direct format; imp <= dmax = solimp[1]; timeconst >= 2 dt unless
    refsafe is disabled): omega = sqrt(dmax K) [rad/s]."""

    name: str  # the equality's name (or "equality <id>")
    kind: str  # weld, connect, joint
    solref: tuple[float, float]
    dmax: float  # solimp[1]
    omega: float  # [rad/s]
    bodies: frozenset  # the bodies of the trees it ties (not the world's)
    bound: float = EQUALITY_OMEGA_DT_MAX

    @property
    def dt_max(self) -> float:
        """The largest step [s] within the bound: its timeconst is at least 2 dt (refsafe), so a
        timeconst-limited weld may stay over the bound at any dt: then make it one body or soften it."""
        return self.bound / self.omega

    def note(self, dt: float, pair: str) -> str:
        return (f"stiff equality: pair {pair} moves with a body that the {self.kind} equality {self.name!r} ties "
                f"(solref = {self.solref[0]:g} {self.solref[1]:g}, solimp dmax = {self.dmax:g}): omega = "
                f"{self.omega:.4g} rad/s, omega dt = {self.omega * dt:.3g} > {self.bound:g} at dt = {dt:g} s; "
                "MSF's sub-cycle sees the tree's own inertia and the equality's force a step late, so the contact "
                "bounces too much (measured: a ball welded to a 1 kg block, COR +10 % at omega dt = 0.26, +39 % at "
                "0.51): make the held geom part of its holder's body (a rigid hold), soften the equality's solref "
                f"(a timeconst above {1.0 / (self.bound / dt * math.sqrt(self.dmax) * max(self.solref[1], 1e-9)):.3g}"
                " s at this dt), or take a smaller dt")


def equality_holds(model: mujoco.MjModel, data: mujoco.MjData) -> list[EqualityHold]:
    """The active weld, connect and joint equalities (data.eq_active) and the
    dynamic bodies they tie (EqualityHold; tendon and flex equalities are not
    looked at)."""
    E = mujoco.mjtEq
    kinds = {int(E.mjEQ_WELD): "weld", int(E.mjEQ_CONNECT): "connect", int(E.mjEQ_JOINT): "joint"}
    dt = float(model.opt.timestep)
    refsafe = not (model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    site = int(mujoco.mjtObj.mjOBJ_SITE)
    out = []
    for e in range(model.neq):
        kind = kinds.get(int(model.eq_type[e]))
        if kind is None or not bool(data.eq_active[e]):
            continue
        roots = set()
        for obj in (int(model.eq_obj1id[e]), int(model.eq_obj2id[e])):
            if obj < 0:
                continue
            if kind == "joint":
                b = int(model.jnt_bodyid[obj])
            elif int(model.eq_objtype[e]) == site:
                b = int(model.site_bodyid[obj])
            else:
                b = obj
            if int(model.body_weldid[b]) != 0:  # a dynamic body (not the world, nor welded to it, nor mocap)
                roots.add(int(model.body_rootid[b]))
        if not roots:
            continue
        ref = (float(model.eq_solref[e, 0]), float(model.eq_solref[e, 1]))
        dmax = float(model.eq_solimp[e, 1])
        if ref[0] > 0:
            tc = max(ref[0], 2 * dt) if refsafe else ref[0]
            K = 1.0 / max(dmax * dmax * tc * tc * ref[1] * ref[1], 1e-300)
        else:
            K = -ref[0] / max(dmax * dmax, 1e-300)
        bodies = frozenset(b for b in range(1, model.nbody) if int(model.body_rootid[b]) in roots)
        out.append(EqualityHold(_name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality"), kind, ref, dmax,
                                math.sqrt(dmax * K), bodies))
    return out


def stiff_pairs(servo_list: list, pair_bodies: list[tuple[int, int]], dt: float) -> dict[int, object]:
    """{pair index: the stiffest hold (a Servo or an EqualityHold) over its
    bound that moves one of its bodies} for pairs given as (body1, body2) ids."""
    out: dict[int, object] = {}
    for s in servo_list:
        if s.omega * dt <= getattr(s, "bound", SERVO_OMEGA_DT_MAX):
            continue
        for i, (b1, b2) in enumerate(pair_bodies):
            if (b1 in s.bodies or b2 in s.bodies) and (i not in out or s.omega > out[i].omega):
                out[i] = s
    return out


__all__ = ["EQUALITY_OMEGA_DT_MAX", "SERVO_OMEGA_DT_MAX", "EqualityHold", "Servo", "equality_holds", "servos",
           "stiff_pairs"]
