"""A box dropped on a plane as a user does it (issue 13), in MuJoCo and
pybullet: a plain PairSpec (no edge radius given: the default
msf_contact.shapes.DEFAULT_EDGE_RADIUS, 1 mm), its corners and rounded
edges carrying the MSF law (engines._narrow.BoxOnPlane), scripts/box_drop.py.

Before: MuJoCo raised "line contact ... no law for it yet" when the box
reached the plane (t = 0.235 s: the corner's curvature was read at the point
midway across the detection margin's gap, an edge's), pybullet "two planes
touch" (plane.urdf is a box: box-on-box went to getClosestPoints' one point
on the face); with the midpoint fixed alone, the corner's sphere law let go
at x = 2 rho and the box fell through the plane (z = -2.3 m after 1.5 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from _scripts import load_script
from engines._contacts.state import ENERGY_GAIN_RTOL
from msf_contact import ContactPair, Curvature, make_law, preset, static_overlap
from msf_contact.geometry import SideFootprint
from msf_contact.shapes import DEFAULT_EDGE_RADIUS

ENGINES = [pytest.param("mujoco", marks=pytest.mark.mujoco), pytest.param("pybullet", marks=pytest.mark.pybullet)]

#: Steps after the start 1 mm above the plane at the user's landing speed
#: (2.4 m/s from 0.3 m): the corner's impact (~10 ms) and the tumble after it.
LANDING_STEPS = 120
#: The deepest a corner may go at that landing [m]: the corner's sphere (rho
#: = 1 mm) alone lets go at x = 2 rho (k_p of (15)); its edge (the line law's
#: growing length below the plane) stops the box before. Measured: 1.7 mm
#: (MuJoCo), 2.2 mm (pybullet) at the end of a step; the record's x_max 2.8
#: and 3.2 mm. Beyond 5 mm the box is going through the plane.
DEEPEST_CORNER_MAX = 5e-3
#: Steps of the rest test: the box set 0.2 mm above the plane tilted (1,
#: 0.5, 0) deg, from rest; it rocks on its face and rests from step ~250.
REST_STEPS = 400
#: A box whose corners approach the plane slower than this is at rest [m/s]
#: (box_drop's speed_normal_end: the centre's speed along the normal +
#: half-extent x the angular speed about axes in the plane; under 1 um a
#: step, as tests/test_static_overlaps.py's REST_SPEED). The box's sideways
#: oscillation on the corners' tangential springs (the law has no Coulomb
#: cap: mu unset) is left out: measured 2.1 mm/s along y in MuJoCo at step
#: 400 (an amplitude of ~1.5 um at the springs' ~1,400 rad/s).
REST_SPEED = 1e-3
#: The corners' approaches at rest against the rigid box's statics
#: (box_drop.static_face, each corner's own law and onset constants) [-]:
#: the box still rocks on its rubber edges at ~1e-3 m/s after 400 steps,
#: tilting the face by ~0.1 um over its 48 mm (measured: within 0.8 %
#: (MuJoCo, 500 steps), 0.5 % (pybullet, 300 steps) of x_s = 6.08 um);
#: 2 % is 0.12 um, and excludes the corners' spheres carrying the face as
#: before (x_s of a 1 mm sphere under m g / 4: 89 um).
STATIC_RTOL = 2e-2
#: The manager's approach against the engine's (the box's pose) at rest [-]:
#: the island step's lead over the engine (measured <= 0.1 %).
INTERNAL_RTOL = 5e-3


@pytest.fixture(scope="module")
def box_drop():
    return load_script("box_drop")


@pytest.mark.parametrize("engine", ENGINES)
def test_the_users_box_lands_on_its_corner_without_exception_or_gain(box_drop, engine):
    """The user's drop (0.3 m, Euler (17, 11, 5) deg, natural rubber on steel,
    plain PairSpec) from 1 mm above the plane at its landing speed: no
    exception, the energy account (kinetic + gravitational + the contacts'
    stored energy) never rises by more than the contacts' own bound
    ENERGY_GAIN_RTOL E0 over any interval (measured: 0 J), the corner is
    stopped within DEEPEST_CORNER_MAX, and its record is flagged (a 2.4 m/s
    corner is beyond the small-strain model: x_max / rho > 0.1)."""
    out = box_drop.run(engine, LANDING_STEPS, gap=1e-3)
    assert out["gain_J"] <= ENERGY_GAIN_RTOL * out["E0_J"], out
    assert out["island_gains"] == 0, out
    assert 0.0 < out["deepest_corner_m"] < DEEPEST_CORNER_MAX, out
    assert out["records"] >= 1 and out["flagged"] >= 1, out
    assert out["E_end_J"] < out["E0_J"], out


@pytest.mark.parametrize("engine", ENGINES)
def test_a_box_rests_on_a_face_at_the_static_overlap(box_drop, engine):
    """The same box set just above the plane nearly flat comes to rest on a
    face, on its four corners, each carrying its edge's end law
    (engines._narrow.SideEndLaw): at the rigid box's static overlaps
    (STATIC_RTOL), the manager's approaches at the engine's (INTERNAL_RTOL),
    and that static overlap is msf_contact's line law of the rounded edge
    (SideFootprint of the edge radius and the edge's straight length 2 (h -
    rho)) carrying half the weight, with each corner's own onset constants:
    the face rests on two edges. The energy account never rises."""
    out = box_drop.run(engine, REST_STEPS, gap=2e-4, euler_deg=(1.0, 0.5, 0.0), height=None)
    assert out["gain_J"] <= ENERGY_GAIN_RTOL * out["E0_J"], out
    assert out["active_end"] == [True] * 4 and out["speed_normal_end"] < REST_SPEED, out
    x_eng, x_s = np.array(out["x_engine_m"]), np.array(out["x_static_m"])
    np.testing.assert_allclose(x_eng, x_s, rtol=STATIC_RTOL, atol=0.0)
    np.testing.assert_allclose(out["x_internal_m"], x_eng, rtol=INTERNAL_RTOL, atol=0.0)
    rho, h = DEFAULT_EDGE_RADIUS, box_drop.HALF
    line = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")),
                    Curvature.side_on_plane(SideFootprint(rho, 2 * (h - rho))))
    for x, onset in zip(x_s, out["onsets"]):
        want = float(static_overlap(line, [box_drop.MASS * box_drop.G / 2], onset)[0])
        assert math.isclose(x, want, rel_tol=STATIC_RTOL), (x, want)


def test_the_rounded_box_corners_in_closed_form():
    """engines._narrow.box_corners and BoxOnPlane.update against the rounded
    box's geometry: lying on a face, its four lowest corners are at the
    sharp box's face (x = 0.5 mm for a face 0.5 mm into the plane, whatever
    the edge radius) and their edge is one of the face's (the most level);
    standing on a corner (body diagonal vertical), the corner sphere's lowest
    point is rho (sqrt(3) - 1) above the sharp corner."""
    from engines._narrow import BoxOnPlane, LawBank, box_corners
    from msf_contact.shapes import Box

    h, rho = np.array([0.03, 0.02, 0.01]), 2e-3
    box = Box(tuple(h), rho)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    c = box_corners(box, [0.0, 0.0, h[2] - 5e-4], np.eye(3), np.zeros(3), [0.0, 0.0, 1.0])
    assert np.sort(c.x)[-4:] == pytest.approx([5e-4] * 4, abs=1e-15)
    bop = BoxOnPlane(box, ("box", "floor"))
    bop.check(law)
    bop.update([0.0, 0.0, h[2] - 5e-4], np.eye(3), np.zeros(3), [0.0, 0.0, 1.0], np.zeros(4, bool), law, LawBank())
    assert sorted(bop.corner.tolist()) == sorted(np.flatnonzero(c.x > 0).tolist())
    assert set(bop.axis.tolist()) <= {0, 1}  # an edge of the bottom face, never the vertical one
    # the body diagonal (1, 1, 1) turned to -z (a 180 deg turn about the bisector of it and -z)
    a = np.array([1.0, 1.0, 1.0]) / math.sqrt(3) - np.array([0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    rot = 2 * np.outer(a, a) - np.eye(3)
    cube = Box((0.01, 0.01, 0.01), rho)
    sharp = 0.01 * math.sqrt(3)  # the sharp corner touches with the centre this high
    c = box_corners(cube, [0.0, 0.0, sharp], rot, np.zeros(3), [0.0, 0.0, 1.0])
    assert np.max(c.x) == pytest.approx(-rho * (math.sqrt(3) - 1), rel=1e-12)


def test_two_flat_faces_are_carried_flagged_by_the_bounding_sphere():
    """engines._narrow.contact_law for two flat faces (a box's face on a
    plane read as a point: no point law): not a ValueError but the point law
    of the box's bounding sphere (radius |h|) on the plane, with the
    records' note, warned once per pair."""
    from engines._narrow import LawBank, Plane, contact_law, effective_radii
    from msf_contact._validate import ValidityWarning
    from msf_contact.shapes import Box

    h = (0.03, 0.02, 0.01)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    bank = LawBank()
    pose = (np.array([0.0, 0.0, 0.01]), np.eye(3))
    args = (Box(h, 1e-3), pose, Plane(), (np.zeros(3), np.eye(3)), np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.0)
    with pytest.warns(ValidityWarning, match=r"pair \('box', 'floor'\).*two planes touch.*carried as the point law"):
        got = contact_law(("box", "floor"), law, bank, *args)
    assert effective_radii(got.curvature) == pytest.approx((math.hypot(*h),) * 2, rel=1e-12)
    assert "carried as the point law" in got.validity_note and not hasattr(law, "validity_note")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per pair
        assert contact_law(("box", "floor"), law, bank, *args) is got
