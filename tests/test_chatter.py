"""Issue 10, "never a silent wrong answer": the gap the manager keeps
between steps (engines._contacts.gaps.KEPT_GAP_DOC) for a body that bounces
or chatters on a stiff contact.

The scene: a steel sphere (R = 10 mm) dropped from rest GAP above a steel
plate under gravity, at dt = 1 ms, MSF on the pair. Steel on steel is stiff
and nearly elastic (COR 0.996 at these speeds), so the sphere bounces a few
um high on a 3-step cycle for the whole run, its contact opening and
closing; the pair stays a candidate, and between its contacts the manager
keeps its own gap. (That gap ratchets: relaxed toward the engine's x, whose
lead comes and goes with the bounce, it drifts from the gap the integration
follows by 0.2-0.9 um here; relaxed toward x~ instead the drift is 3e-10 m,
but the suite then fails elsewhere: docs/engines.md. Not changed.)
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from msf_contact._validate import ValidityWarning
from msf_contact import Body, ContactPair, Curvature, make_law, preset
from test_multi_contact import Scene, _engine_available

DT, STEPS, GAP, G, R = 1e-3, 300, 10e-6, 9.81, 0.01  # s, steps, m, m/s^2, m


def _one_sphere(engine):
    steel = preset("steel")
    law = make_law("msf", ContactPair(steel, steel), Curvature.sphere_on_plane(R))
    scene = Scene(engine, [Body.sphere(steel, R)], [[0.0, 0.0, R + GAP]], [[0.0, 0.0, 0.0]], [(0, -1)], [law], G,
                  DT)
    return scene.adapter, scene._ctx


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
def test_a_kept_gap_the_engine_has_left_behind_is_flagged(engine):
    """Never silent (gaps.KeptGapCheck): the same sphere, its floor gap as the
    manager keeps it moved GAP_DRIFT open after MOVE_AT steps (as the
    steel sphere's wall gap had drifted in the pour that ejected it, 28 um
    open with the engine's sphere 91 um in: docs/engines.md), so the engine's
    sphere falls into the floor with no force on it. The fall-back bound of
    the kept gap (twice the leads summed, ~0.2 mm while the sphere flies)
    lets the manager keep that gap (0.16 mm after 30 bounce steps), so nothing else says so: the check flags
    the pair (ContactManager.kept_gap_flags), warns on stderr (again only for a tenfold overlap) naming
    the pair and dt, and the pair's next contact carries the note in its
    record's outside_validity."""
    _engine_available(engine)
    ad, ctx = _one_sphere(engine)
    mgr = ad.manager
    floor = 0  # the one pair
    moved = False
    records = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with ctx:
            for k in range(STEPS):
                ad.step(1)
                records += ad.pop_records()
                if not moved and k >= MOVE_AT and not mgr.active[floor]:
                    mgr.x[floor] -= GAP_DRIFT  # the kept gap moved open (drifted), the engine's sphere where it is
                    moved = True
                if mgr.kept_gap_flags and any(r.inputs["t_onset"] >= mgr.kept_gap_flags[0][0] for r in records):
                    break
            records += ad.pop_records()
    assert moved
    flags = mgr.kept_gap_flags
    assert flags and all(f[1] == floor and f[2] > 0.0 and f[3] < 0.0 for f in flags), flags
    # none before the move: the bounce's own ratchet (KEPT_GAP_DOC, <= 1.34 approach energies) is below the bound
    assert flags[0][0] >= MOVE_AT * DT, flags[0]
    msgs = [str(w.message) for w in caught if issubclass(w.category, ValidityWarning) and "kept gap" in str(w.message)]
    # warned at the first flagged step, again only for a tenfold larger overlap (gaps.REWARN_FACTOR): from the
    # first flagged overlap (> 0.1 um, the energy bound) to GAP_DRIFT at most three times
    assert 1 <= len(msgs) <= 3 and all(f"pair {floor} " in m and "dt = 0.001 s" in m for m in msgs), msgs
    t_flag = flags[0][0]
    noted = [r for r in records if r.inputs["pair"] == floor and r.inputs["t_onset"] >= t_flag]
    assert noted and any("kept gap" in note for note in noted[0].outside_validity), noted[:1]


#: the step after which the kept gap is moved: the fall-back bound has grown to ~0.16 mm by then
MOVE_AT = 60
#: how far the kept floor gap is moved open in the flagged test [m]: 60 um, inside the fall-back bound and
#: far beyond the steel contact's overlaps here (0.1-1 um), as the pour's 28 + 91 um
GAP_DRIFT = 60e-6
