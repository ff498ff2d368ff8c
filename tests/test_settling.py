"""The resting island step with open gaps beside it (issue 10, the pile).

A settling pile lists, besides its resting contacts, the gaps between
spheres that nearly touch (islands.push_reach: within the reach of the
bodies' speeds over a step, or TOUCH_TOL). Such a gap row is in the
island, and the island took RK4 at its stiffest contact's internal step
for as long as one was listed, resting or not (the two steel spheres
below: ~960 substeps a 1 ms step in MuJoCo). The resting island step
(engines._contacts.resting.settle_island) now takes the gap rows along:
they carry no force and move with the island, and the step holds only if
every gap stays open at its end; a gap that would close is an impact and
the whole island goes back to RK4, which finds the onset.
"""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from engines._contacts.islands import TOUCH_TOL
from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact, static_overlap
import test_multi_contact as MC
from test_multi_contact import ENGINES, Scene, _engine_available

R, G, DT = 0.01, 9.81, 1e-3
STEEL = preset("steel")
#: Steps of the two resting spheres (0.2 s): they rest on the plate from the first steps.
REST_STEPS = 200
#: The plate contacts' internal overlap at rest against x_s of the sphere's weight [-]: the settled
#: step's force balance is exact to m SETTLED_VTOL v_x / dt (~1e-9 of the weight,
#: engines._contacts.state); 1e-6 as tests/test_static_overlaps.py.
INTERNAL_RTOL = 1e-6
#: The gap listed beside the resting contacts [m]: within TOUCH_TOL (1e-12 m), so the pair is a
#: candidate at every step however slowly the spheres move (islands.push_reach).
GAP = 1e-13
#: Normal COR of the sphere-sphere impact inside the island against the reference solver for two free
#: spheres at the record's approach speed [-]: the plate's forces on the two spheres during the
#: ~0.15 ms strike are ~m g, perpendicular to the line of centres (the resolved-step acceptance, 0.1 %,
#: as tests/test_multi_contact.py).
COR_RTOL = 1e-3
#: Round-off bound on a rise of the spheres' energy in a step [J] (E ~ 6e-3 J summed from terms of
#: up to 1e-2 J; measured rises <= 5e-15 J), as tests/test_pile.py.
ENERGY_ROUNDOFF = 1e-12


def _laws():
    plate = make_law("msf", ContactPair(STEEL, STEEL), Curvature.sphere_on_plane(R))
    pair = make_law("msf", ContactPair(STEEL, STEEL), Curvature.two_spheres(R, R))
    return plate, pair


def _scene(engine, x1, v1):
    """Two steel spheres (R = 10 mm) touching a steel plate at rest, sphere 0 at x = 0, sphere 1 at
    x = x1 [m] moving at v1 (3,) [m/s]; pairs (0, plate), (1, plate), (1, 0)."""
    plate, pair = _laws()
    ball = Body.sphere(STEEL, R)
    return Scene(engine, [ball, ball], [[0.0, 0.0, R], [x1, 0.0, R]], [[0.0, 0.0, 0.0], list(v1)],
                 [(0, -1), (1, -1), (1, 0)], [plate, plate, pair], G, DT)


@pytest.mark.parametrize("engine", ENGINES)
def test_resting_island_with_an_open_gap_settles(engine):
    """Two steel spheres resting on a steel plate GAP apart: the island of
    their plate contacts and the gap between them takes the settled step
    (before: RK4 at every step while the gap was listed), the gap stays
    open, the plate contacts rest at x_s of the weight, and the spheres'
    energy (kinetic + potential + the contacts' stored energy) never rises
    in a step beyond round-off plus (dt/2)|dq| (tests/test_static_overlaps.py)."""
    _engine_available(engine)
    sc = _scene(engine, 2 * R + GAP, (0.0, 0.0, 0.0))
    mgr = sc.adapter.manager
    settled_with_gap, E = [], []
    with contextlib.ExitStack() as stack:
        stack.enter_context(sc._ctx)
        for _ in range(REST_STEPS):
            sc.adapter.step(1)
            info = mgr.last_step_info
            listed = 2 in sc.calls[-1][0]
            settled_with_gap.append(listed and not mgr.active[2] and info["settled"] == 2 and info["substeps"] == 0)
            E.append(sc.energy(G) + mgr.stored_energy())
        _, v, _ = sc.state()
    assert all(settled_with_gap[REST_STEPS // 2:]), np.flatnonzero(~np.array(settled_with_gap))
    assert not mgr.active[2] and mgr.x[2] < 0.0
    assert np.max(np.abs(v)) < 1e-6
    o_plate = {k: a[[0]] for k, a in mgr._onset[mgr._group_of[0]].items()}
    x_s = static_overlap(mgr.pairs[0].law, np.array([sc.bodies[0].mass * G]), o_plate)
    np.testing.assert_allclose(mgr.x[:2], [x_s[0], x_s[0]], rtol=INTERNAL_RTOL, atol=0.0)
    # the potential at z, not z - dt v/2: the spheres are at rest after the first steps, where dq ~ 0
    assert np.max(np.diff(E[REST_STEPS // 2:])) <= ENERGY_ROUNDOFF
    assert mgr.island_energy_gains == []


@pytest.mark.parametrize("engine", ENGINES)
def test_closing_gap_leaves_the_settled_step(engine):
    """tests/test_multi_contact.py's struck resting ball: steel ball A
    (R = 2 cm) resting on a soft pad, steel ball B (R = 1 cm) falling on it
    at ~2 m/s. Once B's gap to A is listed (islands.push_reach) and still
    open at the step's end, the island of A's resting pad contact and that
    gap takes the settled step; the step in which the gap would close is
    refused (the gap's end overlap >= 0) and integrated by RK4, so the strike
    begins at touching and B's COR is the reference solver's for two free
    spheres (COR_RTOL; the pad's reasons: test_multi_contact). Taken as a gap
    with no force, B would have passed ~2 mm into A in that step."""
    _engine_available(engine)
    A, B = Body.sphere(STEEL, MC.RA), Body.sphere(STEEL, MC.RB)
    law_pad = make_law("msf", ContactPair(STEEL, MC.PAD), Curvature.sphere_on_plane(MC.RA), omega=300.0)
    law_pad_b = make_law("msf", ContactPair(STEEL, MC.PAD), Curvature.sphere_on_plane(MC.RB), omega=300.0)
    law_hit = make_law("msf", ContactPair(STEEL, STEEL), Curvature.two_spheres(MC.RB, MC.RA))
    gap = MC.V0 * MC.T_HIT + 0.5 * G * MC.T_HIT**2
    sc = Scene(engine, [A, B], [[0.0, 0.0, MC.RA], [0.0, 0.0, 2 * MC.RA + MC.RB + gap]], [[0, 0, 0], [0, 0, -MC.V0]],
               [(0, -1), (1, 0), (1, -1)], [law_pad, law_hit, law_pad_b], G, DT)
    mgr = sc.adapter.manager
    records, steps = [], []  # (gap listed, settled rows, substeps) per step up to the strike's
    with contextlib.ExitStack() as stack:
        stack.enter_context(sc._ctx)
        for _ in range(int(MC.T_HIT / DT) + 20):
            sc.adapter.step(1)
            records += sc.adapter.pop_records()
            if not records and not mgr.active[1]:
                info = mgr.last_step_info
                steps.append((1 in sc.calls[-1][0], info["settled"], info["substeps"]))
        records += sc.adapter.pop_records()
    strikes = [r for r in records if r.inputs["pair"] == 1]
    assert len(strikes) == 1, records
    rec = strikes[0]
    listed = [s for s in steps if s[0]]  # the steps with B's gap listed, the strike's step last
    assert len(listed) >= 2 and all(s[1] == 1 and s[2] == 0 for s in listed[:-1]), listed  # settled, the gap open
    assert listed[-1][1] == 0 and listed[-1][2] > 0, listed  # the strike's step: RK4
    assert rec.inputs["x_onset"] <= TOUCH_TOL, rec.inputs
    ref = simulate_impact(law_hit, B, A, rec.inputs["v_n_in"])
    assert rec.cor_n == pytest.approx(ref.cor_n, rel=COR_RTOL)
    assert mgr.island_energy_gains == []


# ------------------------------------------------------------ slow squeeze ---
#: The squeezed column: a natural-rubber ball (R = 10 mm) on the steel plate under a steel ball,
#: placed touching at rest; after SQUEEZE_SETTLE steps a downward push on the steel ball rises
#: smoothly (3 u^2 - 2 u^3, no kink to ring at) from 0 to SQUEEZE_PUSH over SQUEEZE_RAMP steps and is
#: held for SQUEEZE_HOLD steps, dt = 1 ms. The ramp lasts ~20 periods of the rubber contacts
#: (omega ~ 500 rad/s at rest): quasi-static, both contacts resting (older than
#: SETTLE_AFTER_DURATIONS durations, approaching far below SETTLED_SPEED_RATIO v_x).
SQUEEZE_SETTLE, SQUEEZE_RAMP, SQUEEZE_HOLD = 150, 200, 50
#: The push at the end of the ramp [N]: ~3 times the steel ball's weight (0.32 N).
SQUEEZE_PUSH = 1.0
#: Normal forces of the backward-Euler path (settled rows, resting islands) against the RK4 island
#: path (ContactManager.settled_path off) step by step over the ramp and hold [-]. The settled force
#: is the law's at the step's end state, RK4's the step's mean; on a quasi-static ramp they differ by
#: the curvature of the force history within a step and by the ringing the ramp excites, which RK4
#: resolves and the rubber's damping decays while backward Euler damps it in a step. Measured 1.2e-3
#: over the ramp, 1.8e-4 in the hold (both engines, the same digits); a kinked (linear) ramp rang
#: 7.6e-3.
SQUEEZE_FORCE_RTOL = 2e-3
#: The internal overlaps of the two paths [-], beyond one step's advance of the RK4 overlap
#: |x(t) - x(t - dt)|: backward Euler's force is the end state's, RK4's the step's mean, so the
#: settled overlap lags the RK4 one by up to one step's advance on a ramp (measured 0.25 um at
#: 0.49 um a step); beyond that they agree as the forces do (F ~ x^1.5; 1.6e-4 in the hold).
SQUEEZE_X_RTOL = 2e-3
#: Both paths' overlaps at the end of the hold against x_s of the load each contact carries (the
#: weights above plus the push) [-]: the residual motion after 50 steps of hold (the paths 1.6e-4
#: apart at its end).
SQUEEZE_STATIC_RTOL = 1e-3


def _squeeze(engine, settled_path):
    """The squeezed column of SQUEEZE_* in ``engine`` with the settled path on or off: per step the
    normal forces (2,) [N] and the internal overlaps (2,) [m] of (rubber-plate, steel-rubber), and the
    rows the settled path took; and the loads (2,) [N] at the end."""
    rubber, steel = Body.sphere(preset("natural-rubber"), R), Body.sphere(STEEL, R)
    laws = [make_law("msf", ContactPair(preset("natural-rubber"), STEEL), Curvature.sphere_on_plane(R)),
            make_law("msf", ContactPair(STEEL, preset("natural-rubber")), Curvature.two_spheres(R, R))]
    sc = Scene(engine, [rubber, steel], [[0.0, 0.0, R], [0.0, 0.0, 3 * R]], [[0.0, 0.0, 0.0]] * 2,
               [(0, -1), (1, 0)], laws, G, DT)
    mgr = sc.adapter.manager
    mgr.settled_path = settled_path
    F, x, settled = [], [], []
    with contextlib.ExitStack() as stack:
        stack.enter_context(warnings_off())
        stack.enter_context(sc._ctx)
        for k in range(SQUEEZE_SETTLE + SQUEEZE_RAMP + SQUEEZE_HOLD):
            u = min(max(k - SQUEEZE_SETTLE, 0) / SQUEEZE_RAMP, 1.0)
            push = SQUEEZE_PUSH * u * u * (3.0 - 2.0 * u)
            if engine == "mujoco":
                sc.data.xfrc_applied[2, 2] = -push  # body 0 is the world, 1 the rubber ball, 2 the steel one
            else:
                pb, c = sc._pb, sc._client
                centre = pb.getBasePositionAndOrientation(sc.uids[1], physicsClientId=c)[0]
                pb.applyExternalForce(sc.uids[1], -1, [0.0, 0.0, -push], centre, pb.WORLD_FRAME, physicsClientId=c)
            sc.adapter.step(1)
            Fn = {r.pair: r.F_n for r in sc.adapter.contact_forces()}
            F.append([Fn.get(0, 0.0), Fn.get(1, 0.0)])
            x.append(mgr.x[:2].copy())
            settled.append(mgr.last_step_info["settled"])
    load = np.array([(rubber.mass + steel.mass) * G + SQUEEZE_PUSH, steel.mass * G + SQUEEZE_PUSH])
    return np.array(F), np.array(x), np.array(settled), load, mgr


@contextlib.contextmanager
def warnings_off():
    """The push does work the island energy check does not see (an outside force): its flags are not
    what this test is about."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


@pytest.mark.parametrize("engine", ENGINES)
def test_slow_squeeze_backward_euler_agrees_with_rk4(engine):
    """Issue 10: the settled path (one backward-Euler step of the resting
    island, engines._contacts.resting, and of rows alone) and the RK4 island
    path give the same normal forces and overlaps on a slowly squeezed
    column (SQUEEZE_*), step by step over the ramp and the hold, and both
    end at the static overlaps of the loads."""
    _engine_available(engine)
    Fa, xa, sa, load, mgr = _squeeze(engine, True)
    Fb, xb, sb, _load, _mgr = _squeeze(engine, False)
    ramp = slice(SQUEEZE_SETTLE, None)
    assert np.all(sb == 0) and np.count_nonzero(sa[ramp] == 2) >= 0.9 * (SQUEEZE_RAMP + SQUEEZE_HOLD), sa[ramp]
    np.testing.assert_allclose(Fa[ramp], Fb[ramp], rtol=SQUEEZE_FORCE_RTOL, atol=0.0)
    step = np.abs(np.diff(xb, axis=0))[SQUEEZE_SETTLE - 1:]
    assert np.all(np.abs(xa[ramp] - xb[ramp]) <= step + SQUEEZE_X_RTOL * xb[ramp]), \
        np.max((np.abs(xa[ramp] - xb[ramp]) - step) / xb[ramp], axis=0)
    o = [{k: a[mgr._pos[[p]]] for k, a in mgr._onset[mgr._group_of[p]].items()} for p in (0, 1)]
    x_s = np.array([static_overlap(mgr.pairs[p].law, load[[p]], o[p])[0] for p in (0, 1)])
    for x in (xa, xb):
        np.testing.assert_allclose(x[-1], x_s, rtol=SQUEEZE_STATIC_RTOL, atol=0.0)
