"""Benchmark 2: the cost of sub-cycling.

One normal impact of a natural-rubber ball (R = 20 mm, 1 m/s) on a steel
plate in each engine, run until the contact has ended: at dt = 1 ms with
the contact sub-cycled inside the step, and at dt = tau/50 (tau from the
reference solver), where an explicit step resolves the contact. Reported:
wall time per simulated millisecond and per step (medians), and both COR
errors against the reference solver (the accuracy is the same or better
for the sub-cycled run: that is what the comparison is for).
"""

from __future__ import annotations

import numpy as np

from ._common import RADIUS, log, median_time, rubber_on_steel

SPEED = 1.0
DT_ROBOTICS = 1e-3
STEPS_PER_CONTACT = 50


def run(quick: bool = False) -> list[dict]:
    from engines.base import get_engine
    from msf_contact import Body, preset, simulate_impact

    law, ball = rubber_on_steel()
    plate = Body.half_space(preset("steel"))
    ref = simulate_impact(law, ball, plate, SPEED)
    dt_fine = ref.tau / STEPS_PER_CONTACT
    repeats = 3 if quick else 7
    out = []
    for engine in ("mujoco", "pybullet"):
        fn = get_engine(engine)
        res = {}
        for label, dt in (("subcycled", DT_ROBOTICS), ("resolved", dt_fine)):
            rec_box = []

            def one(dt=dt):
                rec_box.append(fn(law, ball, plate, SPEED, dt=dt))
            med, _ = median_time(one, repeats)
            rec = rec_box[-1]
            steps = int(rec.inputs.get("steps") or round(rec.inputs["t_end"] / dt) + 1)
            res[label] = {"dt": dt, "wall_s": med, "steps": steps, "sim_s": steps * dt,
                          "cor_n": rec.cor_n, "cor_err": abs(rec.cor_n - ref.cor_n) / ref.cor_n}
        s, r = res["subcycled"], res["resolved"]
        rec = {
            "name": "subcycling", "engine": engine, "n_bodies": 1, "dt": DT_ROBOTICS, "dt_resolved": dt_fine,
            "contact_duration_s": ref.tau, "speed_m_s": SPEED, "radius_m": RADIUS,
            "subcycled_wall_per_sim_ms_s": s["wall_s"] / (s["sim_s"] * 1e3),
            "resolved_wall_per_sim_ms_s": r["wall_s"] / (r["sim_s"] * 1e3),
            "subcycled_step_s": s["wall_s"] / s["steps"], "resolved_step_s": r["wall_s"] / r["steps"],
            "ratio_subcycled_over_resolved_per_sim_time":
                (s["wall_s"] / s["sim_s"]) / (r["wall_s"] / r["sim_s"]),
            "cor_reference": ref.cor_n, "cor_err_subcycled": s["cor_err"], "cor_err_resolved": r["cor_err"],
            "steps_subcycled": s["steps"], "steps_resolved": r["steps"],
            "median": "wall time of one whole impact, median over repeats", "repeats": repeats,
        }
        log(f"subcycling: {engine}: dt 1 ms {s['wall_s'] * 1e3:.1f} ms wall ({s['steps']} steps, COR err "
            f"{s['cor_err']:.1e}); dt {dt_fine:.2e} s {r['wall_s'] * 1e3:.1f} ms wall ({r['steps']} steps, "
            f"COR err {r['cor_err']:.1e})")
        out.append(rec)
    return out


__all__ = ["run", "np"]
