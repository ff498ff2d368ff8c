"""MuJoCo 4's threaded batch (``mujoco.batch.Batch``) must not step an
MSF model silently with MuJoCo's own contact while the adapter's hook is
installed: today it refuses the Python hook with its own ValueError
(docs/engines.md, "Your own loop"), also while the adapter's native
mjcb_passive sits in MuJoCo's raw pointer (the batch reads the bindings'
Python hook)."""

import pytest

mujoco = pytest.importorskip("mujoco")
batch = pytest.importorskip("mujoco.batch")
pytestmark = pytest.mark.mujoco

from engines.base import PairSpec  # noqa: E402
from engines.mujoco import MujocoAdapter, installed  # noqa: E402
from msf_contact import ContactPair, Curvature, make_law, preset  # noqa: E402

XML = ('<mujoco><option timestep="0.001"/><worldbody><geom name="floor" type="plane" size="2 2 .1"/>'
       '<body name="ball" pos="0 0 0.1"><freejoint/><geom name="ball" type="sphere" size="0.02" mass="0.03"/>'
       '</body></worldbody></mujoco>')


def test_a_batch_refuses_to_step_while_the_msf_hook_is_installed():
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "floor", law)])
    b = batch.Batch(model, nsim=2, nthread=1)
    z0 = b.bind("qpos")[:, 2].copy()
    with installed(adapter):
        with pytest.raises(ValueError, match="accepts only C callbacks"):
            b.step(nstep=100)
    assert (b.bind("qpos")[:, 2] == z0).all()  # nothing stepped
    # with the native mjcb_passive in MuJoCo's raw pointer (engines.mujoco._native: put there once the ball
    # rests), the batch still sees the bindings' Python hook and refuses
    from engines.mujoco import _native

    with installed(adapter):
        for _ in range(1500):
            mujoco.mj_step(model, data)
        assert _native._STATE["slot"].value == _native._STATE["cfunc"].address
        with pytest.raises(ValueError, match="accepts only C callbacks"):
            b.step(nstep=100)
    assert (b.bind("qpos")[:, 2] == z0).all()
