"""A link held by a MuJoCo position servo (issue 11, item 6): the paddle's
rebound COR does not depend on the engine step from 0.2 to 2 ms.

The sub-cycle uses the links' inertia (W = J M^-1 J^T); the servo acts on
the paddle one step late, through a_ext. Measured by this test:
a 0.5 kg paddle on a hinge held by kp = 1000 N m/rad (omega = 387 rad/s),
a rubber ball at 2 m/s: COR within 1.9 % of the 0.1 ms run up to 2 ms
(Euler), 1.2 % (RK4); the issue's bound is 2 %.
"""

from __future__ import annotations

import warnings

import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, run_until_separated, scenes
from msf_contact import Body, ContactPair, Curvature, make_law, preset

pytestmark = pytest.mark.mujoco

#: The issue's bound on the COR's dependence on the step for a held link.
HELD_COR_RTOL = 0.02


def cor(dt, integrator):
    b = Body.sphere(preset("natural-rubber"), 0.02)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    model, data = scenes.paddle_and_ball(b, 2.0, dt=dt, integrator=integrator, kp=1000.0, gap=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return run_until_separated(MujocoAdapter(model, data, [PairSpec("ball", "paddle", law)]), 100_000).cor_n


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_servo_held_paddle_cor_over_steps(integrator):
    ref = cor(1e-4, integrator)
    for dt in (2e-4, 5e-4, 1e-3, 2e-3):
        assert cor(dt, integrator) == pytest.approx(ref, rel=HELD_COR_RTOL), dt
