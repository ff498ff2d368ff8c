"""Shared helpers: medians of repeated timings, the machine's description, the N-sphere scenes."""

from __future__ import annotations

import math
import os
import platform
import statistics
import sys
import time
from importlib import metadata

import numpy as np

#: Ball of the per-step benchmarks: natural rubber, radius 20 mm, on steel.
RADIUS = 0.02
#: Grid spacing of the spheres on the plate, in radii (they never touch each other).
SPACING_RADII = 3.0
#: Initial gaps are uniform in [0, MAX_GAP] [m] (seeded): the spheres bounce a few
#: times and settle, so the measured steps mix resting and bouncing contacts.
MAX_GAP = 5e-4
SEED = 0


def log(msg: str) -> None:
    print(f"[bench] {msg}", file=sys.stderr, flush=True)


def run_robots(engine: str, label: str, models, steps: int, measure, describe) -> list[dict]:
    """The robot benchmarks' loop (benchmarks/robots.py, robots_pybullet.py):
    ``measure(name, steps)`` for each model, its lines ``describe(record)``
    logged (``engine`` in the records, ``label`` in the log); a model that fails is recorded as failed (with the reason) and
    does not lose the others."""
    out = []
    for name in models:
        log(f"robots: {name} in {label}, {steps} steps of seeded torques, then {steps} at rest")
        try:
            r = measure(name, steps)
        except Exception as exc:  # noqa: BLE001 - one model failing must not lose the other
            log(f"  failed: {type(exc).__name__}: {exc}")
            out.append({"name": "robots", "engine": engine, "model": name, "failed": True,
                        "reason": f"{type(exc).__name__}: {exc}"[:300]})
            continue
        for line in describe(r):
            log(line)
        out.append(r)
    return out


def median_time(fn, repeats: int, clock=time.perf_counter) -> tuple[float, list[float]]:
    """Median time [s] of ``repeats`` calls of fn() (each timed alone) by
    ``clock``: wall time by default, ``time.process_time`` for the CPU time
    of this process (what a shared machine's load changes least)."""
    ts = []
    for _ in range(repeats):
        t = clock()
        fn()
        ts.append(clock() - t)
    return statistics.median(ts), ts


def machine() -> dict:
    cpu = None
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    vers = {}
    for pkg in ("numpy", "scipy", "mujoco", "pybullet", "dask", "distributed"):
        try:
            vers[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            vers[pkg] = None
    vers["python"] = platform.python_version()
    return {"platform": platform.platform(), "cpu_model": cpu or platform.processor() or platform.machine(),
            "cores": os.cpu_count(), "versions": vers}


def rubber_on_steel():
    """(law, ball Body) of the per-step benchmarks."""
    from msf_contact import Body, ContactPair, Curvature, make_law, preset

    rubber, steel = preset("natural-rubber"), preset("steel")
    law = make_law("msf", ContactPair(rubber, steel), Curvature(RADIUS, RADIUS, math.inf, math.inf))
    return law, Body.sphere(rubber, RADIUS)


def grid(n: int) -> np.ndarray:
    """(n, 3) sphere centres on a square grid over the plate z = 0, each a seeded gap above it."""
    side = int(math.ceil(math.sqrt(n)))
    i = np.arange(n)
    gaps = np.random.default_rng(SEED).uniform(0.0, MAX_GAP, n)
    return np.stack([(i % side) * SPACING_RADII * RADIUS, (i // side) * SPACING_RADII * RADIUS,
                     RADIUS + gaps], axis=1)
