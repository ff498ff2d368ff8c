"""The energy at rest of pybullet multibodies under MSF, the numbers
docs/engines.md quotes (issue 13):

    .venv/bin/python scripts/pybullet_robots.py dumbbell     # two links on a hinge resting, 1 and 0.2 ms
    .venv/bin/python scripts/pybullet_robots.py ant          # ant.xml resting on its feet, 10, 1 and 0.2 ms
    .venv/bin/python scripts/pybullet_robots.py feet         # ant.xml put down on its feet, the account, 10 ms
    .venv/bin/python scripts/pybullet_robots.py twist        # ant.xml on its ankle limits, twisted, 10, 5, 2.5 ms
    .venv/bin/python scripts/pybullet_robots.py seeds        # the robots_pybullet benchmark's ant, seeds 13, 1-4,
                                                             # before (no second trial, no depth anchoring) and now
    .venv/bin/python scripts/pybullet_robots.py landing      # ant.xml put down on its ankle limits, 0.3 s at 10 ms
    .venv/bin/python scripts/pybullet_robots.py fall --model humanoid.xml --seeds 13 1
                                                             # the benchmark's rest, MSF and pybullet's own contact

``--no-trial`` makes the adapters without ``limit_trial`` (a joint within
JOINT_LIMIT_TOL of a limit taken as held, as before the trial step);
``--mu`` the feet's Coulomb cap |F_t| <= mu F_n
(``load_mjcf_with_msf_floor(mu=)``): ``engine`` (the default: the friction
pybullet's own contact gives each pair, the ant's feet 0.75, the
humanoid's 0.25), ``none`` (the paper's law, no cap) or a number;
``seeds --model humanoid.xml`` runs the benchmark's humanoid instead,
``seeds --variants before retrial anchor fd now`` the adapter variants of
VARIANTS side by side (default: before and now; fd: a link contact's a_ext
from the finite difference, not the trial), ``--seeds`` other seeds.

Each run puts the body on a steel floor (natural rubber, gravity 9.81
m/s^2), no torques, and prints the mechanical energy plus the elastic
energy held in the contacts (ContactManager.stored_energy) at the start and
the end, and
its largest rise above its running minimum: what a passive body resting on
dissipative contacts must not show beyond rounding. ``twist`` also splits
the account (engines.pybullet.robots.RestEnergy): what pybullet's steps
added beyond the MSF loads' work, and the contacts' own balance.
"""

from __future__ import annotations

import argparse
import os

import numpy as np
import pybullet as pb
import pybullet_data

from engines.base import PairSpec
from engines.pybullet import scenes
from engines.pybullet.adapter import PybulletAdapter
from engines.pybullet.robots import RestEnergy, load_mjcf_with_msf_floor, mechanical_energy
from msf_contact import ContactPair, Curvature, make_law, preset

PAIR = ContactPair(preset("natural-rubber"), preset("steel"))
#: PybulletAdapter(limit_trial=) of the robots' adapters (--no-trial: False)
TRIAL = True


def watch(c, ad, uids, seconds, dt) -> str:
    E = []
    for _ in range(int(round(seconds / dt))):
        ad.step()
        E.append(mechanical_energy(c, uids) + ad.manager.stored_energy())
    E = np.array(E)
    return (f"E + stored {E[0]:.6g} -> {E[-1]:.6g} J, largest rise above its running minimum "
            f"{np.max(E - np.minimum.accumulate(E)):.3g} J")


#: load_mjcf_with_msf_floor(mu=) of the robots (--mu)
MU = "engine"


def dumbbell(shape: str, dt: float, seconds: float) -> str:
    """Two links (spheres, or capsules lying along y) of 1 kg, R 20 mm, 0.2 m
    apart on a hinge about y, resting on the floor."""
    c = scenes.new_client(dt, gravity=9.81)
    try:
        plane = scenes.add_plate(c)
        R = 0.02
        if shape == "sphere":
            s, orn = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c), [0, 0, 0, 1]
        else:
            s = pb.createCollisionShape(pb.GEOM_CAPSULE, radius=R, height=0.1, physicsClientId=c)
            orn = list(pb.getQuaternionFromEuler([np.pi / 2, 0, 0]))
        u = pb.createMultiBody(1.0, s, basePosition=[0, 0, R + 1e-4], baseOrientation=orn, linkMasses=[1.0],
                               linkCollisionShapeIndices=[s], linkVisualShapeIndices=[-1], linkPositions=[[0.2, 0, 0]],
                               linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0, 0, 0]],
                               linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
                               linkJointTypes=[pb.JOINT_REVOLUTE],
                               linkJointAxis=[[0, 1, 0] if shape == "sphere" else [0, 0, 1]], physicsClientId=c)
        for link in (-1, 0):
            pb.changeDynamics(u, link, linearDamping=0, angularDamping=0, jointDamping=0,
                              localInertiaDiagonal=[1.6e-4] * 3, physicsClientId=c)
        pb.setJointMotorControl2(u, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=c)
        law = make_law("msf", PAIR, Curvature.sphere_on_plane(R))
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law), PairSpec((u, 0), (plane, -1), law)])
        return f"dumbbell of {shape}s, dt {dt:g} s, {seconds:g} s: " + watch(c, ad, [u], seconds, dt)
    finally:
        pb.disconnect(c)


def _ant_put_down(c: int):
    """(robots, adapter): ant.xml in client ``c`` with MSF on its shapes
    (mu = MU), its lowest shape moved to 0.5 mm above the floor."""
    robots, floor, pairs, shapes = load_mjcf_with_msf_floor(
        c, os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml"), PAIR, mu=MU)
    u = robots[0]
    gap = min(r[8] for r in pb.getClosestPoints(u, floor, 10.0, physicsClientId=c))
    pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
    pb.resetBasePositionAndOrientation(u, [pos[0], pos[1], pos[2] - gap + 5e-4], orn, physicsClientId=c)
    return robots, PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=TRIAL)


def ant(dt: float, seconds: float) -> str:
    """ant.xml placed with its lowest shape 0.5 mm above the floor, no torques."""
    c = scenes.new_client(dt, gravity=9.81)
    try:
        robots, ad = _ant_put_down(c)
        return f"ant at rest, dt {dt:g} s, {seconds:g} s: " + watch(c, ad, robots, seconds, dt)
    finally:
        pb.disconnect(c)


def feet(dt: float, seconds: float) -> str:
    """ant.xml put down on its feet 0.5 mm above the floor (as ``ant``), no
    torques, with the RestEnergy account: with the feet capped (the default)
    its legs splay and it drops onto its ankle limits."""
    c = scenes.new_client(dt, gravity=9.81)
    try:
        robots, ad = _ant_put_down(c)
        return f"ant put down on its feet, dt {dt:g} s, {seconds:g} s, mu {MU}, trial {TRIAL}: " + _run(ad, robots, dt,
                                                                                                        seconds)
    finally:
        pb.disconnect(c)


def _on_ankle_limits(c):
    """ant.xml in client c with its ankles on their limits, put down 0.5 mm
    above the floor, and its adapter: (robots, adapter)."""
    robots, floor, pairs, shapes = load_mjcf_with_msf_floor(
        c, os.path.join(pybullet_data.getDataPath(), "mjcf", "ant.xml"), PAIR, mu=MU)
    u = robots[0]
    for j in range(pb.getNumJoints(u, physicsClientId=c)):
        info = pb.getJointInfo(u, j, physicsClientId=c)
        if b"ankle" in info[1]:
            pb.resetJointState(u, j, info[8] if info[8] > 0 else info[9], 0.0, physicsClientId=c)
    gap = min(r[8] for r in pb.getClosestPoints(u, floor, 10.0, physicsClientId=c))
    pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
    pb.resetBasePositionAndOrientation(u, [pos[0], pos[1], pos[2] - gap + 5e-4], orn, physicsClientId=c)
    return robots, PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=TRIAL)


def _account(acc, E, C) -> str:
    E, C = np.array(E), np.array(C)
    return (f"E + stored {E[0]:.6g} -> {E[-1]:.6g} J, largest rise above its running minimum "
            f"{np.max(E - np.minimum.accumulate(E)):.3g} J; pybullet added {acc.engine_added:.3g} J beyond the MSF "
            f"loads' work; the contacts' own balance rose {np.max(C - np.minimum.accumulate(C)):.3g} J above its "
            f"running minimum ({len(acc.contact_gains)} steps above RestEnergy's bound)")


def _run(ad, robots, dt: float, seconds: float) -> str:
    """Step ``ad`` for ``seconds`` with a RestEnergy account of ``robots`` kept
    each step; the account's summary (_account)."""
    acc = RestEnergy(ad, robots)
    E, C = [acc.total], [acc.contacts]
    for _ in range(int(round(seconds / dt))):
        ad.step()
        E.append(acc.update())
        C.append(acc.contacts)
    return _account(acc, E, C)


def landing(dt: float, seconds: float) -> str:
    """ant.xml put down on its ankle limits 0.5 mm above the floor, no torques
    (tests/test_robots_pybullet.py takes 0.3 s at 10 ms)."""
    c = scenes.new_client(dt, gravity=9.81)
    try:
        robots, ad = _on_ankle_limits(c)
        return f"ant landing on its ankle limits, dt {dt:g} s, {seconds:g} s: " + _run(ad, robots, dt, seconds)
    finally:
        pb.disconnect(c)


def twist(dt: float, seconds: float, wz: float = 5.0) -> str:
    """ant.xml on its ankle limits (where its torques leave it), put down
    0.5 mm above the floor, 0.5 s to settle, then its torso turned at wz
    about z and its hips at -wz (its feet stay), no torques, for ``seconds``
    (tests/test_robots_pybullet.py takes the first second at 10 ms)."""
    c = scenes.new_client(dt, gravity=9.81)
    try:
        robots, ad = _on_ankle_limits(c)
        u = robots[0]
        ad.step(int(round(0.5 / dt)))
        pb.resetBaseVelocity(u, [0, 0, 0], [0, 0, wz], physicsClientId=c)
        for j in range(pb.getNumJoints(u, physicsClientId=c)):
            info = pb.getJointInfo(u, j, physicsClientId=c)
            if b"hip" in info[1]:
                pb.resetJointState(u, j, pb.getJointState(u, j, physicsClientId=c)[0], -wz, physicsClientId=c)
        ad.placed([u])
        return f"ant twisted on its ankle limits, dt {dt:g} s, {seconds:g} s: " + _run(ad, robots, dt, seconds)
    finally:
        pb.disconnect(c)


#: seeds' adapter variants side by side: name -> PybulletAdapter options (--variants)
VARIANTS = {"before": {"anchor_depth": False, "limit_retrial": False, "trial_a_ext": False},
            "retrial": {"anchor_depth": False, "limit_retrial": True, "trial_a_ext": False},
            "anchor": {"anchor_depth": True, "limit_retrial": False, "trial_a_ext": False},
            "fd": {"trial_a_ext": False},
            "now": {},
            "trial": {"trial_a_ext": True}}


def seeds(tell: bool, mu, model: str = "ant.xml", variants=("before", "now"), which=(13, 1, 2, 3, 4)) -> list[str]:
    """The robots_pybullet benchmark's MSF robot (1,000 steps of torques, 1,000
    at rest) under seeds 13 (the benchmark's), 1, 2, 3 and 4, the torques told
    to the adapter or set through pybullet's own call (seen a step late); mu
    the feet's cap (load_mjcf_with_msf_floor(mu=)); each seed with the
    adapter ``variants`` (VARIANTS: "before" without the second limit trial
    and without the depth anchoring, "now" the defaults), then a table of the
    contacts' own balance's largest rise above its running minimum and the
    rest steps above RestEnergy's bound per seed and variant."""
    import sys

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))
    from benchmarks.robots_pybullet import run_model

    out, table = [], {}
    for seed in which:
        for var in variants:
            r = run_model(model, 1000, True, seed=seed, tell=tell, limit_trial=TRIAL and tell, law_options={"mu": mu},
                          adapter_options=VARIANTS[var])
            table[(seed, var)] = (r["rest_contacts_rise_J"], r["rest_contact_gain_steps"],
                                  r["rest_largest_contact_gain_J"])
            ad = r["adapter"]
            out.append(f"{model}, seed {seed}, {var}, torques {'told' if tell else 'late'}, limit trial "
                       f"{TRIAL and tell}, mu {mu}: rest "
                       f"{r['rest_energy_J'][0]:.1f} -> {r['rest_energy_J'][1]:.1f} J, rise above the running minimum "
                       f"{r['rest_rise_J']:.3g} J, pybullet added {r['rest_engine_added_J']:.3g} J, the contacts' own "
                       f"balance rose {r['rest_contacts_rise_J']:.3g} J ({r['rest_contact_gain_steps']} steps above "
                       f"RestEnergy's bound, the largest {r['rest_largest_contact_gain_J']:.3g} J; "
                       f"{r['rest_gain_steps']} of the account, the largest {r['rest_largest_gain_J']:.3g} J); "
                       f"the trial's misses (held not tried, tried not held) {r['limit_trial_misses']} of "
                       f"{ad.limit_trials} trials, {ad.limit_retrials} steps solved again after the second trial; "
                       f"{ad.anchored} contact-steps anchored to the engine's depth, releasing "
                       f"{ad.anchor_released:.3g} J")
            print(out[-1], flush=True)
    out.append(f"{model}: the contacts' own balance at rest, largest rise above its running minimum (rest steps above "
               "RestEnergy's bound; the largest step)")
    out.append("| seed | " + " | ".join(variants) + " |")
    out.append("|---" * (len(variants) + 1) + "|")
    for seed in which:
        out.append(f"| {seed} | " + " | ".join("{:.3g} J ({}; {:.3g} J)".format(*table[(seed, v)])
                                               for v in variants) + " |")
    return out


def fall(model: str, which, every: int = 100) -> list[str]:
    """The benchmark's robot (benchmarks.robots_pybullet: 1,000 steps of the
    seeded torques, then 1,000 without) with MSF (the defaults, the torques
    told) and with pybullet's own contact, the same script: every ``every``
    rest steps the base height, the highest link, the kinetic and the
    kinetic + potential energy. Whether a robot that moves at rest does so
    with pybullet's own contact too (the humanoid: a ragdoll, loadMJCF drops
    its joint damping)."""
    import sys

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))
    from benchmarks.robots_pybullet import MODELS, drive
    from engines.pybullet.robots import _mechanical

    out = []
    path = os.path.join(pybullet_data.getDataPath(), "mjcf", model)
    for seed in which:
        for msf in (False, True):
            c = scenes.new_client(MODELS[model], gravity=9.81)
            try:
                robots, floor, pairs, shapes = load_mjcf_with_msf_floor(c, path, PAIR, mu=MU)
                uid = robots[0]
                joints, bound = drive(c, uid, path)
                # without an adapter the floor pairs keep pybullet's own contact (the adapter switches it off)
                ad = PybulletAdapter(c, pairs, link_shapes=shapes, limit_trial=TRIAL) if msf else None
                rng = np.random.default_rng(seed)
                for _ in range(1000):
                    tau = rng.uniform(-1.0, 1.0, len(joints)) * bound
                    if ad is not None:
                        ad.set_joint_torques(uid, joints, tau)
                        ad.step()
                    else:
                        pb.setJointMotorControlArray(uid, joints, pb.TORQUE_CONTROL, forces=tau.tolist(),
                                                     physicsClientId=c)
                        pb.stepSimulation(physicsClientId=c)
                pb.setJointMotorControlArray(uid, joints, pb.TORQUE_CONTROL, forces=[0.0] * len(joints),
                                             physicsClientId=c)
                out.append(f"{model}, seed {seed}, {'MSF' if msf else 'pybullet contact'}: rest step, base height [m], "
                           "highest link [m], kinetic [J], kinetic + potential [J]")
                for k in range(1001):
                    if k % every == 0:
                        T, U, _ = _mechanical(c, robots)
                        z = pb.getBasePositionAndOrientation(uid, physicsClientId=c)[0][2]
                        top = max(pb.getLinkState(uid, j, physicsClientId=c)[0][2]
                                  for j in range(pb.getNumJoints(uid, physicsClientId=c)))
                        out.append(f"   {k:5d} {z:.3f} {top:.3f} {T:.3g} {T + U:.2f}")
                    if k < 1000:
                        ad.step() if ad is not None else pb.stepSimulation(physicsClientId=c)
                print("\n".join(out[-12:]), flush=True)
            finally:
                pb.disconnect(c)
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", choices=("dumbbell", "ant", "feet", "twist", "seeds", "landing", "fall"))
    ap.add_argument("--no-trial", action="store_true", help="adapters without limit_trial")
    ap.add_argument("--late", action="store_true", help="seeds: also with the torques set through pybullet's call")
    ap.add_argument("--mu", default="engine",
                    help="the feet's Coulomb cap: engine (pybullet's friction of the pair), none, or a number")
    ap.add_argument("--model", default="ant.xml", choices=("ant.xml", "humanoid.xml"), help="seeds: the robot")
    ap.add_argument("--variants", nargs="+", default=["before", "now"], choices=tuple(VARIANTS),
                    help="seeds: the adapter variants side by side (before: no second trial, no depth anchoring)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[13, 1, 2, 3, 4], help="seeds: the torque seeds")
    args = ap.parse_args()
    TRIAL = not args.no_trial
    MU = None if args.mu == "none" else (args.mu if args.mu == "engine" else float(args.mu))
    if args.case == "dumbbell":
        for shape in ("sphere", "capsule"):
            for dt in (1e-3, 2e-4):
                print(dumbbell(shape, dt, 0.3))
        print(dumbbell("capsule", 1e-3, 1.0))
    elif args.case == "seeds":
        for tell in (True, False) if args.late else (True,):
            print("\n".join(seeds(tell, MU, args.model, args.variants, args.seeds)[-(len(args.seeds) + 3):]))
    elif args.case == "fall":
        fall(args.model, args.seeds)
    elif args.case == "feet":
        print(feet(1e-2, 1.0))
    elif args.case == "landing":
        print(landing(1e-2, 0.3))
    elif args.case == "twist":
        for dt in (1e-2, 5e-3, 2.5e-3):
            print(twist(dt, 2.0))
    else:
        for dt, seconds in ((1e-2, 1.0), (1e-3, 1.0), (2e-4, 0.5)):
            print(ant(dt, seconds))
