"""The MuJoCo adapter's native mjcb_passive (engines.mujoco._native) against
the Python hook it stands in front of: ``MujocoAdapter.step`` takes its
resting steps in compiled code with no Python between MuJoCo and the
kernel, and hands every other call to the Python hook. The same scene
stepped with the native hook and without it must give the same engine
state, forces, contact state, records and warnings bit for bit, also where
the native hook stops part-way (a state written between ``step`` calls: the
tracker's jump; a step that is not a resting one: the kernel's hand-back),
across a user's own ``mj_step`` loop between ``step`` calls, with two
adapters (two MjData) stepped in turn, and the hook's errors must still
raise from ``mj_step``."""

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
            mp.setattr(_native, "enter", lambda *a: None)
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


def test_native_hook_two_adapters_and_errors():
    """Two MjData of one model, each with its adapter, stepped in turn (both installed): each
    the same bit for bit as alone under the Python hook; a timestep changed after the adapter
    was made still raises from the Python hook through the native one, which then leaves
    MuJoCo's mjcb_passive as it was."""
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
        for _ in range(10):
            for ad in ads:
                ad.step(50)
        assert all(int(ad._native.ti[NK.I_COUNT]) > 0 for ad in ads)
        for d, (q, v) in zip(datas, alone):
            assert np.array_equal(d.qpos, q) and np.array_equal(d.qvel, v)
        model.opt.timestep = 2e-3
        with pytest.raises(RuntimeError, match="changed after the adapter"):
            ads[0].step(2)  # (one step alone does not use the native hook)
        assert mujoco.get_mjcb_passive() is _dispatch
        assert _native._STATE["slot"].value == _native._REG[NK.R_FALLBACK]  # the bindings' trampoline again
        assert not _native._REG[NK.R_SLOTS::3].any()
    assert mujoco.get_mjcb_passive() is None


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
