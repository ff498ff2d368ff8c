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
