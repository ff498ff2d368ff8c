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


#: gymnasium's Ant-v5 (RK4, 10 ms) under action seed 3 of scripts/gym_check.py, 300 env
#: steps of torques, then rest mj_step 90: in flight, turning at 8.6 rad/s, its torso
#: (sphere, 0.25 m) 0.126 m above the floor, landing at 2.7 m/s (rounded to the
#: digits printed: the old reading's rise below is the run's to 6e-7 J)
ANT_IN_FLIGHT_QPOS = (-7.375937, -3.776473, 0.37613, -0.043565, -0.802546, 0.552152, -0.2217, -0.385734,
                      1.221183, -0.460069, -0.847747, -0.448013, -1.222375, 0.51512, 0.96389)
ANT_IN_FLIGHT_QVEL = (0.44453, -3.181, -2.4447, -4.8249, -7.00413, 1.12523, 0.17892, -0.00756, -0.01392,
                      -0.01356, -0.0283, 0.00633, -0.0749, 0.28459)
#: steps from that state: the landing (a correction pending after steps 5-7, the torso's
#: contact begun at the end of step 5 and ended inside 6; the old reading's 0.26 J in step 7)
LANDING_STEPS = 12
#: a step replayed with nothing taken out is the step itself: the same forces through the same
#: MuJoCo calls from the same start state (measured: bit for bit, 0 m/s, in the three steps with
#: a correction pending); 1e-9 m/s leaves room for a replay whose sums run in another order
REPLAY_ATOL = 1e-9


def _ant_in_flight():
    env = gym.make("Ant-v5", terminate_when_unhealthy=False)
    env.reset(seed=0)
    model, data = env.unwrapped.model, env.unwrapped.data
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    pairs = [PairSpec(model.geom(g).name, "floor",
                      make_law("msf", pair, Curvature.sphere_on_plane(float(model.geom_size[g, 0]))))
             for g in range(model.ngeom) if model.geom_bodyid[g] != 0 and model.geom(g).name]
    data.qpos[:], data.qvel[:], data.ctrl[:] = ANT_IN_FLIGHT_QPOS, ANT_IN_FLIGHT_QVEL, 0.0
    mujoco.mj_forward(model, data)
    return env, model, data, MujocoAdapter(model, data, pairs)


def test_the_rk4_ants_landing_reads_no_energy_gain():
    """RestEnergy after the torso's landing (issue 13, Ant-v5 seed 3's 0.244 J):
    the step's timing correction J (an impulse applied in the landing step and
    removed in the next) was taken out of qvel as M^-1 J^T J at the end pose,
    while RK4 applied it through its four stages at theirs (the torso turning
    at 8.6 rad/s, the legs swinging): the account read the step after the
    landing 0.26 J high (0.016 J allowed). Now it is the landing step replayed
    without J (MujocoAdapter.exact_offset): no step above the bound, and a
    replay that takes nothing out is the real step."""
    from engines.mujoco.robots import RestEnergy

    env, model, data, adapter = _ant_in_flight()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # RestEnergy warns a step above its bound
        with installed(adapter):
            account = RestEnergy(model, data, adapter)
            landed = False
            for _ in range(LANDING_STEPS):
                mujoco.mj_step(model, data)
                account.update()
                if np.any(adapter.manager.J):
                    landed = True
                    assert np.max(np.abs(adapter._replayed_offset(np.array([], int)))) < REPLAY_ATOL
    env.close()
    assert landed, "the torso must land within the steps"
    assert account.gains == [], account.gains
