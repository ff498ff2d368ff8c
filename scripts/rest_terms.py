"""Where a rest step's rise of engines.mujoco.robots.RestEnergy's account
comes from (issue 13): a model of pybullet_data/mjcf under seeded torques
(as benchmarks/robots.py: uniform in the control ranges, or in [-1, 1] with
``--unit-controls``), then at rest, and each rest step's rise split into
the terms of MuJoCo's step (J):

- ``grav``: the gravitational and joint springs' potential energy's change
  plus the work their forces (at the step start) did on the mid-step
  velocity, dU + h F . v_mid: the semi-implicit Euler term the bound
  allows as (h/2)|P_end - P_start| (``bound_term``, P = F . v);
- ``offset``: its part from the timing corrections' displacement, -h F .
  o_end (the positions advance by qvel, which carries the corrections'
  offset o, ``MujocoAdapter.velocity_offset``; the account works with the
  physical velocities qvel - o);
- ``coriolis``: the kinetic energy's change from M(q) over the step less
  the bias forces' work, 1/2 v' (M' - M) v' + h Q_bias,v . v_mid (~0);
- ``damping``: the joint dampers' work with MuJoCo's implicit Euler
  damping, h (M (v' - v)/h - qfrc_smooth - qfrc_constraint + qfrc_damper) .
  v_mid (<= 0);
- ``contacts``: the MSF contacts' own balance, the change of their stored
  energy (``ContactManager.stored_energy``) plus the work their applied
  generalised force did, dS + h Q_msf . v_mid (<= 0 when their internal
  motion is the engine's: their viscous and slip losses);
- ``constraints``: MuJoCo's constraints' work plus what RestEnergy booked
  for them (0 to round-off: booked exactly).

Their sum is the rise to second order in the step (printed: the largest
|rise - sum| over the steps above the bound; ~1e-9 J at rest).
Printed: the steps above the bound with their terms, each term summed over
every rest step, and how many rest steps had the contacts' balance above
1e-3 of the kinetic energy.

    .venv/bin/python scripts/rest_terms.py humanoid.xml --seed 13
    .venv/bin/python scripts/rest_terms.py ant.xml --seed 4 --rest-steps 200
    .venv/bin/python scripts/rest_terms.py HalfCheetah-v5 --seed 2 --torque-steps 150 --rest-steps 300

A gymnasium environment (a name without ``.xml``) is run as
scripts/gym_check.py runs it (its XML and dt, MSF on every floor pair, the
actions uniform in [-1, 1] through ``env.step``; Euler in place of its RK4
as for the files, and --torque-steps and --rest-steps counted in env steps).
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

TERMS = ("grav", "offset", "coriolis", "damping", "contacts", "constraints")


def _potential(model, s, qpos, qvel):
    """(M (nv, nv), U [J], F (nv,) generalised gravity + joint-spring force [N or N m],
    Q_bias,v (nv,) the velocity part of the bias force) at (qpos, qvel) on scratch s."""
    import mujoco
    import numpy as np

    from engines.mujoco.robots import _mechanical, passive_without_hook

    s.qpos[:], s.qvel[:] = qpos, 0.0
    mujoco.mj_kinematics(model, s)
    mujoco.mj_comPos(model, s)
    mujoco.mj_makeM(model, s)
    mujoco.mj_comVel(model, s)
    g = np.zeros(model.nv)
    mujoco.mj_rne(model, s, 0, g)
    s.qvel[:] = qvel
    mujoco.mj_comVel(model, s)
    b = np.zeros(model.nv)
    mujoco.mj_rne(model, s, 0, b)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, s, M)
    passive_without_hook(model, s)
    T, U, _ = _mechanical(model, s, qvel)
    return M, U, -g + s.qfrc_spring, -(b - g)


def main(argv=None) -> int:
    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import REST_GAIN_RTOL, RestEnergy, load_with_msf_floor
    from msf_contact import ContactPair, preset

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", help="a file of pybullet_data/mjcf, e.g. ant.xml, humanoid.xml, or a gymnasium "
                    "environment, e.g. HalfCheetah-v5")
    ap.add_argument("--torque-steps", type=int, default=1000)
    ap.add_argument("--rest-steps", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=13)
    ap.add_argument("--unit-controls", action="store_true")
    ap.add_argument("--show", type=int, default=20, help="steps above the bound printed")
    a = ap.parse_args(argv)
    env = None
    if a.model.endswith(".xml"):
        model, data, pairs = load_with_msf_floor(os.path.join(pybullet_data.getDataPath(), "mjcf", a.model),
                                                 ContactPair(preset("natural-rubber"), preset("steel")))
    else:
        from gym_check import gym_msf

        env, model, data, pairs = gym_msf(a.model)
        a.rest_steps *= env.unwrapped.frame_skip
    if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:  # RestEnergy reads RK4 through the adapter; the
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER  # split is Euler's, as benchmarks/robots.py runs
    adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(a.seed)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    h = float(model.opt.timestep)
    s = mujoco.MjData(model)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with installed(adapter):
            for _ in range(a.torque_steps):
                if env is not None:  # as scripts/gym_check.py
                    env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
                    continue
                data.ctrl[:] = rng.uniform(-1.0, 1.0, model.nu) if a.unit_controls else rng.uniform(lo, hi)
                mujoco.mj_step(model, data)
            data.ctrl[:] = 0.0
            acc = RestEnergy(model, data, adapter)
            for k in range(a.rest_steps):
                raw0 = data.qvel.copy()
                q0, v0 = data.qpos.copy(), raw0 - adapter.velocity_offset()
                M0, U0, F0, C0 = _potential(model, s, q0, v0)
                before, S0, A0, T0, n_gains = acc.total, acc.contacts, acc.absorbed, acc.kinetic, len(acc.gains)
                mujoco.mj_step(model, data)
                acc.update()
                o1 = adapter.velocity_offset()
                v1 = data.qvel - o1
                M1, U1, _, _ = _potential(model, s, data.qpos, v1)
                vm = 0.5 * (v0 + v1)
                implicit = M0 @ (data.qvel - raw0) / h - data.qfrc_smooth - data.qfrc_constraint
                t = {"grav": U1 - U0 + h * F0 @ vm, "offset": -h * F0 @ o1,
                     "coriolis": 0.5 * v1 @ (M1 - M0) @ v1 + h * C0 @ vm,
                     "damping": h * (data.qfrc_damper + implicit) @ vm,
                     "contacts": acc.contacts - S0 + h * adapter._known._contacts @ vm,
                     "constraints": h * data.qfrc_constraint @ vm + acc.absorbed - A0}
                rise = acc.total - before
                rows.append((k + 1, rise, T0, len(acc.gains) > n_gains, acc.gains[-1][2] if len(acc.gains) > n_gains
                             else None, t))
    above = [r for r in rows if r[3]]
    # second order in the step: exact to round-off at rest, not while the limbs still swing after the torques
    closure = max((abs(r[1] - (sum(r[5].values()) - r[5]["offset"])) for r in above), default=0.0)
    print(f"{a.model}, seed {a.seed}, dt = {h:g} s, {a.torque_steps} torque steps then {a.rest_steps} at rest: "
          f"{len(above)} rest steps above RestEnergy's bound (largest {max((r[1] for r in above), default=0.0):.3g} "
          f"J; the terms close their rises to {closure:.2g} J); the contacts' balance above {REST_GAIN_RTOL:g} of the "
          f"kinetic energy in {sum(r[5]['contacts'] > REST_GAIN_RTOL * r[2] for r in rows)} rest steps")
    print("  summed over every rest step: " + ", ".join(f"{n} {sum(r[5][n] for r in rows):.3g}" for n in TERMS)
          + f" J; contacts + offset over the steps above the bound {sum(r[5]['contacts'] + r[5]['offset'] for r in above):.3g} J")
    for k, rise, T0, _, allowed, t in above[:a.show]:
        print(f"  step {k}: rise {rise:.3g} J, allowed {allowed:.3g} J, kinetic {T0:.3g} J; "
              + ", ".join(f"{n} {t[n]:.3g}" for n in TERMS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
