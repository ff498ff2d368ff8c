"""Deep and oblique impacts in the engines against the reference solver
(issue 10 item 3): the grid whose table docs/engines.md quotes.

    .venv/bin/python scripts/oblique_grid.py [--quick] [--jobs N]

Two families, each impact isolated (no gravity, fixed plate, no initial
spin, the contact beginning at a step start, gap 0), MSF law, contact-point
tangential mode:

- ``beads``: glass beads of radius 0.25, 0.5 and 1 mm on polyurethane
  (the abrasive jet's pair, experiments/configs/jet.toml), 10, 20, 50 and
  100 m/s, 15, 30, 45, 60 and 75 degrees to the plate, dt = 1e-4 and 1e-5 s;
  each contact (~1-10 us) lies wholly inside one engine step;
- ``robotics``: natural-rubber and PTFE balls (R = 10 mm) on steel at
  1 m/s, 15-75 degrees, dt = 1 and 2 ms.

Per case and engine (mujoco, pybullet): the relative errors of cor_t,
spin_out and W_diss_t against :func:`msf_contact.simulate_impact`, the
absolute error of cor_n, and whether the engine raised. The table rows
are the worst case per (family, engine, dt). Prints a markdown table and,
with --json PATH, writes every case.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import warnings

BEAD_RADII = (2.5e-4, 5e-4, 1e-3)
BEAD_SPEEDS = (10.0, 20.0, 50.0, 100.0)
ANGLES = (15.0, 30.0, 45.0, 60.0, 75.0)
BEAD_DTS = (1e-4, 1e-5)
ROBOT_BALLS = ("natural-rubber", "ptfe")
ROBOT_RADIUS = 0.01
ROBOT_SPEED = 1.0
ROBOT_DTS = (1e-3, 2e-3)
ENGINES = ("mujoco", "pybullet")


def setup(ball_name: str, plate_name: str, radius: float):
    """(law, ball Body, plate Body) of an MSF sphere-on-plate impact."""
    from msf_contact import Body, ContactPair, Curvature, ValidityWarning, make_law, preset

    ball_m, plate_m = preset(ball_name), preset(plate_name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        law = make_law("msf", ContactPair(ball_m, plate_m), Curvature.sphere_on_plane(radius))
    return law, Body.sphere(ball_m, radius), Body.half_space(plate_m)


def errors(rec, ref) -> dict:
    """Relative errors of cor_t, spin_out, W_diss_t and the absolute cor_n error."""
    def rel(a, b):
        return abs(a - b) / abs(b) if b else abs(a - b)
    return {"cor_t": rel(rec.cor_t, ref.cor_t), "spin_out": rel(rec.spin_out, ref.spin_out),
            "W_diss_t": rel(rec.W_diss_t, ref.W_diss_t), "cor_n": abs(rec.cor_n - ref.cor_n)}


def run_case(family, ball_name, plate_name, radius, speed, angle, dt, engines=ENGINES) -> list[dict]:
    from engines.base import get_engine
    from msf_contact import ValidityWarning, simulate_impact

    law, ball, plate = setup(ball_name, plate_name, radius)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        ref = simulate_impact(law, ball, plate, speed, angle)
    out = []
    for engine in engines:
        row = {"family": family, "engine": engine, "ball": ball_name, "radius": radius, "speed": speed,
               "angle": angle, "dt": dt}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rec = get_engine(engine)(law, ball, plate, speed, angle, dt=dt)
            row.update(errors(rec, ref), error=None)
        except Exception as e:  # reported in the table: "no engine error" is part of the acceptance
            row.update(cor_t=math.nan, spin_out=math.nan, W_diss_t=math.nan, cor_n=math.nan,
                       error=f"{type(e).__name__}: {e}")
        out.append(row)
    return out


def cases(quick: bool):
    radii = BEAD_RADII[:1] if quick else BEAD_RADII
    speeds = (10.0, 100.0) if quick else BEAD_SPEEDS
    angles = (15.0, 75.0) if quick else ANGLES
    for r, v, a, dt in itertools.product(radii, speeds, angles, BEAD_DTS):
        yield ("beads", "glass", "polyurethane", r, v, a, dt)
    for b, a, dt in itertools.product(ROBOT_BALLS, angles, ROBOT_DTS):
        yield ("robotics", b, "steel", ROBOT_RADIUS, ROBOT_SPEED, a, dt)


def table(rows: list[dict]) -> str:
    keys = sorted({(r["family"], r["engine"], r["dt"]) for r in rows})
    lines = ["| family | engine | dt [s] | cases | max cor_t err | max spin_out err | max W_diss_t err | "
             "max abs cor_n err | engine errors |", "|---|---|---|---|---|---|---|---|---|"]
    for fam, eng, dt in keys:
        sel = [r for r in rows if (r["family"], r["engine"], r["dt"]) == (fam, eng, dt)]
        ok = [r for r in sel if r["error"] is None]

        def mx(k):
            return max((r[k] for r in ok), default=math.nan)
        lines.append(f"| {fam} | {eng} | {dt:g} | {len(sel)} | {100 * mx('cor_t'):.3f} % | "
                     f"{100 * mx('spin_out'):.3f} % | {100 * mx('W_diss_t'):.3f} % | {mx('cor_n'):.1e} | "
                     f"{len(sel) - len(ok)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="0.25 mm beads, 10 and 100 m/s, 15 and 75 degrees only")
    p.add_argument("--json", default=None, metavar="PATH", help="write every case here")
    args = p.parse_args(argv)
    rows = []
    for c in cases(args.quick):
        rows.extend(run_case(*c))
        print(".", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    print(table(rows))
    bad = [r for r in rows if r["error"] is not None]
    for r in bad:
        print(f"engine error: {r}", file=sys.stderr)
    if args.json:
        from experiments._io import write_text_atomic

        write_text_atomic(args.json, json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
