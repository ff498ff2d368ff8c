"""Models nobody here wrote (issue 13): ``ant.xml`` and ``humanoid.xml``
from ``pybullet_data/mjcf`` in MuJoCo at their own time steps, MSF on every
body-floor contact (engines.mujoco.robots), under seeded random torques,
then with the torques off. The suite runs a short stretch (60 steps of
torques, 60-100 steps without, while the robot still settles onto the
floor); the 1,000-step runs, the energy at rest and the cost against
MuJoCo's own contact are ``benchmarks/robots.py`` (make bench)."""

import os

import numpy as np
import pytest

from msf_contact import ContactPair, preset

mujoco = pytest.importorskip("mujoco")
pybullet_data = pytest.importorskip("pybullet_data")
pytestmark = pytest.mark.mujoco

from engines.mujoco import MujocoAdapter, installed  # noqa: E402
from engines.mujoco.robots import load_with_msf_floor, mechanical_energy  # noqa: E402

SEED = 13
#: With the torques off the mechanical energy may rise by float rounding
#: only; a step's worth of MSF impulse is far above (measured here after the
#: first fifth of that phase: no rise at all, ant 11.7 -> 5.1 J, humanoid
#: 381 -> 328 J).
ENERGY_ATOL = 1e-6


@pytest.mark.parametrize("name,torque_steps,rest_steps", [("ant.xml", 60, 60), ("humanoid.xml", 60, 100)])
def test_robot_model_runs_and_gains_no_energy_without_torques(name, torque_steps, rest_steps):
    path = os.path.join(pybullet_data.getDataPath(), "mjcf", name)
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(SEED)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    with installed(adapter):
        for _ in range(torque_steps):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
        data.ctrl[:] = 0.0
        E = []
        for _ in range(rest_steps):
            mujoco.mj_step(model, data)
            E.append(mechanical_energy(model, data, data.qvel - adapter.velocity_offset()) + adapter.manager.stored_energy())
    assert adapter.jumps == 0
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert adapter.records  # MSF carried the robot: its contacts with the floor began and ended
    E = np.array(E)
    start = rest_steps // 5
    assert np.max(E[start:] - E[start]) <= ENERGY_ATOL


def _pressed_bar(integrator: str, torque: float):
    """A rubber box bar (100 x 20 x 20 mm, 0.2 kg, edge radius 5 mm: its
    corners touch, solved together) on a hinge at one end, lying 1 mm above a steel floor, no
    gravity, dt = 10 ms, pressed down by a motor on during steps 10-19 with
    ``torque`` [N m], then released: (adapter, warnings)."""
    import warnings

    from engines.base import PairSpec
    from msf_contact import Curvature, make_law

    r = 0.01
    xml = (f'<mujoco><option timestep="0.01" integrator="{integrator}" gravity="0 0 0"/><worldbody>'
           '<geom name="floor" type="plane" size="1 1 0.1"/>'
           f'<body name="bar" pos="0 0 {r + 0.001}"><joint name="hinge" type="hinge" axis="0 1 0"/>'
           f'<geom name="g" type="box" pos="0.05 0 0" size="0.05 {r} {r}" mass="0.2"/></body></worldbody>'
           '<actuator><motor joint="hinge" gear="1" ctrlrange="-10 10"/></actuator>'
           '<contact><exclude body1="world" body2="bar"/></contact></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(5e-3))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        adapter = MujocoAdapter(model, data, [PairSpec("g", "floor", law)], edge_radii={"g": 5e-3})
        with installed(adapter):
            for i in range(40):
                data.ctrl[0] = torque if 10 <= i < 20 else 0.0
                mujoco.mj_step(model, data)
    return adapter, [str(w.message) for w in caught]


def test_a_link_found_deep_at_its_onset_is_flagged_and_warned():
    """Never silent (issue 13, the MSF ant): a motor switched on inside a
    step drives a link into the floor further than the contacts' free flight
    puts it (their a_ext has the motor from this step on,
    MujocoAdapter._actuation_change, but semi-implicit Euler moves the bar
    by dt^2 a, the free flight by dt^2 a / 2: 1.5 against 0.75 mm toward
    a 1 mm gap), and its corners begin already overlapping, holding elastic
    energy no force worked for (measured under Euler: 0.48 mm, 1.4 mJ, 1.8
    times the contacts' approach energy, COR 1.52; the resting ant's feet
    0.2-0.4 mm, up to 3.4 mJ; the ant's ankle under RK4 26 mm, 111 J, COR
    3.9, when the drives were seen a step late). Each such contact is
    flagged in its outside_validity and warned once per pair."""
    adapter, messages = _pressed_bar("Euler", 0.1)
    assert adapter.deep_onsets >= 1
    deep = [m for m in messages if "deep at its onset" in m]
    assert deep and len(deep) == len({m.split(":")[0] for m in deep})  # once per pair
    assert any(any("deep at its onset" in note for note in r.outside_validity) for r in adapter.records)
    assert not any("under RK4" in m for m in messages)


def test_rk4_on_links_is_warned_once_naming_the_fix():
    """MSF pairs on links of a chain under RK4 (the contact's force held
    through the four stages, constraint forces seen a step late; free bodies
    are as under Euler): one RuntimeWarning naming the pairs and the fix."""
    adapter, messages = _pressed_bar("RK4", 0.0)
    rk4 = [m for m in messages if "under RK4 on links" in m]
    assert len(rk4) == 1 and "smaller timestep" in rk4[0] and "('g', 'floor')" in rk4[0]


#: A pendulum held at rest by its joint limit: the limit's stored energy
#: against 1/2 f r of MuJoCo's own constraint force; measured 1e-6 (the
#: solver's residual); the stiffness D K alone, without the impedance, was 5 %
#: above.
LIMIT_ENERGY_RTOL = 1e-3


def test_limit_energy_is_the_limit_spring_of_mujocos_own_force():
    """engines.mujoco.robots.limit_energy against an independent reading: a
    1 kg bar (300 mm) on a hinge limited to +-10 deg, let go beyond the limit
    under gravity and settled: the solver's static force f on the limit row
    and its violation r give the spring's 1/2 f r."""
    from engines.mujoco.robots import limit_energy

    xml = ('<mujoco><option timestep="0.001"/><worldbody><body name="p" pos="0 0 1">'
           '<joint name="h" type="hinge" axis="0 1 0" range="-10 10" limited="true"/>'
           '<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[0] = np.radians(10.0)
    for _ in range(5000):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    n = data.nefc
    rows = data.efc_type[:n] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
    assert rows.sum() == 1 and abs(data.qvel[0]) < 1e-9
    r = float((data.efc_pos - data.efc_margin)[:n][rows][0])
    f = float(data.efc_force[:n][rows][0])
    assert r < 0 and f > 0
    assert limit_energy(model, data) == pytest.approx(0.5 * f * abs(r), rel=LIMIT_ENERGY_RTOL)
    assert mechanical_energy(model, data, limits=True) - mechanical_energy(model, data) == pytest.approx(
        0.5 * f * abs(r), rel=LIMIT_ENERGY_RTOL)


#: A pendulum's tip against the reference solver's sphere of the tip's
#: effective mass I/l^2: the arm turns ~0.012 rad during the contact (the
#: tip's arc and the arm's turn are outside the reference's straight-line
#: impact). Measured: COR +5.6e-5 to +6.5e-5, tau -5.6e-4 to -6.0e-4 under
#: Euler, RK4 and implicitfast at 1 and 10 ms; the engine's outgoing tip
#: speed (timing correction taken out) against the record's COR: RK4
#: +2.5e-4, Euler +6.9e-4 at 10 ms.
PENDULUM_RTOL = 1e-3


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_a_link_under_rk4_bounces_with_the_reference_cor(dt):
    """A single link under RK4 (a hinged arm, 0.2 m, with a rubber sphere of
    10 mm at its tip, gravity off) swinging into a steel floor at 0.5 m/s,
    the contact (4.8 ms) spread over 5 steps or inside one: the record's COR
    and tau are the reference solver's with the tip's effective mass, within
    PENDULUM_RTOL, no contact found deep at its onset, and the arm leaves
    at the record's COR. (RK4 on links stays warned: on driven links, the
    ant, see docs/engines.md "RK4 on links".)"""
    import math
    import warnings

    from engines.base import PairSpec
    from engines.mujoco import run_until_separated
    from msf_contact import Body, Curvature, make_law, simulate_impact

    rubber, steel = preset("natural-rubber"), preset("steel")
    r, l, v = 0.01, 0.2, 0.5
    xml = (f'<mujoco><option timestep="{dt}" integrator="RK4" gravity="0 0 0"/><worldbody>'
           '<geom name="floor" type="plane" size="1 1 0.1"/>'
           f'<body name="arm" pos="0 0 {r + 1e-4}"><joint name="h" type="hinge" axis="0 1 0"/>'
           f'<geom name="rod" type="capsule" fromto="0 0 0 {l - r} 0 0" size="0.002" mass="0.2" contype="0" '
           'conaffinity="0"/>'
           f'<geom name="tip" type="sphere" pos="{l} 0 0" size="{r}" mass="{rubber.density * 4 / 3 * math.pi * r**3}"/>'
           '</body></worldbody><contact><exclude body1="world" body2="arm"/></contact></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[0] = v / l  # about +y: the tip moves down
    mujoco.mj_forward(model, data)
    M = np.zeros((1, 1))
    mujoco.mj_fullM(model, data, M)
    law = make_law("msf", ContactPair(rubber, steel), Curvature.sphere_on_plane(r))
    ref = simulate_impact(law, Body(rubber, r, float(M[0, 0]) / l**2), Body.half_space(steel), v)
    with pytest.warns(RuntimeWarning, match="under RK4 on links"):
        adapter = MujocoAdapter(model, data, [PairSpec("tip", "floor", law)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing else: no deep onset, no energy gain, no small-strain note
        rec = run_until_separated(adapter, 1000)
    assert abs(rec.cor_n / ref.cor_n - 1) < PENDULUM_RTOL and abs(rec.tau / ref.tau - 1) < PENDULUM_RTOL
    assert adapter.deep_onsets == 0 and not rec.outside_validity
    v_out = -(data.qvel[0] - adapter.velocity_offset()[0]) * l
    assert abs(v_out / (rec.cor_n * v) - 1) < PENDULUM_RTOL


#: The MSF ant under its own RK4 at 10 ms hopped to 6 m under the seeded
#: torques when each step's new torque reached its contacts' free flight one
#: step late. Its torso's highest point over the first 150 steps: measured
#: 1.17 m with the drive seen in its step (also over 1,000 steps; Euler
#: 1.13 m), 4.3 m without (a contact found deep at step 105, then the hop).
ANT_RK4_Z_MAX = 1.5


def test_the_ant_under_rk4_sees_its_drives_in_the_step_they_act():
    """ant.xml at its own RK4, 10 ms, 150 steps of the seeded torques (a new
    torque every step): the actuators' change since their last evaluation
    enters each link pair's a_ext in the step it acts
    (MujocoAdapter._actuation_change), so no contact is found deep at its
    onset and the ant does not hop (ANT_RK4_Z_MAX). The 26 mm deep ankle
    (COR 3.9) of the RK4 ant began at step 105 of this sequence."""
    import warnings

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # RK4 on links stays warned (docs/engines.md)
        adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(SEED)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    z = []
    with installed(adapter):
        for _ in range(150):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
            z.append(float(data.qpos[2]))
    assert adapter.jumps == 0 and adapter.deep_onsets == 0
    assert max(z) < ANT_RK4_Z_MAX, max(z)
