"""A column of spheres resting on a steel plate, MSF on every sphere-plate
and neighbour pair (issue 10: "rest at the static overlaps"):

    .venv/bin/python scripts/column.py --engine mujoco --column rs --steps 400

Spheres of R = 10 mm listed from the bottom up ("s" steel, "r" natural
rubber), placed touching each other and the plate, at rest, under gravity,
dt = 1 ms. Reported (one JSON line): per loaded contact (the bottom
sphere's plate contact, then each sphere on the one below) the internal
overlap x (the manager's), the engine's own overlap from the sphere
centres, and the static overlap x_s of the weight above it
(msf_contact.statics: F_n(x_s, 0) = g sum of the masses above); the
largest rise of the energy E in a step beyond (dt/2)|dq|, E as
scripts/pile.py's (kinetic + potential at z - dt v/2 + the contacts'
stored energy, read at each step start) and q gravity's power m g . v (a
settled step is backward Euler, exact in kinetic + potential at z +
stored: the two measures differ by dt q / 2); the island steps flagged;
the fastest sphere at the end and the first step from which all stay
below REST_SPEED.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engines.base import PairSpec  # noqa: E402
from msf_contact import Body, ContactPair, Curvature, column_loads, make_law, preset, static_overlap  # noqa: E402

R, G = 0.01, 9.81
MATERIALS = {"s": preset("steel"), "r": preset("natural-rubber")}
#: A sphere slower than this is at rest [m/s] (scripts/pile.py: < 1 um in a 1 ms step).
REST_SPEED = 1e-3


def _pile():
    import importlib.util

    spec = importlib.util.spec_from_file_location("pile", Path(__file__).resolve().parent / "pile.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def build(engine: str, column: str, dt: float):
    """(adapter, context, state() -> (centres (n, 3) [m], velocities (n, 3) [m/s]), bodies, laws, loaded
    pair indices (bottom on the plate, then each sphere on the one below))."""
    mats = [MATERIALS[c] for c in column]
    n = len(mats)
    bodies = [Body.sphere(m, R) for m in mats]
    pairs, laws = [], []
    for k in range(n):  # each sphere on the plate (only the bottom one touches it) and on the one below
        pairs.append((k, -1))
        laws.append(make_law("msf", ContactPair(mats[k], MATERIALS["s"]), Curvature.sphere_on_plane(R)))
        if k:
            pairs.append((k, k - 1))
            laws.append(make_law("msf", ContactPair(mats[k], mats[k - 1]), Curvature.two_spheres(R, R)))
    loaded = [0] + [i for i, (_a, b) in enumerate(pairs) if b >= 0]
    pos = [[0.0, 0.0, R + 2.0 * R * k] for k in range(n)]
    if engine == "mujoco":
        import mujoco

        from engines.mujoco import MujocoAdapter

        geoms = "".join(
            f'<body name="b{k}" pos="0 0 {p[2]!r}"><freejoint/><inertial pos="0 0 0" mass="{b.mass!r}" '
            f'diaginertia="{b.J!r} {b.J!r} {b.J!r}"/><geom name="b{k}" type="sphere" size="{R!r}" contype="0" '
            'conaffinity="0"/></body>' for k, (b, p) in enumerate(zip(bodies, pos)))
        xml = (f'<mujoco><option timestep="{dt!r}" integrator="Euler" gravity="0 0 {-G!r}"/><worldbody>'
               '<geom name="plate" type="plane" size="1 1 0.1" contype="0" conaffinity="0"/>'
               f'{geoms}</worldbody></mujoco>')
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        ad = MujocoAdapter(model, data, [PairSpec(f"b{i}", "plate" if j < 0 else f"b{j}", law)
                                         for (i, j), law in zip(pairs, laws)])

        def state():
            return (np.array([data.qpos[7 * k:7 * k + 3] for k in range(n)]),
                    np.array([data.qvel[6 * k:6 * k + 3] for k in range(n)]))

        return ad, ad, state, bodies, laws, loaded
    import pybullet as pb

    from engines.pybullet import PybulletAdapter, scenes

    c = scenes.new_client(dt, G)
    plate = scenes.add_plate(c)
    uids = [scenes.add_sphere(c, b, p, [0.0, 0.0, 0.0]) for b, p in zip(bodies, pos)]
    ad = PybulletAdapter(c, [PairSpec((uids[i], -1), (plate, -1) if j < 0 else (uids[j], -1), law)
                             for (i, j), law in zip(pairs, laws)])
    ctx = contextlib.ExitStack()
    ctx.callback(pb.disconnect, c)
    ctx.enter_context(ad)

    def state():
        return (np.array([pb.getBasePositionAndOrientation(u, physicsClientId=c)[0] for u in uids]),
                np.array([pb.getBaseVelocity(u, physicsClientId=c)[0] for u in uids]))

    return ad, ctx, state, bodies, laws, loaded


def run(engine: str, column: str, steps: int, dt: float = 1e-3) -> dict:
    """The column for ``steps`` steps (the module docstring's report)."""
    pile = _pile()
    ad, ctx, state, bodies, laws, loaded = build(engine, column, dt)
    mgr = ad.manager
    keys = np.unique(mgr._coupling[0][mgr._coupling[0] >= 0])
    E, hq = [], []
    inner = mgr.step

    def step(kin):  # the energy at the step start, inside the hook (scripts/pile.py)
        hq.append(0.5 * mgr.dt * float(np.sum(pile._probe(ad, keys)[2])))
        E.append(pile.energy(ad, keys))
        return inner(kin)

    mgr.step = step
    rest_from = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ctx:
            for k in range(steps + 1):  # the last step only reads the energy after step `steps`
                ad.step(1)
                slow = float(np.abs(state()[1]).max()) < REST_SPEED
                rest_from = (k if rest_from is None else rest_from) if slow else None
            pos, vel = state()
            x_int = mgr.x[loaded].copy()
            active = mgr.active[loaded].copy()
            onset = [{key: v[mgr._pos[[p]]] for key, v in mgr._onset[mgr._group_of[p]].items()} for p in loaded]
    F = column_loads([b.mass for b in bodies], G)
    x_s = [float(static_overlap(laws[p], [F[k]], onset[k])[0]) for k, p in enumerate(loaded)]
    x_eng = [R - pos[0, 2]] + [2.0 * R - (pos[k, 2] - pos[k - 1, 2]) for k in range(1, len(bodies))]
    rise = np.diff(E) - np.abs(np.diff(hq))
    return {"engine": engine, "column": column, "dt": dt, "steps": steps,
            "E_max_step_rise_beyond_dq_J": float(rise.max()), "E_max_rise_step": int(rise.argmax()),
            "island_steps_flagged": len(mgr.island_energy_gains), "v_max_end_m_s": float(np.abs(vel).max()),
            "at_rest_from_step": rest_from, "in_contact": active.tolist(), "load_N": F.tolist(),
            "x_static_m": x_s, "x_internal_m": x_int.tolist(), "x_engine_m": [float(v) for v in x_eng]}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", choices=("mujoco", "pybullet"), default="mujoco")
    ap.add_argument("--column", default="rs", help="materials from the bottom up: s steel, r natural rubber")
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--dt", type=float, default=1e-3)
    a = ap.parse_args(argv)
    if not a.column or set(a.column) - set(MATERIALS):
        raise ValueError(f"column = {a.column!r} must be a non-empty string of {sorted(MATERIALS)}")
    if a.steps < 1:
        raise ValueError(f"steps = {a.steps!r} must be >= 1")
    if not a.dt > 0:
        raise ValueError(f"dt = {a.dt!r} s must be > 0")
    print(json.dumps(run(a.engine, a.column, a.steps, a.dt)))


if __name__ == "__main__":
    main()
