"""pybullet's own (built-in) contact, for comparison with the laws.

The same isolated impact as :func:`engines.pybullet.run_impact`, with the
pair's response left to pybullet. What the settings mean in pybullet 3.2.7
(each measured in ``tests/test_pybullet.py``):

- ``restitution``: pybullet multiplies the two bodies' values
  (``changeDynamics(restitution=...)``), so a ball of restitution 0.8 on a
  plate of the default 0 does not bounce at all. Given one number e here,
  both bodies get sqrt(e) and the pair's restitution is e; given a pair
  (e1, e2), the bodies get e1 and e2 as they are.
- Restitution is lost at small impact speed x time step (bullet3 #3094,
  #4428): the contact is created speculatively, before the surfaces touch
  (``contactProcessingThreshold``), and the solver's target for such a
  contact stops the body at the surface, discarding the restitution
  velocity; below ``restitutionVelocityThreshold`` (default 0.2 m/s) the
  restitution is set to zero; ``contactSlop`` shifts the surfaces. The
  settings that let a restitution act at all (:data:`RESTITUTION_ENGINE`,
  :data:`RESTITUTION_BODY`, after the maintainer's script in #3094 and the
  pybullet change log of PR #1701/#3096): ``restitutionVelocityThreshold=0``,
  ``contactSlop=0``, ``contactProcessingThreshold=0`` on both bodies, and
  ``contactERP=0`` (the position correction of the penetration reached
  within the first contact step otherwise adds a rebound that depends on
  where in the step the contact begins: e = 0.8 came out 0.80-0.88, measured;
  for maximal-coordinate bodies
  ``useSplitImpulse`` with a ``splitImpulsePenetrationThreshold`` above the
  penetration does the same). contactERP=0 leaves a penetration
  uncorrected: right for an isolated impact, not for resting contact.
- ``contact_stiffness`` k [N/m] and ``contact_damping`` d [N s/m]
  (``changeDynamics(contactStiffness, contactDamping)``): pybullet combines
  the two bodies' stiffnesses in series and adds their dampings (measured),
  so both bodies get 2k and d/2 and the pair has k and d: an implicit
  spring-damper (erp = dt k / (dt k + d), cfm = 1 / (dt k + d)).
- ``lateral_friction``: Coulomb friction coefficient of each body
  (``lateralFriction``; pybullet multiplies them too); default: pybullet's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as pb

from msf_contact._validate import check_finite, check_positive, check_range
from msf_contact.record import ImpactRecord

from . import scenes

#: Engine parameters that let a restitution act at all (module docstring).
RESTITUTION_ENGINE = {"restitutionVelocityThreshold": 0.0, "contactSlop": 0.0, "contactERP": 0.0}
#: Per-body setting that keeps speculative contacts from cancelling restitution (#3094, #3096).
RESTITUTION_BODY = {"contactProcessingThreshold": 0.0}


@dataclass(frozen=True)
class BuiltinContact:
    """pybullet's own contact parameters for one pair (module docstring).

    restitution: the pair's restitution e in [0, 1] (sqrt(e) on each body) or
        the two bodies' own values (e1, e2) [-]; None leaves pybullet's (0).
    contact_stiffness [N/m], contact_damping [N s/m]: the pair's spring and
        damper, both or neither.
    lateral_friction: each body's friction coefficient [-]; None leaves pybullet's.
    restitution_settings: apply :data:`RESTITUTION_ENGINE` and
        :data:`RESTITUTION_BODY` (False shows pybullet's default behaviour).
    """

    restitution: float | tuple[float, float] | None = None
    contact_stiffness: float | None = None
    contact_damping: float | None = None
    lateral_friction: float | None = None
    restitution_settings: bool = True

    def __post_init__(self):
        if self.restitution is not None:
            values = self.restitution if isinstance(self.restitution, tuple) else (self.restitution,)
            for e in values:
                check_range("restitution", e, 0.0, 1.0)
        if (self.contact_stiffness is None) != (self.contact_damping is None):
            raise ValueError(f"contact_stiffness = {self.contact_stiffness!r} and contact_damping = "
                             f"{self.contact_damping!r}: give both or neither (pybullet uses them together)")
        if self.contact_stiffness is not None:
            check_positive("contact_stiffness", self.contact_stiffness, unit="N/m")
            check_finite("contact_damping", self.contact_damping)
            if self.contact_damping < 0:
                raise ValueError(f"contact_damping = {self.contact_damping!r} N s/m must be >= 0")
        if self.lateral_friction is not None:
            check_finite("lateral_friction", self.lateral_friction)
            if self.lateral_friction < 0:
                raise ValueError(f"lateral_friction = {self.lateral_friction!r} must be >= 0")

    @staticmethod
    def of(d: dict | None) -> "BuiltinContact":
        """From the command line's dict (restitution, contact_stiffness, contact_damping, ...)."""
        d = dict(d or {})
        valid = ("restitution", "contact_stiffness", "contact_damping", "lateral_friction", "restitution_settings")
        bad = sorted(set(d) - set(valid))
        if bad:
            raise ValueError(f"unknown pybullet built-in setting(s) {bad}; valid: {', '.join(valid)}")
        return BuiltinContact(**d)

    def body_restitutions(self) -> tuple[float, float] | None:
        if self.restitution is None:
            return None
        if isinstance(self.restitution, tuple):
            if len(self.restitution) != 2:
                raise ValueError(f"restitution = {self.restitution!r}: give one number or two (body 1, body 2)")
            return float(self.restitution[0]), float(self.restitution[1])
        r = math.sqrt(float(self.restitution))
        return r, r


def apply(client: int, bodies, contact: BuiltinContact) -> None:
    """Set the contact parameters on both (body, link) of ``bodies`` and the
    engine parameters of the client."""
    if contact.restitution_settings:
        pb.setPhysicsEngineParameter(physicsClientId=client, **RESTITUTION_ENGINE)
    rest = contact.body_restitutions()
    for k, (uid, link) in enumerate(bodies):
        kw = {}
        if rest is not None:
            kw["restitution"] = rest[k]
        if contact.restitution_settings:
            kw.update(RESTITUTION_BODY)
        if contact.contact_stiffness is not None:
            kw.update(contactStiffness=2.0 * contact.contact_stiffness, contactDamping=0.5 * contact.contact_damping)
        if contact.lateral_friction is not None:
            kw["lateralFriction"] = contact.lateral_friction
        if kw:
            pb.changeDynamics(uid, link, physicsClientId=client, **kw)


def measure_impact(scene: scenes.Scene, contact: BuiltinContact, *, max_time: float,
                   after_steps: int = 2) -> ImpactRecord:
    """Step the scene with pybullet's own contact until the pair has touched
    and separated; return the impact record (pybullet's own quantities).

    cor_n and cor_t from the relative centre-of-mass velocities before and
    after (normal +z), tau from the steps with a non-zero normal force
    (``getContactPoints`` normalForce), tau1 until the normal velocity turns,
    x_max from the penetration (-contactDistance), F_max the largest normal
    force. max_time [s]: raise if the contact has not ended by then.
    """
    c, dt = scene.client, scene.dt
    (u1, l1), (u2, l2) = scene.body1, scene.body2

    def state():
        v1, w1 = pb.getBaseVelocity(u1, physicsClientId=c)
        v2, _ = pb.getBaseVelocity(u2, physicsClientId=c) if l2 == -1 else ((0, 0, 0), None)
        return np.subtract(v1, v2), np.asarray(w1, float)

    v_in, w_in = state()
    n = np.array([0.0, 0.0, 1.0])
    vn0 = -float(v_in @ n)
    vt_vec = v_in - (v_in @ n) * n
    vt0 = float(np.linalg.norm(vt_vec))
    t_dir = vt_vec / vt0 if vt0 > 0 else np.array([1.0, 0.0, 0.0])
    axis = np.cross(n, t_dir)
    steps = 0
    in_contact, done, since = False, False, 0
    n_force, k_first, k_turn = 0, None, None
    F_max, x_max = 0.0, 0.0
    limit = int(math.ceil(max_time / dt))
    while steps < limit:
        pb.stepSimulation(physicsClientId=c)
        steps += 1
        cps = pb.getContactPoints(u1, u2, l1, l2, physicsClientId=c)
        F = sum(cp[9] for cp in cps)
        pen = max([-cp[8] for cp in cps], default=0.0)
        v, _ = state()
        if F > 0:
            if k_first is None:
                k_first = steps
            in_contact = True
            n_force += 1
            F_max = max(F_max, F)
            x_max = max(x_max, pen)
            if k_turn is None and float(v @ n) >= 0:
                k_turn = steps
        elif in_contact:
            done = True
        if done:
            since += 1
            if since >= after_steps:
                break
    if not done:
        raise RuntimeError(f"pybullet's built-in contact did not end within max_time = {max_time!r} s "
                           f"({limit} steps of {dt!r} s)")
    v_out, w_out = state()
    v_out_n = float(v_out @ n)
    tau = n_force * dt
    tau1 = (k_turn - k_first + 1) * dt if k_turn is not None else tau
    m1 = pb.getDynamicsInfo(u1, l1, physicsClientId=c)[0]
    m2 = pb.getDynamicsInfo(u2, l2, physicsClientId=c)[0]
    m = m1 if m2 == 0 else m1 * m2 / (m1 + m2)
    params = {"law": "pybullet-builtin", "restitution": contact.restitution,
              "contact_stiffness": contact.contact_stiffness, "contact_damping": contact.contact_damping,
              "lateral_friction": contact.lateral_friction, "restitution_settings": contact.restitution_settings,
              "engine_settings": dict(RESTITUTION_ENGINE) if contact.restitution_settings else {},
              "body_settings": dict(RESTITUTION_BODY) if contact.restitution_settings else {}}
    return ImpactRecord(
        cor_n=max(v_out_n, 0.0) / vn0,
        cor_t=float(v_out @ t_dir) / vt0 if vt0 > 0 else None,
        cor_t_contact=None,
        cor_tau_ratio=tau1 / (tau - tau1) if tau > tau1 else 0.0,
        tau=tau, tau1=tau1, tau2=tau - tau1, x_max=x_max, F_max=F_max,
        Pc_max=None, Pc_at_Fmax=None,
        W_el_comp=None, W_visc_comp=None, W_el_rest=None, W_visc_rest=None,
        W_diss_n=0.5 * m * (vn0**2 - v_out_n**2), W_diss_t=None, Q_t=None,
        spin_in=float(w_in @ axis), spin_out=float(w_out @ axis), f_min=None, f_max=None,
        omega_x=None, omega_y=None, ended_by="overlap-zero", law="pybullet-builtin", engine="pybullet-builtin",
        dt=dt, parameters=params, inputs={"mass_reduced": m},
    )
