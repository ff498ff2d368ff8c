"""The coupled-contact reference (msf_contact.chain): a collinear chain of
spheres, and a sphere between a sphere and a plate, as one ODE.

Checked against what must hold whatever the code: the two-body chain is the
isolated impact of the reference solver; momentum is conserved to round-off;
an elastic chain keeps its energy and a dissipative one never gains any;
Hertz's law has no length or time scale of its own, so an elastic cradle's
outgoing velocities scale with the impact speed; equal elastic spheres far
apart exchange their velocities exactly (binary collisions)."""

import math

import numpy as np
import pytest

from msf_contact import Body, ContactPair, Curvature, Material, make_law, preset, simulate_impact
from msf_contact.chain import onset_speed_floor, simulate_chain

STEEL = preset("steel")
R = 0.01
BALL = Body.sphere(STEEL, R)
#: Same integrator and tolerances as simulate_impact (RTOL 1e-11): the
#: two-body chain reproduces it far below the issue's 1e-6 convergence.
SAME_AS_REFERENCE_RTOL = 1e-9
#: F_max is refined on the dense output in both (a bounded search to ~1e-12
#: of the step): agreement to the convergence bound.
F_MAX_RTOL = 1e-6
#: Momentum: equal and opposite forces, summed in float64.
MOMENTUM_RTOL = 1e-12
#: Energy of an elastic chain and the "never gained" bound: the integration
#: error of DOP853 at RTOL 1e-11 over ~1e3 steps (measured 3e-12).
ENERGY_RTOL = 1e-9
#: Hertz scale invariance and binary exchange: limited by the integration
#: tolerance of the final velocities (measured ~1e-11).
VELOCITY_ATOL = 1e-8


def hertz():
    return make_law("hertz", ContactPair(STEEL, STEEL), Curvature.two_spheres(R, R))


def msf():
    return make_law("msf", ContactPair(STEEL, STEEL), Curvature.two_spheres(R, R))


def cradle(law, n, v0=1.0, gap=0.0, body=BALL):
    return simulate_chain([body] * n, (2 * R + gap) * np.arange(n), [v0] + [0.0] * (n - 1), [law] * (n - 1))


def test_two_bodies_equal_simulate_impact():
    law = msf()
    res = simulate_chain([BALL, BALL], [0.0, 2 * R + 1e-6], [1.0, 0.0], [law])
    ref = simulate_impact(law, BALL, BALL, 1.0)
    (rec,) = res.records
    for name in ("cor_n", "tau", "tau1", "x_max", "W_el_comp", "W_visc_comp", "W_visc_rest", "omega_x"):
        got, want = getattr(rec, name), getattr(ref, name)
        assert abs(got - want) <= SAME_AS_REFERENCE_RTOL * abs(want), (name, got, want)
    assert abs(rec.F_max - ref.F_max) <= F_MAX_RTOL * ref.F_max
    assert rec.ended_by == ref.ended_by
    # the free bodies' velocities follow from the COR and momentum
    v_cm = 0.5
    assert res.velocities == pytest.approx([v_cm - 0.5 * ref.cor_n, v_cm + 0.5 * ref.cor_n], abs=VELOCITY_ATOL)


def test_sphere_on_plate_equals_simulate_impact():
    """One body and the plate: the sphere-on-half-space impact."""
    rigid = Material.rigid_body()
    law = make_law("msf", ContactPair(STEEL, rigid), Curvature.sphere_on_plane(R))
    res = simulate_chain([BALL], [0.0], [2.0], [law], plate=R + 1e-6)
    ref = simulate_impact(law, BALL, Body.half_space(rigid), 2.0)
    (rec,) = res.records
    assert abs(rec.cor_n - ref.cor_n) <= SAME_AS_REFERENCE_RTOL * ref.cor_n
    assert abs(rec.tau - ref.tau) <= SAME_AS_REFERENCE_RTOL * ref.tau
    assert res.velocities[0] == pytest.approx(-2.0 * ref.cor_n, rel=SAME_AS_REFERENCE_RTOL)
    assert res.momentum[1] < 0  # the plate took momentum (its share is not counted)


@pytest.mark.parametrize("n", [3, 5])
def test_elastic_cradle(n):
    """Touching Hertz cradle: energy and momentum kept, every ball leaves
    slower than the one behind it ahead of it (no further collision), the
    first rebounds and the last carries nearly all (the dispersion of a
    Hertz chain: Hinch & Saint-Jean 1999); the outgoing velocities scale with
    the impact speed (Hertz has no scale of its own)."""
    law = hertz()
    res = cradle(law, n, 1.0)
    v = res.velocities
    p0, p1 = res.momentum
    assert abs(p1 - p0) <= MOMENTUM_RTOL * abs(p0)
    assert abs(np.sum(v**2) - 1.0) <= ENERGY_RTOL
    assert res.energy_gain_max <= ENERGY_RTOL
    assert res.energy_closure <= ENERGY_RTOL
    assert np.all(np.diff(v) > 0), v
    assert v[0] < 0 and 0.95 < v[-1] < 1.0, v
    slow = cradle(law, n, 0.1)
    assert slow.velocities / 0.1 == pytest.approx(v, abs=VELOCITY_ATOL)
    assert len(res.records) >= n - 1 and {r.inputs["contact"] for r in res.records} == set(range(n - 1))


def test_elastic_cradle_with_gaps_is_binary_exchange():
    """Gaps far longer than a contact (1 mm at 1 m/s: 1 ms, 20 contact
    durations): binary collisions of equal elastic spheres exchange the
    velocities exactly."""
    res = cradle(hertz(), 4, 1.0, gap=1e-3)
    assert res.velocities == pytest.approx([0.0, 0.0, 0.0, 1.0], abs=VELOCITY_ATOL)


@pytest.mark.parametrize("n", [3, 5])
def test_dissipative_cradle_never_gains(n):
    res = cradle(msf(), n, 1.0)
    assert abs(res.momentum[1] - res.momentum[0]) <= MOMENTUM_RTOL * res.momentum[0]
    assert res.energy_gain_max <= ENERGY_RTOL, res.energy_gain_max
    assert res.energy_closure <= ENERGY_RTOL
    ke = np.sum(0.5 * BALL.mass * res.velocities**2)
    assert ke < 0.5 * BALL.mass  # dissipated
    # the touching contacts began at rest: their onset constants used the floor
    later = [r for r in res.records if r.inputs["contact"] > 0]
    assert later and all(r.inputs["v_n_onset_used"] >= 1e-6 for r in later)


def test_struck_ball_on_plate_under_gravity():
    """A ball resting at its static overlap on a plate under gravity, struck
    from above (the axis points down): both contacts close and open, the
    total energy never rises and the lower ball's plate contact starts
    with its gravity floor speed."""
    law_bb = msf()
    law_bp = make_law("msf", ContactPair(STEEL, STEEL), Curvature.sphere_on_plane(R))
    g = 9.81
    K = 2.0 / 3.0 * law_bp.moduli.E * float(law_bp.psi(np.zeros(1))[0])
    x_s = (BALL.mass * g / K) ** (2.0 / 3.0)  # static overlap, (29) with k_p(0)
    plate = 3 * R - x_s
    res = simulate_chain([BALL, BALL], [0.0, 2 * R + 1e-6], [1.0, 0.0], [law_bb, law_bp], plate=plate,
                         accel=g, t_end=2e-3)
    assert res.energy_gain_max <= ENERGY_RTOL
    assert res.energy_closure <= ENERGY_RTOL
    by = {k: [r for r in res.records if r.inputs["contact"] == k] for k in (0, 1)}
    assert by[0] and by[1]
    # the resting contact began at t = 0 with the floor of its gravity load
    first = by[1][0]
    assert first.inputs["t_onset"] == 0.0
    assert first.inputs["v_n_onset_used"] == pytest.approx(float(onset_speed_floor(law_bp, BALL.mass, g)))
    assert res.velocities[0] < 0  # the striker rebounds up


def test_bad_input():
    law = hertz()
    with pytest.raises(ValueError, match="laws has 1 entries; expected 2"):
        simulate_chain([BALL] * 3, [0, 1, 2], [1, 0, 0], [law])
    with pytest.raises(ValueError, match="must increase"):
        simulate_chain([BALL] * 2, [1.0, 0.0], [1, 0], [law])
    with pytest.raises(ValueError, match="t_end"):
        simulate_chain([BALL] * 2, [0.0, 1.0], [1, 0], [law], accel=9.81)
    with pytest.raises(ValueError, match="finite radius and mass"):
        simulate_chain([Body.half_space(STEEL)], [0.0], [1.0], [])
    with pytest.raises(ValueError, match="velocities"):
        simulate_chain([BALL] * 2, [0.0, 1.0], [math.nan, 0], [law])
