"""A robot model nobody here wrote in pybullet, with MSF on every body-floor
contact (issue 13): ``pybullet.loadMJCF`` of an MJCF file (e.g.
``pybullet_data/mjcf/ant.xml`` or ``humanoid.xml``), a floor plane added if
the file has none, and one :class:`engines.base.PairSpec` per (robot shape,
floor) with a law built for the curvature the floor sees there: a sphere its
radius, a capsule the sphere of its radius (on a plane it touches with its
end spheres, engines.pybullet.narrow), a box the sphere of its edge radius
(its corners).

pybullet cannot report the shapes of such a model: ``getCollisionShapeData``
ends the Python process (no exception) on a link whose capsule the MJCF gives
with ``fromto``, as every limb of the ant and the humanoid, and its MJCF
importer does not place all geoms where MuJoCo does (the humanoid's torso
geoms sit 0.12 m higher than in MuJoCo's compile of the same file). So the
shapes are measured from pybullet's own collision (:func:`probe_link_shapes`):
a plane is put around the link in 26 directions and ``getClosestPoints``
gives, per child shape, its exact support point (the convex-plane
algorithm, not GJK); with each child's kind and radius among the link's
visual shapes (sphere, capsule), the support points minus the radius along
the direction are the sphere's centre or the capsule's segment, fitted to
PROBE_ATOL.

pybullet's MJCF importer keeps a hinge's ``axis`` as written: its forward
dynamics moves the link with the joint speed times that vector (an axis
"-1 1 0" turns the link at sqrt(2) qdot rad/s), while the joint angle turns
it about the unit axis by q (measured, tests/test_robots_pybullet.py).
Velocity and position then disagree, so gravity and every contact do work
the motion does not account for: the ant (ankles "-1 1 0", "1 1 0") resting
on its feet at 1 ms gained 12 J in 0.4 s, the humanoid (shoulders "2 1 1",
elbows "0 -1 1", ...) struck the floor with a foot at 15.4 m/s under its
seeded torques. MuJoCo normalises every axis when it compiles the file, so
:func:`load_mjcf_with_msf_floor` loads a copy whose joint axes are made unit
(:func:`unit_joint_axes`), the model MuJoCo compiles.
"""

from __future__ import annotations

import itertools
import math
import os
import tempfile
import xml.etree.ElementTree as ET

import numpy as np
import pybullet as pb

from engines._contacts.state import ENERGY_GAIN_RTOL
from engines.base import PairSpec
from engines.pybullet.narrow import LinkShape
from msf_contact.curvature import tangent_basis
from msf_contact.geometry import Curvature
from msf_contact.laws import make_law
from msf_contact.materials import ContactPair
from msf_contact.shapes import DEFAULT_EDGE_RADIUS

#: A child shape's support points minus its radius must lie on its segment
#: (a capsule: of its length) or at one centre (a sphere) to this [m]:
#: pybullet stores sizes in float32 (measured residuals <= 7e-10 m on the ant
#: and the humanoid).
PROBE_ATOL = 1e-6
#: Distance of the probe plane from the link's centre of mass [m]: beyond any limb.
PROBE_DISTANCE = 10.0
_DIRECTIONS = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1)[:, None]


def _link_name(client: int, uid: int, link: int) -> str:
    if link < 0:
        return pb.getBodyInfo(uid, physicsClientId=client)[0].decode()
    return pb.getJointInfo(uid, link, physicsClientId=client)[12].decode()


def _inertial_frame(client: int, uid: int, link: int):
    if link < 0:
        pos, orn = pb.getBasePositionAndOrientation(uid, physicsClientId=client)
    else:
        st = pb.getLinkState(uid, link, computeForwardKinematics=1, physicsClientId=client)
        pos, orn = st[0], st[1]
    return np.asarray(pos, float), np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)


def _quat_z_to(v) -> list[float]:
    """The quaternion (x, y, z, w) turning +z onto the unit vector v."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, v)
    s, c = float(np.linalg.norm(axis)), float(z @ v)
    if s < 1e-12:
        return [0.0, 0.0, 0.0, 1.0] if c > 0 else [1.0, 0.0, 0.0, 0.0]
    half = 0.5 * math.atan2(s, c)
    return [*(axis / s * math.sin(half)), math.cos(half)]


def _candidates(client: int, uid: int, link: int) -> set:
    """(kind, radius, length) of the link's visual shapes (spheres, capsules)."""
    out = set()
    for v in pb.getVisualShapeData(uid, physicsClientId=client):
        if v[1] != link:
            continue
        if v[2] == pb.GEOM_SPHERE:
            out.add(("sphere", float(v[3][0]), 0.0))
        elif v[2] == pb.GEOM_CAPSULE:
            out.add(("capsule", float(v[3][1]), float(v[3][0])))
        else:
            raise ValueError(f"link {_link_name(client, uid, link)!r} (body {uid}, link {link}): a shape of geometry "
                             f"type {v[2]} cannot be measured from pybullet (spheres and capsules can): give its "
                             "shapes to PybulletAdapter(link_shapes=...) yourself")
    return out


def _supports(client: int, uid: int, link: int, com) -> np.ndarray:
    """Support points (children, 26, 3) [m] of the link's child shapes in _DIRECTIONS."""
    plane = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client),
                               basePosition=[0.0, 0.0, -1e3], physicsClientId=client)
    try:
        support = None
        for d in _DIRECTIONS:
            pb.resetBasePositionAndOrientation(plane, (com + PROBE_DISTANCE * d).tolist(), _quat_z_to(-d),
                                               physicsClientId=client)
            rows = pb.getClosestPoints(uid, plane, 10.0 * PROBE_DISTANCE, link, -1, physicsClientId=client)
            if support is None:
                support = [[] for _ in rows]
            if len(rows) != len(support):
                raise ValueError(f"link {_link_name(client, uid, link)!r}: pybullet listed {len(support)} shapes, "
                                 f"then {len(rows)}")
            for k, r in enumerate(rows):
                support[k].append(np.asarray(r[5], float))
    finally:
        pb.removeBody(plane, physicsClientId=client)
    return np.array(support, dtype=float).reshape(-1, len(_DIRECTIONS), 3)


def _fit(S, kind: str, r: float, L: float):
    """(residual [m], ends): the support points S (26, 3) as a sphere's
    centre or a capsule's segment of radius r, length L."""
    C = S - r * _DIRECTIONS
    D = np.linalg.norm(C[:, None] - C[None], axis=2)
    i, j = np.unravel_index(int(D.argmax()), D.shape)
    if kind == "sphere":
        return float(D.max()), (C.mean(axis=0), None)
    ax = (C[j] - C[i]) / D[i, j]
    t = (C - C[i]) @ ax
    off = float(np.max(np.linalg.norm(C - C[i] - np.outer(t, ax), axis=1)))
    return max(abs(float(D[i, j]) - L), off), (C[i], C[j])


def probe_link_shapes(client: int, uid: int, link: int) -> list[LinkShape]:
    """The sphere and capsule shapes of a link, measured from pybullet's own
    collision (module docstring), in the link's inertial frame; ValueError
    naming the link for any other kind or a fit beyond PROBE_ATOL."""
    cands = _candidates(client, uid, link)
    if not cands:
        return []
    com, rot = _inertial_frame(client, uid, link)
    out = []
    for S in _supports(client, uid, link, com):
        best = min(((_fit(S, *c), c) for c in sorted(cands)), key=lambda t: t[0][0])
        (res, (a, b)), (kind, r, L) = best
        if not res <= PROBE_ATOL:
            raise ValueError(f"link {_link_name(client, uid, link)!r} (body {uid}, link {link}): a shape pybullet "
                             f"collides is no sphere or capsule of the link's visual sizes (best fit off by {res:.3g} "
                             f"m > {PROBE_ATOL} m): give its shapes to PybulletAdapter(link_shapes=...) yourself")
        if kind == "sphere":
            out.append(LinkShape("sphere", np.array([r]), rot.T @ (a - com), np.eye(3)))
        else:
            axis = (b - a) / np.linalg.norm(b - a)
            t1, t2 = tangent_basis(axis)
            frame = np.column_stack([t1, t2, axis])
            out.append(LinkShape("capsule", np.array([r, 0.5 * L]), rot.T @ (0.5 * (a + b) - com), rot.T @ frame))
    return out


#: Share of a joint's range kept between its load position and a limit (place_joints_in_range).
RANGE_MARGIN = 0.1


def place_joints_in_range(client: int, uid: int) -> dict[int, float]:
    """Put every limited joint that loadMJCF left outside its range (it puts
    all joints at 0; the ant's ankles are limited to 30-100 degrees) at the
    point of its range nearest 0, RANGE_MARGIN of the range inside: pybullet
    pushes a joint beyond its limit back with its limit constraint, which
    adds energy with no contact at all (measured on the ant: +0.7 J per 10 ms
    step in flight). Returns {joint index: new position}."""
    moved = {}
    for j in range(pb.getNumJoints(uid, physicsClientId=client)):
        info = pb.getJointInfo(uid, j, physicsClientId=client)
        lo, hi = float(info[8]), float(info[9])
        if info[2] == pb.JOINT_FIXED or not lo < hi:
            continue
        q = pb.getJointState(uid, j, physicsClientId=client)[0]
        inside = min(max(q, lo + RANGE_MARGIN * (hi - lo)), hi - RANGE_MARGIN * (hi - lo))
        if not lo < q < hi:
            pb.resetJointState(uid, j, inside, 0.0, physicsClientId=client)
            moved[j] = inside
    return moved


#: A joint axis whose length differs from 1 by more than this is made unit
#: before loadMJCF (unit_joint_axes) [-]: far above the rounding of an axis
#: written to 17 digits, far below a length that changes the dynamics.
AXIS_RTOL = 1e-9


def unit_joint_axes(path: str) -> str | None:
    """The MJCF file at ``path`` with every ``<joint axis>`` (also in
    ``<default>``) scaled to unit length, as text; None if every axis is
    unit already (to AXIS_RTOL). ValueError naming the joint for a zero axis."""
    tree = ET.parse(str(path))
    changed = False
    for el in tree.getroot().iter("joint"):
        if "axis" not in el.attrib:
            continue
        a = np.array(el.get("axis").split(), dtype=float)
        n = float(np.linalg.norm(a))
        if a.shape != (3,) or not n > 0.0:
            raise ValueError(f"{path}: joint {el.get('name')!r} has axis {el.get('axis')!r}: give a non-zero 3-vector")
        if abs(n - 1.0) > AXIS_RTOL:
            el.set("axis", " ".join(repr(float(v)) for v in a / n))
            changed = True
    return ET.tostring(tree.getroot(), encoding="unicode") if changed else None


def load_mjcf(client: int, path: str) -> list[int]:
    """``pybullet.loadMJCF`` of the file at ``path`` with its joint axes made
    unit (module docstring): a copy in a temporary directory beside links to
    the entries of the file's own directory, so that the relative paths of
    its assets resolve as from the original; the file itself when every axis
    is unit. Returns loadMJCF's body unique ids."""
    text = unit_joint_axes(path)
    if text is None:
        return list(pb.loadMJCF(str(path), physicsClientId=client))
    src = os.path.dirname(os.path.abspath(str(path)))
    name = os.path.basename(str(path))
    with tempfile.TemporaryDirectory(prefix="msf_mjcf_") as tmp:
        for entry in os.listdir(src):
            if entry != name:
                os.symlink(os.path.join(src, entry), os.path.join(tmp, entry))
        copy = os.path.join(tmp, name)
        with open(copy, "w", encoding="utf-8") as f:
            f.write(text)
        return list(pb.loadMJCF(copy, physicsClientId=client))


#: The client's error reduction of non-contact constraints that
#: load_mjcf_with_msf_floor sets (``setPhysicsEngineParameter(erp=...)``) [-]:
#: none. pybullet pushes a joint that is beyond its limit back by erp times
#: its penetration per step, a velocity no force accounts for; under MSF
#: feet (internal approach integrated with the joint held, W = J M^-1 J^T)
#: that push is work the contacts never see. Measured on the ant standing on
#: its ankle limits at 10 ms (scripts/pybullet_robots.py ant-on-limits):
#: pybullet's default, the contacts' internal approach and the engine's
#: drift apart by up to 8 mm, a foot sinks 0.1 m unseen and the ant is
#: thrown (+1,000 J); with 0, the drift decays to 0.1 um and the ant rests.
#: The limit still stops a joint (its velocity into the limit is removed).
LIMIT_ERP = 0.0


#: ``load_mjcf_with_msf_floor(mu=ENGINE_FRICTION)``: each foot's Coulomb cap
#: is the friction pybullet's own contact gives the pair (engine_friction).
ENGINE_FRICTION = "engine"
#: Bullet's cap on a pair's combined friction (btManifoldResult::calculateCombinedFriction: MAX_FRICTION) [-].
BULLET_MAX_FRICTION = 10.0


def engine_friction(client: int, a: tuple[int, int], b: tuple[int, int]) -> float:
    """The friction coefficient pybullet's own contact uses between link
    ``a`` and link ``b`` ((body unique id, link index)): the product of their
    ``lateralFriction`` clamped to +-BULLET_MAX_FRICTION, as Bullet combines
    it (btManifoldResult::calculateCombinedFriction). loadMJCF sets a geom's
    ``lateralFriction`` to its MJCF ``friction``'s first value (the ant's
    feet 1.5; unset, as in humanoid.xml, Bullet's 0.5), a created plane has
    0.5: the ant's feet on the floor 0.75, the humanoid's 0.25."""
    fa = pb.getDynamicsInfo(a[0], a[1], physicsClientId=client)[1]
    fb = pb.getDynamicsInfo(b[0], b[1], physicsClientId=client)[1]
    return float(min(max(fa * fb, -BULLET_MAX_FRICTION), BULLET_MAX_FRICTION))


def load_mjcf_with_msf_floor(client: int, path: str, pair: ContactPair, *, law: str = "msf",
                             edge_radius: float = DEFAULT_EDGE_RADIUS, limit_erp: float | None = LIMIT_ERP,
                             mu: float | str | None = ENGINE_FRICTION, **law_options):
    """(robot uids, floor uid, pairs, link_shapes): the model at ``path``
    loaded into ``client`` by ``loadMJCF`` with its joint axes made unit
    (:func:`load_mjcf`), a floor plane (z = 0) added if
    the file has none, and the MSF pairs ((uid, link, k), (floor, -1)) with
    laws of ``law`` for ``pair`` (body 1 the robot's material, body 2 the
    floor's), one per robot shape (:func:`probe_link_shapes`), the curvature
    each shows the floor: a sphere its radius, a capsule the sphere of its
    radius. ``link_shapes`` is what
    :class:`engines.pybullet.adapter.PybulletAdapter` needs to know them:
    ``PybulletAdapter(client, pairs, link_shapes=link_shapes)``. The robots'
    joint motors are switched off (pybullet's default velocity motors hold
    every joint; the caller sets torques, as MuJoCo's motors do), and the
    joints loadMJCF left outside their range are put inside it
    (:func:`place_joints_in_range`). edge_radius: of box shapes (none in
    these files). limit_erp: the client's non-contact error reduction
    (LIMIT_ERP: none; it also applies to the user's createConstraint
    constraints; None leaves the client's as it is). mu: the feet's Coulomb
    cap |F_t| <= mu F_n (``make_law(..., mu=)``): ENGINE_FRICTION (default)
    the friction pybullet's own contact gives each (link, floor) pair
    (:func:`engine_friction`), a number for every pair, None for no cap (the
    paper's law: its no-slip Mindlin spring then holds whatever the legs
    load it with, 5-29 times the normal force on the ant's resting feet,
    docs/engines.md)."""
    if limit_erp is not None and not 0.0 <= limit_erp <= 1.0:
        raise ValueError(f"limit_erp = {limit_erp!r} must be in [0, 1] or None")
    if not (mu is None or mu == ENGINE_FRICTION
            or (isinstance(mu, (int, float)) and not isinstance(mu, bool) and mu > 0 and math.isfinite(mu))):
        raise ValueError(f"mu = {mu!r} must be {ENGINE_FRICTION!r}, a finite number > 0 or None")
    uids = load_mjcf(client, path)
    if limit_erp is not None:
        pb.setPhysicsEngineParameter(erp=float(limit_erp), physicsClientId=client)
    floor, robots = None, []
    for u in uids:
        shapes = pb.getVisualShapeData(u, physicsClientId=client)
        if (pb.getNumJoints(u, physicsClientId=client) == 0 and shapes and shapes[0][2] == pb.GEOM_PLANE
                and pb.getDynamicsInfo(u, -1, physicsClientId=client)[0] == 0.0):
            floor = u
        else:
            robots.append(u)
    if floor is None:
        floor = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client),
                                   physicsClientId=client)
    link_shapes: dict[tuple[int, int], list[LinkShape]] = {}
    for u in robots:
        nj = pb.getNumJoints(u, physicsClientId=client)
        pb.setJointMotorControlArray(u, list(range(nj)), pb.VELOCITY_CONTROL, forces=[0.0] * nj,
                                     physicsClientId=client)
        place_joints_in_range(client, u)
        for link in range(-1, nj):
            shapes = probe_link_shapes(client, u, link)
            if shapes:
                link_shapes[(u, link)] = shapes
    laws: dict[tuple, object] = {}
    pairs = []
    for (u, link), shapes in link_shapes.items():
        m = engine_friction(client, (u, link), (floor, -1)) if mu == ENGINE_FRICTION else mu
        if m is not None and not m > 0.0:
            raise ValueError(f"link {_link_name(client, u, link)!r} (body {u}, link {link}): pybullet's friction "
                             f"with the floor is {m!r}: give mu > 0 or None")
        for k, s in enumerate(shapes):
            R = float(s.size[0]) if s.kind in ("sphere", "capsule") else min(edge_radius, float(np.min(s.size)))
            if (R, m) not in laws:
                laws[(R, m)] = make_law(law, pair, Curvature.sphere_on_plane(R), mu=m, **law_options)
            pairs.append(PairSpec((u, link, k), (floor, -1), laws[(R, m)]))
    if not pairs:
        raise ValueError(f"no shape of {path} collides with the floor: nothing for MSF to do")
    return robots, floor, pairs, link_shapes


def motor_torque_limits(path: str) -> dict[str, float]:
    """{joint name: largest motor torque [N m]} of the MJCF file's
    ``<actuator><motor joint gear ctrlrange>`` (gear times the larger
    |ctrlrange| bound; ctrlrange from the motor or the top-level
    ``<default><motor>``, else 1): what MuJoCo's motors apply at full
    control, for driving the same joints in pybullet (loadMJCF imports no
    actuator)."""
    root = ET.parse(str(path)).getroot()
    default = root.find("default/motor")
    base = default.get("ctrlrange") if default is not None else None
    out = {}
    for m in root.iter("motor"):
        if m.get("joint") is None:
            continue
        rng = m.get("ctrlrange", base)
        bound = max(abs(float(v)) for v in rng.split()) if rng else 1.0
        out[m.get("joint")] = float(m.get("gear", "1").split()[0]) * bound
    return out


def mechanical_energy(client: int, uids) -> float:
    """Kinetic plus gravitational potential energy [J] of the bodies ``uids``
    (every link: 1/2 m v^2 + 1/2 w.I w - m g.z, world inertia from the
    inertial frame's principal axes)."""
    T, U, _ = _mechanical(client, uids)
    return T + U


def _mechanical(client: int, uids) -> tuple[float, float, float]:
    """(kinetic [J], gravitational potential energy [J], gravity's power on the bodies sum m g . v [W])."""
    g = np.array([pb.getPhysicsEngineParameters(physicsClientId=client)[k]
                  for k in ("gravityAccelerationX", "gravityAccelerationY", "gravityAccelerationZ")])
    T = U = P = 0.0
    for u in uids:
        nj = pb.getNumJoints(u, physicsClientId=client)
        states = [(*pb.getBasePositionAndOrientation(u, physicsClientId=client),
                   *pb.getBaseVelocity(u, physicsClientId=client))]
        if nj:
            for st in pb.getLinkStates(u, list(range(nj)), computeLinkVelocity=1, physicsClientId=client):
                states.append((st[0], st[1], st[6], st[7]))
        for link, (pos, orn, v, w) in zip(range(-1, nj), states):
            info = pb.getDynamicsInfo(u, link, physicsClientId=client)
            m, I = info[0], np.asarray(info[2], float)
            R = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
            wb = R.T @ np.asarray(w, float)
            v = np.asarray(v, float)
            T += 0.5 * m * v @ v + 0.5 * wb @ (I * wb)
            U -= m * g @ np.asarray(pos, float)
            P += m * g @ v
    return float(T), float(U), float(P)


#: A rest step may raise the account of :class:`RestEnergy` by this share of
#: the kinetic energy at its start (the contacts' own bound,
#: engines._contacts.state.ENERGY_GAIN_RTOL, as engines.mujoco.robots.RestEnergy),
#: plus, for the whole account, the semi-implicit Euler step's gravity term
#: dt/2 |M g . dv_com| (it moves the bodies by dt v_end: the potential energy
#: leads the work gravity did by that much, engines._contacts.balance).
REST_GAIN_RTOL = ENERGY_GAIN_RTOL
#: and the float rounding of the account's terms relative to their size
#: (engines.mujoco.robots.REST_ROUNDOFF: two orders above the double's 2.2e-16).
REST_ROUNDOFF = 1e-13


class RestEnergy:
    """The energy account of robots stepped by a
    :class:`engines.pybullet.adapter.PybulletAdapter` [J], and who moved it.

    ``total``: kinetic + gravitational energy of the bodies ``uids``
    (:func:`mechanical_energy`) plus the energy held in and exchanged by the MSF
    contacts (``ContactManager.stored_energy``). ``engine_added``: what
    pybullet's steps gave the bodies beyond the work of the MSF loads
    (:meth:`PybulletAdapter.last_step_work`), summed: the work of its
    joint-limit constraint impulses (pybullet does not report them: its
    joint force-torque sensor gives no torque about a limited hinge's axis),
    of its damping (a loss), of any motor or user force, the semi-implicit
    step's gravity term and its integration error on turning links (a turning
    link's new orientation, taken from the step's new velocity, enters its
    inertia and Jacobians: the work of a force on it comes out a few % off,
    :meth:`PybulletAdapter.last_step_work`). ``contacts = total -
    engine_added``: the MSF contacts' own balance, what they stored and
    exchanged against the work their loads did in the engine; with the
    adapter's inverse inertias right it changes only by the contacts'
    viscous and slip losses (falls).

    With no torque and no external force, a step that raises ``total`` by
    more than REST_GAIN_RTOL of the kinetic energy at its start plus the
    gravity term dt/2 |M g . dv_com| (and REST_ROUNDOFF) is listed in
    ``gains`` (step, rise [J], allowed [J], engine's part [J]); a step that
    raises ``contacts`` beyond REST_GAIN_RTOL of the kinetic energy (and
    REST_ROUNDOFF) in ``contact_gains`` (step, rise, allowed). MuJoCo's
    counterpart, engines.mujoco.robots.RestEnergy, reads its limit forces and
    counts their work; pybullet's are only in ``engine_added``.

    Use: ``acc = RestEnergy(adapter, uids)`` before a step, ``acc.update()``
    right after every ``adapter.step()``."""

    def __init__(self, adapter, uids):
        self.adapter, self.uids = adapter, [int(u) for u in uids]
        self.client = adapter.client
        self.dt = adapter.timestep
        self.engine_added = 0.0  #: energy pybullet's steps added beyond the MSF loads' work since the start [J]
        self.gains: list[tuple[int, float, float, float]] = []  #: (step, rise, allowed, engine's part) [J]
        self.contact_gains: list[tuple[int, float, float]] = []  #: (step, rise, allowed) of ``contacts`` [J]
        self.steps = 0
        self._read()

    def _read(self) -> None:
        self.kinetic, U, self._power = _mechanical(self.client, self.uids)
        self.mechanical = self.kinetic + U  #: kinetic + potential energy now [J]
        self.stored = self.adapter.manager.stored_energy()  #: the contacts' [J]
        self.total = self.mechanical + self.stored  #: the account [J]
        self.contacts = self.total - self.engine_added  #: the MSF contacts' own balance [J]

    def update(self) -> float:
        """After an ``adapter.step()``: the account now [J]; rises beyond the bounds listed."""
        W = self.adapter.last_step_work(self.uids)
        T0, P0, E0, tot0, con0 = self.kinetic, self._power, self.mechanical, self.total, self.contacts
        self._read()
        d_engine = (self.mechanical - E0) - W
        self.engine_added += d_engine
        self.contacts = self.total - self.engine_added
        self.steps += 1
        round_off = REST_ROUNDOFF * (abs(self.mechanical) + abs(self.stored) + abs(self.engine_added))
        allowed = REST_GAIN_RTOL * T0 + 0.5 * self.dt * abs(self._power - P0) + round_off
        if self.total - tot0 > allowed:
            self.gains.append((self.steps, self.total - tot0, allowed, d_engine))
        allowed_c = REST_GAIN_RTOL * T0 + round_off
        if self.contacts - con0 > allowed_c:
            self.contact_gains.append((self.steps, self.contacts - con0, allowed_c))
        return self.total


__all__ = ["ENGINE_FRICTION", "REST_GAIN_RTOL", "RestEnergy", "engine_friction", "load_mjcf",
           "load_mjcf_with_msf_floor", "mechanical_energy",
           "motor_torque_limits", "place_joints_in_range", "probe_link_shapes", "unit_joint_axes"]
