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

Both run at their own time step; the ant's RK4 is replaced by Euler (MSF
on links under RK4 is warned by the adapter, and RK4 keeps no record of its
stages' limit forces). The rest phase's energy is
:class:`engines.mujoco.robots.RestEnergy`'s account: kinetic energy of the
physical velocities (``MujocoAdapter.velocity_offset`` taken out),
gravitational, the energy held in and exchanged by the MSF contacts
(``ContactManager.stored_energy``) and the energy MuJoCo's constraints
took out (minus the work of their forces, a soft constraint being no
spring): its joint limits, its own contacts (the humanoid's limbs touching
each other, which MSF does not carry; every contact of the built-in
variant), the rest. A rest step that raises it beyond its bound
(``REST_GAIN_RTOL``) is energy the account does not explain: counted in the
record (``*_rest_unexplained_steps``, the largest ``*_rest_unexplained_max_J``)
and warned on stderr.
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


def _variant(name: str, msf: bool, mu=None):
    import mujoco
    import pybullet_data

    from engines.mujoco import MujocoAdapter
    from engines.mujoco.robots import load_with_msf_floor
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", name)
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")), mu=mu)
    if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:  # the module docstring
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    if not msf:  # the same model with MuJoCo's own contact: no exclusion
        model.exclude_signature[:] = -1
        return model, data, None
    return model, data, MujocoAdapter(model, data, pairs)


def measure(name: str, steps: int) -> dict:
    import contextlib

    import mujoco

    from engines.mujoco import installed
    from engines.mujoco.robots import RestEnergy

    out = {"name": "robots", "engine": "mujoco", "model": name, "n_bodies": None}
    for mode in ("msf", "builtin"):
        model, data, adapter = _variant(name, mode == "msf")
        out["integrator"] = int(model.opt.integrator)
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
            account = RestEnergy(model, data, adapter)
            E = [account.total]
            for _ in range(steps):
                mujoco.mj_step(model, data)
                E.append(account.update())
        E = np.array(E)
        out[f"{mode}_rest_energy_J"] = [float(E[0]), float(E[-1])]
        out[f"{mode}_rest_energy_rise_J"] = float(np.max(E - E[0]))
        out[f"{mode}_rest_step_rise_max_J"] = float(np.max(np.diff(E)))
        out[f"{mode}_rest_limits_absorbed_J"] = account.absorbed_by["limits"]
        out[f"{mode}_rest_own_contacts_absorbed_J"] = account.absorbed_by["contacts"]
        out[f"{mode}_rest_constraints_absorbed_J"] = account.absorbed
        out[f"{mode}_rest_unexplained_steps"] = len(account.gains)
        out[f"{mode}_rest_unexplained_max_J"] = max((g[1] for g in account.gains), default=0.0)
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


#: the torque seeds of the rest sweep (rest_sweep): the bench's own SEED is measure()'s
SWEEP_SEEDS = (1, 2, 3, 4)


def rest_sweep(name: str, seed: int, steps: int = STEPS, mu=None) -> dict:
    """MSF only: ``steps`` of torques seeded ``seed`` (as :func:`measure`),
    then ``steps`` at rest under RestEnergy: the rest steps above its bound
    and the largest such rise and excess over the bound [J], the account at
    the rest's start and end [J] (issue 13: no rest step above the bound
    across torque seeds). mu: the feet's Coulomb cap (load_with_msf_floor's)."""
    import warnings

    import mujoco

    from engines.mujoco import installed
    from engines.mujoco.robots import RestEnergy

    model, data, adapter = _variant(name, True, mu)
    rng = np.random.default_rng(seed)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # counted below; the bench's own run shows the warnings
        with installed(adapter):
            for _ in range(steps):
                data.ctrl[:] = rng.uniform(lo, hi)
                mujoco.mj_step(model, data)
            data.ctrl[:] = 0.0
            account = RestEnergy(model, data, adapter)
            start = account.total
            for _ in range(steps):
                mujoco.mj_step(model, data)
                account.update()
    return {"name": "robots-rest-sweep", "engine": "mujoco", "model": name, "seed": seed, "steps": steps,
            "rest_energy_J": [start, account.total], "rest_unexplained_steps": len(account.gains),
            "rest_unexplained_max_J": max((g[1] for g in account.gains), default=0.0),
            "rest_excess_max_J": max((g[1] - g[2] for g in account.gains), default=0.0), "mu": mu,
            "rest_unexplained_first": [list(g) for g in account.gains[:3]], "jumps": adapter.jumps}


#: the gymnasium walkers of :func:`walker_rest` (their own XML, time step, frame_skip and integrator)
WALKERS = ("Ant-v5", "Humanoid-v5", "Walker2d-v5", "HalfCheetah-v5")
#: walker_rest's env steps of seeded random actions, then of zero actions, and its action seed
WALKER_STEPS, WALKER_SEED = 200, 5


def walker_rest(name: str, steps: int = WALKER_STEPS, seed: int = WALKER_SEED) -> dict:
    """A gymnasium walker as a user runs it, MSF on every body-floor pair
    (scripts/gym_check.py's ``gym_msf``) against MuJoCo's own contact:
    ``steps`` env steps of seeded random actions in [-1, 1], then ``steps``
    of zero actions (the walker comes to rest, lying or standing). The CPU
    time (``time.process_time``) per ``mj_step`` (env step / frame_skip),
    medians over each phase: what an RL user pays per step moving and at
    rest. Not profiled: cProfile multiplies the resting step's cost (many
    small Python calls) about fourfold (docs/benchmarks.md, robots)."""
    import warnings

    from engines.mujoco import MujocoAdapter, installed
    from scripts.gym_check import gym_msf

    out = {"name": "robots-walker-rest", "engine": "mujoco", "model": name, "steps": steps, "seed": seed}
    for mode in ("msf", "builtin"):
        env, model, data, pairs = gym_msf(name)
        adapter = None
        if mode == "msf":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the adapter's notes on the model (RK4 on links): not timed
                adapter = MujocoAdapter(model, data, pairs)
        rng = np.random.default_rng(seed)
        per = np.empty(2 * steps)
        with installed(adapter) if adapter is not None else _nothing():
            for i in range(2 * steps):
                a = rng.uniform(-1.0, 1.0, env.action_space.shape) if i < steps else np.zeros(env.action_space.shape)
                t = time.process_time()
                env.step(a)
                per[i] = time.process_time() - t
        per /= env.unwrapped.frame_skip
        out[f"{mode}_moving_step_median_s"] = float(np.median(per[:steps]))
        out[f"{mode}_rest_step_median_s"] = float(np.median(per[steps:]))
        out[f"{mode}_rest_step_mean_s"] = float(np.mean(per[steps:]))
        if adapter is not None:
            out["msf_records"] = len(adapter.records)
        env.close()
    out["dt"], out["frame_skip"] = float(model.opt.timestep), int(env.unwrapped.frame_skip)
    out["ratio_rest_msf_over_builtin"] = out["msf_rest_step_median_s"] / out["builtin_rest_step_median_s"]
    out["load_avg_1min"] = os.getloadavg()[0]
    return out


def _nothing():
    import contextlib

    return contextlib.nullcontext()


def _describe(r: dict) -> list[str]:
    return [f"  rest (RestEnergy): msf {r['msf_rest_energy_J'][0]:.4g} -> {r['msf_rest_energy_J'][1]:.4g} J, limits took "
            f"{r['msf_rest_limits_absorbed_J']:.3g} J, MuJoCo's own contacts {r['msf_rest_own_contacts_absorbed_J']:.3g} J, "
            f"largest step rise {r['msf_rest_step_rise_max_J']:.3g} J, "
            f"{r['msf_rest_unexplained_steps']} steps above the bound (largest {r['msf_rest_unexplained_max_J']:.3g} J); "
            f"built-in {r['builtin_rest_energy_J'][0]:.4g} -> {r['builtin_rest_energy_J'][1]:.4g} J, "
            f"{r['builtin_rest_unexplained_steps']} steps above (largest {r['builtin_rest_unexplained_max_J']:.3g} J)",
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
        for seed in SWEEP_SEEDS:
            sw = rest_sweep(r["model"], seed, QUICK_STEPS if quick else STEPS)
            log(f"  {r['model']} torque seed {seed}: rest {sw['rest_energy_J'][0]:.4g} -> {sw['rest_energy_J'][1]:.4g} J, "
                f"{sw['rest_unexplained_steps']} steps above the bound (largest {sw['rest_unexplained_max_J']:.3g} J)")
            out.append(sw)
    for name in WALKERS:
        w = walker_rest(name, QUICK_STEPS if quick else WALKER_STEPS)
        log(f"  {name} (gymnasium, MSF on every body-floor pair), CPU per mj_step, medians: MSF moving "
            f"{w['msf_moving_step_median_s'] * 1e3:.2f} ms, at rest {w['msf_rest_step_median_s'] * 1e3:.2f} ms; built-in "
            f"{w['builtin_moving_step_median_s'] * 1e3:.3f} / {w['builtin_rest_step_median_s'] * 1e3:.3f} ms "
            f"(rest ratio {w['ratio_rest_msf_over_builtin']:.0f}, load {w['load_avg_1min']:.1f})")
        out.append(w)
    return out
