"""kincal command line: parses, calls the public API, prints (tables for people, --json for programs).

One module per concept: ``model`` (robots and their kinematics), ``design`` (pose design, separation),
``identify`` (calibrate, evaluate), ``parallel`` (seed-2 commands: compensation, error-model
verification), ``study`` (the demonstration).
"""
from __future__ import annotations

import argparse
import sys

import kincal

from . import design, identify, model, parallel, study
from .common import EXIT_ERROR, err


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kincal", description="Robot kinematic calibration.")
    p.add_argument("--version", action="version", version=f"kincal {kincal.__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def cmd(name, func, help_):
        s = sub.add_parser(name, help=help_, description=help_)
        s.add_argument("--json", action="store_true", help="machine-readable result on stdout (SI units)")
        s.set_defaults(func=func)
        return s

    for room in (model, identify, design, parallel, study):
        room.register(cmd)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (kincal.KincalError, ValueError, OSError) as exc:
        msg = " ".join(str(exc).split()) if not isinstance(exc, kincal.IdentifiabilityError) else str(exc)
        err.print(f"kincal: error: {msg}", markup=False)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
