"""A robot model nobody here wrote, with MSF on every body-floor contact
(issue 13): load an MJCF file (e.g. ``pybullet_data/mjcf/ant.xml`` or
``humanoid.xml``), add a floor plane if it has none, exclude MuJoCo's own
contact between the floor and every body whose geoms would touch it, and
return one :class:`engines.base.PairSpec` per (geom, floor) with a law
built for the curvature MuJoCo's narrow phase will report there: a sphere
its radius, a capsule the sphere of its radius (MuJoCo reports a capsule on
a plane as its segment's end spheres), a box the sphere of its edge radius
(its corners). Other geoms (ellipsoids, cylinders, meshes) get a law for
their bounding sphere, which the adapter replaces at each contact by the
law for the curvature there (engines._narrow.LawBank; a contact no law can
carry, such as a cylinder standing on its flat end, is refused at run time
naming both geoms).
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from engines.base import PairSpec
from msf_contact.geometry import Curvature
from msf_contact.laws import make_law
from msf_contact.materials import ContactPair
from msf_contact.shapes import DEFAULT_EDGE_RADIUS

FLOOR = "floor"
#: ``load_with_msf_floor(mu=ENGINE_FRICTION)``: each foot's Coulomb cap is the
#: friction MuJoCo's own contact gives the (geom, floor) pair (:func:`engine_friction`),
#: as engines.pybullet.robots' default
ENGINE_FRICTION = "engine"


def engine_friction(m: mujoco.MjModel, g1: int, g2: int) -> float:
    """The sliding friction coefficient MuJoCo's own contact gives geoms ``g1``
    and ``g2`` [-]: the geom of higher ``priority``'s, the larger of the two at
    equal priority (MuJoCo's documentation, Modeling, "Contact parameters":
    friction is mixed by maximum). An explicit ``<pair>`` is not read (these
    pairs are MSF's, never MuJoCo's)."""
    p1, p2 = int(m.geom_priority[g1]), int(m.geom_priority[g2])
    f1, f2 = float(m.geom_friction[g1, 0]), float(m.geom_friction[g2, 0])
    return f1 if p1 > p2 else f2 if p2 > p1 else max(f1, f2)


def _collides(m: mujoco.MjModel, g1: int, g2: int) -> bool:
    return bool((m.geom_contype[g1] & m.geom_conaffinity[g2]) or (m.geom_contype[g2] & m.geom_conaffinity[g1]))


def load_with_msf_floor(path: str, pair: ContactPair, *, law: str = "msf", edge_radius: float = DEFAULT_EDGE_RADIUS,
                        floor_size: float = 50.0, mu: float | str | None = None, **law_options):
    """(model, data, pairs): the model at ``path`` with a floor geom named
    ``"floor"`` (added, a plane at z = 0, if missing), a free joint on every
    root body without a joint (as pybullet's ``loadMJCF`` makes it a free
    base: the ant's torso), MuJoCo's own contact
    with the floor excluded for every body that would touch it, and the MSF
    pairs (geom, "floor") with laws of ``law`` for ``pair`` (body 1 the
    robot's material, body 2 the floor's) and the curvature each geom shows
    the floor. ``mj_forward`` has been called. mu: the feet's Coulomb cap
    |F_t| <= mu F_n (``make_law(..., mu=)``): None (default) no cap, the
    paper's law; ENGINE_FRICTION the friction MuJoCo's own contact gives each
    (geom, floor) pair (:func:`engine_friction`: the ant's and the humanoid's
    feet 1.0); a number for every pair."""
    if not (mu is None or mu == ENGINE_FRICTION
            or (isinstance(mu, (int, float)) and not isinstance(mu, bool) and mu > 0 and np.isfinite(mu))):
        raise ValueError(f"mu = {mu!r} must be {ENGINE_FRICTION!r}, a finite number > 0 or None")
    spec = mujoco.MjSpec.from_file(str(path))
    for body in spec.worldbody.bodies:  # pybullet's loadMJCF makes a root body without joints a free base
        if not body.joints:
            body.add_freejoint()
    probe = spec.compile()
    if mujoco.mj_name2id(probe, mujoco.mjtObj.mjOBJ_GEOM, FLOOR) < 0:
        spec.worldbody.add_geom(name=FLOOR, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[floor_size, floor_size, 0.1],
                                contype=1, conaffinity=1)
        probe = spec.compile()
    fl = mujoco.mj_name2id(probe, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
    geoms, bodies = [], set()
    for g in range(probe.ngeom):
        b = int(probe.geom_bodyid[g])
        if b == 0 or not _collides(probe, g, fl):
            continue
        geoms.append(g)
        bodies.add(b)
    for b in sorted(bodies):
        spec.add_exclude(bodyname1="world", bodyname2=probe.body(b).name)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    laws: dict[tuple, object] = {}
    pairs = []
    fl = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
    for g in geoms:
        name = model.geom(g).name
        if not name:
            raise ValueError(f"geom {g} of {path} touches the floor but has no name (a PairSpec names its geoms)")
        t = int(model.geom_type[g])
        if t in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE):
            R = float(model.geom_size[g, 0])
        elif t == mujoco.mjtGeom.mjGEOM_BOX:
            R = min(edge_radius, float(min(model.geom_size[g, :3])))
        else:  # a placeholder: the adapter gives each contact the law for its point's curvature (LawBank)
            R = float(model.geom_rbound[g])
        m = engine_friction(model, g, fl) if mu == ENGINE_FRICTION else mu
        if m is not None and not m > 0.0:
            raise ValueError(f"geom {name!r}: MuJoCo's friction with the floor is {m!r}: give mu > 0 or None")
        opts = law_options if m is None else {**law_options, "mu": m}
        if (R, m) not in laws:
            laws[(R, m)] = make_law(law, pair, Curvature.sphere_on_plane(R), **opts)
        pairs.append(PairSpec(name, FLOOR, laws[(R, m)]))
    if not pairs:
        raise ValueError(f"no geom of {path} collides with the floor: nothing for MSF to do")
    return model, data, pairs


def mechanical_energy(model: mujoco.MjModel, data: mujoco.MjData, qvel=None) -> float:
    """Kinetic plus gravitational potential energy [J] at the current qpos
    and ``qvel`` (default ``data.qvel``; with MSF pass ``data.qvel -
    adapter.velocity_offset()``, the physical velocities), both of the same
    instant: ``mj_energyPos`` and ``mj_energyVel`` on a private MjData after
    ``mj_kinematics``, ``mj_comPos`` and ``mj_makeM`` (after ``mj_step``,
    ``data``'s own derived quantities are those of the step's start, so its
    potential energy would belong to the last state and the kinetic to this
    one). Joint springs' energy is in ``mj_energyPos``; MuJoCo's joint-limit
    constraints are not springs: :class:`RestEnergy` adds the work they did."""
    T, U, _ = _mechanical(model, data, qvel)
    return T + U


def _mechanical(model, data, qvel=None) -> tuple[float, float, float]:
    """(kinetic [J], potential energy [J], the power of the forces whose
    potential mj_energyPos counts [W]: gravity's on the whole model, M g .
    v_com, plus the springs', qfrc_spring . v, joints and tendons)."""
    s = mujoco.MjData(model)
    s.qpos[:] = data.qpos
    s.qvel[:] = data.qvel if qvel is None else qvel
    if model.nmocap:
        s.mocap_pos[:], s.mocap_quat[:] = data.mocap_pos, data.mocap_quat
    mujoco.mj_kinematics(model, s)
    mujoco.mj_comPos(model, s)
    mujoco.mj_makeM(model, s)
    mujoco.mj_comVel(model, s)
    mujoco.mj_subtreeVel(model, s)
    flags = model.opt.enableflags
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    try:
        mujoco.mj_energyPos(model, s)
        mujoco.mj_energyVel(model, s)
        power = float(np.sum(model.body_mass[1:]) * (model.opt.gravity @ s.subtree_linvel[0]))
        return float(s.energy[1]), float(s.energy[0]), power + _spring_power(model, s)
    finally:
        model.opt.enableflags = flags


def _spring_power(model, s) -> float:
    """qfrc_spring . qvel [W] of the private MjData ``s`` (kinematics done):
    the power of the joint and tendon springs, whose energy mj_energyPos
    counts. mj_passive computes them (with the process's mjcb_passive hook
    set aside: it is no part of this measure)."""
    if not (np.any(model.jnt_stiffness) or (model.ntendon and np.any(model.tendon_stiffness))):
        return 0.0
    if model.ntendon:
        mujoco.mj_tendon(model, s)
    passive_without_hook(model, s)
    return float(s.qfrc_spring @ s.qvel)


def passive_without_hook(model: mujoco.MjModel, s: mujoco.MjData) -> None:
    """``mj_passive`` on ``s`` with the process's ``mjcb_passive`` hook set
    aside (restored after, also on error): the model's own passive forces
    (qfrc_spring, qfrc_damper, ... (nv,)) without the managed contacts'."""
    hook = mujoco.get_mjcb_passive()
    mujoco.set_mjcb_passive(None)
    try:
        mujoco.mj_passive(model, s)
    finally:
        mujoco.set_mjcb_passive(hook)


def limit_force(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Generalised force of MuJoCo's joint-limit constraints [N or N m] (nv,):
    J^T f over the rows of type mjCNSTR_LIMIT_JOINT of ``data``'s last
    constraint solve (after ``mj_step`` under Euler, implicit or implicitfast:
    the force the step applied, solved at the step's start)."""
    return constraint_forces(model, data, {"limits": (mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT,)})["limits"]


#: MuJoCo's constraint rows by kind (``mjtConstraint``), as :class:`RestEnergy`
#: books their work: its limits (joints, tendons), its own contacts (between a
#: robot's own limbs, which MSF does not carry; a pair handed back to MuJoCo;
#: every contact of a model run with MuJoCo's contact) and the rest
#: (equality constraints, dof and tendon friction loss)
CONSTRAINT_KINDS = {
    "limits": (mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT, mujoco.mjtConstraint.mjCNSTR_LIMIT_TENDON),
    "contacts": (mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS, mujoco.mjtConstraint.mjCNSTR_CONTACT_PYRAMIDAL,
                 mujoco.mjtConstraint.mjCNSTR_CONTACT_ELLIPTIC),
    "other": (mujoco.mjtConstraint.mjCNSTR_EQUALITY, mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF,
              mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON),
}


def constraint_forces(model: mujoco.MjModel, data: mujoco.MjData, kinds=None) -> dict[str, np.ndarray]:
    """Generalised force of MuJoCo's constraints of each kind [N or N m]
    {kind: (nv,)}, J^T f over the rows of ``data``'s last constraint solve
    whose ``efc_type`` is one of the kind's (``kinds``: {name: types},
    default :data:`CONSTRAINT_KINDS`; their sum over all kinds is
    ``qfrc_constraint``). After ``mj_step`` under Euler, implicit or
    implicitfast: the forces the step applied, solved at the step's start."""
    kinds = CONSTRAINT_KINDS if kinds is None else kinds
    n = data.nefc
    out = {k: np.zeros(model.nv) for k in kinds}
    if n:
        typ = data.efc_type[:n]
        for k, types in kinds.items():
            on = np.isin(typ, np.asarray(types, dtype=typ.dtype))
            if np.any(on):
                mujoco.mj_mulJacTVec(model, data, out[k], np.where(on, data.efc_force[:n], 0.0))
    return out


#: A rest step may raise the energy account of :class:`RestEnergy` by this
#: share of the kinetic energy at its start (the contacts' own bound,
#: engines._contacts.state.ENERGY_GAIN_RTOL: the islands' check takes the same),
#: plus the semi-implicit Euler step's term of the potential forces, dt/2 |P_end -
#: P_start| with P their power, gravity's M g . v_com and the joint and tendon
#: springs' qfrc_spring . v (it moves the model by dt v_end, so the potential
#: energy leads the work done by those forces by exactly that much, as for
#: gravity in engines._contacts.balance; the springs' part was missing: a
#: humanoid lying on its joint springs, measured equal to the term to 1e-14 J,
#: issue 13). Measured: every rest
#: step of tests/test_robots_mujoco.py falls; the 1,000-step rests of
#: benchmarks/robots.py have steps above it (docs/engines.md, "Robot models").
REST_GAIN_RTOL = 1e-3
#: and the float rounding of the account's terms, relative to their size (a
#: pendulum held at rest by its limit: rises equal to the gravity term to 8e-16 J
#: of 11 J; two orders of magnitude of headroom over the double's 2.2e-16)
REST_ROUNDOFF = 1e-13


class RestEnergy:
    """The energy account of a model stepped with ``mj_step`` [J]: kinetic +
    gravitational (:func:`mechanical_energy`, physical velocities), plus the
    energy held in and exchanged by the MSF contacts
    (``ContactManager.stored_energy``), plus the energy MuJoCo's constraints
    have taken out of the mechanism (``absorbed``, minus the work of their
    forces; ``absorbed_by`` per kind of :data:`CONSTRAINT_KINDS`: its joint
    limits, its own contacts, which MSF does not carry (a humanoid's limbs
    touching each other: at rest after its torques its buttocks on a foot
    gave back up to 2.8e-5 J a step, the steps the account rose before it
    counted them, issue 13), the rest). With no actuator and no external
    force it changes only by dissipation (joint damping, the contacts'
    viscous and slip losses, the constraints' own net work) and the
    integrator's gravity term; a step that
    raises it beyond ``REST_GAIN_RTOL`` of the kinetic energy plus that term
    (and ``REST_ROUNDOFF``) is energy the account does not explain: listed
    in ``gains`` (step, rise [J], allowed [J]) and warned on stderr once.

    Why work and not a stored energy. MuJoCo's soft constraint (its
    documentation, Computation: "Soft constraint model") solves a limit row's
    force as f = (a_ref - a_u) / (A + R) with a_ref = -b J v - k d r, the
    regulariser R = (1 - d) / d A_hat and d the impedance of ``solimp``, which
    varies with the violation r: f depends on r, on J v and on a_u, the
    acceleration everything else gives the joint (gravity, the other
    constraints, the contacts, the drives). It is no potential force: 1/2 f r
    (what ``limit_energy`` read before) rose by up to 0.25 J a step in a
    humanoid at rest while kinetic + potential + contacts fell every step
    (its weight moved onto a limit raises f at the same r). What the limit
    exchanges with the mechanism is the work of f: under Euler, implicit and
    implicitfast ``mj_step`` applies the force solved at the step's start
    (``efc_force``: :func:`limit_force`) through v' = v + h M^-1 (... + J^T f),
    which changes the kinetic energy by h (J^T f) . (v + v') / 2 (M fixed over
    the step), the work added to ``absorbed`` with its sign reversed. RK4 solves the
    constraints at four stages, v' = v + h sum_j B_j M^-1 (... + Q_j), and
    ``data`` keeps only the last; the MSF adapter's hook, called at every
    stage, reads each stage's constraint force Q_j (``qfrc_constraint``,
    still in ``data`` at the next stage's hook: engines.mujoco._known), and
    their share of the step's kinetic-energy change is
    h (sum_j B_j Q_j) . (v + v') / 2 (M fixed over the step, as above; Euler's
    formula is the one-stage case). A stage whose rows are of several kinds
    cannot be split by kind: it is booked whole under "mixed" and the step
    listed in ``mixed``. RK4 needs that adapter (a MujocoAdapter with a pair
    read through Jacobians: a link, a box; without one use Euler, implicit or
    implicitfast), and ``update()`` right after each ``mj_step``.

    Use: ``acc = RestEnergy(model, data, adapter)`` before a step, then
    ``acc.update()`` after every ``mj_step`` (adapter None: no MSF)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, adapter=None):
        if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and getattr(adapter, "_known", None) is None:
            raise ValueError("integrator = RK4: its limit forces of four stages are not in data after mj_step; "
                             "they are read by a MujocoAdapter with a pair on a link or a box (its hook sees each "
                             f"stage), got adapter = {adapter!r}; without one use Euler, implicit or implicitfast "
                             "(model.opt.integrator)")
        self.model, self.data, self.adapter = model, data, adapter
        if adapter is not None:  # the physical velocities from the step replayed without its timing corrections
            adapter.exact_offset = True
        #: energy MuJoCo's constraints took out of the mechanism since the start, per kind of
        #: CONSTRAINT_KINDS [J] (under RK4 also "mixed": stages whose rows were of several kinds)
        self.absorbed_by = {k: 0.0 for k in CONSTRAINT_KINDS}
        self.absorbed = 0.0  #: their sum [J]
        self.mixed: list[int] = []  #: RK4 steps with a stage whose rows were of several kinds (booked whole)
        self.gains: list[tuple[int, float, float]] = []  #: (step, rise [J], allowed [J]) of unexplained rises
        self.steps = 0
        self._v = self._qvel()
        self.total = self._account(self._v)

    def _qvel(self) -> np.ndarray:
        """The physical velocities (nv,): data.qvel less the adapter's velocity_offset, which this
        account reads exactly (MujocoAdapter.exact_offset: the step replayed without its timing
        corrections; the end-pose formula read gymnasium's Ant-v5 (RK4) 0.26 J high in the step
        after its torso's landing, issue 13)."""
        v = self.data.qvel.copy()
        return v if self.adapter is None else v - self.adapter.velocity_offset()

    def _account(self, v) -> float:
        self.kinetic, U, self._power = _mechanical(self.model, self.data, v)
        self.mechanical = self.kinetic + U  #: kinetic + potential energy now [J]
        self.contacts = 0.0 if self.adapter is None else self.adapter.manager.stored_energy()  #: [J]
        return self.mechanical + self.contacts + self.absorbed

    def update(self) -> float:
        """After an ``mj_step``: the account now [J]; a rise beyond the bound is listed and warned."""
        v = self._qvel()
        vm = 0.5 * (self._v + v)
        forces = (self._rk4_constraint_forces() if self.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
                  else constraint_forces(self.model, self.data))
        for k, f in forces.items():
            self.absorbed_by[k] = self.absorbed_by.get(k, 0.0) - self.model.opt.timestep * float(f @ vm)
        self.absorbed = float(sum(self.absorbed_by.values()))
        T0, P0, before = self.kinetic, self._power, self.total
        self.total = self._account(v)
        self.steps += 1
        rise = self.total - before
        allowed = (REST_GAIN_RTOL * T0 + 0.5 * self.model.opt.timestep * abs(self._power - P0)
                   + REST_ROUNDOFF * (abs(self.mechanical) + abs(self.contacts) + abs(self.absorbed)))
        self._v = v
        if rise > allowed:
            self.gains.append((self.steps, rise, allowed))
            if len(self.gains) == 1:
                warnings.warn(f"energy at rest rose by {rise:.3g} J in step {self.steps} (allowed {allowed:.3g} J): "
                              "kinetic + potential + the MSF contacts' stored energy + the energy MuJoCo's "
                              "constraints took (engines.mujoco.robots.RestEnergy) is not explained by the account; warned "
                              "once, every such step is listed in RestEnergy.gains", RuntimeWarning, stacklevel=2)
        return self.total

    def _rk4_constraint_forces(self) -> dict[str, np.ndarray]:
        """sum_j B_j Q_j over the RK4 step just taken (class docstring), per kind of
        CONSTRAINT_KINDS [N or N m] {kind: (nv,)}: a stage's whole constraint force
        goes to the kind of its rows; a stage with rows of several kinds to "mixed"."""
        from engines.mujoco._stepping import RK4_B

        tracker = self.adapter._tracker
        if tracker.stage != 3 or float(self.data.time) != tracker.t0 + float(self.model.opt.timestep):
            raise RuntimeError("RestEnergy.update() under RK4 must follow each mj_step directly (the adapter "
                               "holds the constraint forces of the last step's stages only until the next call)")
        Qc, types = self.adapter._known.rk4_step()
        out = {k: np.zeros(self.model.nv) for k in CONSTRAINT_KINDS}
        for j, b in enumerate(RK4_B):
            kinds = [k for k, ts in CONSTRAINT_KINDS.items() if types[j] & {int(t) for t in ts}]
            if not kinds:  # no constraint row in that stage: no force
                continue
            if len(kinds) > 1 and (not self.mixed or self.mixed[-1] != self.steps + 1):
                self.mixed.append(self.steps + 1)
            key = kinds[0] if len(kinds) == 1 else "mixed"
            out[key] = out.get(key, np.zeros(self.model.nv)) + b * Qc[j]
        return out


__all__ = ["CONSTRAINT_KINDS", "ENGINE_FRICTION", "FLOOR", "REST_GAIN_RTOL", "RestEnergy", "constraint_forces", "limit_force",
           "engine_friction", "load_with_msf_floor", "mechanical_energy"]
