"""Where a resting contact's engine offset comes from (issue 10, docs/engines.md,
the pile section: "the engine's position lead, frozen by settled steps").

    .venv/bin/python scripts/offset_trace.py --engine pybullet --n 3 --pairs 0 5 12 --steps 3000

scripts/pile.py's box (``--n`` spheres, ``--side`` a row, ``--pour`` grid or low, dt = 1 ms). For each
listed pair (laws_and_pairs' order) it reads, at every step start, the
engine's overlap x_e the manager is handed and the manager's own x, and
splits e = x_e - x of the pair's last contact into: e at its onset (the
first step start it is in contact), the leads since, (dt/2)(x'_end -
x'_start) summed over the sub-cycled steps (a settled step adds none), and
the resting relaxation's moves of x (engines._contacts.state.relax, read by
wrapping it). Printed as JSON: per pair e_final, e_onset, the onset step,
leads, relaxed (x's moves, up positive: they lower e) and the residual
e_final - e_onset - leads + relaxed, what the split does not explain. A diagnostic: it wraps the
manager's own-gap pass and the relaxation of this process only.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import engines._contacts.state as state  # noqa: E402
import pile  # noqa: E402


def trace(engine: str, n: int, side: int, pairs: list[int], steps: int, pour: str = "grid") -> dict:
    """The split of the module docstring for ``pairs`` after ``steps`` steps of 1 ms of the pour
    ``pour`` (scripts/pile.py POURS)."""
    moves: dict[int, float] = {}
    relax = state.relax

    def counting(mgr, p, x0, x_eng, nrm, v, settle, io=None):
        out = relax(mgr, p, x0, x_eng, nrm, v, settle, io)
        for i, q in enumerate(p.tolist()):
            moves[q] = moves.get(q, 0.0) + float(out[i] - x0[i])
        return out

    state.relax = counting
    try:
        ad, ctx, _speeds = (pile.build_mujoco if engine == "mujoco" else pile.build_pybullet)(n, side, 1e-3, pour=pour)
        mgr = ad.manager
        own = mgr._own_gaps
        half_dt = 0.5 * mgr.dt
        rec = {p: {"prev": None} for p in pairs}
        last = {}  # per pair: (x' at the step's start, settled in it, relaxation moves in it)

        def reading(pair, x, nrm, v, a):
            listed = pair.tolist()
            for p in pairs:
                r = rec[p]
                if p not in listed or not mgr.active[p]:
                    r["prev"] = None
                    continue
                e = float(x[listed.index(p)] - mgr.x[p])
                if r["prev"] is None or p not in last:
                    r.update(e_onset=e, onset_step=r.get("step", 0), leads=0.0, relaxed=0.0)
                else:
                    xd0, settled, moved = last[p]
                    r["leads"] += 0.0 if settled else half_dt * (float(mgr.xdot[p]) - xd0)
                    r["relaxed"] += moved
                r["prev"] = e
            return own(pair, x, nrm, v, a)

        mgr._own_gaps = reading
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with ctx:
                for k in range(steps + 1):
                    xd0 = {p: float(mgr.xdot[p]) for p in pairs}
                    moves.clear()
                    for p in pairs:
                        rec[p]["step"] = k
                    ad.step(1)
                    last.clear()
                    for p in pairs:
                        if mgr.active[p]:
                            last[p] = (xd0[p], bool(mgr.settled[p]), moves.get(p, 0.0))
    finally:
        state.relax = relax
    out = {}
    for p in pairs:
        r = rec[p]
        if r["prev"] is None:
            out[p] = None
            continue
        out[p] = {"e_final_m": r["prev"], "e_onset_m": r["e_onset"], "onset_step": r["onset_step"],
                  "leads_m": r["leads"], "relaxed_m": r["relaxed"],
                  "residual_m": r["prev"] - r["e_onset"] - r["leads"] + r["relaxed"]}
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", choices=("mujoco", "pybullet"), default="pybullet")
    ap.add_argument("--n", type=int, default=3)
    ap.add_argument("--side", type=int, default=1)
    ap.add_argument("--pairs", type=int, nargs="+", default=[0, 5, 12])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--pour", choices=pile.POURS, default="grid", help="how the spheres start (scripts/pile.py POURS)")
    a = ap.parse_args(argv)
    for name, v in (("n", a.n), ("side", a.side), ("steps", a.steps)):
        if v < 1:
            raise ValueError(f"{name} = {v!r} must be >= 1")
    n_pairs = len(pile.laws_and_pairs(pile.layout(a.n, a.side)[0]))
    for p in a.pairs:
        if not 0 <= p < n_pairs:
            raise ValueError(f"pairs: {p!r} is outside [0, {n_pairs - 1}]")
    print(json.dumps(trace(a.engine, a.n, a.side, a.pairs, a.steps, a.pour)))


if __name__ == "__main__":
    main()
