"""The MuJoCo adapter's compiled free-group path (engines.mujoco._kernels)
against its numpy path (MujocoAdapter(..., compiled=False)), on the same
scenes, two ways:

- step by step from the same inputs (:class:`Shadow`): inside every engine
  step the numpy path runs first (calling the manager), then the compiled
  path from the same MjData, a_ext state and manager answer; the
  kinematics handed to the manager, the a_ext state left for the next step
  and the generalised forces the hook applies must agree to KERNEL_RTOL;
- over whole runs (:class:`Twin`): the scene built twice, one adapter of
  each kind, stepped in lock-step; kinematics, forces, a_ext state, engine
  state after every step and the records at the end must agree to
  TRAJECTORY_RTOL.
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from engines.base import PairSpec
from engines.mujoco import MujocoAdapter, scenes
from msf_contact import Body, ContactPair, Curvature, make_law, preset

pytestmark = pytest.mark.mujoco

#: The same arithmetic per pair, grouped and ordered differently in places
#: (numpy's einsum, matmul and matrix-vector products against scalar sums
#: of three products, which round differently): a few ulp of the largest
#: entry of each compared array (measured <= 5e-16), which is the scale.
KERNEL_RTOL = 1e-12
#: Whole runs: those ulp-level differences grow through the dynamics and the
#: manager's event location (a separation found by root finding moves with
#: its inputs); measured 2.4e-11 of the step's largest force in the steel
#: balls striking a resting stack, 0 or < 1e-15 in the other scenes.
TRAJECTORY_RTOL = 1e-9

RUBBER, STEEL = preset("natural-rubber"), preset("steel")
G = 9.81
KIN_FIELDS = ("pair", "x", "normal", "point", "v_rel", "v_com_rel", "W", "W_com", "a_ext")


def _law(m1, R1, m2, R2):
    return make_law("msf", ContactPair(m1, m2), Curvature(R1, R1, R2, R2))


def _close(name, got, want, rtol):
    """max |got - want| <= rtol max |want| (exact zeros alike), nan at the same places."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert got.shape == want.shape, f"{name}: shapes {got.shape} != {want.shape}"
    if not want.size:
        return
    assert np.array_equal(np.isnan(got), np.isnan(want)), f"{name}: nan at different places"
    g, w = np.nan_to_num(got, nan=0.0), np.nan_to_num(want, nan=0.0)
    scale = float(np.max(np.abs(w)))
    err = float(np.max(np.abs(g - w)))
    assert err <= rtol * scale or err == 0.0, f"{name}: max error {err:.3g} > {rtol:g} x {scale:.3g}"


def _kin(kin) -> dict:
    lever = getattr(kin, "lever", None)  # the moving contact point's terms (None: every point frozen)
    return {k: np.array(getattr(kin, k)) for k in KIN_FIELDS} | {"t": kin.t,
                                                                 "lever": None if lever is None else np.array(lever)}


def _same_kin(where, got, want, rtol):
    assert got["t"] == want["t"]
    assert np.array_equal(got["pair"], want["pair"]), f"{where}: candidates {got['pair']} != {want['pair']}"
    for k in KIN_FIELDS[1:]:
        _close(f"{where} kin.{k}", got[k], want[k], rtol)
    assert (got["lever"] is None) == (want["lever"] is None), f"{where}: moving contact points in one path only"
    if want["lever"] is not None:
        _close(f"{where} kin.lever", got["lever"], want["lever"], rtol)


class _Replay:
    """The manager as the compiled path sees it in :class:`Shadow`: its
    state after the step, the required pairs of before, and the answer the
    numpy path's call got."""

    def __init__(self, real, required, out, settled, before):
        self._real, self.required_pairs, self._out = real, required, out
        self.settled = settled  # which contacts took the settled path in the step before (the adapter's _lever)
        # what the adapter's _held_geometry reads, as it was before the step
        self.active, self.J, self.x, self.n_in, self.tau_est = before
        self.kin = None

    def step(self, kin):
        self.kin = _kin(kin)
        return self._out

    def __getattr__(self, name):
        return getattr(self._real, name)


class Shadow:
    """One adapter whose every step computes the numpy path and then the
    compiled path from the same inputs, and compares them (module docstring).
    The engine goes on with the compiled path's forces and state."""

    def __init__(self, build, pairs):
        model, data = build()
        self.ad = ad = MujocoAdapter(model, data, pairs, compiled=True)
        self.steps = 0
        self.candidates = 0  # most candidates in a step
        self.forces = 0  # steps with a force on the free group
        self.levers = 0  # steps with a moving contact point (compared: kin.lever)
        ad._compute = self._compute

    def _compute(self):
        ad, mgr = self.ad, self.ad.manager
        where = f"step {self.steps + 1}"
        required = np.array(mgr.required_pairs)
        state = tuple(a.copy() for a in (ad._last_v, ad._last_dv, ad._have_last, ad._push, ad._x_last, ad._last_r,
                                         ad._last_gap))
        settled = mgr.settled.copy()
        before = tuple(a.copy() for a in (mgr.active, mgr.J, mgr.x, mgr.n_in, mgr.tau_est))
        seen = {}
        real_step = mgr.step

        def numpy_step(kin):
            seen["kin"] = _kin(kin)
            seen["out"] = out = real_step(kin)
            return out

        mgr.step = numpy_step
        try:
            ad.compiled = False
            type(ad)._compute(ad)
        finally:
            ad.compiled = True
            del mgr.step
        want_state = tuple(a.copy() for a in (ad._last_v, ad._last_dv, ad._have_last, ad._push, ad._last_r,
                                              ad._last_gap))
        want_fast, want_slow = ad._apply_fast, list(ad._apply)
        q_want = np.zeros(ad.model.nv)
        if want_fast is not None:
            ad._fast.apply(ad.data, *want_fast, out=q_want)
        for a, b in zip((ad._last_v, ad._last_dv, ad._have_last), state):
            a[:] = b
        ad._push = state[3]  # the candidates' extra reach before the step (engines._contacts.islands.push_reach)
        ad._x_last[:] = state[4]  # the overlaps of the step before (the moving contact point's a_ext share)
        ad._last_r[:], ad._last_gap[:] = state[5], state[6]  # sphere-sphere lever arms of the step before
        replay = _Replay(mgr, required, seen["out"], settled, before)
        ad.manager = replay
        try:
            ad._compute_compiled()
        finally:
            ad.manager = mgr
        _same_kin(where, replay.kin, seen["kin"], KERNEL_RTOL)
        for name, got, want in zip(("last_v", "last_dv"), (ad._last_v, ad._last_dv), want_state):
            _close(f"{where} {name}", got, want, KERNEL_RTOL)
        assert np.array_equal(ad._have_last, want_state[2])
        assert np.array_equal(ad._last_gap, want_state[5])
        _close(f"{where} last_r", ad._last_r, want_state[4], KERNEL_RTOL)
        assert (ad._apply_fast is None) == (want_fast is None), f"{where}: forces applied in one path only"
        q_got = np.zeros(ad.model.nv)
        if ad._apply_fast is not None:
            ad._kernels.apply(q_got, ad.data.xipos, ad.data.xanchor, ad.data.xmat, *ad._apply_fast)
        _close(f"{where} generalised force", q_got, q_want, KERNEL_RTOL)
        assert len(ad._apply) == len(want_slow)
        for got, want in zip(ad._apply, want_slow):
            assert got[:3] == want[:3]
            for u, v in zip(got[3:], want[3:]):
                _close(f"{where} slow force", u, v, KERNEL_RTOL)
        self.candidates = max(self.candidates, seen["kin"]["pair"].size)
        self.forces += bool(np.any(q_want != 0.0))
        self.levers += seen["kin"]["lever"] is not None

    def run(self, steps: int) -> None:
        for _ in range(steps):
            self.ad.step(1)
            self.steps += 1


class Twin:
    """One scene as two adapters (numpy, compiled) stepped in lock-step."""

    def __init__(self, build, pairs):
        self.sides = []
        for compiled in (False, True):
            model, data = build()
            ad = MujocoAdapter(model, data, pairs, compiled=compiled)
            log = {}
            step = ad.manager.step

            def spy(kin, step=step, log=log):
                out = step(kin)
                log["kin"] = _kin(kin)
                log["force"] = np.array(out.force, dtype=float)
                return out

            ad.manager.step = spy
            self.sides.append((ad, log))

    def run(self, steps: int) -> None:
        (a, la), (b, lb) = self.sides
        rtol = TRAJECTORY_RTOL
        for s in range(steps):
            for ad, _ in self.sides:
                ad.step(1)
            where = f"step {s + 1}"
            _same_kin(where, lb["kin"], la["kin"], rtol)
            _close(f"{where} force", lb["force"], la["force"], rtol)
            _close(f"{where} qfrc_passive", b.data.qfrc_passive, a.data.qfrc_passive, rtol)
            _close(f"{where} last_v", b._last_v, a._last_v, rtol)
            _close(f"{where} last_dv", b._last_dv, a._last_dv, rtol)
            assert np.array_equal(b._have_last, a._have_last)
            for f in ("qpos", "qvel"):
                _close(f"{where} {f}", getattr(b.data, f), getattr(a.data, f), rtol)
        ra, rb = a.records, b.records
        assert len(ra) == len(rb)
        for x, y in zip(ra, rb):
            for f in dataclasses.fields(x):
                u, v = getattr(x, f.name), getattr(y, f.name)
                if isinstance(u, (float, np.ndarray)):
                    _close(f"record.{f.name}", v, u, rtol)
                elif not isinstance(u, (dict, list, tuple)):
                    assert u == v, f"record.{f.name}: {v!r} != {u!r}"


def both(build, pairs, steps) -> tuple[Shadow, Twin]:
    """Run the scene both ways (module docstring)."""
    shadow = Shadow(build, pairs)
    shadow.run(steps)
    assert shadow.forces, "no step applied a force: the scene tests nothing"
    twin = Twin(build, pairs)
    twin.run(steps)
    return shadow, twin


def _spheres_xml(balls, dt, integrator="Euler", plate="plane"):
    """Free spheres (name, Body, position, velocity, angular velocity) over a plate z = 0."""
    geoms = []
    for name, body, pos, _, _ in balls:
        J = body.J
        x, y, z = (float(c) for c in pos)
        geoms.append(f'<body name="{name}" pos="{x!r} {y!r} {z!r}"><freejoint/>'
                     f'<inertial pos="0 0 0" mass="{body.mass!r}" diaginertia="{J!r} {J!r} {J!r}"/>'
                     f'<geom name="{name}" type="sphere" size="{body.radius!r}" mass="0" contype="0" '
                     'conaffinity="0"/></body>')
    if plate == "plane":
        plate_xml = '<geom name="plate" type="plane" size="1 1 0.1" contype="0" conaffinity="0"/>'
    else:
        plate_xml = '<geom name="plate" type="box" pos="0 0 -0.05" size="1 1 0.05" contype="0" conaffinity="0"/>'
    xml = (f'<mujoco><option timestep="{dt!r}" integrator="{integrator}" gravity="0 0 {-G!r}"/>'
           f'<worldbody>{plate_xml}{"".join(geoms)}</worldbody></mujoco>')

    def build():
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        for k, (_, _, _, v, w) in enumerate(balls):
            data.qvel[6 * k:6 * k + 6] = list(v) + list(w)
        mujoco.mj_forward(model, data)
        return model, data
    return build


def test_resting_spheres_on_a_plane():
    """Nine rubber balls dropped from seeded gaps: bounces, then the settled path."""
    R = 0.02
    ball = Body.sphere(RUBBER, R)
    gaps = np.random.default_rng(0).uniform(0.0, 5e-4, 9)
    balls = [(f"b{i}", ball, (3 * R * (i % 3), 3 * R * (i // 3), R + gaps[i]), (0, 0, 0), (0, 0, 0))
             for i in range(9)]
    law = _law(RUBBER, R, STEEL, math.inf)
    shadow, twin = both(_spheres_xml(balls, 1e-3), [PairSpec(f"b{i}", "plate", law) for i in range(9)], 400)
    assert shadow.candidates == 9
    assert shadow.ad.manager.active_count == 9  # resting at the end


def test_bouncing_ball_rk4():
    """A steel ball bouncing on a plane under gravity, RK4 (four hook calls per step)."""
    ball = Body.sphere(STEEL, 0.01)
    build = lambda: scenes.ball_on_plate(ball, 1.0, gap=2e-3, dt=2e-4, integrator="rk4", gravity=G)  # noqa: E731
    shadow, twin = both(build, [PairSpec("ball", "plate", _law(STEEL, 0.01, STEEL, math.inf))], 1200)
    assert len(shadow.ad.records) >= 2


@pytest.mark.parametrize("angle, spin", [(30.0, 0.0), (45.0, -150.0), (60.0, 300.0)])
def test_oblique_impact_with_spin(angle, spin):
    ball = Body.sphere(RUBBER, 0.02)
    build = lambda: scenes.ball_on_plate(ball, 2.0, angle, spin, gap=1e-3, dt=1e-4)  # noqa: E731
    shadow, twin = both(build, [PairSpec("ball", "plate", _law(RUBBER, 0.02, STEEL, math.inf))], 300)
    assert len(shadow.ad.records) == 1
    assert shadow.levers > 0  # the contact's moving point was compared (compiled lever_free against numpy)


def test_two_spheres_in_flight_colliding():
    """Two free spheres, oblique with spin: in flight (a gap), then colliding."""
    b1, b2 = Body.sphere(STEEL, 0.01), Body.sphere(RUBBER, 0.03)
    build = lambda: scenes.two_spheres(b1, b2, 1.5, 50.0, 200.0, gap=2e-3, dt=1e-4)  # noqa: E731
    shadow, twin = both(build, [PairSpec("ball", "ball2", _law(STEEL, 0.01, RUBBER, 0.03))], 300)
    assert len(shadow.ad.records) == 1


def test_several_contacts_on_one_body():
    """A rubber ball resting on the plate, a steel ball resting on it, and a
    third falling onto that one with spin: bodies in two pairs each, the
    cross terms of a_ext (velocity_change) and held forces."""
    R0, R1, R2 = 0.03, 0.015, 0.01
    b0, b1, b2 = Body.sphere(RUBBER, R0), Body.sphere(STEEL, R1), Body.sphere(STEEL, R2)
    balls = [("a", b0, (0, 0, R0), (0, 0, 0), (0, 0, 0)),
             ("b", b1, (1e-4, 0, 2 * R0 + R1), (0, 0, 0), (0, 0, 0)),
             ("c", b2, (3e-4, 0, 2 * R0 + 2 * R1 + R2 + 0.02), (0, 0, -0.5), (0, 20.0, 0))]
    pairs = [PairSpec("a", "plate", _law(RUBBER, R0, STEEL, math.inf)),
             PairSpec("b", "a", _law(STEEL, R1, RUBBER, R0)),
             PairSpec("c", "b", _law(STEEL, R2, STEEL, R1))]
    shadow, twin = both(_spheres_xml(balls, 1e-3), pairs, 150)
    assert shadow.candidates == 3
    assert len(shadow.ad.records) >= 1


def test_mixed_with_jacobian_pairs():
    """A ball on a box plate (a face: the Jacobian path) under a free ball
    (the compiled group): both groups in one ContactKinematics, impulses
    crossing between them."""
    R0, R1 = 0.02, 0.01
    b0, b1 = Body.sphere(RUBBER, R0), Body.sphere(STEEL, R1)
    balls = [("a", b0, (0, 0, R0 + 1e-4), (0, 0, 0), (0, 0, 0)),
             ("b", b1, (2e-4, 0, 2 * R0 + R1 + 0.01), (0.1, 0, -0.3), (0, 0, 0))]
    pairs = [PairSpec("a", "plate", _law(RUBBER, R0, STEEL, math.inf)),
             PairSpec("b", "a", _law(STEEL, R1, RUBBER, R0))]
    shadow, twin = both(_spheres_xml(balls, 1e-3, plate="box"), pairs, 200)
    ad = shadow.ad
    assert [p.index for p in ad._slow] == [0] and list(ad._fast.index) == [1]
    assert shadow.candidates == 2


def test_coincident_centres_refused_alike():
    """A state the detection refuses raises the numpy path's ValueError."""
    b1, b2 = Body.sphere(STEEL, 0.01), Body.sphere(STEEL, 0.01)
    msgs = []
    for compiled in (False, True):
        model, data = scenes.two_spheres(b1, b2, 1.0, dt=1e-4)
        ad = MujocoAdapter(model, data, [PairSpec("ball", "ball2", _law(STEEL, 0.01, STEEL, 0.01))],
                           compiled=compiled)
        data.qpos[0:3] = data.qpos[7:10]
        mujoco.mj_forward(model, data)
        with pytest.raises(ValueError, match="coincide") as exc:
            ad.step(1)
        msgs.append(str(exc.value))
    assert msgs[0] == msgs[1]


def test_off_image_is_the_step_trackers_numpy_test():
    """engines.mujoco._kernels.off_image (the step tracker's semi-implicit test
    in one pass) answers as the numpy test it replaced, |image - qpos| >
    JUMP_VTOL h (1 + max |qvel|) + 1e-13 (1 + |q0|) per coordinate, on random states: the
    image itself, one coordinate moved just past and just inside the bound,
    NaN in qvel (every tolerance NaN: nothing compares off) or in qpos, and
    inf in qvel (max |qvel| is taken from the bit patterns: inf, not NaN)."""
    from engines.mujoco._kernels import off_image
    from engines.mujoco._stepping import JUMP_VTOL

    rng = np.random.default_rng(5)
    h = 1e-3

    def numpy_off(img, qpos, q0, qvel):
        vmax = float(np.max(np.abs(qvel)))
        return np.abs(img - qpos) > JUMP_VTOL * h * (1.0 + vmax) + 1e-13 * (1.0 + np.abs(q0))

    seen = set()
    for trial in range(200):
        nq = int(rng.integers(1, 60))
        q0, qvel = rng.normal(size=nq), rng.normal(size=nq) * 10.0
        img = q0 + h * qvel
        qpos = img.copy()
        i = int(rng.integers(nq))
        tol = JUMP_VTOL * h * (1.0 + np.max(np.abs(qvel))) + 1e-13 * (1.0 + abs(q0[i]))
        kind = trial % 6
        if kind == 1:
            qpos[i] += 1.5 * tol
        elif kind == 2:
            qpos[i] += 0.5 * tol
        elif kind == 3:
            qvel[i] = np.nan
            qpos[i] += 1.0
        elif kind == 4:
            qpos[i] = np.nan
        elif kind == 5:
            qvel[i] = np.inf
            qpos[(i + 1) % nq] = np.nan
        want = numpy_off(img, qpos, q0, qvel)
        bad = np.ones(nq, bool)
        assert off_image(img, qpos, q0, qvel, h, JUMP_VTOL, bad) == bool(want.any())
        np.testing.assert_array_equal(bad, want)
        seen.add(bool(want.any()))
    assert seen == {True, False}


def test_off_image_start_is_off_image_then_the_start_copies():
    """engines.mujoco._kernels.off_image_start (the step tracker's test and its
    start-state copies in one pass) gives off_image's answer and ``bad``, and
    leaves q0 = q_img = qpos and v0 = qvel (what StepTracker._start copied),
    on states on and off the image."""
    from engines.mujoco._kernels import off_image, off_image_start
    from engines.mujoco._stepping import JUMP_VTOL

    rng = np.random.default_rng(8)
    h = 1e-3
    answers = set()
    for trial in range(50):
        nq, nv = int(rng.integers(1, 40)), int(rng.integers(1, 40))
        q0, qvel = rng.normal(size=nq), rng.normal(size=nv)
        img = q0 + h * rng.normal(size=nq)
        qpos = img.copy()
        if trial % 2:
            qpos[int(rng.integers(nq))] += 1e-3
        bad_want, bad = np.ones(nq, bool), np.zeros(nq, bool)
        want = off_image(img.copy(), qpos, q0.copy(), qvel, h, JUMP_VTOL, bad_want)
        q0_k, img_k, v0 = q0.copy(), img.copy(), np.zeros(nv)
        assert off_image_start(img_k, qpos, q0_k, qvel, v0, h, JUMP_VTOL, bad) == want
        np.testing.assert_array_equal(bad, bad_want)
        np.testing.assert_array_equal(q0_k, qpos)
        np.testing.assert_array_equal(img_k, qpos)
        np.testing.assert_array_equal(v0, qvel)
        answers.add(bool(want))
    assert answers == {True, False}


def test_probe_angular_velocity_is_mj_object_velocity():
    """The adapter's body probe reads a body's angular velocity from cvel; it
    is bit for bit what mj_objectVelocity(..., flg_local=0) returns (which it
    replaced), for a spinning, tumbling free sphere and the world body."""
    m, d = scenes.ball_on_plate(Body.sphere(RUBBER, 0.02), 1.0, 45.0, 50.0, gap=0.01, dt=1e-4, gravity=G)
    adapter = MujocoAdapter(m, d, [PairSpec("ball", "plate", _law(RUBBER, 0.02, STEEL, math.inf))])
    d.qvel[3:6] = [3.0, -7.0, 11.0]
    d.qvel[0:3] = [0.5, 0.2, -1.0]
    for _ in range(5):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    for b in range(m.nbody):
        res = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, res, 0)
        np.testing.assert_array_equal(adapter._angular_velocity(b), res[:3])
    assert np.any(adapter._angular_velocity(m.nbody - 1) != 0.0)


def test_add_couples_is_the_numpy_form():
    """engines.mujoco._kernels.add_couples (the moving contact points' couples
    on free joints' angular dofs) against the numpy form it replaced,
    np.add.at(q, dof + 3..5, einsum('kji,kj->ki', xmat[b], tq)), with bodies
    repeated (their couples add up): equal to an ulp of the largest term
    (bit for bit where einsum sums the three products in order, as measured)."""
    from engines.mujoco._kernels import add_couples

    rng = np.random.default_rng(9)
    nb, m = 7, 40
    R = np.linalg.qr(rng.normal(size=(nb, 3, 3)))[0]
    xmat = R.reshape(nb, 9)
    b = rng.integers(0, nb, size=m)
    dof = 6 * b
    tq = rng.normal(size=(m, 3))
    q0 = rng.normal(size=6 * nb)
    want = q0.copy()
    np.add.at(want, dof[:, None] + np.arange(3, 6), np.einsum("kji,kj->ki", xmat[b].reshape(-1, 3, 3), tq))
    got = q0.copy()
    add_couples(got, xmat, b.astype(np.int64), dof.astype(np.int64), tq)
    assert np.all(np.abs(got - want) <= 4e-16 * (np.abs(want) + np.abs(tq).sum()))
    assert not np.array_equal(got, q0)


def test_required_mask_is_required_pairs():
    """engines.mujoco._kernels.required_mask (the adapter's ``required`` in
    place) marks exactly the pairs of engines._kernel.required
    (ContactManager.required_pairs): in contact, or with any component of a
    timing correction J non-zero."""
    from engines._kernel import required
    from engines.mujoco._kernels import required_mask

    rng = np.random.default_rng(3)
    for _ in range(20):
        P = int(rng.integers(1, 50))
        active = rng.random(P) < 0.3
        J = np.where(rng.random((P, 3)) < 0.2, rng.normal(size=(P, 3)), 0.0)
        out = rng.random(P) < 0.5  # stale contents are overwritten
        required_mask(active, J, out)
        want = np.zeros(P, bool)
        want[required(active, J)] = True
        np.testing.assert_array_equal(out, want)
