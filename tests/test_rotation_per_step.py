"""Rotation per engine step (issue 12 item 3, issue 10 item 4): a record says
in ``outside_validity`` when a body whose contact depends on its
orientation turned more than ROTATION_PER_STEP_MAX = pi/4 per step (pybullet
limits a turn per step to pi/4; the contact sub-cycle holds the step-start
geometry), and not for a sphere centred on its centre of mass (a jet bead
spins at ~1e5 rad/s, 10 rad per 0.1 ms step, and its contact is unaffected).

The ball: natural rubber, R = 20 mm, dropped at 1 m/s on a steel plane at
dt = 1 ms (its 2.7 ms contact sub-cycled), spinning about a horizontal axis.
Made eccentric (centre of mass 2 mm = 0.1 R from the sphere's centre), its
contact point moves with its orientation: at 1000 rad/s it turns 1 rad per
step (flagged), at 10 rad/s 0.01 rad (not flagged)."""

import math
import warnings

import pytest

from engines._contacts.state import ROTATION_PER_STEP_MAX
from msf_contact import Body, ContactPair, Curvature, ValidityWarning, make_law, preset

RUBBER, STEEL = preset("natural-rubber"), preset("steel")
R = 0.02  # ball radius [m]
DT = 1e-3  # engine step [s]
ECC = 0.1 * R  # offset of the eccentric ball's centre of mass from its sphere's centre [m]
FAST, SLOW = 1000.0, 10.0  # spin [rad/s]: 1 rad and 0.01 rad per step at DT
STEPS = 12  # 12 ms: the 2.7 ms contact and the step after it


def _law():
    return make_law("msf", ContactPair(RUBBER, STEEL), Curvature.sphere_on_plane(R))


def _flagged(records) -> list[str]:
    return [s for r in records for s in r.outside_validity if s.startswith("rotation per step")]


def _mujoco(spin: float, eccentric: bool):
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed

    b = Body.sphere(RUBBER, R)
    xml = (f'<mujoco><option timestep="{DT!r}" gravity="0 0 0"><flag autoreset="disable"/></option><worldbody>'
           f'<geom name="plate" type="plane" size="1 1 0.1"/><body name="ball" pos="0 0 {R!r}"><freejoint/>'
           f'<inertial pos="{ECC if eccentric else 0.0!r} 0 0" mass="{b.mass!r}" diaginertia="{b.J!r} {b.J!r} {b.J!r}"/>'
           f'<geom name="ball" type="sphere" size="{R!r}" mass="0"/></body></worldbody>'
           '<contact><exclude body1="world" body2="ball"/></contact></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[:] = [0.0, 0.0, -1.0, 0.0, spin, 0.0]
    mujoco.mj_forward(model, data)
    # the centre of mass where it was put (MuJoCo skips an inertial frame it finds equal to the body's)
    assert abs(data.xipos[1][0] - (ECC if eccentric else 0.0)) < 1e-15
    ad = MujocoAdapter(model, data, [PairSpec("ball", "plate", _law())])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always", ValidityWarning)
        with installed(ad):
            ad.step(STEPS)
        recs = ad.records
    return recs, [str(x.message) for x in w if issubclass(x.category, ValidityWarning)]


def _pybullet(spin: float, eccentric: bool):
    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter
    from engines.pybullet import scenes

    c = scenes.new_client(DT)
    try:
        plate = scenes.add_plate(c)
        b = Body.sphere(RUBBER, R)
        shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, collisionFramePosition=[ECC if eccentric else 0.0,
                                                                                          0.0, 0.0],
                                        physicsClientId=c)
        uid = pb.createMultiBody(b.mass, shape, basePosition=[0.0, 0.0, R], physicsClientId=c)
        pb.changeDynamics(uid, -1, mass=b.mass, localInertiaDiagonal=[b.J] * 3, physicsClientId=c)
        scenes._free_dynamics(c, uid)
        pb.resetBaseVelocity(uid, [0.0, 0.0, -1.0], [0.0, spin, 0.0], physicsClientId=c)
        ad = PybulletAdapter(c, [PairSpec((uid, -1), (plate, -1), _law())])
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always", ValidityWarning)
            for _ in range(STEPS):
                ad.step()
            recs = ad.records
        return recs, [str(x.message) for x in w if issubclass(x.category, ValidityWarning)]
    finally:
        pb.disconnect(c)


ENGINES = [pytest.param(_mujoco, id="mujoco", marks=pytest.mark.mujoco),
           pytest.param(_pybullet, id="pybullet", marks=pytest.mark.pybullet)]


def test_the_bound_is_bullets_angular_motion_threshold():
    """pi/4 rad per step: Bullet's ANGULAR_MOTION_THRESHOLD (0.5 SIMD_HALF_PI)."""
    assert ROTATION_PER_STEP_MAX == pytest.approx(0.5 * (0.5 * math.pi), rel=1e-15)
    assert SLOW * DT < ROTATION_PER_STEP_MAX < FAST * DT


@pytest.mark.parametrize("run", ENGINES)
def test_fast_eccentric_ball_is_flagged(run):
    recs, warned = run(FAST, eccentric=True)
    assert recs, "no impact recorded"
    flags = _flagged(recs)
    assert flags, [r.outside_validity for r in recs]
    assert "rad per engine step" in flags[0] and "take dt <=" in flags[0]
    # the record's own spin says the same: |omega| dt above the bound
    spins = [abs(r.spin_in) for r in recs if r.spin_in is not None]
    assert spins and max(spins) * DT > ROTATION_PER_STEP_MAX
    assert sum(m.startswith("rotation per step") for m in warned) == 1  # warned once per pair


@pytest.mark.parametrize("run", ENGINES)
def test_slow_eccentric_ball_is_not_flagged(run):
    recs, warned = run(SLOW, eccentric=True)
    assert recs and not _flagged(recs), [r.outside_validity for r in recs]
    assert not any(m.startswith("rotation per step") for m in warned)


@pytest.mark.parametrize("run", ENGINES)
def test_fast_centred_ball_is_not_flagged(run):
    """A sphere centred on its centre of mass touches at the same point however
    it turns: 1 rad per step is no reason to doubt its record."""
    recs, _ = run(FAST, eccentric=False)
    assert recs and not _flagged(recs), [r.outside_validity for r in recs]
    assert max(abs(r.spin_in) for r in recs if r.spin_in is not None) * DT > ROTATION_PER_STEP_MAX
