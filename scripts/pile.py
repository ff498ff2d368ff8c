"""A pile of spheres poured into a box, MSF on every sphere-sphere and
sphere-wall pair (issue 10: "200 spheres poured into a box (mixed steel and
rubber): settle with no energy gain at any step and rest at the static
overlaps, both engines, dt = 1 ms").

    .venv/bin/python scripts/pile.py --engine mujoco --n 8 --side 2 --steps 400

Spheres of R = 10 mm, a quarter steel and the rest natural rubber (seeded
shuffle), on a square grid 2.2 R apart in layers, 5 mm above the floor,
with seeded random velocities up to 0.1 m/s (``--pour grid``, the default;
``--pour low`` stacks the layers in the hollows of the layer below, each
0.5 mm above touching: POURS), in a box of five steel planes
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
sphere at the end, the first step from which the pile stays at rest
(``at_rest_from_step``, REST_DOC: every sphere still or rolling steadily)
and the first from which every sphere stays slower than REST_SPEED
(``still_from_step``), each sphere still moving at the end (``rolling_end``),
and the end state against statics: the floor's and walls'
vertical force on the spheres against their weight, and each contact's
overlap against the static overlap of the law's elastic force for the
normal force it carries, and the engine's own overlaps from the sphere
centres (engine_overlaps) against the same; the wall and CPU time per step
(the process's, ``time.process_time``: on a shared machine the wall time
is the load's; the progress lines add the CPU a step since the line before); ``settled_share``: the candidate rows a settled step took
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


#: The pours (``--pour``): "grid", layers of side x side spheres 2.2 R apart, stacked 2.2 R apart straight
#: above each other from 5 mm above the floor, lateral offsets up to 0.05 R, velocities up to 0.1 m/s (the
#: upper layers topple into the hollows below: the top layer falls ~5 cm); "low", the same spheres in layers
#: that alternate the side x side grid and the (side - 1) x (side - 1) grid of its hollows, each layer
#: LOW_GAP above the height at which it would touch the layer below (or the floor), lateral offsets up to
#: 0.01 R, velocities up to 0.01 m/s: a pour from low height (the top layer falls a few mm).
POURS = ("grid", "low")
LOW_GAP = 0.5e-3  # m: above touching, > the offsets' largest effect on a hollow's height (0.22 mm at 0.01 R)


def layout(n: int, side: int, seed: int = 0, pour: str = "grid"):
    """Materials (n,), centres (n, 3) [m], velocities (n, 3) [m/s], box half width [m] of the pour
    (POURS)."""
    if pour not in POURS:
        raise ValueError(f"pour = {pour!r} must be one of {POURS}")
    rng = np.random.default_rng(seed)
    mats = [STEEL] * max(1, n // 4) + [RUBBER] * (n - max(1, n // 4))
    rng.shuffle(mats)
    sp = 2.2 * R
    half = (side - 1) / 2 * sp + 1.15 * R
    if pour == "grid":
        pos = np.array([[(i % side - (side - 1) / 2) * sp, ((i // side) % side - (side - 1) / 2) * sp,
                         R + 5e-3 + (i // (side * side)) * sp] for i in range(n)])
        pos[:, :2] += rng.uniform(-0.05 * R, 0.05 * R, (n, 2))
        vel = rng.uniform(-0.1, 0.1, (n, 3))
        return mats, pos, vel, half
    # "low": a sphere in the hollow of four touching neighbours sp apart (diagonal sp / sqrt 2) sits
    # sqrt(4 R^2 - sp^2 / 2) above them; a one-sphere-wide box stacks them 2 R apart
    rise = 2 * R if side == 1 else float(np.sqrt(4 * R * R - sp * sp / 2))
    pos, z, layer = [], R + LOW_GAP, 0
    while len(pos) < n:
        m = side - layer % 2 if side > 1 else 1
        for i in range(min(m * m, n - len(pos))):
            pos.append([(i % m - (m - 1) / 2) * sp, (i // m - (m - 1) / 2) * sp, z])
        z += rise + LOW_GAP
        layer += 1
    pos = np.array(pos)
    pos[:, :2] += rng.uniform(-0.01 * R, 0.01 * R, (n, 2))
    vel = rng.uniform(-0.01, 0.01, (n, 3))
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


def build_mujoco(n, side, dt, with_centres=False, pour="grid"):
    """(adapter, context, velocities(), [centres()]) of the pour (POURS): velocities() the spheres'
    linear and angular velocities in the world frame (n, 2, 3) [m/s, 1/s] after the last step;
    with_centres adds the spheres' centres (n, 3) [m]."""
    import mujoco

    from engines.mujoco import MujocoAdapter

    mats, pos, vel, half = layout(n, side, pour=pour)
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

    def velocities():  # a free joint's angular velocity is in the body's frame: turned to the world's by
        q = data.qvel.reshape(-1, 6)  # the joint's quaternion (w, u): w' = w + 2 q0 u x w + 2 u x (u x w)
        quat = data.qpos.reshape(-1, 7)[:, 3:]
        q0, u, w = quat[:, :1], quat[:, 1:], q[:, 3:]
        uw = np.cross(u, w)
        return np.stack([q[:, :3], w + 2 * q0 * uw + 2 * np.cross(u, uw)], axis=1)

    def centres():  # xpos after mj_step is the step start's (forward runs before the integration): refresh
        mujoco.mj_kinematics(model, data)
        return np.array([data.body(f"b{k}").xpos for k in range(n)])

    return (ad, ad, velocities, centres) if with_centres else (ad, ad, velocities)


def build_pybullet(n, side, dt, with_centres=False, pour="grid"):
    """As build_mujoco."""
    import pybullet as pb

    from engines.pybullet import PybulletAdapter, scenes

    mats, pos, vel, half = layout(n, side, pour=pour)
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

    def velocities():
        return np.array([pb.getBaseVelocity(u, physicsClientId=c) for u in uids])

    def centres():
        return np.array([pb.getBasePositionAndOrientation(u, physicsClientId=c)[0] for u in uids])

    return (ad, ctx, velocities, centres) if with_centres else (ad, ctx, velocities)


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


#: A sphere slower than this is still [m/s]: it moves < 1 um in a 1 ms step, 1 % of natural rubber's
#: static overlap under its own weight (x_s = 0.10 mm for R = 10 mm on steel).
REST_SPEED = 1e-3
#: A sphere whose velocity and angular velocity (times R) change by less than STEADY_ACC dt in a step
#: moves steadily [m/s^2]: the resultant of its contact forces and its weight is below 0.1 % of its
#: weight (the engines' Euler step: dv = dt F / m), their torque below 0.1 % of m g R.
STEADY_ACC = 1e-3 * G

REST_DOC = """At rest (``at_rest_from_step``): every sphere, in every step of the
window (``--rest-steps``), is still (slower than REST_SPEED) or moves
steadily (STEADY_ACC: its contact forces balance its weight to 0.1 %, and
their torque to 0.1 % of m g R), and the kinetic energy of the spheres not
still does not rise over the window (MOVING_T_RTOL, ROUNDOFF_T: a sphere
that begins to move, or rolls down a slope, starts the window again). MSF is a point contact with no rolling
resistance (the paper's law has none): a sphere that rolls without slip on
the floor or along a groove of the pile, its contacts at the static
overlaps of the forces that hold its weight, keeps its speed for ever, as
a rigid ball would; that is rest in every contact, not energy gain, and
the criterion names it (``rolling_end``: each sphere faster than
REST_SPEED at the end, its speed, height and contacts). ``still_from_step``
is the stricter criterion of before (every sphere slower than REST_SPEED
for the window), which a rolling sphere never meets."""
#: The moving spheres' kinetic energy "does not rise" over a rest window (REST_DOC) if it stays below its
#: value at the window's start times 1 + MOVING_T_RTOL plus ROUNDOFF_T [J]: a steadily rolling steel
#: sphere (3.9 mm/s, 3.5e-7 J) changes its speed by ~1e-10 m/s over hundreds of steps (5e-8 of its
#: kinetic energy); ROUNDOFF_T is 1e-3 of a rubber sphere's kinetic energy at REST_SPEED.
MOVING_T_RTOL = 1e-6
ROUNDOFF_T = 1e-12


class RestWatch:
    """The rest criterion of REST_DOC, fed each step's velocities.

    m, J (n,): the spheres' masses [kg] and moments of inertia [kg m^2]; dt [s]. update(k, vel) takes
    step k's linear and angular velocities (n, 2, 3) [m/s, 1/s] (world frame) and keeps ``rest_from``
    (the first step of the current run of rest steps whose kinetic energy has not risen above its first,
    or None) and ``still_from`` (the same with every sphere slower than REST_SPEED, or None)."""

    def __init__(self, m, J, dt: float):
        self.m, self.J, self.dt = np.asarray(m, float), np.asarray(J, float), dt
        self.rest_from = self.still_from = None
        self._prev = None
        self._T0 = 0.0  # the kinetic energy at the window's start [J]
        self.still = self.steady = np.zeros(self.m.size, bool)

    def update(self, k: int, vel: np.ndarray) -> None:
        vel = np.asarray(vel, float)
        self.still = np.linalg.norm(vel[:, 0], axis=1) < REST_SPEED
        if self._prev is None:
            self.steady = np.zeros(self.m.size, bool)
        else:
            d = np.maximum(np.linalg.norm(vel[:, 0] - self._prev[:, 0], axis=1),
                           R * np.linalg.norm(vel[:, 1] - self._prev[:, 1], axis=1))
            self.steady = d < STEADY_ACC * self.dt
        self._prev = vel
        T = float(np.sum(np.where(self.still, 0.0, 0.5 * self.m * np.sum(vel[:, 0] ** 2, axis=1)
                                  + 0.5 * self.J * np.sum(vel[:, 1] ** 2, axis=1))))
        self.still_from = (k if self.still_from is None else self.still_from) if np.all(self.still) else None
        if not np.all(self.still | self.steady):
            self.rest_from = None
        elif self.rest_from is None or T > self._T0 * (1 + MOVING_T_RTOL) + ROUNDOFF_T:  # kinetic energy rose
            self.rest_from, self._T0 = k, T


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


def run(engine: str, n: int, side: int, steps: int, dt: float, every: int = 0, rest_steps: int = 0,
        pour: str = "grid") -> dict:
    """The pile for up to ``steps`` steps (the module docstring's report). every > 0: a progress line
    (step, fastest sphere, largest rise of E so far, islands flagged, wall and CPU time per step) on stderr
    every that many steps; rest_steps > 0: stop once the pile has stayed at rest (REST_DOC) for that
    many steps; pour: POURS."""
    builder = build_mujoco if engine == "mujoco" else build_pybullet
    ad, ctx, velocities, centres = builder(n, side, dt, with_centres=True, pour=pour)
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
    exploded, rest_from, still_from = None, None, None
    sph = [Body.sphere(m, R) for m in layout(n, side)[0]]
    watch = RestWatch([b.mass for b in sph], [b.J for b in sph], dt)
    t0, c0 = time.perf_counter(), time.process_time()
    c_line, k_line = c0, 0
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
                vel = velocities()
                v = np.linalg.norm(vel[:, 0], axis=1)
                if v.max() > EXPLODED:
                    exploded = k
                    break
                watch.update(k, vel)
                rest_from, still_from = watch.rest_from, watch.still_from
                if every and k % every == 0:
                    rise = float(np.max(np.diff(seq), initial=0.0))
                    c_now = time.process_time()
                    print(json.dumps({"step": k, "v_max_m_s": float(v.max()), "E_J": seq[-1], "E_max_step_rise_J": rise,
                                      "moving": int(np.count_nonzero(~watch.still)),
                                      "unsteady": int(np.count_nonzero(~(watch.still | watch.steady))),
                                      "island_steps_flagged": len(mgr.island_energy_gains),
                                      "settled_share": rows_settled / max(rows_all, 1),
                                      "wall_s_per_step": (time.perf_counter() - t0) / len(seq),
                                      "cpu_s_per_step": (c_now - c0) / len(seq),
                                      "cpu_s_per_step_since_last_line": (c_now - c_line) / max(k - k_line, 1)}),
                          file=sys.stderr, flush=True)
                    c_line, k_line = c_now, k
                if rest_steps and rest_from is not None and k - rest_from >= rest_steps:
                    break
            records += ad.pop_records()
            # an onset deeper than touching on a surface still recovering from a force-zero end is no deep
            # onset (engines._contacts.state.RECOVERY_DOC): counted beyond that surface's indentation
            x_on = np.array([r.inputs["x_onset"] - r.inputs.get("x_surface_onset", 0.0) for r in records]
                            + [mgr.x_onset[p] - mgr.x_surface_onset[p] for p in mgr.active_pairs])
            vel = velocities()
            v_end = float(np.linalg.norm(vel[:, 0], axis=1).max())
            forces = ad.contact_forces()
            support = sum(float(r.force[2]) for r in forces if wall_pairs[r.pair])
            rel = static_overlaps(ad)
            c_end = centres()
            rel_eng = static_overlaps(ad, engine_overlaps(n, side, c_end))
            pair_ij = [(i, j) for i, j, _law in laws_and_pairs(layout(n, side)[0])]
            rolling = []
            for b in np.flatnonzero(np.linalg.norm(vel[:, 0], axis=1) >= REST_SPEED):
                touching = [(pair_ij[r.pair][1] if pair_ij[r.pair][0] == b else pair_ij[r.pair][0], r.F_n)
                            for r in forces if b in pair_ij[r.pair] and r.F_n > 0]
                rolling.append({"sphere": int(b), "material": layout(n, side)[0][b].name,
                                "speed_m_s": float(np.linalg.norm(vel[b, 0])),
                                "omega_R_m_s": float(R * np.linalg.norm(vel[b, 1])),
                                "height_above_floor_m": float(c_end[b, 2] - R),
                                "contacts": [{"with": (f"sphere {o}" if o >= 0 else f"wall {-1 - o}"), "F_n_N": float(f)}
                                             for o, f in touching]})
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    E = np.array(seq)
    rise = np.diff(E)
    gains = mgr.island_energy_gains
    weight = float(np.sum(masses)) * G
    out = {"engine": engine, "n": n, "side": side, "pour": pour, "pairs": len(mgr.pairs), "dt": dt, "steps_run": len(seq) - 1}
    out.update({"E_start_J": float(E[0]), "E_end_J": float(E[-1]),
                "E_max_step_rise_J": float(max(rise.max(initial=0.0), 0.0)),
                "E_max_rise_step": int(np.argmax(rise)) if rise.size and rise.max() > 0 else -1,
                "E_sum_of_rises_J": float(np.sum(np.maximum(rise, 0.0))),
                "E_max_step_rise_beyond_dq_J": float(max((rise - np.abs(np.diff(hq))).max(initial=0.0), 0.0))})
    out.update({"island_steps_flagged": len(gains), "largest_island_gain_J": max((g[2] for g in gains), default=0.0),
                "deep_onsets": int(np.count_nonzero(x_on > TOUCH_TOL)),
                "deepest_onset_m": float(max(x_on.max(initial=0), 0)),
                "v_max_end_m_s": v_end, "at_rest_from_step": rest_from, "still_from_step": still_from,
                "rolling_end": rolling, "exploded_at_step": exploded,
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
    ap.add_argument("--pour", choices=POURS, default="grid", help="how the spheres start (POURS)")
    ap.add_argument("--every", type=int, default=0, help="a progress line on stderr every this many steps")
    ap.add_argument("--rest-steps", type=int, default=0,
                    help="stop once the pile has been at rest (REST_DOC) for this many steps")
    ap.add_argument("--out", default=None,
                    help="write the result as JSON to this file, atomically (default: print it on stdout)")
    a = ap.parse_args(argv)
    for name, v in (("n", a.n), ("side", a.side), ("steps", a.steps)):
        if v < 1:
            raise ValueError(f"{name} = {v!r} must be >= 1")
    if not a.dt > 0:
        raise ValueError(f"dt = {a.dt!r} s must be > 0")
    result = run(a.engine, a.n, a.side, a.steps, a.dt, a.every, a.rest_steps, a.pour)
    if a.out is None:
        print(json.dumps(result))
    else:  # temp file, then rename: an interrupted run leaves no half-written result
        from experiments._io import write_json_atomic
        write_json_atomic(a.out, result)


if __name__ == "__main__":
    main()
