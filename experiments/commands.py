"""Subcommands `calibrate`, `run`, `report` and `demo` of the `msf-contact`
command line (:data:`COMMANDS`; :mod:`experiments.cli` adds them to its own
after ``impact`` and ``identify``)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from . import calibrate
from .arguments import positive_int


@dataclass(frozen=True)
class Command:
    """A subcommand: ``add_arguments(parser)`` declares its flags,
    ``run(args) -> int`` does the work and returns the exit code."""

    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG.toml", help="scenario configuration (see experiments/configs/)")
    p.add_argument("--out", default=None, metavar="DIR", help="result directory (default out/<config name>)")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="local worker processes (default 1), or Dask workers with --dask local")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run the cells on a Dask cluster: a scheduler address, or 'local' for a LocalCluster")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def cmd_run(args) -> int:
    from .runner import run

    out = run(args.config, args.out, workers=args.workers, dask=args.dask, quiet=args.quiet)
    if not args.quiet:
        print(out / "report.md")
    return 0


def add_report_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dir", metavar="DIR", help="a result directory written by `msf-contact run`")
    p.add_argument("--quiet", action="store_true")


def cmd_report(args) -> int:
    from .runner import report

    path = report(args.dir, quiet=args.quiet)
    if not args.quiet:
        print(path)
    return 0


def add_demo_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="out/demo", metavar="DIR", help="result directory (default out/demo)")
    p.add_argument("--quiet", action="store_true")


def cmd_demo(args) -> int:
    from .demo import run_demo

    run_demo(Path(args.out), args.quiet)
    return 0


#: The subcommands of this module, in the order of ``msf-contact --help``.
COMMANDS: dict[str, Command] = {
    "calibrate": Command("MuJoCo solref / pybullet restitution, stiffness and damping that reproduce MSF's "
                         "COR and contact duration at one speed and time step", calibrate.add_calibrate_arguments,
                         calibrate.cmd_calibrate),
    "run": Command("run (or resume) a scenario configuration", add_run_arguments, cmd_run),
    "report": Command("rebuild a result directory's records, figures and report", add_report_arguments, cmd_report),
    "demo": Command("the main comparison (what `make demo` runs)", add_demo_arguments, cmd_demo),
}
