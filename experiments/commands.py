"""Subcommands `run`, `report` and `demo` of the `msf-contact` command line."""

from __future__ import annotations

import argparse
from pathlib import Path

from . import calibrate  # noqa: F401 - registers `calibrate`
from .cli import register_command


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{v} must be >= 1")
    return v


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG.toml", help="scenario configuration (see experiments/configs/)")
    p.add_argument("--out", default=None, metavar="DIR", help="result directory (default out/<config name>)")
    p.add_argument("--workers", type=_positive_int, default=1,
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


register_command("run", "run (or resume) a scenario configuration", add_run_arguments, cmd_run)
register_command("report", "rebuild a result directory's records, figures and report", add_report_arguments,
                 cmd_report)
register_command("demo", "the main comparison (what `make demo` runs)", add_demo_arguments, cmd_demo)
