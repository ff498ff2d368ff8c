"""A pybullet link of several collision shapes (a compound: a URDF link with
several <collision> elements, pybullet_data's tray/traybox.urdf, a table)
carries MSF shape by shape: the pairs name each shape as (uid, link, k), the
shapes read from pybullet's getCollisionShapeData; a pair set that leaves a
shape out, or a pair whose points pybullet's getClosestPoints would give for
the whole link, is refused before any step."""

import numpy as np
import pytest

from msf_contact import ContactPair, Curvature, make_law, preset

pb = pytest.importorskip("pybullet")
pytestmark = pytest.mark.pybullet

from engines.base import PairSpec  # noqa: E402
from engines.pybullet import scenes  # noqa: E402
from engines.pybullet.adapter import PybulletAdapter  # noqa: E402

RUBBER, STEEL = preset("natural-rubber"), preset("steel")
R = 0.01  #: the ball's radius [m]
V = 1.0  #: its landing speed [m/s]
#: The ball on one shape of a compound against the same ball on a body of
#: that shape alone, at the same world pose: the same geometry and law, the
#: same arithmetic up to the rounding of a different frame composition (the
#: compound's child frame in its inertial frame): measured 6.6e-11 on COR.
SAME_RTOL = 1e-9
#: A step (the compound's child 1) and a slab beside it (child 0), half-extents [m];
#: the compound's inertial frame is put off its link frame, so a child frame read
#: in the wrong one puts the step's face elsewhere.
STEP_HALF, SLAB_HALF = (0.05, 0.05, 0.02), (0.2, 0.2, 0.01)
STEP_POS, SLAB_POS = (0.0, 0.0, -0.02), (0.5, 0.0, -0.06)
INERTIAL_OFFSET = (0.03, -0.02, 0.01)


def _law():
    return make_law("msf", ContactPair(RUBBER, STEEL), Curvature.sphere_on_plane(R))


def _ball(c):
    sh = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c)
    u = pb.createMultiBody(RUBBER.density * 4 / 3 * np.pi * R**3, sh, basePosition=[0, 0, R + 1e-4],
                           physicsClientId=c)
    scenes._free_dynamics(c, u)
    pb.resetBaseVelocity(u, [0, 0, -V], [0, 0, 0], physicsClientId=c)
    return u


def _compound(c):
    """The fixed compound (slab, step), its inertial frame off its link frame."""
    sh = pb.createCollisionShapeArray([pb.GEOM_BOX, pb.GEOM_BOX], halfExtents=[SLAB_HALF, STEP_HALF],
                                      collisionFramePositions=[SLAB_POS, STEP_POS], physicsClientId=c)
    return pb.createMultiBody(0.0, sh, basePosition=[0, 0, 0], baseInertialFramePosition=list(INERTIAL_OFFSET),
                              physicsClientId=c)


def _single(c):
    """The step alone, at the same world pose."""
    sh = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(STEP_HALF), physicsClientId=c)
    return pb.createMultiBody(0.0, sh, basePosition=list(STEP_POS), physicsClientId=c)


def _bounce(compound: bool):
    c = scenes.new_client(1e-4)
    try:
        base = _compound(c) if compound else _single(c)
        ball = _ball(c)
        pairs = ([PairSpec((ball, -1), (base, -1, k), _law()) for k in (0, 1)] if compound
                 else [PairSpec((ball, -1), (base, -1), _law())])
        adapter = PybulletAdapter(c, pairs)
        for _ in range(2000):
            adapter.step(1)
            if adapter.records and pb.getBaseVelocity(ball, physicsClientId=c)[0][2] > 0:
                break
        v_out = pb.getBaseVelocity(ball, physicsClientId=c)[0][2]
        return v_out / V, [(r.inputs["pair"], r.outside_validity, r.cor_n) for r in adapter.records]
    finally:
        pb.disconnect(c)


def test_a_ball_on_one_shape_of_a_compound_bounces_as_on_that_shape_alone():
    cor_c, rec_c = _bounce(True)
    cor_s, rec_s = _bounce(False)
    assert 0.3 < cor_s < 1.0  # a rubber bounce happened at all
    assert cor_c == pytest.approx(cor_s, rel=SAME_RTOL)
    # the step's pair (k = 1) carried it; the slab's (k = 0) stayed apart; nothing flagged
    assert [p for p, _, _ in rec_c] == [1] and rec_c[0][1] == rec_s[0][1] == []
    assert rec_c[0][2] == pytest.approx(rec_s[0][2], rel=SAME_RTOL)


def test_a_compound_left_partly_uncovered_is_refused():
    c = scenes.new_client(1e-4)
    try:
        base, ball = _compound(c), _ball(c)
        with pytest.raises(ValueError, match=r"cover 1 of their 2 shape pairs \(missing \(k1, k2\) = \[\(0, 0\)\]"):
            PybulletAdapter(c, [PairSpec((ball, -1), (base, -1, 1), _law())])
        with pytest.raises(ValueError, match=r"has 2 collision shapes \(0: box, 1: box\); give one pair per shape, "
                                             r"body \(uid, link, k\) for k in 0..1"):
            PybulletAdapter(c, [PairSpec((ball, -1), (base, -1), _law())])
        with pytest.raises(ValueError, match=r"shape index 2 is outside \[0, 1\]"):
            PybulletAdapter(c, [PairSpec((ball, -1), (base, -1, k), _law()) for k in (0, 1, 2)])
    finally:
        pb.disconnect(c)


def test_a_pair_whose_points_pybullet_would_give_for_the_whole_compound_is_refused():
    """A capsule against a small box of a compound (too small to be its floor,
    so the pair's points would come from getClosestPoints, which answers for
    every shape of the link at once)."""
    c = scenes.new_client(1e-4)
    try:
        sh = pb.createCollisionShapeArray([pb.GEOM_BOX, pb.GEOM_BOX], halfExtents=[SLAB_HALF, (0.005, 0.005, 0.005)],
                                          collisionFramePositions=[SLAB_POS, (0.0, 0.0, -0.005)], physicsClientId=c)
        base = pb.createMultiBody(0.0, sh, basePosition=[0, 0, 0], physicsClientId=c)
        cap = pb.createMultiBody(0.1, pb.createCollisionShape(pb.GEOM_CAPSULE, radius=R, height=0.1, physicsClientId=c),
                                 basePosition=[0, 0, 0.1], physicsClientId=c)
        with pytest.raises(ValueError, match=r"on a link of several collision shapes: its points come from "
                                             r"pybullet's getClosestPoints"):
            PybulletAdapter(c, [PairSpec((cap, -1), (base, -1, k), _law()) for k in (0, 1)])
    finally:
        pb.disconnect(c)
