"""``python -m benchmarks.run [--out DIR] [--quick] [--only NAME]`` (``make bench``).

Writes ``DIR/results.json`` (a list of records; every record has at least
``name, engine, n_bodies, dt`` and, where they apply, ``msf_step_s,
builtin_step_s, nocontact_step_s, ratio_msf_over_builtin,
ratio_msf_over_nocontact``, plus ``median``/``repeats`` and the machine's
description under ``machine``) and ``DIR/results.md`` (Markdown tables),
both atomically. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from ._common import log, machine

#: name -> module of benchmarks (each has run(quick) -> list[dict]); the jet last.
BENCHMARKS = {"per_step": "spheres", "subcycling": "subcycle", "reference": "reference", "sweep": "sweep",
              "robots": "robots", "robots_pybullet": "robots_pybullet", "pile": "pile", "jet": "jet"}

TARGETS = {
    "mujoco_1000_over_nocontact": 1.5,
    "mujoco_1000_over_builtin": 0.5,
    "pybullet_1000_over_builtin": 1.25,
    "reference_impact_s": 0.020,
    "jet_mujoco_impacts_per_cpu_s": 5000.0,
}


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _ms(v):
    return "" if v is None else f"{v * 1e3:.3f}"


def _x(v):
    return "" if v is None else f"{v:.3g}"


def markdown(records: list[dict], mach: dict, command: str) -> str:
    lines = ["# msf-contact benchmarks", "",
             f"Command: `{command}`  ", f"Machine: {mach['platform']}, {mach['cpu_model']}, {mach['cores']} cores; "
             + ", ".join(f"{k} {v}" for k, v in mach["versions"].items()), ""]
    ps = [r for r in records if r["name"] == "per_step"]
    if ps:
        lines += ["## Per-step cost, N spheres on a plate (dt = 1 ms, medians)", "",
                  "| engine | N | MSF [ms] | built-in [ms] | no contact [ms] | MSF/built-in | MSF/no contact | "
                  "MSF contacts | settled |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for r in ps:
            if r.get("failed"):
                lines.append(f"| {r['engine']} | {r['n_bodies']} | failed: {r['reason']} | | | | | | |")
                continue
            lines.append(f"| {r['engine']} | {r['n_bodies']} | {_ms(r['msf_step_s'])} | {_ms(r['builtin_step_s'])} | "
                         f"{_ms(r['nocontact_step_s'])} | {_x(r['ratio_msf_over_builtin'])} | "
                         f"{_x(r['ratio_msf_over_nocontact'])} | {r['msf_contacts_at_end']} | "
                         f"{r.get('msf_settled_at_end', '')} |")
        lines.append("")
    sc = [r for r in records if r["name"] == "subcycling"]
    if sc:
        lines += ["## Sub-cycling: one impact at dt = 1 ms against a resolved dt (tau/50)", "",
                  "| engine | tau [ms] | resolved dt [us] | wall/sim-ms, 1 ms [ms] | wall/sim-ms, resolved [ms] | "
                  "ratio | COR err 1 ms | COR err resolved |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for r in sc:
            lines.append(f"| {r['engine']} | {r['contact_duration_s'] * 1e3:.3f} | {r['dt_resolved'] * 1e6:.2f} | "
                         f"{_ms(r['subcycled_wall_per_sim_ms_s'])} | {_ms(r['resolved_wall_per_sim_ms_s'])} | "
                         f"{_x(r['ratio_subcycled_over_resolved_per_sim_time'])} | {r['cor_err_subcycled']:.1e} | "
                         f"{r['cor_err_resolved']:.1e} |")
        lines.append("")
    ref = [r for r in records if r["name"] == "reference_impact"]
    cfs = [r for r in records if r["name"] == "closed_form"]
    if ref or cfs:
        lines += ["## Reference solver and closed forms", "", "| what | value |", "|---|---:|"]
        for r in ref:
            lines.append(f"| self-consistent impact at {r['angle_deg']:g} deg [ms] | {_ms(r['time_per_impact_s'])} |")
        for r in ref[:1]:
            if r.get("first_call_s") is not None:
                lines.append(f"| first call, cold caches (builds the onset table) [s] | {r['first_call_s']:.2f} |")
        for r in cfs:
            lines.append(f"| {r['function']} [cases/s] | {r['cases_per_s']:.3g} |")
        lines.append("")
    sw = [r for r in records if r["name"] == "sweep"]
    if sw:
        lines += ["## Sweep (ball on plate)", "", "| backend | cells | wall [s] | speed-up |", "|---|---:|---:|---:|"]
        for r in sw:
            lines.append(f"| {r['backend']} | {r['cells']} | {r['wall_s']:.2f} | {r['speedup_over_local_1']:.2f} |")
        lines.append("")
    rb = [r for r in records if r["name"] == "robots" and not r.get("failed")]
    if rb:
        lines += ["## Robot models (pybullet_data/mjcf, seeded torques)", "",
                  "| engine | model | dt [s] | MSF [ms/step] | built-in [ms/step] | MSF / built-in | base height MSF / "
                  "built-in [m] | rest energy rise MSF [J] |", "|---|---|---:|---:|---:|---:|---:|---:|"]
        for r in rb:
            lines.append(f"| {r.get('engine', 'mujoco')} | {r['model']} | {r['dt']:g} | {_ms(r['msf_step_s'])} | {_ms(r['builtin_step_s'])} | "
                         f"{_x(r['ratio_msf_over_builtin'])} | {r['msf_base_height_m']:.3f} / "
                         f"{r['builtin_base_height_m']:.3f} | {r['msf_rest_energy_rise_J']:.3g} |")
        lines.append("")
    pl = [r for r in records if r["name"] == "pile"]
    if pl:
        lines += ["## 1,000-sphere pile in MuJoCo (cost only; dt = 1 ms, CPU medians)", "",
                  "| N | MSF pairs | MSF [ms] | built-in [ms] | MSF/built-in | MSF contacts | island rows | finite |",
                  "|---:|---:|---:|---:|---:|---:|---:|---|"]
        for r in pl:
            if r.get("failed"):
                lines.append(f"| {r['n_bodies']} | failed: {r['reason']} | | | | | | |")
                continue
            lines.append(f"| {r['n_bodies']} | {r['msf_pairs']} | {_ms(r['msf_step_s'])} | "
                         f"{_ms(r['builtin_step_s'])} | {_x(r['ratio_msf_over_builtin'])} | {r['msf_contacts_at_end']} | "
                         f"{r['msf_island_rows_at_end']} | {r['finite']} |")
        lines.append("")
    jet = [r for r in records if r["name"] == "jet"]
    if jet:
        lines += ["## Abrasive jet", ""]
        for r in jet:
            if r.get("skipped"):
                lines.append(f"- skipped: {r['reason']}")
            else:
                lines.append(f"- {r['engine']}: {r['impacts_per_cpu_s']:.0f} impacts per CPU-second over "
                             f"{r['impacts']} impacts; RSS change {r['rss_growth'] * 100:+.1f}% from the first "
                             "to the last checkpoint")
        for r in (r for r in records if r["name"] == "jet_pp"):
            lines.append(f"- {r['engine']} with particle-particle contacts (one 0.25 mm class, {r['n_bodies']} beads, "
                         f"{r['pp_pairs']} pairs): {r['impacts_per_cpu_s']:.1f} impacts per CPU-second over "
                         f"{r['impacts']} impacts, {r['pp_records']} particle-particle records (no target)")
        lines.append("")
    lines += targets_md(records)
    return "\n".join(lines) + "\n"


def targets_md(records: list[dict]) -> list[str]:
    def find(name, **kw):
        for r in records:
            if r["name"] == name and not r.get("failed") and all(r.get(k) == v for k, v in kw.items()):
                return r
        return None

    rows = []
    mj = find("per_step", engine="mujoco", n_bodies=1000)
    if mj:
        rows.append(("MuJoCo, 1,000 spheres: MSF / no contact", mj["ratio_msf_over_nocontact"], "<= 1.5"))
        rows.append(("MuJoCo, 1,000 spheres: MSF / built-in", mj["ratio_msf_over_builtin"], "<= 0.5"))
        for w, how in (("msf_loop", "the user's own mj_step loop"), ("msf_step1", "adapter.step(1)")):
            if f"ratio_{w}_over_builtin" in mj:
                rows.append((f"MuJoCo, 1,000 spheres: MSF / built-in, {how}", mj[f"ratio_{w}_over_builtin"], "<= 0.5"))
    pb = find("per_step", engine="pybullet", n_bodies=1000)
    if pb:
        rows.append(("pybullet, 1,000 spheres: MSF / built-in", pb["ratio_msf_over_builtin"], "<= 1.25"))
    ref = find("reference_impact", angle_deg=90.0)
    if ref:
        rows.append(("reference solver, ms per self-consistent impact", ref["time_per_impact_s"] * 1e3, "<= 20"))
    jet = find("jet", engine="mujoco")
    if jet and not jet.get("skipped"):
        rows.append(("jet in MuJoCo, impacts per CPU-second", jet["impacts_per_cpu_s"], ">= 5000"))
        rows.append(("jet in MuJoCo, RSS change 1e4 -> 1e5 impacts [%]", jet["rss_growth"] * 100, "|x| <= 10"))
    if not rows:
        return []
    out = ["## Targets (issue 5)", "", "| target | measured | wanted | met |", "|---|---:|---:|---|"]
    for what, val, want in rows:
        op, lim = want.split()[-2], float(want.split()[-1])
        met = abs(val) <= lim if want.startswith("|x|") else val <= lim if op == "<=" else val >= lim
        out.append(f"| {what} | {val:.3g} | {want} | {'yes' if met else 'no'} |")
    return out + [""]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.run", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="out/bench", help="output folder (default out/bench)")
    p.add_argument("--quick", action="store_true", help="small sizes and few repeats: a smoke run")
    p.add_argument("--only", choices=sorted(BENCHMARKS), action="append",
                   help="run only this benchmark (repeatable)")
    args = p.parse_args(argv)
    names = [n for n in BENCHMARKS if not args.only or n in args.only]
    mach = machine()
    records: list[dict] = []
    t0 = time.time()
    for name in names:
        log(f"== {name}")
        mod = importlib.import_module(f"benchmarks.{BENCHMARKS[name]}")
        t = time.time()
        recs = mod.run(quick=args.quick)
        log(f"== {name}: {time.time() - t:.1f} s")
        for r in recs:
            r.setdefault("median", None)
            r.setdefault("repeats", None)
            r["machine"] = mach
            r["quick"] = args.quick
        records += recs
    out = Path(args.out)
    command = "python -m benchmarks.run " + " ".join(argv if argv is not None else sys.argv[1:])
    _write_atomic(out / "results.json", json.dumps(records, indent=1, default=float) + "\n")
    _write_atomic(out / "results.md", markdown(records, mach, command.strip()))
    log(f"wrote {out / 'results.json'} and {out / 'results.md'} in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
