"""The MuJoCo adapter's native mjcb_passive (engines.mujoco._native) against
the Python hook it stands in front of: while the adapter's hook is
installed, resting steps are taken in compiled code with no Python between
MuJoCo and the kernel, whoever calls ``mj_step`` (``adapter.step(n)``,
``step(1)``, a user's own loop, the viewer's loop with ``mj_forward``
between steps), and every other call goes to the Python hook. The same
scene stepped with the native hook and without it must give the same engine
state, forces, contact state, records and warnings bit for bit, also where
the native hook stops part-way (a state written between steps: the
tracker's jump; a step that is not a resting one: the kernel's hand-back),
where Python between the steps reads what a native step left (the last
forces, ``last_step_info``) or changes what the Python hook reads (a
manager setting, its ``step``), with two adapters (two MjData) stepped in
turn and in ``mujoco.rollout``'s threads; RK4 and a chained Python hook
stay on the Python hook; the hook's errors must still raise from
``mj_step``."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from engines.mujoco import _native, _native_kernel as NK, installed
from engines.mujoco import MujocoAdapter
from engines.mujoco.adapter import _dispatch
from tests.test_resting_fused import STATE, _scene

pytestmark = pytest.mark.mujoco

ROOT = Path(__file__).resolve().parent.parent

N = 9


def _trace(ad) -> tuple:
    """What a run is compared on: the engine state, the last forces, the manager's state and info."""
    d, mgr, f = ad.data, ad.manager, ad.last_forces
    return (d.qpos.copy(), d.qvel.copy(), d.qfrc_passive.copy(), d.time,
            None if f is None else (f.force.copy(), f.point.copy(), np.asarray(f.pair).copy()),
            dict(mgr.last_step_info), [getattr(mgr, k).copy() for k in STATE])


def _same(a, b) -> bool:
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b, equal_nan=True)
    return a == b


def _run(native: bool, monkeypatch) -> tuple:
    """9 rubber spheres dropped on a plate: 600 steps in step() calls of 50 (at rest from ~step
    450), sphere 2's velocity written (a jump), 100 steps, 40 steps of the user's own mj_step
    loop, 100 more. Returns (traces, records, warnings, native resting steps)."""
    with monkeypatch.context() as mp:
        if not native:
            mp.setattr(_native, "attach", lambda *a: None)
        model, data, pairs = _scene(N, False)
        ad = MujocoAdapter(model, data, pairs)
        out = []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with ad:
                for _ in range(12):
                    ad.step(50)
                    out.append(_trace(ad))
                data.qvel[2 * 6 + 0] += 0.05  # written between steps: the tracker's jump
                ad.step(100)
                out.append(_trace(ad))
                for _ in range(40):
                    mujoco.mj_step(model, data)
                out.append(_trace(ad))
                ad.step(100)
                out.append(_trace(ad))
        recs = [(r.cor_n, r.tau, r.x_max, r.F_max, tuple(r.outside_validity)) for r in ad.records]
        done = int(ad._native.ti[NK.I_COUNT]) if ad._native is not None else 0
        return out, recs, [str(w.message) for w in caught], done, ad.jumps


def test_native_hook_is_the_python_hook_bit_for_bit(monkeypatch):
    want, recs_w, warn_w, none, jumps_w = _run(False, monkeypatch)
    got, recs_g, warn_g, done, jumps_g = _run(True, monkeypatch)
    assert none == 0
    assert done > 400, f"only {done} resting steps taken natively"
    assert jumps_w == jumps_g == 1
    for i, (g, w) in enumerate(zip(got, want)):
        assert _same(g, w), f"segment {i}: differs"
    assert recs_g == recs_w and len(recs_w) >= N
    assert warn_g == warn_w


def _count(ad) -> int:
    """Resting steps the native hook took for ``ad``."""
    return int(ad._native.ti[NK.I_COUNT]) if ad._native is not None else 0


def _user_loop(native: bool, how: str, monkeypatch, integrator: str = "Euler") -> tuple:
    """The 9 spheres dropped and brought to rest by the user's own loop (``how``: "mj_step", the
    viewer's "mj_step + mj_forward", "step(1)"), 700 steps; between steps: sphere 2's velocity
    written at 450 (a jump), the records popped and the last forces and last_step_info read every
    7th step from 500, a
    manager setting changed at 560 (settle_rate) and its ``step`` wrapped at 620 (the wrapper must
    see every step after). Returns (traces, records, warnings, native steps, wrapper calls)."""
    with monkeypatch.context() as mp:
        if not native:
            mp.setattr(_native, "attach", lambda *a: None)
        model, data, pairs = _scene(N, False, integrator)
        ad = MujocoAdapter(model, data, pairs)
        mgr = ad.manager
        out, calls, popped = [], [], []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with installed(ad):
                for k in range(700):
                    if k == 450:
                        data.qvel[2 * 6 + 2] += 0.05
                    if k == 560:
                        mgr.settle_rate = 0.5 * mgr.settle_rate
                    if k == 620:
                        inner = mgr.step

                        def wrapped(kin, inner=inner):
                            calls.append(kin.t)
                            return inner(kin)

                        mgr.step = wrapped
                    if how == "step(1)":
                        ad.step(1)
                    else:
                        mujoco.mj_step(model, data)
                        if how == "viewer":
                            mujoco.mj_forward(model, data)
                    if k >= 500 and k % 7 == 0:
                        popped += ad.pop_records()
                        f = ad.last_forces
                        out.append((data.qpos.copy(), data.qvel.copy(), data.qfrc_passive.copy(),
                                    None if f is None else (f.force.copy(), np.asarray(f.pair).copy()),
                                    dict(mgr.last_step_info)))
                out.append(_trace(ad))
        recs = [(r.cor_n, r.tau, r.x_max, r.F_max, tuple(r.outside_validity)) for r in popped + ad.records]
        return out, recs, [str(w.message) for w in caught], _count(ad), calls


@pytest.mark.parametrize("how", ["mj_step", "viewer", "step(1)"])
def test_users_own_loop_is_the_python_hook_bit_for_bit(monkeypatch, how):
    want, recs_w, warn_w, none, calls_w = _user_loop(False, how, monkeypatch)
    got, recs_g, warn_g, done, calls_g = _user_loop(True, how, monkeypatch)
    assert none == 0
    # at rest from ~step 450: most of steps 450-620 (until the wrapped step, which is the Python hook's)
    assert done > 100, f"only {done} resting steps taken natively"
    assert len(calls_w) == 700 - 620  # the wrapper sees every step after it was set...
    assert calls_g == calls_w  # ...also where the native hook was armed when it was set
    for i, (g, w) in enumerate(zip(got, want)):
        assert _same(g, w), f"read {i}: differs"
    assert recs_g == recs_w and len(recs_w) >= N
    assert warn_g == warn_w


def test_rk4_stays_on_the_python_hook():
    """RK4's four hook calls a step: the native hook is never armed, and the results are the
    Python hook's (the same loop, the native hook attached or not)."""
    runs = []
    for native in (False, True):
        with pytest.MonkeyPatch.context() as mp:
            runs.append(_user_loop(native, "mj_step", mp, "RK4"))
    (want, recs_w, _, _, _), (got, recs_g, _, done, _) = runs
    assert done == 0
    assert all(_same(g, w) for g, w in zip(got, want)) and recs_g == recs_w


def test_two_adapters_in_a_users_loop_and_errors():
    """Two MjData of one model, each with its adapter, both installed, stepped in turn by the
    user's own mj_step: each the same bit for bit as alone under the Python hook; a timestep
    changed after the adapters were made still raises from the Python hook through the native
    one; after the block MuJoCo's mjcb_passive is as it was (none) and the registry empty."""
    model, _, pairs = _scene(N, False)
    alone = []
    for _ in range(2):
        d = mujoco.MjData(model)
        ad = MujocoAdapter(model, d, pairs)
        ad.fused = False  # the general path: no native hook
        ad.step(500)
        alone.append((d.qpos.copy(), d.qvel.copy()))
    datas = [mujoco.MjData(model) for _ in range(2)]
    ads = [MujocoAdapter(model, d, pairs) for d in datas]
    with installed(ads[0]), installed(ads[1]):
        for _ in range(500):
            for d in datas:
                mujoco.mj_step(model, d)
        assert _native._STATE["slot"].value == _native._STATE["cfunc"].address  # (put there at the first arming)
        assert all(_count(ad) > 100 for ad in ads)
        for d, (q, v) in zip(datas, alone):
            assert np.array_equal(d.qpos, q) and np.array_equal(d.qvel, v)
        model.opt.timestep = 2e-3
        with pytest.raises(RuntimeError, match="changed after the adapter"):
            mujoco.mj_step(model, datas[0])
        assert mujoco.get_mjcb_passive() is _dispatch
    assert mujoco.get_mjcb_passive() is None
    assert _native._STATE["slot"].value is None  # the bindings' trampoline out with the Python hook
    assert not _native._REG[NK.R_SLOTS::3].any() and not _native._OWNERS
    assert all(type(ad) is MujocoAdapter and type(ad.manager) in _native._WATCHED for ad in ads)


def test_a_chained_python_hook_keeps_the_python_hook():
    """A Python mjcb_passive installed before the adapter's is chained by it on every call: the
    native hook, which would skip it, is not used."""
    model, data, pairs = _scene(N, False)
    ad = MujocoAdapter(model, data, pairs)
    seen = []
    mujoco.set_mjcb_passive(lambda m, d: seen.append(d.time))
    try:
        with installed(ad):
            for _ in range(600):
                mujoco.mj_step(model, data)
    finally:
        mujoco.set_mjcb_passive(None)
    assert _count(ad) == 0 and len(seen) == 600


def test_rollout_threads_are_the_plain_loop_bit_for_bit():
    """``mujoco.rollout`` steps two MjData in two threads, each with its adapter installed: the
    resting steps run natively on the rollout's threads (no GIL), and every state equals the
    plain mj_step loop from it under the Python hook."""
    from mujoco import rollout

    model, d0, pairs = _scene(N, False)
    ref = MujocoAdapter(model, d0, pairs)
    ref.step(450)  # come to rest
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.zeros(mujoco.mj_stateSize(model, full))
    mujoco.mj_getState(model, d0, s0, full)
    S = np.repeat(s0[None], 4, 0)
    S[:, 0] += np.arange(4) * 1e-3  # distinct start times: the same resting state
    nstep = 150
    ds = [mujoco.MjData(model) for _ in range(2)]
    ads = [MujocoAdapter(model, d, pairs) for d in ds]
    with installed(ads[0]), installed(ads[1]):
        out, _ = rollout.rollout(model, ds, S, nstep=nstep)
    assert sum(_count(ad) for ad in ads) > 200
    d = mujoco.MjData(model)
    plain = MujocoAdapter(model, d, pairs)
    plain.fused = False
    with installed(plain):
        for k in range(S.shape[0]):
            mujoco.mj_setState(model, d, S[k], full)
            for j in range(nstep):
                mujoco.mj_step(model, d)
                mujoco.mj_getState(model, d, s0, full)
                assert np.array_equal(out[k, j], s0), (k, j)


def test_native_hook_loaded_before_first_use_in_a_fresh_process():
    """The hook's module imported before any adapter uses it (as tests/test_jitcache.py imports
    every kernel module) still finds the registry: the symbol is registered when the kernel
    module is imported (before: the hook read address 0 and the process died in mj_step)."""
    code = ("import engines.mujoco._native_hook\n"
            "from benchmarks.spheres import mujoco_variant\n"
            "from engines.mujoco import _native_kernel as NK\n"
            "step, info, ad = mujoco_variant(3, 'msf')\n"
            "step(600)\n"
            "print(int(ad._native.ti[NK.I_COUNT]), info()['settled'])\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    done, settled = map(int, out.stdout.split())
    assert done > 0 and settled == 3
