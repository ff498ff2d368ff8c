"""Benchmark 7: cost of a 1,000-sphere pile in MuJoCo, MSF against the built-in contact.

N = 1,000 natural-rubber spheres (R = 20 mm) in a 10 x 10 x 10 lattice,
spacing 2R + GAP, over a steel floor (a plane), gravity 9.81 m/s^2,
dt = 1 ms: the pile falls, the layers press on each other and on the
floor. Two variants built in one process and timed interleaved, CPU time
of the process (``time.process_time``), median over repeats:

- ``msf``: MuJoCo's own contact off; every sphere-floor pair and every
  pair of lattice neighbours (centres within NEIGHBOUR_SPACINGS lattice
  spacings at the start: 13 per sphere inside the lattice) is an MSF pair
  through :class:`engines.mujoco.MujocoAdapter` (contacts that share a
  sphere within a step are solved together: islands);
- ``builtin``: MuJoCo's soft contact for every geom pair, its own broad
  phase, default solref/solimp.

This measures cost only. The MSF pile is not yet right (docs/engines.md:
a 16-sphere pile in a box exploded at step 180; issue 10 item 1, worked
on in parallel), and the explicit pair list holds only the starting
neighbours (no broad phase: spheres that become neighbours later do not
interact). The record says how many MSF contacts and island rows the last
timed step had, and whether the state stayed finite.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ._common import RADIUS, log, median_time

DT = 1e-3
GRAVITY = 9.81
SIDE = 10  # spheres per lattice edge (SIDE**3 spheres)
GAP = 1e-3  # between neighbouring spheres at the start [m]
#: Pairs between spheres whose centres start within this many lattice spacings.
NEIGHBOUR_SPACINGS = 1.75
WARMUP = 20
STEPS = 1
REPEATS = 3


def _centres(side: int) -> np.ndarray:
    s = 2 * RADIUS + GAP
    i = np.arange(side ** 3)
    return np.stack([(i % side) * s, (i // side % side) * s, RADIUS + GAP + (i // side ** 2) * s], axis=1)


def _variant(mode: str, side: int):
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter
    from msf_contact import Body, ContactPair, Curvature, make_law, preset

    rubber, steel = preset("natural-rubber"), preset("steel")
    ball = Body.sphere(rubber, RADIUS)
    c = _centres(side)
    J = ball.J
    attr = 'contype="1" conaffinity="1"' if mode == "builtin" else 'contype="0" conaffinity="0"'
    bodies = "".join(
        f'<body name="b{i}" pos="{float(p[0])!r} {float(p[1])!r} {float(p[2])!r}"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{ball.mass!r}" diaginertia="{J!r} {J!r} {J!r}"/>'
        f'<geom name="g{i}" type="sphere" size="{RADIUS!r}" {attr}/></body>' for i, p in enumerate(c))
    xml = (f'<mujoco><size memory="64M"/><option timestep="{DT!r}" integrator="Euler" '
           f'gravity="0 0 {-GRAVITY!r}"/><worldbody><geom name="floor" type="plane" size="0 0 1" {attr}/>'
           f"{bodies}</worldbody></mujoco>")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    if mode == "builtin":
        def step(k):
            for _ in range(k):
                mujoco.mj_step(model, data)
        return step, lambda: {"contacts": int(data.ncon)}, None, data, 0
    floor_law = make_law("msf", ContactPair(rubber, steel), Curvature(RADIUS, RADIUS, math.inf, math.inf))
    pp_law = make_law("msf", ContactPair(rubber, rubber), Curvature.two_spheres(RADIUS, RADIUS))
    n = c.shape[0]
    d = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=2)
    near = np.argwhere(np.triu(d <= NEIGHBOUR_SPACINGS * (2 * RADIUS + GAP), k=1))
    pairs = [PairSpec(f"g{i}", "floor", floor_law) for i in range(n)]
    pairs += [PairSpec(f"g{i}", f"g{j}", pp_law) for i, j in near]
    adapter = MujocoAdapter(model, data, pairs)
    ctx = adapter.__enter__()

    def step(k):
        ctx.step(k)
        adapter.pop_records()

    def info():
        mgr = adapter.manager
        return {"contacts": mgr.active_count, "island_rows": int(mgr.last_step_info.get("island_rows", 0))}
    return step, info, adapter, data, len(pairs)


def measure(side: int = SIDE, warmup: int = WARMUP, steps: int = STEPS, repeats: int = REPEATS) -> dict:
    variants, handles = {}, []
    try:
        for mode in ("builtin", "msf"):  # MuJoCo cannot compile a model while the MSF hook is installed
            step, info, h, data, npairs = _variant(mode, side)
            handles.append(h)
            c0 = time.process_time()
            step(warmup)
            log(f"pile: {mode} warm-up {warmup} steps {time.process_time() - c0:.1f} s CPU")
            variants[mode] = (step, info, data, npairs)
        times = {m: [] for m in variants}
        for _ in range(repeats):
            for m, (step, *_rest) in variants.items():
                times[m].append(median_time(lambda: step(steps), 1, time.process_time)[0] / steps)
        infos = {m: v[1]() for m, v in variants.items()}
        finite = {m: bool(np.all(np.isfinite(v[2].qpos)) and np.all(np.isfinite(v[2].qvel)))
                  for m, v in variants.items()}
        top = {m: float(np.max(v[2].qpos.reshape(-1, 7)[:, 2])) for m, v in variants.items()}
    finally:
        for h in handles:
            if h is not None:
                h.__exit__(None, None, None)
    med = {m: float(np.median(t)) for m, t in times.items()}
    return {"name": "pile", "engine": "mujoco", "n_bodies": side ** 3, "dt": DT, "msf_pairs": variants["msf"][3],
            "msf_step_s": med["msf"], "builtin_step_s": med["builtin"],
            "ratio_msf_over_builtin": med["msf"] / med["builtin"], "warmup_steps": warmup,
            "steps_per_repeat": steps, "repeats": repeats,
            "median": "per-step median over repeats (CPU time of the process)",
            "msf_contacts_at_end": infos["msf"]["contacts"], "msf_island_rows_at_end": infos["msf"]["island_rows"],
            "builtin_contacts_at_end": infos["builtin"]["contacts"], "finite": finite, "highest_centre_m": top,
            "all_s": times}


def run(quick: bool = False) -> list[dict]:
    side = 4 if quick else SIDE
    log(f"pile: {side ** 3} spheres in MuJoCo, {REPEATS} repeats of {STEPS} steps after {WARMUP}")
    try:
        r = measure(side)
    except Exception as exc:  # noqa: BLE001 - reported, not fatal for the other benchmarks
        log(f"  failed: {type(exc).__name__}: {exc}")
        return [{"name": "pile", "engine": "mujoco", "n_bodies": side ** 3, "dt": DT, "failed": True,
                 "reason": f"{type(exc).__name__}: {exc}"[:300]}]
    log(f"  msf {r['msf_step_s'] * 1e3:.2f} ms, builtin {r['builtin_step_s'] * 1e3:.2f} ms per step (CPU), "
        f"ratio {r['ratio_msf_over_builtin']:.3g}, finite {r['finite']}")
    return [r]
