"""pybullet_data's ant (engines.mujoco.robots.load_with_msf_floor, MSF on
every foot-floor pair, natural rubber on steel) under its own RK4 and under
Euler at its own 10 ms step: the numbers docs/engines.md ("Robot models")
quotes.

    .venv/bin/python scripts/ant_integrators.py [--steps 300]
    .venv/bin/python scripts/ant_integrators.py --rest [--torque-steps 60 --rest-steps 300]
    .venv/bin/python scripts/ant_integrators.py --deep [--substeps 1 2 4]

Seeded random torques (uniform in the control range, seed 13) for the first
half of the steps, none after. Per integrator: the step tracker's jumps and
the contacts they interrupted, the impact records and how many are flagged
(outside_validity), the torso height's minimum, maximum and end [m].

``--rest``: after the torques, the energy at rest (kinetic of the physical
velocities + gravity + the contacts' stored energy, robots.mechanical_energy)
without and (Euler only: RK4 keeps no record of its stages' limit forces)
with the energy the joint limits took, the work of their forces
(robots.RestEnergy): over the rest phase after its first fifth, the steps
where it rises by more than 1 uJ, the largest rise, and how many of the
rising steps had a contact found deep at its onset (flagged,
MujocoAdapter.deep_onsets) and the rise they carry.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings


def run(integrator: str, steps: int) -> dict:
    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import load_with_msf_floor
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(13)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    z = []
    with installed(adapter), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(steps):
            data.ctrl[:] = rng.uniform(lo, hi) if i < steps // 2 else 0.0
            mujoco.mj_step(model, data)
            z.append(float(data.qpos[2]))
    recs = adapter.records
    return {"integrator": integrator, "jumps": adapter.jumps, "interrupted": adapter.interrupted,
            "records": len(recs), "flagged": sum(1 for r in recs if r.outside_validity),
            "z_min": min(z), "z_max": max(z), "z_end": z[-1]}


def deep(integrator: str, substeps: int) -> str:
    """1,000 torques of the seeded sequence, each held for 10 ms, at the
    time step 10 ms / substeps, then 10 s at rest: a table row of the
    impacts, those flagged, the contacts found deep at their onset (under
    the torques) and the torso's highest point [m]."""
    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import load_with_msf_floor
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    model.opt.timestep = 0.01 / substeps
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        adapter = MujocoAdapter(model, data, pairs)
        rng = np.random.default_rng(13)
        lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
        z_max = 0.0
        with installed(adapter):
            for _ in range(1000):
                data.ctrl[:] = rng.uniform(lo, hi)
                for _ in range(substeps):
                    mujoco.mj_step(model, data)
                    z_max = max(z_max, float(data.qpos[2]))
            under = adapter.deep_onsets
            data.ctrl[:] = 0.0
            for _ in range(1000 * substeps):
                mujoco.mj_step(model, data)
                z_max = max(z_max, float(data.qpos[2]))
    recs = adapter.records
    return (f"| {integrator} | {1e3 * model.opt.timestep:g} | {len(recs)} | "
            f"{sum(1 for r in recs if r.outside_validity)} | {adapter.deep_onsets} ({under}) | {z_max:.3f} |")


def rest(integrator: str, torque_steps: int, rest_steps: int) -> None:
    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import RestEnergy, load_with_msf_floor, mechanical_energy
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        adapter = MujocoAdapter(model, data, pairs)
        rng = np.random.default_rng(13)
        lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
        E = {False: [], True: []}
        deep = []
        with installed(adapter):
            for _ in range(torque_steps):
                data.ctrl[:] = rng.uniform(lo, hi)
                mujoco.mj_step(model, data)
            data.ctrl[:] = 0.0
            account = RestEnergy(model, data, adapter)
            for _ in range(rest_steps):
                mujoco.mj_step(model, data)
                E[False].append(mechanical_energy(model, data, data.qvel - adapter.velocity_offset())
                                + adapter.manager.stored_energy())
                if account is not None:
                    E[True].append(account.update())
                deep.append(adapter.deep_onsets)
    s0 = rest_steps // 5
    new_deep = np.diff(np.array(deep[s0:])) > 0
    for lim in (False, True):
        if not E[lim]:
            continue
        d = np.diff(np.array(E[lim][s0:]))
        up = d > 1e-6
        print(f"| {integrator} | {'with' if lim else 'without'} | {int(up.sum())} of {d.size} | "
              f"{1e3 * float(d.max()):.3g} | {int((up & new_deep).sum())} ({1e3 * float(d[up & new_deep].sum()):.4g} mJ) |",
              flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rest", action="store_true", help="the energy at rest, with and without the limits")
    ap.add_argument("--torque-steps", type=int, default=60)
    ap.add_argument("--rest-steps", type=int, default=300)
    ap.add_argument("--deep", action="store_true",
                    help="1,000 torques then 10 s at rest: contacts found deep at their onset")
    ap.add_argument("--substeps", type=int, nargs="+", default=[1],
                    help="with --deep: time steps 10 ms / each of these")
    a = ap.parse_args(argv)
    if a.deep:
        bad = [k for k in a.substeps if k < 1]
        if bad:
            ap.error(f"--substeps {bad[0]}: each must be a whole number >= 1")
        print("| integrator | dt [ms] | impacts | flagged | found deep (under the torques) | torso z max [m] |")
        print("|---|---|---|---|---|---|")
        for k in a.substeps:
            for integ in ("rk4", "euler"):
                print(deep(integ, k), flush=True)
        return 0
    if a.rest:
        print("| integrator | limits' energy | steps rising > 1 uJ | largest rise [mJ] | of them with a deep onset |")
        print("|---|---|---|---|---|")
        for integ in ("rk4", "euler"):
            rest(integ, a.torque_steps, a.rest_steps)
        return 0
    print("| integrator | jumps | interrupted | records | flagged | torso z min / max / end [m] |")
    print("|---|---|---|---|---|---|")
    for integ in ("rk4", "euler"):
        r = run(integ, a.steps)
        print(f"| {integ} | {r['jumps']} | {r['interrupted']} | {r['records']} | {r['flagged']} | "
              f"{r['z_min']:.3f} / {r['z_max']:.3f} / {r['z_end']:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
