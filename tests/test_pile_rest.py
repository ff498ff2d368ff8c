"""The pile's rest criterion (issue 10; scripts/pile.py REST_DOC).

MSF is a point contact with no rolling resistance (the paper's law has
none), so a sphere rolling without slip on the floor keeps its speed, its
contact at rest (zero approach rate, the static overlap of its weight):
rest in every contact, no energy gain, but never "slower than REST_SPEED".
A rigid sphere set sliding without spin on a plane ends rolling at 5/7 of
its speed (angular momentum about the contact point conserved:
m v0 R = m v R + (2/5) m R^2 v / R), whatever the friction, and keeps that.

One steel sphere (R = 10 mm) in scripts/pile.py's box, placed touching the
floor, dt = 1 ms: rolling at 4 mm/s (omega = v/R), and sliding at 4 mm/s
with no spin. Both keep their speed over the run within STEADY_RTOL, the
pile's energy E never rises beyond (dt/2)|dq| by more than round-off
(scripts/pile.py: a settled step is exact in kinetic + potential at z, E
moves by (dt/2)|dq| with no gain), and pile.RestWatch calls each
at rest (steady) from an early step, never still.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from _scripts import load_script
from msf_contact import Body
from test_multi_contact import _engine_available

V0 = 4e-3  # m/s: the 200-sphere pile's rolling sphere moved at 3.9 mm/s
STEPS = 300
#: The rolling speed's drift over the last two thirds of the run, relative: MSF has no rolling resistance,
#: and the settled floor contact (steel on steel, x_s = 0.07 um) holds the weight at zero rate. Measured
#: 8e-11 (both engines, both spins); the bound leaves room for round-off over other trajectories.
STEADY_RTOL = 1e-6
#: The final speed against V0 (rolling) or 5/7 V0 (sliding), relative: the tangential spring keeps
#: ~F_t^2 / (2 k_t) of the energy and the contact point lies x/2 below the centre's R. Measured
#: 9.2e-7 (rolling) and 6.5e-5 (sliding), both engines alike.
ROLL_RTOL = 1e-3
#: A rise of E in one step at round-off [J]: E ~ 3.3e-3 J (the sphere's potential energy above z = 0).
E_ROUNDOFF = 1e-15


def _scene(engine):
    """(pile, adapter, context, velocities(), set_state(v, omega)): one steel sphere of the box."""
    pile = load_script("pile")
    build = pile.build_mujoco if engine == "mujoco" else pile.build_pybullet
    ad, ctx, velocities = build(1, 6, 1e-3, pour="low")
    if engine == "mujoco":
        import mujoco

        def set_state(v, w):  # placed touching the floor, identity orientation: w in the body frame = world
            ad.data.qpos[2] = pile.R
            ad.data.qpos[3:7] = (1.0, 0.0, 0.0, 0.0)
            ad.data.qvel[:3], ad.data.qvel[3:6] = v, w
            mujoco.mj_forward(ad.model, ad.data)
    else:
        import pybullet as pb

        c = ad.client
        uid = pb.getBodyUniqueId(pb.getNumBodies(physicsClientId=c) - 1, physicsClientId=c)

        def set_state(v, w):
            p, _q = pb.getBasePositionAndOrientation(uid, physicsClientId=c)
            pb.resetBasePositionAndOrientation(uid, [p[0], p[1], pile.R], [0, 0, 0, 1], physicsClientId=c)
            pb.resetBaseVelocity(uid, list(v), list(w), physicsClientId=c)
    return pile, ad, ctx, velocities, set_state


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
@pytest.mark.parametrize("spin", ["rolling", "sliding"])
def test_a_rolling_sphere_rests_in_its_contacts(engine, spin):
    _engine_available(engine)
    pile, ad, ctx, velocities, set_state = _scene(engine)
    set_state((V0, 0.0, 0.0), (0.0, V0 / pile.R if spin == "rolling" else 0.0, 0.0))
    mgr = ad.manager
    keys = np.unique(mgr._coupling[0][mgr._coupling[0] >= 0])  # the sphere's body key (scripts/pile.py run)
    seq, hq = [], []
    inner = mgr.step

    def step(kin):  # E and (dt/2) q at each step start, inside the hook (scripts/pile.py run)
        hq.append(0.5 * mgr.dt * float(np.sum(pile._probe(ad, keys)[2])))
        seq.append(pile.energy(ad, keys))
        return inner(kin)

    mgr.step = step
    b = Body.sphere(pile.STEEL, pile.R)
    watch = pile.RestWatch([b.mass], [b.J], 1e-3)
    speeds = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ctx:
            for k in range(STEPS):
                ad.step(1)
                vel = velocities()
                watch.update(k, vel)
                speeds.append(float(np.linalg.norm(vel[0, 0])))
    speeds = np.array(speeds)
    v_roll = V0 if spin == "rolling" else 5 / 7 * V0
    assert abs(speeds[-1] - v_roll) <= ROLL_RTOL * v_roll, (speeds[-1], v_roll)
    assert np.ptp(speeds[STEPS // 3:]) <= STEADY_RTOL * v_roll, np.ptp(speeds[STEPS // 3:])
    rise = np.diff(seq) - np.abs(np.diff(hq))  # E's rise beyond (dt/2)|dq| (scripts/pile.py: no gain)
    assert float(rise.max()) <= E_ROUNDOFF, (int(np.argmax(rise)), float(rise.max()))
    assert watch.still_from is None  # 2.9-4 mm/s: never still
    assert watch.rest_from is not None and watch.rest_from < STEPS // 3, watch.rest_from
