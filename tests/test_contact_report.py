"""The MSF contact forces are visible to the engines' tools (issue 11, item 3).

``adapter.contact_forces()`` gives each pair's step-averaged force in SI
(names, point, normal, F_n, F_t, overlap) in both engines; in MuJoCo a user
sensor on a managed geom reads the force through MuJoCo's own sensordata
(mjcb_sensor). A ball resting on the floor must read m g.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pybullet as pb
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from engines.pybullet import PybulletAdapter, scenes
from msf_contact import Body, ContactPair, Curvature, make_law, preset

R, MASS, G, DT = 0.02, 0.0312, 9.81, 1e-3
#: A ball at rest: the settled path balances F_n(x_s, 0) = m g exactly, to the
#: Newton tolerance of the settled solve (engines._contacts.state.SETTLED_VTOL).
REST_RTOL = 1e-6
XML = f"""
<mujoco>
  <option timestep="{DT}" gravity="0 0 -{G}"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 {R + 2e-3}">
      <freejoint/>
      <site name="under" pos="0 0 0" size="0.021"/>
      <geom name="ball" type="sphere" size="{R}" mass="{MASS}"/>
    </body>
  </worldbody>
  <contact><exclude body1="world" body2="ball"/></contact>
  <sensor>
    <user name="msf_fn" objtype="geom" objname="ball" dim="1" needstage="acc"/>
    <user name="msf_floor" objtype="geom" objname="floor" dim="3" needstage="acc"/>
    <touch name="touch" site="under"/>
  </sensor>
</mujoco>
"""


def law():
    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))


def static_overlap(lw, weight):
    """x_s with F_n(x_s, 0) = m g (bisection on the law's elastic force)."""
    onset = lw.onset(np.array([1e-3]), MASS)
    lo, hi = 0.0, 0.5 * R
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        F = float(lw.contact_normal_force(np.array([mid]), np.array([0.0]), onset)[0])
        lo, hi = (mid, hi) if F < weight else (lo, mid)
    return lo


@pytest.mark.mujoco
def test_mujoco_resting_ball_reads_its_weight_in_the_api_and_a_user_sensor():
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "floor", law())])
    with installed(adapter):
        for _ in range(1500):
            mujoco.mj_step(model, data)
        (rep,) = adapter.contact_forces()
        weight = MASS * G
        assert (rep.body1, rep.body2, rep.pair) == ("ball", "floor", 0)
        assert rep.F_n == pytest.approx(weight, rel=REST_RTOL)
        np.testing.assert_allclose(rep.normal, [0, 0, 1], atol=1e-12)
        assert np.linalg.norm(rep.F_t) <= REST_RTOL * weight
        np.testing.assert_allclose(rep.force, rep.F_n * rep.normal + rep.F_t, rtol=0, atol=1e-15)
        assert rep.overlap == pytest.approx(static_overlap(adapter.pairs[0].law, weight), rel=1e-3)
        assert rep.t == pytest.approx(data.time - DT, abs=1e-12)  # the step just taken
        # MuJoCo's own sensordata, filled by the adapter's mjcb_sensor
        fn = data.sensor("msf_fn").data
        floor = data.sensor("msf_floor").data
        assert fn[0] == pytest.approx(weight, rel=REST_RTOL)
        np.testing.assert_allclose(floor, -rep.force, rtol=0, atol=1e-15)
        # MuJoCo's touch sensor sees only MuJoCo's own contacts: none here (documented)
        assert data.sensor("touch").data[0] == 0.0 and data.ncon == 0
        # ... and cfrc_ext too: MSF's force is a passive force, in qfrc_passive (documented)
        mujoco.mj_rnePostConstraint(model, data)
        assert not np.any(data.cfrc_ext[model.body("ball").id])
        assert data.qfrc_passive[2] == pytest.approx(weight, rel=REST_RTOL)
    assert mujoco.get_mjcb_sensor() is None and mujoco.get_mjcb_passive() is None


@pytest.mark.mujoco
def test_mujoco_records_carry_the_pair_names():
    model = mujoco.MjModel.from_xml_string(XML.replace(f'pos="0 0 {R + 2e-3}"', 'pos="0 0 0.1"'))
    adapter = MujocoAdapter(model, mujoco.MjData(model), [PairSpec("ball", "floor", law())])
    adapter.step(200)
    assert adapter.records and adapter.records[0].inputs["body1"] == "ball"
    assert adapter.records[0].inputs["body2"] == "floor"


@pytest.mark.pybullet
def test_pybullet_resting_ball_reads_its_weight_and_names():
    b = Body.sphere(preset("natural-rubber"), R)
    scene = scenes.ball_on_plate(b, 1e-9, dt=DT, gap=2e-3, gravity=G)
    with scene, PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law())]) as ad:
        ad.step(1500)
        (rep,) = ad.contact_forces()
        weight = b.mass * G
        assert rep.F_n == pytest.approx(weight, rel=REST_RTOL)
        assert np.linalg.norm(rep.F_t) <= REST_RTOL * weight
        names = pb.getBodyInfo(scene.body1[0], physicsClientId=scene.client)
        assert rep.body1 == f"body{scene.body1[0]}/{names[0].decode()}"
        assert ad.records[0].inputs["body1"] == rep.body1 and ad.records[0].inputs["body2"] == rep.body2
