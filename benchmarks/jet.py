"""Benchmark 4: the abrasive jet -- impacts per CPU-second and memory against impacts.

Uses ``experiments.scenarios.jet.memory_profile`` (one continuous jet, RSS
at cumulative impact checkpoints) with the configuration
``experiments/configs/jet.toml``. The record gives impacts per CPU-second
over the whole run (what the target is checked against) and after the
first checkpoint (``impacts_per_cpu_s_after_first``: without loading, or
in a fresh checkout compiling, the engines' numba kernels). If the jet scenario or its configuration
is missing, or the run fails, the benchmark records a skip with the reason
instead of failing the whole run.
"""

from __future__ import annotations

from pathlib import Path

from ._common import log

CHECKPOINTS = (10_000, 30_000, 100_000)
QUICK_CHECKPOINTS = (500, 1_000)
TARGET_IMPACTS_PER_CPU_S = 5000.0
MEMORY_RTOL = 0.10
CONFIG = Path(__file__).resolve().parent.parent / "experiments" / "configs" / "jet.toml"


#: Longest reason kept in a skip record (an engine error may print whole arrays).
REASON_CHARS = 300


def _skip(reason: str) -> list[dict]:
    reason = reason if len(reason) <= REASON_CHARS else reason[:REASON_CHARS] + " ..."
    log(f"jet: skipped: {reason}")
    return [{"name": "jet", "engine": None, "n_bodies": None, "dt": None, "skipped": True, "reason": reason}]


def run(quick: bool = False) -> list[dict]:
    try:
        from experiments.config import load_toml
        from experiments.scenarios import jet as J
        memory_profile, spec_from_config = J.memory_profile, J.spec_from_config
    except Exception as exc:  # noqa: BLE001 - any import problem is a skip, reported
        return _skip(f"the jet scenario is not importable ({type(exc).__name__}: {exc})")
    if not CONFIG.is_file():
        return _skip(f"no jet configuration at {CONFIG}")
    try:
        raw, _ = load_toml(CONFIG)
        spec = spec_from_config(J.load(raw, str(CONFIG)))
    except Exception as exc:  # noqa: BLE001
        return _skip(f"{CONFIG.name} does not load ({type(exc).__name__}: {exc})")
    checkpoints = QUICK_CHECKPOINTS if quick else CHECKPOINTS
    out = []
    for engine in ("mujoco", "pybullet"):
        cps = checkpoints if engine == "mujoco" or quick else checkpoints[:2]
        log(f"jet: {engine}, checkpoints {cps}")
        try:
            prof = memory_profile(engine, spec, checkpoints=cps)
        except Exception as exc:  # noqa: BLE001
            out += _skip(f"{engine}: memory_profile failed ({type(exc).__name__}: {exc})")
            continue
        first, last = prof[0], prof[-1]
        growth = (last["rss_kb"] - first["rss_kb"]) / first["rss_kb"]
        rate = last["impacts_per_cpu_s"]
        # after the first checkpoint: without the one-off loading/compiling of the numba kernels
        d_cpu = last["cpu_s"] - first["cpu_s"]
        steady = (last["impacts"] - first["impacts"]) / d_cpu if len(prof) > 1 and d_cpu > 0 else None
        log(f"jet: {engine}: {rate:.0f} impacts per CPU-second"
            + (f" ({steady:.0f} after the first checkpoint)" if steady else "")
            + f", RSS {first['rss_kb']} -> {last['rss_kb']} kB")
        out.append({"name": "jet", "engine": engine, "n_bodies": None, "dt": spec.dt, "impacts": last["impacts"],
                    "impacts_per_cpu_s": rate, "impacts_per_cpu_s_after_first": steady, "rss_growth": growth,
                    "profile": prof,
                    "target_impacts_per_cpu_s": TARGET_IMPACTS_PER_CPU_S if engine == "mujoco" else None,
                    "target_met": (rate >= TARGET_IMPACTS_PER_CPU_S and abs(growth) <= MEMORY_RTOL)
                    if engine == "mujoco" else None,
                    "median": "one continuous run (CPU time of the pool)", "repeats": 1})
    return out
