"""MuJoCo adapter and built-in contact against the reference solver (issue 3).

Every impact here is compared with msf_contact.solver.simulate_impact (the
reference, converged to 1e-6) or with a conservation law; tolerances are
the issue's acceptance numbers unless stated.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

from engines.base import PairSpec, get_engine
from engines.mujoco import MujocoAdapter, installed, run_builtin_impact, run_impact, run_until_separated, scenes
from engines.mujoco.builtin import linear_oscillator_cor
from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact

pytestmark = pytest.mark.mujoco

# ---------------------------------------------------------------- tolerances --
#: Issue 3 acceptance: resolved steps (>= 50 per contact).
COR_RTOL_50 = 1e-3  # 0.1%
TAU_RTOL_50 = 1e-2  # 1%
#: Issue 3 acceptance: >= 250 steps per contact, COR and tau.
RTOL_250 = 2e-4  # 0.02%
#: Issue 3 acceptance: robotics steps (1-2 ms, contact 0.3-0.7 ms), every onset phase.
COR_RTOL_ROBOTICS = 5e-3  # 0.5%
#: Issue 3 acceptance: oblique impacts, cor_t and spin_out.
OBLIQUE_RTOL = 2e-2  # 2%
#: Issue 3 acceptance: resting overlap after a drop at dt = 2 ms.
REST_RTOL = 2e-2  # 2%
#: Issue 3 acceptance: total momentum of two spheres in flight.
MOMENTUM_RTOL = 1e-9
#: Impulse bookkeeping: the engine's momentum change against the sum of the
#: adapter's step-averaged forces times dt (both float64 sums over ~100 steps).
IMPULSE_RTOL = 1e-9
#: The paddle (articulated, driven hinge) against the reference solver with
#: the paddle's effective mass I/r^2 at the hit point: the actuator's spring
#: (kp = 1 N m/rad) and the face's rotation during the contact are outside
#: the reference model; they shift the COR by 4e-5 (measured), kept 25x.
PADDLE_RTOL = 1e-3
#: MuJoCo's soft contact with a constant impedance is a linear oscillator:
#: the COR does not depend on the impact speed (measured to ~1e-12).
BUILTIN_SPEED_RTOL = 1e-6
#: MuJoCo's contact ends where its (unilateral) force returns to zero; at
#: dt = timeconst/1000 the measured COR matches the force-zero linear
#: oscillator to 0.1% (Euler: 0.09%, 0.08%, 0.06% for zeta 0.1, 0.2, 0.4).
BUILTIN_FORCE_ZERO_RTOL = 2e-3
#: The overlap-zero formula exp(-zeta pi/sqrt(1-zeta^2)) underestimates that
#: COR (measured: by 2% at zeta 0.1, 9% at 0.2); "roughly" is 10% for zeta <= 0.2.
BUILTIN_EXP_RTOL = 0.10

RUBBER, STEEL, PTFE = preset("natural-rubber"), preset("steel"), preset("ptfe")
R = 0.02  # ball radius [m]
V = 1.0  # impact speed [m/s]


def ball(mat=RUBBER, radius=R) -> Body:
    return Body.sphere(mat, radius)


PLATE = Body.half_space(STEEL)


def law_of(name, mat=RUBBER, radius=R, R2=math.inf, **opts):
    return make_law(name, ContactPair(mat, STEEL), Curvature(radius, radius, R2, R2), **opts)


LAW_OPTIONS = {
    "msf": {},
    "hertz": {},
    "kuwabara-kono": {"A": 1e-5},
    "hunt-crossley": {"cor": 0.8},
    "spring-dashpot": {},
}


def rel_err(got, want):
    return abs(got - want) / abs(want)


# ------------------------------------------------ resolved steps (acceptance) --
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("steps, cor_rtol, tau_rtol", [(50, COR_RTOL_50, TAU_RTOL_50), (250, RTOL_250, RTOL_250)])
@pytest.mark.parametrize("name", list(LAW_OPTIONS))
def test_resolved_steps_match_reference(name, steps, cor_rtol, tau_rtol, integrator):
    law = law_of(name, **LAW_OPTIONS[name])
    ref = simulate_impact(law, ball(), PLATE, V)
    dt = ref.tau / steps
    rec = run_impact(law, ball(), PLATE, V, dt=dt, gap=0.37 * V * dt, integrator=integrator)
    assert rec.engine == "mujoco" and rec.law == name and rec.dt == dt
    assert rel_err(rec.cor_n, ref.cor_n) <= cor_rtol, (rec.cor_n, ref.cor_n)
    assert rel_err(rec.tau, ref.tau) <= tau_rtol, (rec.tau, ref.tau)
    assert rel_err(rec.x_max, ref.x_max) <= tau_rtol
    assert rel_err(rec.F_max, ref.F_max) <= tau_rtol


def test_implicitfast_integrator_matches_reference():
    law = law_of("hertz")
    ref = simulate_impact(law, ball(), PLATE, V)
    rec = run_impact(law, ball(), PLATE, V, dt=ref.tau / 50, integrator="implicitfast")
    assert rel_err(rec.cor_n, ref.cor_n) <= COR_RTOL_50
    assert rel_err(rec.tau, ref.tau) <= TAU_RTOL_50


def test_box_face_plate_matches_reference():
    law = law_of("hunt-crossley", cor=0.8)
    ref = simulate_impact(law, ball(), PLATE, V)
    rec = run_impact(law, ball(), PLATE, V, dt=ref.tau / 50, plate="box")
    assert rel_err(rec.cor_n, ref.cor_n) <= COR_RTOL_50
    assert rel_err(rec.tau, ref.tau) <= TAU_RTOL_50


# ------------------------------------------------ robotics steps (acceptance) --
N_PHASES = 20


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("dt", [1e-3, 2e-3])
def test_robotics_steps_every_onset_phase(dt, integrator):
    """A PTFE ball (R = 2 cm, 1 m/s: contact 0.62 ms) at dt = 1 and 2 ms; the
    gap puts the onset at N_PHASES different points inside a step."""
    law = law_of("msf", mat=PTFE)
    ref = simulate_impact(law, ball(PTFE), PLATE, V)
    assert 0.3e-3 <= ref.tau <= 0.7e-3
    errs = []
    for k in range(N_PHASES):
        gap = V * dt * (k + 0.5) / N_PHASES
        rec = run_impact(law, ball(PTFE), PLATE, V, dt=dt, gap=gap, integrator=integrator)
        errs.append(rel_err(rec.cor_n, ref.cor_n))
    assert max(errs) <= COR_RTOL_ROBOTICS, errs


# ---------------------------------------------------- oblique (acceptance) --
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("angle", [30.0, 60.0])
def test_oblique_cor_t_and_spin(angle, integrator):
    law = law_of("msf")
    ref = simulate_impact(law, ball(), PLATE, V, angle)
    rec = run_impact(law, ball(), PLATE, V, angle, dt=ref.tau / 50, integrator=integrator)
    assert rel_err(rec.cor_n, ref.cor_n) <= COR_RTOL_50
    assert rel_err(rec.cor_t, ref.cor_t) <= OBLIQUE_RTOL, (rec.cor_t, ref.cor_t)
    assert rel_err(rec.spin_out, ref.spin_out) <= OBLIQUE_RTOL, (rec.spin_out, ref.spin_out)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("angle", [30.0, 60.0])
def test_oblique_robotics_steps(angle, integrator):
    """The PTFE ball's 0.6 ms contact at dt = 1 and 2 ms (inside one or two
    steps), five onset phases: cor_t and spin_out still within 2% (measured:
    0.5% and 0.3% at 30 degrees, 0.8% and 0.4% at 60)."""
    law = law_of("msf", mat=PTFE)
    ref = simulate_impact(law, ball(PTFE), PLATE, V, angle)
    for dt in (1e-3, 2e-3):
        for k in range(5):
            rec = run_impact(law, ball(PTFE), PLATE, V, angle, dt=dt, gap=V * dt * (k + 0.5) / 5,
                             integrator=integrator)
            assert rel_err(rec.cor_n, ref.cor_n) <= COR_RTOL_ROBOTICS
            assert rel_err(rec.cor_t, ref.cor_t) <= OBLIQUE_RTOL, (dt, k, rec.cor_t, ref.cor_t)
            assert rel_err(rec.spin_out, ref.spin_out) <= OBLIQUE_RTOL, (dt, k, rec.spin_out, ref.spin_out)


def test_oblique_with_backspin_sign_convention():
    """Positive spin = rolling in the direction of incidence, as the reference."""
    law = law_of("msf")
    spin = -30.0
    ref = simulate_impact(law, ball(), PLATE, V, 45.0, spin)
    rec = run_impact(law, ball(), PLATE, V, 45.0, spin, dt=ref.tau / 50)
    assert rel_err(rec.spin_in, spin) <= 1e-12
    assert rel_err(rec.spin_out, ref.spin_out) <= OBLIQUE_RTOL, (rec.spin_out, ref.spin_out)
    assert rel_err(rec.cor_t, ref.cor_t) <= OBLIQUE_RTOL


# ---------------------------------------------------- drop to rest (acceptance) --
def static_overlap(law, body, g):
    onset = law.onset([1.0], [body.mass])
    return brentq(lambda x: float(law.normal_force(np.array([x]), np.array([0.0]), onset)[0]) - body.mass * g,
                  1e-15, 0.5 * body.radius, xtol=1e-18, rtol=1e-14)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_drop_comes_to_rest_without_energy_gain(integrator):
    """Dropped from 5 mm at dt = 2 ms (the contact lasts ~2.7 ms at 0.3 m/s):
    bounces with COR <= 1, flight energy never above the previous flight's,
    and rest at the static overlap m g = F_n(x_s, 0)."""
    g, dt = 9.81, 2e-3
    b = ball()
    law = law_of("msf")
    x_s = static_overlap(law, b, g)
    model, data = scenes.ball_on_plate(b, 1e-9, gap=5e-3, dt=dt, integrator=integrator, gravity=g)
    data.qvel[:] = 0.0
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "plate", law)])
    flights = []  # energy at every step without contact, grouped by flight
    in_flight = True
    with adapter:
        for _ in range(300):
            adapter.step(1)
            v = data.qvel[:3]
            energy = 0.5 * b.mass * v @ v + 0.5 * b.J * data.qvel[3:] @ data.qvel[3:] + b.mass * g * data.qpos[2]
            free = not adapter.manager.active[0] and data.qpos[2] > R
            if free and not in_flight:
                flights.append([])
            if free:
                if not flights:
                    flights.append([])
                flights[-1].append(energy)
            in_flight = free
    recs = adapter.records
    assert len(recs) >= 5  # it did bounce
    assert all(r.cor_n <= 1.0 for r in recs)
    # semi-implicit Euler loses 1/2 m g^2 dt^2 per flight step; no flight starts above the last
    for before, after in zip(flights, flights[1:]):
        assert after[0] <= before[-1] * (1 + 1e-12), (before[-1], after[0])
    x_end = R - data.qpos[2]
    assert adapter.manager.active[0]
    assert rel_err(x_end, x_s) <= REST_RTOL, (x_end, x_s)
    assert abs(data.qvel[2]) <= 1e-3 * math.sqrt(2 * g * 5e-3)


# ---------------------------------------------- two spheres (acceptance) --
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_two_spheres_conserve_momentum(integrator):
    b1, b2 = ball(), Body.sphere(RUBBER, 0.03)
    law = make_law("msf", ContactPair(RUBBER, RUBBER), Curvature(R, R, 0.03, 0.03))
    ref = simulate_impact(law, b1, b2, V, 60.0, 10.0)
    model, data = scenes.two_spheres(b1, b2, V, 60.0, 10.0, dt=ref.tau / 50, integrator=integrator, gap=1e-4)
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "ball2", law)])

    def momentum():
        return b1.mass * data.qvel[0:3] + b2.mass * data.qvel[6:9]

    p0 = momentum()
    run_until_separated(adapter, 10_000)
    p1 = momentum()
    assert np.linalg.norm(p1 - p0) <= MOMENTUM_RTOL * np.linalg.norm(p0), (p0, p1)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_two_spheres_head_on_match_reference(integrator):
    """Head-on (the reference solver keeps n fixed; in an oblique collision of
    two spheres the line of centres turns, which only the engine has)."""
    b1, b2 = ball(), Body.sphere(RUBBER, 0.03)
    law = make_law("msf", ContactPair(RUBBER, RUBBER), Curvature(R, R, 0.03, 0.03))
    ref = simulate_impact(law, b1, b2, V)
    rec = run_impact(law, b1, b2, V, dt=ref.tau / 50, integrator=integrator, gap=1e-4)
    assert rel_err(rec.cor_n, ref.cor_n) <= COR_RTOL_50
    assert rel_err(rec.tau, ref.tau) <= TAU_RTOL_50
    assert rel_err(rec.inputs["mass_effective"], ref.inputs["mass_reduced"]) <= 1e-12


# ----------------------------------------------------- not counted twice --
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_force_not_counted_twice(integrator):
    """MuJoCo makes no contact row for the pair, and the ball's momentum
    change equals the impulse of the adapter's forces (so every RK4 stage
    saw the same force, and nothing else pushed)."""
    b = ball()
    law = law_of("hertz")
    ref = simulate_impact(law, b, PLATE, V, 60.0)
    model, data = scenes.ball_on_plate(b, V, 60.0, dt=ref.tau / 50, integrator=integrator)
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "plate", law)])
    g_ball, g_plate = model.geom("ball").id, model.geom("plate").id
    v0 = data.qvel[:3].copy()
    impulse = np.zeros(3)
    passive = np.zeros(3)
    with adapter:
        for _ in range(200):
            adapter.step(1)
            if adapter.last_forces is not None:
                impulse += adapter.last_forces.force[0] * adapter.timestep
            passive += data.qfrc_passive[:3] * adapter.timestep
            for c in range(data.ncon):
                con = data.contact[c]
                assert {int(con.geom[0]), int(con.geom[1])} != {g_ball, g_plate} or con.efc_address < 0
            assert not np.any(data.efc_type == mujoco.mjtConstraint.mjCNSTR_CONTACT_PYRAMIDAL)
            assert not np.any(data.efc_type == mujoco.mjtConstraint.mjCNSTR_CONTACT_ELLIPTIC)
    dp = b.mass * (data.qvel[:3] - v0)
    assert len(adapter.records) == 1
    assert np.linalg.norm(dp - impulse) <= IMPULSE_RTOL * np.linalg.norm(dp), (dp, impulse)
    assert np.linalg.norm(dp - passive) <= IMPULSE_RTOL * np.linalg.norm(dp), (dp, passive)
    assert rel_err(adapter.records[0].cor_n, ref.cor_n) <= COR_RTOL_50


# ----------------------------------------------------------- the hook --
def _adapter(dt=1e-4, integrator="euler"):
    model, data = scenes.ball_on_plate(ball(), V, dt=dt, integrator=integrator)
    return MujocoAdapter(model, data, [PairSpec("ball", "plate", law_of("hertz"))])


class Boom(RuntimeError):
    pass


@pytest.mark.parametrize("previous", [None, "python hook"])
def test_exception_inside_hook_restores_previous_hook(previous):
    calls = []

    def old_hook(m, d):
        calls.append(d.time)

    adapter = _adapter()  # compile first: MuJoCo 4.0 cannot compile a model under a Python hook
    mujoco.set_mjcb_passive(old_hook if previous else None)
    try:

        def fail(kin):
            raise Boom("inside the hook")

        adapter.manager.step = fail
        with pytest.raises(Boom):
            with installed(adapter):
                adapter.step(5)
        assert mujoco.get_mjcb_passive() is (old_hook if previous else None)
        with pytest.raises(Boom):
            adapter.step(5)  # installs for the call only
        assert mujoco.get_mjcb_passive() is (old_hook if previous else None)
        if previous:
            assert calls, "the previous hook was not chained"
    finally:
        mujoco.set_mjcb_passive(None)


def test_one_hook_dispatches_by_data_and_chains():
    calls = []

    def old_hook(m, d):
        calls.append(id(d))

    a, b = _adapter(), _adapter()
    plain_model, plain_data = scenes.ball_on_plate(ball(), V)  # no adapter: untouched by the hook
    mujoco.set_mjcb_passive(old_hook)
    try:
        with installed(a), installed(b):
            hook = mujoco.get_mjcb_passive()
            assert hook is not old_hook
            with pytest.raises(ValueError, match="already installed"):
                with installed(a):
                    pass
            for _ in range(60):
                a.step(1)
                b.step(1)
                mujoco.mj_step(plain_model, plain_data)
            assert mujoco.get_mjcb_passive() is hook
        assert mujoco.get_mjcb_passive() is old_hook
        assert {id(a.data), id(b.data), id(plain_data)} <= set(calls)
        # identical set-ups stepped in lockstep through one hook: identical states
        np.testing.assert_array_equal(a.data.qvel, b.data.qvel)
        assert a.data.qvel[2] > 0  # both bounced
        np.testing.assert_array_equal(plain_data.qvel[:3], [0.0, 0.0, -V])  # excluded, no hook force: passes through
    finally:
        mujoco.set_mjcb_passive(None)


def test_rk4_calls_the_manager_once_per_step():
    adapter = _adapter(integrator="rk4")
    calls = []
    step = adapter.manager.step

    def counting(kin):
        calls.append(kin.t)
        return step(kin)

    adapter.manager.step = counting
    hook_calls = []

    def old(m, d):
        hook_calls.append(d.time)

    mujoco.set_mjcb_passive(old)
    try:
        adapter.step(10)
    finally:
        mujoco.set_mjcb_passive(None)
    assert len(hook_calls) == 40  # four RK4 stages per step
    assert len(calls) == 10 and len(set(calls)) == 10


def test_run_stops_soon_after_separation_and_guards_max_time():
    law = law_of("hertz")
    ref = simulate_impact(law, ball(), PLATE, V)
    dt = ref.tau / 50
    rec = run_impact(law, ball(), PLATE, V, dt=dt)
    assert rec.inputs["steps"] <= 50 * 1.02 + 2 * 8  # contact + at most the check interval, twice
    model, data = scenes.ball_on_plate(ball(), V, dt=dt)
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "plate", law)])
    with pytest.raises(RuntimeError, match="did not end within 20 steps"):
        run_until_separated(adapter, 20)
    assert mujoco.get_mjcb_passive() is None


# ------------------------------------------------------- articulated --
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_paddle_on_driven_hinge_matches_reference_effective_mass(integrator):
    """The paddle is a link on a hinge with a position actuator; the reference
    solver gets body 2 = a half-space of mass I_hinge / r^2 (the paddle's
    effective mass at the hit point), which the adapter must find through
    mj_jac and mj_solveM."""
    b = ball()
    hit_x = 0.15
    law = law_of("msf")
    model, data = scenes.paddle_and_ball(b, V, hit_x=hit_x, integrator=integrator, dt=1e-4)
    m_eff = scenes.hinge_inertia(model) / hit_x**2
    ref = simulate_impact(law, b, Body(STEEL, math.inf, m_eff), V)
    model, data = scenes.paddle_and_ball(b, V, hit_x=hit_x, integrator=integrator, dt=ref.tau / 50)
    adapter = MujocoAdapter(model, data, [PairSpec("ball", "paddle", law)])
    rec = run_until_separated(adapter, 10_000)
    assert rel_err(rec.inputs["mass_effective"], 1.0 / (1.0 / b.mass + 1.0 / m_eff)) <= 1e-9
    assert rel_err(rec.cor_n, ref.cor_n) <= PADDLE_RTOL, (rec.cor_n, ref.cor_n)
    assert rel_err(rec.tau, ref.tau) <= TAU_RTOL_50
    assert data.qvel[0] != 0.0  # the paddle swung


# ------------------------------------------------------------ bad input --
def test_bad_input_is_refused_with_names():
    law = law_of("hertz")
    with pytest.raises(ValueError, match="dt"):
        run_impact(law, ball(), PLATE, V, dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        run_impact(law, ball(), PLATE, V, dt=-1e-4)
    with pytest.raises(ValueError, match="integrator"):
        run_impact(law, ball(), PLATE, V, integrator="verlet")
    with pytest.raises(ValueError, match="exclusive"):
        run_impact(law, ball(), PLATE, V, builtin={"solref": (0.01, 1.0)})
    model, data = scenes.ball_on_plate(ball(), V)
    with pytest.raises(ValueError, match="'bal' is neither a geom name, a geom id nor a body name"):
        MujocoAdapter(model, data, [PairSpec("bal", "plate", law)])
    with pytest.raises(ValueError, match="body1 = 'plate' is a plane"):
        MujocoAdapter(model, data, [PairSpec("plate", "ball", law)])
    with pytest.raises(ValueError, match="R1a = 0.03"):
        MujocoAdapter(model, data, [PairSpec("ball", "plate", law_of("hertz", radius=0.03))])
    with pytest.raises(ValueError, match="empty"):
        MujocoAdapter(model, data, [])


@pytest.mark.parametrize("shape,slots", [("capsule", 2), ("ellipsoid", 1), ("cylinder", 4), ("box", 4)])
def test_other_geoms_go_through_the_narrow_phase(shape, slots):
    """Issue 13: shapes other than a sphere on a sphere, plane or box face are
    accepted, one managed contact per point MuJoCo's narrow phase may give
    (tests/test_narrow_mujoco.py has their physics and the refusals)."""
    xml = f"""<mujoco><worldbody><geom name="plate" type="plane" size="1 1 .1"/>
      <body name="b" pos="0 0 .1"><freejoint/><geom name="thing" type="{shape}" size=".02 .03 .02"/></body>
      </worldbody><contact><exclude body1="world" body2="b"/></contact></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    adapter = MujocoAdapter(model, mujoco.MjData(model), [PairSpec("thing", "plate", law_of("hertz"))])
    assert len(adapter.pairs) == slots


def test_registry():
    assert get_engine("mujoco") is run_impact
    assert get_engine("mujoco-builtin") is run_builtin_impact


# ------------------------------------------------------ built-in contact --
SOLIMP_CONSTANT = (0.95, 0.95, 0.001, 0.5, 2.0)  # d0 = d_width: constant impedance


@pytest.mark.parametrize("zeta", [0.1, 0.2, 0.4])
def test_builtin_cor_depends_on_dampratio_alone(zeta):
    """MuJoCo docs: with solref = (timeconst, dampratio) and a constant
    impedance the contact is a linear oscillator with damping ratio
    dampratio, so the COR is the same at 1 and 3 m/s and for another mass."""
    builtin = {"solref": (0.005, zeta), "solimp": SOLIMP_CONSTANT}
    slow = run_builtin_impact(ball(), PLATE, 1.0, builtin=builtin, dt=1e-4)
    fast = run_builtin_impact(ball(), PLATE, 3.0, builtin=builtin, dt=1e-4)
    heavy = run_builtin_impact(Body(RUBBER, R, 10 * ball().mass), PLATE, 2.0, builtin=builtin, dt=1e-4)
    assert rel_err(fast.cor_n, slow.cor_n) <= BUILTIN_SPEED_RTOL, (slow.cor_n, fast.cor_n)
    assert rel_err(heavy.cor_n, slow.cor_n) <= BUILTIN_SPEED_RTOL
    assert fast.x_max > 2.5 * slow.x_max  # the impacts really differ: penetration ~ speed
    assert slow.engine == "mujoco-builtin" and slow.parameters["solref"] == [0.005, zeta]


def test_builtin_cor_changes_with_dampratio_and_matches_linear_oscillator():
    tc, dt = 0.005, 5e-6
    cors = {}
    for zeta in (0.1, 0.2, 0.4):
        rec = run_builtin_impact(ball(), PLATE, V, builtin={"solref": (tc, zeta), "solimp": SOLIMP_CONSTANT},
                                 dt=dt)
        cors[zeta] = rec.cor_n
        assert rel_err(rec.cor_n, linear_oscillator_cor(zeta, end="force-zero")) <= BUILTIN_FORCE_ZERO_RTOL
        if zeta <= 0.2:
            assert rel_err(rec.cor_n, linear_oscillator_cor(zeta)) <= BUILTIN_EXP_RTOL
        # contact time: force-zero end of a damped oscillator with omega_n = 1/(tc zeta)
        assert rel_err(rec.tau, linear_oscillator_tau_force_zero(zeta, tc)) <= 2e-2
    assert cors[0.1] > cors[0.2] > cors[0.4]


def linear_oscillator_tau_force_zero(zeta, tc):
    wn = 1.0 / (tc * zeta)
    wd = wn * math.sqrt(1 - zeta**2)
    th = math.atan2(-2 * zeta * math.sqrt(1 - zeta**2), 1 - 2 * zeta**2) + math.pi
    return th / wd


def test_builtin_default_solimp_makes_cor_speed_dependent():
    """With MuJoCo's default solimp the impedance grows with penetration
    (0.9 -> 0.95 over 1 mm), so the COR is no longer speed-independent: the
    reason the comparison sets d0 = d_width."""
    builtin = {"solref": (0.005, 0.1)}
    slow = run_builtin_impact(ball(), PLATE, 1.0, builtin=builtin, dt=1e-4)
    fast = run_builtin_impact(ball(), PLATE, 3.0, builtin=builtin, dt=1e-4)
    assert rel_err(fast.cor_n, slow.cor_n) > 100 * BUILTIN_SPEED_RTOL


def test_builtin_bad_input():
    with pytest.raises(ValueError, match="solref"):
        run_builtin_impact(ball(), PLATE, V, builtin={"solimp": SOLIMP_CONSTANT})
    with pytest.raises(ValueError, match="solref"):
        run_builtin_impact(ball(), PLATE, V, builtin={"solref": (0.01, -1.0)})
    with pytest.raises(ValueError, match="solimp"):
        run_builtin_impact(ball(), PLATE, V, builtin={"solref": (0.01, 1.0), "solimp": (0.9, 1.2, 0.001)})
    with pytest.raises(ValueError, match="dt"):
        run_builtin_impact(ball(), PLATE, V, builtin={"solref": (0.01, 1.0)}, dt=0.0)
