"""The pybullet adapter does not own the client (issue 11, item 2).

``close()`` leaves the client connected and gives the pair back to
pybullet's own contact; while the adapter is open, a ``stepSimulation()``
taken without it is detected at the next ``adapter.step()`` and warned
about, not integrated as a contact.
"""

from __future__ import annotations

import warnings

import numpy as np
import pybullet as pb
import pytest

from engines.base import PairSpec
from engines.pybullet import PybulletAdapter, scenes
from msf_contact import Body, ContactPair, Curvature, make_law, preset

pytestmark = pytest.mark.pybullet

R, DT, G = 0.02, 1e-3, 9.81


def resting_ball():
    """A rubber ball dropped 5 mm onto a steel plane, settled by MSF."""
    b = Body.sphere(preset("natural-rubber"), R)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))
    scene = scenes.ball_on_plate(b, 1e-9, dt=DT, gap=5e-3, gravity=G)
    return scene, PairSpec(scene.body1, scene.body2, law)


def z_of(scene):
    return pb.getBasePositionAndOrientation(scene.body1[0], physicsClientId=scene.client)[0][2]


def test_close_keeps_the_client_and_returns_the_pair_to_pybullet():
    scene, pair = resting_ball()
    with scene:
        with PybulletAdapter(scene.client, [pair]) as ad:
            ad.step(500)
            assert ad.manager.active[0]
            z_msf = z_of(scene)
        assert pb.isConnected(scene.client)
        with pytest.raises(RuntimeError, match="closed"):
            ad.step(1)
        for _ in range(500):  # the user's own loop after the adapter: pybullet's contact holds the ball
            pb.stepSimulation(physicsClientId=scene.client)
        z = z_of(scene)
        # pybullet's contact (default settings) rests the ball within a few mm of the surface;
        # with the pair still filtered out it would fall through (z < -1 m after 0.5 s)
        assert abs(z - R) < 0.25 * R and abs(z_msf - R) < 0.25 * R
        assert len(pb.getContactPoints(scene.body1[0], scene.body2[0], physicsClientId=scene.client)) > 0
    assert not pb.isConnected(scene.client)


def test_stepping_without_the_adapter_is_loud_and_not_a_contact():
    scene, pair = resting_ball()
    with scene, PybulletAdapter(scene.client, [pair]) as ad:
        ad.step(500)
        assert ad.manager.active[0] and ad.jumps == 0  # ordinary steps are not jumps
        for _ in range(3):
            pb.stepSimulation(physicsClientId=scene.client)  # the mistake: MSF's force is not applied
        with pytest.warns(RuntimeWarning, match=r"instead of p\.stepSimulation\(\).*1 MSF contact"):
            ad.step(1)
        assert ad.jumps == 1 and ad.interrupted == 1
        # a placed body declared with placed() is interrupted quietly
        ad.step(200)
        pb.resetBasePositionAndOrientation(scene.body1[0], [0, 0, 0.1], [0, 0, 0, 1], physicsClientId=scene.client)
        ad.placed([scene.body1])
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            ad.step(1)
        assert ad.jumps == 2 and ad.interrupted == 2
        v = pb.getBaseVelocity(scene.body1[0], physicsClientId=scene.client)[0]
        np.testing.assert_allclose(v, [0, 0, -G * DT], rtol=1e-9, atol=1e-12)  # free flight, no contact force


def test_client_settings_the_adapter_cannot_step_are_refused():
    """numSubSteps > 1 (each stepSimulation moves a body by other than dt v_end: every contact read as a jump,
    no record; measured: a bouncing rubber ball gave 0 records and 421 warnings in 3 s), real-time simulation
    and a time step changed after the adapter was made are refused naming the setting, at construction and at
    the next adapter.step()."""
    scene, pair = resting_ball()
    with scene:
        c = scene.client
        pb.setPhysicsEngineParameter(numSubSteps=4, physicsClientId=c)
        with pytest.raises(ValueError, match="numSubSteps = 4"):
            PybulletAdapter(c, [pair])
        pb.setPhysicsEngineParameter(numSubSteps=1, physicsClientId=c)  # one integration a step: accepted
        with PybulletAdapter(c, [pair]) as ad:
            ad.step(50)
            pb.setPhysicsEngineParameter(numSubSteps=2, physicsClientId=c)
            with pytest.raises(ValueError, match="numSubSteps = 2"):
                ad.step(1)
            pb.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=c)
            pb.setTimeStep(2 * DT, physicsClientId=c)
            with pytest.raises(ValueError, match="time step changed to 0.002 s since the adapter was made with 0.001 s"):
                ad.step(1)
            pb.setTimeStep(DT, physicsClientId=c)
            ad.step(1)
