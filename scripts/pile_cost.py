"""Where a step of the pile goes (issue 10: the 200-sphere pile's cost).

    .venv/bin/python scripts/pile_cost.py --engine mujoco --n 200 --side 6 --skip 250 --steps 20 --pour low

Runs ``scripts/pile.py``'s scene for ``--skip`` steps, then ``--steps`` more
under cProfile, and prints one JSON line: the CPU time per profiled step
(``time.process_time``: on a shared machine the wall time is the load's),
the share of it inside the compiled islands
(``engines._island_kernel.advance_islands``) and the functions with the
most own time; per step (mean over the profiled steps) the candidate rows,
the islands and the rows of the largest, the island rows in contact, the
islands' RK4 substeps (``last_step_info["substeps"]``) and segments (one per
onset or end found inside the step); and, at the last profiled step, the
internal step each contact row of the largest island would take alone
(``h_row``: pi sqrt(m/k) / SUBSTEPS_PER_CONTACT at its overlap, the
kernel's ``_stiff_step`` of that row) against the one the island takes
(the smallest): an island integrates all its rows at its stiffest
contact's step; and the CPU time of one RK4 substep of that island.
"""

from __future__ import annotations

import argparse
import cProfile
import inspect
import json
import pstats
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import pile  # noqa: E402

from engines import _island_kernel as IK  # noqa: E402
from engines._contacts import island_compiled as IC  # noqa: E402
from engines._contacts.state import SUBSTEPS_PER_CONTACT  # noqa: E402


def measure(engine: str, n: int, side: int, skip: int, steps: int, dt: float = 1e-3, top: int = 8,
            pour: str = "grid") -> dict:
    """The module docstring's report for ``steps`` steps after ``skip`` of the pour ``pour`` (pile.POURS)."""
    builder = pile.build_mujoco if engine == "mujoco" else pile.build_pybullet
    ad, ctx, _speeds = builder(n, side, dt, pour=pour)
    mgr = ad.manager
    per_step: list[dict] = []
    last: dict = {}
    inner_isl, inner_adv = mgr._step_with_islands, IK.advance_islands

    def with_islands(multi, pair, *args, **kw):  # the islands' sizes, before they are stepped
        lab = multi[multi >= 0]
        _u, c = np.unique(lab, return_counts=True)
        last.update(rows=int(pair.size), islands=int(c.size), largest_island_rows=int(c.max(initial=0)),
                    island_rows_in_contact=int(np.count_nonzero(mgr.active[pair[multi >= 0]])))
        return inner_isl(multi, pair, *args, **kw)

    def advance(*a):  # the first call of a step: the island's rows, for h_row
        if "args" not in last:
            last["args"] = a
        return inner_adv(*a)

    mgr._step_with_islands = with_islands
    warnings.simplefilter("ignore")
    prof = cProfile.Profile(time.process_time)  # CPU: on a shared machine the wall clock is the load's
    with ctx:
        for _ in range(skip):
            ad.step(1)
            ad.pop_records()
        IC.IK = _Shim(advance)
        try:
            c0 = time.process_time()
            for _ in range(steps):
                last.clear()
                last.update(rows=0, islands=0, largest_island_rows=0, island_rows_in_contact=0)
                prof.enable()
                ad.step(1)
                prof.disable()
                ad.pop_records()
                info = mgr.last_step_info
                per_step.append({**{k: v for k, v in last.items() if k != "args"},
                                 "substeps": info.get("substeps", 0), "segments": info.get("segments", 0)})
            cpu = (time.process_time() - c0) / steps
        finally:
            IC.IK = IK
        rs = _row_steps(last.get("args"))
    st = pstats.Stats(prof)
    total = sum(v[2] for v in st.stats.values())  # own time of every function
    kern = sum(v[2] for k, v in st.stats.items() if k[2] == "advance_islands")
    own = sorted(((v[2], f"{Path(k[0]).name}:{k[1]}({k[2]})") for k, v in st.stats.items()), reverse=True)[:top]
    mean = {k: float(np.mean([s[k] for s in per_step])) for k in per_step[0]}
    out = {"engine": engine, "n": n, "side": side, "pour": pour, "pairs": len(mgr.pairs), "after_step": skip,
           "steps": steps,
           "cpu_s_per_step": cpu, "share_in_island_kernel": kern / total if total else 0.0,
           "top_own_time_s": [(round(t / steps, 6), name) for t, name in own], "mean_per_step": mean}
    if rs is not None and rs[0].size:
        h_row = rs[0]
        out.update({"h_island_s": float(h_row.min()), "h_row_median_s": float(np.median(h_row)),
                    "rows_below_2x_h_island": int(np.count_nonzero(h_row < 2 * h_row.min())),
                    "rk4_substep_cpu_s": rs[1]})
    return out


class _Shim:
    """engines._island_kernel with advance_islands wrapped (the rest passed through)."""

    def __init__(self, advance):
        self.advance_islands = advance

    def __getattr__(self, name):
        return getattr(IK, name)


def _row_steps(a) -> tuple[np.ndarray, float] | None:
    """h_row (module docstring) of the contact rows with x > 0 of the largest island of the call's
    arguments a (advance_islands'), and the CPU time [s] of one RK4 substep of that island (the
    kernel's _rk4 at its state, on copies, median of 20)."""
    if a is None:
        return None
    g = inspect.signature(IK.advance_islands.py_func).bind(*a).arguments
    io, cio = g["io"], g["cio"]
    i = int(np.argmax(np.diff(io)))
    pairs, n, W, kg, codes, LC, oc, y, in_c = (g[k] for k in ("pairs", "n", "W", "kg", "codes", "LC", "oc", "y", "in_c"))
    buf = np.empty(6)
    h = np.array([IK._stiff_step(r, r + 1, pairs, n, W, kg, codes, LC, oc, in_c, y, buf, float(SUBSTEPS_PER_CONTACT))
                  for r in range(int(io[i]), int(io[i + 1])) if in_c[r] and y[r, 0] > 0])
    cp, cq = g["cp"], g["cq"]
    eb = np.flatnonzero(in_c[cq[cio[i]:cio[i + 1]]]).astype(np.int64) + cio[i]  # as _island lists them
    work, out, F = np.empty_like(g["work"]), np.empty_like(y), np.zeros_like(g["F"])
    args = (int(io[i]), int(io[i + 1]), int(cio[i]), int(cio[i]) + eb.size, pairs, n, g["T"], W, g["Wc"], g["a"],
            g["paper"], g["Lr"], kg, codes, LC, oc, cp, cq, g["Wpq"], g["Wcpq"], np.r_[np.zeros(cio[i], np.int64), eb],
            in_c, y.copy(), float(h.min()) if h.size else 1e-6, out, work, F, buf, False)
    times = []
    for _ in range(20):
        c0 = time.process_time()
        IK._rk4(*args)
        times.append(time.process_time() - c0)
    return h, float(np.median(times))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", choices=("mujoco", "pybullet"), default="mujoco")
    ap.add_argument("--n", type=int, default=200, help="spheres")
    ap.add_argument("--side", type=int, default=6, help="spheres a row in the box")
    ap.add_argument("--skip", type=int, default=250, help="steps run before the profiled ones")
    ap.add_argument("--steps", type=int, default=20, help="steps profiled")
    ap.add_argument("--pour", choices=pile.POURS, default="grid", help="how the spheres start (pile.POURS)")
    a = ap.parse_args(argv)
    for name, v, lo in (("n", a.n, 1), ("side", a.side, 1), ("skip", a.skip, 0), ("steps", a.steps, 1)):
        if v < lo:
            raise ValueError(f"{name} = {v!r} must be >= {lo}")
    print(json.dumps(measure(a.engine, a.n, a.side, a.skip, a.steps, pour=a.pour)))


if __name__ == "__main__":
    main()
