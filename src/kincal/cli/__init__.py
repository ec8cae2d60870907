"""kincal command line: parses, calls the public API, prints (tables for people, --json for programs).

One module per concept: ``model`` (robots and their kinematics), ``design`` (pose design, separation),
``identify`` (calibrate, evaluate), ``report`` (the calibration report), ``parallel`` (compensation
and the error-model verification of the 3-PUU paper of 2024), ``study`` (Guo et al. 2024 reproduced, and its
Monte-Carlo study). Each adds its commands with ``register(cmd)``, through ``cmd(name, func, help[, robot help
or None])`` (:func:`build_parser`).
"""
from __future__ import annotations

import argparse
import re
import os
import signal
import sys
import traceback

import kincal
from kincal._atomic import DATA_STREAMS

from . import change, design, history, identify, model, parallel, report, study
from .common import EXIT_ERROR, EXIT_INTERRUPTED, EXIT_TERMINATED, err, line, point, progress_lines
from kincal.history import how_to_set, store_url

EXIT_INTERNAL = 70  # a bug in kincal, not in the user's input (KINCAL_DEBUG=1 shows the traceback)


class Terminated(Exception):
    """SIGTERM, turned into an exception so files being written are cleaned up like on Ctrl-C."""


def prepared(parser: argparse.ArgumentParser, args: argparse.Namespace) -> argparse.Namespace:
    """``args`` with ``given``: the options of the command that differ from their defaults, destination -> the
    flag (its long spelling), what :func:`kincal.identify.refuse_inapplicable` judges against the data's kinds;
    after the checks of flags that several commands share: a flag that asks for the default while another
    contradicts it, a flag without the one it modifies (ValueError)."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    args.given = {}
    for action in sub.choices[args.command]._actions:
        if action.option_strings and action.default is not argparse.SUPPRESS and action.dest not in args.given:
            if vars(args).get(action.dest, action.default) != action.default:
                args.given[action.dest] = action.option_strings[-1]  # declared short first: "-o", "--output"
    if "rebase" in args.given and args.rebase:  # the old spelling of --no-same-frame: it takes effect as that
        if args.same_frame:
            raise ValueError("--rebase (each session's frame re-fitted, as --no-same-frame) contradicts "
                             "--same-frame; give one")
        args.same_frame = False  # also over a calibration's recorded --same-frame (report)
    if "force" in args.given and args.force and not args.output:
        raise ValueError("--force writes the calibrated model despite a refused verdict: give the file with -o")
    if "at" in args.given and "store" in vars(args) and store_url(args.store) is None:
        raise ValueError(f"--at dates the record in the calibration store, and none is set: {how_to_set()}")
    return args


def on_sigterm(signum, frame):
    raise Terminated()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kincal", description="Robot kinematic calibration.")
    p.add_argument("--version", action="version", version=f"kincal {kincal.__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def cmd(name, func, help_, robot: str | None = "bundled name, kincal robot YAML or URDF file"):
        """A command's parser: --json and, unless ``robot`` is None, the ROBOT argument (``robot``: its help)
        with the tool point and the URDF chain flags."""
        s = sub.add_parser(name, help=help_, description=help_)
        s.add_argument("--json", action="store_true", help="machine-readable result on stdout (SI units)")
        if robot is not None:
            s.add_argument("robot", help=robot)
            s.add_argument("--tool", type=point, metavar="X,Y,Z[UNIT]",
                           help="the measured point (reflector, probe) in the flange frame, e.g. 0,0,93.2mm (unit m, "
                                "mm or um after the numbers; m when none); replaces the robot file's tool point")
            g = s.add_argument_group("URDF robots")
            g.add_argument("--base-link", help="first link of the chain (default: the URDF's root link)")
            g.add_argument("--tip-link", help="last link of the chain (default: the only end link)")
        s.set_defaults(func=func)
        return s

    for room in (model, identify, report, design, parallel, study, change, history):
        room.register(cmd)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run one command; exit 0 (done), 1 (bad input), 3 (not converged), 4 (refused by a check),
    70 (internal error), 130 (Ctrl-C), 143 (SIGTERM). Outputs are written atomically, so an
    interrupted command leaves no half-written file."""
    previous = signal.signal(signal.SIGTERM, on_sigterm), signal.getsignal(signal.SIGINT)
    DATA_STREAMS.clear()  # this command's outputs decide where its messages go (common.emit)
    try:
        parser = build_parser()
        tokens = _negative_values(parser, list(sys.argv[1:] if argv is None else argv))
        args, extra = parser.parse_known_args(tokens)
        if extra:
            parser.exit(2, f"kincal {args.command}: error: unrecognized arguments: {' '.join(extra)}"
                           f"{_elsewhere(parser, args.command, extra)}\n")
        if progress_lines():  # a log (or a test) learns that Ctrl-C and SIGTERM are handled from here on
            line(f"kincal: {args.command} started")
        try:  # a signal while an error is printed is still caught below
            _once(parser, tokens)
            return args.func(prepared(parser, args))
        except Terminated:  # an Exception, but no internal error: stopped below
            raise
        except (kincal.KincalError, ValueError, OSError) as exc:
            if not isinstance(exc, (kincal.KincalError, OSError)) and not raised_by_kincal(exc):
                return internal(exc)
            msg = " ".join(str(exc).split()) if not isinstance(exc, kincal.IdentifiabilityError) else str(exc)
            err.print(f"kincal: error: {msg}", markup=False)
            return EXIT_ERROR
        except Exception as exc:  # never a bare traceback for a user
            return internal(exc)
    except KeyboardInterrupt:
        return stopped("interrupted", EXIT_INTERRUPTED)
    except Terminated:
        return stopped("terminated", EXIT_TERMINATED)
    finally:
        signal.signal(signal.SIGTERM, previous[0])
        if previous[1] is not None:  # None: a handler not set from Python
            signal.signal(signal.SIGINT, previous[1])


def internal(exc: Exception) -> int:
    """A bug in kincal, not in the user's input: one line asking for a report (KINCAL_DEBUG=1: the traceback,
    re-raised from the handler that called this)."""
    if os.environ.get("KINCAL_DEBUG"):
        raise exc
    err.print(f"kincal: internal error ({type(exc).__name__}: {exc}); please report it with the command "
              f"line (KINCAL_DEBUG=1 shows the details)", markup=False)
    return EXIT_INTERNAL


KINCAL_DIR = os.path.dirname(os.path.abspath(kincal.__file__)) + os.sep
_REMOTE_FRAME = re.compile(r'\s*File "([^"]+)", line \d+, in ')  # a frame of a traceback's text; its code follows


def raised_by_kincal(exc: BaseException) -> bool:
    """Whether a raise statement of a kincal module raised ``exc``: a message kincal wrote for the user (a
    ValueError naming the flag or the value and what to do). A ValueError raised inside numpy or another library,
    or by an operation in kincal's code (shapes that do not broadcast, ``list.index`` of a missing name), is a bug
    and reported as one. A worker process's exception is judged by its traceback's text, which it carries."""
    remote = exc.__cause__  # concurrent.futures' _RemoteTraceback: the worker's traceback as text (.tb)
    text = vars(remote).get("tb") if remote is not None and type(remote).__name__ == "_RemoteTraceback" else None
    if isinstance(text, str):
        lines = text.splitlines() + [""]
        frames = [(m.group(1), "" if lines[k + 1].lstrip().startswith("File ") else lines[k + 1])
                  for k, m in enumerate(map(_REMOTE_FRAME.match, lines[:-1])) if m]
    else:
        frames = [(f.filename, f.line or "") for f in traceback.extract_tb(exc.__traceback__)]
    if not frames:
        return False
    filename, line = frames[-1]
    return os.path.abspath(filename).startswith(KINCAL_DIR) and line.strip().startswith("raise ")


def _once(parser: argparse.ArgumentParser, argv: list[str]) -> None:
    """Refuse a flag that takes one value given more than once (``--seed 1 --seed 2``: argparse keeps the last
    silently); repeatable flags (``--test``, ``--keep-out``) may repeat."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    command = sub.choices.get(argv[0]) if argv else None
    if command is None:
        return
    seen: dict[str, str | None] = {}
    for k, token in enumerate(argv[1:], start=1):
        flag, _, inline = token.partition("=")
        action = command._option_string_actions.get(flag) if token.startswith("-") else None
        if action is None or type(action) not in (argparse._StoreAction, argparse._StoreTrueAction,
                                                  argparse._StoreConstAction, argparse.BooleanOptionalAction):
            continue  # repeatable: --test, --keep-out, --distance and --plane (each judged on its own)
        value = (inline or None) if "=" in token else (argv[k + 1] if action.nargs != 0 and k + 1 < len(argv) else None)
        if isinstance(action, argparse.BooleanOptionalAction):  # --coverage and --no-coverage: two values
            value = "off" if flag.startswith("--no-") else "on"
        if action.dest in seen and seen[action.dest] != value and isinstance(action, argparse.BooleanOptionalAction):
            raise ValueError(f"{' and '.join(action.option_strings)} are both given (only the last would count): "
                             f"give one")
        if action.dest in seen and seen[action.dest] != value:  # the same value again changes nothing
            raise ValueError(f"{flag} is given twice, as {seen[action.dest]} and {value} (only the last would "
                             f"count): give it once")
        seen[action.dest] = value


RECORDED = ("report",)  # commands that read how the data are read from the calibration's record
MAIN = ("calibrate", "evaluate", "compensate", "design", "simulate")  # named first where a flag is theirs


def _elsewhere(parser: argparse.ArgumentParser, command: str, extra: list[str]) -> str:
    """A hint for flags a command does not have: the commands that do (``--type`` is calibrate's and evaluate's,
    not report's, which reads how the files were read from the calibration's record); '' when none has them."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    hints = []
    for flag in dict.fromkeys(t.partition("=")[0] for t in extra if t.startswith("--")):
        owners = sorted((name for name, p in sub.choices.items() if flag in p._option_string_actions),
                        key=lambda name: MAIN.index(name) if name in MAIN else len(MAIN))  # stable: then as listed
        if owners:
            more = f" and {len(owners) - 3} more" if len(owners) > 3 else ""
            hints.append(f"{flag} is a flag of {', '.join(owners[:3])}{more}, not of {command}")
    if hints and command in RECORDED:
        hints.append(f"{command} reads how the data were read (their type, units, columns, orientation) from the "
                     f"calibration's record; --joint-cols, --xyz-cols and the units override it")
    return f" ({'; '.join(hints)})" if hints else ""


def _negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``--tool -1,-7,1.6mm`` as ``--tool=-1,-7,1.6mm``: argparse takes a value that starts with '-' and is not
    one plain number for another flag ("expected one argument"). Only after a flag of the command that takes a value."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    command = sub.choices.get(argv[0]) if argv else None
    if command is None:
        return argv
    out: list[str] = []
    for token in argv:
        action = command._option_string_actions.get(out[-1]) if out else None
        if action is not None and action.nargs != 0 and re.match(r"-[\d.]", token):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def stopped(word: str, code: int) -> int:
    """One line for Ctrl-C or SIGTERM; a second signal while it is printed, or while Python shuts down, is ignored."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    line(f"kincal: {word}; nothing half-written")
    return code
