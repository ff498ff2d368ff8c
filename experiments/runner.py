"""`msf-contact run CONFIG.toml [--out DIR]` and `msf-contact report DIR`.

A result directory holds:

- ``config.toml``: the configuration as given;
- ``manifest.json``: scenario, inputs, versions of the project and the
  engines, git commit, seeds, time steps, machine, cell counts, timings;
- ``cells/<key>.json``: one file per finished cell (resumable sweeps);
- ``records.csv`` (flat, readable by pandas) and ``records.jsonl`` (full);
- ``figures/*.png`` and ``report.md``.

All files are written atomically.
"""

from __future__ import annotations

import csv
import io
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from ._io import write_json_atomic, write_text_atomic
from .config import ConfigError, load_toml
from .scenarios import get_scenario
from .sweep import cell_key, collect, run_sweep


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    from importlib import metadata

    for pkg in ("msf-contact", "numpy", "scipy", "mujoco", "pybullet", "matplotlib", "pandas", "dask", "distributed"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    out["python"] = platform.python_version()
    return out


def git_commit() -> str | None:
    here = Path(__file__).resolve().parent.parent
    try:
        r = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if r.returncode != 0:
        return None
    return r.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def machine() -> dict:
    return {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count()}


def load_config(path: str | Path):
    raw, text = load_toml(path)
    name = raw.get("scenario")
    if not isinstance(name, str):
        raise ConfigError(f"{path}: [scenario] is required: the scenario's name (e.g. \"ball-on-plate\")")
    try:
        scenario = get_scenario(name)
    except ValueError as exc:
        raise ConfigError(f"{path}: [scenario] {exc}") from None
    return scenario, scenario.load(raw, str(path)), text


def _flat(v):
    if isinstance(v, (dict, list)):
        return json.dumps(v, sort_keys=True)
    return v


def write_records(out: Path, rows: list[dict]) -> None:
    lines = "".join(json.dumps(r, sort_keys=True, allow_nan=False) + "\n" for r in rows)
    write_text_atomic(out / "records.jsonl", lines)
    keys: list[str] = []
    for r in rows:
        for k in r:
            if k not in keys and k != "inputs":
                keys.append(k)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: _flat(r.get(k)) for k in keys})
    write_text_atomic(out / "records.csv", buf.getvalue())


def run(config: str | Path, out: str | Path | None = None, *, workers: int = 1, dask: str | None = None,
        quiet: bool = False) -> Path:
    """Validate the configuration, run (or resume) its cells, write the results."""
    scenario, cfg, text = load_config(config)
    out = Path(out) if out is not None else Path("out") / Path(config).stem
    cells = scenario.cells(cfg)  # everything validated before this point
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "config.toml", text)
    t0 = time.time()
    counts = run_sweep(scenario.run_cell, cells, out, workers=workers, dask=dask, quiet=quiet,
                       desc=scenario.name)
    manifest = {
        "scenario": scenario.name, "config_path": str(config), "config": cfg_for_manifest(cfg),
        "versions": versions(), "git_commit": git_commit(), "machine": machine(),
        "cells": counts, "backend": {"workers": workers, "dask": dask},
        "wall_time_s": time.time() - t0, "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "command": " ".join(sys.argv),
    }
    write_json_atomic(out / "manifest.json", manifest)
    report(out, quiet=quiet)
    return out


def cfg_for_manifest(cfg: dict) -> dict:
    return json.loads(json.dumps(cfg, default=str))


def report(out: str | Path, quiet: bool = False) -> Path:
    """Rebuild records.csv/jsonl, figures and report.md from the saved cells."""
    out = Path(out)
    if not (out / "config.toml").is_file():
        raise ConfigError(f"{out}: not a result directory (no config.toml)")
    scenario, cfg, _ = load_config(out / "config.toml")
    rows = collect(out, {cell_key(c) for c in scenario.cells(cfg)})
    if not rows:
        raise ConfigError(f"{out}: no finished cells to report")
    write_records(out, rows)
    md, _ = scenario.report(out, rows, cfg)
    manifest = out / "manifest.json"
    if manifest.is_file():
        m = json.loads(manifest.read_text())
        md += (f"\n---\nProduced by msf-contact {m['versions'].get('msf-contact')} (git {m.get('git_commit')}), "
               f"mujoco {m['versions'].get('mujoco')}, pybullet {m['versions'].get('pybullet')}; "
               f"{m['cells']['total']} cells ({m['cells']['skipped']} reused); "
               f"machine {m['machine']['platform']}, {m['machine']['cpus']} CPUs.\n")
    path = write_text_atomic(out / "report.md", md)
    if not quiet:
        print(f"wrote {path}", file=sys.stderr)
    return path
