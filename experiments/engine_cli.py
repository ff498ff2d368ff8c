"""Engines of `msf-contact impact --engine` beyond the reference solver and
the closed forms: the MuJoCo and pybullet adapters (``mujoco``,
``pybullet``) and the engines' own contact (``mujoco-builtin``,
``pybullet-builtin``), with their flags. Registered into
:data:`experiments.impact.ENGINES` by that module; the engines themselves
are imported only when one runs, so ``--help`` stays fast.

Like the reference solver, an engine run simulates the isolated impact
(no gravity, fixed plate) unless ``--gravity G`` is given.
"""

from __future__ import annotations

import argparse

from .arguments import number, numbers

#: MuJoCo's default solref and solimp (XML reference), used when not given.
MUJOCO_DEFAULT_SOLREF = (0.02, 1.0)
MUJOCO_DEFAULT_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)


def add_engine_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("engines (--engine mujoco, pybullet, mujoco-builtin, pybullet-builtin)")
    g.add_argument("--dt", type=number, default=1e-4, metavar="SECONDS",
                   help="engine time step [s] (default 1e-4); contacts shorter than ~50 steps are sub-cycled")
    g.add_argument("--gap", type=number, default=0.0, metavar="METRES",
                   help="distance between the surfaces at t = 0 [m] (default 0); sets where in a step the "
                        "contact begins")
    g.add_argument("--gravity", type=number, default=None, metavar="G",
                   help="gravity [m/s^2] toward the plate (default: none, the isolated impact)")
    g.add_argument("--integrator", choices=("euler", "rk4", "implicitfast"), default="euler",
                   help="MuJoCo integrator (default euler)")
    g.add_argument("--solref", type=numbers, default=None, metavar="TC,ZETA|-K,-B",
                   help="mujoco-builtin: solref on both geoms (timeconst,dampratio or -stiffness,-damping); "
                        f"default MuJoCo's {MUJOCO_DEFAULT_SOLREF[0]:g},{MUJOCO_DEFAULT_SOLREF[1]:g}")
    g.add_argument("--solimp", type=numbers, default=None, metavar="D0,DW,W[,MID,POW]",
                   help="mujoco-builtin: solimp on both geoms; default MuJoCo's "
                        + ",".join(f"{v:g}" for v in MUJOCO_DEFAULT_SOLIMP))
    g.add_argument("--restitution", type=number, default=None, metavar="E",
                   help="pybullet-builtin: the pair's restitution (sqrt(E) on each body, since pybullet "
                        "multiplies them), with the settings that let it act at small speed x dt")
    g.add_argument("--contact-stiffness", dest="contact_stiffness", type=number, default=None, metavar="N_M",
                   help="pybullet-builtin: the pair's contact stiffness [N/m] (with --contact-damping)")
    g.add_argument("--contact-damping", dest="contact_damping", type=number, default=None, metavar="NS_M",
                   help="pybullet-builtin: the pair's contact damping [N s/m] (with --contact-stiffness)")


def _common(args) -> dict:
    from msf_contact._validate import check_finite, check_positive

    check_positive("--dt", args.dt, unit="s")
    check_finite("--gap", args.gap)
    if args.gap < 0:
        raise ValueError(f"--gap = {args.gap!r} m must be >= 0 (the bodies may not start overlapping)")
    if args.gravity is not None:
        check_finite("--gravity", args.gravity)
    return {"dt": args.dt, "gap": args.gap, "gravity": args.gravity}


def _only(args, engine: str, dests: tuple[str, ...]) -> None:
    for d in dests:
        if getattr(args, d) is not None and args.engine != engine:
            raise ValueError(f"--{d.replace('_', '-')} applies to --engine {engine} only, not {args.engine!r}")


def run_mujoco(setup):
    from engines.base import get_engine

    a = setup.args
    _only(a, "mujoco-builtin", ("solref", "solimp"))
    _only(a, "pybullet-builtin", ("restitution", "contact_stiffness", "contact_damping"))
    return get_engine("mujoco")(setup.law, setup.ball, setup.plate, setup.speed, setup.angle_deg, setup.spin,
                                tangential=setup.tangential, integrator=a.integrator, **_common(a))


def run_mujoco_builtin(setup):
    from engines.base import get_engine

    a = setup.args
    _only(a, "pybullet-builtin", ("restitution", "contact_stiffness", "contact_damping"))
    builtin = {"solref": a.solref or MUJOCO_DEFAULT_SOLREF, "solimp": a.solimp or MUJOCO_DEFAULT_SOLIMP}
    return get_engine("mujoco-builtin")(setup.ball, setup.plate, setup.speed, setup.angle_deg, setup.spin,
                                        builtin=builtin, integrator=a.integrator, **_common(a))


def run_pybullet(setup):
    from engines.base import get_engine

    a = setup.args
    _only(a, "mujoco-builtin", ("solref", "solimp"))
    _only(a, "pybullet-builtin", ("restitution", "contact_stiffness", "contact_damping"))
    return get_engine("pybullet")(setup.law, setup.ball, setup.plate, setup.speed, setup.angle_deg, setup.spin,
                                  tangential=setup.tangential, **_common(a))


def run_pybullet_builtin(setup):
    from engines.base import get_engine

    a = setup.args
    _only(a, "mujoco-builtin", ("solref", "solimp"))
    builtin = {k: getattr(a, k) for k in ("restitution", "contact_stiffness", "contact_damping")
               if getattr(a, k) is not None}
    return get_engine("pybullet-builtin")(setup.law, setup.ball, setup.plate, setup.speed, setup.angle_deg,
                                          setup.spin, builtin=builtin, **_common(a))
