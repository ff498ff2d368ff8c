"""Held links against the engine step (issue 11, item 6): the sweeps whose
numbers docs/engines.md ("Drive-held links") and engines/mujoco/_held.py
quote.

    .venv/bin/python scripts/held_links.py mujoco [--kp 1000,3000,10000] [--integrators euler,rk4,implicitfast]
    .venv/bin/python scripts/held_links.py kuka

``mujoco``: a 0.5 kg paddle on a hinge held by a MuJoCo position servo
(engines.mujoco.scenes.paddle_and_ball, kp [N m/rad]) struck by a natural
rubber ball (R = 20 mm, 2 m/s, 1 mm gap); per kp and integrator the
first-bounce COR at dt = 0.2-2 ms against the 0.1 ms run, with omega dt
(omega = sqrt(kp / M_dd)) and whether the adapter flagged the record.

``kuka``: pybullet_data's KUKA iiwa (kuka_iiwa/model.urdf) holding a paddle
(engines.pybullet.scenes.kuka_paddle): the same ball dropped on it, the
first-bounce COR at 0.2, 0.5, 1, 2 ms and 1/240 s against 0.2 ms, held
by a createConstraint to the arm's flange, and by the arm's own
POSITION_CONTROL motors.
"""

from __future__ import annotations

import argparse
import sys
import warnings

MUJOCO_STEPS = (2e-4, 3e-4, 4e-4, 5e-4, 6e-4, 7e-4, 8e-4, 1e-3, 1.5e-3, 2e-3)
KUKA_STEPS = (2e-4, 5e-4, 1e-3, 2e-3, 1.0 / 240.0)


def _ball_law():
    from msf_contact import Body, ContactPair, Curvature, make_law, preset

    ball = Body.sphere(preset("natural-rubber"), 0.02)
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    return ball, law


def mujoco_strike(dt: float, integrator: str, kp: float):
    """(record or None, omega [rad/s], what failed) of the first bounce."""
    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, run_until_separated, scenes
    from engines.mujoco._held import servos

    ball, law = _ball_law()
    model, data = scenes.paddle_and_ball(ball, 2.0, dt=dt, integrator=integrator, kp=kp, gap=1e-3)
    omega = servos(model, data)[0].omega
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return run_until_separated(MujocoAdapter(model, data, [PairSpec("ball", "paddle", law)]),
                                       100_000), omega, ""
        except Exception as exc:  # noqa: BLE001 - a diverging servo is a result of the sweep
            return None, omega, type(exc).__name__


def sweep_mujoco(kps, integrators) -> None:
    print("| integrator | kp [N m/rad] | omega [rad/s] | dt [ms] | omega dt | COR | vs 0.1 ms | flagged |")
    print("|---|---|---|---|---|---|---|---|")
    for integ in integrators:
        for kp in kps:
            ref, omega, _ = mujoco_strike(1e-4, integ, kp)
            for dt in MUJOCO_STEPS:
                rec, _, failed = mujoco_strike(dt, integ, kp)
                if rec is None:
                    row = f"| {failed} | - | - |"
                else:
                    flag = any(n.startswith("stiff servo") for n in rec.outside_validity)
                    row = f"{rec.cor_n:.4f} | {(rec.cor_n / ref.cor_n - 1) * 100:+.2f} % | {'yes' if flag else 'no'} |"
                print(f"| {integ} | {kp:g} | {omega:.0f} | {dt * 1e3:g} | {omega * dt:.2f} | {row}", flush=True)


def kuka_strike(dt: float, holder: str):
    """The first-bounce record on the KUKA-held paddle (holder: 'constraint' or 'motor')."""
    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter, scenes

    ball, law = _ball_law()
    sc = scenes.kuka_paddle(ball, 2.0, dt=dt, holder=holder, gap=1e-3)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with PybulletAdapter(sc.client, [PairSpec(sc.body1, sc.body2, law)]) as ad:
                for _ in range(int(0.05 / dt) + 1):
                    ad.step()
                    if ad.records:
                        return ad.records[0]
        return None
    finally:
        sc.close()


def sweep_kuka() -> None:
    print("| holder | dt [ms] | steps per contact | COR | vs 0.2 ms | flagged |")
    print("|---|---|---|---|---|---|")
    for holder in ("constraint", "motor"):
        ref = kuka_strike(KUKA_STEPS[0], holder)
        for dt in KUKA_STEPS:
            rec = kuka_strike(dt, holder)
            if rec is None:
                print(f"| {holder} | {dt * 1e3:.3g} | - | no bounce | - | - |")
                continue
            flag = any(n.startswith("held link") for n in rec.outside_validity)
            print(f"| {holder} | {dt * 1e3:.3g} | {rec.tau / dt:.2g} | {rec.cor_n:.4f} | "
                  f"{(rec.cor_n / ref.cor_n - 1) * 100:+.2f} % | {'yes' if flag else 'no'} |", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("which", choices=("mujoco", "kuka"))
    ap.add_argument("--kp", default="100,1000,2000,3000,5000,10000,30000,100000")
    ap.add_argument("--integrators", default="euler,rk4,implicitfast")
    a = ap.parse_args(argv)
    if a.which == "mujoco":
        sweep_mujoco([float(k) for k in a.kp.split(",")], a.integrators.split(","))
    else:
        sweep_kuka()
    return 0


if __name__ == "__main__":
    sys.exit(main())
