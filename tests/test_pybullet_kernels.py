"""The pybullet adapter's compiled array work (engines/pybullet/_kernels.py)
against its numpy path (``compiled=False``), and the per-body force
application both share.

Each scene is built twice, identically, and run once with each path: the
kinematics handed to the manager, the impulses applied, the bodies' states
and the impact records must agree. The two paths compute the same
quantities in a different order of floating-point operations (numpy's
einsum and matrix products against written-out loops), so they agree to
round-off at the first step and the difference then grows only as much as
the dynamics amplifies it.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

from engines.base import PairSpec
from engines.pybullet import PybulletAdapter, scenes
from msf_contact import Body, ContactPair, Curvature, make_law, preset

pytestmark = pytest.mark.pybullet

#: First step, same engine state: the kinematics of the two paths differ at
#: most by float64 round-off of a few operations (measured: bit-identical).
FIRST_STEP_RTOL = 1e-13
#: Over a whole scene: round-off at each step, carried by the contact
#: dynamics and amplified in a_ext (a difference of velocities over dt):
#: measured <= 4e-14 relative to each quantity's largest value (a_ext of the
#: sphere-sphere scene), states and records <= 3e-16; kept at 1e-10 so that
#: another compiler's rounding does not fail it while a wrong term does.
SCENE_RTOL = 1e-10
#: Forces at points on one body vs their sum at its centre of mass plus
#: their torque about it: what pybullet integrates is the same force and
#: torque, summed in another order (measured equal to the last bit).
LOAD_RTOL = 1e-13

RUBBER, STEEL, PU = preset("natural-rubber"), preset("steel"), preset("polyurethane")
G = 9.81


def law_for(material, R1, R2=math.inf, other=STEEL):
    return make_law("msf", ContactPair(material, other), Curvature(R1, R1, R2, R2))


def fixed_sphere(c, radius, pos):
    shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=radius, physicsClientId=c)
    return pb.createMultiBody(0.0, shape, basePosition=list(pos), physicsClientId=c)


# ------------------------------------------------------------ the scenes --
# each: build(compiled) -> (adapter, uids of the free bodies, steps)
def resting_spheres(compiled):
    """Five rubber spheres dropped from small gaps onto a plane: bounces, then rest (settled path)."""
    R = 0.02
    ball = Body.sphere(RUBBER, R)
    c = scenes.new_client(1e-3, G)
    plate = scenes.add_plate(c, "plane")
    gaps = [0.0, 1e-4, 2.5e-4, 4e-4, 5e-4]
    uids = [scenes.add_sphere(c, ball, (3 * R * k, 0.0, R + g)) for k, g in enumerate(gaps)]
    law = law_for(RUBBER, R)
    return PybulletAdapter(c, [PairSpec((u, -1), (plate, -1), law) for u in uids], compiled=compiled), uids, 400


def bouncing_ball(compiled):
    """A polyurethane ball dropped 5 mm onto a plane, dt = 0.1 ms: several resolved bounces."""
    R = 0.02
    ball = Body.sphere(PU, R)
    scene = scenes.ball_on_plate(ball, 1e-9, dt=1e-4, gap=5e-3, gravity=G)
    ad = PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law_for(PU, R))], compiled=compiled)
    return ad, [scene.body1[0]], 1500


def oblique_spin(compiled):
    """Oblique impact (35 degrees) with backspin on a plane, no gravity, dt = 20 us."""
    R = 0.02
    ball = Body.sphere(PU, R)
    scene = scenes.ball_on_plate(ball, 1.5, angle_deg=35.0, spin=-40.0, dt=2e-5, gap=1e-5)
    ad = PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law_for(PU, R))], compiled=compiled)
    return ad, [scene.body1[0]], 400


def sphere_sphere(compiled):
    """Two free steel spheres colliding obliquely in flight with spin, and a
    third falling off-centre onto a fixed sphere (a sphere-sphere pair with a fixed body 2)."""
    Ra, Rb, Rc, Rf = 0.02, 0.015, 0.01, 0.03
    a, b, cb = Body.sphere(STEEL, Ra), Body.sphere(STEEL, Rb), Body.sphere(PU, Rc)
    c = scenes.new_client(1e-5, G)
    ua = scenes.add_sphere(c, a, (0.0, 0.0, 1.0), (0.0, 0.0, -0.2), (0.0, 30.0, 0.0))
    ub = scenes.add_sphere(c, b, (0.004, 0.0, 1.0 - Ra - Rb - 2e-6), (0.0, 0.0, 0.3))
    uf = fixed_sphere(c, Rf, (0.5, 0.0, 0.0))
    uc = scenes.add_sphere(c, cb, (0.5 + 0.006, 0.001, Rf + Rc + 1e-6), (0.0, 0.0, -0.5), (5.0, 0.0, 0.0))
    pairs = [PairSpec((ua, -1), (ub, -1), make_law("msf", ContactPair(STEEL, STEEL), Curvature(Ra, Ra, Rb, Rb))),
             PairSpec((uc, -1), (uf, -1), make_law("msf", ContactPair(PU, STEEL), Curvature(Rc, Rc, Rf, Rf)))]
    return PybulletAdapter(c, pairs, compiled=compiled), [ua, ub, uc], 300


def several_contacts(compiled):
    """Ball A rests on a plane; balls B and C strike it from both sides and D
    from above, all in the same few steps: A is in four pairs, so its forces
    are summed (at its centre of mass, with their torque)."""
    R, r = 0.02, 0.01
    A, small = Body.sphere(RUBBER, R), Body.sphere(STEEL, r)
    c = scenes.new_client(1e-4, G)
    plate = scenes.add_plate(c, "plane")
    ua = scenes.add_sphere(c, A, (0.0, 0.0, R - 1e-5))
    ub = scenes.add_sphere(c, small, (-(R + r + 1e-5), 0.0, R + 0.004), (0.3, 0.0, 0.0))
    uc = scenes.add_sphere(c, small, ((R + r + 2e-5), 0.0, R - 0.003), (-0.4, 0.0, 0.0), (0.0, 0.0, 20.0))
    ud = scenes.add_sphere(c, small, (0.003, 0.0, 2 * R + r + 3e-5), (0.0, 0.0, -0.5))
    ls = make_law("msf", ContactPair(STEEL, RUBBER), Curvature(r, r, R, R))
    pairs = [PairSpec((ua, -1), (plate, -1), law_for(RUBBER, R))] + [PairSpec((u, -1), (ua, -1), ls)
                                                                     for u in (ub, uc, ud)]
    return PybulletAdapter(c, pairs, compiled=compiled), [ua, ub, uc, ud], 300


def mixed_with_box(compiled):
    """Spheres on a plane and one on a box plate: the box pair goes pair by
    pair (the numpy code of both paths), the others through the kernels; the
    rows are merged in pair order."""
    R = 0.02
    ball = Body.sphere(RUBBER, R)
    c = scenes.new_client(1e-3, G)
    box = scenes.add_plate(c, "box")
    plane = scenes.add_plate(c, "plane")
    pb.setCollisionFilterPair(box, plane, -1, -1, enableCollision=0, physicsClientId=c)
    uids = [scenes.add_sphere(c, ball, (3 * R * k, 0.1, R + 1e-4 * k)) for k in range(3)]
    law = law_for(RUBBER, R)
    pairs = [PairSpec((uids[0], -1), (plane, -1), law), PairSpec((uids[1], -1), (box, -1), law),
             PairSpec((uids[2], -1), (plane, -1), law)]
    return PybulletAdapter(c, pairs, compiled=compiled), uids, 300


SCENES = [resting_spheres, bouncing_ball, oblique_spin, sphere_sphere, several_contacts, mixed_with_box]


# ------------------------------------------------------------ running --
def run(build, compiled):
    ad, uids, steps = build(compiled)
    calls = []
    step = ad.manager.step

    def spy(kin):
        calls.append({k: np.array(getattr(kin, k), float) for k in
                      ("pair", "x", "normal", "point", "v_rel", "v_com_rel", "W", "W_com", "a_ext")})
        return step(kin)

    ad.manager.step = spy
    c = ad.client
    states = []
    with ad:
        for _ in range(steps):
            ad.step(1)
            states.append([list(pb.getBasePositionAndOrientation(u, physicsClientId=c)[0])
                           + list(pb.getBasePositionAndOrientation(u, physicsClientId=c)[1])
                           + [x for vec in pb.getBaseVelocity(u, physicsClientId=c) for x in vec] for u in uids])
        ad.manager.step = step
        records = ad.pop_records()
        return dict(calls=calls, states=np.array(states), impulse=ad.impulse.copy(), records=records)


def scaled_err(got, want, rtol):
    """max |got - want| / (rtol * scale), scale = the largest |want| (at least tiny)."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    scale = max(float(np.max(np.abs(want), initial=0.0)), 1e-300)
    return float(np.max(np.abs(got - want), initial=0.0)) / (rtol * scale)


@pytest.mark.parametrize("build", SCENES, ids=[s.__name__ for s in SCENES])
def test_compiled_path_equals_numpy_path(build):
    ref, got = run(build, False), run(build, True)
    # the same candidates every step, the same kinematics
    assert len(ref["calls"]) == len(got["calls"])
    assert any(c["pair"].size for c in ref["calls"]), "the scene never has a candidate"
    for s, (a, b) in enumerate(zip(ref["calls"], got["calls"])):
        assert np.array_equal(a["pair"], b["pair"]), (s, a["pair"], b["pair"])
        tol = FIRST_STEP_RTOL if s == 0 else SCENE_RTOL
        for key in a:
            assert scaled_err(b[key], a[key], tol) <= 1.0, (s, key, b[key], a[key])
    # the same engine states, impulses and records
    for q in range(ref["states"].shape[1]):
        st_r, st_g = ref["states"][:, q], got["states"][:, q]
        for cols in (slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13)):
            assert scaled_err(st_g[:, cols], st_r[:, cols], SCENE_RTOL) <= 1.0, (q, cols)
    assert scaled_err(got["impulse"], ref["impulse"], SCENE_RTOL) <= 1.0
    assert len(got["records"]) == len(ref["records"])
    for rg, rr in zip(got["records"], ref["records"]):
        assert rg.inputs.get("pair") == rr.inputs.get("pair")
        for name in ("cor_n", "cor_t", "tau", "x_max", "F_max", "spin_in", "spin_out"):
            want, have = getattr(rr, name), getattr(rg, name)
            if want is None:
                assert have is None, name
            else:
                assert scaled_err(have, want, SCENE_RTOL) <= 1.0, (name, have, want)


def test_scenes_reach_every_branch():
    """The scenes above exercise what they claim: resting contacts on the
    settled path, a body with several forces in one step, merged pair-by-pair rows."""
    ad, uids, steps = several_contacts(True)
    with ad:
        counts = []
        orig = ad._k.body_loads

        def spy(*args):
            out = orig(*args)
            counts.append(out[3].size)  # bodies with several forces
            return out

        ad._k.body_loads = spy
        try:
            ad.step(steps)
        finally:
            ad._k.body_loads = orig
        assert max(counts) >= 1, counts
    ad, uids, steps = resting_spheres(True)
    with ad:
        ad.step(steps)
        assert ad.manager.last_step_info["settled"] == len(uids)
    ad, uids, steps = mixed_with_box(True)
    with ad:
        assert ad._slow == [1] and list(ad._fast) == [0, 2]


def test_forces_summed_per_body_are_what_pybullet_applies():
    """The adapter applies several forces on one free body as their sum at
    the centre of mass plus their torque about it: pybullet integrates the
    same motion as with each force at its point (rotated body, spin)."""
    ball = Body.sphere(PU, 0.02)
    forces = np.array([[1.0, 2.0, 30.0], [-5.0, 0.5, 0.3], [0.7, -2.0, 1.1]])
    offsets = np.array([[0.0, 0.0, -0.02], [0.02, 0.0, 0.0], [0.0, 0.01, 0.01]])
    out = []
    for summed in (False, True):
        c = scenes.new_client(1e-3, G)
        u = scenes.add_sphere(c, ball, (0.1, 0.2, 0.3), (0.3, -0.2, 0.1), (1.0, 2.0, -3.0))
        pb.resetBasePositionAndOrientation(u, (0.1, 0.2, 0.3), pb.getQuaternionFromEuler((0.3, -0.7, 1.1)),
                                           physicsClientId=c)
        for _ in range(5):
            com = np.array(pb.getBasePositionAndOrientation(u, physicsClientId=c)[0])
            pts = com + offsets
            if summed:
                torque = np.cross(pts - com, forces).sum(axis=0)
                pb.applyExternalForce(u, -1, forces.sum(axis=0).tolist(), com.tolist(), pb.WORLD_FRAME,
                                      physicsClientId=c)
                pb.applyExternalTorque(u, -1, torque.tolist(), pb.WORLD_FRAME, physicsClientId=c)
            else:
                for f, p in zip(forces, pts):
                    pb.applyExternalForce(u, -1, f.tolist(), p.tolist(), pb.WORLD_FRAME, physicsClientId=c)
            pb.stepSimulation(physicsClientId=c)
        pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
        v, w = pb.getBaseVelocity(u, physicsClientId=c)
        out.append(np.array([*pos, *orn, *v, *w]))
        pb.disconnect(c)
    assert scaled_err(out[1], out[0], LOAD_RTOL) <= 1.0, out


def test_compiled_must_be_a_bool():
    ball = Body.sphere(PU, 0.02)
    scene = scenes.ball_on_plate(ball, 1.0, dt=1e-4)
    try:
        with pytest.raises(ValueError, match="compiled"):
            PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law_for(PU, 0.02))], compiled="yes")
    finally:
        scene.close()
