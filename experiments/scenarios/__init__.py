"""Scenario registry: name -> Scenario.

A scenario turns a validated configuration into independent cells, runs
one cell (a module-level function, so local processes and Dask workers can
run it) and builds its report from the saved records.

What a scenario must provide (:class:`Scenario`):

1. ``load(raw, path) -> cfg``: validate the parsed TOML (errors name the
   file, key and bound) and check every cell's inputs before anything runs.
2. ``cells(cfg) -> list[dict]``: JSON-serialisable cells; everything a cell
   needs is inside it.
3. ``run_cell(cell) -> list[dict]``: the records of one cell (deterministic).
4. ``report(out, rows, cfg) -> (markdown, figures)``: tables and figures from
   the collected records only (``msf-contact report DIR`` reruns it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from engines.registry import resolve


@dataclass(frozen=True)
class Scenario:
    name: str
    help: str
    load: Callable
    cells: Callable
    run_cell: Callable
    report: Callable


#: Scenarios registered as objects (:func:`register`), and the built-in ones
#: by name -> "module:SCENARIO", imported on the first :func:`get_scenario`
#: (so this package never imports its scenario modules, which import it).
SCENARIOS: dict[str, Scenario] = {}
BUILTIN: dict[str, str] = {
    "ball-on-plate": "experiments.scenarios.ball_on_plate:SCENARIO",
    "calibration": "experiments.scenarios.calibration:SCENARIO",
    "chung-ooi": "experiments.scenarios.chung_ooi:SCENARIO",
    "jet": "experiments.scenarios.jet:SCENARIO",
    "objects": "experiments.scenarios.objects:SCENARIO",
    "paddle": "experiments.scenarios.paddle:SCENARIO",
}


def register(s: Scenario) -> Scenario:
    """Add a scenario object (the built-in ones are in :data:`BUILTIN`)."""
    SCENARIOS[s.name] = s
    return s


def get_scenario(name: str) -> Scenario:
    if name not in SCENARIOS and name in BUILTIN:
        SCENARIOS[name] = resolve(BUILTIN[name])
    try:
        return SCENARIOS[name]
    except KeyError:
        valid = sorted(set(SCENARIOS) | set(BUILTIN))
        raise ValueError(f"unknown scenario {name!r}; valid names: {', '.join(valid)}") from None
