"""A per-pair switch at run time, and non-smooth contacts that never end a
run (issue 11, items 4 and 5).

MuJoCo: a model without any <exclude> gets MSF (the adapter switches
MuJoCo's contact off for the pair itself, and restores the model on exit);
``set_mode`` moves a pair between MSF, MuJoCo's own contact and neither.
pybullet: the same through setCollisionFilterPair. A sphere at a box edge
or corner is handed to the engine's own contact while it lasts (counted,
warned), never refused: a ball rolling off a table edge, and a ball resting
near a tilted box (refused at 0.36-0.46 m before), run on without an
exception and without energy gain.
"""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import pybullet as pb
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from engines.pybullet import PybulletAdapter, scenes
from msf_contact import Body, ContactPair, Curvature, make_law, preset

R, MASS, G, DT = 0.02, 0.0312, 9.81, 1e-3
#: Energy may not grow: the mechanical energy after the run over the energy
#: at the start, with round-off room.
ENERGY_GROWTH_MAX = 1e-9


def law():
    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))


NO_EXCLUDE = f"""
<mujoco>
  <option timestep="{DT}" gravity="0 0 -{G}"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 {R + 2e-3}"><freejoint/><geom name="ball" type="sphere" size="{R}" mass="{MASS}"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.mujoco
def test_mujoco_switch_per_pair_without_editing_the_model():
    model = mujoco.MjModel.from_xml_string(NO_EXCLUDE)
    data = mujoco.MjData(model)
    before = (model.exclude_signature.copy(), model.geom_contype.copy(), model.geom_conaffinity.copy())
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "floor", law())])
    with installed(adapter):
        for _ in range(800):
            mujoco.mj_step(model, data)
            assert data.ncon == 0  # MuJoCo's contact is off for the pair: MSF alone holds the ball
        (rep,) = adapter.contact_forces()
        assert rep.F_n == pytest.approx(MASS * G, rel=1e-6)
        adapter.set_mode(("ball", "floor"), "engine")
        assert adapter.mode(0) == "engine"
        for _ in range(300):
            mujoco.mj_step(model, data)
        assert data.ncon >= 1 and not adapter.contact_forces()  # MuJoCo's own contact, no MSF force
        assert abs(data.qpos[2] - R) < 0.25 * R
        adapter.set_mode(0, "off")
        for _ in range(100):
            mujoco.mj_step(model, data)
        assert data.ncon == 0 and data.qpos[2] < 0.0  # neither: it falls through
        with pytest.raises(ValueError, match="mode"):
            adapter.set_mode(0, "both")
    # the model is the user's again
    for a, b in zip(before, (model.exclude_signature, model.geom_contype, model.geom_conaffinity)):
        np.testing.assert_array_equal(a, b)
    assert mujoco.get_mjcb_contactfilter() is None and mujoco.get_mjcb_passive() is None


EXCLUDED = NO_EXCLUDE.replace("</worldbody>", '</worldbody><contact><exclude body1="world" body2="ball"/></contact>')


@pytest.mark.mujoco
def test_mujoco_engine_mode_lifts_the_models_exclude_and_restores_it():
    model = mujoco.MjModel.from_xml_string(EXCLUDED)
    data = mujoco.MjData(model)
    saved = model.exclude_signature.copy()
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "floor", law())])
    adapter.set_mode(0, "engine")
    with installed(adapter):
        for _ in range(300):
            mujoco.mj_step(model, data)
        assert data.ncon >= 1 and abs(data.qpos[2] - R) < 0.25 * R
    np.testing.assert_array_equal(model.exclude_signature, saved)


def energy(model, data):
    """The ball's mechanical energy as semi-implicit Euler conserves it in free
    flight: kinetic (a solid sphere, I = 2/5 m R^2) + potential - m g dt v_z / 2
    (the integrator's invariant; plain kinetic + potential changes by m g^2 dt^2
    / 2 a step), from qpos and qvel (data.energy would use the previous
    state's positions after mj_step)."""
    v, w = data.qvel[0:3], data.qvel[3:6]
    return float(0.5 * MASS * (v @ v) + 0.2 * MASS * R * R * (w @ w) + MASS * G * data.qpos[2]
                 - 0.5 * MASS * G * DT * v[2])


TABLE = f"""
<mujoco>
  <option timestep="{DT}" gravity="0 0 -{G}"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" pos="0 0 -0.5"/>
    <geom name="table" type="box" size="0.2 0.2 0.05" pos="0 0 0" euler="0 {{tilt}} 0"/>
    <body name="ball" pos="{{x}} 0 {{z}}"><freejoint/><geom name="ball" type="sphere" size="{R}" mass="{MASS}"/></body>
  </worldbody>
  <contact><exclude body1="world" body2="ball"/></contact>
</mujoco>
"""


@pytest.mark.mujoco
def test_mujoco_ball_rolling_off_a_table_edge_runs_on_without_energy_gain():
    model = mujoco.MjModel.from_xml_string(TABLE.format(tilt=0, x=0.1, z=0.05 + R))
    data = mujoco.MjData(model)
    data.qvel[0] = 0.5  # rolling toward the edge at x = 0.2
    data.qvel[4] = 0.5 / R
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "table", law())])
    mujoco.mj_forward(model, data)
    e0 = energy(model, data)
    with installed(adapter), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(500):  # off the edge at ~0.2 s, then free fall (the floor is not a pair)
            mujoco.mj_step(model, data)
            assert energy(model, data) <= e0 * (1 + ENERGY_GROWTH_MAX) + 1e-12
    # the box's edge is rounded (engines._narrow.SphereOnBox): MSF carries the ball over it, nothing is
    # handed to MuJoCo's contact (before issue 13: handed over 1 mm before the edge, warned)
    assert adapter.edge_handoffs == 0 and not caught
    assert data.qpos[0] > 0.2 and data.qpos[2] < 0.0  # it left the table


@pytest.mark.mujoco
@pytest.mark.parametrize("distance", [0.26, 0.36, 0.41, 0.46, 0.66])
def test_mujoco_far_tilted_box_is_no_error(distance):
    """The issue's scene: a ball at rest in the air next to a box tilted 11.5
    degrees, the ball's centre ``distance`` from the box's: refused at
    0.36-0.46 m before (the face test was made on a face plane far from the
    box); now no exception, and no contact."""
    model = mujoco.MjModel.from_xml_string(TABLE.format(tilt=11.5, x=distance, z=0.0).replace(
        'gravity="0 0 -9.81"', 'gravity="0 0 0"'))
    data = mujoco.MjData(model)
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "table", law())])
    adapter.step(50)
    assert not adapter.contact_forces() and adapter.edge_handoffs == 0
    np.testing.assert_allclose(data.qvel, 0.0, atol=1e-15)


@pytest.mark.pybullet
def test_pybullet_switch_and_edge():
    b = Body.sphere(preset("natural-rubber"), R)
    scene = scenes.ball_on_plate(b, 1e-9, dt=DT, gap=2e-3, gravity=G)
    c, u = scene.client, scene.body1[0]
    with scene, PybulletAdapter(c, [PairSpec(scene.body1, scene.body2, law())]) as ad:
        ad.step(800)
        (rep,) = ad.contact_forces()
        assert rep.F_n == pytest.approx(b.mass * G, rel=1e-6)
        ad.set_mode(0, "engine")
        ad.step(300)
        assert not ad.contact_forces() and pb.getContactPoints(u, scene.body2[0], physicsClientId=c)
        assert abs(pb.getBasePositionAndOrientation(u, physicsClientId=c)[0][2] - R) < 0.25 * R
        ad.set_mode(0, "off")
        ad.step(200)
        assert pb.getBasePositionAndOrientation(u, physicsClientId=c)[0][2] < 0.0
        ad.set_mode(0, "msf")
        assert ad.mode(0) == "msf"


@pytest.mark.pybullet
def test_pybullet_ball_rolling_off_a_box_edge_runs_on():
    b = Body.sphere(preset("natural-rubber"), R)
    scene = scenes.ball_on_plate(b, 1e-9, dt=DT, gap=1e-4, gravity=G, plate="box")
    c, u = scene.client, scene.body1[0]
    pos = pb.getBasePositionAndOrientation(u, physicsClientId=c)[0]
    pb.resetBasePositionAndOrientation(u, [scenes.PLATE_HALF_WIDTH - 0.01, 0, pos[2]], [0, 0, 0, 1],
                                       physicsClientId=c)
    pb.resetBaseVelocity(u, [0.5, 0, 0], [0, 0.5 / R, 0], physicsClientId=c)

    def e():
        (p, _), (v, w) = pb.getBasePositionAndOrientation(u, physicsClientId=c), pb.getBaseVelocity(u, physicsClientId=c)
        return 0.5 * b.mass * np.dot(v, v) + 0.5 * 0.4 * b.mass * R * R * np.dot(w, w) + b.mass * G * p[2]

    with scene, PybulletAdapter(c, [PairSpec(scene.body1, scene.body2, law())]) as ad:
        e0 = e()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(300):
                ad.step()
                assert e() <= e0 * (1 + 1e-6) + 1e-9
        assert ad.edge_handoffs == 0 and not caught  # MSF over the rounded edge (engines._narrow.SphereOnBox)
        assert pb.getBasePositionAndOrientation(u, physicsClientId=c)[0][0] > scenes.PLATE_HALF_WIDTH
