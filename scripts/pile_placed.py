"""A pile placed at rest in scripts/pile.py's box (issue 10: "settle with no
energy gain at any step and rest at the static overlaps").

    .venv/bin/python scripts/pile_placed.py --engine mujoco --steps 600 --drop 0.5e-3

Nine spheres of R = 10 mm in scripts/pile.py's box two spheres wide (the
walls 2.25 R from its axis): four in the bottom corners on the floor, each
under a second one (four columns of two, 10 um from two walls each), and one
in the middle on the four bottom ones (its contacts 62 degrees from the
vertical push them into the walls; 0.64 mm from the upper four). Natural
rubber but for the middle sphere and two opposite upper corners (steel). Placed touching, at rest,
each layer raised by ``drop`` [m] above its place (0: touching), so it
falls into place. Reported: scripts/pile.py's JSON (``run``) for this
layout, the engine's overlaps against the static overlaps of the forces the
contacts carry among them.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np

R = 0.01
#: The box of scripts/pile.py two spheres a row (half width 2.25 R) and nine spheres in it.
SIDE, N = 2, 9
#: The corner spheres' clearance from the walls [m]: a sphere placed exactly touching a wall at rest
#: chattered in pybullet (onsets and ends at x ~ 0 beyond the island's MAX_SEGMENTS in a step); the
#: middle sphere pushes the lower ones this far into the walls in the first steps.
WALL_GAP = 1e-5


def _pile():
    """A private copy of scripts/pile.py (its ``layout`` is replaced in this copy only)."""
    spec = importlib.util.spec_from_file_location("pile_for_placed", Path(__file__).resolve().parent / "pile.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def placed_layout(pile, drop: float = 0.0):
    """Materials (9,), centres (9, 3) [m], velocities (9, 3) [m/s] and the box's half width [m] of the
    module docstring's pile, each layer ``drop`` [m] above its touching place."""
    half = pile.layout(N, SIDE)[3]
    c = half - R - WALL_GAP  # a corner sphere's centre off the axis: WALL_GAP from two walls
    h = math.sqrt(4.0 * R * R - 2.0 * c * c)  # height of the middle sphere over the corners touching them
    corners = [(sx * c, sy * c) for sx in (-1, 1) for sy in (-1, 1)]
    pos = ([(x, y, R + drop) for x, y in corners] + [(0.0, 0.0, R + h + 2 * drop)]
           + [(x, y, 3 * R + 2 * drop) for x, y in corners])
    mats = [pile.RUBBER] * 4 + [pile.STEEL] + [pile.STEEL, pile.RUBBER, pile.RUBBER, pile.STEEL]
    return mats, np.array(pos), np.zeros((N, 3)), half


def run(engine: str, steps: int, dt: float = 1e-3, drop: float = 0.0, rest_steps: int = 0) -> dict:
    """scripts/pile.py's run on the placed pile (its report, module docstring)."""
    pile = _pile()
    lay = placed_layout(pile, drop)
    pile.layout = lambda n, side, seed=0, pour="grid": lay
    return pile.run(engine, N, SIDE, steps, dt, rest_steps=rest_steps)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", choices=("mujoco", "pybullet"), default="mujoco")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--drop", type=float, default=0.0, help="each layer this far above its place [m]")
    ap.add_argument("--rest-steps", type=int, default=0,
                    help="stop once every sphere has been slower than scripts/pile.py's REST_SPEED this many steps")
    a = ap.parse_args(argv)
    if a.steps < 1:
        raise ValueError(f"steps = {a.steps!r} must be >= 1")
    if not a.dt > 0:
        raise ValueError(f"dt = {a.dt!r} s must be > 0")
    if not a.drop >= 0:
        raise ValueError(f"drop = {a.drop!r} m must be >= 0")
    print(json.dumps(run(a.engine, a.steps, a.dt, a.drop, a.rest_steps)))


if __name__ == "__main__":
    main()
