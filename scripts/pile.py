"""A pile of spheres poured into a box, MSF on every sphere-sphere and
sphere-wall pair (issue 10: "200 spheres poured into a box (mixed steel and
rubber): settle with no energy gain at any step and rest at the static
overlaps, both engines, dt = 1 ms").

    .venv/bin/python scripts/pile.py --engine mujoco --n 16 --steps 600

Spheres of R = 10 mm, a quarter steel and the rest natural rubber (seeded
shuffle), on a square grid 2.2 R apart in layers, 5 mm above the floor,
with seeded random velocities up to 0.1 m/s, in a box of five steel planes
(floor and four walls) whose width holds ``--side`` spheres a row. Every
sphere-sphere and sphere-wall pair is managed (n (n - 1)/2 + 5 n pairs).

Reported per run (stdout, one JSON line):
- energy E = kinetic + potential (the adapters' energy probes: timing
  corrections taken out of the velocities) + stored in the open contacts
  (engines._contacts.balance.IslandBalance.stored: elastic energy of the
  internal overlap + W_t - Q_t), its largest rise in one step [J] and the
  step, the sum of its rises, and E at the start and the end;
- the islands' energy check (ContactManager.island_energy_gains): how many
  island steps were flagged and the largest gain;
- onsets found already overlapping (records' x_onset > TOUCH_TOL), the
  deepest;
- the fastest sphere at the end [m/s], whether it exploded (> 10 m/s), the
  wall time per step.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engines._contacts.balance import IslandBalance  # noqa: E402
from engines._contacts.islands import TOUCH_TOL  # noqa: E402
from engines.base import PairSpec  # noqa: E402
from msf_contact import Body, ContactPair, Curvature, make_law, preset  # noqa: E402

R, G = 0.01, 9.81
STEEL, RUBBER = preset("steel"), preset("natural-rubber")
EXPLODED = 10.0  # m/s: a sphere this fast has been thrown out by an energy gain


def layout(n: int, side: int, seed: int = 0):
    """Materials (n,), centres (n, 3) [m], velocities (n, 3) [m/s], box half width [m]."""
    rng = np.random.default_rng(seed)
    mats = [STEEL] * max(1, n // 4) + [RUBBER] * (n - max(1, n // 4))
    rng.shuffle(mats)
    sp = 2.2 * R
    half = (side - 1) / 2 * sp + 1.15 * R
    pos = np.array([[(i % side - (side - 1) / 2) * sp, ((i // side) % side - (side - 1) / 2) * sp,
                     R + 5e-3 + (i // (side * side)) * sp] for i in range(n)])
    pos[:, :2] += rng.uniform(-0.05 * R, 0.05 * R, (n, 2))
    vel = rng.uniform(-0.1, 0.1, (n, 3))
    return mats, pos, vel, half


WALLS = (((0, 0, 0), (0, 0, 1)), ((-1, 0, 0), (1, 0, 0)), ((1, 0, 0), (-1, 0, 0)), ((0, -1, 0), (0, 1, 0)),
         ((0, 1, 0), (0, -1, 0)))  # (position / half width, inward normal)


def laws_and_pairs(mats):
    """(i, j or -1 - wall index, law) for every pair."""
    cache = {}

    def law(a, b, plane):
        key = (a.name, b.name, plane)
        if key not in cache:
            cache[key] = make_law("msf", ContactPair(a, b),
                                  Curvature.sphere_on_plane(R) if plane else Curvature.two_spheres(R, R))
        return cache[key]

    out = []
    for i in range(len(mats)):
        out += [(i, j, law(mats[i], mats[j], False)) for j in range(i)]
        out += [(i, -1 - w, law(mats[i], STEEL, True)) for w in range(len(WALLS))]
    return out


def build_mujoco(n, side, dt):
    import mujoco

    from engines.mujoco import MujocoAdapter

    mats, pos, vel, half = layout(n, side)
    bodies = "".join(
        f'<body name="b{k}" pos="{float(p[0])!r} {float(p[1])!r} {float(p[2])!r}"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{Body.sphere(m, R).mass!r}" diaginertia="{Body.sphere(m, R).J!r} '
        f'{Body.sphere(m, R).J!r} {Body.sphere(m, R).J!r}"/>'
        f'<geom name="b{k}" type="sphere" size="{R!r}" contype="0" conaffinity="0"/></body>'
        for k, (m, p) in enumerate(zip(mats, pos)))
    walls = "".join(f'<geom name="w{w}" type="plane" pos="{c[0] * half!r} {c[1] * half!r} 0" '
                    f'zaxis="{z[0]} {z[1]} {z[2]}" size="1 1 0.1" contype="0" conaffinity="0"/>'
                    for w, (c, z) in enumerate(WALLS))
    xml = (f'<mujoco><option timestep="{dt!r}" integrator="Euler" gravity="0 0 {-G!r}">'
           f'<flag autoreset="disable"/></option><worldbody>{walls}{bodies}</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for k, v in enumerate(vel):
        data.qvel[6 * k:6 * k + 3] = v
    mujoco.mj_forward(model, data)
    specs = [PairSpec(f"b{i}", f"b{j}" if j >= 0 else f"w{-1 - j}", law) for i, j, law in laws_and_pairs(mats)]
    ad = MujocoAdapter(model, data, specs)

    def speeds():
        return np.linalg.norm(data.qvel.reshape(-1, 6)[:, :3], axis=1)

    return ad, ad, speeds


def build_pybullet(n, side, dt):
    import pybullet as pb

    from engines.pybullet import PybulletAdapter, scenes

    mats, pos, vel, half = layout(n, side)
    c = scenes.new_client(dt, G)
    walls = []
    for cpos, z in WALLS:
        shape = pb.createCollisionShape(pb.GEOM_PLANE, planeNormal=list(z), physicsClientId=c)
        walls.append(pb.createMultiBody(0.0, shape, basePosition=[cpos[0] * half, cpos[1] * half, 0.0],
                                        physicsClientId=c))
    uids = [scenes.add_sphere(c, Body.sphere(m, R), p, v) for m, p, v in zip(mats, pos, vel)]
    specs = [PairSpec((uids[i], -1), (uids[j], -1) if j >= 0 else (walls[-1 - j], -1), law)
             for i, j, law in laws_and_pairs(mats)]
    ad = PybulletAdapter(c, specs)
    ctx = contextlib.ExitStack()
    ctx.callback(pb.disconnect, c)
    ctx.enter_context(ad)

    def speeds():
        return np.array([np.linalg.norm(pb.getBaseVelocity(u, physicsClientId=c)[0]) for u in uids])

    return ad, ctx, speeds


def energy(ad) -> float:
    """Kinetic + potential + stored energy of the pile [J] (module docstring)."""
    mgr = ad.manager
    keys = np.unique(mgr._coupling[0][mgr._coupling[0] >= 0])
    if hasattr(ad, "_read_bodies"):  # pybullet: the state now, not the last step start's
        T, U, _q, _m = ad._energy_probe(keys, ad._read_bodies())
    else:  # MuJoCo: bring xipos, ximat and cvel to the state after the step (no hook call)
        import mujoco

        for f in (mujoco.mj_kinematics, mujoco.mj_comPos, mujoco.mj_comVel):
            f(ad.model, ad.data)
        T, U, _q, _m = ad._energy_probe(keys)
    return float(np.sum(T) + np.sum(U)) + IslandBalance.stored(mgr, np.flatnonzero(mgr.active))


def run(engine: str, n: int, side: int, steps: int, dt: float) -> dict:
    ad, ctx, speeds = (build_mujoco if engine == "mujoco" else build_pybullet)(n, side, dt)
    mgr = ad.manager
    records = []
    rise, rise_at, rise_sum, exploded = 0.0, -1, 0.0, None
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ctx:
            e0 = e_prev = energy(ad)
            for k in range(steps):
                ad.step(1)
                e = energy(ad)
                if e - e_prev > rise:
                    rise, rise_at = e - e_prev, k
                rise_sum += max(e - e_prev, 0.0)
                e_prev = e
                records += ad.pop_records()
                if speeds().max() > EXPLODED:
                    exploded = k
                    break
            records += ad.pop_records()
            x_on = np.array([r.inputs["x_onset"] for r in records] + [mgr.x_onset[p] for p in mgr.active_pairs])
            v_end = float(speeds().max())
    wall = time.perf_counter() - t0
    gains = mgr.island_energy_gains
    return {"engine": engine, "n": n, "side": side, "pairs": len(mgr.pairs), "dt": dt, "steps_run": k + 1,
            "E_start_J": e0, "E_end_J": e_prev, "max_step_rise_J": rise, "max_rise_step": rise_at,
            "sum_of_rises_J": rise_sum, "island_steps_flagged": len(gains),
            "largest_island_gain_J": max((g[2] for g in gains), default=0.0),
            "deep_onsets": int(np.count_nonzero(x_on > TOUCH_TOL)), "deepest_onset_m": float(max(x_on.max(initial=0), 0)),
            "v_max_end_m_s": v_end, "exploded_at_step": exploded, "wall_s_per_step": wall / (k + 1)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", choices=("mujoco", "pybullet"), default="mujoco")
    ap.add_argument("--n", type=int, default=16, help="spheres")
    ap.add_argument("--side", type=int, default=3, help="spheres a row in the box")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--dt", type=float, default=1e-3)
    a = ap.parse_args(argv)
    for name, v in (("n", a.n), ("side", a.side), ("steps", a.steps)):
        if v < 1:
            raise ValueError(f"{name} = {v!r} must be >= 1")
    if not a.dt > 0:
        raise ValueError(f"dt = {a.dt!r} s must be > 0")
    print(json.dumps(run(a.engine, a.n, a.side, a.steps, a.dt)))


if __name__ == "__main__":
    main()
