"""A pile of spheres poured into a box, MSF on every sphere-sphere and
sphere-wall pair (issue 10: "200 spheres poured into a box (mixed steel and
rubber): settle with no energy gain at any step and rest at the static
overlaps, both engines, dt = 1 ms").

    .venv/bin/python scripts/pile.py --engine mujoco --n 8 --side 2 --steps 400

Spheres of R = 10 mm, a quarter steel and the rest natural rubber (seeded
shuffle), on a square grid 2.2 R apart in layers, 5 mm above the floor,
with seeded random velocities up to 0.1 m/s, in a box of five steel planes
(floor and four walls) whose width holds ``--side`` spheres a row. Every
sphere-sphere and sphere-wall pair is managed (n (n - 1)/2 + 5 n pairs).

Energy, read at the start of every step inside the adapter's hook (where
the island energy check reads it, engines._contacts.balance: the last
step's timing corrections are taken out of the velocities at the lever arms
their removal uses):

- ``E`` = kinetic + potential at z - (dt/2) v + the contacts' stored energy
  as the island check counts it (``ContactManager.stored_energy``, the one
  measure, engines._contacts.balance): for each open contact the elastic
  energy of its normal force at the internal overlap plus W_t - Q_t, and
  W_t - Q_t of every finished contact. The potential is taken at
  z - (dt/2) v because the engines' semi-implicit Euler moves a body by
  dt v_end: in free fall m v^2/2 + m g (z - dt v/2) is exactly conserved
  step by step, while m g z rises and falls by m g dt |dv|/2 with every
  change of velocity. E changes only by the contacts' viscous work if the
  step integrates what the engine then does: a rise of E is a gain of the
  integration (the issue's "energy gain"). (``E_phys``, the same with
  k |s|^2 / 2 of the tangential springs in place of W_t - Q_t, is gone: MSF's
  tangential stiffness grows with the overlap, k ~ sqrt(x), and k |s|^2 / 2
  rose by |s|^2 dk / 2 with no work, issue 13.)

Reported (stdout, one JSON line): E at the start and the end,
its largest rise in one step and the step, the sum of its rises, and its
largest rise beyond (dt/2)|dq| (q = gravity's power m g . v: a settled
step, the resting contacts' backward Euler, is exact in kinetic +
potential at z + stored, and E differs from that by dt q / 2, so a
settling pile's E moves by up to (dt/2)|dq| a step with no gain; the
island check allows the same term, engines._contacts.balance); the
island energy check (island steps flagged, largest gain); onsets found
already overlapping (records' x_onset beyond x_surface_onset, the indentation
of a surface still recovering from a force-zero end, by more than TOUCH_TOL); settling: the fastest
sphere at the end, the first step from which every sphere stays slower
than REST_SPEED, and the end state against statics: the floor's and walls'
vertical force on the spheres against their weight, and each contact's
overlap against the static overlap of the law's elastic force for the
normal force it carries, and the engine's own overlaps from the sphere
centres (engine_overlaps) against the same; the wall and CPU time per step
(the process's, ``time.process_time``: on a shared machine the wall time
is the load's); ``settled_share``: the candidate rows a settled step took
(rows alone and resting islands, engines._contacts.resting) over all the
candidate rows, summed over the steps.
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

from engines._contacts.islands import TOUCH_TOL  # noqa: E402
from engines.base import PairSpec  # noqa: E402
from msf_contact import Body, ContactPair, Curvature, make_law, preset, static_overlap  # noqa: E402

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


def build_mujoco(n, side, dt, with_centres=False):
    """(adapter, context, speeds(), [centres()]): with_centres adds the spheres' centres (n, 3) [m]."""
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

    def centres():  # xpos after mj_step is the step start's (forward runs before the integration): refresh
        mujoco.mj_kinematics(model, data)
        return np.array([data.body(f"b{k}").xpos for k in range(n)])

    return (ad, ad, speeds, centres) if with_centres else (ad, ad, speeds)


def build_pybullet(n, side, dt, with_centres=False):
    """As build_mujoco."""
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

    def centres():
        return np.array([pb.getBasePositionAndOrientation(u, physicsClientId=c)[0] for u in uids])

    return (ad, ctx, speeds, centres) if with_centres else (ad, ctx, speeds)


def engine_overlaps(n: int, side: int, centres: np.ndarray) -> np.ndarray:
    """The approach of the undeformed surfaces of every pair (laws_and_pairs' order) from the
    engine's sphere centres (n, 3) [m]: 2 R - |c_i - c_j| for two spheres, R - (c_i - w) . n_w for a
    wall at w with inward normal n_w (P,) [m]; the engine's own geometry, not the manager's x."""
    half = layout(n, side)[3]
    out = []
    for i, j, _law in laws_and_pairs(layout(n, side)[0]):
        if j >= 0:
            out.append(2 * R - float(np.linalg.norm(centres[i] - centres[j])))
        else:
            c, z = WALLS[-1 - j]
            out.append(R - float(np.dot(centres[i] - half * np.asarray(c, float), np.asarray(z, float))))
    return np.array(out)


#: A sphere slower than this is at rest [m/s]: it moves < 1 um in a 1 ms step, 1 % of natural rubber's
#: static overlap under its own weight (x_s = 0.10 mm for R = 10 mm on steel).
REST_SPEED = 1e-3


def _probe(ad, keys):
    """Kinetic, potential energy and gravity's power (b,) each of the bodies keys, read inside the
    hook (the adapters' energy probe: the state at the step start, timing corrections taken out)."""
    T, U, q, _m = ad._energy_probe(keys)
    return np.asarray(T), np.asarray(U), np.asarray(q)


def energy(ad, keys) -> float:
    """E of the pile [J] now (module docstring); call inside the hook at a step start."""
    T, U, q = _probe(ad, keys)
    return float(np.sum(T) + np.sum(U) + 0.5 * ad.manager.dt * np.sum(q)) + ad.manager.stored_energy()


def static_overlaps(ad, x_engine=None) -> np.ndarray:
    """Per contact of the last step, (|x - x_s| / x_s, |x - x_s| [m], F_n [N]) (k, 3): the manager's
    overlap x (or, with x_engine (P,) [m], the engine's own, engine_overlaps) against x_s, the static
    overlap of the normal force F_n it carried (msf_contact.static_overlap: F_n(x_s, 0) = F_n, the law
    at zero rate with the contact's onset constants)."""
    mgr = ad.manager
    rel = []
    for r in ad.contact_forces():
        if r.overlap <= 0.0 or r.F_n <= 0.0:
            continue
        p = r.pair
        g = mgr._group_of[p]
        o = {k: v[mgr._pos[[p]]] for k, v in mgr._onset[g].items()}
        x_s = float(static_overlap(mgr._groups[g], r.F_n, o)[0])
        x = r.overlap if x_engine is None else float(x_engine[p])
        rel.append((abs(x - x_s) / x_s, abs(x - x_s), r.F_n))
    return np.array(rel).reshape(-1, 3)


#: Contacts carrying less than this share of a mean sphere's weight are left out of the relative
#: overlap-vs-static figures (a wall touched at 1e-4 N has x_s ~ 0.1 um: a 1 um difference is 10x);
#: their absolute difference is in the *_abs_m figures.
LOADED_SHARE = 0.1


def _static_summary(prefix: str, rel: np.ndarray, w_mean: float) -> dict:
    """Largest and median |x - x_s| / x_s over the contacts carrying >= LOADED_SHARE w_mean [N], and the
    largest |x - x_s| [m] over all; rel (k, 3) of static_overlaps."""
    loaded = rel[rel[:, 2] >= LOADED_SHARE * w_mean, 0]
    return {f"{prefix}overlap_vs_static_max_rel": float(loaded.max(initial=0.0)),
            f"{prefix}overlap_vs_static_median_rel": float(np.median(loaded)) if loaded.size else 0.0,
            f"{prefix}overlap_vs_static_max_abs_m": float(rel[:, 1].max(initial=0.0))}


def run(engine: str, n: int, side: int, steps: int, dt: float, every: int = 0, rest_steps: int = 0) -> dict:
    """The pile for up to ``steps`` steps (the module docstring's report). every > 0: a progress line
    (step, fastest sphere, largest rise of E so far, islands flagged, wall and CPU time per step) on stderr
    every that many steps; rest_steps > 0: stop once every sphere has stayed below REST_SPEED for
    that many steps."""
    builder = build_mujoco if engine == "mujoco" else build_pybullet
    ad, ctx, speeds, centres = builder(n, side, dt, with_centres=True)
    mgr = ad.manager
    rows_settled = rows_all = 0  # candidate rows taken by a settled step, candidate rows, summed over the steps
    keys = np.unique(mgr._coupling[0][mgr._coupling[0] >= 0])
    wall_pairs = np.array([j < 0 for _i, j, _law in laws_and_pairs(layout(n, side)[0])])  # sphere-plane pairs
    seq: list[float] = []
    inner = mgr.step

    hq: list[float] = []  # (dt/2) q at each step start, q gravity's power m g . v [J]

    def step(kin):  # the energy at the step start, inside the hook (module docstring)
        hq.append(0.5 * mgr.dt * float(np.sum(_probe(ad, keys)[2])))
        seq.append(energy(ad, keys))
        return inner(kin)

    mgr.step = step
    records = []
    exploded, rest_from = None, None
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with ctx:
            masses = None
            for k in range(steps + 1):  # the last step only reads the energy after step `steps`
                ad.step(1)
                if masses is None:
                    masses = np.asarray(ad._energy_probe(keys)[3], dtype=float)
                records += ad.pop_records()
                info = mgr.last_step_info or {}
                rows_settled += info.get("settled", 0)
                rows_all += info.get("rows", 0)
                v = speeds()
                if v.max() > EXPLODED:
                    exploded = k
                    break
                if v.max() < REST_SPEED:
                    rest_from = k if rest_from is None else rest_from
                else:
                    rest_from = None
                if every and k % every == 0:
                    rise = float(np.max(np.diff(seq), initial=0.0))
                    print(json.dumps({"step": k, "v_max_m_s": float(v.max()), "E_J": seq[-1], "E_max_step_rise_J": rise,
                                      "island_steps_flagged": len(mgr.island_energy_gains),
                                      "settled_share": rows_settled / max(rows_all, 1),
                                      "wall_s_per_step": (time.perf_counter() - t0) / len(seq),
                                      "cpu_s_per_step": (time.process_time() - c0) / len(seq)}), file=sys.stderr,
                          flush=True)
                if rest_steps and rest_from is not None and k - rest_from >= rest_steps:
                    break
            records += ad.pop_records()
            # an onset deeper than touching on a surface still recovering from a force-zero end is no deep
            # onset (engines._contacts.state.RECOVERY_DOC): counted beyond that surface's indentation
            x_on = np.array([r.inputs["x_onset"] - r.inputs.get("x_surface_onset", 0.0) for r in records]
                            + [mgr.x_onset[p] - mgr.x_surface_onset[p] for p in mgr.active_pairs])
            v_end = float(speeds().max())
            forces = ad.contact_forces()
            support = sum(float(r.force[2]) for r in forces if wall_pairs[r.pair])
            rel = static_overlaps(ad)
            rel_eng = static_overlaps(ad, engine_overlaps(n, side, centres()))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    E = np.array(seq)
    rise = np.diff(E)
    gains = mgr.island_energy_gains
    weight = float(np.sum(masses)) * G
    out = {"engine": engine, "n": n, "side": side, "pairs": len(mgr.pairs), "dt": dt, "steps_run": len(seq) - 1}
    out.update({"E_start_J": float(E[0]), "E_end_J": float(E[-1]),
                "E_max_step_rise_J": float(max(rise.max(initial=0.0), 0.0)),
                "E_max_rise_step": int(np.argmax(rise)) if rise.size and rise.max() > 0 else -1,
                "E_sum_of_rises_J": float(np.sum(np.maximum(rise, 0.0))),
                "E_max_step_rise_beyond_dq_J": float(max((rise - np.abs(np.diff(hq))).max(initial=0.0), 0.0))})
    out.update({"island_steps_flagged": len(gains), "largest_island_gain_J": max((g[2] for g in gains), default=0.0),
                "deep_onsets": int(np.count_nonzero(x_on > TOUCH_TOL)),
                "deepest_onset_m": float(max(x_on.max(initial=0), 0)),
                "v_max_end_m_s": v_end, "at_rest_from_step": rest_from, "exploded_at_step": exploded,
                "support_over_weight": support / weight, "contacts_end": int(rel.shape[0]),
                **_static_summary("", rel, weight / n), **_static_summary("engine_", rel_eng, weight / n),
                "settled_share": rows_settled / max(rows_all, 1),
                "wall_s_per_step": wall / len(seq), "cpu_s_per_step": cpu / len(seq)})
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", choices=("mujoco", "pybullet"), default="mujoco")
    ap.add_argument("--n", type=int, default=16, help="spheres")
    ap.add_argument("--side", type=int, default=3, help="spheres a row in the box")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--every", type=int, default=0, help="a progress line on stderr every this many steps")
    ap.add_argument("--rest-steps", type=int, default=0,
                    help="stop once every sphere has been slower than REST_SPEED for this many steps")
    ap.add_argument("--out", default=None,
                    help="write the result as JSON to this file, atomically (default: print it on stdout)")
    a = ap.parse_args(argv)
    for name, v in (("n", a.n), ("side", a.side), ("steps", a.steps)):
        if v < 1:
            raise ValueError(f"{name} = {v!r} must be >= 1")
    if not a.dt > 0:
        raise ValueError(f"dt = {a.dt!r} s must be > 0")
    result = run(a.engine, a.n, a.side, a.steps, a.dt, a.every, a.rest_steps)
    if a.out is None:
        print(json.dumps(result))
    else:  # temp file, then rename: an interrupted run leaves no half-written result
        from experiments._io import write_json_atomic
        write_json_atomic(a.out, result)


if __name__ == "__main__":
    main()
