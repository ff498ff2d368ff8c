"""Models nobody here wrote (issue 13): ``ant.xml`` and ``humanoid.xml``
from ``pybullet_data/mjcf`` in MuJoCo at their own time steps, MSF on every
body-floor contact (engines.mujoco.robots), under seeded random torques,
then with the torques off. The suite runs a short stretch (60 steps of
torques, 60-100 steps without, while the robot still settles onto the
floor); the 1,000-step runs, the energy at rest and the cost against
MuJoCo's own contact are ``benchmarks/robots.py`` (make bench)."""

import math
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


@pytest.mark.parametrize("name,torque_steps,rest_steps", [("ant.xml", 60, 60), ("humanoid.xml", 60, 100)])
def test_robot_model_runs_and_gains_no_energy_without_torques(name, torque_steps, rest_steps):
    """No energy gain at rest, with engines.mujoco.robots.RestEnergy's
    account (kinetic + gravitational + the MSF contacts' stored_energy + the
    energy MuJoCo's joint limits took, the work of their forces): no rest step
    raises it beyond REST_GAIN_RTOL of the kinetic energy and the integrator's
    gravity term (measured: every step falls, the ant 30.7 -> 22.2 J with the
    limits taking 12.2 J, the humanoid 392 -> 338 J, 10.1 J). Each at its own
    time step; the ant's RK4 (whose stage forces data does not keep, and
    under which MSF on links is warned) is replaced by Euler."""
    _, data, adapter, account, start, _ = _at_rest(name, SEED, torque_steps, rest_steps)
    assert adapter.jumps == 0
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert adapter.records  # MSF carried the robot: its contacts with the floor began and ended
    assert account.gains == []
    assert account.total < start and account.absorbed > 0.0  # the limits took energy out


def _at_rest(name: str, seed: int, torque_steps: int, rest_steps: int, *, euler: bool = True):
    """``name`` of pybullet_data/mjcf at its own time step (its RK4 replaced
    by Euler unless ``euler`` is False), MSF on its floor pairs:
    ``torque_steps`` of seeded torques (uniform in the actuators' ranges, as
    benchmarks/robots.py), then ``rest_steps`` with none under RestEnergy's
    account: (model, data, adapter, account, its total at the rest's start,
    islands flagged before the rest)."""
    from engines.mujoco.robots import RestEnergy

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", name)
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    if euler and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(seed)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    with installed(adapter):
        for _ in range(torque_steps):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
        data.ctrl[:] = 0.0
        flagged = len(adapter.manager.island_energy_gains)
        account = RestEnergy(model, data, adapter)
        start = account.total
        for _ in range(rest_steps):
            mujoco.mj_step(model, data)
            account.update()
    assert adapter.jumps == 0 and np.all(np.isfinite(data.qpos))
    return model, data, adapter, account, start, flagged


def test_the_ant_at_rest_gains_no_energy():
    """The ant of benchmarks/robots.py (seed 13): 1,000 steps of seeded
    torques, then 340 with none: no rest step raises RestEnergy's account
    beyond its bound and no island's energy check flags a step. The ant
    lies on its torso and legs, most contacts resting: a body's resting
    contacts are solved together in its island (engines._contacts.islands,
    issue 13). With the rule before (ContactManager.set_together of no
    pair: a set of resting contacts stepped one by one, each with the
    others' forces held in its a_ext a step late, while the legs pass load
    through their joints within the step) rest step 331 of this run rose
    above the bound (measured at ef6700c)."""
    _, _, adapter, account, start, flagged = _at_rest("ant.xml", 13, 1000, 340)
    assert account.gains == []
    assert len(adapter.manager.island_energy_gains) == flagged
    assert account.total < start


def test_the_ant_whose_legs_slam_onto_their_limits_gains_no_energy():
    """The same ant under seed 1: as the drives let go its legs slam onto
    their limits (33 J taken by the limits in the first rest step). With
    the limits' forces a step late in the legs' finite-difference a_ext (as
    at f9780ae, islands of resting rows and all: the stopping impulse read
    as an acceleration through the next step) a foot began 2.5 mm deep and
    the account rose 0.365 J in rest step 3 (0.068 J allowed). The
    constraint forces are now predicted in their step
    (engines.mujoco._known): no rest step above the bound."""
    _, _, adapter, account, _, _ = _at_rest("ant.xml", 1, 1000, 10)
    assert account.gains == []


def test_the_humanoid_resting_on_its_limbs_keeps_the_rk4_island():
    """The humanoid of benchmarks/robots.py (seed 13, 2 ms): 1,000 steps of
    seeded torques, then 150 at rest: no rest step above RestEnergy's bound.
    Its limbs' contacts are own-gap pairs (links on the fixed floor) but not
    free bodies: a resting island of them keeps the RK4 island
    (ContactManager.settle_rigid, cleared by the MuJoCo adapter for links),
    not the settled island step of free bodies (engines._contacts.resting).
    With that step (main 751b2d1) a shin's force went 62 -> 246 N in the
    step after it and the account rose 93 mJ in rest step 139 (5 mJ
    allowed)."""
    _, _, _, account, _, _ = _at_rest("humanoid.xml", SEED, 1000, 150)
    assert account.gains == []


def _account_of(xml: str, steps: int, qpos0=None):
    """(model, data, RestEnergy account, kinetic + potential energy lost [J])
    of the model ``xml`` let go from qpos0 (default the model's) for ``steps``."""
    from engines.mujoco.robots import RestEnergy

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    if qpos0 is not None:
        data.qpos[:len(qpos0)] = qpos0
    mujoco.mj_forward(model, data)
    account = RestEnergy(model, data)
    E0 = account.mechanical
    for _ in range(steps):
        mujoco.mj_step(model, data)
        account.update()
    return model, data, account, E0 - account.mechanical


#: A free ball's energy lost to MuJoCo's contact against the work the account books: exact but
#: for round-off (its mass matrix is constant and the Euler gravity term telescopes to
#: dt/2 m g (v_end - v_start) = 0); measured 6e-15, with margin for another BLAS's sums
CONTACT_WORK_RTOL = 1e-9


def test_mujocos_own_contact_work_is_in_the_rest_account():
    """RestEnergy books the work of MuJoCo's own contacts as it books its
    limits' (engines.mujoco.robots.CONSTRAINT_KINDS): a 0.1 kg ball dropped
    from 0.2 m onto a plane with MuJoCo's soft contact (Euler, 2 ms) bounces
    and settles; its kinetic + potential energy lost is the energy the
    account says the contact took, and no step rises above the bound (a
    free body's mass matrix is constant, so the Euler step's work is exact:
    measured 6e-15 relative). Without it the ball's account rose by 0.29 mJ
    in step 106 (allowed 0.066 mJ), as the humanoid's did at rest after its
    torques, its buttocks resting on a foot through MuJoCo's contact (MSF
    carries only the floor's: benchmarks/robots.py, 114 steps above the
    bound at f9780ae, up to 67 uJ, were those)."""
    xml = ('<mujoco><option timestep="0.002" integrator="Euler"/><worldbody><geom type="plane" size="1 1 0.1"/>'
           '<body pos="0 0 0.2"><freejoint/><geom type="sphere" size="0.02" mass="0.1"/></body></worldbody></mujoco>')
    _, _, account, lost = _account_of(xml, 1000)
    assert lost > 0.9 * 0.1 * 9.81 * 0.18  # it came to rest: the contact took what the fall gave
    assert account.absorbed_by["contacts"] == pytest.approx(lost, rel=CONTACT_WORK_RTOL)
    assert account.absorbed_by["limits"] == 0.0
    assert account.gains == []


#: How far past its upper end the bar's hinge limit is moved (_pressed_bar): [rad]. Measured at
#: 0.03 rad: Euler and RK4 no contact found deep at its onset, x_max/R 0.057 and 0.061; with the
#: limit's force change left out of a_ext (a step late, as before engines.mujoco._known), RK4 has 4
#: corners found 51 um deep and both leave the small-strain range (x_max/R 0.16, 0.14).
LIMIT_PAST = 0.03


def _pressed_bar(integrator: str, torque: float, pushed: float = 0.0, by_callback: float = 0.0, limit: bool = False):
    """A rubber box bar (100 x 20 x 20 mm, 0.2 kg, edge radius 5 mm: its
    corners touch, solved together) on a hinge at one end, lying 1 mm above a steel floor, no
    gravity, dt = 10 ms, pressed down during steps 10-19 by a motor with
    ``torque`` [N m], by a generalised force ``pushed`` [N m] on the hinge
    (qfrc_applied), by the motor's control ``by_callback`` [N m] written in
    MuJoCo's mjcb_control (called after the contacts' hook), or (``limit``)
    by a joint limit moved onto the bar (its range set to [-0.5, -LIMIT_PAST]
    rad: the bar, at 0, is past its upper end); then released:
    (adapter, warnings)."""
    import warnings

    from engines.base import PairSpec
    from msf_contact import Curvature, make_law

    r = 0.01
    xml = (f'<mujoco><option timestep="0.01" integrator="{integrator}" gravity="0 0 0"/><worldbody>'
           '<geom name="floor" type="plane" size="1 1 0.1"/>'
           f'<body name="bar" pos="0 0 {r + 0.001}"><joint name="hinge" type="hinge" axis="0 -1 0" '
           f'limited="{str(limit).lower()}" range="-1 1"/>'
           f'<geom name="g" type="box" pos="0.05 0 0" size="0.05 {r} {r}" mass="0.2"/></body></worldbody>'
           '<actuator><motor joint="hinge" gear="-1" ctrlrange="-10 10"/></actuator>'
           '<contact><exclude body1="world" body2="bar"/></contact></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(5e-3))
    step = [0]

    def control(m, d):
        d.ctrl[0] = by_callback if 10 <= step[0] < 20 else 0.0

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        adapter = MujocoAdapter(model, data, [PairSpec("g", "floor", law)], edge_radii={"g": 5e-3})
        if by_callback:
            mujoco.set_mjcb_control(control)
        try:
            with installed(adapter):
                for i in range(40):
                    step[0] = i
                    if not by_callback:
                        data.ctrl[0] = torque if 10 <= i < 20 else 0.0
                    data.qfrc_applied[0] = -pushed if 10 <= i < 20 else 0.0
                    if limit:
                        model.jnt_range[0] = (-0.5, -LIMIT_PAST) if 10 <= i < 20 else (-1.0, 1.0)
                    mujoco.mj_step(model, data)
        finally:
            mujoco.set_mjcb_control(None)
    return adapter, [str(w.message) for w in caught]


def test_a_link_found_deep_at_its_onset_is_flagged_and_warned():
    """Never silent (issue 13, the MSF ant): the motor's control written by
    MuJoCo's mjcb_control (0.1 N m, called after the contacts' hook, so the
    contacts' a_ext sees it a step late) switched on inside a step drives
    the link toward the floor 1 mm below, where the contacts' free flight
    (and their own gaps, which take the engine's gap beyond the
    integrator's lead) do not put it, and its corners begin already
    overlapping, holding elastic energy no force worked for (the ant's
    ankle under RK4 26 mm, 111 J, COR 3.9, when its drives were seen a step
    late). Each such contact is flagged in its outside_validity and warned
    once per pair."""
    adapter, messages = _pressed_bar("Euler", 0.0, by_callback=0.1)
    assert adapter.deep_onsets >= 1
    deep = [m for m in messages if "deep at its onset" in m]
    assert deep and len(deep) == len({m.split(":")[0] for m in deep})  # once per pair
    assert any(any("deep at its onset" in note for note in r.outside_validity) for r in adapter.records)


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
@pytest.mark.parametrize("push", ["motor", "qfrc_applied", "limit"])
def test_a_push_on_a_link_is_seen_in_its_step(integrator, push):
    """The same bar pressed by its motor's control set before the step, by
    qfrc_applied, or by a joint limit moved onto it (a limit engaging inside
    a step) under Euler and RK4: each is seen by the contacts in its step
    (engines.mujoco._known: the actuator, user and constraint forces'
    change since the last step in a_ext; the limit's response in W), so no
    contact is found deep at its onset, and nothing is warned (RK4 on links
    is no longer warned). Before: qfrc_applied gave 2 deep onsets under
    Euler, and RK4 on links warned once."""
    kw = dict(motor=dict(torque=0.1), qfrc_applied=dict(torque=0.0, pushed=0.1), limit=dict(torque=0.0, limit=True))[push]
    adapter, messages = _pressed_bar(integrator, **kw)
    assert adapter.records and adapter.deep_onsets == 0
    assert not messages, messages


#: A pendulum whose only force besides gravity is its joint limit: the
#: mechanical energy it loses against the energy RestEnergy says the limit
#: took; measured 1.1e-4 (the semi-implicit Euler step's gravity term over
#: the impacts on the limit, dt/2 |m g . dv| a step, not in either)
LIMIT_WORK_RTOL = 1e-3


def test_the_limits_work_is_the_energy_a_pendulum_loses_to_them():
    """engines.mujoco.robots.RestEnergy's limit work against an independent
    balance: a 1 kg bar (300 mm) on an undamped hinge limited to +-10 deg,
    let go at the lower limit, falls onto the upper one at ~19 rad/s and
    settles there (1,500 steps of 2 ms, Euler). Gravity is its only other
    force, so the kinetic + potential energy it loses is what the limit
    took; the account (their sum) never rises beyond its bound in a step.
    The limit took energy and kept it (absorbed > 0 at rest): MuJoCo's soft
    limit dissipates (its reference acceleration's damping), no spring."""
    xml = ('<mujoco><option timestep="0.002" integrator="Euler"/><worldbody><body name="p" pos="0 0 1">'
           '<joint name="h" type="hinge" axis="0 1 0" range="-10 10" limited="true"/>'
           '<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/></body></worldbody></mujoco>')
    _, data, account, lost = _account_of(xml, 1500, qpos0=[np.radians(-10.0)])
    assert abs(data.qvel[0]) < 1e-6 and np.degrees(data.qpos[0]) > 10.0  # at rest on the upper limit
    fall = 1.0 * 9.81 * 0.15 * 2.0 * math.sin(math.radians(10.0))  # m g of the centre's drop, limit to limit
    assert lost > 0.9 * fall  # at rest on the upper limit: its bounces took what the fall gave
    assert account.absorbed == pytest.approx(lost, rel=LIMIT_WORK_RTOL)
    assert account.gains == []


def test_rest_energy_refuses_rk4_without_the_adapter():
    """Under RK4 the limits' forces of the four stages are read by the MSF
    adapter's hook; without one (adapter None) RestEnergy refuses, naming
    the integrator and what would make it work."""
    from engines.mujoco.robots import RestEnergy

    model = mujoco.MjModel.from_xml_string('<mujoco><option integrator="RK4"/><worldbody><body><freejoint/>'
                                           '<geom size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(ValueError, match="RK4.*MujocoAdapter.*Euler"):
        RestEnergy(model, mujoco.MjData(model))


def test_the_ant_under_rk4_gains_no_energy_at_rest():
    """ant.xml at its own RK4 and 10 ms (issue 13, "RK4 on links"): 60 steps
    of the seeded torques, then 60 without. RestEnergy's account under RK4
    (the limits' work from the four stages' constraint forces the adapter's
    hook reads, weighted as RK4 weighs them) never rises beyond its bound
    in a rest step, the limits took energy out, every stage's rows were
    joint limits, and nothing is warned (RK4 on links no longer is).
    Measured: 61.3 -> 54.9 J, the limits taking 24.7 J."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, _, adapter, account, start, _ = _at_rest("ant.xml", SEED, 60, 60, euler=False)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert adapter.jumps == 0 and adapter.records
    assert account.gains == [] and account.mixed == []
    assert account.total < start and account.absorbed > 0.0
    assert not any(r.outside_validity for r in adapter.records)
    assert not caught, [str(w.message) for w in caught]


#: A bar pressed into the floor by its joint limit (_pressed_bar's limit, no
#: motor) at dt = 1 ms against the same at 0.5 ms: the largest approach.
#: Measured 0.49 % (Euler) and 0.30 % (RK4) with the limit responding in W
#: (engines.mujoco._known, M_eff); 0.5 ms is within 0.4 % of 0.2 ms
#: (x_max/R 0.0847 Euler, 0.0849 RK4, converged); with W = J M^-1 J^T, 1 ms
#: was 8.1 % and 7.8 % below 0.2 ms.
LIMIT_PRESS_RTOL = 2e-2


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_a_link_pressed_by_its_limit_is_the_fine_steps_contact(integrator):
    """The hinged bar pressed into the floor by a joint limit moved 0.03 rad
    onto it: the joint limit responds to the contact force within the
    step (MuJoCo's soft constraint: f = -(A + R)^-1 (J qacc_smooth -
    a_ref)), so the contact's inverse inertia is J M_eff^-1 J^T with the
    limit's row in M_eff. Its deepest approach at 1 ms is the 0.5 ms
    run's within LIMIT_PRESS_RTOL."""
    def x_max(dt):
        import warnings

        from engines.base import PairSpec
        from msf_contact import Curvature, make_law

        r = 0.01
        xml = (f'<mujoco><option timestep="{dt}" integrator="{integrator}" gravity="0 0 0"/><worldbody>'
               '<geom name="floor" type="plane" size="1 1 0.1"/>'
               f'<body name="bar" pos="0 0 {r + 0.001}"><joint name="hinge" type="hinge" axis="0 -1 0" '
               'limited="true" range="-1 1"/>'
               f'<geom name="g" type="box" pos="0.05 0 0" size="0.05 {r} {r}" mass="0.2"/></body></worldbody>'
               '<contact><exclude body1="world" body2="bar"/></contact></mujoco>')
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(5e-3))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            adapter = MujocoAdapter(model, data, [PairSpec("g", "floor", law)], edge_radii={"g": 5e-3})
            n = int(round(0.01 / dt))
            with installed(adapter):
                for i in range(13 * n):
                    model.jnt_range[0] = (-0.5, -LIMIT_PAST) if n <= i < 11 * n else (-1.0, 1.0)
                    mujoco.mj_step(model, data)
        assert adapter.deep_onsets == 0 and adapter.records
        return max(rec.x_max for rec in adapter.records)

    fine, coarse = x_max(5e-4), x_max(1e-3)
    assert abs(coarse / fine - 1.0) < LIMIT_PRESS_RTOL, (coarse, fine)


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
    at the record's COR, with nothing warned."""
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
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing: no RK4 warning, no deep onset, no energy gain, no small-strain note
        adapter = MujocoAdapter(model, data, [PairSpec("tip", "floor", law)])
        rec = run_until_separated(adapter, 1000)
    assert abs(rec.cor_n / ref.cor_n - 1) < PENDULUM_RTOL and abs(rec.tau / ref.tau - 1) < PENDULUM_RTOL
    assert adapter.deep_onsets == 0 and not rec.outside_validity
    v_out = -(data.qvel[0] - adapter.velocity_offset()[0]) * l
    assert abs(v_out / (rec.cor_n * v) - 1) < PENDULUM_RTOL


#: The MSF ant under its own RK4 at 10 ms hopped to 6 m under the seeded
#: torques when each step's new torque reached its contacts' free flight one
#: step late. Its torso's highest point over the first 150 steps: measured
#: 0.855 m with the drive seen in its step and the links' own gaps (1.17 m
#: with the drive alone; 1.31 m over 1,000 steps), 4.3 m without either (a
#: contact found deep at step 105, then the hop).
ANT_RK4_Z_MAX = 1.5


def test_the_ant_under_rk4_sees_its_drives_in_the_step_they_act():
    """ant.xml at its own RK4, 10 ms, 150 steps of the seeded torques (a new
    torque every step): the actuators' change since their last evaluation
    enters each link pair's a_ext in the step it acts
    (engines.mujoco._known), so no contact is found deep at its
    onset and the ant does not hop (ANT_RK4_Z_MAX). The 26 mm deep ankle
    (COR 3.9) of the RK4 ant began at step 105 of this sequence."""
    import warnings

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # RK4 on links is no longer warned
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


#: The contacts' inverse inertia (engines.mujoco._known.KnownForces.solve) against MuJoCo's own
#: Euler step's velocity change per unit generalised impulse, column by column: measured 3.5e-13
#: and 4.5e-13 (implicit damping off and on); the margin is for the constraint solver's
#: convergence and the finite impulse (linear while the limit row stays pressed)
STEP_RESPONSE_RTOL = 1e-9


def _response_per_impulse(model, data):
    """(KnownForces.solve's velocity change per unit generalised impulse on
    each dof (nv, nv), mj_step's own (a small qfrc_applied on each dof in
    turn against the step without it), each row's largest |entry| of the
    latter, and M_eff^-1 from M alone), the limit's row pressed in ``data``."""
    import copy

    from engines.mujoco._known import KnownForces

    known = KnownForces(model, data)
    known.change()
    assert known._Js.shape[0] == 1  # the limit's row is pressed
    nv, h, impulse = model.nv, model.opt.timestep, 1e-4
    X = np.zeros((nv, nv))
    known.solve(X, np.eye(nv))
    free = copy.copy(data)
    mujoco.mj_step(model, free)
    dv0 = free.qvel - data.qvel
    engine = np.zeros((nv, nv))
    for i in range(nv):
        pushed = copy.copy(data)
        pushed.qfrc_applied[i] = impulse / h
        mujoco.mj_step(model, pushed)
        engine[i] = (pushed.qvel - data.qvel - dv0) / impulse
    Minv = np.zeros((nv, nv))
    mujoco.mj_solveM(model, data, Minv, np.eye(nv))
    return X, engine, np.abs(engine).max(axis=1), Minv - known._G.T @ known._Ainv @ known._G


@pytest.mark.parametrize("implicit", [True, False])
def test_the_contacts_inverse_inertia_is_the_euler_steps_response(implicit):
    """A three-link arm (damping 5 N m s/rad, armature 0.002 kg m^2, dt = 2 ms,
    Euler) pressed by gravity onto the upper limit of its root hinge: the
    velocity change that KnownForces.solve gives per unit generalised impulse
    is MuJoCo's own step's (a small qfrc_applied on each dof in turn, against
    the step without it) within STEP_RESPONSE_RTOL, with MuJoCo's implicit
    Euler damping on (its default: the step solves with M + h B) and off.
    With the damping on, the inverse inertia from M alone (M_eff^-1 with the
    limit's row, as before issue 13's fix) is off by more than 1 %: 43x on
    the wrist, whose inertia is below h B (measured)."""
    xml = ('<mujoco><option timestep="0.002" integrator="Euler"/><default><joint damping="5" armature="0.002"/>'
           '</default><worldbody><body pos="0 0 1"><joint type="hinge" axis="0 1 0" limited="true" range="0 30"/>'
           '<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>'
           '<body pos="0.3 0 0"><joint type="hinge" axis="0 1 0"/>'
           '<geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.025" mass="0.5"/>'
           '<body pos="0.25 0 0"><joint type="hinge" axis="1 0 0"/><geom type="box" size="0.05 0.03 0.02" mass="0.2"/>'
           '</body></body></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    if not implicit:
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)
    data = mujoco.MjData(model)
    data.qpos[:] = [math.radians(30.5), 0.3, 0.2]  # past the upper limit, where gravity holds it
    mujoco.mj_forward(model, data)
    X, engine, scale, with_m = _response_per_impulse(model, data)
    assert np.all(np.abs(X - engine).max(axis=1) < STEP_RESPONSE_RTOL * scale)
    off = np.abs(with_m - engine).max(axis=1) / scale
    assert (off.max() > 1e-2) == implicit, off


def test_the_ant_under_torque_seed_4_gains_no_energy_at_rest():
    """benchmarks/robots.py's ant under torque seed 4 (its rest sweep): 1,000
    steps of the seeded torques, then 120 at rest. On main at 7d84f67 rest
    step 112 rose 3.86 mJ (2.23 mJ allowed): the contacts' inverse inertia
    and the held forces' answer from the joint limits were not the engine
    step's (engines.mujoco._known: implicit Euler damping, the held forces'
    response when the active rows change). No rest step above the bound."""
    _, _, _, account, _, _ = _at_rest("ant.xml", 4, 1000, 120)
    assert account.gains == []


@pytest.mark.parametrize("integrator", ["implicitfast", "implicit"])
def test_the_contacts_inverse_inertia_is_the_implicit_steps_response(integrator):
    """The arm of the test above under MuJoCo's implicit integrators, moving
    (qvel 0.5-2 rad/s: the Coriolis derivative of ``implicit``), with a
    velocity servo (kv 3 N m s/rad) on the root, a position servo with kv
    (2 N m s/rad) on the elbow and a damped fixed tendon (4 N m s/rad) over
    both: the step solves (M - h D) qacc = f (engines.mujoco._known,
    StepResponse), and the velocity change KnownForces.solve gives per unit
    generalised impulse is mj_step's within STEP_RESPONSE_RTOL, the limit's
    row pressed. The inverse inertia from M alone (before: no derivative
    under these integrators) is more than 1 % off."""
    xml = (f'<mujoco><option timestep="0.002" integrator="{integrator}"/><default><joint damping="5" '
           'armature="0.002"/></default><worldbody><body pos="0 0 1">'
           '<joint name="root" type="hinge" axis="0 1 0" limited="true" range="0 30"/>'
           '<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>'
           '<body pos="0.3 0 0"><joint name="elbow" type="hinge" axis="0 1 0"/>'
           '<geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.025" mass="0.5"/>'
           '<body pos="0.25 0 0"><joint type="hinge" axis="1 0 0"/><geom type="box" size="0.05 0.03 0.02" mass="0.2"/>'
           '</body></body></body></worldbody>'
           '<tendon><fixed name="t" damping="4"><joint joint="root" coef="1"/><joint joint="elbow" coef="0.5"/>'
           '</fixed></tendon><actuator><velocity joint="root" kv="3"/><position joint="elbow" kp="40" kv="2"/>'
           '</actuator></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = [math.radians(30.5), 0.3, 0.2]  # past the upper limit, where gravity holds it
    data.qvel[:] = [0.5, -1.0, 2.0]
    data.ctrl[:] = [0.2, 0.1]
    mujoco.mj_forward(model, data)
    X, engine, scale, with_m = _response_per_impulse(model, data)
    assert np.all(np.abs(X - engine).max(axis=1) < STEP_RESPONSE_RTOL * scale), np.abs(X - engine).max(axis=1) / scale
    assert (np.abs(with_m - engine).max(axis=1) / scale).max() > 1e-2


#: the contact's internal approach rate at a step's end against the engine's
#: (physical) one on a damped slide, relative to the largest rate: both follow
#: the same velocity change when a_ext holds this step's damping force, so they
#: agree to round-off (measured 3.4e-16; 6.7e-3 with the damping a step late)
DAMPED_RATE_RTOL = 1e-12


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_a_damped_links_contact_moves_as_the_engine_does(integrator):
    """A rubber ball (R 20 mm, 50 g) on a vertical slide joint with damping
    0.5 N s/m, dropped 0.5 mm onto a steel floor and settling there (dt 1 ms,
    250 steps): the joint's damping force -B v changes every step, and the
    step applies it at the step start's velocity (its answer to the contact's
    impulse is the implicit part, in W). Seen in its own step
    (engines.mujoco._known: qfrc_damper a known force but under RK4), the
    contact's internal approach rate at every step's end equals the engine's
    to DAMPED_RATE_RTOL; held a step late (before), the contact's internal
    motion left the engine's: a humanoid rocking at rest on its limbs rose
    above RestEnergy's bound in 60 rest steps (issue 13, benchmarks.robots.rest_sweep
    seed 2)."""
    import warnings

    from engines.base import PairSpec
    from msf_contact import Curvature, make_law

    xml = (f'<mujoco><option timestep="0.001" integrator="{integrator}"/><worldbody>'
           '<geom name="floor" type="plane" size="1 1 0.1"/><body pos="0 0 0.0205">'
           '<joint type="slide" axis="0 0 1" damping="0.5"/><geom name="ball" type="sphere" size="0.02" mass="0.05"/>'
           '</body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "floor", law)])
    mgr = adapter.manager
    internal, engine = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with installed(adapter):
            for _ in range(250):
                was = bool(mgr.active[0])
                mujoco.mj_step(model, data)
                if was and mgr.active[0]:  # a whole step in contact
                    internal.append(float(mgr.xdot[0]))
                    engine.append(-float(data.qvel[0] - adapter.velocity_offset()[0]))  # normal +z
    assert len(engine) > 200 and adapter.records  # it landed and rests
    internal, engine = np.array(internal), np.array(engine)
    assert np.abs(internal - engine).max() < DAMPED_RATE_RTOL * np.abs(engine).max()


def test_the_feet_coulomb_cap_is_mujocos_own_pair_friction(tmp_path):
    """load_with_msf_floor(mu=ENGINE_FRICTION): each pair's cap is the
    friction MuJoCo's own contact uses for that geom pair, read from MuJoCo's
    contact list of the same model with the floor let in (its mixing: the
    higher priority's, else the larger), and mu is refused outside (0, inf)."""
    from engines.mujoco.robots import ENGINE_FRICTION

    xml = ('<mujoco><worldbody><geom name="floor" type="plane" size="5 5 .1" friction="0.8 .005 .0001"/>'
           '<body name="a" pos="0 0 0.049"><freejoint/><geom name="ga" type="sphere" size=".05" friction="1.3"/></body>'
           '<body name="b" pos="1 0 0.049"><freejoint/><geom name="gb" type="sphere" size=".05" friction="0.3"/></body>'
           '<body name="c" pos="2 0 0.049"><freejoint/><geom name="gc" type="sphere" size=".05" friction="0.3" '
           'priority="1"/></body></worldbody></mujoco>')
    path = tmp_path / "three.xml"
    path.write_text(xml)
    own = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(own)
    mujoco.mj_forward(own, d)
    expected = {own.geom(int(max(c.geom1, c.geom2))).name: float(c.friction[0]) for c in d.contact[:d.ncon]}
    assert expected == {"ga": 1.3, "gb": 0.8, "gc": 0.3}  # max, max, priority
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    _, _, pairs = load_with_msf_floor(str(path), pair, mu=ENGINE_FRICTION)
    assert {p.body1: p.law.mu for p in pairs} == expected
    _, _, pairs = load_with_msf_floor(str(path), pair)
    assert all(p.law.mu is None for p in pairs)  # the paper's uncapped law unless asked
    for bad in (0.0, -1.0, math.inf, "pybullet", True):
        with pytest.raises(ValueError, match="mu"):
            load_with_msf_floor(str(path), pair, mu=bad)
