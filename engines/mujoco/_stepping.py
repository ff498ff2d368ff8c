"""Which MuJoCo step a call of ``mjcb_passive`` belongs to.

MuJoCo calls the passive hook from ``mj_fwdVelocity``, i.e. in every
``mj_forward`` (MuJoCo 4.0, ``src/engine/engine_forward.c``):

- ``mj_step`` = ``mj_forward`` at the step's start state, then the
  integrator. Euler, implicit and implicitfast add no further call; RK4
  (``mj_RungeKutta``) calls ``mj_forwardSkip`` for its three later stages,
  with ``data.time`` set to t + h/2, t + h/2, t + h and the stage's qpos,
  qvel; ``mj_step(model, data, nstep)`` is nstep of these;
  ``mj_step1``/``mj_step2`` call it once (in ``mj_step1``);
- a user's ``mj_forward`` (the viewer's sync, gymnasium's ``set_state``,
  rendering) calls it at whatever state ``data`` holds;
- ``mj_rnePostConstraint`` does not call it.

After a step MuJoCo's ``mj_advance`` sets qvel += h qacc', qpos = qpos (+) h
qvel_new (Euler, implicit, implicitfast: the new velocity; RK4: the
tableau's weighted velocity) and time += h.

RK4 (``mj_RungeKutta``, stage i = 1..3 at X_i = X_0 (+) h sum_j A_ij K_j):
the stage and final velocities are linear, v_i = v_0 + h sum_j A_ij a_j and
v_new = v_0 + h sum_j B_j a_j, with a_3 (the last stage's acceleration)
left in ``data.qacc_warmstart`` by ``mj_advance`` (``data.qacc`` is not
it). The rotation of a free or ball joint is integrated two ways depending
on the MuJoCo version: classically, K_j = the stage's angular velocity
omega_j (MuJoCo <= 3.x, the source quoted above), or on the Lie group
(Runge-Kutta-Munthe-Kaas, measured on MuJoCo 4.0.0: K_j =
dexp^-1_{theta_j}(omega_j), theta_j = h sum_k A_jk K_k, with
dexp^-1_theta(w) = w + theta x w / 2 + (1 - (|theta|/2) cot(|theta|/2))
/|theta|^2 theta x (theta x w); Iserles, Munthe-Kaas, Norsett, Zanna, Acta
Numerica 9 (2000) 215, eq. (3.21) for so(3)). The two differ by
O(h^2 |omega| |domega|) (2e-6 on the ant's torso quaternion at 10 ms); a
step is accepted when it is the image under either, so the tracker holds
across MuJoCo versions without reading the version.

:class:`StepTracker` classifies each call from ``data`` alone, so the
contact state advances exactly once per step whoever calls the hook and how
often:

- ``"first"``: the first call seen;
- ``"same"``: the start state of the current step again (a repeated
  ``mj_forward``, or ``mj_step`` after ``mj_forward``): reuse the step's force;
- ``"stage"``: an RK4 stage of the current step (time t + C_i h, in order);
- ``"step"``: the start of the next step: time is exactly t + h and the
  state is what the integrator makes of the last start state (checked to
  ``JUMP_VTOL``, below);
- ``"jump"``: anything else: ``mj_resetData``, a time set by the user, a
  qpos or qvel written between steps (or a qpos/qvel edit followed by
  ``mj_forward`` at the same time); ``jumped`` marks the dofs that jumped
  (``None``: all of them, when time did). The adapter then interrupts the contacts of
  the kinematic trees of those dofs (``engines.mujoco.adapter``) instead of
  integrating the jump as a contact; the other pairs step on.

Not covered: MuJoCo's sleeping islands (``mjENBL_SLEEP``) re-run
``mj_forwardSkip`` inside ``mj_advance``; such a call is taken as a jump.
"""

from __future__ import annotations

import mujoco
import numpy as np

from engines.mujoco._kernels import off_image_start

#: A new step's state must be the integrator's image of the last start state
#: to this velocity tolerance [m/s or rad/s per dof], relative to 1 + |qvel|
#: (qpos: JUMP_VTOL h (1 + max |qvel|)). The image is recomputed with
#: MuJoCo's mj_integratePos from the start state: bitwise the step's for the
#: semi-implicit integrators, to round-off for RK4 (its weighted velocity is
#: summed in another order); a velocity edit below 1e-7 (1 + |v|) is not told
#: from the step (it acts as a 1e-7 m/s error on a contact, far below the
#: laws' accuracy).
JUMP_VTOL = 1e-7

#: RK4's stage times as fractions of h (MuJoCo's RK4_A row sums).
RK4_C = (0.5, 0.5, 1.0)
#: RK4's weights (MuJoCo's RK4_B).
RK4_B = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)
#: RK4's stage matrix rows (MuJoCo's RK4_A, stages 1-3).
RK4_A = ((0.5, 0.0, 0.0), (0.0, 0.5, 0.0), (0.0, 0.0, 1.0))
#: Below this rotation [rad] dexp^-1's coefficient (1 - (a/2) cot(a/2))/a^2 is
#: its series 1/12 + a^2/720 (the closed form loses digits to cancellation).
_DEXPINV_SERIES_BELOW = 1e-3
#: MuJoCo's RK4 integrator code, read once (an enum's int() per hook call costs microseconds).
_RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)


def dexpinv(theta: np.ndarray, w: np.ndarray) -> np.ndarray:
    """dexp^-1_theta(w) on so(3) (rows: (n, 3) arrays of rotation vectors
    [rad] and angular velocities [rad/s]; the module docstring's formula)."""
    a = np.linalg.norm(theta, axis=-1, keepdims=True)
    small = a < _DEXPINV_SERIES_BELOW
    a_safe = np.where(small, 1.0, a)
    c = np.where(small, 1.0 / 12.0 + a * a / 720.0, (1.0 - 0.5 * a_safe / np.tan(0.5 * a_safe)) / (a_safe * a_safe))
    tw = _cross(theta, w)
    return w + 0.5 * tw + c * _cross(theta, tw)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross of rows (n, 3), its arithmetic (a1 b2 - a2 b1, ...: the same values) without
    its axis handling, which cost more than the products at three rows."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a[..., 1] * b[..., 2], a[..., 2] * b[..., 1], out=out[..., 0])
    np.subtract(a[..., 2] * b[..., 0], a[..., 0] * b[..., 2], out=out[..., 1])
    np.subtract(a[..., 0] * b[..., 1], a[..., 1] * b[..., 0], out=out[..., 2])
    return out


class StepTracker:
    """See the module docstring. ``classify(data)`` once per hook call."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self._opt = model.opt  # the model's options (the same object at every access: read once)
        self._nv = model.nv
        self.h = float(model.opt.timestep)  # the timestep read at the last classify [s]
        self._views = None  # (MjData, its qpos, its qvel): views into d's memory, which stays where it is for d's
        # life, kept from call to call while the same MjData is classified
        self.t0: float | None = None  # time of the current step's start state
        self.q0 = np.zeros(model.nq)
        self.v = np.zeros((4, model.nv))  # qvel of the start state and of RK4's stages 2-4
        self.stage = 0  # RK4 stage calls seen since the start state
        self._q = np.zeros(model.nq)
        #: why the last "jump" was one (for warnings)
        self.why = ""
        #: the kinematic trees (MuJoCo's body_treeid) that jumped at the last "jump"; None: all
        #: of them (time jumped)
        self.jumped: np.ndarray | None = None
        # the tree of each qpos coordinate (nq,), of each dof: model.dof_treeid
        self._qtree = np.full(model.nq, -1)
        for j in range(model.njnt):
            a = int(model.jnt_qposadr[j])
            n = {int(mujoco.mjtJoint.mjJNT_FREE): 7, int(mujoco.mjtJoint.mjJNT_BALL): 4}.get(int(model.jnt_type[j]), 1)
            self._qtree[a:a + n] = model.body_treeid[model.jnt_bodyid[j]]
        # the angular-velocity dofs of every free and ball joint, (n_rot, 3): RK4's Lie-group stages
        rot = []
        for j in range(model.njnt):
            t, a = int(model.jnt_type[j]), int(model.jnt_dofadr[j])
            if t == int(mujoco.mjtJoint.mjJNT_FREE):
                rot.append(range(a + 3, a + 6))
            elif t == int(mujoco.mjtJoint.mjJNT_BALL):
                rot.append(range(a, a + 3))
        self._rot = np.array(rot, dtype=int).reshape(-1, 3)
        self._vbar = np.zeros(model.nv)
        self._bad_q = np.zeros(model.nq, bool)  # the coordinates off the step's image (off_image)
        # _q holds q0 (the base the next image is integrated from: off_image_start wrote both)
        self._q_is_q0 = False
        # off_image_start has already taken the start state of the call being classified
        self._taken = False

    def classify(self, d: mujoco.MjData) -> str:
        # (each read of an MjData or MjModel field from Python costs ~0.2 us, ~1 us in the hook after
        # MuJoCo's step has run through the caches: read each once per call)
        t = float(d.time)
        opt = self._opt
        h = self.h = float(opt.timestep)
        v = self._views
        if v is None or v[0] is not d:
            v = self._views = (d, d.qpos, d.qvel)
        qpos, qvel = v[1], v[2]
        if self.t0 is None:
            return self._start(d, "first", t)
        rk4 = int(opt.integrator) == _RK4
        if rk4 and self.stage < 3 and t == self.t0 + RK4_C[self.stage] * h:
            self.stage += 1
            self.v[self.stage] = qvel
            return "stage"
        if t == self.t0 and np.array_equal(qpos, self.q0) and np.array_equal(qvel, self.v[0]):
            self.stage = 0
            return "same"
        self.jumped = None
        if t == self.t0 + h and (not rk4 or self.stage == 3):
            why = self._not_integrated(d, h, rk4, qpos, qvel)
            if not why:
                return self._start(d, "step", t)
        elif t == self.t0:
            why = "qpos/qvel changed without a step"
        elif rk4 and t == self.t0 + h:
            why = "time advanced by one step without RK4's stages (a state set by the user)"
        else:
            why = f"time went from {self.t0!r} s to {t!r} s, not one step of {h!r} s (a reset, or time set)"
        self.why = why
        return self._start(d, "jump", t)

    def _start(self, d, kind: str, t: float) -> str:
        """The state of this call (time t = d.time [s]) becomes the step's start state."""
        self.t0 = t
        if self._taken:  # off_image_start copied qpos, qvel in its pass
            self._taken = False
        else:
            _, qpos, qvel = self._views  # d's (classify keeps them)
            self.q0[:] = qpos
            self.v[0] = qvel
            self._q_is_q0 = False
        self.stage = 0
        return kind

    def _not_integrated(self, d, h: float, rk4: bool, qpos: np.ndarray, qvel: np.ndarray) -> str:
        """'' if (qpos, qvel) (d's, the views classify keeps) is the integrator's step from the start
        state, else what differs (and the trees that differ in ``jumped``)."""
        m = self.model
        if not rk4 and self._nv:
            # semi-implicit: qpos advanced with the new velocity (a qvel written between steps
            # breaks that too); the coordinates off the image in one compiled pass
            # (engines.mujoco._kernels.off_image: the tolerance below), which also takes the
            # new start state (off_image_start: q0, v[0] and _q, the next image's base, = this state)
            bad_q = self._bad_q
            if not self._q_is_q0:
                self._q[:] = self.q0
            mujoco.mj_integratePos(m, self._q, qvel, h)
            off = off_image_start(self._q, qpos, self.q0, qvel, self.v[0], h, JUMP_VTOL, bad_q)
            self._taken = self._q_is_q0 = True
            if not off:
                return ""
            return self._jumped_trees(np.unique(self._qtree[bad_q]))
        vmax = float(np.max(np.abs(d.qvel))) if m.nv else 0.0
        tol_q = JUMP_VTOL * h * (1.0 + vmax) + 1e-13 * (1.0 + np.abs(self.q0))
        if rk4:
            # qpos advanced with the weighted stage velocities, the rotations of free and ball
            # joints classically or on the Lie group (module docstring): either is a step
            vbar = sum(b * self.v[i] for i, b in enumerate(RK4_B))
            bad_q = np.abs(self._image(vbar, h) - d.qpos) > tol_q
            if bad_q.any() and len(self._rot):
                bad_q &= np.abs(self._image(self._vbar_lie(vbar, h), h) - d.qpos) > tol_q
            # qvel: v_new = v_0 + h sum_j B_j a_j, a_0..a_2 from the stage velocities
            # (h A_ij a_j = v_i - v_0), a_3 from data.qacc_warmstart (module docstring)
            v0 = self.v[0]
            v_new = (v0 + (self.v[1] - v0) / 3.0 + 2.0 * (self.v[2] - v0) / 3.0 + (self.v[3] - v0) / 3.0
                     + (h / 6.0) * d.qacc_warmstart)
            bad_v = np.abs(v_new - d.qvel) > JUMP_VTOL * (1.0 + np.abs(d.qvel))
        else:  # no dofs
            bad_q = np.abs(self._image(d.qvel, h) - d.qpos) > tol_q
            bad_v = np.zeros(m.nv, dtype=bool)
        return self._jumped_trees(np.union1d(self._qtree[bad_q], m.dof_treeid[bad_v]))

    def _jumped_trees(self, trees: np.ndarray) -> str:
        """'' if no tree jumped, else the reason, with the trees (sorted, unique) in ``jumped``."""
        if not trees.size:
            return ""
        self.jumped = trees
        return (f"qpos/qvel of {trees.size} kinematic tree(s) are not the step's image of the last state "
                "(qpos or qvel written between steps)")

    def _image(self, vbar: np.ndarray, h: float) -> np.ndarray:
        """The start qpos advanced by vbar over h with MuJoCo's own
        mj_integratePos (a rotation of more than pi per step, e.g. a
        spinning bead, is not recovered by differentiating)."""
        self._q[:] = self.q0
        self._q_is_q0 = False
        mujoco.mj_integratePos(self.model, self._q, vbar, h)
        return self._q

    def _vbar_lie(self, vbar: np.ndarray, h: float) -> np.ndarray:
        """vbar with the free and ball joints' angular part replaced by
        sum_j B_j K_j, K_j = dexp^-1_{theta_j}(omega_j) (Runge-Kutta-Munthe-Kaas)."""
        r = self._rot
        w = [self.v[i][r] for i in range(4)]  # (n_rot, 3) each
        K = [w[0]]
        for i, row in enumerate(RK4_A, start=1):
            theta = h * sum(a * K[j] for j, a in enumerate(row[:i]))
            K.append(dexpinv(theta, w[i]))
        out = self._vbar
        out[:] = vbar
        out[r] = sum(b * K[j] for j, b in enumerate(RK4_B))
        return out
