"""The MuJoCo adapter never continues silently after MuJoCo resets a blown-up state."""

import mujoco
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter
from msf_contact import ContactPair, Curvature, make_law, preset

XML = """
<mujoco>
  <option timestep="0.001"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 0.1"><freejoint/><geom name="ball" type="sphere" size="0.02" mass="0.03"/></body>
  </worldbody>
  <contact><exclude body1="world" body2="ball"/></contact>
</mujoco>
"""


@pytest.mark.mujoco
def test_bad_acceleration_reset_raises():
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "floor", law)])
    adapter.step(2)  # a sane step passes
    data.xfrc_applied[1, 2] = 1e20  # an acceleration far above MuJoCo's bound
    with pytest.raises(RuntimeError, match="bad acceleration"):
        adapter.step(1)


@pytest.mark.mujoco
def test_law_for_another_radius_is_refused():
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.03))
    with pytest.raises(ValueError, match="curvature R1a = 0.03 m does not match the engine shape's radius 0.02"):
        MujocoAdapter(model, data, [PairSpec("ball", "floor", law)])
