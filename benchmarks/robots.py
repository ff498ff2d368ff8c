"""Benchmark: models nobody here wrote, ``pybullet_data/mjcf/ant.xml`` and
``humanoid.xml`` in MuJoCo at their own time steps (ant 10 ms, humanoid
2 ms), MSF on every body-floor contact (natural rubber on steel,
:func:`engines.mujoco.robots.load_with_msf_floor`) against MuJoCo's own
contact, under the same seeded random torques (uniform in each actuator's
control range, seed 13) for STEPS steps, then STEPS steps with the torques
off. Per record: the wall time per step of each variant and their ratio,
the base height at the end of the torques, the MSF impact records, and the
mechanical energy (kinetic + gravitational) over the rest phase (its
largest rise above the rest phase's start after the first fifth).

The ant's own integrator is RK4; MSF runs it with Euler (both variants),
because the adapter's step tracker (engines/mujoco/_stepping.py) reads the
ant's RK4 steps, with damped, armatured joints, as state jumps and
interrupts every contact (reported, issue 11).
"""

from __future__ import annotations

import os
import time

import numpy as np

from ._common import log

STEPS = 1000
QUICK_STEPS = 100
SEED = 13
MODELS = ("ant.xml", "humanoid.xml")


def _variant(name: str, msf: bool):
    import mujoco
    import pybullet_data

    from engines.mujoco import MujocoAdapter
    from engines.mujoco.robots import load_with_msf_floor
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", name)
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    if not msf:  # the same model with MuJoCo's own contact: no exclusion
        model.exclude_signature[:] = -1
        return model, data, None
    return model, data, MujocoAdapter(model, data, pairs)


def measure(name: str, steps: int) -> dict:
    import contextlib

    import mujoco

    from engines.mujoco import installed
    from engines.mujoco.robots import mechanical_energy

    out = {"name": "robots", "engine": "mujoco", "model": name, "n_bodies": None}
    for mode in ("msf", "builtin"):
        model, data, adapter = _variant(name, mode == "msf")
        out["dt"] = float(model.opt.timestep)
        out["n_bodies"] = int(model.nbody - 1)
        rng = np.random.default_rng(SEED)
        lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
        ctx = installed(adapter) if adapter is not None else contextlib.nullcontext()
        with ctx:
            t = time.perf_counter()
            for _ in range(steps):
                data.ctrl[:] = rng.uniform(lo, hi)
                mujoco.mj_step(model, data)
            out[f"{mode}_step_s"] = (time.perf_counter() - t) / steps
            out[f"{mode}_base_height_m"] = float(data.qpos[2])
            data.ctrl[:] = 0.0
            E = []
            for _ in range(steps):
                mujoco.mj_step(model, data)
                E.append(mechanical_energy(model, data))
        E = np.array(E)
        out[f"{mode}_rest_energy_J"] = [float(E[0]), float(E[-1])]
        out[f"{mode}_rest_energy_rise_J"] = float(np.max(E[steps // 5:] - E[steps // 5]))
        if adapter is not None:
            out["msf_records"] = len(adapter.records)
            out["msf_managed_contacts"] = len(adapter.pairs)
    out["ratio_msf_over_builtin"] = out["msf_step_s"] / out["builtin_step_s"]
    return out


def run(quick: bool = False) -> list[dict]:
    steps = QUICK_STEPS if quick else STEPS
    out = []
    for name in MODELS:
        log(f"robots: {name} in MuJoCo, {steps} steps of seeded torques, then {steps} at rest")
        try:
            r = measure(name, steps)
        except Exception as exc:  # noqa: BLE001 - one model failing must not lose the other
            log(f"  failed: {type(exc).__name__}: {exc}")
            out.append({"name": "robots", "engine": "mujoco", "model": name, "failed": True,
                        "reason": f"{type(exc).__name__}: {exc}"[:300]})
            continue
        log(f"  msf {r['msf_step_s'] * 1e3:.2f} ms, builtin {r['builtin_step_s'] * 1e3:.3f} ms per step; "
            f"rest energy rise msf {r['msf_rest_energy_rise_J']:.3g} J")
        out.append(r)
    return out
