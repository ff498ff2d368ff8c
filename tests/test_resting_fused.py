"""The MuJoCo adapter's resting step in one compiled call
(engines.mujoco._resting) against the general path it replaces
(``adapter.fused = False``): the same scene stepped by both must give the
same engine state, forces, contact state and records bit for bit, since the
one call runs the same compiled passes in the same order. Checked where
the resting step is taken most steps and where it has to hand back to the
general path (a sphere lifted off its contact, one pushed to slide, a
sphere resting on a fixed sphere: the held sphere-sphere geometry), under
semi-implicit Euler and RK4 (whose later stages apply the resting step's
forces as the general path's)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import engines.mujoco._resting as resting
from engines.mujoco import _native
from engines.base import PairSpec
from engines.mujoco import MujocoAdapter
from msf_contact import Body, ContactPair, Curvature, make_law, preset

pytestmark = pytest.mark.mujoco

RUBBER, STEEL = preset("natural-rubber"), preset("steel")
R = 0.02
DT = 1e-3
#: the manager's per-pair state compared after the runs
STATE = ("active", "settled", "x", "xdot", "s", "vc", "J", "dv_corr", "dvc_corr", "_fl", "_off", "_xd0", "_an",
         "W_el", "W_visc", "Q_t", "W_t", "phase", "turned", "outside", "_listed", "_point", "couple")


def _scene(n: int, on_sphere: bool, integrator: str = "Euler"):
    """n rubber spheres (R = 20 mm) over a steel plate, seeded gaps of 0-0.5 mm (as
    benchmarks/spheres.py); with on_sphere, one more rubber sphere balanced on a fixed
    steel sphere. Returns (model, data, pairs)."""
    law = make_law("msf", ContactPair(RUBBER, STEEL), Curvature(R, R, math.inf, math.inf))
    ball = Body.sphere(RUBBER, R)
    gaps = np.random.default_rng(3).uniform(0.0, 5e-4, n)
    side = math.ceil(math.sqrt(n))
    body = ('<body name="b{i}" pos="{x!r} {y!r} {z!r}"><freejoint/><inertial pos="0 0 0" mass="{m!r}" '
            'diaginertia="{J!r} {J!r} {J!r}"/><geom name="g{i}" type="sphere" size="{R!r}" contype="0" '
            'conaffinity="0"/></body>')
    xml = [body.format(i=i, x=(i % side) * 3 * R, y=(i // side) * 3 * R, z=R + float(gaps[i]), m=float(ball.mass), J=float(ball.J), R=R)
           for i in range(n)]
    pairs = [PairSpec(f"g{i}", "plate", law) for i in range(n)]
    if on_sphere:
        Rs = 0.05
        xml.append(f'<geom name="anvil" type="sphere" size="{Rs!r}" pos="-0.2 0 {Rs!r}" contype="0" conaffinity="0"/>')
        xml.append(body.format(i=n, x=-0.2, y=0.0, z=2 * Rs + R + 1e-4, m=float(ball.mass), J=float(ball.J), R=R))
        pairs.append(PairSpec(f"g{n}", "anvil", make_law("msf", ContactPair(RUBBER, STEEL), Curvature(R, R, Rs, Rs))))
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><option timestep="{DT!r}" integrator="{integrator}" gravity="0 0 -9.81"/><worldbody>'
        f'<geom name="plate" type="plane" size="0 0 1" contype="0" conaffinity="0"/>{"".join(xml)}'
        "</worldbody></mujoco>")
    return model, mujoco.MjData(model), pairs


def _run(fused: bool, n: int, steps: int, on_sphere: bool, pushes: dict, integrator: str):
    """Step the scene; pushes {step: (body, xfrc (6,))} set data.xfrc_applied from that step
    on. Returns the adapter and the engine state (qpos, qvel, qfrc_passive) of every step."""
    model, data, pairs = _scene(n, on_sphere, integrator)
    data.qpos[7 * 3 + 2] += 3e-3  # sphere 3 lands later, spinning: the moving contact point until it settles
    data.qvel[6 * 3 + 3] = 5.0
    ad = MujocoAdapter(model, data, pairs)
    ad.fused = fused
    trace = []
    with ad:
        for s in range(steps):
            for b, f in pushes.get(s, ()):
                data.xfrc_applied[b] = f
            ad.step(1)
            trace.append((data.qpos.copy(), data.qvel.copy(), data.qfrc_passive.copy()))
    return ad, trace


@pytest.mark.parametrize("on_sphere, integrator", [(False, "Euler"), (True, "Euler"), (False, "RK4")])
def test_resting_step_in_one_call_is_the_general_path_bit_for_bit(monkeypatch, on_sphere, integrator):
    taken = {True: 0, False: 0}
    real = resting.step

    def counting(ad, factor):
        out = real(ad, factor)
        taken[out[0]] += 1
        return out

    monkeypatch.setattr(resting, "step", counting)
    # the Python hook's resting step (the native hook, which would take most of these steps, is held to
    # this one in tests/test_native_passive.py)
    monkeypatch.setattr(_native, "attach", lambda *a: None)
    n, steps = 9, 700
    # from step 500: body 1 (sphere 0) lifted off the plate for 30 steps, body 2 pushed sideways
    pushes = {500: [(1, [0, 0, 20.0, 0, 0, 0]), (2, [2.0, 0, 0, 0, 0, 0])],
              530: [(1, [0.0] * 6), (2, [0.0] * 6)]}
    general, want = _run(False, n, steps, on_sphere, pushes, integrator)
    assert taken == {True: 0, False: 0}, "the general path took the resting step"
    fused, got = _run(True, n, steps, on_sphere, pushes, integrator)
    assert taken[True] > steps // 3, f"the resting step was taken in {taken[True]} of {steps} steps"
    assert taken[False] > 0, "no step went back to the general path: the hand-back is not tested"
    for s, (g, w) in enumerate(zip(got, want)):
        for name, a, b in zip(("qpos", "qvel", "qfrc_passive"), g, w):
            assert np.array_equal(a, b), f"step {s + 1}: {name} differs"
    mg, mw = fused.manager, general.manager
    for name in STATE:
        assert np.array_equal(getattr(mg, name), getattr(mw, name), equal_nan=True), f"manager.{name} differs"
    for name in ("_last_v", "_last_dv", "_x_last", "_p1", "_p2"):
        assert np.array_equal(getattr(fused, name), getattr(general, name)), f"adapter.{name} differs"
    assert mg.last_step_info == mw.last_step_info
    rg, rw = fused.records, general.records
    assert len(rg) == len(rw) and len(rw) >= n  # every sphere's first impact, and the lifted one's end
    for a, b in zip(rg, rw):
        assert (a.cor_n, a.tau, a.x_max, a.F_max) == (b.cor_n, b.tau, b.x_max, b.F_max)
    reports = [(r.pair, r.force.tolist(), r.overlap) for r in fused.contact_forces()]
    assert reports == [(r.pair, r.force.tolist(), r.overlap) for r in general.contact_forces()]
