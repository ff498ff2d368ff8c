"""Ball on plate: impacts over speeds, angles and spins, for every engine.

Configuration (TOML)::

    scenario = "ball-on-plate"
    title = "..."
    [impact]          # any `msf-contact impact` flag, '-' written '_'
    ball = "natural-rubber"
    plate = "steel"
    radius = 0.02
    [sweep]           # lists; the grid is their product
    speed = [0.5, 1.0, 2.0]
    angle = [90.0]
    spin = [0.0]
    engine = ["reference", "closed-form"]
    [engine_options.mujoco-builtin]   # flags for one engine only
    solref = [0.002, 0.3]
    [curves]
    samples = 300     # force-time samples stored for the reference solver (0: none)

Every cell is checked by the command line's own validation before anything
runs; a bad value names the file and key.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import math
from pathlib import Path

from ..config import ConfigError, Field, validate
from . import Scenario

SWEEP_KEYS = ("speed", "angle", "spin", "engine")


def _impact_parser() -> argparse.ArgumentParser:
    from .. import impact

    p = argparse.ArgumentParser(prog="impact", add_help=False, exit_on_error=False)
    impact.add_impact_arguments(p)
    return p


def _flag_names(p: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    out = {}
    for a in p._actions:  # noqa: SLF001 - argparse exposes no public list
        for s in a.option_strings:
            if s.startswith("--"):
                out[s[2:].replace("-", "_")] = a
    return out


def to_argv(values: dict, actions: dict[str, argparse.Action], path: str, section: str) -> list[str]:
    argv = []
    for k, v in values.items():
        if k not in actions:
            valid = ", ".join(sorted(actions))
            raise ConfigError(f"{path}: [{section}.{k}] is not a known key; valid keys: {valid}")
        flag = actions[k].option_strings[-1]
        if isinstance(actions[k], argparse._StoreTrueAction):  # noqa: SLF001
            if not isinstance(v, bool):
                raise ConfigError(f"{path}: [{section}.{k}] = {v!r} must be true or false")
            if v:
                argv.append(flag)
            continue
        if isinstance(v, list):
            v = ",".join(repr(float(x)) if isinstance(x, (int, float)) else str(x) for x in v)
        elif isinstance(v, bool):
            raise ConfigError(f"{path}: [{section}.{k}] = {v!r} must be a value, not true/false")
        argv += [flag, str(v)]
    return argv


def parse_cell_args(argv: list[str]):
    """Parse an `impact` argv with the command line's parser; errors -> ValueError."""
    p = _impact_parser()
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            return p.parse_args(argv)
    except (argparse.ArgumentError, SystemExit) as exc:
        msg = str(exc) if isinstance(exc, argparse.ArgumentError) else err.getvalue().strip().splitlines()[-1]
        raise ValueError(msg) from None


SCHEMA = {
    "": {"scenario": Field("str", required=True), "title": Field("str", default="Ball on plate")},
    "impact": {},  # checked against the command line's flags
    "sweep": {
        "speed": Field("list[float]", lo=0.0, lo_open=True, required=True, help="impact speeds [m/s]"),
        "angle": Field("list[float]", default=[90.0], lo=0.0, hi=90.0, lo_open=True,
                       help="angles to the plate [deg], 90 = normal"),
        "spin": Field("list[float]", default=[0.0], help="initial spins [rad/s]"),
        "engine": Field("list[str]", default=["reference"], help="engines (msf-contact impact --engine)"),
    },
    "curves": {"samples": Field("int", default=300, lo=0, hi=100000)},
}


def load(raw: dict, path: str) -> dict:
    impact = raw.get("impact", {})
    if not isinstance(impact, dict):
        raise ConfigError(f"{path}: [impact] must be a table")
    per_engine = raw.get("engine_options", {})
    if not isinstance(per_engine, dict) or not all(isinstance(v, dict) for v in per_engine.values()):
        raise ConfigError(f"{path}: [engine_options] must hold one table per engine, e.g. "
                          "[engine_options.mujoco-builtin]")
    rest = {k: v for k, v in raw.items() if k not in ("impact", "engine_options")}
    schema = {k: v for k, v in SCHEMA.items() if k != "impact"}
    cfg = validate(rest, schema, path)
    actions = _flag_names(_impact_parser())
    for k in SWEEP_KEYS:
        if k in impact:
            raise ConfigError(f"{path}: [impact.{k}] is swept: give it in [sweep.{k}]")
    base = to_argv(impact, actions, path, "impact")
    cfg["impact_argv"] = base
    cfg["impact"] = impact
    cfg["engine_argv"] = {}
    for eng, opts in per_engine.items():
        if eng not in cfg["sweep"]["engine"]:
            raise ConfigError(f"{path}: [engine_options.{eng}] names an engine that is not in [sweep.engine] "
                              f"= {cfg['sweep']['engine']}")
        cfg["engine_argv"][eng] = to_argv(opts, actions, path, f"engine_options.{eng}")
    cells(cfg)  # builds every cell's argv
    _check_cells(cfg, path)
    return cfg


def cells(cfg: dict) -> list[dict]:
    sw = cfg["sweep"]
    out = []
    for speed, angle, spin, engine in itertools.product(sw["speed"], sw["angle"], sw["spin"], sw["engine"]):
        argv = cfg["impact_argv"] + cfg.get("engine_argv", {}).get(engine, []) + [
            "--speed", repr(float(speed)), "--angle", repr(float(angle)), "--spin", repr(float(spin)),
            "--engine", engine]
        out.append({"scenario": "ball-on-plate", "argv": argv, "speed": float(speed), "angle": float(angle),
                    "spin": float(spin), "engine": engine, "samples": cfg["curves"]["samples"]})
    return out


def _check_cells(cfg, path):
    from .. import impact

    for c in cells(cfg):
        try:
            args = parse_cell_args(c["argv"])
            impact.build_impact(args)
        except ValueError as exc:
            raise ConfigError(f"{path}: cell (speed={c['speed']}, angle={c['angle']}, spin={c['spin']}, "
                              f"engine={c['engine']}): {exc}") from None


def run_cell(cell: dict) -> list[dict]:
    """One impact; the reference engine also stores force-time curves."""
    import warnings

    from msf_contact.solver import simulate_impact

    from .. import impact

    args = parse_cell_args(cell["argv"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        setup = impact.build_impact(args)
        if cell["engine"] == "reference":
            rec = simulate_impact(setup.law, setup.ball, setup.plate, setup.speed, setup.angle_deg, setup.spin,
                                  tangential=setup.tangential, n_samples=cell["samples"])
        else:
            rec = impact.ENGINES[cell["engine"]].run(setup)
    d = rec.to_dict() if hasattr(rec, "to_dict") else dict(rec)
    return [d]


# ---------------------------------------------------------------- report ---
def _series(rows, x_key, y_key, fixed):
    """{engine: (xs, ys)} of rows matching the fixed cell values, sorted by x."""
    out = {}
    for r in rows:
        if any(r.get(f"cell.{k}") != v for k, v in fixed.items()):
            continue
        y = r.get(y_key)
        if y is None:
            continue
        out.setdefault(r["cell.engine"], []).append((r[f"cell.{x_key}"], y))
    return {e: tuple(zip(*sorted(v))) for e, v in out.items()}


def report(out: Path, rows: list[dict], cfg: dict) -> tuple[str, list[str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import add_figure, figure_links

    figs = []
    sw = cfg["sweep"]
    colors = {e: f"C{i}" for i, e in enumerate(sw["engine"])}
    # overlapping series stay visible: the reference as a thick line, the
    # others as distinct open markers on thin lines
    markers = dict(zip(sw["engine"], "osD^vxP*"))

    def style(eng):
        if eng == "reference":
            return dict(color=colors.get(eng), lw=4, alpha=0.35, marker="o", ms=9)
        return dict(color=colors.get(eng), lw=1, marker=markers.get(eng, "o"), ms=7, mfc="none", mew=1.5)

    def autoscale(ax):
        ys = [y for line in ax.get_lines() for y in line.get_ydata() if y > 0]
        if ys and max(ys) / min(ys) > 30:
            ax.set_yscale("log")
    lines = [f"# {cfg['']['title']}\n", "Ball-on-plate impacts; SI units in the records, ms/mm below.\n"]
    # speed sweeps at each (angle, spin)
    for angle, spin in itertools.product(sw["angle"], sw["spin"]):
        fixed = {"angle": angle, "spin": spin}
        if len(sw["speed"]) > 1:
            fig, axes = plt.subplots(2, 2, figsize=(10, 7))
            for ax, (key, label, scale) in zip(axes.flat, (("cor_n", "normal COR [-]", 1), ("tau", "tau [ms]", 1e3),
                                                           ("x_max", "x_max [mm]", 1e3), ("F_max", "F_max [N]", 1))):
                for eng, (xs, ys) in sorted(_series(rows, "speed", key, fixed).items(),
                                            key=lambda kv: kv[0] != "reference"):
                    ax.plot(xs, [y * scale for y in ys], label=eng, **style(eng))
                autoscale(ax)
                ax.set_xlabel("impact speed [m/s]")
                ax.set_ylabel(label)
                ax.grid(alpha=0.3)
            fig.suptitle(f"angle {angle:g} deg, spin {spin:g} rad/s")
            handles = {h.get_label(): h for ax in axes.flat for h in ax.get_lines()}
            axes.flat[0].legend(handles.values(), handles.keys(), fontsize=8)
            add_figure(fig, out, f"speed_sweep_a{angle:g}_s{spin:g}.png", figs)
    # angle sweeps
    if len(sw["angle"]) > 1:
        for speed, spin in itertools.product(sw["speed"], sw["spin"]):
            fixed = {"speed": speed, "spin": spin}
            fig, axes = plt.subplots(1, 2, figsize=(10, 4))
            for ax, (key, label) in zip(axes, (("cor_t", "tangential COR (centre of mass) [-]"),
                                               ("spin_out", "rebound spin [rad/s]"))):
                for eng, (xs, ys) in sorted(_series(rows, "angle", key, fixed).items(),
                                            key=lambda kv: kv[0] != "reference"):
                    ax.plot(xs, ys, label=eng, **style(eng))
                ax.set_xlabel("angle to the plate [deg]")
                ax.set_ylabel(label)
                ax.grid(alpha=0.3)
            axes[0].legend(fontsize=8)
            fig.suptitle(f"speed {speed:g} m/s, initial spin {spin:g} rad/s")
            add_figure(fig, out, f"angle_sweep_v{speed:g}_s{spin:g}.png", figs)
    # force-time curves of every record that has them
    curves = [r for r in rows if isinstance(r.get("inputs"), dict) and "curves" in r["inputs"]]
    if curves:
        # one panel per engine, each over the reference solver's curves: engines that agree
        # (MuJoCo and pybullet draw the same staircase) no longer hide each other
        others = sorted({r["cell.engine"] for r in curves} - {"reference"}) or ["reference"]
        fig, axes = plt.subplots(1, len(others), figsize=(5.5 * len(others) + 3.6, 4.6), sharey=True,
                                 squeeze=False)
        speeds = sorted({r["cell.speed"] for r in curves})
        shade = {v: f"C{i}" for i, v in enumerate(speeds)}
        for ax, engine in zip(axes[0], others):
            for r in sorted(curves, key=lambda r: r["cell.speed"]):
                if r["cell.engine"] not in ("reference", engine):
                    continue
                c = r["inputs"]["curves"]
                # the legend (beside the last panel) serves every panel: the engine is in each panel's title
                case = f"{r['cell.speed']:g} m/s, {r['cell.angle']:g} deg"
                t_ms = [t * 1e3 for t in c["t"]]
                if c.get("kind") == "step-averaged":  # an engine: the force it applied over each step
                    ax.step(t_ms + [t_ms[-1] + c["dt"] * 1e3], c["F_n"] + [c["F_n"][-1]], where="post", lw=1.2,
                            ls="--", marker="o", ms=3, color=shade[r["cell.speed"]],
                            label=f"{case}: engine of the panel, per step")
                else:
                    ax.plot(t_ms, c["F_n"], lw=2, color=shade[r["cell.speed"]], alpha=0.5,
                            label=f"{case}: reference solver")
            ax.set_title(f"{engine} against the reference solver", fontsize=9)
            ax.set_xlabel("time since onset [ms]")
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("normal force F_n [N]")
        handles = {h.get_label(): h for ax in axes[0] for h in ax.get_lines() if not h.get_label().startswith("_")}
        order = sorted(handles, key=lambda k: (float(k.split(" m/s")[0]), "reference" not in k))
        axes[0][-1].legend([handles[k] for k in order], order, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.suptitle("Normal force. An engine's staircase is the mean force it applied over each step: it starts "
                     "at the step that holds the onset (before t = 0) and, for a contact of a few steps, stays "
                     "below the peak", fontsize=8)
        add_figure(fig, out, "force_time.png", figs)
    # table
    lines.append("| engine | law | V [m/s] | angle [deg] | spin [rad/s] | COR | cor_t | tau [ms] | x_max [mm] | "
                 "F_max [N] | spin_out [rad/s] |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")

    def f(v, s=1.0, fmt=".4f"):
        return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v * s, fmt)

    order = {e: i for i, e in enumerate(sw["engine"])}
    for r in sorted(rows, key=lambda r: (r["cell.angle"], r["cell.spin"], r["cell.speed"],
                                         order.get(r["cell.engine"], len(order)))):
        lines.append(f"| {r['cell.engine']} | {r.get('law')} | {r['cell.speed']:g} | {r['cell.angle']:g} | "
                     f"{r['cell.spin']:g} | {f(r.get('cor_n'))} | {f(r.get('cor_t'))} | {f(r.get('tau'), 1e3)} | "
                     f"{f(r.get('x_max'), 1e3)} | {f(r.get('F_max'), 1, '.2f')} | {f(r.get('spin_out'), 1, '.2f')} |\n")
    lines.append("\n")
    lines.append(figure_links(figs))
    return "".join(lines), figs


SCENARIO = Scenario("ball-on-plate", "impacts of a ball on a plate over speeds, angles and spins",
                    load, cells, run_cell, report)
