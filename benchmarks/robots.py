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

Both run at their own integrator (the ant RK4, the humanoid Euler): the
step tracker reads RK4 steps with damped, armatured joints as steps
(issue 11). The rest phase's energy is the physical one: kinetic with the
MSF timing correction's one-step offset taken out
(``MujocoAdapter.velocity_offset``), gravitational, plus the elastic energy
held in the MSF contacts (``ContactManager.stored_energy``); its largest
rise over one step is split by whether one of MuJoCo's joint-limit
constraints acted in that step (a soft constraint whose own stored energy
is not in the sum). Under RK4 the MSF ant hops under these torques,
impacts flagged for energy from outside the contact
(scripts/ant_integrators.py, docs/engines.md).
"""

from __future__ import annotations

import os
import time

import numpy as np

from ._common import log, run_robots

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
    if not msf:  # the same model with MuJoCo's own contact: no exclusion
        model.exclude_signature[:] = -1
        return model, data, None
    return model, data, MujocoAdapter(model, data, pairs)


def _limit_force(data) -> float:
    """Sum of |force| of MuJoCo's joint-limit constraints in the last step [N or N m]."""
    import mujoco

    n = data.nefc
    on = data.efc_type[:n] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
    return float(np.sum(np.abs(data.efc_force[:n][on])))


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
            wall = np.empty(steps)
            for k in range(steps):
                data.ctrl[:] = rng.uniform(lo, hi)
                t = time.perf_counter()
                mujoco.mj_step(model, data)
                wall[k] = time.perf_counter() - t
            out[f"{mode}_step_s"] = float(np.mean(wall))
            out[f"{mode}_step_median_s"] = float(np.median(wall))
            out[f"{mode}_base_height_m"] = float(data.qpos[2])
            data.ctrl[:] = 0.0
            E, limited = [], []
            for _ in range(steps):
                mujoco.mj_step(model, data)
                if adapter is None:
                    E.append(mechanical_energy(model, data))
                else:  # the physical velocities and the energy held in the MSF contacts
                    E.append(mechanical_energy(model, data, data.qvel - adapter.velocity_offset())
                             + adapter.manager.stored_energy())
                limited.append(_limit_force(data) > 0.0)
        E = np.array(E)
        out[f"{mode}_rest_energy_J"] = [float(E[0]), float(E[-1])]
        out[f"{mode}_rest_energy_rise_J"] = float(np.max(E[steps // 5:] - E[steps // 5]))
        # the largest rise over one step after the first fifth, in steps where one of MuJoCo's
        # joint-limit constraints pushes (a soft constraint: its stored energy is not in the sum)
        # and in the others
        rise = np.diff(E)[steps // 5:]
        lim = np.array(limited[1:])[steps // 5:]
        out[f"{mode}_rest_step_rise_limits_J"] = float(np.max(rise[lim], initial=0.0))
        out[f"{mode}_rest_step_rise_free_J"] = float(np.max(rise[~lim], initial=0.0))
        out[f"{mode}_rest_steps_limited"] = int(np.count_nonzero(lim))
        if adapter is not None:
            out["msf_records"] = len(adapter.records)
            out["msf_managed_contacts"] = len(adapter.pairs)
    out["ratio_msf_over_builtin"] = out["msf_step_s"] / out["builtin_step_s"]
    out["ratio_median_msf_over_builtin"] = out["msf_step_median_s"] / out["builtin_step_median_s"]
    out["load_avg_1min"] = os.getloadavg()[0]
    return out


STAND_STEPS = 300


def standing(name: str, steps: int = STAND_STEPS) -> dict:
    """The model from its own initial pose with no torque for ``steps`` steps,
    MSF and MuJoCo's own contact: the base height [m], the joint angles
    [deg], and how the feet rest: MuJoCo's contact distances (positive: a
    gap; the model's geom margin makes its contact act across it) and MSF's
    approaches [m]."""
    import contextlib

    import mujoco

    from engines.mujoco import installed

    out = {"name": "robots-standing", "engine": "mujoco", "model": name, "steps": steps}
    for mode in ("msf", "builtin"):
        model, data, adapter = _variant(name, mode == "msf")
        with installed(adapter) if adapter is not None else contextlib.nullcontext():
            for _ in range(steps):
                mujoco.mj_step(model, data)
        out[f"{mode}_base_height_m"] = float(data.qpos[2])
        out[f"{mode}_joints_deg"] = [round(float(np.degrees(q)), 2) for q in data.qpos[7:]]
        if adapter is None:
            out["builtin_contact_dist_m"] = sorted(float(c.dist) for c in data.contact[:data.ncon])
        else:
            act = np.flatnonzero(adapter.manager.active)
            out["msf_approach_m"] = sorted(float(x) for x in adapter.manager.x[act])
    return out


def _describe(r: dict) -> list[str]:
    return [f"  rest, largest step rise: msf {r['msf_rest_step_rise_free_J']:.3g} J without a joint limit acting, "
            f"{r['msf_rest_step_rise_limits_J']:.3g} J with; built-in {r['builtin_rest_step_rise_free_J']:.3g}, "
            f"{r['builtin_rest_step_rise_limits_J']:.3g} J",
            f"  msf {r['msf_step_median_s'] * 1e3:.2f} ms, builtin {r['builtin_step_median_s'] * 1e3:.3f} ms per step "
            f"(medians; ratio {r['ratio_median_msf_over_builtin']:.0f}, load {r['load_avg_1min']:.1f}); "
            f"rest energy rise msf {r['msf_rest_energy_rise_J']:.3g} J"]


def run(quick: bool = False) -> list[dict]:
    out = run_robots("mujoco", "MuJoCo", MODELS, QUICK_STEPS if quick else STEPS, measure, _describe)
    for r in [r for r in out if not r.get("failed")]:
        st = standing(r["model"])
        log(f"  {r['model']} standing, no torque, {STAND_STEPS} steps: base msf {st['msf_base_height_m']:.4f} m, built-in "
            f"{st['builtin_base_height_m']:.4f} m; built-in contact distances "
            f"{[round(1e3 * d, 2) for d in st['builtin_contact_dist_m']]} mm, MSF approaches "
            f"{[round(1e3 * x, 3) for x in st['msf_approach_m']]} mm")
        out.append(st)
    return out
