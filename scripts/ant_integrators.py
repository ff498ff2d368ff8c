"""pybullet_data's ant (engines.mujoco.robots.load_with_msf_floor, MSF on
every foot-floor pair, natural rubber on steel) under its own RK4 and under
Euler at its own 10 ms step: the numbers docs/engines.md ("Robot models")
quotes.

    .venv/bin/python scripts/ant_integrators.py [--steps 300]

Seeded random torques (uniform in the control range, seed 13) for the first
half of the steps, none after. Per integrator: the step tracker's jumps and
the contacts they interrupted, the impact records and how many are flagged
(outside_validity), the torso height's minimum, maximum and end [m].
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=300)
    a = ap.parse_args(argv)
    print("| integrator | jumps | interrupted | records | flagged | torso z min / max / end [m] |")
    print("|---|---|---|---|---|---|")
    for integ in ("rk4", "euler"):
        r = run(integ, a.steps)
        print(f"| {integ} | {r['jumps']} | {r['interrupted']} | {r['records']} | {r['flagged']} | "
              f"{r['z_min']:.3f} / {r['z_max']:.3f} / {r['z_end']:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
