"""The adapter's own scratch MjData is no user's: under MuJoCo's implicit
integrators the adapter evaluates the step's response on a scratch MjData
(engines.mujoco._known.StepResponse: mj_fwdVelocity, which calls the process's
mjcb_passive); that call must not warn that an MjData steps without MSF (it
did, for any model with a hinge under implicit or implicitfast), while a
second MjData the user steps still is warned. And a model in which MuJoCo
never calls mjcb_passive is refused."""

import warnings

import mujoco
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from msf_contact import ContactPair, Curvature, make_law, preset

UNMANAGED = "mjcb_passive was called for an MjData that has no MSF adapter"


def _model(integrator):
    xml = f"""<mujoco><option timestep="0.001" integrator="{integrator}"/><worldbody>
      <geom name="floor" type="plane" size="1 1 .1"/>
      <body name="arm" pos="0 0 0.05"><joint type="hinge" axis="0 1 0" pos="-0.1 0 0"/>
        <geom name="ball" type="sphere" size="0.02" mass="0.0312"/></body></worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def _adapter(model, data):
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    return MujocoAdapter(model, data, [PairSpec("ball", "floor", law)])


@pytest.mark.mujoco
@pytest.mark.parametrize("integrator", ["implicit", "implicitfast"])
def test_the_scratch_data_of_an_implicit_step_is_not_warned(integrator):
    model = _model(integrator)
    data = mujoco.MjData(model)
    adapter = _adapter(model, data)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with installed(adapter):
            for _ in range(300):
                mujoco.mj_step(model, data)
    assert adapter.records, "the hinged ball did not bounce"
    assert not [w for w in caught if UNMANAGED in str(w.message)]


@pytest.mark.mujoco
def test_a_second_user_data_is_still_warned():
    model = _model("implicitfast")
    data, other = mujoco.MjData(model), mujoco.MjData(model)
    adapter = _adapter(model, data)
    with installed(adapter):
        mujoco.mj_step(model, data)
        with pytest.warns(RuntimeWarning, match=UNMANAGED):
            mujoco.mj_step(model, other)


@pytest.mark.mujoco
def test_springs_and_dampers_both_disabled_is_refused():
    """MuJoCo skips mj_passive, and the mjcb_passive MSF works in, when both
    springs and dampers are disabled: a rubber ball fell through its floor
    with no record and no word. Refused at construction, at install and at
    adapter.step (the flags may change in between)."""
    model = _model("Euler")
    data = mujoco.MjData(model)
    off = mujoco.mjtDisableBit
    adapter = _adapter(model, data)
    model.opt.disableflags |= off.mjDSBL_SPRING  # one of the two: mj_passive still runs
    adapter.step(2)
    model.opt.disableflags |= off.mjDSBL_DAMPER
    with pytest.raises(ValueError, match="disables both spring and damper"):
        _adapter(model, data)
    with pytest.raises(ValueError, match="disables both spring and damper"):
        with installed(adapter):
            pass
    with pytest.raises(ValueError, match="disables both spring and damper"):
        adapter.step(1)
