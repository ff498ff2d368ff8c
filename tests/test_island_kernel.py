"""The compiled island integrator (engines._island_kernel, driven by
engines._contacts.island_compiled) against the numpy step_island
(engines._contacts.islands), its readable reference.

Each scene runs twice, ``manager.island_compiled`` True and False (the
numpy reference): Newton's cradles of 3 and 5 steel balls at dt = 1e-5 ...
2e-3 s, a ball resting on a plate struck by another, an oblique island of
two laws with friction, deep oblique bead impacts with their moving contact
points, whole runs compared step by step; and an 8-sphere
pile in a box (several islands a step, three laws), where both paths take
every step from the same manager state (a pile amplifies round-off from
step to step, as any chaotic system: whole runs part after ~30 steps at
1e-8 and reach 1e-3 by step 70, measured, while every single step agrees
to 3e-12).
"""

from __future__ import annotations

import contextlib
import copy
import math
import warnings

import numpy as np
import pytest

import engines._contacts.manager as manager_mod
from engines._contacts.island_compiled import coupled_rows
from msf_contact import Body, ContactPair, Curvature, make_law, preset
from test_multi_contact import Scene, _engine_available
from _scripts import load_script

#: Both paths do the same arithmetic per row in another order (einsum and
#: np.add.at against written-out sums; the laws' own numpy methods against
#: the kernel's inlined forces) and find the same roots to ROOT_TOL (1e-13
#: of a substep): agreement to round-off. Measured: the cradles and the
#: struck ball bit for bit; a pile step from one state 3.4e-12 (forces) at
#: most over 200 steps. 1e-9 leaves room for the root finding's conditioning
#: near a grazing end (as tests/test_kernel.py's SAME_RTOL for rows alone).
ISLAND_RTOL = 1e-9
#: The records' quantities compared. Not f_min: it is not continuous in the state. The first
#: substep's |F_t|/F_n counts whenever F_n > 0 (F_RATIO_FLOOR is relative to the running peak,
#: which is that sample), so a contact that begins at x = +2.5e-20 m (F_n ~ 1e-19 N, F_t = 0
#: with s reset) records f_min = 0 where one beginning at x = -2.3e-21 m records 0.0030: measured
#: in test_oblique_island_of_two_laws in pybullet, the two free-flight onsets differing by the
#: round-off of (v . n) (einsum against a written-out sum).
RECORD_KEYS = ("cor_n", "cor_t", "cor_t_contact", "tau", "tau1", "x_max", "F_max", "W_el_comp", "W_visc_comp",
               "W_diss_n", "W_diss_t", "Q_t", "f_max")
STEEL = preset("steel")
R = 0.01
BALL = Body.sphere(STEEL, R)
V0 = 1.0


def _law(name="msf", plane=False, **kw):
    curv = Curvature.sphere_on_plane(R) if plane else Curvature.two_spheres(R, R)
    return make_law(name, ContactPair(STEEL, STEEL), curv, **kw)


@contextlib.contextmanager
def _count_kernel_calls(counter):
    """Count the compiled island path's calls (the test must exercise it)."""
    real = manager_mod.step_islands

    def spy(*args, **kw):
        counter[0] += 1
        return real(*args, **kw)

    manager_mod.step_islands = spy
    try:
        yield
    finally:
        manager_mod.step_islands = real


def _run_scene(make, steps, compiled):
    """(per-step forces, records) of the scene from make() run with the
    compiled island path on or off."""
    sc = make()
    mgr = sc.adapter.manager
    mgr.island_compiled = compiled
    forces = []
    step = mgr.step

    def spy(kin):
        out = step(kin)
        forces.append((out.pair.copy(), out.force.copy()))
        return out

    mgr.step = spy
    records = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with sc._ctx:
            for _ in range(steps):
                sc.adapter.step(1)
                records += sc.adapter.pop_records()
            records += sc.adapter.pop_records()
    return forces, records


def _close(a, b, scale):
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= ISLAND_RTOL * max(abs(b), scale)


def _same_records(rc, rn):
    key = lambda r: (r.inputs["pair"], r.inputs["t_onset"])  # noqa: E731 (the islands' end order may differ)
    rc, rn = sorted(rc, key=key), sorted(rn, key=key)
    assert len(rc) == len(rn)
    for a, b in zip(rc, rn):
        assert a.inputs["pair"] == b.inputs["pair"] and a.ended_by == b.ended_by
        assert _close(a.inputs["t_end"], b.inputs["t_end"], 1e-6)
        e_scale = abs(b.W_el_comp) + abs(b.W_diss_n) + abs(b.W_diss_t)
        for k in RECORD_KEYS:
            va, vb = getattr(a, k), getattr(b, k)
            # each against its natural scale: works against the impact's energies, times against 1 us,
            # restitution coefficients and force ratios against 1 (a small |F_t|/F_n is a difference)
            scale = e_scale if k.startswith(("W_", "Q_")) else (1e-6 if k in ("tau", "tau1") else 1.0)
            assert _close(va, vb, scale), (k, va, vb)


def _compare(make, steps, min_records):
    calls = [0]
    with _count_kernel_calls(calls):
        fc, rc = _run_scene(make, steps, True)
    assert calls[0] > 0  # the compiled island path ran
    fn, rn = _run_scene(make, steps, False)
    assert len(fc) == len(fn)
    for (pa, a), (pb, b) in zip(fc, fn):
        assert np.array_equal(pa, pb)
        assert np.max(np.abs(a - b), initial=0.0) <= ISLAND_RTOL * max(np.max(np.abs(b), initial=0.0), 1e-30)
    assert len(rc) >= min_records
    _same_records(rc, rn)


@pytest.mark.mujoco
@pytest.mark.parametrize("n", [3, 5])
@pytest.mark.parametrize("dt", [1e-5, 1e-4, 1e-3, 2e-3])
def test_cradle(n, dt):
    """test_islands.test_cradle's scene, both paths."""
    _engine_available("mujoco")
    law = _law()
    gap = max(3.0 * V0 * dt, 1e-4)
    x0 = [-(2 * R + gap)] + [2 * R * i for i in range(n - 1)]

    def make():
        return Scene("mujoco", [BALL] * n, [[x, 0, 0] for x in x0], [[V0, 0, 0]] + [[0, 0, 0]] * (n - 1),
                     [(i + 1, i) for i in range(n - 1)], [law] * (n - 1), 0.0, dt)

    _compare(make, int((gap / V0 + 4e-4) / dt) + 3, n - 1)


@pytest.mark.mujoco
def test_struck_ball_on_plate():
    """test_islands.test_struck_ball_on_plate's scene (two laws: ball-ball,
    ball-plate; a resting contact joined by an impact), both paths."""
    _engine_available("mujoco")
    g, dt = 9.81, 1e-3
    law_bb, law_bp = _law(), _law(plane=True)
    K = 2.0 / 3.0 * law_bp.moduli.E * float(law_bp.psi(np.zeros(1))[0])
    z_a = R - (BALL.mass * g / K) ** (2.0 / 3.0)
    z_b = z_a + 2 * R + 3e-3

    def make():
        return Scene("mujoco", [BALL, BALL], [[0, 0, z_a], [0, 0, z_b]], [[0, 0, 0], [0, 0, -V0]],
                     [(0, -1), (1, 0)], [law_bp, law_bb], g, dt)

    _compare(make, 8, 2)


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
def test_oblique_island_of_two_laws(engine):
    """A striker hits the middle of three balls off-axis (tangential forces
    and Coulomb friction in the coupling, spin): MSF with mu = 0.3 on the
    strike, Hunt-Crossley (cor 0.8) between the struck balls, dt = 1 ms."""
    _engine_available(engine)
    dt = 1e-3
    laws = [_law("msf", mu=0.3), _law("hunt-crossley", cor=0.8)]
    gap = 3e-3
    off = 0.4 * R  # striker's line off the struck ball's centre
    c = math.sqrt((2 * R) ** 2 - off ** 2)

    def make():
        return Scene(engine, [BALL] * 3, [[-(c + gap), off, 0], [0, 0, 0], [2 * R + 2e-4, 0, 0]],
                     [[V0, 0, 0], [0, 0, 0], [0, 0, 0]], [(1, 0), (2, 1)], laws, 0.0, dt)

    _compare(make, 10, 2)


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
def test_deep_oblique_island(engine):
    """test_islands.test_deep_oblique_island's coupled scene (two glass beads
    at 50 m/s, 45 degrees on polyurethane, x_max/R = 0.5, striking each other
    during their plate contacts): the moving contact points (the lever) of
    the island's rows, both paths."""
    _engine_available(engine)
    from test_islands import bead_scene

    _compare(lambda: bead_scene(engine, 2, vy=2.0), 6, 3)


def _pile_module():
    return load_script("pile")


#: The closed-form coupling blocks against MuJoCo's Jacobians and mass matrix: the same
#: rigid-body algebra in another order (measured 2e-16 of the largest block).
BLOCKS_RTOL = 1e-12


@pytest.mark.mujoco
def test_mujoco_coupling_blocks_closed_form():
    """The MuJoCo adapter's closed-form blocks of free spheres (walls and
    sphere-sphere pairs of scripts/pile.py's 8-sphere box, after 60 steps:
    turned, moving bodies) equal the Jacobian route (mj_jac, mj_solveM)."""
    _engine_available("mujoco")
    ad, ctx, _ = _pile_module().build_mujoco(8, 3, 1e-3)
    with warnings.catch_warnings(), ctx:
        warnings.simplefilter("ignore")
        ad.step(60)
        pp, pq = coupled_rows(ad._keys)
        assert pp.size > 100 and np.all(ad._closed_pair)
        W, Wc = ad._coupling_blocks(pp, pq)
        Wj, Wcj = ad._coupling_blocks_jac(pp, pq)
    assert np.max(np.abs(W - Wj)) <= BLOCKS_RTOL * np.max(np.abs(Wj))
    assert np.max(np.abs(Wc - Wcj)) <= BLOCKS_RTOL * np.max(np.abs(Wcj))
    assert np.max(np.abs(W - Wc)) > 0.1 * np.max(np.abs(Wj))  # the rotational terms are there


def _snapshot(mgr):
    skip = ("_coupling", "_probe", "_probe_batch", "_balance", "pairs", "_groups", "step")
    return {k: (v.copy() if isinstance(v, np.ndarray) else copy.deepcopy(v))
            for k, v in mgr.__dict__.items() if k not in skip}


def _restore(mgr, snap):
    """Back to the snapshot, arrays in place (several are views of one array)."""
    for k, v in snap.items():
        cur = mgr.__dict__.get(k)
        if isinstance(v, np.ndarray) and isinstance(cur, np.ndarray) and cur.shape == v.shape:
            cur[...] = v
        else:
            mgr.__dict__[k] = copy.deepcopy(v)


@pytest.mark.mujoco
def test_pile_of_eight_step_by_step():
    """scripts/pile.py's 8 spheres (steel and rubber, three laws) in a box in
    MuJoCo, 120 steps of 1 ms (the pour and the first bounces: up to 5
    islands a step): each step taken by both paths from the same manager
    state; the forces, the per-pair state and the records agree."""
    _engine_available("mujoco")
    ad, ctx, _ = _pile_module().build_mujoco(8, 3, 1e-3)
    mgr = ad.manager
    mgr.set_energy_probe(None)  # its bookkeeping would see each step twice
    step = mgr.step
    stats = {"island_rows": 0, "records": 0, "calls": 0}

    def twin(kin):
        before = _snapshot(mgr)
        mgr.island_compiled = False
        ref = step(kin)
        after = _snapshot(mgr)
        _restore(mgr, before)
        mgr.island_compiled = True
        out = step(kin)
        assert np.array_equal(out.pair, ref.pair)
        scale = max(np.max(np.abs(ref.force), initial=0.0), 1e-30)
        assert np.max(np.abs(out.force - ref.force), initial=0.0) <= ISLAND_RTOL * scale
        for k in ("active", "x", "s", "vc", "J", "dv_corr", "W_el", "W_visc", "W_t", "Q_t"):
            a, b = getattr(mgr, k), after[k]
            assert np.allclose(a, b, rtol=ISLAND_RTOL, atol=ISLAND_RTOL * np.max(np.abs(b), initial=0.0)), k
        new_c, new_n = mgr.records[len(before["records"]):], after["records"][len(before["records"]):]
        _same_records(new_c, new_n)
        stats["island_rows"] += mgr.last_step_info.get("island_rows", 0)
        stats["records"] += len(new_c)
        return out

    mgr.step = twin
    calls = [0]
    with warnings.catch_warnings(), _count_kernel_calls(calls):
        warnings.simplefilter("ignore")
        with ctx:
            ad.step(120)
    assert calls[0] > 10 and stats["island_rows"] > 50 and stats["records"] > 5, (calls, stats)


@pytest.mark.mujoco
@pytest.mark.parametrize("kind, tilt_deg", [("cylinder", 0.0), ("capsule", 3.0)])
def test_lying_side_line_law_island(kind, tilt_deg):
    """A cylinder lying flat and a capsule tilted 3 degrees (r 10 mm,
    half-length 30 mm, natural rubber on steel, 1 m/s, dt 1 ms, 150 steps:
    bounces and rest) dropped on a plate: the side's two ends are one island
    of two engines._narrow.SideEndLaw rows (the line law, its pose refreshed
    every step: engines._kernel CODE_SIDE); compiled == numpy step by step,
    records included."""
    _engine_available("mujoco")
    from engines.base import PairSpec
    from engines.mujoco.adapter import MujocoAdapter
    from test_narrow_mujoco import scene

    rubber = preset("natural-rubber")
    r, h = 0.01, 0.03
    m = rubber.density * math.pi * r * r * 2 * h
    inertia = (m * (3 * r * r + 4 * h * h) / 12, m * (3 * r * r + 4 * h * h) / 12, m * r * r / 2)
    law = make_law("msf", ContactPair(rubber, STEEL), Curvature.sphere_on_plane(r))

    class _Lying:
        def __init__(self):
            model, data = scene(f'<geom name="g" type="{kind}" size="{r} {h}" mass="0"/>', m, inertia,
                                r + h * math.sin(math.radians(tilt_deg)) + 1e-4, euler=f"0 {90 - tilt_deg} 0")
            self.adapter = MujocoAdapter(model, data, [PairSpec("g", "plate", law)])
            self._ctx = contextlib.nullcontext()

    calls = [0]
    with _count_kernel_calls(calls):
        fc, rc = _run_scene(_Lying, 150, True)
    assert calls[0] > 0
    fn, rn = _run_scene(_Lying, 150, False)
    assert len(fc) == len(fn)
    for (pa, a), (pb, b) in zip(fc, fn):
        assert np.array_equal(pa, pb)
        assert np.max(np.abs(a - b), initial=0.0) <= ISLAND_RTOL * max(np.max(np.abs(b), initial=0.0), 1e-30)
    assert len(rc) >= 2 and all(rec.parameters["R_b"] == math.inf for rec in rc)  # the line law's records
    _same_records(rc, rn)
