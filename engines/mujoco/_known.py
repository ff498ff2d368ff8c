"""The forces besides the managed contacts that change from one MuJoCo step
to the next, seen by the contacts in the step they act (issue 13, "RK4 on
links").

A pair read through Jacobians (a link of a chain, a box face) takes its
outside acceleration a_ext from the finite difference of its v_rel over the
last step (:mod:`engines.mujoco.adapter`): it holds the last step's forces.
A force that changes between steps then reaches the contact's free flight
one step after it moved the link. Three kinds change that way, and all
three are known at the hook (``mjcb_passive``, called inside ``mj_passive``
in every ``mj_forward``; MuJoCo 4.0 ``src/engine/engine_forward.c``,
``mj_forwardSkip``: ``mj_fwdPosition``, then ``mj_fwdVelocity`` = ...
``mj_passive`` (the hook) ``mj_referenceConstraint``, ``mj_rne`` (qfrc_bias),
then ``mjcb_control``, ``mj_fwdActuation``, ``mj_fwdAcceleration``,
``mj_fwdConstraint``):

- the actuators' forces (a policy's new control every step): this step's
  from ``mj_fwdActuation``, called here before MuJoCo calls it (same
  inputs, same result);
- the user's ``qfrc_applied`` and ``xfrc_applied`` (set before ``mj_step``;
  an ``xfrc_applied`` row acts at its body's centre of mass, ``xipos``, as
  MuJoCo's ``mj_xfrcAccumulate``);
- MuJoCo's constraint forces (joint limits; any of MuJoCo's own contacts,
  equality constraints, friction loss): solved after the hook, so predicted
  here by the same solve on this state (:meth:`KnownForces.constraint_now`:
  ``mj_referenceConstraint``, ``mj_rne``, ``mj_fwdAcceleration``,
  ``mj_fwdConstraint``, the calls MuJoCo makes next) with the managed
  contacts' generalised force of the last step held in ``qfrc_passive``
  (their best prediction, as the contact manager holds a resting force);
  ``qfrc_passive`` and ``efc_force`` (PGS's warm start) are put back, and
  MuJoCo's own solve after the hook starts from the same inputs.

The constraints respond to the contact force inside the step. For MuJoCo's
soft constraints in their quadratic state (a joint limit pressed, an
equality) the solution of its Gauss problem (MuJoCo's documentation,
Computation, "Soft constraint model") with the active rows S fixed is
f_S = -(A_S + R_S)^-1 (J_S qacc_smooth - a_ref), A_S = J_S M^-1 J_S^T, so
an added generalised force Q moves qacc by M_eff^-1 Q,
M_eff^-1 = M^-1 - M^-1 J_S^T (A_S + R_S)^-1 J_S M^-1: a leg held by its
limit is heavier at the foot than its free joint says. The pairs' W, their
island couplings and the impulses' velocity change kept for the next
a_ext use M_eff^-1 (:meth:`KnownForces.solve`) with the rows active in the
prediction, and the constraint forces compared between steps are those
without the contacts' own share (their response -J_S^T (A_S + R_S)^-1
J_S M^-1 Q_contacts, taken out of the prediction and of the last step's).

What the last step's a_ext holds of them: under Euler, implicit and
implicitfast the forces of its one forward pass; under RK4 the tableau's
weighted sum over its four stages, v_new - v_0 = h sum_j B_j a_j (MuJoCo's
``mj_RungeKutta``), each stage's actuator and constraint forces read at the
next hook call (``qfrc_actuator`` and ``qfrc_constraint`` are kept in
``MjData`` until the next stage's ``mj_fwdActuation`` / ``mj_fwdConstraint``
overwrite them). The pairs' a_ext then gets J M^-1 (Q(now) - Q(last)) with
M this state's.

What stays approximated (the same under every integrator): the forces'
change inside the step (RK4's stages follow the state, the contact's free
flight holds the step start's: first order in dt, as the finite difference
itself), a control written by ``mjcb_control`` (called after the hook:
seen a step late), MuJoCo's constraint response to this step's change of
the contact force beyond the rows active at the step start (a limit the
contact itself pushes into activity within the step), and a tendon armature's bias
force (``mj_tendonBias`` is not in the Python bindings: left out of the
prediction's unconstrained acceleration, which only the constraint rows
read).
"""

from __future__ import annotations

import mujoco
import numpy as np

from engines.mujoco._stepping import RK4_B

_RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)
_QUADRATIC = int(mujoco.mjtConstraintState.mjCNSTRSTATE_QUADRATIC)


class KnownForces:
    """See the module docstring. Call :meth:`read` at every hook call (with
    the call's kind from :class:`engines.mujoco._stepping.StepTracker`),
    :meth:`change` once per step when the contacts are computed (it also
    fixes the active constraint rows :meth:`solve` uses), and
    :meth:`applied` with the managed contacts' generalised force of the step."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData):
        self.model, self.data = model, data
        nv = model.nv
        #: generalised constraint and actuator forces of each stage of the step in progress [N or N m]
        #: (4, nv) (stage j read at the call after it; stage 3 / Euler's only stage at the next step)
        self.constraint = np.zeros((4, nv))
        self.actuator = np.zeros((4, nv))
        #: the efc_type values of each stage's constraint rows (RestEnergy's account)
        self.row_types: list[frozenset] = [frozenset()] * 4
        self._types = frozenset()  # the current call's rows
        self._user = np.zeros(nv)  # qfrc_applied + xfrc_applied of the step in progress
        self._contacts = np.zeros(nv)  # the managed contacts' generalised force of the step in progress
        self._reaction = np.zeros(nv)  # the active constraints' response to it (module docstring)
        self._last: np.ndarray | None = None  # the known forces the last step's a_ext holds (nv,)
        self._dq = np.zeros((1, nv))
        # the active rows of the step start's prediction: J_S (r, nv), M^-1 J_S^T as rows (r, nv),
        # (A_S + R_S)^-1 (r, r); r = 0: none
        self._Js = self._G = np.zeros((0, nv))
        self._Ainv = np.zeros((0, 0))

    def read(self, kind: str, stage: int) -> None:
        """At every hook call: the previous stage's actuator and constraint
        forces, still in ``data``; at a new step, what the finished step's
        a_ext holds of the known forces. ``stage``: the tracker's stage
        count after classifying this call (RK4: 1..3 for "stage")."""
        d = self.data
        rk4 = int(self.model.opt.integrator) == _RK4
        if kind == "stage":
            self._take(stage - 1)
        elif kind == "step":
            self._take(3 if rk4 else 0)
            if rk4:
                Q = sum(b * (self.constraint[i] + self.actuator[i]) for i, b in enumerate(RK4_B))
            else:
                Q = self.constraint[0] + self.actuator[0]
            self._last = Q + self._user - self._reaction
        elif kind in ("first", "jump"):
            self._last = None
        n = int(d.nefc)
        self._types = frozenset(np.unique(d.efc_type[:n]).tolist()) if n else frozenset()

    def _take(self, j: int) -> None:
        d = self.data
        self.constraint[j] = d.qfrc_constraint
        self.actuator[j] = d.qfrc_actuator
        self.row_types[j] = self._types

    def applied(self, before: np.ndarray) -> None:
        """The managed contacts' generalised force of this step: ``qfrc_passive``
        after the hook added them less ``before`` (nv,); and the active
        constraint rows' response to it."""
        np.subtract(self.data.qfrc_passive, before, out=self._contacts)
        self._reaction = self._response(self._contacts)

    def _response(self, Q: np.ndarray) -> np.ndarray:
        """-J_S^T (A_S + R_S)^-1 J_S M^-1 Q: the active rows' constraint force in answer to Q (nv,)."""
        if not self._Js.shape[0]:
            return np.zeros(self.model.nv)
        return -self._Js.T @ (self._Ainv @ (self._G @ Q))

    def user_now(self) -> np.ndarray:
        """qfrc_applied plus xfrc_applied's generalised force (at each body's
        centre of mass, as MuJoCo's mj_xfrcAccumulate) [N or N m] (nv,)."""
        m, d = self.model, self.data
        Q = np.array(d.qfrc_applied, dtype=float)
        for b in np.flatnonzero(np.any(d.xfrc_applied != 0.0, axis=1)):
            mujoco.mj_applyFT(m, d, d.xfrc_applied[b, :3].copy(), d.xfrc_applied[b, 3:].copy(), d.xipos[b].copy(),
                              int(b), Q)
        return Q

    def constraint_now(self) -> np.ndarray:
        """This state's constraint forces without the managed contacts' share
        [N or N m] (nv,), solved as MuJoCo will after the hook with the last
        step's contact forces held, less the active rows' response to them;
        fixes the active rows for :meth:`solve` (module docstring). Needs
        this step's qfrc_actuator (mj_fwdActuation first)."""
        m, d = self.model, self.data
        n = int(d.nefc)
        self._Js = self._G = np.zeros((0, m.nv))
        self._Ainv = np.zeros((0, 0))
        if n == 0:
            return np.zeros(m.nv)
        passive = d.qfrc_passive.copy()
        warm = d.efc_force.copy()
        try:
            mujoco.mj_referenceConstraint(m, d)
            mujoco.mj_rne(m, d, 0, d.qfrc_bias)
            d.qfrc_passive += self._contacts
            mujoco.mj_fwdAcceleration(m, d)
            mujoco.mj_fwdConstraint(m, d)
            Qc = d.qfrc_constraint.copy()
            on = np.flatnonzero(d.efc_state[:n] == _QUADRATIC)
            if on.size:
                if mujoco.mj_isSparse(m):
                    J = np.zeros((n, m.nv))
                    mujoco.mju_sparse2dense(J, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
                else:
                    J = d.efc_J.reshape(n, m.nv)
                Js = np.ascontiguousarray(J[on])
                G = np.zeros_like(Js)
                mujoco.mj_solveM(m, d, G, Js)
                self._Js, self._G = Js, G
                self._Ainv = np.linalg.inv(Js @ G.T + np.diag(d.efc_R[on]))
        finally:
            d.qfrc_passive[:] = passive
            d.efc_force[:] = warm
        return Qc - self._response(self._contacts)

    def solve(self, out: np.ndarray, rows: np.ndarray) -> None:
        """out = rows M_eff^-1 (each row y_i -> M_eff^-1 y_i, (k, nv)): MuJoCo's
        mj_solveM less the active constraint rows' response (module docstring)."""
        mujoco.mj_solveM(self.model, self.data, out, rows)
        if self._Js.shape[0]:
            out -= ((out @ self._Js.T) @ self._Ainv) @ self._G

    def change(self) -> np.ndarray | None:
        """M^-1 (Q(now) - Q(last)) [(nv,)]: the generalised acceleration by
        the known forces' change since the forces the last step's a_ext
        holds (None: the first step, after a jump, or no change). Computes
        this step's actuator forces in ``data`` (mj_fwdActuation) and fixes
        the active constraint rows (:meth:`constraint_now`)."""
        m, d = self.model, self.data
        user = self.user_now()
        last, self._user = self._last, user
        if m.nu:
            mujoco.mj_fwdActuation(m, d)
        Q = user + self.constraint_now()
        if last is None:
            return None
        if m.nu:
            Q += d.qfrc_actuator
        Q -= last
        if not np.any(Q):
            return None
        mujoco.mj_solveM(m, d, self._dq, Q.reshape(1, -1))
        return self._dq[0].copy()

    def rk4_step(self) -> tuple[np.ndarray, list]:
        """After an RK4 ``mj_step``: the constraint forces of its four stages
        (4, nv) and the efc_type values of each stage's rows (4 frozensets)
        (stage 3's are still in ``data``)."""
        Qc = self.constraint.copy()
        Qc[3] = self.data.qfrc_constraint
        return Qc, self.row_types[:3] + [self._types]
