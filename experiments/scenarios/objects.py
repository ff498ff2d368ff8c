"""Objects from ``pybullet_data`` dropped and tumbling on a plane (issue 13):
a cube (``cube_small.urdf``), a cylinder (``pybullet_data`` has no cylinder
object: one given by its radius, half-length and mass) and a mesh
(``duck_vhacd.urdf``, its convex hull), MSF against the engine's own
contact, side by side.

Each object starts with its lowest point ``height`` above the plane, turned
by ``tilt_deg`` (about x, then y) and spinning at ``omega``, and falls for
``duration``. MSF: the pair (object, floor) through the engine's narrow
phase, a law per contact point (the object's material on the floor's, the
curvature at each point: box corners and cylinder rims with ``edge_radius``,
the mesh's local fit; the mesh's hull vertices are contacts, 4 managed, as a
box's corners: ``MujocoAdapter(mesh_slots=...)``). Recorded every ``sample`` seconds: the centre of
mass's height and the mechanical energy (kinetic + gravitational, the
physical velocities: the MSF timing correction's one-step offset taken out,
``MujocoAdapter.velocity_offset``; with MSF plus ``ContactManager.stored_energy``,
the elastic energy held in the contacts and W_t - Q_t of every contact,
finished ones included, read at steps without a pending timing correction:
:func:`msf_energy`);
per cell the largest energy gain over any interval (MSF must not create
energy: above ENERGY_GAIN_RTOL E0, the contacts' own bound, the report marks
it and a RuntimeWarning says so), the impacts and the records
flagged outside the model's validity, the wall time per step. A run that
raises is recorded as failed with the message (the report says so).

Engines: ``mujoco`` (MSF), ``mujoco-builtin`` (default solref/solimp);
``pybullet`` (MSF through ``engines.pybullet.narrow``) and
``pybullet-builtin`` (pybullet's defaults): the runners are per engine
(:data:`RUNNERS`), the cell and the report are not.

Configuration (TOML)::

    scenario = "objects"
    [objects]    # run: cube, cylinder, duck; cube_urdf, duck_urdf (pybullet_data names);
                 # cylinder_radius, cylinder_half_length [m], cylinder_mass [kg]
    [materials]  # object, floor (msf_contact presets), law, edge_radius [m], friction
    [drop]       # height [m], tilt_deg [deg] (2,), omega [rad/s] (3,), duration, sample, dt [s], integrator
    [engines]    # run: mujoco, mujoco-builtin, pybullet, pybullet-builtin
"""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path

from ..config import ConfigError, Field, validate
from . import Scenario

OBJECTS = ("cube", "cylinder", "duck")
ENGINES = ("mujoco", "mujoco-builtin", "pybullet", "pybullet-builtin")

SCHEMA = {
    "": {"scenario": Field("str", required=True),
         "title": Field("str", default="Objects from pybullet_data dropped and tumbling on a plane")},
    "objects": {
        "run": Field("list[str]", default=list(OBJECTS), choices=OBJECTS),
        "cube_urdf": Field("str", default="cube_small.urdf", help="pybullet_data file of the cube"),
        "duck_urdf": Field("str", default="duck_vhacd.urdf", help="pybullet_data file of the mesh object"),
        "cylinder_radius": Field("float", default=0.02, lo=0.0, lo_open=True, help="[m]"),
        "cylinder_half_length": Field("float", default=0.05, lo=0.0, lo_open=True, help="[m]"),
        "cylinder_mass": Field("float", default=0.15, lo=0.0, lo_open=True, help="[kg]"),
    },
    "materials": {
        "object": Field("str", default="ptfe", help="msf_contact preset of the objects"),
        "floor": Field("str", default="steel", help="msf_contact preset of the plane"),
        "law": Field("str", default="msf", choices=("msf", "hertz", "kuwabara-kono", "hunt-crossley")),
        "edge_radius": Field("float", default=2e-3, lo=0.0, lo_open=True,
                             help="of the box's edges and the cylinder's rim [m]"),
        "friction": Field("float", default=0.5, lo=0.0, lo_open=True,
                          help="Coulomb coefficient, both contacts [-]"),
        "cor": Field("float", default=0.8, lo=0.0, hi=1.0, lo_open=True, help="hunt-crossley only [-]"),
    },
    "drop": {
        "height": Field("float", default=0.05, lo=0.0, help="lowest point above the plane [m]"),
        "tilt_deg": Field("list[float]", default=[25.0, 15.0], lo=-180.0, hi=180.0,
                          help="turn about x, then about y [deg]"),
        "omega": Field("list[float]", default=[3.0, -2.0, 1.0], help="initial spin, world axes [rad/s]"),
        "duration": Field("float", default=1.0, lo=0.0, lo_open=True, hi=60.0, help="[s]"),
        "sample": Field("float", default=5e-3, lo=0.0, lo_open=True, help="recording interval [s]"),
        "dt": Field("float", default=1e-3, lo=0.0, lo_open=True, hi=0.01, help="engine step [s]"),
        "integrator": Field("str", default="implicitfast", choices=("euler", "rk4", "implicitfast"),
                            help="MuJoCo's"),
    },
    "engines": {"run": Field("list[str]", default=["mujoco", "mujoco-builtin"], choices=ENGINES)},
}


def pybullet_shapes_available() -> bool:
    """True when the pybullet adapter takes box, cylinder and mesh pairs (engines.pybullet.narrow)."""
    import importlib.util

    return importlib.util.find_spec("engines.pybullet.narrow") is not None


def load(raw: dict, path: str) -> dict:
    cfg = validate(raw, SCHEMA, path)
    from msf_contact.materials import preset

    for key in ("object", "floor"):
        try:
            preset(cfg["materials"][key])
        except ValueError as exc:
            raise ConfigError(f"{path}: [materials.{key}] {exc}") from None
    d = cfg["drop"]
    if len(d["tilt_deg"]) != 2:
        raise ConfigError(f"{path}: [drop.tilt_deg] = {d['tilt_deg']!r} must be 2 angles (about x, then y)")
    if len(d["omega"]) != 3:
        raise ConfigError(f"{path}: [drop.omega] = {d['omega']!r} must be 3 components [rad/s]")
    if d["sample"] < d["dt"]:
        raise ConfigError(f"{path}: [drop.sample] = {d['sample']!r} s must be >= [drop.dt] = {d['dt']!r} s")
    if d["duration"] / d["dt"] > 1e6:
        raise ConfigError(f"{path}: [drop.duration] / [drop.dt] = {d['duration'] / d['dt']:.3g} steps is above "
                          "the bound 1e6")
    if "pybullet" in cfg["engines"]["run"] and not pybullet_shapes_available():
        raise ConfigError(f"{path}: [engines.run] 'pybullet': the pybullet adapter has no box, cylinder or mesh "
                          "pairs in this tree (engines/pybullet/narrow.py, issue 13); run 'mujoco', "
                          "'mujoco-builtin', 'pybullet-builtin'")
    objs = cfg["objects"]
    import os

    import pybullet_data

    for key in ("cube_urdf", "duck_urdf"):
        f = os.path.join(pybullet_data.getDataPath(), objs[key])
        if not os.path.isfile(f):
            raise ConfigError(f"{path}: [objects.{key}] = {objs[key]!r} is not a file of pybullet_data ({f})")
    return cfg


def cells(cfg: dict) -> list[dict]:
    base = {"scenario": "objects", "objects": cfg["objects"], "materials": cfg["materials"], "drop": cfg["drop"]}
    return [dict(base, object=o, engine=e) for o, e in itertools.product(cfg["objects"]["run"], cfg["engines"]["run"])]


def object_description(cell: dict) -> dict:
    """The engine-neutral description of the cell's object: a pybullet_data
    URDF file (cube, duck) or the cylinder's kind, size (radius,
    half-length) [m] and mass [kg]."""
    import os

    import pybullet_data

    o = cell["objects"]
    if cell["object"] == "cylinder":
        return {"kind": "cylinder", "size": [o["cylinder_radius"], o["cylinder_half_length"]],
                "mass": o["cylinder_mass"]}
    return {"urdf": os.path.join(pybullet_data.getDataPath(), o["cube_urdf" if cell["object"] == "cube" else
                                                                  "duck_urdf"])}


def law_template(cell: dict):
    """The pair's law (object material on floor material); its curvature is a
    placeholder the adapters replace by the curvature at each contact point
    (engines._narrow.LawBank)."""
    from msf_contact import ContactPair, Curvature, make_law, preset

    m = cell["materials"]
    opts = {"mu": m["friction"]}
    if m["law"] == "hunt-crossley":
        opts["cor"] = m["cor"]
    return make_law(m["law"], ContactPair(preset(m["object"]), preset(m["floor"])),
                    Curvature.sphere_on_plane(m["edge_radius"]), **opts)


def _start_quat(tilt_deg) -> list[float]:
    ax, ay = (math.radians(a) / 2 for a in tilt_deg)
    qx = (math.cos(ax), math.sin(ax), 0.0, 0.0)
    qy = (math.cos(ay), 0.0, math.sin(ay), 0.0)
    w1, x1, y1, z1 = qy  # q = qy * qx: about x first, then about (world) y
    w2, x2, y2, z2 = qx
    return [w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2]


def run_mujoco(cell: dict, msf: bool) -> dict:
    """One drop in MuJoCo: the series (t [s], z [m], E [J]) and the MSF records."""
    import warnings

    import mujoco
    import numpy as np

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.objects import FLOOR, OBJECT, com_height, object_on_plane, urdf_object
    from engines.mujoco.robots import mechanical_energy

    d, m = cell["drop"], cell["materials"]
    desc = object_description(cell)
    obj = urdf_object(desc["urdf"]) if "urdf" in desc else desc
    model, data = object_on_plane(obj, dt=d["dt"], height=d["height"], quat=_start_quat(d["tilt_deg"]),
                                  omega=d["omega"], msf=msf, friction=m["friction"], integrator=d["integrator"])
    adapter = MujocoAdapter(model, data, [PairSpec(OBJECT, FLOOR, law_template(cell))],
                            edge_radii={OBJECT: m["edge_radius"]}, mesh_slots={OBJECT: 4}) if msf else None
    steps = int(round(d["duration"] / d["dt"]))
    every = max(1, int(round(d["sample"] / d["dt"])))
    t, z, E = [0.0], [com_height(model, data)], [mechanical_energy(model, data)]
    W_fin = [0.0]  # MSF: the finished contacts' W_t - Q_t in E (msf_energy), to take out for the display
    wall = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if adapter is None:
            for k in range(1, steps + 1):
                mujoco.mj_step(model, data)
                if k % every == 0:
                    t.append(float(data.time)), z.append(com_height(model, data))
                    E.append(mechanical_energy(model, data))
        else:
            with installed(adapter):
                for k in range(1, steps + 1):
                    mujoco.mj_step(model, data)
                    if k % every == 0 and not np.any(adapter.manager.J != 0.0):
                        t.append(float(data.time)), z.append(com_height(model, data))
                        E.append(msf_energy(model, data, adapter))
                        W_fin.append(float(np.sum(adapter.manager.W_tq_finished)))
    wall = (time.perf_counter() - wall) / steps
    out = {"t": t, "z": z, "E": E, "step_s": wall, "warnings": sorted({str(w.message)[:200] for w in caught})[:5]}
    if adapter is not None:
        out["W_fin"] = W_fin
        recs = adapter.records
        out.update(impacts=len(recs), outside=sum(bool(r.outside_validity) for r in recs),
                   outside_examples=sorted({r.outside_validity[0][:160] for r in recs if r.outside_validity})[:3],
                   laws=len(adapter.laws), mass=float(model.body_mass[1]))
    return out


def msf_energy(model, data, adapter) -> float:
    """The energy MSF conserves or dissipates in MuJoCo [J]: kinetic (the
    physical velocities, the one-step timing offset taken out) plus
    gravitational energy, plus ``ContactManager.stored_energy`` (the island
    check's measure: the elastic energy held in the contacts in progress and
    W_t - Q_t of every contact, finished ones included; MSF's tangential
    spring stiffens with the overlap and gives back energy no force worked
    for: left out for the finished contacts, a tumbling object read 0.07 %
    gained). Read at steps without a pending timing correction (as the
    island energy check reads its bodies)."""
    from engines.mujoco.robots import mechanical_energy

    return mechanical_energy(model, data, data.qvel - adapter.velocity_offset()) + adapter.manager.stored_energy()


def _pybullet_energy(c: int, uid: int) -> float:
    """m g z + m v^2 / 2 + w.I w / 2 of a free pybullet body (its base frame
    is its inertial frame: position the centre of mass, inertia diagonal)."""
    import numpy as np
    import pybullet as pb

    info = pb.getDynamicsInfo(uid, -1, physicsClientId=c)
    m, I = float(info[0]), np.array(info[2], dtype=float)
    pos, orn = pb.getBasePositionAndOrientation(uid, physicsClientId=c)
    v, w = (np.array(a, dtype=float) for a in pb.getBaseVelocity(uid, physicsClientId=c))
    R = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
    wl = R.T @ w
    g = float(pb.getPhysicsEngineParameters(physicsClientId=c)["gravityAccelerationZ"])
    return float(-m * g * pos[2] + 0.5 * m * v @ v + 0.5 * wl @ (I * wl))


def run_pybullet(cell: dict, msf: bool) -> dict:
    """One drop in pybullet: the object from its URDF (``loadURDF``: the
    inertia of its collision shape) or a cylinder shape, over a plane; MSF
    through the adapter's narrow phase or pybullet's own contact (its
    defaults, lateral friction ``friction``). With MSF the energy is sampled
    only at steps without a pending timing correction (the pybullet adapter
    has no velocity offset to take out), plus the contacts' elastic energy."""
    import warnings

    import numpy as np
    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter, scenes

    d, m = cell["drop"], cell["materials"]
    c = scenes.new_client(d["dt"], gravity=9.81)
    try:
        plane = scenes.add_plate(c)
        desc = object_description(cell)
        w, x, y, z = _start_quat(d["tilt_deg"])
        orn = [x, y, z, w]
        if "urdf" in desc:
            uid = pb.loadURDF(desc["urdf"], [0, 0, 1.0], orn, physicsClientId=c)
        else:
            r, h = desc["size"]
            sh = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=r, height=2 * h, physicsClientId=c)
            uid = pb.createMultiBody(desc["mass"], sh, basePosition=[0, 0, 1.0], baseOrientation=orn,
                                     physicsClientId=c)
            Ixx = desc["mass"] * (3 * r * r + 4 * h * h) / 12
            pb.changeDynamics(uid, -1, localInertiaDiagonal=[Ixx, Ixx, desc["mass"] * r * r / 2], physicsClientId=c)
        scenes._free_dynamics(c, uid)
        for body in (uid, plane):
            pb.changeDynamics(body, -1, lateralFriction=m["friction"], physicsClientId=c)
        gap = min(p[8] for p in pb.getClosestPoints(uid, plane, 2.0, physicsClientId=c))
        pos, _ = pb.getBasePositionAndOrientation(uid, physicsClientId=c)
        pb.resetBasePositionAndOrientation(uid, [pos[0], pos[1], pos[2] + d["height"] - gap], orn, physicsClientId=c)
        pb.resetBaseVelocity(uid, [0, 0, 0], list(d["omega"]), physicsClientId=c)
        adapter = None
        if msf:
            adapter = PybulletAdapter(c, [PairSpec((uid, -1), (plane, -1), law_template(cell))],
                                      edge_radii={(uid, -1): m["edge_radius"]}, mesh_slots={(uid, -1): 4})

        def height():
            return float(pb.getBasePositionAndOrientation(uid, physicsClientId=c)[0][2])

        steps = int(round(d["duration"] / d["dt"]))
        every = max(1, int(round(d["sample"] / d["dt"])))
        t, zs, E = [0.0], [height()], [_pybullet_energy(c, uid)]
        W_fin = [0.0]  # as run_mujoco's
        wall = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for k in range(1, steps + 1):
                if adapter is None:
                    pb.stepSimulation(physicsClientId=c)
                else:
                    adapter.step()
                if k % every == 0 and (adapter is None or not np.any(adapter.manager.J != 0.0)):
                    t.append(k * d["dt"]), zs.append(height())
                    E.append(_pybullet_energy(c, uid) + (0.0 if adapter is None else adapter.manager.stored_energy()))
                    W_fin.append(0.0 if adapter is None else float(np.sum(adapter.manager.W_tq_finished)))
        wall = (time.perf_counter() - wall) / steps
        out = {"t": t, "z": zs, "E": E, "step_s": wall,
               "warnings": sorted({str(w_.message)[:200] for w_ in caught})[:5]}
        if adapter is not None:
            out["W_fin"] = W_fin
            recs = adapter.records
            out.update(impacts=len(recs), outside=sum(bool(r.outside_validity) for r in recs),
                       outside_examples=sorted({r.outside_validity[0][:160] for r in recs if r.outside_validity})[:3],
                       laws=len(adapter.laws))
        return out
    finally:
        pb.disconnect(c)


RUNNERS = {"mujoco": run_mujoco, "pybullet": run_pybullet}


def run_cell(cell: dict) -> list[dict]:
    import warnings

    import numpy as np

    from engines._contacts.state import ENERGY_GAIN_RTOL

    eng = cell["engine"]
    base, contact = (eng[:-len("-builtin")], "builtin") if eng.endswith("-builtin") else (eng, "msf")
    rec = {"object": cell["object"], "engine": base, "contact": contact}
    try:
        out = RUNNERS[base](cell, contact == "msf")
    except Exception as exc:  # noqa: BLE001 - a failed run is a result: the report says which and why
        return [dict(rec, failed=True, reason=f"{type(exc).__name__}: {exc}"[:400])]
    E = np.asarray(out["E"])
    gain = float(np.max(E - np.minimum.accumulate(E)))
    above = contact == "msf" and gain > ENERGY_GAIN_RTOL * float(E[0])
    if above:
        warnings.warn(f"objects: {cell['object']} with MSF in {base} gained {gain:.3g} J, above the bound "
                      f"ENERGY_GAIN_RTOL E0 = {ENERGY_GAIN_RTOL * float(E[0]):.3g} J", RuntimeWarning, stacklevel=2)
    # shown: what the object and its contacts in progress hold, E less the finished contacts' W_t - Q_t, which
    # the gain check needs (a finished contact can end with tangential energy of either sign) but which also
    # books every joule Coulomb slip dissipated (ContactManager.stored_energy): a PTFE cube at rest in MuJoCo
    # read 0.0627 J against its 0.0245 J of potential energy, 38 mJ of it slip
    W_fin = np.asarray(out.get("W_fin", np.zeros(E.size)))
    return [{**rec, **out, "failed": False, "E0": float(E[0]), "E_end": float(E[-1] - W_fin[-1]),
             "W_fin_end": float(W_fin[-1]), "z_end": float(out["z"][-1]),
             "energy_gain": gain, "energy_gain_rel": gain / float(E[0]), "energy_gain_above_bound": above}]


# ----------------------------------------------------------------- report ---
STYLE = {("mujoco", "msf"): "C0-", ("mujoco", "builtin"): "C0:", ("pybullet", "msf"): "C1-",
         ("pybullet", "builtin"): "C1:"}


def _label(r) -> str:
    return f"MSF in {r['engine']}" if r["contact"] == "msf" else f"{r['engine']} built-in"


def report(out: Path, rows: list[dict], cfg: dict) -> tuple[str, list[str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from engines._contacts.state import ENERGY_GAIN_RTOL

    from .._io import add_figure, figure_links

    d, m = cfg["drop"], cfg["materials"]
    figs: list[str] = []
    lines = [f"# {cfg['']['title']}\n\n",
             f"{m['object']} objects on a {m['floor']} plane, law {m['law']}, edge radius {1e3 * m['edge_radius']:g} "
             f"mm, friction {m['friction']:g}; dropped with the lowest point {d['height']:g} m above the plane, "
             f"turned {d['tilt_deg'][0]:g} deg about x then {d['tilt_deg'][1]:g} deg about y, spinning at "
             f"{d['omega']} rad/s; dt = {d['dt']:g} s ({d['integrator']}), {d['duration']:g} s. Energy (E end, "
             "the figures): kinetic + gravitational of the physical velocities (MSF's one-step timing offset taken "
             "out), plus with MSF what its contacts in progress hold (elastic, W_t - Q_t), read at steps without "
             "a pending timing correction. Gain: the largest rise over any interval of that sum plus the finished "
             "contacts' W_t - Q_t (the contacts' own check's measure: a finished contact may end with tangential "
             "energy of either sign), which also books what Coulomb slip dissipated, shown apart as 'finished "
             "W_t - Q_t' (the built-in contact's penetration stores energy that these sums leave out); MSF's "
             f"bound: ENERGY_GAIN_RTOL E0 = {ENERGY_GAIN_RTOL:g} E0 (the contacts' own energy check), above it "
             "marked and warned. Outside: MSF records flagged outside the model's validity.\n\n",
             "| object | contact | failed | E0 [J] | E end [J] | finished W_t - Q_t [J] | energy gain [J] (of E0) | "
             "z end [m] | impacts | outside | laws | step [ms] |\n"
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"]
    for r in sorted(rows, key=lambda r: (OBJECTS.index(r["object"]), ENGINES.index(
            r["engine"] + ("-builtin" if r["contact"] == "builtin" else "")))):
        if r["failed"]:
            lines.append(f"| {r['object']} | {_label(r)} | {r['reason']} | | | | | | | | | |\n")
            continue
        mark = " **above the bound**" if r.get("energy_gain_above_bound") else ""
        w_fin = f"{r['W_fin_end']:.4f}" if r["contact"] == "msf" and "W_fin_end" in r else ""
        lines.append(f"| {r['object']} | {_label(r)} | no | {r['E0']:.4f} | {r['E_end']:.4f} | {w_fin} | "
                     f"{r['energy_gain']:.3g} "
                     f"({100 * r['energy_gain_rel']:.4f} %){mark} | {r['z_end']:.4f} | {r.get('impacts', '')} | "
                     f"{r.get('outside', '')} | {r.get('laws', '')} | {1e3 * r['step_s']:.3f} |\n")
    lines.append("\n")
    notes = sorted({ex for r in rows if not r["failed"] for ex in r.get("outside_examples", [])})
    if notes:
        lines.append("Outside-validity flags (examples):\n\n" + "".join(f"- {n}\n" for n in notes) + "\n")
    for obj in OBJECTS:
        sel = [r for r in rows if r["object"] == obj and not r["failed"]]
        if not sel:
            continue
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.0))
        for r in sel:
            style = STYLE[(r["engine"], r["contact"])]
            axes[0].plot(r["t"], r["z"], style, label=_label(r))
            E = np.asarray(r["E"]) - np.asarray(r.get("W_fin", np.zeros(len(r["E"]))))
            axes[1].plot(r["t"], E, style, label=_label(r))
        axes[0].set_ylabel("centre of mass height [m]")
        axes[1].set_ylabel("energy [J] (kinetic, gravity, MSF elastic)")
        for ax in axes:
            ax.set_xlabel("t [s]")
            ax.grid(alpha=0.3)
        axes[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.suptitle(f"{obj}: dropped and tumbling, MSF and the built-in contact")
        add_figure(fig, out, f"objects_{obj}.png", figs)
    lines.append(figure_links(figs))
    return "".join(lines), figs


SCENARIO = Scenario("objects", "pybullet_data objects (cube, cylinder, mesh) dropped and tumbling: MSF vs built-in",
                    load, cells, run_cell, report)
