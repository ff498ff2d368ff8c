"""gymnasium's own Ant-v5 (its XML, its RK4 at 10 ms, frame_skip 5, its
``env.step``) with MSF on every body-floor pair, the way a user would put it
in: nothing here was written for msf-contact. The run must stay a
simulation: no MuJoCo bad-QACC reset, no state jump, finite, the torso
below a hop's height, every flagged record warned. A working tree with
kernels cached by earlier commits (numba cannot see a change in another
module: msf_contact._jitcache) blew up in this very scene: torso at
7.9 m, MuJoCo's reset at 4.61 s (env step 92)."""
import re
import warnings

import mujoco
import numpy as np
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from msf_contact import ContactPair, Curvature, make_law, preset

gym = pytest.importorskip("gymnasium")  # gymnasium[mujoco] is in the test extra: never skipped in CI

ENV_STEPS = 100       # 500 mj_steps, 5 s: past the step (92) where the ant blew up
TORQUE_STEPS = 60     # seeded random torques, then zero (the ant settles)
# gymnasium's built-in contact under the same torques peaks the torso at
# 1.41 m (its own trajectory), the MSF run 1.25 m; the run that blew up
# passed 2.6 m two steps before MuJoCo's reset: 2 m separates a hop from an
# explosion.
TORSO_MAX = 2.0


def test_gymnasium_ant_rk4_with_msf_on_every_floor_pair_stays_stable():
    env = gym.make("Ant-v5", terminate_when_unhealthy=False)
    env.reset(seed=0)
    model, data = env.unwrapped.model, env.unwrapped.data
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4  # gymnasium's choice, kept
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    pairs = [PairSpec(model.geom(g).name, "floor",
                      make_law("msf", pair, Curvature.sphere_on_plane(float(model.geom_size[g, 0]))))
             for g in range(model.ngeom) if model.geom_bodyid[g] != 0 and model.geom(g).name]
    assert len(pairs) == 13  # torso, four hips, four legs, four ankles
    rng = np.random.default_rng(1)
    torso = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        adapter = MujocoAdapter(model, data, pairs)
        with installed(adapter):
            for i in range(ENV_STEPS):
                a = rng.uniform(-1.0, 1.0, env.action_space.shape) if i < TORQUE_STEPS else np.zeros(env.action_space.shape)
                env.step(a)
                torso.append(float(data.qpos[2]))
    env.close()
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 0, "MuJoCo reset a blown-up state"
    assert adapter.jumps == 0
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert max(torso) < TORSO_MAX, max(torso)
    assert adapter.records, "the ant's feet must have hit the floor"
    # no warning but real flags (RK4 on links is no longer warned: engines.mujoco._known), and
    # every flagged record's pair is named on stderr
    messages = [str(w.message) for w in caught]
    assert not any("RK4 on links" in m for m in messages)
    flagged = {int(r.inputs["pair"]) for r in adapter.records if r.outside_validity}
    warned = {int(n) for m in messages for n in re.findall(r"pair (\d+)", m)}
    assert all(re.search(r"pair \d+", m) for m in messages), messages  # every warning names its pair
    assert flagged <= warned, (flagged, warned)
