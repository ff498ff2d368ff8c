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

import mujoco
import numpy as np

from engines.base import PairSpec
from msf_contact.geometry import Curvature
from msf_contact.laws import make_law
from msf_contact.materials import ContactPair
from msf_contact.shapes import DEFAULT_EDGE_RADIUS

FLOOR = "floor"


def _collides(m: mujoco.MjModel, g1: int, g2: int) -> bool:
    return bool((m.geom_contype[g1] & m.geom_conaffinity[g2]) or (m.geom_contype[g2] & m.geom_conaffinity[g1]))


def load_with_msf_floor(path: str, pair: ContactPair, *, law: str = "msf", edge_radius: float = DEFAULT_EDGE_RADIUS,
                        floor_size: float = 50.0, **law_options):
    """(model, data, pairs): the model at ``path`` with a floor geom named
    ``"floor"`` (added, a plane at z = 0, if missing), a free joint on every
    root body without a joint (as pybullet's ``loadMJCF`` makes it a free
    base: the ant's torso), MuJoCo's own contact
    with the floor excluded for every body that would touch it, and the MSF
    pairs (geom, "floor") with laws of ``law`` for ``pair`` (body 1 the
    robot's material, body 2 the floor's) and the curvature each geom shows
    the floor. ``mj_forward`` has been called."""
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
    laws: dict[float, object] = {}
    pairs = []
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
        if R not in laws:
            laws[R] = make_law(law, pair, Curvature.sphere_on_plane(R), **law_options)
        pairs.append(PairSpec(name, FLOOR, laws[R]))
    if not pairs:
        raise ValueError(f"no geom of {path} collides with the floor: nothing for MSF to do")
    return model, data, pairs


def mechanical_energy(model: mujoco.MjModel, data: mujoco.MjData, qvel=None, *, limits: bool = False) -> float:
    """Kinetic plus gravitational potential energy [J] at the current qpos
    and ``qvel`` (default ``data.qvel``; with MSF pass ``data.qvel -
    adapter.velocity_offset()``, the physical velocities), both of the same
    instant: ``mj_energyPos`` and ``mj_energyVel`` on a private MjData after
    ``mj_kinematics``, ``mj_comPos`` and ``mj_makeM`` (after ``mj_step``,
    ``data``'s own derived quantities are those of the step's start, so its
    potential energy would belong to the last state and the kinetic to this one).

    limits: add the energy held in MuJoCo's joint-limit constraints
    (:func:`limit_energy`), so a limit that pushes a link back gives back
    what it stored rather than appearing as a gain."""
    s = mujoco.MjData(model)
    s.qpos[:] = data.qpos
    s.qvel[:] = data.qvel if qvel is None else qvel
    if model.nmocap:
        s.mocap_pos[:], s.mocap_quat[:] = data.mocap_pos, data.mocap_quat
    if limits:
        mujoco.mj_fwdPosition(model, s)  # kinematics, com, M and the constraints at this qpos
    else:
        mujoco.mj_kinematics(model, s)
        mujoco.mj_comPos(model, s)
        mujoco.mj_makeM(model, s)
    flags = model.opt.enableflags
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    try:
        mujoco.mj_energyPos(model, s)
        mujoco.mj_energyVel(model, s)
        return float(s.energy[0] + s.energy[1]) + (_limit_energy(model, s) if limits else 0.0)
    finally:
        model.opt.enableflags = flags


def limit_energy(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Energy [J] held in MuJoCo's joint-limit constraints at ``data``'s qpos:
    per violated limit row (``efc_type`` mjCNSTR_LIMIT_JOINT, r = efc_pos -
    efc_margin < 0), 1/2 D K d r^2 with K the reference acceleration's
    stiffness and d the impedance (``efc_KBIP[:, 0]`` and ``[:, 2]``, from
    the joint's ``solref``, 0.02 s for the ant, and ``solimp``) and D = 1/R
    the constraint's mass (``efc_D``): MuJoCo's soft constraint at rest
    pushes with D a_ref = -D K d r (``efc_aref``; its documentation,
    "Computation: soft constraints"), a spring of stiffness D K d in the
    joint's own units. d varies with r across solimp's width (0.001 rad by
    default), so this is the spring's energy at the current stiffness, not
    an exact potential (a pendulum held by its limit: 1/2 f r of the
    solver's own force to 1e-3). On a private MjData after ``mj_fwdPosition``."""
    s = mujoco.MjData(model)
    s.qpos[:] = data.qpos
    if model.nmocap:
        s.mocap_pos[:], s.mocap_quat[:] = data.mocap_pos, data.mocap_quat
    mujoco.mj_fwdPosition(model, s)
    return _limit_energy(model, s)


def _limit_energy(model: mujoco.MjModel, s: mujoco.MjData) -> float:
    n = s.nefc
    if n == 0:
        return 0.0
    rows = s.efc_type[:n] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
    r = s.efc_pos[:n] - s.efc_margin[:n]
    rows &= r < 0.0
    kbip = s.efc_KBIP[:n][rows]
    return float(0.5 * np.sum(s.efc_D[:n][rows] * kbip[:, 0] * kbip[:, 2] * r[rows] ** 2))


__all__ = ["FLOOR", "limit_energy", "load_with_msf_floor", "mechanical_energy"]
