"""A damped link's impact at a large step (issue 13): a hinged arm (0.2 m,
a 10 mm natural-rubber tip on a steel floor, gravity off) swinging into the
floor at 1 m/s with joint damping B, under MuJoCo's Euler (its damping
implicit: (M + h B) qacc = f) at dt = 10 ms and 1 ms, MSF on the tip.

Printed per (B, dt): h B / I (I the arm's inertia about the hinge), the
record's COR and x_max, the arm's angular speed 50 ms after the start
(physical: ``velocity_offset`` taken out) and RestEnergy's steps above its
bound with the largest excess, and whether the record is flagged
(engines.mujoco.adapter.DAMPED_SHARE_MIN). With the contacts' inverse inertia the
step's own response, W = J (M + h B)^-1 M M^-1 J^T (engines.mujoco._known.
StepResponse), the implicit damper acts on the impact as added inertia h B
(no loss) while a_ext holds its force -B v at the step's start: at 10 ms
the contact goes deeper and gives back more as B grows, where at 1 ms
(converged) the damper takes energy during the contact.

    .venv/bin/python scripts/damped_impact.py
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def run(B: float, dt: float, r: float = 0.01, l: float = 0.2, v: float = 1.0, duration: float = 0.05) -> dict:
    import mujoco
    import numpy as np

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import RestEnergy
    from msf_contact import ContactPair, Curvature, make_law, preset

    xml = (f'<mujoco><option timestep="{dt}" integrator="Euler" gravity="0 0 0"/><worldbody>'
           '<geom name="floor" type="plane" size="1 1 0.1"/>'
           f'<body name="arm" pos="0 0 {r + 1e-3}"><joint name="h" type="hinge" axis="0 1 0" damping="{B}"/>'
           f'<geom name="rod" type="capsule" fromto="0 0 0 {l - r} 0 0" size="0.002" mass="0.2" contype="0" '
           'conaffinity="0"/>'
           f'<geom name="tip" type="sphere" pos="{l} 0 0" size="{r}" mass="0.05"/>'
           '</body></worldbody><contact><exclude body1="world" body2="arm"/></contact></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[0] = v / l  # about +y: the tip moves down
    mujoco.mj_forward(m, d)
    M = np.zeros((1, 1))
    mujoco.mj_fullM(m, d, M)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(r))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # RestEnergy warns its first step above the bound: counted below
        adapter = MujocoAdapter(m, d, [PairSpec("tip", "floor", law)])
        with installed(adapter):
            acc = RestEnergy(m, d, adapter)
            for _ in range(round(duration / dt)):
                mujoco.mj_step(m, d)
                acc.update()
    rec = adapter.records[0] if adapter.records else None
    return {"B": B, "dt": dt, "hB_over_I": dt * B / float(M[0, 0]), "cor": rec.cor_n if rec else float("nan"),
            "x_max": rec.x_max if rec else float("nan"), "omega_out": -float(d.qvel[0] - adapter.velocity_offset()[0]),
            "gains": len(acc.gains), "excess": max((g[1] - g[2] for g in acc.gains), default=0.0),
            "damped_onsets": adapter.damped_onsets,
            "flagged": bool(rec and any("damped link" in n for n in rec.outside_validity))}


def main() -> int:
    print("| B [N m s] | dt [ms] | h B / I | COR | x_max [mm] | omega at 50 ms [rad/s] | steps above the bound (largest excess [J]) | flagged |")
    print("|---|---|---|---|---|---|---|---|")
    for B in (0.0, 0.1, 0.2, 0.5, 1.0):
        for dt in (0.01, 0.001):
            o = run(B, dt)
            print(f"| {B:g} | {dt * 1e3:g} | {o['hB_over_I']:.2f} | {o['cor']:.3f} | {o['x_max'] * 1e3:.3f} | "
                  f"{o['omega_out']:.3f} | {o['gains']} ({o['excess']:.3g}) | {'yes' if o['flagged'] else 'no'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
