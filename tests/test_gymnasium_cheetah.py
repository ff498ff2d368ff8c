"""gymnasium's own HalfCheetah-v5 (its XML, Euler at 10 ms, frame_skip 5)
with MSF on every body-floor pair. Its leg joints are damped (dof_damping
1.5-6 N m s against a diagonal inertia of ~0.1-0.5 kg m^2), and MuJoCo's
Euler step takes that damping implicitly: a generalised force Q changes
the velocities by h (M + h B)^-1 Q, not h M^-1 Q (engines.mujoco._known,
euler_damping). The contacts' inverse inertia W must be that response, or
every contact predicts a motion the engine does not make (6-11 % more
velocity change per impulse: the cheetah's feet drifted from the engine's
geometry by up to 0.18 mm and its rest account rose in 563 of 1,500 steps,
docs/engines.md, gymnasium's walkers)."""
import copy
import warnings

import mujoco
import numpy as np
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, installed
from msf_contact import ContactPair, Curvature, make_law, preset

gym = pytest.importorskip("gymnasium")  # gymnasium[mujoco] is in the test extra: never skipped in CI

#: W F h against MuJoCo's own velocity change for the same force at the same
#: point: both are linear in F, so they agree to round-off when W is the
#: step's response (measured 3e-16 relative); W = J M^-1 J^T was 6-11 % off (11 % at the reset pose)
W_RTOL = 1e-9


def _cheetah():
    env = gym.make("HalfCheetah-v5")
    env.reset(seed=0)
    model, data = env.unwrapped.model, env.unwrapped.data
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER  # gymnasium's choice, kept
    assert np.any(model.dof_damping > 0)
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    pairs = [PairSpec(model.geom(g).name, "floor",
                      make_law("msf", pair, Curvature.sphere_on_plane(float(model.geom_size[g, 0]))))
             for g in range(model.ngeom)
             if model.geom_bodyid[g] != 0 and model.geom(g).name and (model.geom_contype[g] or model.geom_conaffinity[g])]
    return env, model, data, pairs


def _velocity_change(model, state, body, point, force):
    """qvel after one plain mj_step (no hook; ``model`` a copy with MuJoCo's
    contacts off, as the adapter's contact filter keeps them off for the MSF
    pairs) from ``state`` with ``force`` [N] (3,) at ``point`` [m] on ``body``
    (through qfrc_applied)."""
    d = mujoco.MjData(model)
    mujoco.mj_setState(model, d, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(model, d)
    mujoco.mj_applyFT(model, d, np.asarray(force, float), np.zeros(3), np.asarray(point, float), body, d.qfrc_applied)
    mujoco.mj_step(model, d)
    return d.qvel.copy()


def test_the_contacts_inverse_inertia_is_the_euler_steps_own_response():
    """Each pair's W (the adapter's, from the step start) times a force at
    its point, times h, equals the change of the point's velocity MuJoCo's
    Euler step makes for that force (two plain steps from the same state,
    with and without it): W is what the engine does, with the damping
    taken implicitly."""
    env, model, data, pairs = _cheetah()
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    state = np.empty(size)
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        adapter = MujocoAdapter(model, data, pairs)
        with installed(adapter):
            mujoco.mj_step(model, data)  # the reset pose has a foot on the floor: rows in the first step
    env.close()
    kin = adapter._last_kin
    assert np.asarray(kin.pair).size, "no pair was a candidate in the first step"
    h = model.opt.timestep
    plain = copy.copy(model)
    plain.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    checked = 0
    for k, i in enumerate(np.asarray(kin.pair).tolist()):
        p = adapter._pairs[i]
        if p.fixed1 or not p.fixed2:  # a robot's geom on the world's floor
            continue
        point = adapter._p1[i].copy()
        J = np.zeros((3, model.nv))
        d0 = mujoco.MjData(model)
        mujoco.mj_setState(model, d0, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        mujoco.mj_forward(model, d0)
        mujoco.mj_jac(model, d0, J, None, point, p.body1)
        free = _velocity_change(plain, state, p.body1, point, np.zeros(3))
        for F in 100.0 * np.eye(3):
            pushed = _velocity_change(plain, state, p.body1, point, F)
            engine = J @ (pushed - free)
            predicted = h * np.asarray(kin.W[k]) @ F
            assert np.allclose(predicted, engine, rtol=W_RTOL, atol=W_RTOL * np.abs(engine).max()), (i, F, predicted,
                                                                                                    engine)
        checked += 1
    assert checked
