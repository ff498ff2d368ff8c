"""Benchmark 1: per-step cost of N spheres resting/bouncing on a plate.

Each engine runs the same N free spheres (natural rubber, R = 20 mm, on a
steel plate; gravity 9.81 m/s^2; dt = 1 ms; seeded initial gaps in
[0, 0.5 mm]) three ways, built side by side in one process:

- ``msf``: MuJoCo/pybullet's own contact off, the MSF law through the adapter
  (sub-cycled inside each step);
- ``builtin``: the engine's own contact (MuJoCo soft contact with default
  solref/solimp and condim; pybullet's default contact);
- ``nocontact``: no collision at all (MuJoCo: the spheres collide with
  nothing; pybullet: collision filter masks 0).

In MuJoCo the MSF variant is also timed as a user steps it (the same
adapter and MjData, interleaved with the others): ``msf`` is
``adapter.step(k)``, ``msf_loop`` the user's own ``mujoco.mj_step`` loop
under the installed hook, ``msf_step1`` a loop of ``adapter.step(1)``.

After WARMUP steps (0.5 s: every sphere has bounced and come to rest, so
the timed steps are N resting contacts, which MSF handles on the manager's
settled path) each variant runs STEPS steps per repeat, the variants
interleaved (msf, builtin, nocontact, msf, ...) so machine noise hits them
alike, each repeat after REWARM untimed steps of its own; in MuJoCo the
built-in and no-contact variants are timed without the MSF variant's
mjcb_passive (MuJoCo's callbacks are global to the process: installed, it
would add a Python call per mj_step to theirs). Each variant runs the same
number of mj_step of the same scene at the same dt. The per-step figure is
the median over repeats of the process's CPU
time (``time.process_time``: on a shared machine other jobs' load changes
it less than wall time). The record also
gives how many MSF contacts took the settled path in the last step.
"""

from __future__ import annotations

import time

import numpy as np

from ._common import RADIUS, grid, log, median_time, rubber_on_steel

DT = 1e-3
GRAVITY = 9.81
#: Warm-up steps before timing: 0.5 s at DT, after which the spheres rest (module docstring).
WARMUP = 500
#: Untimed steps of a variant before each of its timed repeats, so that the repeat starts with its
#: own data in the caches and not the variant timed before it (measured at N = 1,000 in MuJoCo: the
#: variant timed right after MSF ran 10-20 us per step slower over 100 steps, ~2 % of the built-in).
REWARM = 5
SIZES = (1, 100, 1000, 10000)
QUICK_SIZES = (1, 100)


def _steps(n: int, engine: str) -> int:
    """Steps per timed repeat: ~0.05-0.2 s of the slowest variant per repeat
    on a 2-core machine (enough steps that the timer and one-off hiccups
    do not set the figure)."""
    if n <= 1:
        return 2000
    if n <= 100:
        return 500
    if n <= 1000:
        return 100
    return 10


# ------------------------------------------------------------------ MuJoCo --
def mujoco_variant(n: int, mode: str):
    """(step(k) callable, info callable) for N spheres in MuJoCo."""
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter

    law, ball = rubber_on_steel()
    J = ball.J
    ball_attr = {"msf": 'contype="0" conaffinity="0"', "builtin": 'contype="1" conaffinity="0"',
                 "nocontact": 'contype="0" conaffinity="0"'}[mode]
    bodies = "".join(
        f'<body name="b{i}" pos="{float(c[0])!r} {float(c[1])!r} {float(c[2])!r}"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{ball.mass!r}" diaginertia="{J!r} {J!r} {J!r}"/>'
        f'<geom name="g{i}" type="sphere" size="{RADIUS!r}" {ball_attr}/></body>'
        for i, c in enumerate(grid(n)))
    # MuJoCo's default arena is too small for 10,000 bodies and their contacts
    size = f'<size memory="{max(16, n // 10)}M"/>'
    xml = (f'<mujoco>{size}<option timestep="{DT!r}" integrator="Euler" gravity="0 0 {-GRAVITY!r}"/>'
           f'<worldbody><geom name="plate" type="plane" size="0 0 1" contype="0" conaffinity="1"/>{bodies}'
           "</worldbody></mujoco>")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    if mode != "msf":
        def step(k):
            for _ in range(k):
                mujoco.mj_step(model, data)
        return step, lambda: {"contacts": int(data.ncon)}, None
    adapter = MujocoAdapter(model, data, [PairSpec(f"g{i}", "plate", law) for i in range(n)])
    ctx = adapter.__enter__()  # the hook stays installed for the whole benchmark (closed by the caller)

    def step(k):
        ctx.step(k)
        adapter.pop_records()
    return step, lambda: _msf_info(adapter.manager), adapter


def mujoco_msf_ways(adapter) -> dict:
    """The MSF variant's other ways of stepping (module docstring), on its adapter and MjData:
    ``msf_loop`` the user's own ``mujoco.mj_step`` loop, ``msf_step1`` a loop of
    ``adapter.step(1)``; each pops the records after its k steps, as ``msf`` (``adapter.step(k)``)."""
    import mujoco

    m, d = adapter.model, adapter.data

    def loop(k):
        for _ in range(k):
            mujoco.mj_step(m, d)
        adapter.pop_records()

    def one(k):
        for _ in range(k):
            adapter.step(1)
        adapter.pop_records()
    return {"msf_loop": loop, "msf_step1": one}


def _msf_info(manager) -> dict:
    return {"contacts": manager.active_count, "settled": int(manager.last_step_info.get("settled", 0))}


# ----------------------------------------------------------------- pybullet --
def pybullet_variant(n: int, mode: str):
    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter
    from engines.pybullet.scenes import add_plate, add_sphere, new_client

    law, ball = rubber_on_steel()
    c = new_client(DT, GRAVITY)
    plate = add_plate(c, "plane")
    uids = [add_sphere(c, ball, pos) for pos in grid(n)]
    if mode == "nocontact":
        for u in uids + [plate]:
            pb.setCollisionFilterGroupMask(u, -1, 0, 0, physicsClientId=c)
    if mode != "msf":
        def step(k):
            for _ in range(k):
                pb.stepSimulation(physicsClientId=c)
        return step, lambda: {"contacts": len(pb.getContactPoints(physicsClientId=c))}, c
    adapter = PybulletAdapter(c, [PairSpec((u, -1), (plate, -1), law) for u in uids])

    def step(k):
        adapter.step(k)
        adapter.pop_records()
    return step, lambda: _msf_info(adapter.manager), adapter


def _close(engine, handle):
    if handle is None:
        return
    if engine == "mujoco":
        handle.__exit__(None, None, None)
    elif isinstance(handle, int):
        import pybullet as pb
        if pb.isConnected(handle):
            pb.disconnect(handle)
    else:
        handle.close()
        import pybullet as pb
        if pb.isConnected(handle.client):
            pb.disconnect(handle.client)


def _without_hook(step):
    """``step`` run with no mjcb_passive installed (the MSF variant's hook, restored after: a
    Python call per mj_step, 3-5 us measured with a no-op callable at N = 1,000), so the
    built-in and no-contact figures are MuJoCo's alone."""
    import mujoco

    hook = mujoco.get_mjcb_passive()

    def run(k):
        mujoco.set_mjcb_passive(None)
        try:
            step(k)
        finally:
            mujoco.set_mjcb_passive(hook)
    return run


def measure(engine: str, n: int, repeats: int) -> dict:
    build = mujoco_variant if engine == "mujoco" else pybullet_variant
    steps = _steps(n, engine)
    variants = {}
    handles = []
    try:
        # MuJoCo cannot compile a model while a Python mjcb_passive is installed: msf last
        for mode in ("builtin", "nocontact", "msf"):
            step, info, h = build(n, mode)
            handles.append(h)
            step(WARMUP)
            variants[mode] = (step, info)
            if engine == "mujoco" and mode == "msf":
                variants.update({w: (f, info) for w, f in mujoco_msf_ways(h).items()})
        if engine == "mujoco":  # MuJoCo's callback is global: the others run without the MSF variant's
            variants = {m: (v if m.startswith("msf") else (_without_hook(v[0]), v[1])) for m, v in variants.items()}
        times = {m: [] for m in variants}
        for _ in range(repeats):
            for m, (step, _) in variants.items():  # interleaved: noise hits every variant alike
                step(REWARM)
                times[m].append(median_time(lambda: step(steps), 1, time.process_time)[0] / steps)
        infos = {m: info() for m, (_, info) in variants.items()}
    finally:
        for h in handles:
            _close(engine, h)
    med = {m: float(np.median(t)) for m, t in times.items()}
    ways = {}
    for w in ("msf_loop", "msf_step1"):
        if w in med:
            ways.update({f"{w}_step_s": med[w], f"ratio_{w}_over_builtin": med[w] / med["builtin"]})
    return {**ways,
        "name": "per_step", "engine": engine, "n_bodies": n, "dt": DT,
        "msf_step_s": med["msf"], "builtin_step_s": med["builtin"], "nocontact_step_s": med["nocontact"],
        "ratio_msf_over_builtin": med["msf"] / med["builtin"],
        "ratio_msf_over_nocontact": med["msf"] / med["nocontact"],
        "median": "per-step median over repeats (CPU time of the process)", "repeats": repeats, "steps_per_repeat": steps,
        "warmup_steps": WARMUP, "rewarm_steps": REWARM,
        "msf_contacts_at_end": infos["msf"]["contacts"], "msf_settled_at_end": infos["msf"]["settled"],
        "builtin_contacts_at_end": infos["builtin"]["contacts"],
        "all_s": {m: t for m, t in times.items()},
    }


def run(quick: bool = False) -> list[dict]:
    out = []
    sizes = QUICK_SIZES if quick else SIZES
    for engine in ("mujoco", "pybullet"):
        for n in sizes:
            repeats = 3 if quick else 7
            log(f"per_step: {engine}, N = {n}, {repeats} repeats of {_steps(n, engine)} steps")
            try:
                r = measure(engine, n, repeats)
            except Exception as exc:  # noqa: BLE001 - one size failing must not lose the others
                log(f"  failed: {type(exc).__name__}: {exc}")
                out.append({"name": "per_step", "engine": engine, "n_bodies": n, "dt": DT, "failed": True,
                            "reason": f"{type(exc).__name__}: {exc}"[:300]})
                continue
            log(f"  msf {r['msf_step_s'] * 1e3:.3f} ms, builtin {r['builtin_step_s'] * 1e3:.3f} ms, "
                f"no contact {r['nocontact_step_s'] * 1e3:.3f} ms per step"
                + (f"; msf as the user's mj_step loop {r['msf_loop_step_s'] * 1e3:.3f} ms, as step(1) "
                   f"{r['msf_step1_step_s'] * 1e3:.3f} ms" if "msf_loop_step_s" in r else ""))
            out.append(r)
    return out


if __name__ == "__main__":  # one size, MuJoCo: python -m benchmarks.spheres [N] [repeats]
    import json
    import sys

    r = measure("mujoco", int(sys.argv[1]) if len(sys.argv) > 1 else 1000, int(sys.argv[2]) if len(sys.argv) > 2 else 7)
    r.pop("all_s")
    print(json.dumps(r, indent=1))
