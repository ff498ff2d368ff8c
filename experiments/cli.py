"""The ``msf-contact`` command line (issue 2 "Command line" is the contract).

Subcommands live in :data:`COMMANDS` (name -> :class:`Command`), so other
issues add ``run``, ``report``, ``demo`` with :func:`register_command`.
Engines of ``msf-contact impact --engine`` live in :data:`ENGINES`
(name -> :class:`Engine`), so the engines issue adds ``mujoco``,
``pybullet``, ``mujoco-builtin``, ``pybullet-builtin`` with
:func:`register_engine` (before :func:`build_parser` runs).

Bad input (issue 2 "Bad input") is refused before any work: the message
names the parameter, its value and the bound, goes to stderr as
``msf-contact: error: ...`` and the exit code is 2. Validity warnings (the
bound (100)) go to stderr as ``msf-contact: warning: ...``; ``--strict``
makes them errors.

Only numpy/scipy (through msf_contact) are imported here; commands that need
heavy packages import them inside their handler, so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import warnings
from dataclasses import asdict, dataclass, replace
from typing import Any, Callable

from msf_contact import closed_forms as cf
from msf_contact._normal import SEPARATIONS
from msf_contact._validate import ValidityWarning, check_finite, check_positive, check_range, check_tan_delta
from msf_contact.geometry import KP_MODES, Curvature, peak_pressure_closed
from msf_contact.laws import LAWS, OMEGA_MODES, ForceLaw, make_law
from msf_contact.materials import MODULUS_CONVENTIONS, ContactPair, Material, preset, preset_names
from msf_contact.record import CONTRACT_KEYS, ImpactRecord, _clean
from msf_contact.solver import TANGENTIAL_MODES, Body, check_impact_inputs, reduced_mass, simulate_impact

PROG = "msf-contact"
#: Exit code of refused input (argparse uses the same).
EXIT_BAD_INPUT = 2
#: Exit code of a failure while computing (e.g. a solver that did not converge).
EXIT_FAILURE = 1

DEFAULT_BALL = "polyurethane"
DEFAULT_RADIUS = 0.01  # [m]
DEFAULT_SPEED = 1.0  # [m/s]
#: Base of a plate given only by --plate-E (no --plate NAME): nu and density
#: of steel, no damping. The density only enters the sound-speed check.
PLATE_BASE = dict(tan_delta=0.0, nu=0.3, density=7850.0)


# ------------------------------------------------------------ registries ---
@dataclass(frozen=True)
class Command:
    """A subcommand: ``add_arguments(parser)`` declares its flags,
    ``run(args) -> int`` does the work and returns the exit code."""

    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


COMMANDS: dict[str, Command] = {}


def register_command(name: str, help: str, add_arguments, run) -> None:
    """Add a subcommand (``run``, ``report``, ``demo`` are added by other issues)."""
    COMMANDS[name] = Command(help, add_arguments, run)


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


# --------------------------------------------------------- small helpers ---
def _number(text: str) -> float:
    """argparse type: a float (NaN and inf are refused later, by name)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _finite(args, dest):
    v = getattr(args, dest)
    if v is not None:
        check_finite(_flag(dest), v)
    return v


def _positive(args, dest, unit):
    v = getattr(args, dest)
    if v is not None:
        check_positive(_flag(dest), v, unit=unit)
    return v


def _lower(text: str) -> str:
    """argparse type of preset names (matched case-insensitively, as ``preset``)."""
    return text.strip().lower()


def _install_warning_printer() -> None:
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{PROG}: warning: {message}", file=sys.stderr)

    warnings.showwarning = show
    warnings.simplefilter("once", ValidityWarning)


# -------------------------------------------------------------- materials ---
def _add_material_arguments(p: argparse.ArgumentParser, role: str, default_help: str) -> None:
    g = p.add_argument_group(f"{role} material")
    g.add_argument(f"--{role}", type=_lower, choices=preset_names(), metavar="NAME",
                   help=f"preset material ({', '.join(preset_names())}); {default_help}")
    g.add_argument(f"--{role}-E", dest=f"{role}_E", type=_number, metavar="PA",
                   help=f"{role} storage modulus E' [Pa] (overrides the preset's)")
    g.add_argument(f"--{role}-tan-delta", dest=f"{role}_tan_delta", type=_number, metavar="TG",
                   help=f"{role} loss factor tg(beta) = E''/E' [-], valid in [0, 1/3] (100)")
    g.add_argument(f"--{role}-nu", dest=f"{role}_nu", type=_number, metavar="NU",
                   help=f"{role} Poisson ratio [-], in (-1, 0.5)")
    if role == "ball":
        g.add_argument("--density", "--ball-density", dest="ball_density", type=_number, metavar="KG_M3",
                       help="ball density [kg/m^3]; sets the mass 4/3 pi R^3 rho unless --mass is given")
    else:
        g.add_argument("--plate-density", dest="plate_density", type=_number, metavar="KG_M3",
                       help="plate density [kg/m^3] (only the sound-speed check uses it)")


def _material(args, role: str, default: str | None) -> Material:
    """The ball's or plate's material from the preset and the overriding flags.
    ``default`` None: no flags at all gives a rigid plate."""
    values = {
        "E_storage": getattr(args, f"{role}_E", None),
        "tan_delta": getattr(args, f"{role}_tan_delta", None),
        "nu": getattr(args, f"{role}_nu", None),
        "density": getattr(args, f"{role}_density", None),
    }
    flags = {"E_storage": f"--{role}-E", "tan_delta": f"--{role}-tan-delta", "nu": f"--{role}-nu",
             "density": f"--{role}-density" if role == "plate" else "--density"}
    if values["E_storage"] is not None:
        check_positive(flags["E_storage"], values["E_storage"], unit="Pa")
    if values["tan_delta"] is not None:
        check_finite(flags["tan_delta"], values["tan_delta"])
        if values["tan_delta"] < 0:
            raise ValueError(f"{flags['tan_delta']} = {values['tan_delta']!r} must be >= 0 (bound (100): [0, 1/3])")
    if values["nu"] is not None:
        check_range(flags["nu"], values["nu"], -1.0, 0.5, lo_open=True, hi_open=True)
    if values["density"] is not None:
        check_positive(flags["density"], values["density"], unit="kg/m^3")
    name = getattr(args, role, None) or default
    given = {k: v for k, v in values.items() if v is not None}
    if name is None:
        if not given:
            return Material.rigid_body("rigid plate")
        if "E_storage" not in given:
            raise ValueError(f"{', '.join(flags[k] for k in given)} given without --{role}-E or --{role} NAME")
        return Material(role, given.pop("E_storage"), **{**PLATE_BASE, **given}, source="command line")
    base = preset(name)
    if not given:
        return base
    if base.rigid and "E_storage" not in given:
        raise ValueError(f"--{role} rigid has no finite modulus: {', '.join(flags[k] for k in given)} need --{role}-E")
    return replace(base, name=f"{base.name} (modified)", source="command line", **given)


def _material_dict(mat: Material) -> dict:
    return {"name": mat.name, "E_storage": mat.E_storage, "tan_delta": mat.tan_delta, "nu": mat.nu,
            "density": mat.density, "source": mat.source}


# ----------------------------------------------------------------- impact ---
#: Flags that belong to one law only (dest names); given with another law they
#: are refused rather than silently ignored.
LAW_ONLY_FLAGS = {
    "kp_mode": "msf", "omega": "msf", "A": "kuwabara-kono", "hc_cor": "hunt-crossley",
    "k": "spring-dashpot", "c": "spring-dashpot",
}


def add_impact_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--engine", choices=sorted(ENGINES), default="reference",
                   help="what computes the impact (default reference: the reference solver; closed-form: "
                        "the paper's (87), (89), (90), (95) for a sphere on a half-space)")
    p.add_argument("--law", choices=list(LAWS), default="msf", help="force law (default msf)")
    p.add_argument("--radius", type=_number, default=DEFAULT_RADIUS, metavar="R",
                   help=f"ball radius [m] (default {DEFAULT_RADIUS})")
    p.add_argument("--mass", type=_number, metavar="KG", help="ball mass [kg] (default: from the density)")
    _add_material_arguments(p, "ball", f"default {DEFAULT_BALL}")
    _add_material_arguments(p, "plate", "omitted (with no --plate-* flag): a rigid plate. "
                                        "--plate-E alone: nu 0.3, density 7850, tg(beta) 0")
    p.add_argument("--convention", choices=MODULUS_CONVENTIONS, default="msf",
                   help="effective modulus: msf = (9) (default), hertz = E* with (1 - nu^2)")
    p.add_argument("--speed", type=_number, default=DEFAULT_SPEED, metavar="V",
                   help=f"impact speed [m/s] (default {DEFAULT_SPEED})")
    p.add_argument("--angle", type=_number, default=90.0, metavar="DEG",
                   help="angle of incidence to the plate [deg], the paper's alpha; 90 = normal (default)")
    p.add_argument("--spin", type=_number, default=0.0, metavar="W",
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
    p.add_argument("--mu", type=_number, default=None, help="optional Coulomb cap |F_t| <= mu F_n (default none)")
    p.add_argument("--A", dest="A", type=_number, default=None, metavar="SECONDS",
                   help="kuwabara-kono dissipative constant A [s]; default (99) with k_p = 1, nu of the softer "
                        "body and tau from (95) as printed (k_p = 1) with k_x from (89)")
    p.add_argument("--hc-cor", dest="hc_cor", type=_number, default=None, metavar="E",
                   help="hunt-crossley target restitution in (0, 1]; default (89) of the pair's tg(beta)")
    p.add_argument("--k", dest="k", type=_number, default=None, metavar="N_M",
                   help="spring-dashpot stiffness [N/m]; default: the law's own (84) at the onset speed")
    p.add_argument("--c", dest="c", type=_number, default=None, metavar="NS_M",
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
            raise ValueError(f"{_flag(dest)} = {getattr(args, dest)!r} applies to --law {law} only, "
                             f"not {args.law!r}")
    opts: dict[str, Any] = {"separation": args.separation, "mu": args.mu}
    if args.law == "msf":
        opts.update(kp_mode=args.kp_mode or "msf", omega=_parse_omega(args.omega), strict=args.strict)
    elif args.law == "kuwabara-kono":
        opts["A"] = args.A if args.A is not None else default_A(pair, radius, mass, v_n)
    elif args.law == "hunt-crossley":
        opts["cor"] = args.hc_cor if args.hc_cor is not None else default_hc_cor(pair)
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
    radius = check_positive("--radius", args.radius, unit="m").item()
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
        _finite(args, dest)
    if args.A is not None and args.A < 0:
        raise ValueError(f"--A = {args.A!r} s must be >= 0")
    if args.hc_cor is not None:
        check_range("--hc-cor", args.hc_cor, 0.0, 1.0, lo_open=True)
    _positive(args, "k", "N/m")
    if args.c is not None and args.c < 0:
        raise ValueError(f"--c = {args.c!r} N s/m must be >= 0")

    ball_mat = _material(args, "ball", DEFAULT_BALL)
    plate_mat = _material(args, "plate", None)
    pair = ContactPair(ball_mat, plate_mat, convention=args.convention)
    check_tan_delta("tg(beta) of the pair ((91), from --ball-tan-delta, --plate-tan-delta or the presets)",
                    pair.moduli().tan_delta, strict=args.strict)
    ball = Body.sphere(ball_mat, radius, args.mass)
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


# ---------------------------------------------------------------- output ---
#: (key, unit) rows of the human table of ``impact``.
IMPACT_ROWS = (
    ("cor_n", "-"), ("cor_t", "-"), ("cor_t_contact", "-"), ("cor_tau_ratio", "-"),
    ("tau", "s"), ("tau1", "s"), ("tau2", "s"), ("x_max", "m"), ("F_max", "N"), ("Pc_max", "Pa"),
    ("W_diss_n", "J"), ("W_diss_t", "J"), ("spin_in", "rad/s"), ("spin_out", "rad/s"),
    ("f_min", "-"), ("f_max", "-"), ("omega_x", "rad/s"), ("omega_y", "rad/s"), ("ended_by", ""),
)


def to_json(d: dict) -> str:
    """Strict JSON (SI units): infinities (a rigid plate's modulus) and NaN become null."""
    return json.dumps(_clean(d), allow_nan=False)


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def format_table(rows, title: str = "") -> str:
    """rows: (label, value, unit); an aligned plain-text table."""
    rows = [(str(a), _fmt(b), str(c)) for a, b, c in rows]
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    lines = [title] if title else []
    lines += [f"  {a:<{w0}}  {b:>{w1}}  {c}".rstrip() for a, b, c in rows]
    return "\n".join(lines)


def _impact_title(d: dict) -> str:
    inp = d.get("inputs", {})
    mats = inp.get("materials", {})
    ball, plate = mats.get("ball", {}), mats.get("plate", {})
    return (f"impact: law {d.get('law')}, engine {d.get('engine')}; ball {ball.get('name')} "
            f"R = {_fmt(inp.get('body1', {}).get('radius'))} m, m = {_fmt(inp.get('body1', {}).get('mass'))} kg; "
            f"plate {plate.get('name')}; V = {_fmt(inp.get('speed'))} m/s at {_fmt(inp.get('angle_deg'))} deg")


def cmd_impact(args) -> int:
    engine = ENGINES[args.engine]  # argparse restricted the choice
    setup = build_impact(args)
    result = engine.run(setup)
    d = result.to_dict() if hasattr(result, "to_dict") else dict(result)
    d.setdefault("inputs", {})
    d["inputs"]["materials"] = {"ball": _material_dict(setup.ball.material),
                                "plate": _material_dict(setup.plate.material)}
    d["inputs"]["engine"] = args.engine
    if args.json:
        print(to_json(d))
    else:
        print(format_table([(k, d.get(k), u) for k, u in IMPACT_ROWS], _impact_title(d)))
        for reason in d.get("outside_validity") or []:
            print(f"  outside validity: {reason}")
    return 0


# -------------------------------------------------------------- identify ---
def add_identify_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tau", type=_number, required=True, metavar="T", help="measured contact duration tau_x [s]")
    p.add_argument("--cor", type=_number, required=True, metavar="K", help="measured normal restitution k_x [-]")
    p.add_argument("--speed", type=_number, required=True, metavar="V", help="normal impact speed [m/s]")
    p.add_argument("--radius", type=_number, required=True, metavar="R", help="ball radius [m]")
    p.add_argument("--mass", type=_number, required=True, metavar="KG", help="ball mass [kg]")
    p.add_argument("--kp-mode", choices=KP_MODES, default="msf", help="k_p mode of the MSF law (default msf)")
    p.add_argument("--omega", default="self-consistent", metavar="self-consistent|VALUE",
                   help="numerical inverse: omega_x self-consistent (default, = pi/tau_x) or fixed [rad/s]")
    p.add_argument("--separation", choices=SEPARATIONS, default="force-zero", help="end of contact (default force-zero)")
    _add_material_arguments(p, "plate", "omitted: a rigid plate (the identified moduli are the ball's)")
    p.add_argument("--strict", action="store_true", help="tg(beta) > 1/3 from (88) is an error, not a warning")
    p.add_argument("--json", action="store_true", help="print one JSON object (SI units)")


def cmd_identify(args) -> int:
    from msf_contact.identification import ImpactMeasurement, identify_numerical, identify_printed

    for dest, unit in (("tau", "s"), ("speed", "m/s"), ("radius", "m"), ("mass", "kg")):
        check_positive(_flag(dest), getattr(args, dest), unit=unit)
    check_finite("--cor", args.cor)
    omega = args.omega
    if omega != "self-consistent":
        try:
            omega = float(omega)
        except ValueError:
            raise ValueError(f"--omega = {args.omega!r} is not self-consistent or a number [rad/s]") from None
        check_positive("--omega", omega, unit="rad/s")
    plate = _material(args, "plate", None)
    meas = ImpactMeasurement(tau=args.tau, cor=args.cor, speed=args.speed, radius=args.radius, mass=args.mass)
    printed = identify_printed(meas, args.kp_mode, strict=args.strict)
    numerical = identify_numerical(meas, kp_mode=args.kp_mode, omega=omega, separation=args.separation,
                                   plate=plate)
    out = {"inputs": {**asdict(meas), "kp_mode": args.kp_mode, "omega": omega, "separation": args.separation,
                      "plate": _material_dict(plate)},
           "printed": asdict(printed), "numerical": asdict(numerical)}
    if args.json:
        print(to_json(out))
        return 0
    rows = [
        ("E' [Pa]", printed.E_storage, numerical.ball_E_storage),
        ("E'' [Pa]", printed.E_loss, numerical.ball_E_loss),
        ("E'' (97) as printed [Pa]", printed.E_loss_as_printed, None),
        ("tg(beta) [-]", printed.tan_delta, numerical.ball_tan_delta),
        ("k_p [-]", printed.k_p, None),
        ("omega_x [rad/s]", None, numerical.omega_x),
        ("model tau - tau_x [rel]", None, numerical.residual_tau),
        ("model k_x - k_x [-]", None, numerical.residual_cor),
    ]
    w0 = max(len(r[0]) for r in rows)
    print(f"identify: tau_x = {_fmt(args.tau)} s, k_x = {_fmt(args.cor)}, V = {_fmt(args.speed)} m/s, "
          f"R = {_fmt(args.radius)} m, m = {_fmt(args.mass)} kg, k_p mode {args.kp_mode}, plate {plate.name}")
    print(f"  {'':<{w0}}  {'(96)-(97), (88)':>16}  {'numerical':>16}")
    for label, a, b in rows:
        print(f"  {label:<{w0}}  {_fmt(a):>16}  {_fmt(b):>16}")
    if not plate.rigid:
        print(f"  ((96)-(97): effective values of the pair; numerical: the ball's, with effective (9), (91) "
              f"E' = {_fmt(numerical.E_storage)} Pa, tg(beta) = {_fmt(numerical.tan_delta)})")
    return 0


register_command("impact", "one isolated impact of a ball on a plate", add_impact_arguments, cmd_impact)
register_command("identify", "E', E'' and tg(beta) from a measured (tau_x, k_x), (96)-(97) and numerically",
                 add_identify_arguments, cmd_identify)


# ------------------------------------------------------------------ main ---
class _Parser(argparse.ArgumentParser):
    """argparse reading ``--tau -1e-3`` as a (negative, then refused by name)
    number; plain argparse takes only -1 and -0.5 for numbers and would
    report "expected one argument" without the value."""

    _NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-inf$|^-nan$", re.IGNORECASE)

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self._negative_number_matcher = self._NUMBER


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog=PROG,
        description="The MSF viscoelastic contact model (Goloshchapov 2015): impacts and identification. SI units.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, command in COMMANDS.items():
        p = sub.add_parser(name, help=command.help, description=command.help)
        command.add_arguments(p)
        p.set_defaults(_run=command.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``msf-contact`` console script. Returns 0; refused
    input raises SystemExit(2) with ``msf-contact: error: ...`` on stderr."""
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        _install_warning_printer()
        try:
            return args._run(args)
        except ValueError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            raise SystemExit(EXIT_BAD_INPUT) from None
        except RuntimeError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            raise SystemExit(EXIT_FAILURE) from None


# run, report and demo (issue "experiments") register themselves on import;
# the engine adapters' runners and flags register here (imported lazily)
from . import commands  # noqa: E402,F401
from .engine_cli import load_engines  # noqa: E402

load_engines()

if __name__ == "__main__":
    # `python -m experiments.cli`: use the package's module, where the commands registered
    from experiments.cli import main as _main

    sys.exit(_main())
