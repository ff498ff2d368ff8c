"""MuJoCo pairs named by body or by geom id: the geoms of gymnasium's and most
robot files carry no names (Pusher-v5's object, its wrist capsules), so a pair
side may be a geom name, a geom id or a body name (each of the body's geoms that
can collide). Each way of naming the same geoms gives the same contact."""

import mujoco
import numpy as np
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from msf_contact import ContactPair, Curvature, make_law, preset

R = 0.02
# a rubber ball dropped on the world's plane; the geoms unnamed, the bodies named (MuJoCo names the world)
XML = f"""
<mujoco>
  <option timestep="0.001"/>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 0.06"><freejoint/><geom type="sphere" size="{R}" mass="0.0312"/>
      <geom type="sphere" size="0.005" pos="0 0 0.01" contype="0" conaffinity="0" mass="0.001"/></body>
    <body name="ghost" pos="1 0 0.5"><freejoint/><geom type="box" size="0.01 0.01 0.01" contype="0"
      conaffinity="0"/></body>
  </worldbody>
</mujoco>
"""


def _law():
    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))


def _drop(side1, side2, steps=300):
    """(records' (cor_n, tau), final qpos, the adapter's pair names) of the ball dropped with the pair named so."""
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    adapter = MujocoAdapter(model, data, [PairSpec(side1, side2, _law())])
    with installed(adapter):
        for _ in range(steps):
            mujoco.mj_step(model, data)
    return [(r.cor_n, r.tau) for r in adapter.pop_records()], data.qpos.copy(), adapter.pair_names


@pytest.mark.mujoco
def test_body_names_and_geom_ids_reach_unnamed_geoms():
    """By body names ("ball", "world": the ball's one geom that can collide, the world's plane) and by geom
    ids (1, 0) the ball bounces the same, to the bit, and the records name the geoms by body and id; the ball's
    second geom (contype = conaffinity = 0) is not paired."""
    by_body = _drop("ball", "world")
    by_id = _drop(1, 0)
    assert by_body[0], "the ball did not bounce"
    assert by_body[0] == by_id[0]
    assert np.array_equal(by_body[1], by_id[1])
    assert by_body[2] == [("ball/geom 1", "world/geom 0")] == by_id[2]
    cor, tau = by_body[0][0]
    assert 0.6 < cor < 0.8 and 1e-3 < tau < 5e-3  # a rubber ball's bounce (the demo's COR 0.728), not a pass-through


@pytest.mark.mujoco
def test_bad_names_are_refused():
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    with pytest.raises(ValueError, match="'balll' is neither a geom name, a geom id nor a body name.*'ball'"):
        MujocoAdapter(model, data, [PairSpec("balll", "world", _law())])
    with pytest.raises(ValueError, match=r"body2 = 7 is not a geom id of the model \(0 <= id < ngeom = 4\)"):
        MujocoAdapter(model, data, [PairSpec("ball", 7, _law())])
    with pytest.raises(ValueError, match="'ghost' is a body with no geom that can collide"):
        MujocoAdapter(model, data, [PairSpec("ghost", "world", _law())])
