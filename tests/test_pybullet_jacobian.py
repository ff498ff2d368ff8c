"""The contact's Jacobian on a pybullet multibody (W = J M^-1 J^T, the
coupling of a robot's contacts) is in the world frame whatever the base's
orientation. pybullet's calculateJacobian answers in the base's frame
(3.2.7, measured): the adapter rotates it (engines.pybullet.adapter
``_jacobian``). Before, a fixed-base robot mounted turned (pybullet_data's
cartpole.urdf loaded turned) stopped with "n.W.n = 0" when its cart, which
moves along a tilted rail, touched the floor, and every turned floating
base (a walking ant) had its contacts' inverse inertia turned with it."""

import os

import numpy as np
import pytest

pb = pytest.importorskip("pybullet")
pybullet_data = pytest.importorskip("pybullet_data")
pytestmark = pytest.mark.pybullet

from engines.base import PairSpec  # noqa: E402
from engines.pybullet.adapter import PybulletAdapter, _mat  # noqa: E402
from msf_contact import ContactPair, Curvature, make_law, preset  # noqa: E402

#: J x against pybullet's own link velocity (getLinkState), relative to the
#: speed: measured up to 2.4e-7 (pybullet's Jacobian and link states do not
#: agree to double precision); the Jacobian in the base's frame is off by
#: O(1) (the base turned by ~1 rad).
VEL_RTOL = 1e-6
TURN = (0.4, -0.3, 1.2)  #: the base's Euler angles [rad]


def _law():
    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))


def _client():
    c = pb.connect(pb.DIRECT)
    pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
    pb.setGravity(0, 0, -9.81, physicsClientId=c)
    pb.setTimeStep(1e-3, physicsClientId=c)
    return c


def _check_link_velocities(c, adapter, uid, floating):
    """For every movable link: adapter._jacobian(link) @ (pybullet's coordinates' velocities) = the link's
    centre-of-mass velocity in the world (getLinkState)."""
    rng = np.random.default_rng(0)
    mov = [j for j in range(pb.getNumJoints(uid, physicsClientId=c))
           if pb.getJointInfo(uid, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
    for j in mov:
        pb.resetJointState(uid, j, 0.1, float(rng.uniform(-1, 1)), physicsClientId=c)
    if floating:
        pb.resetBaseVelocity(uid, [0.1, 0.2, 0.3], [0.5, -0.2, 0.4], physicsClientId=c)
    adapter._steps += 1  # a new step: the joint state is read again (engines.pybullet.adapter._multibody)
    qd = np.array([pb.getJointState(uid, j, physicsClientId=c)[1] for j in mov])
    R = _mat(pb.getBasePositionAndOrientation(uid, physicsClientId=c)[1])
    if floating:  # pybullet's coordinates: the base's angular then linear velocity in its own axes
        v, w = (np.asarray(a, float) for a in pb.getBaseVelocity(uid, physicsClientId=c))
        x = np.r_[R.T @ w, R.T @ v, qd]
    else:
        x = qd
    checked = 0
    for link in mov:
        pose = adapter._pose((uid, link))
        J = adapter._jacobian((uid, link), pose, pose.com)
        assert np.linalg.norm(J @ x - pose.v) <= VEL_RTOL * np.linalg.norm(pose.v), f"link {link}"
        checked += 1
    return checked


def test_a_turned_fixed_base_robots_jacobian_is_in_the_world_frame():
    c = _client()
    try:
        plane = pb.loadURDF("plane.urdf", physicsClientId=c)
        u = pb.loadURDF("cartpole.urdf", [0, 0, 0.5], pb.getQuaternionFromEuler(TURN), physicsClientId=c)
        adapter = PybulletAdapter(c, [PairSpec((u, link), (plane, -1), _law()) for link in (0, 1)])
        assert _check_link_velocities(c, adapter, u, floating=False) == 2
    finally:
        pb.disconnect(c)


def test_a_turned_floating_base_robots_jacobian_is_in_the_world_frame():
    from engines.pybullet.robots import load_mjcf_with_msf_floor

    c = _client()
    try:
        uids, _, pairs, shapes = load_mjcf_with_msf_floor(c, os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml"), ContactPair(preset("natural-rubber"),
                                                                                          preset("steel")))
        uid = uids[0]
        adapter = PybulletAdapter(c, pairs, link_shapes=shapes)
        pos = pb.getBasePositionAndOrientation(uid, physicsClientId=c)[0]
        pb.resetBasePositionAndOrientation(uid, [pos[0], pos[1], 1.0], pb.getQuaternionFromEuler(TURN),
                                           physicsClientId=c)
        assert _check_link_velocities(c, adapter, uid, floating=True) == 8
    finally:
        pb.disconnect(c)



def test_a_multibody_with_spherical_joints_is_refused_before_any_step():
    """pybullet_data's humanoid/humanoid.urdf (8 spherical joints): before,
    pybullet.error "Spherical joints are not supported" from calculateJacobian
    at its first contact, mid-run."""
    c = _client()
    try:
        plane = pb.loadURDF("plane.urdf", physicsClientId=c)
        u = pb.loadURDF("humanoid/humanoid.urdf", [0, 0, 1.0], physicsClientId=c)
        links = [-1] + list(range(pb.getNumJoints(u, physicsClientId=c)))
        links = [k for k in links if len(pb.getCollisionShapeData(u, k, physicsClientId=c)) == 1]
        with pytest.raises(ValueError, match=r"body \d+ has 8 spherical joint\(s\) \(1 'chest', .*supports "
                                             r"revolute, prismatic and fixed joints only"):
            PybulletAdapter(c, [PairSpec((u, k), (plane, -1), _law()) for k in links])
    finally:
        pb.disconnect(c)
