"""The MuJoCo adapter's body probe (records' body_in/body_out) read from cvel
against MuJoCo's own Jacobian."""

from __future__ import annotations

import mujoco
import numpy as np

from engines.mujoco.adapter import MujocoAdapter

#: Same velocity two ways (cvel transported to xipos against J(xipos) qvel):
#: round-off of a few products, 1e-12 of the largest speed.
PROBE_RTOL = 1e-12

XML = """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/>
<body name="a" pos="0 0 1"><joint type="hinge" axis="0 1 0"/>
  <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"/>
  <body name="b" pos=".3 0 0"><joint type="hinge" axis="0 0 1"/><geom type="sphere" size=".05" pos=".1 .02 0"/></body>
</body>
<body name="f" pos="0.5 0 0.3"><freejoint/><geom type="box" size=".05 .02 .03" pos=".01 .02 0"/></body>
<body name="fixed" pos="1 0 0"><geom type="sphere" size=".1"/></body>
</worldbody></mujoco>"""


def test_com_velocity_from_cvel_equals_the_jacobian():
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    d.qpos[0], d.qpos[1] = 0.3, -0.5  # bent chain: off-axis centres of mass
    d.qvel[:] = np.random.default_rng(1).normal(size=m.nv)
    mujoco.mj_forward(m, d)

    class Probe:  # the two attributes _com_velocity reads
        model, data = m, d

    scale = float(np.max(np.abs(d.qvel)))
    for b in range(1, m.nbody):
        J = np.zeros((3, m.nv))
        mujoco.mj_jac(m, d, J, None, d.xipos[b], b)
        want = np.zeros(3) if m.body_weldid[b] == 0 else J @ d.qvel
        got = MujocoAdapter._com_velocity(Probe, b)
        assert np.allclose(got, want, rtol=0, atol=PROBE_RTOL * scale), (b, got, want)
    assert np.any(MujocoAdapter._com_velocity(Probe, 2) != 0.0)  # the check is not vacuous
