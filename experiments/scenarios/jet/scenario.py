"""The scenario ``jet`` for ``msf-contact run``: its TOML configuration
(:data:`SCHEMA`, :func:`load`, :func:`spec_from_config`), one cell per
(engine, chunk of impacts) (:func:`cells`) and a cell's run
(:func:`run_cell`)."""

from __future__ import annotations

import json
import math

from engines.pool import sphere_pool_class
from msf_contact import ValidityWarning

from ...config import ConfigError, Field, build_material, material_fields, validate
from .pool import _check_spheres, make_pool, rss_kb
from .spec import ARRIVALS, ENGINES, PLATE_KINDS, Bins, JetSpec, Nozzle, Particles, Plate


# --------------------------------------------------------------------------
# Configuration (TOML)
# --------------------------------------------------------------------------
_DIR45 = [math.sqrt(0.5), 0.0, -math.sqrt(0.5)]

SCHEMA = {
    "": {"scenario": Field("str", required=True),
         "title": Field("str", default="Abrasive jet: glass beads on a polyurethane coating")},
    "nozzle": {
        "aim": Field("list[float]", default=[0.0, 0.0], help="where the axis meets the plate (x, y) [m]"),
        "direction": Field("list[float]", default=_DIR45, help="unit axis (3), pointing at the plate"),
        "standoff": Field("float", lo=0.0, lo_open=True, help="distance from the exit to the plate along the axis [m]"),
        "position": Field("list[float]", help="exit centre (3) [m]; instead of aim and standoff"),
        "half_angle": Field("float", default=20.0, lo=0.0, hi=90.0, hi_open=True, help="cone half-angle [deg]"),
        "diameter": Field("float", default=1e-3, lo=0.0, help="exit diameter [m]"),
    },
    "particles": {
        **material_fields("particles"),
        "radius": Field("list[float]", lo=0.0, lo_open=True, help="radii of the size classes [m]"),
        "probability": Field("list[float]", lo=0.0, help="probabilities of the size classes"),
        "radius_mean": Field("float", lo=0.0, lo_open=True, help="normal distribution of radii: mean [m]"),
        "radius_sd": Field("float", lo=0.0, help="normal distribution of radii: sd [m]"),
        "classes": Field("int", default=5, lo=1, hi=50, help="classes the normal distribution is binned into"),
        "speed_mean": Field("float", default=30.0, lo=0.0, lo_open=True, help="[m/s]"),
        "speed_sd": Field("float", default=3.0, lo=0.0, help="[m/s]"),
        "feed_rate": Field("float", default=1e5, lo=0.0, lo_open=True, help="[particles/s]"),
        "arrival": Field("str", default="uniform", choices=ARRIVALS),
    },
    "plate": {
        **material_fields("plate"),
        "kind": Field("str", default="plane", choices=PLATE_KINDS),
        "size": Field("list[float]", default=[0.04, 0.04], lo=0.0, lo_open=True, help="[m] (2)"),
        "thickness": Field("float", default=0.005, lo=0.0, lo_open=True, help="box thickness [m]"),
        "strength": Field("float", default=10e6, lo=0.0, lo_open=True, help="coating strength [Pa]"),
    },
    "contact": {
        "particle_particle": Field("bool", default=False, help="MSF contacts among pool members"),
        "tangential": Field("str", default="contact-point", choices=("contact-point", "paper")),
    },
    "run": {
        "engines": Field("list[str]", default=list(ENGINES), choices=ENGINES),
        "impacts": Field("int", default=1000, lo=1, help="plate impacts per engine"),
        "chunk": Field("int", default=500, lo=1, help="impacts per cell (an independent burst, own seed)"),
        "seed": Field("int", default=0, lo=0),
        "dt": Field("float", default=1e-4, lo=0.0, lo_open=True, help="engine time step [s]"),
        "gravity": Field("float", default=0.0, lo=0.0, help="[m/s^2] along -z"),
        "pool": Field("int", default=0, lo=0, help="particles per size class (0: from the feed rate)"),
    },
    "aggregates": {
        "angle_bins": Field("int", default=18, lo=1, hi=900),
        "map_bins": Field("list[int]", default=[40, 40], lo=1, hi=2000),
        "pc_range": Field("list[float]", default=[1e5, 1e9], lo=0.0, lo_open=True, help="[Pa]"),
        "pc_bins": Field("int", default=200, lo=1, hi=1000),
    },
}


def spec_from_config(cfg: dict) -> JetSpec:
    """A :class:`JetSpec` from a validated configuration (ValueError naming
    the key on a bad combination)."""
    nz, pa, pl, ru, ag, co = (cfg[k] for k in ("nozzle", "particles", "plate", "run", "aggregates", "contact"))
    if len(nz["direction"]) != 3:
        raise ValueError(f"nozzle.direction = {nz['direction']!r} must have 3 components")
    if nz["position"] is not None:
        if nz["standoff"] is not None:
            raise ValueError("nozzle.position and nozzle.standoff are exclusive: give the exit position, "
                             "or aim and standoff")
        if len(nz["position"]) != 3:
            raise ValueError(f"nozzle.position = {nz['position']!r} must have 3 components")
        nozzle = Nozzle(tuple(nz["position"]), tuple(nz["direction"]), nz["half_angle"], nz["diameter"])
    else:
        if len(nz["aim"]) != 2:
            raise ValueError(f"nozzle.aim = {nz['aim']!r} must have 2 components (x, y)")
        nozzle = Nozzle.aimed(nz["aim"], nz["direction"], 0.02 if nz["standoff"] is None else nz["standoff"],
                              nz["half_angle"], nz["diameter"])
    mat_p = cfg["_materials"]["particles"]
    mat_pl = cfg["_materials"]["plate"]
    kw = dict(speed_mean=pa["speed_mean"], speed_sd=pa["speed_sd"], feed_rate=pa["feed_rate"], arrival=pa["arrival"])
    if pa["radius_mean"] is not None:
        if pa["radius"] is not None:
            raise ValueError("particles.radius and particles.radius_mean are exclusive: discrete classes, or a "
                             "normal distribution binned into classes")
        particles = Particles.binned_normal(mat_p, pa["radius_mean"], pa["radius_sd"] or 0.0, pa["classes"], **kw)
    else:
        radii = pa["radius"] if pa["radius"] is not None else [2.0e-4, 2.5e-4, 3.0e-4]
        probs = pa["probability"] if pa["probability"] is not None else (
            [0.25, 0.5, 0.25] if pa["radius"] is None else [1.0] * len(radii))
        particles = Particles(mat_p, tuple(radii), tuple(probs), **kw)
    if len(pl["size"]) != 2:
        raise ValueError(f"plate.size = {pl['size']!r} must have 2 components")
    plate = Plate(mat_pl, pl["kind"], tuple(pl["size"]), pl["thickness"], pl["strength"])
    if len(ag["map_bins"]) != 2:
        raise ValueError(f"aggregates.map_bins = {ag['map_bins']!r} must have 2 components")
    if len(ag["pc_range"]) != 2:
        raise ValueError(f"aggregates.pc_range = {ag['pc_range']!r} must have 2 components")
    bins = Bins(ag["angle_bins"], tuple(ag["map_bins"]), tuple(ag["pc_range"]), ag["pc_bins"])
    law = dict(cfg["law"])
    name = law.pop("name", "msf")
    return JetSpec(nozzle, particles, plate, law=name, law_options=law, tangential=co["tangential"],
                   particle_particle=co["particle_particle"], dt=ru["dt"], gravity=ru["gravity"],
                   pool=ru["pool"] or None, bins=bins)


def _materials(cfg: dict, path: str) -> dict:
    return {"particles": build_material(cfg["particles"], path, "particles", "glass"),
            "plate": build_material(cfg["plate"], path, "plate", "polyurethane")}


def load(raw: dict, path: str) -> dict:
    law = raw.get("law", {})
    if not isinstance(law, dict):
        raise ConfigError(f"{path}: [law] must be a table (name = \"msf\" and the law's options)")
    if "name" in law and not isinstance(law["name"], str):
        raise ConfigError(f"{path}: [law.name] = {law['name']!r} must be a string (a registry law)")
    cfg = validate({k: v for k, v in raw.items() if k != "law"}, {k: v for k, v in SCHEMA.items()}, path)
    cfg["law"] = dict(law)
    cfg["_materials"] = _materials(cfg, path)
    try:
        spec = spec_from_config(cfg)
        spec.plate_laws()
        if spec.particle_particle:
            spec.pp_laws()
        cfg["_validity"] = spec.check_validity()
        for e in cfg["run"]["engines"]:
            _engine_check(e, spec)
    except ValueError as exc:
        raise ConfigError(_config_message(path, str(exc))) from None
    if len(set(cfg["run"]["engines"])) != len(cfg["run"]["engines"]):
        raise ConfigError(f"{path}: [run.engines] = {cfg['run']['engines']!r} repeats an engine")
    return cfg


def _config_message(path: str, msg: str) -> str:
    """"run.dt = ..." -> "PATH: [run.dt] = ..." (the file, the key, the bound)."""
    import re

    m = re.match(r"^([a-z_]+\.[a-z_]+(?:\[\d+\])?)(?::)? (.*)$", msg, re.S)
    if m and (m.group(1).split(".")[0] in SCHEMA or m.group(1).startswith("law.")):
        return f"{path}: [{m.group(1)}] {m.group(2)}"
    m = re.match(r"^([a-z_]+): (.*)$", msg, re.S)
    if m and (m.group(1) in SCHEMA or m.group(1) == "law"):
        return f"{path}: [{m.group(1)}] {m.group(2)}"
    return f"{path}: {msg}"


def _engine_check(engine: str, spec: JetSpec) -> None:
    _check_spheres(sphere_pool_class(engine), spec)


def _cell_config(cfg: dict) -> dict:
    """What a cell needs to rebuild the spec (JSON; no title, no engine list)."""
    keep = {k: cfg[k] for k in ("nozzle", "particles", "plate", "contact", "aggregates", "law")}
    keep["run"] = {k: cfg["run"][k] for k in ("seed", "dt", "gravity", "pool")}
    return json.loads(json.dumps(keep))


def cells(cfg: dict) -> list[dict]:
    """One cell per (engine, chunk): chunk c is an independent burst of
    ``run.chunk`` impacts (the last one what is left) with the seed
    (run.seed, c); the same seeds in every engine."""
    total, size = cfg["run"]["impacts"], cfg["run"]["chunk"]
    n_chunks = int(math.ceil(total / size))
    conf = _cell_config(cfg)
    return [{"scenario": "jet", "engine": e, "chunk": c, "impacts": min(size, total - c * size), "config": conf}
            for e in cfg["run"]["engines"] for c in range(n_chunks)]


def _cfg_from_cell(cell: dict) -> dict:
    cfg = json.loads(json.dumps(cell["config"]))
    cfg["_materials"] = _materials(cfg, "cell")
    return cfg


def run_cell(cell: dict) -> list[dict]:
    """One burst of ``cell["impacts"]`` plate impacts in one engine: a
    summary row (kind "summary": the fixed-size aggregates, counters, CPU
    time, memory) and one row per impact (kind "impact") or particle-particle
    contact (kind "particle-particle")."""
    import warnings

    cfg = _cfg_from_cell(cell)
    spec = spec_from_config(cfg)
    rows: list[dict] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)  # checked in load(), reported per impact
        with make_pool(cell["engine"], spec, [cfg["run"]["seed"], cell["chunk"]]) as pool:
            pool.run(cell["impacts"], sink=rows.extend, progress=None)
    cur, peak = rss_kb()
    c = pool.counts
    summary = {"kind": "summary", "engine": cell["engine"], "chunk": cell["chunk"], "impacts": c.impacts,
               "emitted": c.emitted, "lost": c.lost, "pp_impacts": c.pp_impacts, "pp_W": c.pp_W,
               "pool_waits": c.pool_waits, "steps": c.steps, "pool_size": pool.n, "cpu_s": pool.cpu_s,
               "wall_s": pool.wall_s, "rss_kb": cur, "peak_rss_kb": peak, "validity": pool.validity,
               "aggregates": pool.aggregates.to_dict()}
    return [summary] + rows
