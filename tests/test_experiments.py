"""Scenario configs, sweeps (resume, Dask), result directories."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from experiments import runner
from experiments.config import ConfigError
from experiments.scenarios import get_scenario
from experiments.sweep import cell_key, collect, done_keys, run_sweep

ROOT = Path(__file__).resolve().parent.parent

BASE = """
scenario = "ball-on-plate"
title = "test"
[impact]
ball = "natural-rubber"
plate = "steel"
radius = 0.02
[sweep]
speed = {speeds}
engine = ["reference", "closed-form"]
[curves]
samples = 20
"""


def write(tmp_path, text, name="c.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def test_run_writes_a_complete_result_directory(tmp_path):
    cfg = write(tmp_path, BASE.format(speeds="[0.5, 2.0]"))
    out = runner.run(cfg, tmp_path / "out", quiet=True)
    for name in ("config.toml", "manifest.json", "records.csv", "records.jsonl", "report.md"):
        assert (out / name).is_file(), name
    assert (out / "figures" / "speed_sweep_a90_s0.png").is_file()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["versions"]["mujoco"] and manifest["versions"]["pybullet"]
    assert manifest["cells"] == {"total": 4, "skipped": 0, "ran": 4}
    import pandas as pd

    df = pd.read_csv(out / "records.csv")
    assert len(df) == 4
    ref = df[df["cell.engine"] == "reference"].sort_values("cell.speed")
    # the record equals a direct call of the reference solver
    from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact

    pair = ContactPair(preset("natural-rubber"), preset("steel"))
    law = make_law("msf", pair, Curvature.sphere_on_plane(0.02))
    direct = simulate_impact(law, Body.sphere(pair.body1, 0.02), Body.half_space(pair.body2), 2.0)
    assert ref["cor_n"].iloc[1] == direct.cor_n
    # report rebuilds from saved results alone
    (out / "report.md").unlink()
    runner.report(out, quiet=True)
    assert "| reference | msf | 2 |" in (out / "report.md").read_text()


@pytest.mark.parametrize(
    "text, needle",
    [
        (BASE.format(speeds="[0.5]") + "\n[bogus]\nx = 1\n", r"\[bogus\] is not a known section"),
        (BASE.format(speeds="[0.5]").replace('radius = 0.02', 'radius = 0.02\nwobble = 3'),
         r"\[impact.wobble\] is not a known key"),
        (BASE.format(speeds="[-1.0]"), r"\[sweep.speed\[0\]\] = -1.0 is below the bound > 0"),
        (BASE.format(speeds="[0.5]").replace('samples = 20', 'samples = -3'), r"\[curves.samples\] = -3"),
        (BASE.format(speeds="[0.5]").replace('radius = 0.02', 'radius = -0.02'), "--radius = -0.02"),
        (BASE.format(speeds="[0.5]").replace('"natural-rubber"', '"unobtainium"'), "unobtainium"),
        (BASE.format(speeds="[0.5]").replace('ball-on-plate', 'moon-landing'), "unknown scenario 'moon-landing'"),
        (BASE.format(speeds="[1e5]"), "sound speed"),
        ("scenario = \n", "malformed TOML"),
    ],
)
def test_bad_configs_name_file_key_and_bound(tmp_path, text, needle):
    cfg = write(tmp_path, text)
    with pytest.raises(ConfigError, match=needle) as exc:
        runner.run(cfg, tmp_path / "out", quiet=True)
    assert str(cfg) in str(exc.value)
    assert not (tmp_path / "out" / "cells").exists()  # nothing ran


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="no such configuration file"):
        runner.run(tmp_path / "nope.toml", tmp_path / "out", quiet=True)


class Interrupt(Exception):
    pass


def test_interrupted_sweep_resumes_every_cell_exactly_once(tmp_path):
    scenario = get_scenario("ball-on-plate")
    cfg = scenario.load(__import__("tomllib").loads(BASE.format(speeds="[0.3, 0.6, 0.9, 1.2]")), "mem")
    cells = scenario.cells(cfg)
    calls = []

    def flaky(cell):
        if len(calls) == 3:
            raise Interrupt
        calls.append(cell_key(cell))
        return scenario.run_cell(cell)

    with pytest.raises(Interrupt):
        run_sweep(flaky, cells, tmp_path, quiet=True)
    assert len(done_keys(tmp_path)) == 3
    counts = run_sweep(scenario.run_cell, cells, tmp_path, quiet=True)
    assert counts == {"total": 8, "skipped": 3, "ran": 5}
    rows = collect(tmp_path)
    assert sorted(r["cell_key"] for r in rows) == sorted(cell_key(c) for c in cells)


def test_killed_process_resumes(tmp_path):
    """SIGKILL a real `msf-contact run` after its first cells, then re-run."""
    cfg = write(tmp_path, BASE.format(speeds=str([0.2 + 0.1 * i for i in range(16)])))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "experiments.cli", "run", str(cfg), "--out", str(out), "--quiet"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and len(done_keys(out)) < 2 and proc.poll() is None:
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    first = len(done_keys(out))
    assert first >= 1
    leftovers = [p for p in (out / "cells").iterdir() if p.suffix != ".json"]
    assert all(p.name.startswith(".") for p in leftovers)  # only temp files, never a torn .json
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["cells"]["total"] == 32
    assert manifest["cells"]["skipped"] == first
    lines = (out / "records.jsonl").read_text().splitlines()
    keys = [json.loads(x)["cell_key"] for x in lines]
    assert len(keys) == 32 and len(set(keys)) == 32


def test_dask_local_gives_identical_records(tmp_path):
    cfg = write(tmp_path, BASE.format(speeds="[0.5, 1.5]"))
    a = runner.run(cfg, tmp_path / "local", quiet=True)
    b = runner.run(cfg, tmp_path / "dask", dask="local", workers=2, quiet=True)
    ra = sorted((a / "records.jsonl").read_text().splitlines())
    rb = sorted((b / "records.jsonl").read_text().splitlines())
    assert ra == rb


def test_process_pool_gives_identical_records(tmp_path):
    cfg = write(tmp_path, BASE.format(speeds="[0.5, 1.5]"))
    a = runner.run(cfg, tmp_path / "one", quiet=True)
    b = runner.run(cfg, tmp_path / "two", workers=2, quiet=True)
    assert sorted((a / "records.jsonl").read_text().splitlines()) == sorted(
        (b / "records.jsonl").read_text().splitlines())


def test_shipped_configs_load():
    for p in sorted((ROOT / "experiments" / "configs").glob("*.toml")):
        scenario, cfg, _ = runner.load_config(p)
        assert scenario.cells(cfg)


def test_engine_options_apply_to_their_engine_only(tmp_path):
    text = BASE.format(speeds="[1.0]").replace('engine = ["reference", "closed-form"]',
                                               'engine = ["reference", "pybullet-builtin"]')
    text += "\n[engine_options.pybullet-builtin]\nrestitution = 0.55\n"
    out = runner.run(write(tmp_path, text), tmp_path / "out", quiet=True)
    rows = [json.loads(x) for x in (out / "records.jsonl").read_text().splitlines()]
    by = {r["cell.engine"]: r for r in rows}
    assert by["pybullet-builtin"]["cor_n"] == pytest.approx(0.55, rel=1e-6)
    assert by["reference"]["cor_n"] < 0.8  # the MSF law, untouched by the restitution flag
    bad = text.replace("[engine_options.pybullet-builtin]", "[engine_options.mujoco]")
    with pytest.raises(ConfigError, match=r"\[engine_options.mujoco\] names an engine that is not in"):
        runner.run(write(tmp_path, bad, "bad.toml"), tmp_path / "out2", quiet=True)
