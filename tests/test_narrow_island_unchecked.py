"""Never silent (issue 13): pybullet's islands' energy check
(engines._contacts.balance) leaves out every island holding a link of a
multibody (PybulletAdapter._energy_probe gives NaN for a multibody's key:
its motors, torques and limits do work it does not see). Before (main
7ce0dab) that was silent; now the adapter warns once naming the pairs and
lists them in ``island_energy_unchecked``, while a free body's islands are
checked and not listed."""

import warnings

import pytest

pb = pytest.importorskip("pybullet")
pytestmark = pytest.mark.pybullet

from msf_contact import ContactPair, Curvature, make_law, preset  # noqa: E402

from engines.base import PairSpec  # noqa: E402
from engines.pybullet import PybulletAdapter, scenes  # noqa: E402

HALF = [0.05, 0.02, 0.005]  # the paddle's half-extents [m]


def _drop(hinged: bool):
    """(adapter, warnings) of a steel paddle (a box, 0.2 kg) dropped 1.2 mm
    onto a plane on its face, 300 steps of 1 ms: a link on a free hinge at
    one end (a multibody) or a free body."""
    c = scenes.new_client(1e-3, 9.81)
    try:
        plane = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_PLANE, planeNormal=[0, 0, 1],
                                                                physicsClientId=c), physicsClientId=c)
        if hinged:
            box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=HALF, collisionFramePosition=[HALF[0], 0, 0],
                                          physicsClientId=c)
            uid = pb.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=-1, basePosition=[0, 0, HALF[2] + 1.2e-3],
                linkMasses=[0.2], linkCollisionShapeIndices=[box], linkVisualShapeIndices=[-1],
                linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                linkInertialFramePositions=[[HALF[0], 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                linkParentIndices=[0], linkJointTypes=[pb.JOINT_REVOLUTE], linkJointAxis=[[0, 1, 0]],
                physicsClientId=c)
            pb.setJointMotorControl2(uid, 0, pb.VELOCITY_CONTROL, force=0.0, physicsClientId=c)
            body = (uid, 0)
        else:
            box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=HALF, physicsClientId=c)
            uid = pb.createMultiBody(0.2, box, basePosition=[0, 0, HALF[2] + 1.2e-3], physicsClientId=c)
            scenes._free_dynamics(c, uid)  # noqa: SLF001 - the scenes' settings for a free body
            body = (uid, -1)
        law = make_law("msf", ContactPair(preset("steel"), preset("steel")), Curvature.sphere_on_plane(0.01))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ad = PybulletAdapter(c, [PairSpec(body, (plane, -1), law)])
            ad.step(300)
    finally:
        pb.disconnect(c)
    return ad, [w for w in caught if "island energy check left out" in str(w.message)]


def test_a_multibody_links_islands_left_out_of_the_energy_check_are_said():
    ad, said = _drop(hinged=True)
    assert ad.records and ad.island_energy_unchecked
    assert len(said) == 1 and issubclass(said[0].category, RuntimeWarning)
    assert all(f"{p} " in str(said[0].message) for p in ad.island_energy_unchecked)
    assert ad.manager._balance.unchecked > 0


def test_a_free_bodys_islands_are_checked_and_not_listed():
    ad, said = _drop(hinged=False)
    assert ad.records and not ad.island_energy_unchecked and not said
    assert ad.manager._balance.checked > 0
