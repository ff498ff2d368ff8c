"""Benchmark 5: wall time of a ball-on-plate sweep on 1 and 2 local
workers and on a Dask LocalCluster (2 workers); each backend starts from an
empty result folder (pool or cluster start-up included), after a warm-up
of a few cells in this process. Cells: natural
rubber on steel, R = 20 mm, 16 speeds in 0.2-5 m/s, normal and 45 degree
incidence, engines reference, mujoco and pybullet (96 cells, a few seconds
of work on one core, so that start-up does not decide the comparison; 8
cells in --quick)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from ._common import log

CONFIG = """
scenario = "ball-on-plate"
[impact]
ball = "natural-rubber"
plate = "steel"
radius = 0.02
law = "msf"
[sweep]
speed = {speeds}
angle = {angles}
engine = {engines}
[curves]
samples = 0
"""


def run(quick: bool = False) -> list[dict]:
    from experiments.config import load_toml
    from experiments.scenarios import get_scenario
    from experiments.sweep import run_sweep

    import numpy as np
    speeds = [0.5, 1.0] if quick else [float(v) for v in np.round(np.geomspace(0.2, 5.0, 16), 4)]
    angles = [90.0, 45.0]
    engines = '["reference", "mujoco"]' if quick else '["reference", "mujoco", "pybullet"]'

    sc = get_scenario("ball-on-plate")
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sweep.toml"
        path.write_text(CONFIG.format(speeds=speeds, angles=angles, engines=engines))
        raw, _ = load_toml(path)
        cells = sc.cells(sc.load(raw, str(path)))
        # warm-up in this process (imports, numba kernels, onset tables): the first backend
        # timed would otherwise pay them alone (the local pool forks from this process)
        run_sweep(sc.run_cell, cells[:6], Path(tmp) / "warm-up", quiet=True, workers=1)
        for label, kw in (("local-1", {"workers": 1}), ("local-2", {"workers": 2}),
                          ("dask-local-2", {"workers": 2, "dask": "local"})):
            t = time.perf_counter()
            counts = run_sweep(sc.run_cell, cells, Path(tmp) / label, quiet=True, **kw)
            wall = time.perf_counter() - t
            log(f"sweep: {label}: {len(cells)} cells in {wall:.2f} s")
            out.append({"name": "sweep", "engine": "reference+mujoco" + ("" if quick else "+pybullet"), "n_bodies": 1,
                        "dt": None,
                        "backend": label, "cells": len(cells), "ran": counts["ran"], "wall_s": wall,
                        "median": "one run per backend (includes pool/cluster start-up)", "repeats": 1})
    base = out[0]["wall_s"]
    for r in out:
        r["speedup_over_local_1"] = base / r["wall_s"]
    return out
