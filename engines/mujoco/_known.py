"""The forces besides the managed contacts that change from one MuJoCo step
to the next, seen by the contacts in the step they act (issue 13, "RK4 on
links").

A pair read through Jacobians (a link of a chain, a box face) takes its
outside acceleration a_ext from the finite difference of its v_rel over the
last step (:mod:`engines.mujoco.adapter`): it holds the last step's forces.
A force that changes between steps then reaches the contact's free flight
one step after it moved the link. Four kinds change that way, and all
four are known at the hook (``mjcb_passive``, called inside ``mj_passive``
in every ``mj_forward``; MuJoCo 4.0 ``src/engine/engine_forward.c``,
``mj_forwardSkip``: ``mj_fwdPosition``, then ``mj_fwdVelocity`` = ...
``mj_passive`` (the hook) ``mj_referenceConstraint``, ``mj_rne`` (qfrc_bias),
then ``mjcb_control``, ``mj_fwdActuation``, ``mj_fwdAcceleration``,
``mj_fwdConstraint``):

- the actuators' forces (a policy's new control every step): this step's
  from ``mj_fwdActuation``, called here before MuJoCo calls it (same
  inputs, same result);
- the joint and tendon springs and gravity compensation (``qfrc_spring``,
  ``qfrc_gravcomp``: computed by ``mj_passive`` before the hook, so this
  step's are read there). gymnasium's HalfCheetah stands on leg springs of
  60-240 N m/rad: held a step late, its feet's contacts predicted less
  motion than the engine made and its rest account rose in its slow
  rocking (docs/engines.md, gymnasium's walkers);
- the joints' and tendons' damping force ``qfrc_damper`` = -B v (also
  computed by ``mj_passive`` before the hook) under Euler, implicit and
  implicitfast: their step applies it at the step start's velocities
  whole, its answer to the step's own impulses being the implicit part, S
  below. Held a step late it changed by -B (v_k - v_k-1) unseen: a humanoid
  rocking on its limbs at rest (joint damping 1-5 N m s/rad, kinetic energy
  ~5e-6 J, period ~35 steps of 2 ms) had its contacts' internal approach
  move 1-3 % more or less than the engine's, in phase with the rocking, and
  RestEnergy's account rose above its bound in 60 rest steps (seed 2 of
  benchmarks.robots.rest_sweep, up to 4.7 uJ) and 15 (seed 13) (issue 13).
  Not under RK4, whose stages' damping follows the stages' velocities, which
  carry the contacts' impulses: with the whole ``qfrc_passive`` and
  ``qfrc_bias`` the RK4 ant chattered at rest, ~1e-4 J every third step.
  The bias force (gravity's generalised force and the Coriolis terms) stays
  in a_ext's finite difference, a step late;
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
without the share of the contacts' impulses that leave a_ext (their
response -J_S^T (A_S + R_S)^-1 J_S M^-1 Q_unheld, taken out of the
prediction and of the last step's). The held forces (resting contacts:
engines.mujoco.adapter.held_forces) stay in the next a_ext as its
prediction, and so does the rows' response to them: when the active rows
change between steps (a limit engaging or letting go under a resting
humanoid), the held forces' response changes with them, and that change
reaches the contacts in its step. With the held forces' response taken out
on both sides, a limit engaging gave the head's and an arm's contacts a
spurious a_ext the size of the limit's answer to their 85 N (their internal
approach moved 2-13x the engine's), and RestEnergy's contacts' own balance
rose 1.4e-4 J in that step (issue 13). A held pair's own force left its
own a_ext (engines.mujoco.adapter): it takes its share of that change back
out (:meth:`KnownForces.held_change`).

MuJoCo's Euler step takes the dofs' damping implicitly (:func:`euler_damping`):
its velocity change is h (M + h B)^-1 M qacc, so every M^-1 here (W, the
couplings, the impulses' velocity change, the known forces' change) is
followed by S = (M + h B)^-1 M (:func:`damped_response`). gymnasium's
HalfCheetah (B = 1.5-6 N m s on its legs, 10 ms): with M^-1 alone each
impulse was predicted to change its foot's velocity 6-9 % more than the step
did (tests/test_gymnasium_cheetah.py). The implicit integrators solve
(M - h D) qacc = qfrc_smooth + qfrc_constraint with D = d qfrc_smooth / d qvel
(``mj_implicitSkip``, MuJoCo's documentation, Computation, "Numerical
integration"): implicitfast with D's joint and tendon damping and actuator
gain and bias derivatives, read as the symmetric matrix of its lower
triangle (``mj_factorI``), implicit with the Coriolis and centripetal (RNE)
derivatives as well (LU). S is then (M - h D)^-1 M, D read from ``qDeriv``
after ``mj_implicit`` on a private copy of the step's state
(:class:`StepResponse`): W equals mj_step's velocity change per impulse to
rounding (tests/test_robots_mujoco.py, implicit and implicitfast). Not
reproduced: implicitfast's local 6x6 solve of a standalone free body with
its gyroscopic derivative (``mjd_freeMhat``; its rows are M - h D here), and
the free bodies' pairs (no KnownForces there: a damped free joint is read
with M^-1).

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

import weakref

import mujoco
import numpy as np

from engines.mujoco._stepping import RK4_B

#: ids of the adapters' own scratch MjData (StepResponse's): MuJoCo's mj_fwdVelocity on them calls the
#: process's mjcb_passive, which must neither step an adapter nor warn of an MjData without one
#: (engines.mujoco.adapter._dispatch; an id leaves the set when its StepResponse is collected)
SCRATCH_IDS: set[int] = set()

_RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)
_EULER = int(mujoco.mjtIntegrator.mjINT_EULER)
_IMPLICIT = int(mujoco.mjtIntegrator.mjINT_IMPLICIT)
_IMPLICITFAST = int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST)


def euler_damping(model: mujoco.MjModel) -> np.ndarray | None:
    """h B [kg m^2/s or kg/s] (nv,), B the dofs' damping, when ``mj_step``
    integrates it implicitly, else None. MuJoCo's Euler step (its
    documentation, Computation, "Numerical integration"; ``mj_EulerSkip`` in
    ``src/engine/engine_forward.c``) takes the damping implicitly when a dof
    has ``dof_damping`` > 0 and ``mjDSBL_EULERDAMP`` is not set: v' = v + h
    (M + h B)^-1 M qacc, qacc = M^-1 f with the damping force -B v in f. A
    generalised force Q then changes v' by h (M + h B)^-1 Q, not h M^-1 Q
    (measured against ``mj_step`` on gymnasium's HalfCheetah-v5, whose leg
    dofs have B = 1.5-6 N m s against M_dd ~ 0.1-0.5 kg m^2 at h = 10 ms:
    equal to 1e-16 in qvel; W with M^-1 6-11 % off, tests/test_gymnasium_cheetah.py)."""
    if int(model.opt.integrator) != _EULER or model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP:
        return None
    B = np.asarray(model.dof_damping, dtype=float)
    if not np.any(B > 0.0):
        return None
    return float(model.opt.timestep) * B


def damped_response(model: mujoco.MjModel, data: mujoco.MjData, source: mujoco.MjData | None = None
                    ) -> np.ndarray | None:
    """S = A^-1 M (nv, nv), the map from MuJoCo's acceleration M^-1 f to the
    step's velocity change per h, A the matrix ``mj_step`` solves its
    velocity change with (:class:`StepResponse`); None when A is M (S = I).
    ``data``: its mass matrix is this state's (``mj_makeM`` done; Euler
    reads M there); ``source``: the MjData whose state (qpos, qvel, act,
    ctrl, applied forces) the implicit integrators' D is taken at (default
    ``data``). A private StepResponse per call: a caller stepping often keeps one."""
    return StepResponse(model)(data, source)


class StepResponse:
    """The matrix A [kg m^2 or kg] (nv, nv) with which ``mj_step`` turns the
    generalised forces into its velocity change, v' = v + h A^-1 (f + Q_c)
    (module docstring), and S = A^-1 M: Euler with implicit damping
    A = M + h diag(B) (:func:`euler_damping`); implicitfast A = M - h D, D
    read by ``mj_factorI`` from its lower triangle (symmetric); implicit
    A = M - h D (D with the RNE derivative, not symmetric); RK4, or Euler
    without damping, A = M (None). D is ``qDeriv`` after ``mj_implicit`` on a
    private MjData holding the step's state (``mj_fwdPosition`` and
    ``mj_fwdVelocity`` first: the derivatives read the actuators' moments,
    the tendons and the bodies' velocities there), in MuJoCo's sparse
    layout (``D_rownnz``, ``D_rowadr``, ``D_colind``)."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self._scratch: mujoco.MjData | None = None
        self._state = None
        rownnz, rowadr = np.asarray(model.D_rownnz), np.asarray(model.D_rowadr)
        idx = np.concatenate([np.arange(a, a + n) for a, n in zip(rowadr.tolist(), rownnz.tolist())]
                             ) if model.nv else np.zeros(0, int)
        self._rows = np.repeat(np.arange(model.nv), rownnz)
        self._idx = idx.astype(int)
        self._cols = np.asarray(model.D_colind)[self._idx]

    def implicit(self) -> bool:
        return int(self.model.opt.integrator) in (_IMPLICIT, _IMPLICITFAST)

    def matrix(self, data: mujoco.MjData, source: mujoco.MjData | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """(A, M) (nv, nv) each at ``source``'s state (Euler: ``data``'s M), or None when A = M."""
        m = self.model
        if not self.implicit():
            hB = euler_damping(m)
            if hB is None:
                return None
            M = np.zeros((m.nv, m.nv))
            mujoco.mj_fullM(m, data, M)
            return M + np.diag(hB), M
        src = data if source is None else source
        if self._scratch is None:
            self._scratch = mujoco.MjData(m)
            SCRATCH_IDS.add(id(self._scratch))
            weakref.finalize(self, SCRATCH_IDS.discard, id(self._scratch))
            self._spec = mujoco.mjtState.mjSTATE_INTEGRATION
            self._state = np.empty(mujoco.mj_stateSize(m, self._spec))
        s = self._scratch
        mujoco.mj_getState(m, src, self._state, self._spec)
        mujoco.mj_setState(m, s, self._state, self._spec)
        mujoco.mj_fwdPosition(m, s)  # the moments, tendons, M; then the velocities (no control callback, no solve)
        mujoco.mj_fwdVelocity(m, s)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, s, M)
        mujoco.mj_implicit(m, s)  # fills qDeriv at this state (and advances the scratch: not used)
        D = np.zeros((m.nv, m.nv))
        D[self._rows, self._cols] = s.qDeriv[self._idx]
        A = M - float(m.opt.timestep) * D
        if int(m.opt.integrator) == _IMPLICITFAST:  # mj_factorI reads the lower triangle as a symmetric matrix
            A = np.tril(A) + np.tril(A, -1).T
        return A, M

    def __call__(self, data: mujoco.MjData, source: mujoco.MjData | None = None) -> np.ndarray | None:
        """S = A^-1 M (nv, nv), or None when A = M (see :func:`damped_response`)."""
        AM = self.matrix(data, source)
        if AM is None:
            return None
        A, M = AM
        return np.linalg.solve(A, M)


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
        #: the known passive forces (joint and tendon springs, gravity compensation; the damping but
        #: under RK4) of each stage [N or N m] (4, nv), read at the stage's own hook call (mj_passive
        #: has computed them)
        self.passive = np.zeros((4, nv))
        #: qfrc_damper is a known force (Euler, implicit, implicitfast: module docstring); read at each
        #: call, as a user may switch the integrator between steps
        self._damper = False
        #: the efc_type values of each stage's constraint rows (RestEnergy's account)
        self.row_types: list[frozenset] = [frozenset()] * 4
        self._types = frozenset()  # the current call's rows
        self._user = np.zeros(nv)  # qfrc_applied + xfrc_applied of the step in progress
        self._contacts = np.zeros(nv)  # the managed contacts' generalised force of the step in progress
        self._unheld = np.zeros(nv)  # its part not held into the next step (the rest stays in a_ext)
        self._reaction = np.zeros(nv)  # the active constraints' response to that part (module docstring)
        self._last: np.ndarray | None = None  # the known forces the last step's a_ext holds (nv,)
        self._dq = np.zeros((1, nv))
        # the active rows of the step start's prediction: J_S (r, nv), M^-1 J_S^T as rows (r, nv),
        # (A_S + R_S)^-1 (r, r); r = 0: none
        self._Js = self._G = np.zeros((0, nv))
        self._Ainv = np.zeros((0, 0))
        self._old = (self._Js, self._Ainv, self._G)  # the last step's rows (held_change)
        self._S: np.ndarray | None = None  # the step's A^-1 M (StepResponse) at this step, or None (A = M)
        self._step_response = StepResponse(model)

    def read(self, kind: str, stage: int) -> None:
        """At every hook call: the previous stage's actuator and constraint
        forces, still in ``data``; at a new step, what the finished step's
        a_ext holds of the known forces. ``stage``: the tracker's stage
        count after classifying this call (RK4: 1..3 for "stage")."""
        d = self.data
        rk4 = int(self.model.opt.integrator) == _RK4
        self._damper = not rk4
        if kind == "stage":
            self._take(stage - 1)
            self._springs(stage)
        elif kind == "step":
            self._take(3 if rk4 else 0)
            if rk4:
                Q = sum(b * (self.constraint[i] + self.actuator[i] + self.passive[i]) for i, b in enumerate(RK4_B))
            else:
                Q = self.constraint[0] + self.actuator[0] + self.passive[0]
            self._last = Q + self._user - self._reaction
            self._springs(0)
        elif kind in ("first", "jump"):
            self._last = None
            self._springs(0)
        n = int(d.nefc)
        self._types = frozenset(np.unique(d.efc_type[:n]).tolist()) if n else frozenset()

    def _take(self, j: int) -> None:
        d = self.data
        self.constraint[j] = d.qfrc_constraint
        self.actuator[j] = d.qfrc_actuator
        self.row_types[j] = self._types

    def _springs(self, j: int) -> None:
        """The passive forces known at this hook call into passive[j]: springs, gravity
        compensation and, but under RK4, the damping (module docstring)."""
        d = self.data
        np.add(d.qfrc_spring, d.qfrc_gravcomp, out=self.passive[j])
        if self._damper:
            self.passive[j] += d.qfrc_damper

    def applied(self, before: np.ndarray, unheld: np.ndarray | None) -> None:
        """The managed contacts' generalised force of this step: ``qfrc_passive``
        after the hook added them less ``before`` (nv,); ``unheld`` (nv,) its
        part whose impulse leaves the next step's a_ext (None: none, every
        force held or no force); and the active constraint rows' response to
        that part. The held forces' response stays in the constraint forces
        compared between steps (module docstring)."""
        np.subtract(self.data.qfrc_passive, before, out=self._contacts)
        if unheld is None:
            self._unheld[:] = 0.0
        else:
            self._unheld[:] = unheld
        self._reaction = self._response(self._unheld)

    def _response(self, Q: np.ndarray, rows=None) -> np.ndarray:
        """-J_S^T (A_S + R_S)^-1 J_S M^-1 Q: the active rows' constraint force in answer to Q (nv,)
        (rows: (J_S, (A_S + R_S)^-1, M^-1 J_S^T as rows), default this step's)."""
        Js, Ainv, G = (self._Js, self._Ainv, self._G) if rows is None else rows
        if not Js.shape[0]:
            return np.zeros(self.model.nv)
        return -Js.T @ (Ainv @ (G @ Q))

    def held_change(self, Q: np.ndarray) -> np.ndarray:
        """S M^-1 (r_now(Q) - r_last(Q)) [(nv,)]: how the change of the active
        rows since the last step changes the velocity a held force's
        generalised force Q (nv,) gives a step, per h (r: the rows' response,
        :meth:`_response`; S: the step's A^-1 M, :class:`StepResponse`). :meth:`change` holds
        it for every held force (their share of the last step's a_ext was the
        old rows'); a held pair's own force, which left its own a_ext, takes
        it back out with this."""
        dQ = self._response(Q) - self._response(Q, self._old)
        out = np.zeros((1, self.model.nv))
        if np.any(dQ):
            self.solve_free(out, dQ.reshape(1, -1))
        return out[0]

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
        """This state's constraint forces without the share of the managed
        contacts' unheld impulses [N or N m] (nv,), solved as MuJoCo will after
        the hook with the last step's contact forces held, less the active
        rows' response to their unheld part (module docstring);
        fixes the active rows for :meth:`solve` (module docstring). Needs
        this step's qfrc_actuator (mj_fwdActuation first)."""
        m, d = self.model, self.data
        n = int(d.nefc)
        self._old = (self._Js, self._Ainv, self._G)  # the last step's rows (held_change)
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
        return Qc - self._response(self._unheld)

    def solve(self, out: np.ndarray, rows: np.ndarray) -> None:
        """out = rows M_eff^-1 (each row y_i -> M_eff^-1 y_i, (k, nv)): MuJoCo's
        mj_solveM less the active constraint rows' response (module docstring)."""
        mujoco.mj_solveM(self.model, self.data, out, rows)
        if self._Js.shape[0]:
            out -= ((out @ self._Js.T) @ self._Ainv) @ self._G
        if self._S is not None:  # implicit damping / derivatives: the velocity change is S times M^-1's
            out[:] = out @ self._S.T

    def damped_share(self, J: np.ndarray, n: np.ndarray) -> float:
        """n.W n / n.W_0 n [-] of a pair (J (3, nv) its point Jacobian, n (3,) its
        normal): the velocity change along n the step gives an impulse along n
        (W, with the step's S, :meth:`solve`) over what the contact's own
        inertia would give (W_0, M_eff^-1 without S); 1 when the step's A is M.
        A damped link's contact sees the implicit damper as added inertia h B
        (engines.mujoco.adapter.DAMPED_SHARE_MIN)."""
        if self._S is None:
            return 1.0
        row = np.ascontiguousarray((n @ J).reshape(1, -1))
        out = np.zeros_like(row)
        mujoco.mj_solveM(self.model, self.data, out, row)
        if self._Js.shape[0]:
            out -= ((out @ self._Js.T) @ self._Ainv) @ self._G
        w0 = float(out[0] @ row[0])
        w = float((out[0] @ self._S.T) @ row[0])
        return w / w0 if w0 > 0.0 else 1.0

    def change(self) -> np.ndarray | None:
        """S M^-1 (Q(now) - Q(last)) [(nv,)]: the generalised acceleration by
        the known forces' change since the forces the last step's a_ext
        holds (None: the first step, after a jump, or no change). Computes
        this step's actuator forces in ``data`` (mj_fwdActuation) and fixes
        the active constraint rows (:meth:`constraint_now`)."""
        m, d = self.model, self.data
        self._S = self._step_response(d)
        user = self.user_now()
        last, self._user = self._last, user
        if m.nu:
            mujoco.mj_fwdActuation(m, d)
        Q = user + self.constraint_now() + self.passive[0]
        if last is None:
            return None
        if m.nu:
            Q += d.qfrc_actuator
        Q -= last
        if not np.any(Q):
            return None
        self.solve_free(self._dq, Q.reshape(1, -1))
        return self._dq[0].copy()

    def solve_free(self, out: np.ndarray, rows: np.ndarray) -> None:
        """out = rows M^-1, with the step's S (:class:`StepResponse`: implicit damping and derivatives) but
        without the constraint rows' response (the known forces' own change is solved so)."""
        mujoco.mj_solveM(self.model, self.data, out, rows)
        if self._S is not None:
            out[:] = out @ self._S.T

    def rk4_step(self) -> tuple[np.ndarray, list]:
        """After an RK4 ``mj_step``: the constraint forces of its four stages
        (4, nv) and the efc_type values of each stage's rows (4 frozensets)
        (stage 3's are still in ``data``)."""
        Qc = self.constraint.copy()
        Qc[3] = self.data.qfrc_constraint
        return Qc, self.row_types[:3] + [self._types]
