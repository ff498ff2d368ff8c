"""pybullet back-end against the reference solver (issue 3 acceptance), its
built-in contact's documented behaviour, and bad input.

Every comparison is with :func:`msf_contact.simulate_impact` (converged to
1e-6) for the same law, bodies and incidence; errors are relative,
(got - want) / |want|.
"""

import math

import numpy as np
import pybullet as pb
import pytest
from scipy.optimize import brentq

from engines.base import PairSpec, get_engine
from engines.pybullet import PybulletAdapter, run_builtin_impact, run_impact, scenes
from engines.pybullet.builtin import BuiltinContact
from msf_contact import closed_forms as cf
from msf_contact.geometry import Curvature
from msf_contact.laws import make_law
from msf_contact.materials import ContactPair, preset
from msf_contact.solver import Body, simulate_impact

pytestmark = pytest.mark.pybullet

#: Issue 3: normal COR within 0.1% at >= 50 engine steps per contact.
RESOLVED_COR_RTOL = 1e-3
#: Issue 3: contact duration within 1% at >= 50 steps per contact (tau is
#: resolved by the manager's root finding, not by the engine step).
RESOLVED_TAU_RTOL = 1e-2
#: Issue 3: COR and tau within 0.02% at >= 250 steps per contact.
FINE_RTOL = 2e-4
#: Issue 3: COR within 0.5% at robotics steps (1-2 ms, contact 0.3-0.7 ms), every onset phase.
ROBOTICS_COR_RTOL = 5e-3
#: Issue 3: oblique impact, cor_t and spin_out within 2% of the reference.
OBLIQUE_RTOL = 2e-2
#: Issue 3: a dropped ball rests at the static overlap within 2%.
REST_OVERLAP_RTOL = 2e-2
#: Issue 3: total momentum of two spheres colliding in flight, relative.
MOMENTUM_RTOL = 1e-9
#: The impulse pybullet gave body 1 equals the impulse the adapter applied:
#: float64 round-off of F dt / m summed over ~100 steps.
IMPULSE_RTOL = 1e-10
#: No energy gain at a bounce: the free-flight invariant of pybullet's
#: semi-implicit Euler may not grow by more than float64 round-off.
ENERGY_GAIN_RTOL = 1e-9
#: Paddle on a hinge vs the reference with the paddle's effective mass: the
#: hinge turns the face by ~1e-3 rad during the contact, the reference
#: assumes a translating plate; 0.1% (the resolved-step acceptance).
PADDLE_RTOL = 1e-3
#: Angular momentum about the paddle's hinge, relative: the paddle's turn
#: within the step the force is applied in (W frozen over a step) is O(dt^2).
ANGULAR_MOMENTUM_RTOL = 1e-6
#: pybullet's built-in restitution: the product of the bodies' values, as
#: exact as the solver's velocity target (float64).
BUILTIN_COR_ATOL = 1e-9

PU = preset("polyurethane")
PTFE = preset("ptfe")
STEEL = preset("steel")
RIGID = preset("rigid")
R = 0.02
SPEED = 1.0
#: MSF with a fixed collision frequency [rad/s] where the self-consistent
#: onset is not the point (cheap onset; same law in engine and reference).
OMEGA_FIXED = 2000.0


def ball_plate(material=PU, radius=R):
    return Body.sphere(material, radius), Body.half_space(RIGID), ContactPair(material, RIGID), Curvature(radius, radius)


def msf_fixed(material=PU, radius=R):
    b1, b2, pair, curv = ball_plate(material, radius)
    return make_law("msf", pair, curv, omega=OMEGA_FIXED), b1, b2


def comparison_laws():
    """MSF (self-consistent) and each comparison law on polyurethane / rigid."""
    b1, b2, pair, curv = ball_plate()
    msf = make_law("msf", pair, curv)
    omega = simulate_impact(msf, b1, b2, SPEED).omega_x
    return [
        ("msf", {}),
        ("kuwabara-kono", {"A": float(cf.kuwabara_kono_A_equivalent(PU.tan_delta, omega))}),
        ("hunt-crossley", {"cor": 0.7}),
        ("spring-dashpot", {}),
        ("hertz", {}),
    ]


def rel(got, want):
    return abs(got - want) / abs(want)


# ------------------------------------------------------------- acceptance --
@pytest.mark.parametrize("law_name, kw", comparison_laws())
def test_resolved_steps_match_reference(law_name, kw):
    b1, b2, pair, curv = ball_plate()
    law = make_law(law_name, pair, curv, **kw)
    ref = simulate_impact(law, b1, b2, SPEED)
    for steps, cor_tol, tau_tol in ((50, RESOLVED_COR_RTOL, RESOLVED_TAU_RTOL), (250, FINE_RTOL, FINE_RTOL)):
        dt = ref.tau / steps
        rec = run_impact(law, b1, b2, SPEED, dt=dt, gap=0.37 * SPEED * dt)
        assert rec.engine == "pybullet" and rec.dt == dt and rec.law == law_name
        assert rel(rec.cor_n, ref.cor_n) <= cor_tol, (steps, rec.cor_n, ref.cor_n)
        assert rel(rec.tau, ref.tau) <= tau_tol, (steps, rec.tau, ref.tau)


@pytest.mark.parametrize("dt", [1e-3, 2e-3])
def test_robotics_step_every_onset_phase(dt):
    # PTFE ball R = 15 mm at 0.5 m/s: a contact of about 0.5 ms, under one step
    speed = 0.5
    law, b1, b2 = msf_fixed(PTFE, 0.015)
    ref = simulate_impact(law, b1, b2, speed)
    assert 0.3e-3 <= ref.tau <= 0.7e-3
    errors = []
    for k in range(20):
        gap = 1e-4 + speed * dt * k / 20.0
        rec = run_impact(law, b1, b2, speed, dt=dt, gap=gap)
        errors.append(rel(rec.cor_n, ref.cor_n))
    assert max(errors) <= ROBOTICS_COR_RTOL, errors


@pytest.mark.parametrize("angle", [30.0, 60.0])
def test_oblique_msf_tangential(angle):
    law, b1, b2 = msf_fixed()
    ref = simulate_impact(law, b1, b2, SPEED, angle_deg=angle)
    dt = ref.tau / 100
    rec = run_impact(law, b1, b2, SPEED, angle_deg=angle, dt=dt, gap=1e-4)
    assert rel(rec.cor_n, ref.cor_n) <= RESOLVED_COR_RTOL
    assert rel(rec.cor_t, ref.cor_t) <= OBLIQUE_RTOL, (rec.cor_t, ref.cor_t)
    assert rel(rec.spin_out, ref.spin_out) <= OBLIQUE_RTOL, (rec.spin_out, ref.spin_out)


#: Oblique impacts at robotics steps (1-2 ms, longer than the 1.5-1.7 ms
#: contact): sub-cycled inside one or two steps, cor_n, cor_t and spin_out
#: were measured within 2e-5 of the reference (issue 3's bound is 2 %).
OBLIQUE_ROBOTICS_RTOL = 1e-4


@pytest.mark.parametrize("angle", [30.0, 60.0])
@pytest.mark.parametrize("dt", [1e-3, 2e-3])
def test_oblique_msf_tangential_at_robotics_steps(angle, dt):
    """Issue 12: no oblique pybullet test at 1-2 ms existed; two onset phases."""
    law, b1, b2 = msf_fixed()
    ref = simulate_impact(law, b1, b2, SPEED, angle_deg=angle)
    for k in (0, 3):
        rec = run_impact(law, b1, b2, SPEED, angle_deg=angle, dt=dt, gap=1e-4 + SPEED * dt * k / 4)
        for key in ("cor_n", "cor_t", "spin_out"):
            assert rel(getattr(rec, key), getattr(ref, key)) <= OBLIQUE_ROBOTICS_RTOL, (key, k)


def test_dropped_ball_comes_to_rest_without_energy_gain():
    g, dt = 9.81, 2e-3
    law, b1, b2 = msf_fixed()
    scene = scenes.ball_on_plate(b1, 1e-9, dt=dt, gap=0.01, gravity=g)
    uid = scene.body1[0]
    m = b1.mass

    def invariant():
        # semi-implicit Euler conserves 1/2 v^2 + g z - 1/2 g dt v_z exactly in free flight
        (v, _), (pos, _) = pb.getBaseVelocity(uid, physicsClientId=scene.client), pb.getBasePositionAndOrientation(uid, physicsClientId=scene.client)
        return m * (0.5 * np.dot(v, v) + g * pos[2] - 0.5 * g * dt * v[2])

    flights = []  # [invariant at the end of the flight, its last step] per free flight
    with scene, PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law)]) as ad:
        for k in range(int(0.55 / dt)):  # at rest (overlap within 1e-4) after 0.5 s
            ad.step()
            if not ad.manager.active[0]:
                if not flights or flights[-1][1] != k - 1:
                    flights.append([None, k])
                flights[-1] = [invariant(), k]
        z = pb.getBasePositionAndOrientation(uid, physicsClientId=scene.client)[0][2]
        v = pb.getBaseVelocity(uid, physicsClientId=scene.client)[0]
        records = ad.records
    assert len(records) >= 3  # it bounced
    assert all(r.cor_n <= 1.0 for r in records)
    energies = [f[0] for f in flights]
    for before, after in zip(energies, energies[1:]):
        assert after <= before + ENERGY_GAIN_RTOL * abs(energies[0])
    onset = law.onset([1.0], [m])
    x_static = brentq(lambda x: float(law.contact_normal_force(np.array([x]), np.array([0.0]), onset)[0]) - m * g,
                      1e-12, R)
    assert rel(R - z, x_static) <= REST_OVERLAP_RTOL, (R - z, x_static)
    assert abs(v[2]) < 1e-3  # m/s: at rest


def test_two_spheres_in_flight_momentum_and_no_double_count():
    b1, b2 = Body.sphere(PU, R), Body.sphere(STEEL, 0.01)
    law = make_law("msf", ContactPair(PU, STEEL), Curvature(R, R, 0.01, 0.01), omega=OMEGA_FIXED)
    # normal incidence: with a tangential relative speed the sphere-sphere normal turns
    # during the contact, which the planar reference does not model
    ref = simulate_impact(law, b1, b2, SPEED)
    dt = ref.tau / 60
    scene = scenes.two_spheres(b1, b2, SPEED, dt=dt, gap=1e-4, drift=(0.3, -0.2, 0.5))
    (u1, _), (u2, _) = scene.body1, scene.body2

    def momenta():
        return (b1.mass * np.array(pb.getBaseVelocity(u1, physicsClientId=scene.client)[0]),
                b2.mass * np.array(pb.getBaseVelocity(u2, physicsClientId=scene.client)[0]))

    p1_0, p2_0 = momenta()
    with scene, PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law)]) as ad:
        seen_builtin = 0
        while not ad.records:
            ad.step()
            seen_builtin += len(pb.getContactPoints(u1, u2, physicsClientId=scene.client))
            assert ad.time < 100 * ref.tau
        p1, p2 = momenta()
        rec, impulse = ad.records[0], ad.impulse[0].copy()
    total0 = p1_0 + p2_0
    assert np.linalg.norm(p1 + p2 - total0) <= MOMENTUM_RTOL * np.linalg.norm(total0)
    # pybullet's own contact made no force: the whole change is the adapter's impulse
    assert seen_builtin == 0
    assert np.linalg.norm((p1 - p1_0) - impulse) <= IMPULSE_RTOL * np.linalg.norm(impulse)
    assert rel(rec.cor_n, ref.cor_n) <= RESOLVED_COR_RTOL


def test_paddle_link_matches_reference_with_effective_mass():
    law, b1, _ = msf_fixed()
    paddle, d = scenes.Paddle(), 0.2
    m_eff = paddle.effective_mass(d)
    ref = simulate_impact(law, b1, Body(RIGID, math.inf, m_eff), SPEED)
    dt = ref.tau / 60
    scene = scenes.paddle_and_ball(b1, paddle, d, SPEED, dt=dt, gap=1e-4)
    with scene, PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law)]) as ad:
        while not ad.records:
            ad.step()
            assert ad.time < 100 * ref.tau
        rec = ad.records[0]
        hinge_rate = pb.getJointState(scene.body2[0], 0, physicsClientId=scene.client)[1]
        v_ball, w_ball = pb.getBaseVelocity(scene.body1[0], physicsClientId=scene.client)
        pos = pb.getBasePositionAndOrientation(scene.body1[0], physicsClientId=scene.client)[0]
    assert rel(rec.inputs["mass_effective"], 1.0 / (1.0 / b1.mass + 1.0 / m_eff)) <= 1e-9
    assert rel(rec.cor_n, ref.cor_n) <= PADDLE_RTOL, (rec.cor_n, ref.cor_n)
    assert rel(rec.tau, ref.tau) <= RESOLVED_TAU_RTOL
    # angular momentum about the hinge axis (+y) is conserved: the motor is off and the
    # forces are equal and opposite at one point (paddle_and_ball has pybullet's hinge at the origin)
    L_before = b1.mass * d * SPEED
    L_after = (b1.mass * (pos[2] * v_ball[0] - pos[0] * v_ball[2]) + b1.J * w_ball[1]
               + paddle.hinge_inertia() * hinge_rate)
    assert rel(L_after, L_before) <= ANGULAR_MOMENTUM_RTOL


def test_registered_engines():
    assert get_engine("pybullet") is run_impact
    law, b1, b2 = msf_fixed()
    rec = get_engine("pybullet-builtin")(law, b1, b2, SPEED, dt=1e-4, gap=1e-4, builtin={"restitution": 0.5})
    assert rec.engine == "pybullet-builtin" and abs(rec.cor_n - 0.5) <= BUILTIN_COR_ATOL


# ------------------------------------------------ pybullet's own contact --
def test_builtin_restitution_is_the_product_of_both_bodies():
    b1, b2, _, _ = ball_plate()
    for e1, e2 in ((0.8, 0.5), (0.9, 0.9), (0.6, 1.0)):
        rec = run_builtin_impact(b1, b2, SPEED, dt=1e-4, gap=1e-4, builtin=BuiltinContact(restitution=(e1, e2)))
        assert abs(rec.cor_n - e1 * e2) <= BUILTIN_COR_ATOL, (e1, e2, rec.cor_n)
    # one number is the pair's value: sqrt(e) on each body
    rec = run_builtin_impact(b1, b2, SPEED, dt=1e-4, gap=1e-4, builtin={"restitution": 0.64})
    assert abs(rec.cor_n - 0.64) <= BUILTIN_COR_ATOL


def test_builtin_restitution_lost_at_small_speed_times_dt_unless_settings():
    b1, b2, _, _ = ball_plate()
    speed, dt = 0.05, 1e-3  # 50 um per step, below pybullet's 0.2 m/s threshold
    for k in range(5):
        gap = 1e-3 + speed * dt * k / 5
        lost = run_builtin_impact(b1, b2, speed, dt=dt, gap=gap,
                                  builtin=BuiltinContact(restitution=0.64, restitution_settings=False))
        kept = run_builtin_impact(b1, b2, speed, dt=dt, gap=gap, builtin=BuiltinContact(restitution=0.64))
        assert lost.cor_n == 0.0
        assert abs(kept.cor_n - 0.64) <= BUILTIN_COR_ATOL, (gap, kept.cor_n)


# -------------------------------------------------------------- bad input --
def test_bad_input_named():
    law, b1, b2 = msf_fixed()
    with pytest.raises(ValueError, match="dt"):
        run_impact(law, b1, b2, SPEED, dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        run_impact(law, b1, b2, SPEED, dt=-1e-4)
    with pytest.raises(ValueError, match="gap"):
        run_impact(law, b1, b2, SPEED, gap=-1e-3)
    with pytest.raises(ValueError, match="half-space"):
        run_impact(law, b1, Body(RIGID, math.inf, 1.0), SPEED)
    with pytest.raises(ValueError, match="contact_damping"):
        run_builtin_impact(b1, b2, SPEED, builtin={"contact_stiffness": 1e4})
    with pytest.raises(ValueError, match="unknown pybullet built-in"):
        run_builtin_impact(b1, b2, SPEED, builtin={"stiffness": 1e4})


def test_adapter_refuses_unknown_bodies_and_non_smooth_shapes():
    law, b1, _ = msf_fixed()
    scene = scenes.ball_on_plate(b1, SPEED, dt=1e-4, gap=1e-3)
    c = scene.client
    try:
        with pytest.raises(ValueError, match="999"):
            PybulletAdapter(c, [PairSpec((999, -1), scene.body2, law)])
        with pytest.raises(ValueError, match="link index 3"):
            PybulletAdapter(c, [PairSpec((scene.body1[0], 3), scene.body2, law)])
        # capsules, cylinders, boxes and meshes are carried (tests/test_narrow_pybullet.py); a height field is not
        field = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_HEIGHTFIELD, meshScale=[0.1, 0.1, 1.0],
                                                                heightfieldData=[0.0] * 16, numHeightfieldRows=4,
                                                                numHeightfieldColumns=4, physicsClientId=c),
                                   physicsClientId=c)
        with pytest.raises(ValueError, match="no collision shape.*height field.*pybullet's own contact"):
            PybulletAdapter(c, [PairSpec(scene.body1, (field, -1), law)])
        other = make_law("msf", ContactPair(PU, RIGID), Curvature(0.03, 0.03), omega=OMEGA_FIXED)
        with pytest.raises(ValueError, match="curvature R1a"):
            PybulletAdapter(c, [PairSpec(scene.body1, scene.body2, other)])
        with pytest.raises(ValueError, match="client"):
            PybulletAdapter(12345, [PairSpec(scene.body1, scene.body2, law)])
        with pytest.raises(ValueError, match=r"limit_trial = 1 must be True or False"):
            PybulletAdapter(c, [PairSpec(scene.body1, scene.body2, law)], limit_trial=1)
        with pytest.raises(ValueError, match=r"compiled = 'yes' must be True or False"):
            PybulletAdapter(c, [PairSpec(scene.body1, scene.body2, law)], compiled="yes")
    finally:
        scene.close()


def test_box_face_equals_plane():
    law, b1, b2 = msf_fixed()
    ref = simulate_impact(law, b1, b2, SPEED, angle_deg=60.0)
    out = {}
    for kind in ("plane", "box"):
        scene = scenes.ball_on_plate(b1, SPEED, 60.0, dt=ref.tau / 60, gap=1e-4, plate=kind)
        with scene, PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law)]) as ad:
            while not ad.records:
                ad.step()
            out[kind] = ad.records[0]
    assert out["box"].cor_n == pytest.approx(out["plane"].cor_n, rel=1e-12)
    assert out["box"].cor_t == pytest.approx(out["plane"].cor_t, rel=1e-12)
