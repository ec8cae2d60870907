"""kincal command line: parses, calls the public API, prints (tables for people, --json for programs).

One module per concept: ``model`` (robots and their kinematics), ``design`` (pose design, separation),
``identify`` (calibrate, evaluate), ``report`` (the calibration report), ``parallel`` (compensation
and the 3-PUU paper's error-model verification), ``study`` (Guo et al. 2024 reproduced, and its
Monte-Carlo study).
"""
from __future__ import annotations

import argparse
import os
import signal
import sys

import kincal

from . import design, identify, model, parallel, report, study
from .common import EXIT_ERROR, EXIT_INTERRUPTED, EXIT_TERMINATED, err, line, progress_lines

EXIT_INTERNAL = 70  # a bug in kincal, not in the user's input (KINCAL_DEBUG=1 shows the traceback)


class Terminated(Exception):
    """SIGTERM, turned into an exception so files being written are cleaned up like on Ctrl-C."""


def _on_sigterm(signum, frame):
    raise Terminated()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kincal", description="Robot kinematic calibration.")
    p.add_argument("--version", action="version", version=f"kincal {kincal.__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def cmd(name, func, help_):
        s = sub.add_parser(name, help=help_, description=help_)
        s.add_argument("--json", action="store_true", help="machine-readable result on stdout (SI units)")
        s.set_defaults(func=func)
        return s

    for room in (model, identify, report, design, parallel, study):
        room.register(cmd)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run one command; exit 0 (done), 1 (bad input), 3 (not converged), 4 (refused by a check),
    70 (internal error), 130 (Ctrl-C), 143 (SIGTERM). Outputs are written atomically, so an
    interrupted command leaves no half-written file."""
    previous = signal.signal(signal.SIGTERM, _on_sigterm), signal.getsignal(signal.SIGINT)
    try:
        return _run(argv)
    except KeyboardInterrupt:
        return _stopped("interrupted", EXIT_INTERRUPTED)
    except Terminated:
        return _stopped("terminated", EXIT_TERMINATED)
    finally:
        signal.signal(signal.SIGTERM, previous[0])
        if previous[1] is not None:  # None: a handler not set from Python
            signal.signal(signal.SIGINT, previous[1])


def _stopped(word: str, code: int) -> int:
    """One line for Ctrl-C or SIGTERM; a second signal while it is printed is ignored."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    line(f"kincal: {word}; nothing half-written")
    return code


def _run(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if progress_lines():  # a log (or a test) learns that Ctrl-C and SIGTERM are handled from here on
        line(f"kincal: {args.command} started")
    try:
        return args.func(args)
    except (kincal.KincalError, ValueError, OSError) as exc:
        msg = " ".join(str(exc).split()) if not isinstance(exc, kincal.IdentifiabilityError) else str(exc)
        err.print(f"kincal: error: {msg}", markup=False)
        return EXIT_ERROR
    except (KeyboardInterrupt, Terminated):
        raise
    except Exception as exc:  # never a bare traceback for a user
        if os.environ.get("KINCAL_DEBUG"):
            raise
        err.print(f"kincal: internal error ({type(exc).__name__}: {exc}); please report it with the command "
                  f"line (KINCAL_DEBUG=1 shows the details)", markup=False)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
