"""Calibration of the engines' own contact to MSF, and where it departs.

At each time step dt the built-in contacts are fitted to the reference
solver's COR and contact duration at the calibration speed
(:mod:`experiments.calibrate`: MuJoCo solref, pybullet restitution, pybullet
stiffness and damping); then every calibrated contact, the reference solver
and (optionally) MSF inside the engines run over speeds (factors of the
calibration speed, normal impacts) and angles (at the calibration speed).

Configuration (TOML)::

    scenario = "calibration"
    title = "..."
    [impact]          # the pair and its law: any `msf-contact impact` flag
    ball = "natural-rubber"   # except the swept/engine ones (speed, angle,
    plate = "steel"           # spin, engine, dt, gap, integrator, solref,
    radius = 0.02             # solimp, restitution, contact_*, gravity, json)
    [calibration]
    speed = 1.0       # calibration speed [m/s]
    dt = [1e-4, 1e-3] # engine time steps [s], one calibration each
    phases = 8        # onset phases averaged per engine figure
    forms = ["mujoco-solref", "pybullet-restitution", "pybullet-spring"]
    integrator = "euler"      # MuJoCo's
    [departure]
    speed_factors = [0.2, 0.5, 1.0, 2.0, 5.0]   # normal impacts at factor x speed
    angles = [90.0, 60.0, 45.0, 30.0]           # at the calibration speed [deg to the plate]
    friction = 1.0    # Coulomb coefficient of the built-in contacts (oblique impacts)
    msf_engines = ["mujoco", "pybullet"]        # MSF through the adapters, [] for none

Engines (cell.engine): ``reference`` (the target), the three fitted forms,
``mujoco`` and ``pybullet`` (MSF in the engine). Engine figures are means
over the onset phases, with the COR's spread over them.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

from ..calibrate import DEFAULT_PHASES, FORMS
from ..config import ConfigError, Field, validate
from . import Scenario
from .ball_on_plate import _flag_names, _impact_parser, parse_cell_args, to_argv

#: [impact] keys this scenario sets itself.
RESERVED = ("speed", "angle", "spin", "engine", "dt", "gap", "integrator", "solref", "solimp", "restitution",
            "contact_stiffness", "contact_damping", "gravity", "json")
MSF_ENGINES = ("mujoco", "pybullet")

SCHEMA = {
    "": {"scenario": Field("str", required=True),
         "title": Field("str", default="Calibration of the built-in contact to MSF")},
    "calibration": {
        "speed": Field("float", lo=0.0, lo_open=True, required=True, help="calibration speed [m/s]"),
        "dt": Field("list[float]", lo=0.0, hi=0.01, lo_open=True, required=True, help="engine time steps [s]"),
        "phases": Field("int", default=DEFAULT_PHASES, lo=1, hi=64, help="onset phases averaged"),
        "forms": Field("list[str]", default=list(FORMS), choices=FORMS, help="built-in forms fitted"),
        "integrator": Field("str", default="euler", choices=("euler", "rk4", "implicitfast")),
    },
    "departure": {
        "speed_factors": Field("list[float]", default=[0.2, 0.5, 1.0, 2.0, 5.0], lo=0.0, hi=100.0, lo_open=True,
                               help="normal impacts at these multiples of the calibration speed"),
        "angles": Field("list[float]", default=[90.0, 60.0, 45.0, 30.0], lo=0.0, hi=90.0, lo_open=True,
                        help="angles to the plate at the calibration speed [deg]"),
        "friction": Field("float", default=1.0, lo=0.0, lo_open=True,
                          help="Coulomb coefficient of the built-in contacts in oblique impacts"),
        "msf_engines": Field("list[str]", default=list(MSF_ENGINES), choices=MSF_ENGINES,
                             help="engines that also run MSF through their adapter"),
    },
}


def load(raw: dict, path: str) -> dict:
    impact = raw.get("impact", {})
    if not isinstance(impact, dict):
        raise ConfigError(f"{path}: [impact] must be a table")
    if raw.get("departure", {}).get("msf_engines") == []:
        raw = dict(raw, departure={k: v for k, v in raw["departure"].items() if k != "msf_engines"})
        empty_msf = True
    else:
        empty_msf = False
    cfg = validate({k: v for k, v in raw.items() if k != "impact"},
                   {k: v for k, v in SCHEMA.items()}, path)
    if empty_msf:
        cfg["departure"]["msf_engines"] = []
    for k in RESERVED:
        if k in impact:
            raise ConfigError(f"{path}: [impact.{k}] is set by the calibration scenario ([calibration] / "
                              "[departure]); remove it")
    cfg["impact"] = impact
    cfg["impact_argv"] = to_argv(impact, _flag_names(_impact_parser()), path, "impact")
    c = cfg["calibration"]
    if len(set(c["dt"])) != len(c["dt"]) or len(set(c["forms"])) != len(c["forms"]):
        raise ConfigError(f"{path}: [calibration] dt and forms must not repeat a value")
    try:
        for v in _speeds(cfg):
            _problem(tuple(cfg["impact_argv"]), v, c["dt"][0], c["phases"], c["integrator"])
    except ValueError as exc:
        raise ConfigError(f"{path}: [calibration.speed] / [departure.speed_factors]: {exc}") from None
    return cfg


def _speeds(cfg) -> list[float]:
    V = cfg["calibration"]["speed"]
    return [V * f for f in cfg["departure"]["speed_factors"]]


def cells(cfg: dict) -> list[dict]:
    c, d = cfg["calibration"], cfg["departure"]
    base = {"scenario": "calibration", "argv": cfg["impact_argv"], "V_cal": c["speed"], "phases": c["phases"],
            "integrator": c["integrator"], "friction": d["friction"]}
    V = c["speed"]
    cases = [(V * f, 90.0) for f in d["speed_factors"]]
    cases += [(V, a) for a in d["angles"] if (V, a) not in cases]
    out = [dict(base, kind="impact", engine="reference", dt=None, speed=v, angle=a) for v, a in cases]
    for dt in c["dt"]:
        for form in c["forms"]:
            out.append(dict(base, kind="fit", engine=form, dt=dt, speed=V, angle=90.0))
            out += [dict(base, kind="impact", engine=form, dt=dt, speed=v, angle=a) for v, a in cases]
        for eng in d["msf_engines"]:
            out += [dict(base, kind="impact", engine=eng, dt=dt, speed=v, angle=a) for v, a in cases]
    return out


@functools.lru_cache(maxsize=64)
def _problem(argv: tuple, speed: float, dt: float, phases: int, integrator: str):
    import warnings

    from .. import impact
    from ..calibrate import Problem

    args = parse_cell_args(list(argv) + ["--speed", repr(float(speed))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = impact.build_impact(args)
    return Problem(s.law, s.ball, s.plate, s.speed, dt, phases=phases, integrator=integrator)


@functools.lru_cache(maxsize=32)
def fitted(argv: tuple, V: float, dt: float, phases: int, integrator: str, form: str):
    """The calibration of one form (cached per process: impact cells reuse it)."""
    from ..calibrate import calibrate

    _, fits = calibrate(_problem(argv, V, dt, phases, integrator), (form,))
    return fits[form]


def run_cell(cell: dict) -> list[dict]:
    import warnings
    from dataclasses import asdict

    from ..calibrate import mujoco_builtin, pybullet_builtin, reference

    argv = tuple(cell["argv"])
    eng, v, a = cell["engine"], cell["speed"], cell["angle"]
    if eng == "reference":
        p = _problem(argv, cell["V_cal"], 1e-4, cell["phases"], cell["integrator"])
        r = reference(p, v, a).to_dict()
        keep = ("cor_n", "cor_t", "tau", "x_max", "F_max", "spin_out", "law", "engine")
        return [dict({k: r.get(k) for k in keep}, cor_n_min=r["cor_n"], cor_n_max=r["cor_n"])]
    p = _problem(argv, cell["V_cal"], cell["dt"], cell["phases"], cell["integrator"])
    if eng in FORMS:
        fit = fitted(argv, cell["V_cal"], cell["dt"], cell["phases"], cell["integrator"], eng)
        if cell["kind"] == "fit":
            return [dict(fit.to_dict(), engine=eng)]
        fr = cell["friction"] if a < 90.0 else None
        if eng == "mujoco-solref":
            s = mujoco_builtin(p, fit.params["solref"], fit.params["solimp"], speed=v, angle_deg=a, friction=fr)
        else:
            s = pybullet_builtin(p, fit.params, speed=v, angle_deg=a, friction=fr)
        return [dict(asdict(s), engine=eng, params=fit.params, fit_cor_ok=fit.cor_ok, fit_tau_ok=fit.tau_ok)]
    from .. import impact

    setup_args = parse_cell_args(list(argv) + ["--speed", repr(float(v)), "--angle", repr(float(a)),
                                               "--engine", eng, "--dt", repr(cell["dt"]),
                                               "--integrator", cell["integrator"]])
    from ..calibrate import PhaseStats, phase_gaps

    recs = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        setup = impact.build_impact(setup_args)
        from engines.base import get_engine

        run = get_engine(eng)
        kw = {"integrator": cell["integrator"]} if eng == "mujoco" else {}
        for g in phase_gaps(v, a, cell["dt"], cell["phases"]):
            recs.append(run(setup.law, setup.ball, setup.plate, v, a, 0.0, dt=cell["dt"], gap=g, **kw))
    return [dict(asdict(PhaseStats.of(recs)), engine=eng, law=setup.law.name)]


# ---------------------------------------------------------------- report ---
ENGINE_LABELS = {
    "reference": "MSF reference solver",
    "mujoco-solref": "MuJoCo built-in, calibrated solref",
    "pybullet-restitution": "pybullet built-in, calibrated restitution",
    "pybullet-spring": "pybullet built-in, calibrated stiffness/damping",
    "mujoco": "MSF in MuJoCo",
    "pybullet": "MSF in pybullet",
}
STYLE = {"reference": ("k-", "o"), "mujoco-solref": ("C0-", "s"), "pybullet-restitution": ("C1-", "^"),
         "pybullet-spring": ("C2-", "v"), "mujoco": ("C0:", "x"), "pybullet": ("C1:", "+")}


def _fmt(v, s=1.0, f=".4f"):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v * s, f)


def _pct(got, want):
    if got is None or want is None or want == 0:
        return "-"
    return f"{100.0 * (got - want) / abs(want):+.1f}%"


def _fit_table(fits: list[dict]) -> list[str]:
    lines = ["| dt [s] | form | fitted | held | COR target | COR engine (mean) | COR error | COR over phases | "
             "tau target [ms] | tau engine [ms] | tau error | matched | note |\n",
             "|---:|---|---|---|---:|---:|---:|---|---:|---:|---:|---|---|\n"]
    for r in sorted(fits, key=lambda r: (r["cell.dt"], FORMS.index(r["engine"]))):
        p = r["params"]
        if r["engine"] == "mujoco-solref":
            fitted = f"solref = ({p['solref'][0]:.6g}, {p['solref'][1]:.6g})"
            eq = r["equivalent"]["solref_direct"]
            held = f"solimp = ({', '.join(f'{x:g}' for x in p['solimp'])}); direct form ({eq[0]:.6g}, {eq[1]:.6g})"
        elif r["engine"] == "pybullet-restitution":
            fitted = f"restitution = {p['restitution']:.6g}"
            held = "restitution settings (engines/pybullet/builtin.py)"
        else:
            fitted = f"k = {p['contact_stiffness']:.6g} N/m, d = {p['contact_damping']:.6g} N s/m"
            held = f"restitution 0; reduced mass {r['equivalent']['reduced_mass']:.4g} kg"
        st = r["stats"]
        matched = ("COR" if r["cor_ok"] else "") + (" + tau" if r["tau_ok"] else "")
        lines.append(f"| {r['cell.dt']:g} | {r['engine']} | {fitted} | {held} | {r['target_cor']:.4f} | "
                     f"{st['cor_n']:.4f} | {100 * r['cor_error']:+.2f}% | {st['cor_n_min']:.4f}..{st['cor_n_max']:.4f} | "
                     f"{1e3 * r['target_tau']:.4f} | {1e3 * st['tau']:.4f} | {100 * r['tau_error']:+.1f}% | "
                     f"{matched or 'no'} | {r.get('note') or ''} |\n")
    return lines


def report(out: Path, rows: list[dict], cfg: dict) -> tuple[str, list[str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    from .._io import add_figure, figure_links

    c, d = cfg["calibration"], cfg["departure"]
    V = c["speed"]
    imp = cfg["impact"]
    figs: list[str] = []
    fits = [r for r in rows if r["cell.kind"] == "fit"]
    impacts = [r for r in rows if r["cell.kind"] == "impact"]
    refs = {(r["cell.speed"], r["cell.angle"]): r for r in impacts if r["cell.engine"] == "reference"}
    lines = [f"# {cfg['']['title']}\n\n",
             f"Pair: {', '.join(f'{k} = {v}' for k, v in imp.items())}. Calibration speed {V:g} m/s (normal "
             f"impact); engine figures are means over {c['phases']} onset phases per step; MuJoCo integrator "
             f"{c['integrator']}.\n\n",
             "## Fitted parameters (what solref gives my material?)\n\n"]
    lines += _fit_table(fits)
    lines.append("\nCOR over phases: the range of single impacts' COR when the contact begins at different "
                 "points of a step; the fit matches the mean.\n\n")
    engines_present = [e for e in ["reference", *FORMS, *MSF_ENGINES]
                       if any(r["cell.engine"] == e for r in impacts)]
    for dt in c["dt"]:
        def at(eng, v, a):
            for r in impacts:
                if (r["cell.engine"] == eng and r["cell.speed"] == v and r["cell.angle"] == a
                        and (eng == "reference" or r["cell.dt"] == dt)):
                    return r
            return None

        speeds = sorted({V * f for f in d["speed_factors"]})
        lines.append(f"## Departure across speeds, dt = {dt:g} s (normal impacts)\n\n"
                     "Relative departures from the MSF reference solver at the same speed.\n\n"
                     "| V [m/s] | engine | COR | vs MSF | COR over phases | tau [ms] | vs MSF | x_max [mm] | vs MSF | "
                     "F_max [N] | vs MSF |\n|---:|---|---:|---:|---|---:|---:|---:|---:|---:|---:|\n")
        for v in speeds:
            ref = refs.get((v, 90.0))
            if ref is None:
                continue
            for e in engines_present:
                r = ref if e == "reference" else at(e, v, 90.0)
                if r is None:
                    continue
                lines.append(f"| {v:g} | {e} | {r['cor_n']:.4f} | {_pct(r['cor_n'], ref['cor_n'])} | "
                             f"{r['cor_n_min']:.4f}..{r['cor_n_max']:.4f} | {_fmt(r['tau'], 1e3)} | "
                             f"{_pct(r['tau'], ref['tau'])} | {_fmt(r['x_max'], 1e3)} | {_pct(r['x_max'], ref['x_max'])} | "
                             f"{_fmt(r['F_max'], 1, '.2f')} | {_pct(r['F_max'], ref['F_max'])} |\n")
        lines.append("\n")
        # figure: COR(v), tau(v), x_max(v)
        if len(speeds) > 1:
            fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
            for ax, (key, label, sc) in zip(axes, (("cor_n", "normal COR [-]", 1.0), ("tau", "tau [ms]", 1e3),
                                                   ("x_max", "x_max [mm]", 1e3))):
                for e in engines_present:
                    pts = [(v, at(e, v, 90.0)) for v in speeds]
                    pts = [(v, r) for v, r in pts if r is not None and r.get(key) is not None]
                    if not pts:
                        continue
                    ls, mk = STYLE[e]
                    ax.plot([v for v, _ in pts], [r[key] * sc for _, r in pts], ls, marker=mk,
                            label=ENGINE_LABELS[e])
                    if key == "cor_n" and e != "reference":
                        ax.fill_between([v for v, _ in pts], [r["cor_n_min"] for _, r in pts],
                                        [r["cor_n_max"] for _, r in pts], color=ls[:2], alpha=0.12)
                ax.axvline(V, color="0.6", lw=0.8, ls="--")
                ax.set_xscale("log")
                ax.set_xticks(speeds)
                ax.xaxis.set_major_formatter(ScalarFormatter())
                ax.xaxis.set_minor_formatter(NullFormatter())
                ax.set_xlabel("impact speed [m/s]")
                ax.set_ylabel(label)
                ax.grid(alpha=0.3)
            axes[1].legend(fontsize=7)
            fig.suptitle(f"calibrated at {V:g} m/s (dashed), dt = {dt:g} s; band: COR over onset phases")
            add_figure(fig, out, f"speed_departure_dt{dt:g}.png", figs)
        angles = sorted(set(d["angles"]), reverse=True)
        if len(angles) > 1:
            lines.append(f"## Departure across angles, dt = {dt:g} s, V = {V:g} m/s\n\n"
                         f"Built-in contacts with Coulomb friction {d['friction']:g} (MuJoCo condim 3; pybullet "
                         "lateral friction); the MSF tangential law has no cap. Its tangential response is not "
                         "calibrated.\n\n")
            lines.append("| angle [deg] | engine | COR | cor_t | vs MSF | spin_out [rad/s] | vs MSF |\n"
                         "|---:|---|---:|---:|---:|---:|---:|\n")
            for a in angles:
                ref = refs.get((V, a))
                for e in engines_present:
                    r = ref if e == "reference" else at(e, V, a)
                    if r is None or ref is None:
                        continue
                    lines.append(f"| {a:g} | {e} | {r['cor_n']:.4f} | {_fmt(r.get('cor_t'))} | "
                                 f"{_pct(r.get('cor_t'), ref.get('cor_t'))} | {_fmt(r.get('spin_out'), 1, '.2f')} | "
                                 f"{_pct(r.get('spin_out'), ref.get('spin_out'))} |\n")
            lines.append("\n")
            fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
            for ax, (key, label) in zip(axes, (("cor_n", "normal COR [-]"), ("cor_t", "tangential COR [-]"),
                                               ("spin_out", "rebound spin [rad/s]"))):
                for e in engines_present:
                    pts = [(a, at(e, V, a)) for a in angles]
                    pts = [(a, r) for a, r in pts if r is not None and r.get(key) is not None]
                    if pts:
                        ls, mk = STYLE[e]
                        ax.plot([a for a, _ in pts], [r[key] for _, r in pts], ls, marker=mk, label=ENGINE_LABELS[e])
                ax.set_xlabel("angle to the plate [deg]")
                ax.set_ylabel(label)
                ax.grid(alpha=0.3)
            axes[0].legend(fontsize=7)
            fig.suptitle(f"V = {V:g} m/s, dt = {dt:g} s")
            add_figure(fig, out, f"angle_departure_dt{dt:g}.png", figs)
    lines.append(figure_links(figs))
    return "".join(lines), figs


SCENARIO = Scenario("calibration", "fit MuJoCo/pybullet built-in contact to MSF at one speed; departures",
                    load, cells, run_cell, report)
