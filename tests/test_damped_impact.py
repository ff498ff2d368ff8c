"""A damped link's impact at a large step under MuJoCo's implicit damping
is flagged and warned (issue 13; engines.mujoco.adapter.DAMPED_SHARE_MIN,
MujocoAdapter._check_damped_onsets; scripts/damped_impact.py)."""
import pytest

from _scripts import load_script

pytestmark = pytest.mark.mujoco


@pytest.fixture(scope="module")
def damped_impact():
    return load_script("damped_impact")


def test_a_strongly_damped_arms_impact_at_10_ms_is_flagged(damped_impact):
    """The hinged arm (I = 4.45e-3 kg m^2) into the floor at 1 m/s, B = 0.5
    N m s, dt = 10 ms (h B / I = 1.13, the step leaving 0.47 of an impulse's
    velocity change): the contact takes the damper for added inertia and its
    step rises above RestEnergy's bound (measured 34 mJ); its record is
    flagged and the adapter counts it."""
    out = damped_impact.run(0.5, 0.01)
    assert out["flagged"] and out["damped_onsets"] == 1
    assert out["gains"] == 1  # the gain the flag says (not corrected)


@pytest.mark.parametrize("B, dt", [(0.1, 0.01), (0.5, 0.001), (0.0, 0.01)])
def test_a_lightly_damped_or_resolved_impact_is_not_flagged(damped_impact, B, dt):
    """h B / I = 0.23 at 10 ms, 0.11 at 1 ms, 0 (the step leaves 0.81, 0.90,
    1 of the velocity change, above DAMPED_SHARE_MIN): no flag, and no step
    above RestEnergy's bound (measured)."""
    out = damped_impact.run(B, dt)
    assert not out["flagged"] and out["damped_onsets"] == 0 and out["gains"] == 0
