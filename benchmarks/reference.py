"""Benchmark 3: the reference solver and the closed forms.

- Time per self-consistent impact: ``msf_contact.solver.simulate_impact``
  of a natural-rubber ball on steel (omega_x solved self-consistently),
  normal and oblique, median over repeats (target: <= 20 ms).
- First call [s] (``first_call_s``), from cold caches: the first
  self-consistent impact of a material builds its onset table
  (``msf_contact._scaling.eps_table``: 15 bracketed roots, ~0.5 s), which
  seeds every later root; the 45 degree series reuses it.
- Closed forms per second: Hertz x_max and tau, (89) COR of tan delta,
  (90) x_max and (95) tau over numpy vectors of cases.
"""

from __future__ import annotations

import time

import numpy as np

from ._common import log, median_time, rubber_on_steel

TARGET_S = 0.020
N_CASES = 1_000_000


def run(quick: bool = False) -> list[dict]:
    from msf_contact import Body, _scaling, preset, simulate_impact
    from msf_contact import closed_forms as cf

    law, ball = rubber_on_steel()
    plate = Body.half_space(preset("steel"))
    repeats = 5 if quick else 21
    out = []
    for cache in (_scaling.eps_table, _scaling.self_consistent, _scaling.self_consistent_bracketed,
                  _scaling.unit_impact):
        cache.cache_clear()  # an earlier benchmark in this process may have built the onset table
    for angle in (90.0, 45.0):
        t0 = time.perf_counter()
        simulate_impact(law, ball, plate, 1.0, angle)  # warm the onset tables
        first = time.perf_counter() - t0
        speeds = iter(np.geomspace(0.3, 3.0, repeats))
        med, all_s = median_time(lambda: simulate_impact(law, ball, plate, float(next(speeds)), angle), repeats)
        log(f"reference: {med * 1e3:.2f} ms per self-consistent impact at {angle} deg "
            f"(first call {first * 1e3:.0f} ms)")
        out.append({"name": "reference_impact", "engine": "reference", "n_bodies": 1, "dt": None,
                    "angle_deg": angle, "time_per_impact_s": med, "target_s": TARGET_S,
                    "target_met": bool(med <= TARGET_S), "median": "median over speeds 0.3-3 m/s",
                    "repeats": repeats, "first_call_s": first})
    n = 100_000 if quick else N_CASES
    rng = np.random.default_rng(0)
    m = rng.uniform(1e-3, 1.0, n)
    V = rng.uniform(0.1, 10.0, n)
    E = rng.uniform(1e6, 1e10, n)
    R = rng.uniform(1e-3, 0.1, n)
    tg = rng.uniform(0.01, 1.0, n)
    cor = rng.uniform(0.1, 0.95, n)
    forms = {
        "hertz_x_max": lambda: cf.hertz_x_max(m, V, E, R),
        "hertz_tau": lambda: cf.hertz_tau(m, V, E, R),
        "cor_89": lambda: cf.cor_89(tg),
        "x_max_90": lambda: cf.x_max_90(m, V, E, tg, R, 1.0),
        "tau_95": lambda: cf.tau_95(m, V, E, R, 1.0, cor),
    }
    for name, f in forms.items():
        med, _ = median_time(f, 5)
        out.append({"name": "closed_form", "engine": "closed-form", "n_bodies": n, "dt": None, "function": name,
                    "cases": n, "cases_per_s": n / med, "median": "median of 5 vector calls", "repeats": 5})
        log(f"closed form {name}: {n / med:.3g} cases/s")
    return out
