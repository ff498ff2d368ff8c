"""A box on a box's face bounded by that face (issue 13;
engines._narrow.BoxOnBox): a corner beyond the face's edge touches nothing
there; its slot is carried at the face's nearest point under the upper
box's own face (the foot clamped into the face: a corner of the two faces'
overlap, on the lower box's edge).

Before (main dff70d0) the lower box's face was an unbounded plane: an upper
box set flat over the lower one's edge, its centre 20 mm off (its +x
corners 20 mm beyond the face), rested on all four corners, two of them in
the air 20 mm past the edge, and the edge under it carried nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from engines._narrow import BoxOnBox, LawBank, make_shape
from msf_contact import ContactPair, Curvature, make_law, preset

ENGINES = [pytest.param("mujoco", marks=pytest.mark.mujoco), pytest.param("pybullet", marks=pytest.mark.pybullet)]

#: The boxes' half-extent [m] and mass [kg] (scripts/box_stack.py's).
HALF, MASS = 0.025, 0.1
#: The upper box's centre this far off the lower box's along x [m]
#: (scripts/box_stack.py's OVERHANG: its centre of mass still over the face,
#: 20 < 25 mm, its +x corners 20 mm past it).
OFFSET = 0.02
#: The lower box's slide on the floor by the end of the overhang scene [m]
#: (its tangential springs under the upper box's push: measured 2.7 um),
#: the tolerance on the world points against its face's edge.
SLIDE_ATOL = 2e-5
#: Steps of the overhang scene: the fall through the gap (6 ms) and the
#: rocking between the corners and the edge that follows (at 150 steps the
#: corners still leave the face; at 300 all four slots are in contact).
OVERHANG_STEPS = 300


def _law():
    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))


def _poses(offset: float, gap: float):
    """(pos1, rot1, pos2, rot2): body 1 the upper box, flat, ``offset`` [m] off
    along x and ``gap`` [m] above the lower box (body 2, at the origin)."""
    return np.array([offset, 0.0, 2 * HALF + gap]), np.eye(3), np.zeros(3), np.eye(3)


def test_a_corner_beyond_the_face_is_carried_at_the_face_s_edge():
    """The upper box flat, 10 um into the lower box's face, offset along x:
    every slot's point lies on the face (its foot within the lower box's
    half-extents), the corners beyond the edge moved onto it (x = HALF) at
    the same depth; offset less than the edge radius, no corner moves."""
    box = make_shape("box", (HALF, HALF, HALF))
    law, bank = _law(), LawBank()
    for offset, beyond in ((0.0, 0), (5e-4, 0), (OFFSET, 2), (-OFFSET, 2), (0.045, 2)):
        bb = BoxOnBox(box, box, ("top", "bottom"))
        bb.update(*_poses(offset, -1e-5), np.zeros(4, bool), law, bank, up=np.array([0.0, 0.0, 1.0]))
        assert bb.which == 1 and bb.face == (2, 1.0)
        per = bb.slots(np.eye(4) / MASS, np.zeros(4, bool), lambda *a: None)
        pts = bb.points()
        moved = [s for s in range(4) if bb.moved[s]]
        assert len(moved) == beyond and all(bb.moved[s] is None or bb.moved[s] for s in range(4)), (offset, bb.moved)
        for s, q in enumerate(per):
            assert q is not None
            x, point, normal = q
            assert np.all(np.abs(point[:2]) <= HALF + 1e-12) and x == pytest.approx(1e-5, abs=1e-12), (offset, q)
            np.testing.assert_allclose(point, pts[s] + 0.5 * x * normal, atol=1e-15)
            if s in moved:
                assert abs(point[0]) == pytest.approx(HALF, abs=1e-12), (offset, q)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_box_over_the_edge_rests_on_its_corners_and_the_edge(engine):
    """scripts/box_stack.py overhang: the upper box set flat 0.2 mm above the
    lower one, its centre OFFSET = 20 mm off along x (its +x corners 20 mm
    past the face, its centre of mass over it). It lands and rests on four
    slots: its two -x corners and, moved onto the lower box's +x edge
    (x = HALF), the two past it; the edge, 5 mm from the centre of mass
    against the corners' 25 mm, carries more (the manager's approaches: the
    edge law is linear in x at rest); the energy account never rises, no
    island gains energy. Main: the +x slots at the corners 20 mm past the
    edge, in the air."""
    from _scripts import load_script

    out = load_script("box_stack").run(engine, "overhang", OVERHANG_STEPS)
    assert out["gain_J"] <= 0.0 and out["island_gains"] == 0, out
    row = out["interfaces"][0]
    assert row["active"] == [True] * 4 and row["which"] == 1 and row["face"] == [2, 1.0], row
    pts = np.array(row["points_m"])
    moved = np.array(row["moved"])
    # world points: the lower box slides a few micrometres on the floor (SLIDE_ATOL)
    assert moved.sum() == 2 and np.all(np.abs(pts[:, :2]) <= HALF + SLIDE_ATOL), row
    np.testing.assert_allclose(pts[moved, 0], HALF, atol=SLIDE_ATOL)
    x = np.array(row["x_internal_m"])
    assert x[moved].min() > x[~moved].max() > 0.0, row
    # the upper box on the lower one's face: its centre HALF above the face, less the corners' micrometres
    assert math.isclose(out["z_end_m"][1] - out["z_end_m"][0], 2 * HALF, abs_tol=1e-4), out["z_end_m"]
