"""Benchmark 4: the abrasive jet -- impacts per CPU-second and memory against impacts.

Uses ``experiments.scenarios.jet.memory_profile`` (one continuous jet, RSS
at cumulative impact checkpoints) with the configuration
``experiments/configs/jet.toml``. Each engine's profile runs in a fresh
interpreter (a spawned process), so the RSS measures the jet alone and not
what the benchmarks before it left resident (the 10,000-sphere scenes
leave ~1.3 GB, which would dilute any growth), after a short warm-up run
there (WARMUP_IMPACTS: loads, in a fresh checkout compiles, the numba
kernels and builds the onset tables). The record gives impacts per
CPU-second over the whole timed run (what the target is checked against)
and after its first checkpoint (``impacts_per_cpu_s_after_first``). A last
record (``jet_pp``) gives the rate of the jet with particle-particle
contacts on (MuJoCo, one size class: :func:`_pp_profile`), reported
without a target. If the
jet scenario or its configuration is missing, or the run fails, the
benchmark records a skip with the reason instead of failing the whole run.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
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


#: Impacts of a throw-away jet run first in the worker: it loads (in a fresh
#: checkout: compiles, ~15 s of CPU once) the numba kernels and builds the
#: onset tables, one-off costs a long jet amortises; the timed profile
#: starts after it, in the same process.
WARMUP_IMPACTS = 300


def _profile(engine: str, checkpoints: tuple[int, ...]) -> list[dict]:
    """memory_profile of one engine with the configuration (in the worker),
    after a WARMUP_IMPACTS warm-up run."""
    from experiments.config import load_toml
    from experiments.scenarios import jet as J
    raw, _ = load_toml(CONFIG)
    spec = J.spec_from_config(J.load(raw, str(CONFIG)))
    J.memory_profile(engine, spec, checkpoints=(WARMUP_IMPACTS,))
    return J.memory_profile(engine, spec, checkpoints=checkpoints)


#: Plate impacts of the particle-particle jet (PP_IMPACTS, quick: PP_IMPACTS_QUICK): at ~165 impacts per
#: CPU-second under load (the broad phase; ~75 before it, docs/benchmarks.md) ~2 s; it is reported, not
#: held to a target.
PP_IMPACTS, PP_IMPACTS_QUICK = 250, 30


def _pp_profile(impacts: int) -> dict:
    """experiments/configs/jet.toml's jet with particle-particle contacts on (the jet of
    ``scripts/jet_check.py pp-rate``: one size class, 0.25 mm), MuJoCo, in the worker: impacts per
    CPU-second of the pool (its own time.process_time) after a warm-up of a tenth of them."""
    import math
    import warnings

    from experiments.scenarios.jet import JetSpec, Nozzle, Particles, Plate, make_pool
    from msf_contact import ValidityWarning, preset

    a = math.radians(45.0)
    spec = JetSpec(Nozzle.aimed((0.0, 0.0), (math.cos(a), 0.0, -math.sin(a)), 0.02, 20.0, 1e-3),
                   Particles(preset("glass"), (2.5e-4,), (1.0,), 30.0, 3.0, 1e5), Plate(preset("polyurethane")),
                   particle_particle=True, dt=1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)  # the records carry it (outside_validity)
        with make_pool("mujoco", spec, 0) as pool:
            pool.run(max(1, impacts // 10))
            i0, c0, pp0 = pool.counts.impacts, pool.cpu_s, pool.counts.pp_impacts
            pool.run(i0 + impacts)
            di, dc = pool.counts.impacts - i0, pool.cpu_s - c0
            return {"name": "jet_pp", "engine": "mujoco", "n_bodies": pool.n, "dt": spec.dt, "impacts": di,
                    "cpu_s": dc, "impacts_per_cpu_s": di / dc if dc > 0 else None,
                    "pp_records": pool.counts.pp_impacts - pp0, "pp_pairs": len(pool.pp_pairs),
                    "median": "one run after a warm-up of a tenth of the impacts (CPU time of the pool)",
                    "repeats": 1}


def run(quick: bool = False) -> list[dict]:
    try:
        from experiments.config import load_toml
        from experiments.scenarios import jet as J
        spec_from_config = J.spec_from_config
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
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as ex:
                prof = ex.submit(_profile, engine, tuple(cps)).result()
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
    impacts = PP_IMPACTS_QUICK if quick else PP_IMPACTS
    log(f"jet: mujoco with particle-particle contacts, {impacts} impacts")
    try:
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as ex:
            r = ex.submit(_pp_profile, impacts).result()
    except Exception as exc:  # noqa: BLE001
        return out + _skip(f"mujoco with particle-particle contacts failed ({type(exc).__name__}: {exc})")
    log(f"jet: mujoco with particle-particle contacts: {r['impacts_per_cpu_s']:.1f} impacts per CPU-second "
        f"({r['pp_records']} particle-particle records, pool {r['n_bodies']}, {r['pp_pairs']} pairs)")
    out.append(r)
    return out
