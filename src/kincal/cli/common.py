"""Helpers shared by the command-line modules: consoles, data flags, progress, output."""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from rich.console import Console

import kincal
from kincal._atomic import data_on_stdout
from kincal._csv import open_table
from kincal.models.plausible import MAX_TOOL  # m: no tool point lies farther from the flange (robot files too)
from kincal.units import ANGLE_UNITS, LENGTH_UNITS

out = Console(highlight=False, soft_wrap=True)
err = Console(stderr=True, highlight=False, soft_wrap=True)
EXIT_ERROR, EXIT_NOT_CONVERGED, EXIT_REFUSED = 1, 3, 4
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143
CELL_SIZE = 100.0  # m: a length beyond this in a robot cell, given without a unit, is taken for mm
CELL_UNITLESS = 10.0  # m: a cell flag's length beyond this without a unit (--floor -50) is refused as mm
CELL = "the cell"  # lengths(where=CELL): a cell flag's message
TYPES = kincal.observe.KINDS  # measurement types (--type)


def verdict_exit(verdict, converged: bool) -> int:
    """The exit status of a calibration's ``verdict`` (its status alone): 0 good or suspect; refused EXIT_REFUSED,
    EXIT_NOT_CONVERGED when the fit did not ``converge`` and no reason but that (and the likely cause it prompted)
    refuses it."""
    if verdict.status != "refused":
        return 0
    others = [r for r in verdict.reasons if r.level == "refused" and r.code != "not-converged"
              and not r.code.startswith("cause-")]
    return EXIT_NOT_CONVERGED if not converged and not others else EXIT_REFUSED


def csv_list(s: str) -> list[str]:
    return [c.strip() for c in s.split(",") if c.strip()]


def _number(s: str, ok, need: str, parse=float, what: str = "a number"):
    """``s`` read by ``parse`` (``what``) for which ``ok`` holds; an ArgumentTypeError saying ``need`` (with ``s``
    and the value ``v`` put in) otherwise."""
    try:
        v = parse(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}' is not {what}") from None
    if not ok(v):
        raise argparse.ArgumentTypeError(need.format(s=s, v=v))
    return v


def positive_int(s: str) -> int:
    """argparse type: a whole number ≥ 1."""
    return _number(s, lambda v: v >= 1, "{v}: give at least 1", int, "a whole number")


def nonneg_int(s: str) -> int:
    """argparse type: a whole number ≥ 0."""
    return 0 if s.strip() == "0" else positive_int(s)


def nonneg_float(s: str) -> float:
    """argparse type: a finite number ≥ 0."""
    return _number(s, lambda v: np.isfinite(v) and v >= 0, "{s}: give a finite number >= 0")


def finite_float(s: str) -> float:
    """argparse type: a finite number."""
    return _number(s, np.isfinite, "'{s}': give a finite number")


def positive_float(s: str) -> float:
    """argparse type: a finite number > 0."""
    v = nonneg_float(s)
    if v == 0:
        raise argparse.ArgumentTypeError(f"{s}: give a number > 0")
    return v


def checked(check):
    """An argparse type from ``check``, whose ValueError's message is the flag's error."""
    def parse(s: str):
        try:
            return check(s)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return parse


def judged(parse, rule):
    """argparse type: ``parse``'s value (SI) judged at once by ``rule``, the option record's own check of that value
    (e.g. the record built with it alone), whose refusal is said with the value as typed. A record's message is
    'SUBJECT: WHAT TO DO', its subject in SI ("tracker range 20.0..0.5 m: give 0 ≤ min < max"); the flag's is the
    text typed and what to do ("argument --tracker-range: '20000,500mm': give 0 ≤ min < max")."""
    def parsed(s: str):
        value = parse(s)
        try:
            rule(value)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"'{s.strip()}': {str(exc).partition(': ')[2] or exc}") from None
        return value
    return parsed


def row_list(s: str) -> list[int]:
    """'5,7-9' -> [5, 7, 8, 9] (input file rows, header = 1)."""
    rows: list[int] = []
    for part in csv_list(s):
        lo, _, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi or lo)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{part}' is not a row number or range like 7-9") from None
        if a < 2 or b < a:
            raise argparse.ArgumentTypeError(f"'{part}': rows are file line numbers from 2 (after the header)")
        rows += range(a, b + 1)
    return rows


def lengths(count: int, example: str, what: str = "", limit: float = CELL_SIZE, where: str = "the robot"):
    """argparse type: ``count`` numbers with an optional length unit after them ('3000,0,500mm'), in m.
    ``what`` names the numbers in the message (default "<count> finite number(s)"); without a unit, a
    value beyond ``limit`` (m) from ``where`` is taken for mm (:func:`cell_lengths`: beyond ``CELL_UNITLESS``)."""
    def parse(s: str) -> tuple[float, ...]:
        text = s.strip()
        unit = next((u for u in sorted(LENGTH_UNITS, key=len, reverse=True) if text.endswith(u)), None)
        try:
            t = tuple(float(x) * LENGTH_UNITS[unit or "m"] for x in csv_list(text[:-len(unit)] if unit else text))
        except ValueError:
            t = ()
        if len(t) != count or not all(np.isfinite(t)):
            raise argparse.ArgumentTypeError(f"'{s}': give {what or f'{count} finite number(s)'} and a unit, "
                                             f"e.g. {example}")
        if unit is None and max(map(abs, t)) > limit:
            big = max(t, key=abs)
            raise argparse.ArgumentTypeError(f"'{s}': {big:g} m without a unit looks like mm: give the unit ({text}mm)"
                                             if where == CELL else f"'{s}': {abs(big):g} m from {where}; these look "
                                             f"like mm: write {text}mm")
        return t
    return parse


def cell_lengths(count: int, example: str):
    """argparse type of a cell flag's lengths (--floor, --keep-out, --tracker, --tracker-range, --link-radius): as
    :func:`lengths`, and a value beyond ``CELL_UNITLESS`` (10 m) without a unit (--floor -50) is refused as mm."""
    return lengths(count, example, limit=CELL_UNITLESS, where=CELL)


# argparse type: 'X,Y,Z' with an optional length unit after the numbers ('0,0,93.2mm'), in m
point = lengths(3, "0,0,93.2mm", "three finite numbers X,Y,Z", MAX_TOOL, "the flange")


def one_type(args, flag: str = "--type") -> str:
    """The one measurement type --type gives (point when none); a ValueError starting with ``flag`` otherwise."""
    kinds = args.type or ["point"]
    if len(kinds) != 1 or kinds[0] not in TYPES:
        raise ValueError(f"{flag}: give one of {', '.join(TYPES)}")
    return kinds[0]


def load_robot(args, inputs=None, outputs=()):
    """The command's robot, with the URDF chain flags when given; with ``inputs`` (files the command reads), first
    :func:`check_paths` of them, the robot's own files and ``outputs``."""
    if inputs is not None:
        check_paths([*robot_inputs(args.robot), *inputs], outputs)
    return kincal.load_robot(args.robot, base_link=args.base_link, tip_link=args.tip_link, tool=args.tool)


def covariates_read(robot, uncertainty):
    """``robot`` without the covariates no term of it reads (a calibration given --covariate-cols whose model has no
    thermal term: they change no prediction), its ``uncertainty``'s training ranges without them, and a note naming
    them ('' when there are none)."""
    used = kincal.models.without_unread_covariates(robot)
    unread = [c for c in robot.covariate_names if c not in used.covariate_names]
    if not unread:
        return robot, uncertainty, ""
    keep = [robot.joint_names.index(n) for n in used.joint_names]
    note = (f"note: no term of the error model ({robot.error_model}) reads the covariate {', '.join(unread)}: its "
            f"column is not used, the file need not have it")
    return used, None if uncertainty is None else uncertainty.on_inputs(keep), note


def hidden_alias(p: argparse.ArgumentParser, flag: str, dest: str, **kw) -> None:
    """An old spelling of an option, still accepted for one release, not shown in --help."""
    p.add_argument(flag, dest=dest, help=argparse.SUPPRESS, default=argparse.SUPPRESS, **kw)


def robot_inputs(robot: str) -> list[str]:
    """The robot argument as an input file, if it is one, and the file it was made from (a calibrated
    robot file's ``source``, e.g. the user's URDF): outputs must replace neither."""
    if not Path(robot).is_file():
        return []
    try:
        source = kincal.models.yaml_io.read_section(robot, "source")
    except kincal.errors.KincalError:  # a malformed file: loading it says why
        source = None
    made_from = source.get("file") if isinstance(source, dict) else None
    made_from = str(Path(robot).parent / made_from) if isinstance(made_from, str) else None  # relative to the file
    return [robot] + ([made_from] if made_from and Path(made_from).is_file() else [])


def check_paths(inputs, outputs) -> None:
    """Before any work: every output can be written, and none is an input or another output."""
    ins = [Path(p) for p in inputs if p]
    seen: list[Path] = []
    for raw in (o for o in outputs if o):
        out_path = Path(raw)
        for other in ins + seen:  # an input that does not exist yet: the same path
            if (os.path.samefile(out_path, other) if out_path.exists() and other.exists() else
                    out_path.resolve() == other.resolve()):
                raise ValueError(f"{raw}: the output would overwrite {other}, which this command reads (or writes "
                                 f"already); choose another output file")
        folder = out_path.parent  # Path("out.csv").parent is Path(".")
        if out_path.is_dir():
            raise ValueError(f"{raw}: is a folder; give a file name for the output")
        if not folder.is_dir():
            raise ValueError(f"{raw}: the folder {folder} does not exist; create it or choose another output path")
        if not os.access(folder, os.W_OK):
            raise ValueError(f"{raw}: the folder {folder} is not writable; choose another output path")
        seen.append(out_path)


def add_data_flags(p: argparse.ArgumentParser, std: bool = True) -> None:
    """The columns and units of a data file; ``std``: the file may carry σ columns (measurements do,
    targets and verification readings do not: there the flag does not exist, so it is refused)."""
    g = p.add_argument_group("data columns and units")
    g.add_argument("--joint-cols", type=csv_list, default=None,
                   help="comma-separated joint columns (default: the robot's joint names)")
    g.add_argument("--xyz-cols", type=csv_list, default=["x", "y", "z"], help="position columns (default x,y,z)")
    g.add_argument("--length-unit", default="m", choices=list(LENGTH_UNITS), help="positions, prismatic joints")
    g.add_argument("--angle-unit", choices=list(ANGLE_UNITS), help="revolute joints (default rad)")
    if std:
        g.add_argument("--std-cols", type=csv_list, default=None,
                       help="the instrument's σ per sample, X,Y,Z columns in the length unit (default: "
                            "measurement_std_x,measurement_std_y,measurement_std_z when present; 'none' ignores them)")


def angle_unit(args) -> str:
    """--angle-unit as typed, else its default "rad": the flag is None when not typed, and the readers told None
    say so of joint values in another unit."""
    return args.angle_unit or "rad"


def joint_values(args, robot, path: str | None) -> np.ndarray:
    """The joints of the CSV ``path`` (read as the data flags say), else ``args.poses`` random feasible poses."""
    return (kincal.read_joints(path, robot, args.joint_cols, args.length_unit, args.angle_unit) if path
            else robot.sample_joints(args.poses, seed=args.seed))


def read(args, robot, path):
    std = None if args.std_cols is None else ([] if args.std_cols == ["none"] else args.std_cols)
    return kincal.read_measurements(path, robot, joint_cols=args.joint_cols, xyz_cols=args.xyz_cols,
                                    length_unit=args.length_unit, angle_unit=args.angle_unit, std_cols=std)


def unread_joints(path: str, robot, joint_cols) -> list[str]:
    """Columns of a data file named like its joint columns with another number (joint_7 beside the joint_1 …
    joint_6 a six-joint robot reads): a robot with more joints may have made the file."""
    try:
        header = open_table(path).header
    except (OSError, kincal.KincalError, ValueError):
        return []
    cols = list(joint_cols) if joint_cols else robot.default_columns(header)
    found = [re.fullmatch(r"(.*?)(\d+)", c) for c in cols]
    prefixes = {f.group(1) for f in found if f is not None}
    if None in found or len(prefixes) != 1:
        return []
    prefix = prefixes.pop()
    return [h for h in header if h not in cols and re.fullmatch(re.escape(prefix) + r"\d+", h)]


def progress_lines() -> bool:
    """Whether progress goes to stderr as plain lines (``KINCAL_PROGRESS=1``, e.g. for a log)."""
    return os.environ.get("KINCAL_PROGRESS", "") not in ("", "0")


def line(text: str) -> None:
    """One plain line on stderr, written at once. Progress lines and the last words after Ctrl-C go
    this way, not through rich: a signal that lands while rich copies its buffer to the terminal
    leaves that buffer full, and rich's next print would show the interrupted line twice."""
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


@contextmanager
def progress(message: str, quiet: bool):
    """A spinner on stderr for work that may take over a second (off with --json); with
    ``KINCAL_PROGRESS=1`` each stage as a line ``kincal: <stage>`` instead, terminal or not."""
    if progress_lines():
        line(f"kincal: {message}")
        yield lambda msg: line(f"kincal: {msg}")
        return
    if quiet or not err.is_terminal:
        yield lambda msg: None
        return
    with err.status(message) as status:
        yield lambda msg: status.update(msg)


@contextmanager
def progress_bar(args, label: str, total: int | None = None):
    """A progress bar on stderr for ``label``: tasks done of ``total``, or with no total a share of
    bytes; yields the callback, called with (done, total). Silent with --json or when stderr is not
    a terminal; with ``KINCAL_PROGRESS=1`` a line ``kincal: <label> N %`` per tenth instead."""
    lines = progress_lines() and not args.json
    if args.json or not err.is_terminal or lines:
        shown = [-1]  # the last tenth said

        def say(done: int, of: int) -> None:
            if lines and of > 0 and int(10 * done / of) > shown[0]:
                shown[0] = int(10 * done / of)
                line(f"kincal: {label} {100 * done // of} %")
        yield say
        return
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TaskProgressColumn, TextColumn,
                               TimeRemainingColumn)

    count = MofNCompleteColumn() if total is not None else TaskProgressColumn()
    with Progress(TextColumn(label), BarColumn(), count, TimeRemainingColumn(), console=err,
                  transient=total is None) as bar:
        task = bar.add_task(label, total=total)
        yield lambda done, of: bar.update(task, completed=done, total=of)


def emit(args, payload: dict, text, code: int = 0) -> int:
    """Print the result (``payload`` as JSON with --json, else ``text``); return the exit ``code``. To the standard
    error when an output file went to the standard output (``-o /dev/stdout``): the data stay data."""
    moved = data_on_stdout()
    if args.json:
        (sys.stderr if moved else sys.stdout).write(json.dumps(payload, indent=2, default=json_default) + "\n")
    else:  # plain text printed as it is: '[' in a parameter name is no rich markup
        (err if moved else out).print(text, markup=False if isinstance(text, str) else None)
    return code


def json_default(o):
    if isinstance(o, (np.ndarray, np.generic)):  # a numpy scalar's tolist() is its item()
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
