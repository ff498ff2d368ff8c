"""Benchmark: ``pybullet_data/mjcf/ant.xml`` and ``humanoid.xml`` in
pybullet (``loadMJCF``) at MuJoCo's time steps of the files (ant 10 ms,
humanoid 2 ms), MSF on every body-floor contact (natural rubber on steel, each foot's
tangential force capped at the friction pybullet's own contact gives the
pair, :func:`engines.pybullet.robots.load_mjcf_with_msf_floor`) against
pybullet's own contact, under the same seeded random torques (uniform in
each motor's MJCF torque range, gear x ctrlrange, seed 13) for STEPS steps,
then STEPS steps with the torques off. Per record: the wall time per step
of each variant and their ratio, the base height at the end of the
torques, the MSF impact records, and the energy over the rest phase: with
MSF the account of :class:`engines.pybullet.robots.RestEnergy` (kinetic +
gravitational, :func:`engines.pybullet.robots.mechanical_energy`, plus the
energy held in the contacts, ``ContactManager.stored_energy``), its largest
rise above its start and above its running minimum over the whole rest, how much of the rest's
change pybullet's steps added beyond the MSF loads' work (``engine_added``:
its joint limits' impulses, its integration of turning links) and the
largest rise of the contacts' own balance (account less engine_added), and
the steps above RestEnergy's bounds; with pybullet's own contact the
mechanical energy (its penetration energy is outside the sum). The MuJoCo
variant is :mod:`benchmarks.robots`; ``make bench`` runs both.
"""

from __future__ import annotations

import os
import time

import numpy as np

from ._common import run_robots

STEPS = 1000
QUICK_STEPS = 100
SEED = 13
MODELS = {"ant.xml": 0.01, "humanoid.xml": 0.002}


def drive(client: int, uid: int, path: str):
    """(movable joints, torque bounds [N m]) of the robot: each movable joint
    with an MJCF motor gets its torque range, the others 0."""
    import pybullet as pb

    from engines.pybullet.robots import motor_torque_limits

    limits = motor_torque_limits(path)
    joints = [j for j in range(pb.getNumJoints(uid, physicsClientId=client))
              if pb.getJointInfo(uid, j, physicsClientId=client)[2] != pb.JOINT_FIXED]
    bound = np.array([limits.get(pb.getJointInfo(uid, j, physicsClientId=client)[1].decode(), 0.0)
                      for j in joints])
    return joints, bound


def run_model(name: str, steps: int, msf: bool, rest_steps: int | None = None, *, seed: int = SEED,
              tell: bool = True, limit_trial: bool | None = None, law_options: dict | None = None,
              observer=None, adapter_options: dict | None = None) -> dict:
    """One variant: ``steps`` steps of torques seeded with ``seed`` then
    ``rest_steps`` (default ``steps``) without; the record's fields (module
    docstring) and the adapter (None for the built-in contact). tell: with
    MSF, set the torques through ``PybulletAdapter.set_joint_torques`` (the
    contacts see them in their step); False: through pybullet's own call
    (seen a step late). limit_trial: ``PybulletAdapter(limit_trial=)`` (the
    joints a limit holds found by a trial step; default: with the torques
    told, which it needs). law_options: keyword arguments of
    ``load_mjcf_with_msf_floor`` for the feet's law (``mu``: their Coulomb
    cap, by default the friction pybullet's own contact gives each pair, the
    built-in variant's; ``{"mu": None}`` for none, the paper's law).
    observer: with MSF, an object whose ``before(adapter, account, phase)``
    and ``after(adapter, account, phase, step)`` are called around every
    step (phase "torque" or "rest"; the account a RestEnergy, kept over the
    torques too; scripts/pybullet_rest_split.py).
    adapter_options: further keyword arguments of the MSF variant's
    PybulletAdapter (``{"anchor_depth": False}``: the internal approach as
    integrated, as before)."""
    import pybullet as pb
    import pybullet_data

    from engines.pybullet import scenes
    from engines.pybullet.adapter import PybulletAdapter
    from engines.pybullet.robots import RestEnergy, load_mjcf_with_msf_floor, mechanical_energy
    from msf_contact import ContactPair, preset

    rest_steps = steps if rest_steps is None else rest_steps
    path = os.path.join(pybullet_data.getDataPath(), "mjcf", name)
    dt = MODELS[name]
    c = scenes.new_client(dt, gravity=9.81)
    try:
        robots, floor, pairs, shapes = load_mjcf_with_msf_floor(c, path, ContactPair(preset("natural-rubber"),
                                                                                     preset("steel")),
                                                                **(law_options or {}))
        uid = robots[0]
        joints, bound = drive(c, uid, path)
        trial = tell if limit_trial is None else limit_trial
        adapter = (PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=trial, **(adapter_options or {}))
                   if msf else None)
        step = adapter.step if msf else (lambda: pb.stepSimulation(physicsClientId=c))
        rng = np.random.default_rng(seed)
        watch = RestEnergy(adapter, robots) if (msf and observer is not None) else None
        t = time.perf_counter()
        for k in range(steps):
            tau = rng.uniform(-1.0, 1.0, len(joints)) * bound
            if msf and tell:  # pybullet's TORQUE_CONTROL, told to the contacts (PybulletAdapter.set_joint_torques)
                adapter.set_joint_torques(uid, joints, tau)
            else:
                pb.setJointMotorControlArray(uid, joints, pb.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=c)
            if watch is not None:
                observer.before(adapter, watch, "torque")
            step()
            if watch is not None:
                watch.update()
                observer.after(adapter, watch, "torque", k + 1)
        wall = time.perf_counter() - t
        if msf:  # the limit trial's share of the MSF step under the torques (PybulletAdapter.limit_trial_s)
            trial_s = adapter.limit_trial_s
        out = {"step_s": wall / steps,
               "base_height_m": float(pb.getBasePositionAndOrientation(uid, physicsClientId=c)[0][2])}
        pb.setJointMotorControlArray(uid, joints, pb.TORQUE_CONTROL, forces=[0.0] * len(joints), physicsClientId=c)
        acc = RestEnergy(adapter, robots) if msf else None
        E = [acc.total] if msf else [mechanical_energy(c, robots)]
        C = [acc.contacts] if msf else []
        for k in range(rest_steps):
            if observer is not None and msf:
                observer.before(adapter, acc, "rest")
            step()
            if msf:
                E.append(acc.update())
                if observer is not None:
                    observer.after(adapter, acc, "rest", k + 1)
                C.append(acc.contacts)
            else:
                E.append(mechanical_energy(c, robots))
        E = np.array(E)
        out.update(rest_energy_J=[float(E[0]), float(E[-1])], rest_energy_rise_J=float(np.max(E - E[0])),
                   rest_rise_J=_rise(E), dt=dt, adapter=adapter,
                   finite=bool(np.all(np.isfinite(pb.getBasePositionAndOrientation(uid, physicsClientId=c)[0]))))
        if msf:
            out.update(rest_mechanical_J=acc.mechanical, rest_engine_added_J=acc.engine_added,
                       rest_contacts_rise_J=_rise(np.array(C)), rest_gain_steps=len(acc.gains),
                       rest_contact_gain_steps=len(acc.contact_gains),
                       rest_largest_gain_J=max((g[1] for g in acc.gains), default=0.0),
                       rest_largest_contact_gain_J=max((g[1] for g in acc.contact_gains), default=0.0))
        if adapter is not None:
            out["limit_trial_share"] = trial_s / wall
            out["limit_trial_misses"] = list(adapter.limit_trial_misses)  # (held not tried, tried not held) steps
            out.update(records=len(adapter.records), managed_contacts=len(adapter.pairs), jumps=adapter.jumps,
                       outside_validity=sum(bool(r.outside_validity) for r in adapter.records))
        return out
    finally:
        pb.disconnect(c)


def _rise(E) -> float:
    """The largest rise of E (n,) above its running minimum [J] (0 for a series that never rises)."""
    return float(np.max(E - np.minimum.accumulate(E))) if E.size else 0.0


def measure(name: str, steps: int) -> dict:
    out = {"name": "robots", "engine": "pybullet", "model": name}
    for mode in ("msf", "builtin"):
        r = run_model(name, steps, mode == "msf")
        r.pop("adapter")
        out["dt"] = r.pop("dt")
        out.update({f"{mode}_{k}": v for k, v in r.items()})
    out["ratio_msf_over_builtin"] = out["msf_step_s"] / out["builtin_step_s"]
    out["rest_steps"] = steps
    return out


def _describe(r: dict) -> list[str]:
    return [f"  msf {r['msf_step_s'] * 1e3:.2f} ms, builtin {r['builtin_step_s'] * 1e3:.3f} ms per step; "
            f"rest energy rise above its start msf {r['msf_rest_energy_rise_J']:.3g} J, builtin "
            f"{r['builtin_rest_energy_rise_J']:.3g} J; above its running minimum msf {r['msf_rest_rise_J']:.3g} J, "
            f"builtin {r['builtin_rest_rise_J']:.3g} J",
            f"  msf rest: account {r['msf_rest_energy_J'][0]:.1f} -> {r['msf_rest_energy_J'][1]:.1f} J "
            f"(mechanical {r['msf_rest_mechanical_J']:.1f} J at the end), pybullet added "
            f"{r['msf_rest_engine_added_J']:.3g} J beyond the MSF loads' work, contacts' own balance rise "
            f"{r['msf_rest_contacts_rise_J']:.3g} J; steps above the bound {r['msf_rest_gain_steps']} "
            f"(contacts' {r['msf_rest_contact_gain_steps']}, the largest {r['msf_rest_largest_contact_gain_J']:.3g} J) "
            f"of {r.get('rest_steps', '?')}; the limit trial ~{100 * r['msf_limit_trial_share']:.0f} % of the MSF step"]


def run(quick: bool = False) -> list[dict]:
    return run_robots("pybullet", "pybullet", MODELS, QUICK_STEPS if quick else STEPS, measure, _describe)
