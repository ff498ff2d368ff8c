"""Domain randomisation changes a model between episodes; an MSF geom whose
size or pose in its body changed after the adapter was made is refused
(its law's curvature and the contact geometry were taken from it then): a
ball's radius set from 0.02 to 0.03 m kept the contact at 0.02 m, the ball
resting 10 mm inside the floor, with no word. Other changes (a mass) are
read every step and stay allowed."""

import mujoco
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from msf_contact import ContactPair, Curvature, make_law, preset

XML = """<mujoco><option timestep="0.001"/><worldbody><geom name="floor" type="plane" size="1 1 .1"/>
<body name="b" pos="0 0 0.1"><freejoint/><geom name="ball" type="sphere" size="0.02" mass="0.0312"/></body>
</worldbody></mujoco>"""


def _setup():
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    return model, data, MujocoAdapter(model, data, [PairSpec("ball", "floor", law)])


@pytest.mark.mujoco
def test_a_changed_geom_size_is_refused_at_install_step_and_reset():
    model, data, adapter = _setup()
    model.geom_size[1, 0] = 0.03
    with pytest.raises(RuntimeError, match=r"geom_size of the MSF geom 'ball' changed from \[0.02, 0.0, 0.0\] to "
                                           r"\[0.03, 0.0, 0.0\]"):
        with installed(adapter):
            pass
    with pytest.raises(RuntimeError, match="geom_size of the MSF geom 'ball'"):
        adapter.step(1)
    model.geom_size[1, 0] = 0.02
    with installed(adapter):
        for _ in range(50):
            mujoco.mj_step(model, data)
        model.geom_pos[1, 2] = 0.005  # randomised between episodes, then the episode's reset
        mujoco.mj_resetData(model, data)
        with pytest.raises(RuntimeError, match="geom_pos of the MSF geom 'ball'"):
            mujoco.mj_step(model, data)


@pytest.mark.mujoco
def test_a_changed_mass_is_still_allowed():
    model, data, adapter = _setup()
    model.body_mass[1] *= 2
    adapter.step(300)
    assert adapter.records  # it bounced
