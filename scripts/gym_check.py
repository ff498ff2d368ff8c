"""A gymnasium MuJoCo environment as a user would run it (its own XML, time
step, frame_skip and integrator, stepped by ``env.step``), with MSF on every
body-floor pair: natural rubber on steel, each geom's law from its first
size (``Curvature.sphere_on_plane(geom_size[0])``, as tests/test_gymnasium_ant.py
does; a capsule's side takes the line law from the geometry). Seeded random
actions in [-1, 1] for ``--torque-steps`` env steps, then zero actions for
``--rest-steps``, through which the energy account
``engines.mujoco.robots.RestEnergy`` is read after every ``mj_step`` (kinetic
+ gravitational + the contacts' stored energy + the work of MuJoCo's
constraints; under RK4 it needs the MSF adapter, so ``--builtin`` prints no
account unless ``--euler``).

    .venv/bin/python scripts/gym_check.py Ant-v5 --torque-steps 300 --rest-steps 200
    .venv/bin/python scripts/gym_check.py Walker2d-v5 --euler --torque-steps 150 --rest-steps 300
    .venv/bin/python scripts/gym_check.py Hopper-v5 --builtin --euler
    .venv/bin/python scripts/gym_check.py HalfCheetah-v5 --mu engine --seed 2

``--mu``: the feet's Coulomb cap (none, the paper's law, by default; engine:
the friction MuJoCo's own contact gives each pair; or a number).

Printed: CPU seconds of the env steps, the root height's range, MuJoCo's
bad-acceleration count, the records and how many are flagged (with their
notes' kinds), the rest account's start and end, the steps above its bound
(``RestEnergy.gains``), the largest rise among them and the largest excess
over the bound (rise - allowed) with its step. The two differ: in a step
where the walker still lands on its feet the bound's semi-implicit term
(dt/2 |P_end - P_start| of gravity and the joint springs) is most of the rise
(HalfCheetah-v5 seed 1: a rise of 0.61 J of which 0.598 J allowed). Nothing
is written.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: planar walkers keep their height in qpos[1] (rootx, rootz, rooty); free-joint robots in qpos[2]
PLANAR = ("Hopper", "Walker2d", "HalfCheetah")


def gym_msf(name: str, mu=None):
    """(env, model, data, pairs): the gymnasium environment ``name`` reset with
    seed 0 and MSF on every body-floor pair (module docstring; mu: the feet's
    Coulomb cap, None (the paper's law), a number, or engines.mujoco.robots.
    ENGINE_FRICTION for MuJoCo's own friction of each pair). ValueError if it
    has no plane geom."""
    import gymnasium as gym
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco.robots import ENGINE_FRICTION, engine_friction
    from msf_contact import ContactPair, Curvature, make_law, preset

    kw = {} if name.startswith(("HalfCheetah", "Swimmer")) else {"terminate_when_unhealthy": False}
    env = gym.make(name, **kw)
    env.reset(seed=0)
    model, data = env.unwrapped.model, env.unwrapped.data
    planes = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE]
    if not planes:
        raise ValueError(f"{name} has no plane geom to put MSF on")
    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    pairs = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != 0 and model.geom(g).name and (model.geom_contype[g] or model.geom_conaffinity[g]):
            m = engine_friction(model, g, planes[0]) if mu == ENGINE_FRICTION else mu
            pairs.append(PairSpec(model.geom(g).name, model.geom(planes[0]).name,
                                  make_law("msf", pair, Curvature.sphere_on_plane(float(model.geom_size[g, 0])), mu=m)))
    return env, model, data, pairs


def main(argv=None) -> int:
    import mujoco
    import numpy as np

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import RestEnergy

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env", help="a gymnasium MuJoCo environment, e.g. Ant-v5, Hopper-v5, Walker2d-v5, HalfCheetah-v5")
    ap.add_argument("--torque-steps", type=int, default=300, help="env steps of seeded random actions")
    ap.add_argument("--rest-steps", type=int, default=200, help="env steps of zero actions after them")
    ap.add_argument("--seed", type=int, default=1, help="seed of the actions (the env is reset with seed 0)")
    ap.add_argument("--builtin", action="store_true", help="MuJoCo's own contact instead of MSF")
    ap.add_argument("--euler", action="store_true", help="run under Euler instead of the env's integrator")
    ap.add_argument("--mu", default="none", help="the feet's Coulomb cap: none (the paper's law), engine (MuJoCo's "
                    "own friction of each pair) or a number")
    a = ap.parse_args(argv)
    for name in ("torque_steps", "rest_steps"):
        if getattr(a, name) < 0:
            ap.error(f"--{name.replace('_', '-')} = {getattr(a, name)} must be >= 0")
    if a.torque_steps + a.rest_steps == 0:
        ap.error("--torque-steps + --rest-steps = 0: nothing to run")

    try:
        env, model, data, pairs = gym_msf(a.env, None if a.mu == "none" else a.mu if a.mu == "engine" else float(a.mu))
    except ValueError as exc:
        ap.error(str(exc))
    if a.euler:
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    z_index = 1 if a.env.startswith(PLANAR) else 2
    print(f"{a.env}: dt = {model.opt.timestep:g} s, frame_skip {env.unwrapped.frame_skip}, integrator "
          f"{mujoco.mjtIntegrator(model.opt.integrator).name}, {'built-in contact' if a.builtin else 'MSF'} "
          f"on {len(pairs)} floor pairs")
    rng = np.random.default_rng(a.seed)
    height, E = [], []
    account = None
    cpu = 0.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        adapter = None if a.builtin else MujocoAdapter(model, data, pairs)
        with installed(adapter) if adapter is not None else contextlib.nullcontext():
            t0 = time.process_time()
            for i in range(a.torque_steps):
                env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
                height.append(float(data.qpos[z_index]))
            cpu += time.process_time() - t0
            data.ctrl[:] = 0.0
            readable = adapter is not None or model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
            if readable:
                account = RestEnergy(model, data, adapter)
                E.append(account.total)
            zero = np.zeros(env.action_space.shape)
            for i in range(a.rest_steps):
                t0 = time.process_time()
                if account is None:
                    env.step(zero)
                else:  # the env step's mj_steps one by one, the account read after each
                    for _ in range(env.unwrapped.frame_skip):
                        mujoco.mj_step(model, data)
                        E.append(account.update())
                cpu += time.process_time() - t0
                height.append(float(data.qpos[z_index]))
    env.close()
    print(f"CPU {cpu:.3f} s; root height {min(height):.4f} .. {max(height):.4f} m, last {height[-1]:.4f} m; "
          f"finite {bool(np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel)))}; bad-acceleration "
          f"resets {data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number}")
    if adapter is not None:
        kinds = Counter(re.sub(r"\d[\d.e+-]*", "#", note.split(":")[0].split(" (")[0])[:60]
                        for r in adapter.records for note in r.outside_validity)
        flagged = sum(1 for r in adapter.records if r.outside_validity)
        print(f"records {len(adapter.records)}, flagged {flagged}: {dict(kinds)}")
    if account is not None:
        E = np.array(E)
        over = max(account.gains, key=lambda g: g[1] - g[2], default=(0, 0.0, 0.0))
        print(f"rest account {E[0]:.4f} -> {E[-1]:.4f} J over {E.size - 1} mj_steps; steps above the bound "
              f"{len(account.gains)}, largest rise {max((g[1] for g in account.gains), default=0.0):.3g} J; "
              f"largest excess over the bound {over[1] - over[2]:.3g} J (rest mj_step {over[0]}: rise {over[1]:.3g} "
              f"J, allowed {over[2]:.3g} J)")
    else:
        print("rest account: not read (RK4 without the MSF adapter; add --euler)")
    print(f"warnings {len(caught)}")
    for w in caught[:6]:
        print("  ", str(w.message)[:240])
    return 0


if __name__ == "__main__":
    sys.exit(main())
