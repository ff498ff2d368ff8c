"""The ``msf-contact`` command line (issue 2 "Command line" is the contract).

Subcommands live in :data:`COMMANDS` (name -> :class:`Command`): ``impact``
and ``identify`` here, ``calibrate``, ``run``, ``report``, ``demo`` from
:mod:`experiments.commands`; more with :func:`register_command` (before
:func:`build_parser` runs). Engines of ``msf-contact impact --engine`` live
in :data:`experiments.impact.ENGINES` (re-exported here as ``ENGINES``;
add one with :func:`experiments.impact.register_engine`). The flags'
types, checks and materials are :mod:`experiments.arguments`.

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
import os
import re
import sys
import warnings
from dataclasses import asdict

from msf_contact._normal import SEPARATIONS
from msf_contact._validate import ValidityWarning, check_finite, check_positive
from msf_contact.geometry import KP_MODES

from .arguments import (
    DEFAULT_BALL, DEFAULT_RADIUS, DEFAULT_SPEED, PLATE_BASE, add_material_arguments, flag, fmt, format_table,
    material, material_dict, number, to_json,
)
from .commands import COMMANDS as _MORE_COMMANDS
from .commands import Command
from .impact import (
    ENGINES, Engine, ImpactSetup, add_impact_arguments, build_impact, register_engine, run_reference,
)

__all__ = ["COMMANDS", "Command", "register_command", "ENGINES", "Engine", "register_engine", "ImpactSetup",
           "build_impact", "run_reference", "to_json", "format_table", "DEFAULT_BALL", "DEFAULT_RADIUS",
           "DEFAULT_SPEED", "PLATE_BASE", "EXIT_BAD_INPUT", "EXIT_FAILURE", "build_parser", "main"]

PROG = "msf-contact"
#: Exit code of refused input (argparse uses the same).
EXIT_BAD_INPUT = 2
#: Exit code of a failure while computing (e.g. a solver that did not converge).
EXIT_FAILURE = 1

COMMANDS: dict[str, Command] = {}


def register_command(name: str, help: str, add_arguments, run) -> None:
    """Add a subcommand (``calibrate``, ``run``, ``report``, ``demo``: :mod:`experiments.commands`)."""
    COMMANDS[name] = Command(help, add_arguments, run)


def _install_warning_printer() -> None:
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{PROG}: warning: {message}", file=sys.stderr)

    warnings.showwarning = show
    warnings.simplefilter("once", ValidityWarning)


#: (key, unit) rows of the human table of ``impact``.
IMPACT_ROWS = (
    ("cor_n", "-"), ("cor_t", "-"), ("cor_t_contact", "-"), ("cor_tau_ratio", "-"),
    ("tau", "s"), ("tau1", "s"), ("tau2", "s"), ("x_max", "m"), ("F_max", "N"), ("Pc_max", "Pa"),
    ("W_diss_n", "J"), ("W_diss_t", "J"), ("spin_in", "rad/s"), ("spin_out", "rad/s"),
    ("f_min", "-"), ("f_max", "-"), ("omega_x", "rad/s"), ("omega_y", "rad/s"), ("ended_by", ""),
)


def _impact_title(d: dict) -> str:
    inp = d.get("inputs", {})
    mats = inp.get("materials", {})
    ball, plate = mats.get("ball", {}), mats.get("plate", {})
    return (f"impact: law {d.get('law')}, engine {d.get('engine')}; ball {ball.get('name')} "
            f"R = {fmt(inp.get('body1', {}).get('radius'))} m, m = {fmt(inp.get('body1', {}).get('mass'))} kg; "
            f"plate {plate.get('name')}; V = {fmt(inp.get('speed'))} m/s at {fmt(inp.get('angle_deg'))} deg")


def cmd_impact(args) -> int:
    engine = ENGINES[args.engine]  # argparse restricted the choice
    setup = build_impact(args)
    result = engine.run(setup)
    d = result.to_dict() if hasattr(result, "to_dict") else dict(result)
    d.setdefault("inputs", {})
    d["inputs"]["materials"] = {"ball": material_dict(setup.ball.material),
                                "plate": material_dict(setup.plate.material)}
    d["inputs"]["engine"] = args.engine
    if args.json:
        print(to_json(d))
    else:
        print(format_table([(k, d.get(k), u) for k, u in IMPACT_ROWS], _impact_title(d)))
        for reason in d.get("outside_validity") or []:
            print(f"  outside validity: {reason}")
    for reason in d.get("outside_validity") or []:  # also on stderr, so --json users see it
        print(f"{PROG}: warning: outside validity: {_one_line(reason)}", file=sys.stderr)
    return 0


# -------------------------------------------------------------- identify ---
def add_identify_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tau", type=number, required=True, metavar="T", help="measured contact duration tau_x [s]")
    p.add_argument("--cor", type=number, required=True, metavar="K", help="measured normal restitution k_x [-]")
    p.add_argument("--speed", type=number, required=True, metavar="V", help="normal impact speed [m/s]")
    p.add_argument("--radius", type=number, required=True, metavar="R", help="ball radius [m]")
    p.add_argument("--mass", type=number, required=True, metavar="KG", help="ball mass [kg]")
    p.add_argument("--kp-mode", choices=KP_MODES, default="msf", help="k_p mode of the MSF law (default msf)")
    p.add_argument("--omega", default="self-consistent", metavar="self-consistent|VALUE",
                   help="numerical inverse: omega_x self-consistent (default, = pi/tau_x) or fixed [rad/s]")
    p.add_argument("--separation", choices=SEPARATIONS, default="force-zero", help="end of contact (default force-zero)")
    add_material_arguments(p, "plate", "omitted: a rigid plate (the identified moduli are the ball's)")
    p.add_argument("--strict", action="store_true", help="tg(beta) > 1/3 from (88) is an error, not a warning")
    p.add_argument("--json", action="store_true", help="print one JSON object (SI units)")


def cmd_identify(args) -> int:
    from msf_contact.identification import ImpactMeasurement, identify_numerical, identify_printed

    for dest, unit in (("tau", "s"), ("speed", "m/s"), ("radius", "m"), ("mass", "kg")):
        check_positive(flag(dest), getattr(args, dest), unit=unit)
    check_finite("--cor", args.cor)
    omega = args.omega
    if omega != "self-consistent":
        try:
            omega = float(omega)
        except ValueError:
            raise ValueError(f"--omega = {args.omega!r} is not self-consistent or a number [rad/s]") from None
        check_positive("--omega", omega, unit="rad/s")
    plate = material(args, "plate", None)
    meas = ImpactMeasurement(tau=args.tau, cor=args.cor, speed=args.speed, radius=args.radius, mass=args.mass)
    printed = identify_printed(meas, args.kp_mode, strict=args.strict)
    numerical = identify_numerical(meas, kp_mode=args.kp_mode, omega=omega, separation=args.separation,
                                   plate=plate)
    out = {"inputs": {**asdict(meas), "kp_mode": args.kp_mode, "omega": omega, "separation": args.separation,
                      "plate": material_dict(plate)},
           "printed": asdict(printed), "numerical": asdict(numerical)}
    if args.json:
        out["use"] = "numerical" if (abs(numerical.residual_tau) <= IDENTIFY_MATCH
                                     and abs(numerical.residual_cor) <= IDENTIFY_MATCH) else None
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
    print(f"identify: tau_x = {fmt(args.tau)} s, k_x = {fmt(args.cor)}, V = {fmt(args.speed)} m/s, "
          f"R = {fmt(args.radius)} m, m = {fmt(args.mass)} kg, k_p mode {args.kp_mode}, plate {plate.name}")
    print(f"  {'':<{w0}}  {'(96)-(97), (88)':>16}  {'numerical':>16}")
    for label, a, b in rows:
        print(f"  {label:<{w0}}  {fmt(a):>16}  {fmt(b):>16}")
    if not plate.rigid:
        print(f"  ((96)-(97): effective values of the pair; numerical: the ball's, with effective (9), (91) "
              f"E' = {fmt(numerical.E_storage)} Pa, tg(beta) = {fmt(numerical.tan_delta)})")
    print(identify_advice(printed, numerical))
    return 0


#: |model - measured| of the numerical inverse below which it reproduces the
#: measurement (relative tau, absolute k_x); its own tolerances are ~1e-6.
IDENTIFY_MATCH = 1e-4


def identify_advice(printed, numerical) -> str:
    """Which answer of ``identify`` to use and why (issue 12)."""
    good = (abs(numerical.residual_tau) <= IDENTIFY_MATCH and abs(numerical.residual_cor) <= IDENTIFY_MATCH)
    r_E = printed.E_storage / numerical.ball_E_storage
    r_loss = printed.E_loss / numerical.ball_E_loss if numerical.ball_E_loss else float("nan")
    if good:
        return (f"  use the numerical column: with these moduli the reference solver reproduces tau_x and k_x "
                f"(residuals above). The (96)-(97) column is the paper's closed-form inverse, kept for "
                f"comparison: it rests on (89), which overstates the model's own restitution (docs/errata.md), "
                f"so its E' is {r_E:.3g} x and its E'' {r_loss:.3g} x the numerical ones")
    return ("  neither column reproduces the measurement: the numerical inverse did not match tau_x and k_x "
            f"within {IDENTIFY_MATCH:g} (residuals above); the measurement may lie outside what the model gives "
            "(tg(beta) <= 1/3, (100))")


register_command("impact", "one isolated impact of a ball on a plate", add_impact_arguments, cmd_impact)
register_command("identify", "E', E'' and tg(beta) from a measured (tau_x, k_x), (96)-(97) and numerically",
                 add_identify_arguments, cmd_identify)
COMMANDS.update(_MORE_COMMANDS)  # calibrate, run, report, demo


# ------------------------------------------------------------------ main ---
class _Parser(argparse.ArgumentParser):
    """argparse reading ``--tau -1e-3`` as a (negative, then refused by name)
    number; plain argparse takes only -1 and -0.5 for numbers and would
    report "expected one argument" without the value."""

    _NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-inf$|^-nan$", re.IGNORECASE)

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self._negative_number_matcher = self._NUMBER

    def error(self, message):
        """One line on stderr, exit code 2 (argparse prints its whole usage
        first: a 21-line dump for one bad value). ``--help`` shows the usage."""
        print(f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def _one_line(text) -> str:
    return " ".join(str(text).split())


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
    input raises SystemExit(2) (EXIT_BAD_INPUT) and a failed run SystemExit(1)
    (EXIT_FAILURE), each with one line ``msf-contact: error: ...`` on stderr
    and no usage dump or traceback."""
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        _install_warning_printer()
        try:
            return args._run(args)
        except ValueError as exc:  # refused input (ConfigError is one)
            print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
            raise SystemExit(EXIT_BAD_INPUT) from None
        except RuntimeError as exc:  # a run that failed (no convergence, a contact that never ended)
            print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
            raise SystemExit(EXIT_FAILURE) from None
        except Exception as exc:  # no traceback reaches a user (MSF_CONTACT_TRACEBACK=1 shows it)
            if os.environ.get("MSF_CONTACT_TRACEBACK"):
                raise
            print(f"{PROG}: error: {type(exc).__name__}: {_one_line(exc)} (a run failure; please report it with "
                  "the command line; MSF_CONTACT_TRACEBACK=1 shows where)", file=sys.stderr)
            raise SystemExit(EXIT_FAILURE) from None


if __name__ == "__main__":
    sys.exit(main())
