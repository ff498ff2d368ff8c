"""Models nobody here wrote (issue 13): ``ant.xml`` and ``humanoid.xml``
from ``pybullet_data/mjcf`` in pybullet (``loadMJCF``) at the files' time
steps, MSF on every body-floor contact (engines.pybullet.robots), under
seeded random torques, then with the torques off. The suite runs a short
stretch (each robot starts with its lowest shape 5 mm above the floor so
that it lands within it); the 1,000-step runs, the energy at rest and the
cost against pybullet's own contact are benchmarks/robots_pybullet.py (make
bench). The shapes are measured from pybullet's own collision
(probe_link_shapes), checked here against getClosestPoints; the energy of
the multibody contact path on a jointed dumbbell."""

import os

import numpy as np
import pytest

from msf_contact import ContactPair, preset

pb = pytest.importorskip("pybullet")
pybullet_data = pytest.importorskip("pybullet_data")
pytestmark = pytest.mark.pybullet

from engines._contacts.state import ENERGY_GAIN_RTOL  # noqa: E402
from engines.pybullet import scenes  # noqa: E402
from engines.pybullet.adapter import PybulletAdapter  # noqa: E402
from engines.pybullet.robots import (  # noqa: E402
    ENGINE_FRICTION,
    REST_ROUNDOFF,
    RestEnergy,
    load_mjcf,
    load_mjcf_with_msf_floor,
    mechanical_energy,
    motor_torque_limits,
    probe_link_shapes,
)

SEED = 13
#: A floating-base multibody's contacts (engines/pybullet/adapter.py: W = J
#: M^-1 J^T through pybullet's Jacobians and mass matrix, the contacts of one
#: multibody coupled): kinetic energy plus the contacts' stored elastic work
#: may exceed the energy before the impact by float rounding only (measured:
#: never above, at 1 and 0.1-0.2 ms).
ENERGY_RTOL = 1e-9
#: The time steps of the files (<option timestep>): ant 10 ms, humanoid 2 ms.
DT = {"ant.xml": 0.01, "humanoid.xml": 0.002}
#: The measured shapes must give pybullet's own distance to a plane to this
#: [m] (float32 sizes; measured <= 1e-9 m).
SHAPE_ATOL = 1e-7


def _path(name):
    return os.path.join(pybullet_data.getDataPath(), "mjcf", name)


def _load_ant(c, mu=ENGINE_FRICTION):
    """ant.xml in client c with MSF feet (natural rubber on steel; their Coulomb
    cap load_mjcf_with_msf_floor(mu=)): its body id, the floor's, pairs, shapes."""
    robots, floor, pairs, shapes = load_mjcf_with_msf_floor(c, _path("ant.xml"),
                                                            ContactPair(preset("natural-rubber"), preset("steel")),
                                                            mu=mu)
    return robots[0], floor, pairs, shapes


def _put_down(c, u, floor, height):
    """Move body u vertically so that its lowest point is ``height`` [m] above the floor."""
    gap = min(r[8] for r in pb.getClosestPoints(u, floor, 10.0, physicsClientId=c))
    pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
    pb.resetBasePositionAndOrientation(u, [pos[0], pos[1], pos[2] - gap + height], orn, physicsClientId=c)


def test_measured_shapes_give_pybullets_own_distances():
    """Every capsule and sphere the probe measures on the humanoid, placed
    in the world, is as far from a tilted plane as pybullet says (the
    lowest shape of each link: getClosestPoints' nearest row)."""
    c = scenes.new_client(DT["humanoid.xml"])
    try:
        robots, floor, pairs, shapes = load_mjcf_with_msf_floor(c, _path("humanoid.xml"),
                                                                ContactPair(preset("natural-rubber"), preset("steel")))
        n = np.array([0.2, -0.1, 1.0]) / np.linalg.norm([0.2, -0.1, 1.0])
        q = pb.getQuaternionFromAxisAngle(np.cross([0, 0, 1.0], n).tolist(), float(np.arccos(n[2])))
        pb.resetBasePositionAndOrientation(floor, [0, 0, 0.05], q, physicsClientId=c)
        for (u, link), sh in shapes.items():
            assert probe_link_shapes(c, u, link)[0].kind == sh[0].kind
            if link < 0:
                pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
            else:
                pos, orn = pb.getLinkState(u, link, physicsClientId=c)[:2]
            R = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
            ours = []
            for s in sh:
                centre, axis = np.asarray(pos) + R @ s.pos, R @ s.rot[:, 2]
                lift = 0.0 if s.kind == "sphere" else abs(axis @ n) * s.size[1]
                ours.append((centre - np.array([0, 0, 0.05])) @ n - lift - s.size[0])
            rows = pb.getClosestPoints(u, floor, 10.0, link, -1, physicsClientId=c)
            assert abs(min(ours) - min(r[8] for r in rows)) < SHAPE_ATOL, (u, link)
    finally:
        pb.disconnect(c)


@pytest.mark.parametrize("name,torque_steps,rest_steps", [("ant.xml", 15, 20), ("humanoid.xml", 25, 25)])
def test_robot_model_runs_under_seeded_torques(name, torque_steps, rest_steps):
    """Seeded torques (each motor's MJCF range), then none: no exception, no
    state jump, a finite state, MSF carrying the robot on the floor (the
    robot starts with its lowest shape 5 mm above the floor, so that it lands
    at once). The energy at rest: test_the_ant_rests_on_its_feet_without_energy_gain."""
    drop = 0.005
    c = scenes.new_client(DT[name], gravity=9.81)
    try:
        robots, floor, pairs, shapes = load_mjcf_with_msf_floor(c, _path(name),
                                                                ContactPair(preset("natural-rubber"), preset("steel")))
        u = robots[0]
        if drop:  # the lowest shape `drop` above the floor
            _put_down(c, u, floor, drop)
        limits = motor_torque_limits(_path(name))
        joints = [j for j in range(pb.getNumJoints(u, physicsClientId=c))
                  if pb.getJointInfo(u, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
        bound = np.array([limits.get(pb.getJointInfo(u, j, physicsClientId=c)[1].decode(), 0.0) for j in joints])
        assert np.count_nonzero(bound) == len(limits)  # every MJCF motor drives a pybullet joint
        adapter = PybulletAdapter(c, pairs, link_shapes=shapes)
        rng = np.random.default_rng(SEED)
        touching = 0
        for _ in range(torque_steps):
            pb.setJointMotorControlArray(u, joints, pb.TORQUE_CONTROL,
                                         forces=(rng.uniform(-1, 1, len(joints)) * bound).tolist(),
                                         physicsClientId=c)
            adapter.step()
            touching = max(touching, int(adapter.manager.active.sum()))
        pb.setJointMotorControlArray(u, joints, pb.TORQUE_CONTROL, forces=[0.0] * len(joints), physicsClientId=c)
        for _ in range(rest_steps):
            adapter.step()
            touching = max(touching, int(adapter.manager.active.sum()))
        assert adapter.jumps == 0
        assert np.all(np.isfinite(pb.getBasePositionAndOrientation(u, physicsClientId=c)[0]))
        assert touching > 0  # MSF carries the robot on the floor
    finally:
        pb.disconnect(c)


@pytest.mark.parametrize("dt,tilt", [(1e-3, 0.0), (1e-3, 0.02), (2e-4, 0.02)])
def test_a_jointed_dumbbell_bounces_without_energy_gain(dt, tilt):
    """A floating-base multibody, two spheres (R 20 mm, 1 kg each) 0.2 m
    apart joined by a free hinge, dropped on a steel plane at 1 m/s, flat or
    with one end 20 mm lower: both spheres are links of one multibody (their
    contacts coupled through its mass matrix). Kinetic energy plus the
    contacts' elastic work never exceeds the energy before; each bounce's COR
    is the free rubber sphere's within 1 % (measured 0.7261-0.7315, the
    free sphere 0.7275)."""
    from msf_contact import Curvature, make_law
    from engines.base import PairSpec

    c = scenes.new_client(dt)
    try:
        plane = scenes.add_plate(c)
        R = 0.02
        s = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c)
        orn = pb.getQuaternionFromEuler([0, float(np.arctan(tilt / 0.2)), 0])
        u = pb.createMultiBody(1.0, s, basePosition=[0, 0, R + 1e-4 + tilt], baseOrientation=orn,
                               linkMasses=[1.0], linkCollisionShapeIndices=[s], linkVisualShapeIndices=[-1],
                               linkPositions=[[0.2, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                               linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                               linkParentIndices=[0], linkJointTypes=[pb.JOINT_REVOLUTE], linkJointAxis=[[0, 1, 0]],
                               physicsClientId=c)
        for link in (-1, 0):
            pb.changeDynamics(u, link, linearDamping=0, angularDamping=0, jointDamping=0,
                              localInertiaDiagonal=[1.6e-4] * 3, physicsClientId=c)
        pb.setJointMotorControl2(u, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=c)
        pb.resetBaseVelocity(u, [0, 0, -1.0], [0, 0, 0], physicsClientId=c)
        law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law), PairSpec((u, 0), (plane, -1), law)])
        E0 = mechanical_energy(c, [u])
        for _ in range(int(0.05 / dt)):
            ad.step()
            E = mechanical_energy(c, [u]) + float(np.sum(ad.manager.W_el[ad.manager.active]))
            assert E <= E0 * (1 + ENERGY_RTOL)
        assert len(ad.records) == 2
        assert all(abs(r.cor_n / 0.7275 - 1) < 1e-2 for r in ad.records)
    finally:
        pb.disconnect(c)


def test_a_floating_multibody_with_only_fixed_joints_is_refused_saying_what_works():
    c = scenes.new_client(1e-3)
    try:
        plane = scenes.add_plate(c)
        s = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.02, physicsClientId=c)
        u = pb.createMultiBody(1.0, s, basePosition=[0, 0, 0.1], linkMasses=[1.0], linkCollisionShapeIndices=[s],
                               linkVisualShapeIndices=[-1], linkPositions=[[0.2, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                               linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                               linkParentIndices=[0], linkJointTypes=[pb.JOINT_FIXED], linkJointAxis=[[0, 0, 1]],
                               physicsClientId=c)
        from msf_contact import Curvature, make_law
        from engines.base import PairSpec

        law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
        with pytest.raises(ValueError, match=r"body \d+ is a floating multibody whose 1 joints are all fixed.*"
                                             r"compound collision shape"):
            PybulletAdapter(c, [PairSpec((u, 0), (plane, -1), law)])
    finally:
        pb.disconnect(c)


#: The velocity change pybullet gives a link point for an impulse, against
#: J M^-1 J^T P (the adapter's W): float rounding of a 182 kg multibody's
#: dynamics [m/s] (measured <= 2.1e-11 m/s on dv up to 1.9e-4 m/s).
IMPULSE_ATOL = 1e-8


def test_an_impulse_on_the_ant_moves_its_points_by_its_inverse_inertia():
    """The ant (floating base, 8 hinges) in the air, gravity off, its joints
    inside their ranges: a force at a point of the torso, a foot and an
    ankle for one step changes that point's velocity by W F dt, W = J M^-1
    J^T the adapter's inverse inertia (PybulletAdapter._inverse_inertia)."""
    dt = 1e-3
    c = scenes.new_client(dt)
    try:
        u, floor, pairs, shapes = _load_ant(c)
        for j in range(pb.getNumJoints(u, physicsClientId=c)):
            info = pb.getJointInfo(u, j, physicsClientId=c)
            if info[2] != pb.JOINT_FIXED:
                pb.resetJointState(u, j, 0.5 * (info[8] + info[9]), 0.0, physicsClientId=c)
        ad = PybulletAdapter(c, pairs, link_shapes=shapes)
        F = np.array([3.0, -2.0, 5.0])
        for i in (0, 5, 11):
            bodies = ad._read_bodies()
            j1, j2 = ad._slot[i]
            pose = bodies.pose(j1)
            point = pose.com + np.array([0.01, -0.02, -0.03])
            W, _ = ad._inverse_inertia(i, (pose, bodies.pose(j2)), point)
            v0 = pose.v + np.cross(pose.w, point - pose.com)
            (uid, link), _ = ad._bodies[i]
            pb.applyExternalForce(uid, link, F.tolist(), point.tolist(), pb.WORLD_FRAME, physicsClientId=c)
            pb.stepSimulation(physicsClientId=c)
            after = ad._read_bodies().pose(j1)
            v1 = after.v + np.cross(after.w, point - after.com)
            assert np.allclose(v1 - v0, W @ F * dt, rtol=0, atol=IMPULSE_ATOL), (i, v1 - v0, W @ F * dt)
            ad._steps += 1  # the adapter's per-step caches belong to the next state
            pb.resetBaseVelocity(u, [0, 0, 0], [0, 0, 0], physicsClientId=c)
            for j in range(pb.getNumJoints(u, physicsClientId=c)):
                pb.resetJointState(u, j, pb.getJointState(u, j, physicsClientId=c)[0], 0.0, physicsClientId=c)
    finally:
        pb.disconnect(c)


#: Every hinge of the loaded models must turn its link at qdot = 1 rad/s about
#: its unit axis to this [rad/s]: pybullet keeps the axis in float32 (measured
#: 1.7e-8 off); pybullet's own loadMJCF of the ant turns an ankle at sqrt(2).
AXIS_SPEED_ATOL = 1e-6


@pytest.mark.parametrize("name", ["ant.xml", "humanoid.xml"])
def test_every_hinge_turns_its_link_at_its_joint_speed(name):
    """load_mjcf makes the MJCF joint axes unit, as MuJoCo's compiler does
    (engines.pybullet.robots): a joint speed of 1 rad/s, everything else at
    rest, turns the link at 1 rad/s; its angle turns it by the angle."""
    c = scenes.new_client(DT[name])
    try:
        u = [b for b in load_mjcf(c, _path(name)) if pb.getNumJoints(b, physicsClientId=c)][0]
        hinges = [j for j in range(pb.getNumJoints(u, physicsClientId=c))
                  if pb.getJointInfo(u, j, physicsClientId=c)[2] == pb.JOINT_REVOLUTE]
        assert len(hinges) == {"ant.xml": 8, "humanoid.xml": 21}[name]
        for j in hinges:
            for k in hinges:
                pb.resetJointState(u, k, 0.0, 1.0 if k == j else 0.0, physicsClientId=c)
            w = pb.getLinkState(u, j, computeLinkVelocity=1, physicsClientId=c)[7]
            assert abs(float(np.linalg.norm(w)) - 1.0) < AXIS_SPEED_ATOL, (j, w)
            R0 = np.array(pb.getMatrixFromQuaternion(pb.getLinkState(u, j, computeForwardKinematics=1,
                                                                     physicsClientId=c)[1])).reshape(3, 3)
            pb.resetJointState(u, j, 0.3, 0.0, physicsClientId=c)
            R1 = np.array(pb.getMatrixFromQuaternion(pb.getLinkState(u, j, computeForwardKinematics=1,
                                                                     physicsClientId=c)[1])).reshape(3, 3)
            angle = float(np.arccos(np.clip((np.trace(R1 @ R0.T) - 1.0) / 2.0, -1.0, 1.0)))
            assert abs(angle - 0.3) < 1e-6, (j, angle)
            pb.resetJointState(u, j, 0.0, 0.0, physicsClientId=c)
    finally:
        pb.disconnect(c)


#: Per 10 ms step, the ant's energy at rest (mechanical plus ContactManager.stored_energy)
#: may rise by what the semi-implicit Euler step moves in gravity's potential,
#: dt/2 |M g . dv_com| (it moves a body by dt v_end: engines._contacts.balance),
#: plus this share of its kinetic and normal elastic energy [-]: the settled
#: path couples the four feet of one multibody through their held forces a
#: step late (engines._contacts.islands; measured <= 0.011 at 10 ms; every
#: step within the bound when the feet are solved as one island). Before the
#: joint axes were made unit: 1.34.
REST_GAIN_RTOL = 0.02
#: Over the whole second, the energy's largest rise above its running
#: minimum, as a share of the ant's energy above the floor at the start: the
#: contacts' own bound on an island's energy gain (ENERGY_GAIN_RTOL, 1e-3,
#: the objects scenario's bound too). Measured at 10 ms: 0.51 J of 662 J
#: (7.7e-4) with the feet solved together at rest (no joint at a limit:
#: PybulletAdapter._rest_together); 1.31 J (2.0e-3) when the resting feet
#: took the settled path one by one, each seeing the others' forces a step
#: late in its a_ext (scripts/pybullet_robots.py ant).
REST_RISE_RTOL = ENERGY_GAIN_RTOL


def test_the_ant_rests_on_its_feet_without_energy_gain():
    """ant.xml from pybullet_data at its own 10 ms step, put down 0.5 mm above
    the floor, no torques, for 1 s: its energy (mechanical plus what the
    contacts hold) falls overall, rises above its running minimum by less
    than REST_RISE_RTOL of the start (its four feet, links of one
    multibody with no joint at a limit, solved together at rest too) and
    never rises in a step beyond
    REST_GAIN_RTOL (scripts/pybullet_robots.py ant: 662.2 -> 652.9 J; at 1 ms
    and 0.2 ms the largest rise above the running minimum is 0.079 J and
    0.005 J). The feet without a Coulomb cap (mu=None, the paper's law):
    free hinges and no motor, the ant stands only while its feet's
    tangential springs hold its legs from splaying; with pybullet's friction
    (0.75, the default) the feet slide, the legs splay and it drops onto its
    ankle limits (docs/engines.md)."""
    dt = DT["ant.xml"]
    c = scenes.new_client(dt, gravity=9.81)
    try:
        u, floor, pairs, shapes = _load_ant(c, mu=None)
        _put_down(c, u, floor, 5e-4)
        ad = PybulletAdapter(c, pairs, link_shapes=shapes)
        nj = pb.getNumJoints(u, physicsClientId=c)
        mass = np.array([pb.getDynamicsInfo(u, link, physicsClientId=c)[0] for link in range(-1, nj)])
        inertia = np.array([pb.getDynamicsInfo(u, link, physicsClientId=c)[2] for link in range(-1, nj)])

        def state():
            """(mechanical energy + stored_energy [J], kinetic + normal elastic [J], M v_com,z [N s])"""
            vs = [(pb.getBaseVelocity(u, physicsClientId=c), pb.getBasePositionAndOrientation(u, physicsClientId=c)[1])]
            vs += [((s[6], s[7]), s[1]) for s in pb.getLinkStates(u, list(range(nj)), computeLinkVelocity=1,
                                                                    physicsClientId=c)]
            v = np.array([a[0][0] for a in vs])
            wb = np.array([np.array(pb.getMatrixFromQuaternion(o)).reshape(3, 3).T @ np.asarray(a[1])
                           for a, o in vs])
            T = 0.5 * float(mass @ np.sum(v * v, axis=1)) + 0.5 * float(np.sum(inertia * wb * wb))
            E = mechanical_energy(c, [u]) + ad.manager.stored_energy()
            return E, T + float(np.sum(ad.manager.W_el[ad.manager.active])), float(mass @ v[:, 2])

        E0, _, p0 = state()
        start = lowest = E0
        rise = 0.0
        for _ in range(100):
            ad.step()
            E1, scale, p1 = state()
            allowed = 0.5 * dt * 9.81 * abs(p1 - p0) + REST_GAIN_RTOL * scale
            assert E1 - E0 <= allowed, (ad.time, E1 - E0, allowed)
            E0, p0 = E1, p1
            lowest = min(lowest, E1)
            rise = max(rise, E1 - lowest)
        assert ad.manager.active.sum() == 4  # on its four feet
        assert E1 < start
        assert rise <= REST_RISE_RTOL * start, (rise, start)
    finally:
        pb.disconnect(c)


def test_a_contact_past_the_laws_range_is_clamped_and_flagged_not_fatal():
    """A rubber ball (R 10 mm) striking steel at 80 m/s: the msf approach
    would pass 2R before maximum compression (the law refuses the onset).
    The run goes on: the onset constants are those of the largest speed the
    law accepts, the ball bounces, the record says so in outside_validity
    and stderr names the pair, dt and what to change (records._onset_in_range)."""
    from msf_contact import Curvature, make_law
    from msf_contact._validate import ValidityWarning
    from engines.base import PairSpec

    c = scenes.new_client(1e-3, gravity=9.81)
    try:
        plane = scenes.add_plate(c)
        R = 0.01
        rubber = preset("natural-rubber")
        law = make_law("msf", ContactPair(rubber, preset("steel")), Curvature.sphere_on_plane(R))
        m = 4.0 / 3.0 * np.pi * R**3 * rubber.density
        with pytest.raises(ValueError, match="reaches 2R"):
            law.onset(np.array([80.0]), np.array([m]))
        s = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c)
        u = pb.createMultiBody(m, s, basePosition=[0, 0, R + 1e-3], physicsClientId=c)
        pb.resetBaseVelocity(u, [0, 0, -80.0], [0, 0, 0], physicsClientId=c)
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law)])
        with pytest.warns(ValidityWarning, match=r"pair 0 .*dt = 0.001 s: a contact began at 80 m/s.*2R.*"
                                                 r"smaller dt.*larger radius"):
            ad.step(10)
        assert pb.getBaseVelocity(u, physicsClientId=c)[0][2] > 0  # it bounced
        (rec,) = ad.records
        assert any("past the law's range" in note for note in rec.outside_validity)
    finally:
        pb.disconnect(c)


ARM_URDF = """<robot name="arm">
  <link name="base"/>
  <link name="tip">
    <inertial><origin xyz="0.3 0 0"/><mass value="1"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.02"/></geometry></collision>
  </link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="tip"/><axis xyz="0 0 1"/>
    <limit lower="-0.5" upper="0.5" effort="0" velocity="100"/></joint>
</robot>
"""


def test_a_joint_stopped_at_its_limit_does_not_enter_a_ext_as_an_acceleration(tmp_path):
    """An arm (fixed base, a hinge limited to +-0.5 rad, a rubber sphere 0.3 m
    out, 25 mm above the floor) swung at 5 rad/s into its limit: pybullet
    stops the joint in one step, an impulse the finite-difference a_ext would
    take for an acceleration of 5 x 0.3 / dt = 1,500 m/s^2 (the humanoid's
    foot: 3,100 m/s^2, then an onset-speed floor of 15.4 m/s past the law's
    2R). The adapter sees the stop (limit_stops) and keeps the pair's last a_ext."""
    from msf_contact import Curvature, make_law
    from engines.base import PairSpec

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM_URDF)
    c = scenes.new_client(1e-3)
    try:
        plane = scenes.add_plate(c)
        u = pb.loadURDF(str(urdf), [0, 0, 0.045], useFixedBase=True, physicsClientId=c)
        pb.changeDynamics(u, 0, linearDamping=0, angularDamping=0, physicsClientId=c)
        pb.setJointMotorControl2(u, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=c)
        pb.setPhysicsEngineParameter(erp=0.0, physicsClientId=c)
        pb.resetJointState(u, 0, 0.4, 5.0, physicsClientId=c)
        law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
        ad = PybulletAdapter(c, [PairSpec((u, 0), (plane, -1), law)])
        worst = 0.0
        for _ in range(40):
            ad.step()
            worst = max(worst, float(np.linalg.norm(ad._last_a_ext[0])))
        assert abs(pb.getJointState(u, 0, physicsClientId=c)[0] - 0.5) < 1e-2  # stopped at the limit
        assert ad.limit_stops >= 1
        assert worst < 10.0 * 9.81  # no impulse taken for an acceleration
    finally:
        pb.disconnect(c)


#: A resting foot's internal approach (the manager's x at a step's end) must
#: follow the engine's geometry (the foot's approach found at the next step's
#: start) to this [m]: what the settle relaxation leaves after 1.2 s
#: (measured <= 2.6 um with no limit position correction, LIMIT_ERP; with
#: pybullet's own, 80-1,400 um and a foot leaving the floor).
FOOT_DRIFT_ATOL = 2e-5


def _ant_on_its_ankle_limits(c, limit_trial=False, mu=ENGINE_FRICTION):
    """The ant loaded in client c (its feet's Coulomb cap mu), its ankles put
    on their limits (where its torques leave it), put down on the floor 0.5 mm
    deep, and its PybulletAdapter (PybulletAdapter(limit_trial=)): (body id, adapter)."""
    u, floor, pairs, shapes = _load_ant(c, mu)
    for j in range(pb.getNumJoints(u, physicsClientId=c)):
        info = pb.getJointInfo(u, j, physicsClientId=c)
        if b"ankle" in info[1]:
            pb.resetJointState(u, j, info[8] if info[8] > 0 else info[9], 0.0, physicsClientId=c)
    _put_down(c, u, floor, 5e-4)
    return u, PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=limit_trial)


@pytest.mark.parametrize("limit_trial", [True, False])
def test_the_contacts_of_the_ant_landing_on_its_ankle_limits_gain_no_energy(limit_trial):
    """The ant put down on its ankle limits at its 10 ms step, no torques,
    0.3 s: the MSF contacts' own balance (RestEnergy.contacts: the account
    less what pybullet's steps added beyond the MSF loads' work) rises above
    its running minimum by less than REST_RISE_RTOL of the account when the
    joints a limit holds are found by a trial step
    (PybulletAdapter(limit_trial=True): measured 0 J of 570 J with the
    trial's a_ext, the default; 0.003 J of 574 J with the finite difference), and not
    when a joint within JOINT_LIMIT_TOL of a limit is taken as held: two
    ankles left their limits in pybullet's steps (one 17 mrad past it at
    1.7 rad/s, one off it at 1.4 rad/s) while the contacts' inverse inertia
    held them, and the contacts' balance rose 1.1 J and 2.3 J in those two
    steps (2.45 J in all). With the trial the real steps hold the joints it
    found: the step is tried again with the contacts' own forces and solved
    again where those hold other joints (PybulletAdapter(limit_retrial=True),
    the default; with one trial, the last step's loads, 3 of the 30 steps
    held fewer joints than it said)."""
    c = scenes.new_client(DT["ant.xml"], gravity=9.81)
    try:
        u, ad = _ant_on_its_ankle_limits(c, limit_trial)
        acc = RestEnergy(ad, [u])
        contacts = [acc.contacts]
        for _ in range(30):
            ad.step()
            acc.update()
            contacts.append(acc.contacts)
        contacts = np.array(contacts)
        rise = float(np.max(contacts - np.minimum.accumulate(contacts)))
        assert ad.limit_trials == (30 if limit_trial else 0)
        assert (rise <= REST_RISE_RTOL * abs(acc.total)) == limit_trial, (rise, acc.total)
        if limit_trial:
            assert ad.limit_trial_misses == [0, 0] and ad.limit_retrials >= 1  # measured [0, 3] with one trial
    finally:
        pb.disconnect(c)


def test_the_ant_on_its_ankle_limits_rests_with_its_feet_where_the_engine_has_them():
    """The ant put on its ankle limits (where its torques leave it) at its
    10 ms step, no torques, 1.5 s: pybullet's limit holds the ankles
    (load_mjcf_with_msf_floor: no limit position correction, whose push no
    force accounts for), all four feet stay on the floor and each foot's
    internal approach follows the engine's."""
    c = scenes.new_client(DT["ant.xml"], gravity=9.81)
    try:
        u, ad = _ant_on_its_ankle_limits(c)
        m = ad.manager
        drift = []
        for k in range(150):
            x_end, on = m.x.copy(), m.active.copy()
            ad.step()
            if k >= 120:
                assert np.count_nonzero(on) == 4
                drift += [abs(x_end[i] - ad._narrow_found[i][0]) for i in np.flatnonzero(on)]
        assert max(drift) < FOOT_DRIFT_ATOL
    finally:
        pb.disconnect(c)


#: A body that does not turn: pybullet's step changes its kinetic plus
#: potential energy by the work of the MSF force (PybulletAdapter.last_step_work)
#: plus the semi-implicit step's gravity term -dt/2 m g . dv, to float rounding
#: of a 0.05 kg ball's energy [J] (measured <= 5e-18 J).
WORK_ATOL = 1e-12


def test_last_step_work_is_the_msf_forces_work_on_a_body_that_does_not_turn():
    """A rubber ball (R 20 mm, 50 g) dropped on steel at 1 m/s, 1 ms: every
    step, what pybullet's step added beyond the MSF force's work
    (RestEnergy.engine_added) is the semi-implicit Euler step's gravity term
    -dt/2 m g . (v_end - v_start), the only other force, exactly; the
    contacts' own balance (RestEnergy.contacts) never rises and falls over
    the bounce by the viscous loss."""
    from msf_contact import Curvature, make_law
    from engines.base import PairSpec

    dt, R, m = 1e-3, 0.02, 0.05
    c = scenes.new_client(dt, gravity=9.81)
    try:
        plane = scenes.add_plate(c)
        s = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c)
        u = pb.createMultiBody(m, s, basePosition=[0, 0, R + 2e-4], physicsClientId=c)
        pb.changeDynamics(u, -1, linearDamping=0, angularDamping=0, physicsClientId=c)
        pb.resetBaseVelocity(u, [0, 0, -1.0], [0, 0, 0], physicsClientId=c)
        law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law)])
        acc = RestEnergy(ad, [u])
        start, loaded = acc.contacts, 0
        for _ in range(20):
            v0, before, con = np.array(pb.getBaseVelocity(u, physicsClientId=c)[0]), acc.engine_added, acc.contacts
            ad.step()
            acc.update()
            v1 = np.array(pb.getBaseVelocity(u, physicsClientId=c)[0])
            loaded += ad.last_step_work([u]) != 0.0
            assert abs((acc.engine_added - before) - 0.5 * dt * m * 9.81 * (v1 - v0)[2]) < WORK_ATOL
            assert acc.contacts - con <= REST_ROUNDOFF * abs(acc.total)
        assert loaded >= 3 and len(ad.records) == 1  # the bounce happened, over several steps
        assert acc.contacts < start * (1 - 0.1)  # the viscous loss (COR 0.73: 47 % of the energy)
        assert not acc.gains and not acc.contact_gains
    finally:
        pb.disconnect(c)


@pytest.mark.parametrize("limit_trial, anchor_depth", [(False, False), (False, True), (True, True)])
def test_what_the_twisted_ant_on_its_ankle_limits_gains_at_10_ms_pybullet_adds(limit_trial, anchor_depth):
    """The energy gain of pybullet's ant at rest after its torques (the
    benchmark, docs/engines.md) is pybullet's step, not the MSF contacts:
    the ant put on its ankle limits at its 10 ms step, then its torso turned
    at 5 rad/s against its legs (hips -5 rad/s: the mode its torques leave
    it rocking in), no torques, 1 s. Its energy account rises, and
    pybullet's steps added more than that beyond the MSF loads' work
    (RestEnergy.engine_added: the integration of the legs turning on their
    limits; scripts/pybullet_robots.py twist, 2 s: 105 J at 10 ms, 13 J at 5 ms,
    0.44 J at 2.5 ms), while the
    contacts' own balance rose by a few % of it, not beyond REST_RISE_RTOL
    of the account in each variant (measured, the account ~630-790 J: 0.357 J
    without the limit trial or the depth anchoring, 0.048 J anchored, 0.024 J
    with both and the trial's a_ext, the default since issue 13's fifth
    session: there pybullet's steps added 150 J and the account rose 121 J,
    against 38.9 J and 6.9 J with the finite-difference a_ext: the uncapped
    feet's forces differ and pybullet's integration pumps more; 0.063 J with
    the finite difference). Before the contacts' Jacobian was turned from the base's
    frame into the world's (engines.pybullet.adapter._jacobian,
    tests/test_pybullet_jacobian.py) the variant with neither rose 1.41 J,
    above the bound, and the other two 0 J. The feet without a Coulomb cap (mu=None, the paper's law): with
    pybullet's friction, the default, nothing is pumped
    (test_the_twisted_ant_with_pybullets_friction_on_its_feet_is_not_pumped)."""
    dt = DT["ant.xml"]
    c = scenes.new_client(dt, gravity=9.81)
    try:
        u, ad = _ant_on_its_ankle_limits(c, limit_trial, mu=None)
        ad.anchor_depth = anchor_depth
        ad.step(50)
        _twist(c, u, 5.0)
        ad.placed([u])
        acc = RestEnergy(ad, [u])
        total, contacts = [acc.total], [acc.contacts]
        for _ in range(100):
            ad.step()
            total.append(acc.update())
            contacts.append(acc.contacts)
        total, contacts = np.array(total), np.array(contacts)
        rise = float(np.max(total - np.minimum.accumulate(total)))
        rise_contacts = float(np.max(contacts - np.minimum.accumulate(contacts)))
        assert rise > 5.0  # the gain (measured 16.2 J; 6.8 J anchored, 121 J with the trial)
        assert acc.engine_added > rise  # pybullet's steps put it there (measured 53.8 J; 38.4 J; 150 J)
        assert rise_contacts < 0.05 * acc.engine_added  # measured 0.357 J; 0.048 J; 0.024 J
        assert rise_contacts <= REST_RISE_RTOL * abs(acc.total), (rise_contacts, acc.total)
    finally:
        pb.disconnect(c)


def test_the_feet_are_capped_at_the_friction_pybullets_own_contact_gives_the_pair():
    """load_mjcf_with_msf_floor's default law caps each foot's tangential
    force at the friction Bullet's contact uses for that (link, floor) pair,
    the product of their lateralFriction (btManifoldResult::
    calculateCombinedFriction): loadMJCF reads the MJCF friction (the ant's
    1.5; the humanoid gives none, Bullet's 0.5), the floor plane 0.5. A
    number caps every pair at it, None leaves the paper's law uncapped;
    anything else is refused by name before loading."""
    c = scenes.new_client(DT["humanoid.xml"], gravity=9.81)
    try:
        pair = ContactPair(preset("natural-rubber"), preset("steel"))
        for bad in (0.0, -1.0, float("nan"), True, "mujoco"):
            with pytest.raises(ValueError, match=r"mu = .* must be 'engine', a finite number > 0 or None"):
                load_mjcf_with_msf_floor(c, _path("humanoid.xml"), pair, mu=bad)
        robots, floor, pairs, _ = load_mjcf_with_msf_floor(c, _path("humanoid.xml"), pair)
        for p in pairs:
            f1 = pb.getDynamicsInfo(p.body1[0], p.body1[1], physicsClientId=c)[1]
            f2 = pb.getDynamicsInfo(floor, -1, physicsClientId=c)[1]
            assert p.law.mu == f1 * f2
        assert {p.law.mu for p in pairs} == {0.25}
        _, _, pairs, _ = load_mjcf_with_msf_floor(c, _path("humanoid.xml"), pair, mu=None)
        assert {p.law.mu for p in pairs} == {None}
        _, _, pairs, _ = load_mjcf_with_msf_floor(c, _path("humanoid.xml"), pair, mu=1.0)
        assert {p.law.mu for p in pairs} == {1.0}
    finally:
        pb.disconnect(c)


def test_the_twisted_ant_with_pybullets_friction_on_its_feet_is_not_pumped():
    """The twisted ant above (on its ankle limits at 10 ms, torso turned at
    5 rad/s against its legs, no torques, 1 s) with the feet's default law:
    a Coulomb cap at the friction pybullet's own contact gives the pair
    (load_mjcf_with_msf_floor(mu=ENGINE_FRICTION): 1.5 x 0.5 = 0.75). The
    feet slip instead of holding the legs with tangential forces many times
    their normal force, and pybullet's steps take energy out where they
    pumped the uncapped ant (RestEnergy.engine_added -16.3 J; +52.8 J with
    no cap), the account falls (696 -> 548 J) and never rises above its
    running minimum beyond REST_RISE_RTOL of it (measured 0.020 J; 14.9 J
    with no cap)."""
    dt = DT["ant.xml"]
    c = scenes.new_client(dt, gravity=9.81)
    try:
        u, ad = _ant_on_its_ankle_limits(c)
        assert {p.law.mu for p in ad.pairs} == {0.75}
        ad.step(50)
        _twist(c, u, 5.0)
        ad.placed([u])
        acc = RestEnergy(ad, [u])
        total = [acc.total]
        for _ in range(100):
            ad.step()
            total.append(acc.update())
        total = np.array(total)
        assert acc.engine_added < 0.0
        assert total[-1] < total[0]
        assert float(np.max(total - np.minimum.accumulate(total))) <= REST_RISE_RTOL * abs(acc.total)
    finally:
        pb.disconnect(c)


def _twist(c, u, wz):
    """Turn body u's base at wz [rad/s] about z and its hips at -wz (its feet stay)."""
    pb.resetBaseVelocity(u, [0, 0, 0], [0, 0, wz], physicsClientId=c)
    for j in range(pb.getNumJoints(u, physicsClientId=c)):
        info = pb.getJointInfo(u, j, physicsClientId=c)
        if b"hip" in info[1]:
            pb.resetJointState(u, j, pb.getJointState(u, j, physicsClientId=c)[0], -wz, physicsClientId=c)


#: The outside acceleration a_ext the adapter gives a contact point of the
#: ant, its joints inside their ranges, against the point's acceleration over
#: the step, with new torques at every 1 ms step told through
#: set_joint_torques [-] (measured median 7e-4, largest 6.1e-3: the links
#: turn within the step; told a step late, through pybullet's own call:
#: median 1.28, up to 4.9).
A_EXT_RTOL = 1e-2


@pytest.mark.parametrize("tell", [True, False])
def test_joint_torques_told_to_the_adapter_reach_the_contacts_in_their_step(tell):
    """The ant in the air (gravity, joints mid-range), new random joint
    torques (150 N m) at every 1 ms step: told through
    PybulletAdapter.set_joint_torques, each foot's a_ext is the acceleration
    its point then has over the step (J M^-1 (tau - tau_last) added to the
    finite difference of the last step); set with pybullet's own call, it is
    the last step's acceleration, off by the change of the torques."""
    dt = 1e-3
    c = scenes.new_client(dt, gravity=9.81)
    try:
        u, floor, pairs, shapes = _load_ant(c)
        pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
        pb.resetBasePositionAndOrientation(u, [0, 0, 3.0], orn, physicsClientId=c)
        ad = PybulletAdapter(c, pairs, link_shapes=shapes)
        joints = [j for j in range(pb.getNumJoints(u, physicsClientId=c))
                  if pb.getJointInfo(u, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
        feet = [i for i, names in enumerate(ad.pair_names) if "foot" in names[0]]
        rng = np.random.default_rng(SEED)
        errors = []
        for k in range(12):
            tau = rng.uniform(-1.0, 1.0, len(joints)) * 150.0
            if tell:
                ad.set_joint_torques(u, joints, tau)
            else:
                pb.setJointMotorControlArray(u, joints, pb.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=c)
            b0 = ad._read_bodies()
            ad.step()
            b1 = ad._read_bodies()
            for i in feet:
                j, p = ad._slot[i, 0], ad._pt[i]
                local = b0.rot[j].T @ (p - b0.com[j])
                a = ((b1.v[j] + np.cross(b1.w[j], b1.rot[j] @ local)) - (b0.v[j] + np.cross(b0.w[j], p - b0.com[j]))) / dt
                if k >= 2:  # a_ext is measured from the second step on
                    errors.append(float(np.linalg.norm(ad._last_a_ext[i] - a) / np.linalg.norm(a)))
        assert (max(errors) < A_EXT_RTOL) == tell, max(errors)
    finally:
        pb.disconnect(c)


def test_bad_joint_torques_are_refused_naming_what_is_wrong():
    c = scenes.new_client(DT["ant.xml"])
    try:
        u, floor, pairs, shapes = _load_ant(c)
        ad = PybulletAdapter(c, pairs, link_shapes=shapes)
        with pytest.raises(ValueError, match=r"uid = 999: no link of a multibody"):
            ad.set_joint_torques(999, [1], [0.0])
        with pytest.raises(ValueError, match=r"torques has 1 values for 2 joints"):
            ad.set_joint_torques(u, [1, 3], [0.0])
        with pytest.raises(ValueError, match=r"joints \[0\] of body \d+ are not movable joints"):
            ad.set_joint_torques(u, [0], [1.0])  # a fixed joint
        with pytest.raises(ValueError, match=r"must be finite"):
            ad.set_joint_torques(u, [1], [np.nan])
    finally:
        pb.disconnect(c)


def test_bad_robot_inputs_are_refused_before_loading(tmp_path):
    """A joint axis of zero length (which loadMJCF would keep) and a limit ERP
    outside [0, 1] are ValueErrors naming the joint or the parameter."""
    from engines.pybullet.robots import unit_joint_axes

    bad = tmp_path / "bad.xml"
    bad.write_text('<mujoco><worldbody><body name="b"><joint name="hinge" type="hinge" axis="0 0 0"/>'
                   '<geom type="sphere" size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(ValueError, match=r"joint 'hinge' has axis '0 0 0': give a non-zero 3-vector"):
        unit_joint_axes(str(bad))
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    c = scenes.new_client(DT["ant.xml"])
    try:
        with pytest.raises(ValueError, match=r"limit_erp = 1.5 must be in \[0, 1\] or None"):
            load_mjcf_with_msf_floor(c, _path("ant.xml"), pair, limit_erp=1.5)
        assert pb.getNumBodies(physicsClientId=c) == 0  # refused before anything was loaded
    finally:
        pb.disconnect(c)


@pytest.mark.parametrize("how", ["torque", "force"])
def test_the_limit_trial_consumes_what_pybullets_own_calls_set_before_step(how):
    """Why PybulletAdapter(limit_trial=True) is not the default: pybullet
    applies a TORQUE_CONTROL torque and an applyExternalForce force for one
    stepSimulation and cannot report them (getJointState's applied motor
    torque reads 0 under TORQUE_CONTROL; there is no getter of external
    forces) nor keep them over saveState/restoreState, so the trial's
    stepSimulation uses them up and the real step goes without: a torque
    (1 N m) or a force (1 N) set with pybullet's own call before step moves
    the dumbbell in the air without the trial and not at all with it. A
    torque told through set_joint_torques acts with the trial too."""
    from msf_contact import Curvature, make_law
    from engines.base import PairSpec

    moved = {}
    for trial in (False, True):
        c = scenes.new_client(1e-2, gravity=0.0)
        try:
            plane = scenes.add_plate(c)
            s = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.02, physicsClientId=c)
            u = pb.createMultiBody(1.0, s, basePosition=[0, 0, 0.5], linkMasses=[1.0],
                                   linkCollisionShapeIndices=[s], linkVisualShapeIndices=[-1],
                                   linkPositions=[[0.2, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                                   linkInertialFramePositions=[[0, 0, 0]],
                                   linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
                                   linkJointTypes=[pb.JOINT_REVOLUTE], linkJointAxis=[[0, 1, 0]],
                                   physicsClientId=c)
            pb.setJointMotorControl2(u, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=c)
            law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")),
                           Curvature.sphere_on_plane(0.02))
            ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law), PairSpec((u, 0), (plane, -1), law)],
                                 limit_trial=trial)
            if how == "torque":
                pb.setJointMotorControl2(u, 0, pb.TORQUE_CONTROL, force=1.0, physicsClientId=c)
            else:
                pb.applyExternalForce(u, -1, [1.0, 0, 0], [0, 0, 0.5], pb.WORLD_FRAME, physicsClientId=c)
            ad.step()
            moved[trial] = (abs(pb.getJointState(u, 0, physicsClientId=c)[1]) if how == "torque"
                            else abs(pb.getBaseVelocity(u, physicsClientId=c)[0][0]))
            assert ad.limit_trials == int(trial)
            if how == "torque":  # told to the adapter: set again after the trial
                ad.set_joint_torques(u, [0], [1.0])
                w = pb.getJointState(u, 0, physicsClientId=c)[1]
                ad.step()
                assert abs(pb.getJointState(u, 0, physicsClientId=c)[1] - w) > 0.5 * moved[False]
        finally:
            pb.disconnect(c)
    assert moved[False] > 1e-3 and moved[True] == 0.0


def test_the_trial_sees_the_capped_ant_land_on_its_ankle_limits():
    """The ant put down on its feet at 10 ms with the default (capped) feet,
    no torques, and the trial (PybulletAdapter(limit_trial=True)): the feet
    slide, the legs splay and it drops onto its ankle limits (0.3 s). The
    trial applies the last step's loads and, for a contact closing within
    the step, at least the force that stops it (PybulletAdapter._trial_loads):
    the landing's contact force holds the ankles on their limits in the trial
    as in the step, and the contacts' own balance rises above its running
    minimum by less than REST_RISE_RTOL of the account (measured 0.095 J of
    ~600 J); with the last step's loads alone (~0 before the landing) the
    trial left the ankles free, W = J M^-1 J^T 3x too large along n in the
    landing step (0.152 against 0.047 1/kg; PybulletAdapter.limit_trial_misses
    counts that step), and it rose 18.1 J. The contacts' a_ext here is the
    finite difference (trial_a_ext=False): this test's subject is which
    joints the trial holds. With the trial's own a_ext (the default) the
    balance rises 0.721 J, all in the landing step, whose contact force comes
    late in the step: its timing correction J (applied in that step, taken
    back in the next, engines._contacts) is a velocity offset whose kinetic
    energy, 3.14 J, is in that step's account; with it taken out, as the
    islands' energy check reads a multibody (PybulletAdapter._correction_energy),
    that step rises 0.035 J (docs/engines.md)."""
    dt = DT["ant.xml"]
    c = scenes.new_client(dt, gravity=9.81)
    try:
        u, floor, pairs, shapes = _load_ant(c)
        _put_down(c, u, floor, 5e-4)
        ad = PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=True, trial_a_ext=False)
        acc = RestEnergy(ad, [u])
        contacts, engaged = [acc.contacts], 0
        for _ in range(40):
            ad.step()
            acc.update()
            contacts.append(acc.contacts)
            engaged = max(engaged, int(np.count_nonzero(ad._engaged.get(u, []))))
        contacts = np.array(contacts)
        assert engaged == 4  # it landed on its four ankle limits
        assert ad.limit_trial_misses[0] == 0  # no step held a joint the trial left free (1 with the last loads)
        rise = float(np.max(contacts - np.minimum.accumulate(contacts)))
        assert rise <= REST_RISE_RTOL * abs(acc.total), (rise, acc.total)
    finally:
        pb.disconnect(c)


#: benchmarks/robots_pybullet.py's ant (seed 4) for this many steps of torques, then this many without: the
#: settling right after the torques, where the legs' acceleration changes from step to step (ankles engaging
#: and leaving their limits); the 1,000 + 1,000 steps of the benchmark take minutes (docs/engines.md)
SETTLE_SEED, SETTLE_TORQUE_STEPS, SETTLE_REST_STEPS = 4, 60, 20


def test_the_ants_contacts_gain_nothing_as_it_settles_after_its_torques():
    """The benchmark's ant (MSF feet capped at pybullet's friction, the limit
    trial, torques told through set_joint_torques) under torque seed 4 for
    0.6 s at 10 ms, then 0.2 s without: no rest step raises the contacts' own
    balance (RestEnergy.contacts) beyond RestEnergy's bound. A link contact's
    outside acceleration a_ext is the step's own, from the trial
    (PybulletAdapter(trial_a_ext=True), the default: pybullet's step is affine
    in the loads given the held joints, docs/engines.md). With the finite
    difference of the last step's velocities (trial_a_ext=False, the default
    before) two of the 20 steps rose above the bound, 0.727 J and 0.031 J: the last step's
    acceleration is not this step's while the legs settle."""
    dt = DT["ant.xml"]
    c = scenes.new_client(dt, gravity=9.81)
    try:
        u, floor, pairs, shapes = _load_ant(c)
        limits = motor_torque_limits(_path("ant.xml"))
        joints = [j for j in range(pb.getNumJoints(u, physicsClientId=c))
                  if pb.getJointInfo(u, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
        bound = np.array([limits.get(pb.getJointInfo(u, j, physicsClientId=c)[1].decode(), 0.0) for j in joints])
        ad = PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=True)
        rng = np.random.default_rng(SETTLE_SEED)
        for _ in range(SETTLE_TORQUE_STEPS):
            ad.set_joint_torques(u, joints, rng.uniform(-1.0, 1.0, len(joints)) * bound)
            ad.step()
        pb.setJointMotorControlArray(u, joints, pb.TORQUE_CONTROL, forces=[0.0] * len(joints), physicsClientId=c)
        acc = RestEnergy(ad, [u])
        moving = acc.kinetic
        for _ in range(SETTLE_REST_STEPS):
            ad.step()
            acc.update()
        assert moving > 1.0  # the rest begins with the ant moving (measured 80 J; 52 J with the finite difference)
        assert ad.manager.active.any()  # on the floor
        assert not acc.contact_gains, acc.contact_gains
    finally:
        pb.disconnect(c)
