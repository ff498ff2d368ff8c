"""One isolated impact of a ball on a plate, as ``msf-contact impact`` and
the scenarios (ball-on-plate, calibration, paddle) build it: the flags
(:func:`add_impact_arguments`), their validation and the construction of
the law and bodies (:func:`build_impact` -> :class:`ImpactSetup`), and the
engines that compute it (:data:`ENGINES`: the reference solver, the
paper's closed forms, and the MuJoCo/pybullet runners of
:mod:`experiments.engine_cli`; more with :func:`register_engine`).

Only numpy/scipy (through msf_contact) are imported here; the engines are
imported when one runs.
"""

from __future__ import annotations

import argparse
import math
import warnings
from dataclasses import dataclass
from typing import Any, Callable

from msf_contact import closed_forms as cf
from msf_contact._normal import SEPARATIONS
from msf_contact._validate import (RADIUS_MAX, RADIUS_MIN, ValidityWarning, check_between, check_finite, check_positive,
                                   check_range, check_tan_delta)
from msf_contact.geometry import KP_MODES, Curvature, peak_pressure_closed
from msf_contact.laws import HC_COR_MIN, HC_DAMPINGS, LAWS, OMEGA_MODES, ForceLaw, make_law
from msf_contact.materials import MODULUS_CONVENTIONS, ContactPair
from msf_contact.record import ImpactRecord
from msf_contact.solver import (TANGENTIAL_MODES, Body, check_impact_inputs, outside_validity, reduced_mass,
                                simulate_impact)

from . import engine_cli
from .arguments import (
    DEFAULT_BALL, DEFAULT_RADIUS, DEFAULT_SPEED, add_material_arguments, finite_arg, flag, material, number,
    positive_arg,
)


@dataclass(frozen=True)
class ImpactSetup:
    """One isolated impact, validated, as every engine receives it.

    law: the constructed force law (pair = (ball, plate)); ball, plate: the
    bodies (plate a half-space); speed [m/s]; angle_deg: to the plate, 90 =
    normal; spin [rad/s]; tangential: "contact-point" or "paper"; strict:
    validity violations are errors; args: the parsed command line (for
    engine-specific flags such as --dt).
    """

    law: ForceLaw
    ball: Body
    plate: Body
    speed: float
    angle_deg: float
    spin: float
    tangential: str
    strict: bool
    args: argparse.Namespace


@dataclass(frozen=True)
class Engine:
    """An engine of ``impact``: ``run(setup)`` returns an
    :class:`~msf_contact.record.ImpactRecord` (or its ``to_dict()``) with at
    least :data:`~msf_contact.record.CONTRACT_KEYS`; ``add_arguments``
    optionally declares engine-specific flags on the ``impact`` parser."""

    run: Callable[[ImpactSetup], Any]
    help: str = ""
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None


ENGINES: dict[str, Engine] = {}


def register_engine(name: str, run, help: str = "", add_arguments=None) -> None:
    """Add an engine to ``impact --engine`` (call before :func:`build_parser`)."""
    ENGINES[name] = Engine(run, help, add_arguments)


#: Flags that belong to one law only (dest names); given with another law they
#: are refused rather than silently ignored.
LAW_ONLY_FLAGS = {
    "kp_mode": "msf", "omega": "msf", "A": "kuwabara-kono", "hc_cor": "hunt-crossley",
    "hc_damping": "hunt-crossley",
    "k": "spring-dashpot", "c": "spring-dashpot",
}


def add_impact_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--engine", choices=sorted(ENGINES), default="reference",
                   help="what computes the impact (default reference: the reference solver; closed-form: "
                        "the paper's (87), (89), (90), (95) for a sphere on a half-space)")
    p.add_argument("--law", choices=list(LAWS), default="msf",
                   help="force law (default msf). Every law, hertz included, uses the effective modulus of "
                        "--convention: by default the paper's (9) without 1 - nu^2, softer than textbook Hertz; "
                        "--convention hertz gives the textbook E*")
    p.add_argument("--radius", type=number, default=DEFAULT_RADIUS, metavar="R",
                   help=f"ball radius [m] (default {DEFAULT_RADIUS})")
    p.add_argument("--mass", type=number, metavar="KG", help="ball mass [kg] (default: from the density)")
    add_material_arguments(p, "ball", f"default {DEFAULT_BALL}")
    add_material_arguments(p, "plate", "omitted (with no --plate-* flag): a rigid plate. "
                                        "--plate-E alone: nu 0.3, density 7850, tg(beta) 0")
    p.add_argument("--convention", choices=MODULUS_CONVENTIONS, default="msf",
                   help="effective modulus of every law: msf = (9), 1/E = 1/E1 + 1/E2 without 1 - nu^2 "
                        "(default, the paper's); hertz = textbook E* with (1 - nu^2), stiffer: the msf "
                        "convention's durations are (1 - nu^2)^(-2/5) times the textbook ones, 3.8 %% longer "
                        "at nu = 0.3, 11.6 %% at 0.49")
    p.add_argument("--speed", type=number, default=DEFAULT_SPEED, metavar="V",
                   help=f"impact speed [m/s] (default {DEFAULT_SPEED})")
    p.add_argument("--angle", type=number, default=90.0, metavar="DEG",
                   help="angle of incidence to the plate [deg], the paper's alpha; 90 = normal (default)")
    p.add_argument("--spin", type=number, default=0.0, metavar="W",
                   help="initial spin [rad/s], positive for rolling in the direction of incidence")
    p.add_argument("--kp-mode", choices=KP_MODES, default=None,
                   help="msf law: correlation coefficient k_p: msf = sqrt(2 - x/R) (15) (default), "
                        "msf-small = sqrt(2) (25), hertz = 1 (30)")
    p.add_argument("--separation", choices=SEPARATIONS, default="force-zero",
                   help="end of contact: force-zero (default, F_n returns to 0) or overlap-zero")
    p.add_argument("--omega", default=None, metavar="self-consistent|paper|VALUE",
                   help="msf law: collision frequency omega_x (46): self-consistent (default), paper "
                        "(tau of (95)), or a fixed value [rad/s]")
    p.add_argument("--tangential", choices=TANGENTIAL_MODES, default="contact-point",
                   help="tangential displacement: contact-point (default) or paper (49)")
    p.add_argument("--mu", type=number, default=None, help="optional Coulomb cap |F_t| <= mu F_n (default none)")
    p.add_argument("--A", dest="A", type=number, default=None, metavar="SECONDS",
                   help="kuwabara-kono dissipative constant A [s]; default (99) with k_p = 1, nu of the softer "
                        "body and tau from (95) as printed (k_p = 1) with k_x from (89)")
    p.add_argument("--hc-cor", dest="hc_cor", type=number, default=None, metavar="E",
                   help="hunt-crossley target restitution in (0, 1]; default (89) of the pair's tg(beta). "
                        "With the default --hc-damping flores it is the recipe's target, not the COR the run "
                        "returns (0.8 gives 0.7885); --hc-damping exact returns it")
    p.add_argument("--hc-damping", dest="hc_damping", choices=HC_DAMPINGS, default=None,
                   help="hunt-crossley damping recipe chi = alpha/v0: flores (default, Flores et al. 2011, "
                        "alpha = 8 (1 - e)/(5 e)) or exact (alpha (1 + e) = ln((1 + alpha)/(1 - alpha e)): "
                        "the run returns COR = --hc-cor)")
    p.add_argument("--k", dest="k", type=number, default=None, metavar="N_M",
                   help="spring-dashpot stiffness [N/m]; default: the law's own (84) at the onset speed")
    p.add_argument("--c", dest="c", type=number, default=None, metavar="NS_M",
                   help="spring-dashpot damping [N s/m]; default: the law's own (84)")
    p.add_argument("--strict", action="store_true", help="validity violations (100) are errors, not warnings")
    p.add_argument("--json", action="store_true", help="print one JSON object (SI units)")
    for engine in ENGINES.values():
        if engine.add_arguments is not None:
            engine.add_arguments(p)


def _parse_omega(text: str | None):
    if text is None or text in OMEGA_MODES:
        return text or "self-consistent"
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--omega = {text!r} is not one of {', '.join(OMEGA_MODES)} or a number [rad/s]") from None
    check_positive("--omega", value, unit="rad/s")
    return value


def _law_options(args, pair: ContactPair, radius: float, mass: float, v_n: float) -> dict:
    for dest, law in LAW_ONLY_FLAGS.items():
        if getattr(args, dest) is not None and args.law != law:
            raise ValueError(f"{flag(dest)} = {getattr(args, dest)!r} applies to --law {law} only, "
                             f"not {args.law!r}")
    opts: dict[str, Any] = {"separation": args.separation, "mu": args.mu}
    if args.law == "msf":
        opts.update(kp_mode=args.kp_mode or "msf", omega=_parse_omega(args.omega), strict=args.strict)
    elif args.law == "kuwabara-kono":
        opts["A"] = args.A if args.A is not None else default_A(pair, radius, mass, v_n)
    elif args.law == "hunt-crossley":
        opts["cor"] = args.hc_cor if args.hc_cor is not None else default_hc_cor(pair)
        opts["damping"] = args.hc_damping or "flores"
    elif args.law == "spring-dashpot":
        opts.update(k=args.k, c=args.c)
    return opts


def default_A(pair: ContactPair, radius: float, mass: float, v_n: float) -> float:
    """Default Kuwabara-Kono A [s]: (99) with k_p = 1, nu of the softer body and
    tau_x of (95) as printed (k_p = 1) with k_x of (89); 0 for an elastic pair.
    radius: effective radius R [m]; mass: effective mass [kg]; v_n: normal speed [m/s]."""
    mod = pair.moduli()
    if mod.tan_delta == 0:
        return 0.0
    if mod.tan_delta > 1.0 / 3.0:
        raise ValueError(f"the default --A needs tg(beta) <= 1/3 ((89), (95), bound (100)); the pair has "
                         f"tg(beta) = {mod.tan_delta:.6g}: give --A")
    soft = pair.body1 if pair.body1_is_softer else pair.body2
    tau = float(cf.tau_95_as_printed(mass, v_n, mod.E, radius, 1.0, cf.cor_89(mod.tan_delta)))
    return float(cf.brilliantov_A_99(mod.tan_delta, soft.nu, 1.0, tau))


def default_hc_cor(pair: ContactPair) -> float:
    """Default Hunt-Crossley target restitution: (89) of the pair's tg(beta) (91)."""
    return float(cf.cor_89(pair.moduli().tan_delta))


def build_impact(args) -> ImpactSetup:
    """Validate everything and construct the law and bodies (no solving)."""
    check_positive("--radius", args.radius, unit="m")
    radius = check_between("--radius", args.radius, RADIUS_MIN, RADIUS_MAX, "m",
                           "bounds of plausibility, msf_contact._validate").item()
    if args.mass is not None:
        check_positive("--mass", args.mass, unit="kg")
        if args.ball_density is not None:
            raise ValueError("give --mass or --density, not both")
    speed = check_positive("--speed", args.speed, unit="m/s").item()
    check_range("--angle", args.angle, 0.0, 90.0, lo_open=True)
    check_finite("--spin", args.spin)
    if args.mu is not None:
        check_positive("--mu", args.mu)
    for dest in ("A", "hc_cor", "k", "c"):
        finite_arg(args, dest)
    if args.A is not None and args.A < 0:
        raise ValueError(f"--A = {args.A!r} s must be >= 0")
    if args.hc_cor is not None:
        check_range("--hc-cor", args.hc_cor, HC_COR_MIN, 1.0)
    positive_arg(args, "k", "N/m")
    if args.c is not None and args.c < 0:
        raise ValueError(f"--c = {args.c!r} N s/m must be >= 0")

    ball_mat = material(args, "ball", DEFAULT_BALL)
    plate_mat = material(args, "plate", None)
    pair = ContactPair(ball_mat, plate_mat, convention=args.convention)
    check_tan_delta("tg(beta) of the pair ((91), from --ball-tan-delta, --plate-tan-delta or the presets)",
                    pair.moduli().tan_delta, strict=args.strict)
    try:
        ball = Body.sphere(ball_mat, radius, args.mass)
    except ValueError as exc:  # the mean density bound: say which flags set it
        raise ValueError(f"--mass/--density and --radius: {exc}") from None
    plate = Body.half_space(plate_mat)
    m = reduced_mass(ball.mass, plate.mass)
    v_n = speed * math.sin(math.radians(args.angle))
    curvature = Curvature.sphere_on_plane(radius)
    if math.isinf(m):
        raise ValueError(f"the ball ({ball_mat.name}) has an infinite mass: give --mass")
    opts = _law_options(args, pair, radius, m, v_n)
    with warnings.catch_warnings():
        # the pair's tg(beta) was checked above, with the command-line names
        warnings.simplefilter("ignore", ValidityWarning)
        law = make_law(args.law, pair, curvature, **opts)
    check_impact_inputs(law, ball, plate, speed, args.angle, args.spin, args.strict)
    check_x_max(law, m, v_n)
    return ImpactSetup(law, ball, plate, speed, float(args.angle), float(args.spin), args.tangential,
                       args.strict, args)


#: Elastic work of the msf normal force (43) from x = 0 to x = 2R, in units of
#: E' R^3: (4/3) int_0^2 sqrt(2 - s) s^(3/2) ds = (4/3)(pi/2) = 2 pi/3.
MSF_WORK_TO_2R = 2.0 * math.pi / 3.0


def check_x_max(law: ForceLaw, mass: float, v_n: float) -> None:
    """Refuse, before solving, an impact whose approach can reach 2R in msf
    k_p mode, where k_p = sqrt(2 - x/R) of (15) has no real value.

    The test is the elastic msf law's own x_max, an upper bound of the
    viscoelastic x_max (the viscous force resists compression): it reaches 2R
    when m V_n^2/2 >= (2 pi/3) E' R^3. (The elastic Hertz x_max with k_p = 1
    is not a bound: it stays below 2R up to (8/15) 2^(5/2) = 3.02 E' R^3.)
    """
    if law.kp_mode != "msf":
        return
    R = law.geom.R
    kinetic = 0.5 * mass * v_n**2
    capacity = MSF_WORK_TO_2R * law.moduli.E * R**3
    if kinetic >= capacity:
        raise ValueError(
            f"x_max >= 2R = {2 * R:.6g} m: the normal kinetic energy m V_n^2/2 = {kinetic:.6g} J (V_n = {v_n:.6g} m/s) "
            f"is >= {capacity:.6g} J = (2 pi/3) E' R^3, the elastic work of (43) up to x = 2R, so the approach "
            "can reach 2R where k_p = sqrt(2 - x/R) of (15) has no real value; lower --speed or use --kp-mode hertz"
        )


# --------------------------------------------------------------- engines ---
def run_reference(setup: ImpactSetup) -> ImpactRecord:
    """The reference solver (msf_contact.solver.simulate_impact)."""
    return simulate_impact(setup.law, setup.ball, setup.plate, setup.speed, setup.angle_deg, setup.spin,
                           tangential=setup.tangential, strict=setup.strict)


#: Laws that have closed forms for a sphere on a half-space.
CLOSED_FORM_LAWS = ("msf", "hertz")


def run_closed_form(setup: ImpactSetup) -> dict:
    """The paper's closed forms for a sphere on a half-space, in the record's
    keys (None where no closed form exists). msf: k_x (89), x_m (90) with k_p
    of the mode ((15) at x_m by fixed point), tau (95) as printed (and the
    consistent (95) under ``closed_forms``), omega_x (87), tau1 = k_x tau/(1 + k_x)
    and tau2 = tau/(1 + k_x) from (62), P_c at x_m (42), works (53)-(56).
    hertz: the elastic Hertz/Landau values. F_max of msf has no closed form
    (the peak falls before x_m): None."""
    law = setup.law
    if law.name not in CLOSED_FORM_LAWS:
        raise ValueError(f"--engine closed-form has closed forms for --law {' and '.join(CLOSED_FORM_LAWS)} only, "
                         f"not {law.name!r}; use --engine reference")
    if law.name == "msf" and not isinstance(law.omega, str):
        raise ValueError(f"--omega = {law.omega!r} (fixed): the closed forms assume the paper's omega_x of (87)/(95); "
                         "use --engine reference")
    m = reduced_mass(setup.ball.mass, setup.plate.mass)
    v_n = setup.speed * math.sin(math.radians(setup.angle_deg))
    law.onset_reference([v_n], [m])  # refuses what the reference solver refuses (e.g. no damped oscillation)
    mod, R = law.moduli, law.geom.R
    E, td = mod.E, mod.tan_delta
    extra: dict[str, Any] = {}
    if law.name == "hertz":
        k_p, cor = 1.0, 1.0
        x_m = float(cf.hertz_x_max(m, v_n, E, R))
        tau = float(cf.hertz_tau(m, v_n, E, R))
        tau1 = tau2 = tau / 2.0
        F_max = float(cf.hertz_F_max(m, v_n, E, R))
        omega = None
        works = (float(cf.work_elastic_compression_53(x_m, E, R, k_p)), 0.0,
                 float(cf.work_elastic_restitution_55(x_m, E, R, k_p)), 0.0)
    else:
        if td == 0:
            raise ValueError("tg(beta) = 0: (95) is 0/0 at k_x = 1; use --law hertz for the elastic closed forms")
        k_p = float(cf.kp_for_mode(law.kp_mode, m, v_n, E, td, R))
        cor = float(cf.cor_89(td))
        if not cor > 0:
            raise ValueError(f"tg(beta) = {td:.6g}: (89) gives k_x = {cor:.6g} <= 0 (it needs tg(beta) < pi/3; the "
                             "model's validity (100) is tg(beta) <= 1/3); use --engine reference")
        x_m = float(cf.x_max_90(m, v_n, E, td, R, k_p))
        tau = float(cf.tau_95_as_printed(m, v_n, E, R, k_p, cor))
        omega = math.pi / tau  # (87)
        tau1, tau2 = cor * tau / (1.0 + cor), tau / (1.0 + cor)  # (62) with tau1 + tau2 = tau
        F_max = None
        works = (float(cf.work_elastic_compression_53(x_m, E, R, k_p)),
                 float(cf.work_viscous_compression_54(x_m, mod.E_loss, R, k_p, omega, tau1)),
                 float(cf.work_elastic_restitution_55(x_m, E, R, k_p)),
                 float(cf.work_viscous_restitution_56(x_m, mod.E_loss, R, k_p, omega, tau2)))
        extra = {"tau_95_as_printed": tau, "tau_95": float(cf.tau_95(m, v_n, E, R, k_p, cor)),
                 "cor_89": cor, "x_max_90": x_m, "omega_x_87": omega}
    Pc = float(peak_pressure_closed(x_m, 0.0, E, 0.0, law.geom, law.kp_mode))
    normal = setup.angle_deg == 90.0 and setup.spin == 0.0
    rec = ImpactRecord(
        cor_n=cor, cor_t=None, cor_t_contact=None, cor_tau_ratio=tau1 / tau2,
        tau=tau, tau1=tau1, tau2=tau2, x_max=x_m, F_max=F_max, Pc_max=Pc, Pc_at_Fmax=None,
        W_el_comp=works[0], W_visc_comp=works[1], W_el_rest=works[2], W_visc_rest=works[3],
        W_diss_n=0.5 * m * v_n**2 * (1.0 - cor**2), W_diss_t=0.0 if normal else None, Q_t=None,
        spin_in=setup.spin, spin_out=0.0 if normal else None, f_min=None, f_max=None,
        omega_x=omega, omega_y=None, ended_by=None, law=law.name, engine="closed-form", dt=None,
        parameters=law.parameters(), inputs=_impact_inputs(setup, m),
        outside_validity=outside_validity(law, x_m, Pc),
    )
    d = rec.to_dict()
    d["closed_forms"] = {"k_p": k_p, "tan_delta": td, **extra}
    return d


def _impact_inputs(setup: ImpactSetup, m: float) -> dict:
    b1, b2 = setup.ball, setup.plate
    return {
        "speed": setup.speed, "angle_deg": setup.angle_deg, "spin": setup.spin, "tangential": setup.tangential,
        "mass_reduced": m, "body1": {"material": b1.material.name, "radius": b1.radius, "mass": b1.mass},
        "body2": {"material": b2.material.name, "radius": b2.radius, "mass": b2.mass},
    }


register_engine("reference", run_reference, "the reference solver (msf_contact.solver)")
register_engine("closed-form", run_closed_form, "the paper's closed forms for a sphere on a half-space")
register_engine("mujoco", engine_cli.run_mujoco,
                "the law inside MuJoCo (passive-force hook, sub-cycled contacts)", engine_cli.add_engine_arguments)
register_engine("pybullet", engine_cli.run_pybullet, "the law inside pybullet (external forces, sub-cycled contacts)")
register_engine("mujoco-builtin", engine_cli.run_mujoco_builtin, "MuJoCo's own soft contact (--solref, --solimp)")
register_engine("pybullet-builtin", engine_cli.run_pybullet_builtin,
                "pybullet's own contact (--restitution, --contact-stiffness/--contact-damping)")
