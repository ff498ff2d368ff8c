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


@dataclass(frozen=True)
class Scenario:
    name: str
    help: str
    load: Callable
    cells: Callable
    run_cell: Callable
    report: Callable


SCENARIOS: dict[str, Scenario] = {}


def register(s: Scenario) -> Scenario:
    SCENARIOS[s.name] = s
    return s


def get_scenario(name: str) -> Scenario:
    _load_builtin()
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; valid names: {', '.join(sorted(SCENARIOS))}") from None


def _load_builtin() -> None:
    from . import ball_on_plate, calibration, chung_ooi, jet, paddle  # noqa: F401
