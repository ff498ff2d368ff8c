"""Particle-particle contacts in the jet (issue 10 item 5) and the contact
geometry they need: two spheres that close within a step meet on the
normal of first touch (engines._sweep), not on the step-start line of
centres.

- two glass beads in free flight, oblique collisions at 60 m/s closing
  inside one 0.1 ms step, MuJoCo (compiled and numpy paths): the record's
  normal is the normal of first touch, and both beads leave with the
  velocities of the reference solver's two-sphere impact; beads that miss
  each other pass untouched;
- a dense jet (MuJoCo): fast beads overtake slow ones in flight; the
  particle-particle records are there, none gains energy, and each one that
  began outside an island (two beads alone) has the reference solver's
  cor_n for a sphere-sphere pair at its closing speed;
- pybullet refuses particle-particle jets, naming the reason.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from engines._sweep import sweep
from engines.base import PairSpec
from experiments.scenarios.jet import JetSpec, Nozzle, Particles, Plate, make_pool
from msf_contact import Body, ContactPair, Curvature, ValidityWarning, make_law, preset, simulate_impact

R = 2.5e-4  # bead radius [m]
GLASS = preset("glass")
#: cor_n of a two-bead contact against the reference solver at the record's
#: closing speed (absolute): the engines take omega_x from the scaled onset
#: table, the reference solves it (tests/test_jet.py's plate impacts: ~2e-5).
#: Measured 3e-7 for every two-bead record of the dense jet below (before
#: the held normal: 1.4e-2 for a contact straddling a step start).
PP_COR_N_ATOL = 1e-4
#: Outgoing bead velocities after an oblique two-bead collision against the
#: reference solver's (cor_n, cor_t) on the normal of first touch, relative
#: to the closing speed: cor_t differs by 2e-6 (the engines' RK4 at
#: tau/200 against DOP853); measured <= 1e-6 of 60 m/s.
VELOCITY_RTOL = 1e-4
#: Spin after the collision against the reference's spin_out (relative):
#: measured 2e-6; before the timing correction was taken back on the normal
#: of first touch (MujocoAdapter._held_geometry) it was 10 % low.
SPIN_RTOL = 1e-4
#: The record's normal against the exact normal of first touch (round-off of
#: the quadratic's root and of MuJoCo's positions).
NORMAL_ATOL = 1e-9
#: A two-bead contact is alone when no other contact of either bead begins
#: within this time of its onset [s] (half an engine step; the contacts last
#: ~1 us): then it must be the reference's isolated sphere-sphere impact.
ALONE_WINDOW = 5e-5
#: A contact may not end with more normal kinetic energy than it began with:
#: cor_n <= 1 up to round-off; W_diss_n, W_diss_t >= 0 up to this fraction of
#: the contact's incoming relative kinetic energy (the manager's own
#: ENERGY_GAIN_RTOL is 1e-3; measured: all positive).
GAIN_RTOL = 1e-9


def pp_law():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        return make_law("msf", ContactPair(GLASS, GLASS), Curvature.two_spheres(R, R))


def two_beads(b_frac: float, compiled: bool, speed: float = 30.0, dt: float = 1e-4, gap: float = 1.3e-3):
    """Bead 0 at the origin moving +x, bead 1 ahead at an impact parameter
    b = b_frac 2R moving -x, both at ``speed``; returns (records, final
    velocities (2, 3), final spins (2, 3))."""
    import mujoco

    from engines.mujoco import MujocoAdapter

    b = Body.sphere(GLASS, R)
    J = b.J
    pos = [(0.0, 0.0, 0.01), (2 * R + gap, b_frac * 2 * R, 0.01)]
    geoms = "".join(
        f'<body name="b{k}" pos="{p[0]!r} {p[1]!r} {p[2]!r}"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{b.mass!r}" diaginertia="{J!r} {J!r} {J!r}"/>'
        f'<geom name="b{k}" type="sphere" size="{R!r}" mass="0" contype="0" conaffinity="0"/></body>'
        for k, p in enumerate(pos))
    xml = (f'<mujoco><option timestep="{dt!r}" integrator="Euler" gravity="0 0 0"><flag autoreset="disable"/>'
           f"</option><worldbody>{geoms}</worldbody></mujoco>")
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[0], d.qvel[6] = speed, -speed
    mujoco.mj_forward(m, d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        with MujocoAdapter(m, d, [PairSpec("b0", "b1", pp_law())], compiled=compiled) as ad:
            for _ in range(int(round(2 * gap / speed / dt)) + 10):
                ad.step()
            recs = ad.pop_records()
    return recs, np.array([d.qvel[0:3], d.qvel[6:9]]), np.array([d.qvel[3:6], d.qvel[9:12]])


@pytest.mark.mujoco
@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("b_frac", [0.0, 0.3, 0.6, 0.95])
def test_oblique_bead_collision_meets_on_the_normal_of_first_touch(b_frac, compiled):
    """Before engines._sweep: the 53 deg collision (b = 0.6 2R) was solved on
    the step-start line of centres (80 deg) and bead 0 left at
    (-28.6, -7.4) m/s instead of (-13.4, -21.9) m/s."""
    v = 30.0
    recs, vel, spin = two_beads(b_frac, compiled, v)
    assert len(recs) == 1
    rec = recs[0]
    # first touch: centres 2R apart with the offset b across the line of flight
    n_true = np.array([-math.sqrt(1.0 - b_frac ** 2), -b_frac, 0.0])  # from bead 1 to bead 0
    np.testing.assert_allclose(rec.inputs["normal"], n_true, atol=NORMAL_ATOL)
    w = np.array([2 * v, 0.0, 0.0])  # bead 0 relative to bead 1
    vn = -float(w @ n_true)
    assert rec.inputs["v_n_in"] == pytest.approx(vn, rel=1e-9)
    b = Body.sphere(GLASS, R)
    angle = math.degrees(math.asin(vn / (2 * v)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        ref = simulate_impact(pp_law(), b, b, 2 * v, angle)
    assert rec.cor_n == pytest.approx(ref.cor_n, abs=PP_COR_N_ATOL)
    w_t = w + vn * n_true
    w_out = ref.cor_n * vn * n_true + (ref.cor_t if ref.cor_t is not None else 0.0) * w_t
    # equal masses: each bead keeps the mean velocity (zero) plus half the relative one
    np.testing.assert_allclose(vel[0], 0.5 * w_out, atol=VELOCITY_RTOL * 2 * v)
    np.testing.assert_allclose(vel[1], -0.5 * w_out, atol=VELOCITY_RTOL * 2 * v)
    if b_frac > 0:  # spin: the timing correction is taken back on the normal of first touch
        assert rec.spin_out == pytest.approx(ref.spin_out, rel=SPIN_RTOL)
        np.testing.assert_allclose(spin[0], spin[1], atol=SPIN_RTOL * abs(ref.spin_out))  # equal beads
    # momentum (both beads, equal masses): the step-averaged forces are equal and opposite
    np.testing.assert_allclose(vel.sum(axis=0), 0.0, atol=1e-9 * v)


@pytest.mark.mujoco
@pytest.mark.parametrize("compiled", [True, False])
def test_beads_that_miss_pass_untouched(compiled):
    """An impact parameter above 2R: the step-start line of centres predicted
    a head-on approach; the closest approach says they never touch."""
    recs, vel, spin = two_beads(1.05, compiled)
    assert recs == []
    np.testing.assert_array_equal(vel, [[30.0, 0.0, 0.0], [-30.0, 0.0, 0.0]])
    np.testing.assert_array_equal(spin, 0.0)


def test_sweep_reduces_to_the_line_of_centres_for_collinear_motion():
    """A cradle or a stack: closing along the line of centres keeps the
    normal (to round-off) and the gap; separating or touching pairs are not swept."""
    e = np.array([[3e-3, 0.0, 0.0], [3e-3, 0.0, 0.0], [1e-3, 0.0, 0.0]])
    w = np.array([[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    swept, n, x = sweep(e, w, np.array([2e-3, 2e-3, 2e-3]), 1e-3)
    assert swept.tolist() == [True, False, False]  # the third overlaps already
    np.testing.assert_allclose(n[0], [1.0, 0.0, 0.0], atol=1e-15)
    assert x[0] == pytest.approx(-1e-3, rel=1e-12)


@pytest.mark.parametrize("w", [[-0.01, 0.0, 0.05], [-0.01, 0.0, 0.2]], ids=["touch", "miss"])
def test_sweep_of_a_later_approach_takes_the_step_end(w):
    """Spheres (S = 20 mm) 0.1 mm apart sliding past each other slowly: a
    first touch (10.7 ms) or a closest approach (5.0 ms) after the 1 ms
    step. The manager's gap x - (w . n) t along the returned normal is the
    true gap S - |e + w t| at the step's end, above it before (never later
    to close), and below 0 all through the step (no touch in it)."""
    S, dt = 0.02, 1e-3
    e, w = np.array([S + 1e-4, 0.0, 0.0]), np.array(w)
    swept, n, x = sweep(e[None], w[None], np.array([S]), dt)
    assert swept[0]
    t = np.linspace(0.0, dt, 101)
    true = S - np.linalg.norm(e + w * t[:, None], axis=1)
    lin = x[0] - float(w @ n[0]) * t
    assert lin[-1] == pytest.approx(true[-1], rel=1e-12)
    assert np.all(lin >= true - 1e-18) and np.all(lin < 0.0)
    np.testing.assert_allclose(n[0], (e + w * dt) / np.linalg.norm(e + w * dt), rtol=1e-15)


def dense_spec(pool=24) -> JetSpec:
    """Overtaking in flight: a narrow beam (1 deg cone, 0.6 mm exit) 50 mm
    long with speeds 30 +- 9 m/s at 1e5 particles/s; fast beads catch slow
    ones before the plate."""
    a = math.radians(45.0)
    return JetSpec(Nozzle.aimed((0.0, 0.0), (math.cos(a), 0.0, -math.sin(a)), 0.05, 1.0, 6e-4),
                   Particles(GLASS, (R,), (1.0,), 30.0, 9.0, 1e5), Plate(preset("polyurethane")),
                   particle_particle=True, dt=1e-4, pool=pool)


@pytest.mark.mujoco
def test_dense_jet_particle_particle_records():
    spec = dense_spec()
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        with make_pool("mujoco", spec, 0) as pool:
            pool.run(24, sink=rows.extend)
            mgr = pool.bodies.adapter.manager
    # the islands of beads touching each other and the plate keep their energy (engines._contacts.balance);
    # one whose bead the pool parked (placed) before the step's end was read is not checked (measured:
    # 38 island steps checked, largest rise of kinetic + stored 2.7e-19 J; 13 discarded; docs/jet.md)
    assert mgr._balance.checked >= 10 and mgr._balance.discarded >= 1
    assert mgr.island_energy_gains == [], mgr.island_energy_gains
    assert not any("island energy" in r["outside_validity"] for r in rows)
    pp = [r for r in rows if r["kind"] == "particle-particle"]
    assert len(pp) >= 5, f"the dense jet gave {len(pp)} particle-particle records"
    assert pool.counts.pp_impacts == len(pp)
    # energy accounted: the counter is the sum of the records' dissipation
    assert pool.counts.pp_W == pytest.approx(sum(r["W_diss_n"] + r["W_diss_t"] for r in pp), rel=1e-12)
    law = spec.pp_laws()[(0, 0)]
    b = Body.sphere(GLASS, R)
    m_eff = 0.5 * b.mass
    # the contacts of each bead, (t_onset, t_end) [s]
    spans = {}
    for r in rows:
        if r["kind"] == "impact":
            spans.setdefault(r["particle"], []).append((r["t_onset"], r["t_onset"] + r["tau"]))
        else:
            for i in (r["p1"], r["p2"]):
                spans.setdefault(i, []).append((r["t_onset"], r["t_end"]))
    alone = 0
    for r in pp:
        E_in = 0.5 * m_eff * (r["v_n_in"] ** 2 + r["v_t_in"] ** 2)
        assert r["cor_n"] <= 1.0 + 1e-12, r
        assert r["W_diss_n"] >= -GAIN_RTOL * E_in and r["W_diss_t"] >= -GAIN_RTOL * E_in, r
        assert "energy gained" not in r["outside_validity"], r
        others = [s for i in (r["p1"], r["p2"]) for s in spans[i] if s != (r["t_onset"], r["t_end"])]
        if all(abs(s[0] - r["t_onset"]) > ALONE_WINDOW for s in others):
            # two beads alone (no other contact of either within the window): the reference's
            # sphere-sphere impact, also across a step start (3,4 at 1.5998 ms straddles 1.6 ms)
            alone += 1
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ValidityWarning)
                ref = simulate_impact(law, b, b, r["v_n_in"], 90.0)
            assert abs(r["cor_n"] - ref.cor_n) <= PP_COR_N_ATOL, (r["cor_n"], ref.cor_n)
    assert alone >= 3
    impacts = [r for r in rows if r["kind"] == "impact"]
    assert any(r["deflected"] for r in impacts)  # plate impacts after a particle-particle contact
    # no plate impact leaves faster than it came, except one struck by a neighbour while on the plate:
    # that one takes the neighbour's energy (measured: bead 13's plate contact, 4.3760-4.3992 ms, struck
    # by bead 15 at 4.3876 ms, cor_n 1.001; its island's energy, checked above, does not rise)
    struck = [r for r in impacts if any(r["t_onset"] < s[0] < r["t_onset"] + r["tau"] for s in spans[r["particle"]]
                                        if s[0] != r["t_onset"])]
    assert all(r["cor_n"] <= 1.0 for r in impacts if r not in struck), [r for r in impacts if r not in struck]
    assert len(struck) <= 2


@pytest.mark.pybullet
def test_pybullet_refuses_particle_particle_jets():
    with pytest.raises(ValueError, match=r"particle_particle = true is not supported in pybullet.*first touch"):
        make_pool("pybullet", dense_spec(), 0)
