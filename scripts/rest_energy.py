"""A robot from pybullet_data/mjcf at rest in MuJoCo, in a user's own
``mj_step`` loop: the energy account of engines.mujoco.robots.RestEnergy
(kinetic + gravitational + the MSF contacts' stored energy + the energy
MuJoCo's constraints took, the work of their forces: its joint limits and
its own contacts between the robot's limbs) and, per joint-limit episode
(from a limit row's first force to its release), the work the limit did:
the numbers docs/engines.md ("Robot models", MuJoCo's joint limits) quotes.

    .venv/bin/python scripts/rest_energy.py humanoid.xml --torque-steps 200 --rest-steps 600 --seed 3 --unit-controls
    .venv/bin/python scripts/rest_energy.py ant.xml --torque-steps 1000 --rest-steps 1000 --builtin

Seeded random controls for the torque steps (uniform in each actuator's
control range, or in [-1, 1] with ``--unit-controls`` as a user's loop
might: MuJoCo clamps them), none after. RK4 models run under Euler at
their own time step (RestEnergy refuses RK4). ``--builtin``: MuJoCo's own
contact instead of MSF. ``--resting-apart``: the manager's rule before
issue 13's fix, for comparison (ContactManager.set_together with no pair:
a body whose contacts all rest has them stepped one by one, each with the
others' held forces a step late, instead of in its island). Printed: the
account at the start and end of the rest phase, its largest one-step
change, the steps it rose beyond its bound (RestEnergy.gains), the energy
the limits and MuJoCo's own contacts took; the limit episodes that ended
in each phase, how many gave back more energy than they took and how
much.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import RestEnergy, limit_force, load_with_msf_floor
    from msf_contact import ContactPair, preset

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", help="a file of pybullet_data/mjcf, e.g. ant.xml, humanoid.xml")
    ap.add_argument("--torque-steps", type=int, default=200)
    ap.add_argument("--rest-steps", type=int, default=600)
    ap.add_argument("--seed", type=int, default=13)
    ap.add_argument("--unit-controls", action="store_true")
    ap.add_argument("--builtin", action="store_true")
    ap.add_argument("--resting-apart", action="store_true",
                    help="the rule before issue 13's fix: a body whose contacts all rest has them stepped one by one "
                         "with the others' held forces a step late, not in its island")
    a = ap.parse_args(argv)
    model, data, pairs = load_with_msf_floor(os.path.join(pybullet_data.getDataPath(), "mjcf", a.model),
                                             ContactPair(preset("natural-rubber"), preset("steel")))
    if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    if a.builtin:
        model.exclude_signature[:] = -1
    adapter = None if a.builtin else MujocoAdapter(model, data, pairs)
    if a.resting_apart and adapter is not None:
        adapter.manager.set_together(np.zeros(len(adapter.manager.pairs), bool))
    rng = np.random.default_rng(a.seed)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    h = model.opt.timestep
    episode, began, ended = np.zeros(model.nv), np.zeros(model.nv, int), []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with installed(adapter) if adapter is not None else contextlib.nullcontext():
            account = None
            for k in range(a.torque_steps + a.rest_steps):
                if k == a.torque_steps:
                    data.ctrl[:] = 0.0
                    account = RestEnergy(model, data, adapter)
                    E = [account.total]
                elif k < a.torque_steps:
                    data.ctrl[:] = rng.uniform(-1.0, 1.0, model.nu) if a.unit_controls else rng.uniform(lo, hi)
                v0 = data.qvel - (adapter.velocity_offset() if adapter is not None else 0.0)
                mujoco.mj_step(model, data)
                v1 = data.qvel - (adapter.velocity_offset() if adapter is not None else 0.0)
                f = limit_force(model, data)
                work = h * f * 0.5 * (v0 + v1)  # RestEnergy's work of the limits, per dof
                on = f != 0.0
                for j in np.flatnonzero(~on & (episode != 0.0)):
                    ended.append((int(began[j]) >= a.torque_steps, float(episode[j])))
                episode[~on] = 0.0
                began[on & (episode == 0.0)] = k
                episode[on] += work[on]
                if account is not None:
                    E.append(account.update())
    E = np.array(E)
    print(f"{a.model}, {'built-in contact' if a.builtin else 'MSF'}, dt = {h:g} s: rest {a.rest_steps} steps: account "
          f"{E[0]:.4f} -> {E[-1]:.4f} J, largest one-step change {np.diff(E).max():.4g} J, steps above the bound "
          f"{len(account.gains)} (largest {max((g[1] for g in account.gains), default=0.0):.3g} J), the limits took "
          f"{account.absorbed_by['limits']:.4g} J, MuJoCo's own contacts {account.absorbed_by['contacts']:.4g} J")
    for rest, label in ((False, "torques"), (True, "rest")):
        W = np.array([w for r, w in ended if r == rest])
        print(f"  limit episodes begun and ended under {label}: {W.size}, net work of the limits {W.sum():.4g} J; "
              f"{int((W > 0).sum())} gave back more than they took ({W[W > 0].sum():.4g} J, largest "
              f"{W.max(initial=0.0):.4g} J)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
