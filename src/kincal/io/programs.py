"""Robot programs: the move targets in a program's text, and the text with new targets put back.

One module per vendor language — a :class:`Dialect` — finds the moves and their literal targets:
``program_ur.py`` (Universal Robots' URScript), ``program_krl.py`` (KUKA KRL), ``program_rapid.py``
(ABB RAPID), ``program_fanuc.py`` (FANUC TP, ASCII ``.ls``) and ``program_inform.py`` (Yaskawa
INFORM ``.JBI``). Everything else — comments, declarations, speeds, blends, other commands, spacing,
line endings, a byte-order mark — stays byte for byte, because only the spans of the literal targets
(URScript) or of their numbers (the other languages: each written again in its own style,
:mod:`kincal._numstyle`) are replaced. A move whose target is not a literal (a variable filled at
run time, an offset computed by the controller) is listed with its line and why, never touched.

A target's values are in SI and one convention for every language: a pose is x, y, z (m) and a
rotation vector (rad) of the TCP in the program's frame; joints are rad (revolute) or m. Its
``config`` keeps the branch as written (KRL S and T, RAPID cf1/cf4/cf6/cfx, FANUC ``CONFIG``,
INFORM ``RCONF``) and its ``frames`` the tool and base (work object, user frame) the program names.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from .._atomic import write_text_atomic
from .._collector import paused_collector
from .._numstyle import restyle_all
from ..errors import MeasurementError


@dataclass(frozen=True)
class Target:
    """One literal target: its span in the text and its line, the move, and its values: a pose (x, y,
    z in m, rotation vector in rad; ``kind`` "pose"), joint values (rad; "joints") or a Yaskawa PULSE
    position's encoder counts as written ("pulses": joints once the robot's pulses per degree are known);
    where the move is in the text (``at``) and the variable it moves to ('' for a literal in the move; the span and
    line are then those of the variable's literal). In the vendor languages ``fields`` are the spans of
    the numbers that carry ``values`` (in the language's order and units: what a rewrite replaces),
    ``config`` the branch as written ((S, T); (cf1, cf4, cf6, cfx); ('N U T', turn1, turn2, turn3);
    the RCONF digits) and ``frames`` the (tool, base) the target is in, as the program names them ('' for
    none named: the controller's default)."""

    start: int
    end: int
    line: int
    move: str
    kind: str
    values: np.ndarray
    at: int = -1
    variable: str = ""
    fields: tuple[tuple[int, int], ...] = ()
    config: tuple = ()
    frames: tuple[str, str] = ("", "")


@dataclass(frozen=True)
class Program:
    """A program's text, its literal targets in the order of the moves, what is listed, never touched
    (line, what: the move or item as written, why: the reason a user reads), the TCPs it sets (position in
    the text, the pose (6,) or None when not a literal), its language's comment mark ('' for a language that
    allows none beside a target) and its dialect's name."""

    source: str
    text: str
    targets: tuple[Target, ...]
    not_literal: tuple[tuple[int, str, str], ...] = field(default=())
    encoding: str = "utf-8"
    tcps: tuple = ()
    comment: str = "#"
    dialect: str = "ur"

    def tcp_at(self, at: int):
        """The TCP set last before position ``at`` (its pose (6,), None if not a literal), or () when none."""
        before = [pose for where, pose in self.tcps if where < at]
        return before[-1] if before else ()

    def with_targets(self, texts: dict[int, str], marks: dict[int, str] | None = None) -> str:
        """The text with target k's span replaced by ``texts[k]`` (the others as they are), and a
        comment ``marks[k]`` at the end of the line of each target k that is left as it is."""
        edits = sorted([(t.start, t.end, texts[k]) for k, t in enumerate(self.targets) if k in texts]
                       + _marks(self, marks or {}))
        out, at = [], 0
        for a, b, new in edits:
            out += [self.text[at:a], new]
            at = b
        return "".join(out) + self.text[at:]

    def with_values(self, values: dict[int, np.ndarray], marks: dict[int, str] | None = None) -> str:
        """The text with target k written again from ``values[k]`` (SI, the target's kind) by the
        program's dialect — in the vendor languages number by number, each in the style it had — and
        every other byte as it is; ``marks`` as in :meth:`with_targets`."""
        ks = list(values)
        new = dialects()[self.dialect].write(self.text, [self.targets[k] for k in ks], [values[k] for k in ks])
        return self.with_targets(dict(zip(ks, new)), marks)


def no_frames(program: Program) -> dict[str, np.ndarray]:
    """A language whose programs declare no frame values of their own: none."""
    return {}


@dataclass(frozen=True)
class Dialect:
    """A vendor language: its name, the file suffixes it is read from (lower case), its comment mark,
    its reader ``parse(source, text) -> Program``, its writer ``write(text, targets, values) -> texts`` (the
    new texts of the targets' spans for new SI values, all at once; see :func:`write_fields`) and
    ``frames(program)``: the tool and base frames a program declares (or its controller holds beside it) with
    their values, by the names its targets use (4x4, m; or why a frame it names cannot be known)."""

    name: str
    suffixes: tuple[str, ...]
    comment: str
    parse: Callable[[str, str], Program]
    write: Callable[[str, Sequence[Target], Sequence[np.ndarray]], list[str]]
    frames: Callable[[Program], Mapping[str, np.ndarray | str]] = no_frames


Numbers = Callable[[str, Sequence[Target], np.ndarray], tuple[np.ndarray, np.ndarray]]


def write_fields(text: str, targets: Sequence[Target], values: Sequence[np.ndarray], numbers: Numbers) -> list[str]:
    """The new texts of the targets' spans for new SI ``values``, field by field: the targets are taken in
    groups of one kind and one number of values, ``numbers(text, group, values (G, V))`` gives each group's
    field numbers (G, F) in the fields' units and their resolution (G, F) or (F,), and each number is written
    in its old style with at least the decimals that carry it to its resolution
    (:func:`kincal._numstyle.restyle_all`); every other byte of a span as it is. All at once per group (a
    10^4-target program is converted in one step, not target by target)."""
    out = [""] * len(targets)
    groups: dict[tuple[str, int], list[int]] = {}
    for k, (t, v) in enumerate(zip(targets, values)):
        groups.setdefault((t.kind, np.size(v)), []).append(k)
    for ks in groups.values():
        group = [targets[k] for k in ks]
        found, resolution = numbers(text, group, np.array([values[k] for k in ks], dtype=float))
        olds = [text[a:b] for t in group for a, b in t.fields]
        new = iter(restyle_all(olds, found.ravel(), np.broadcast_to(resolution, found.shape).ravel()))
        for k, t in zip(ks, group):
            out[k] = _spliced(text, t, [next(new) for _ in t.fields])
    return out


def old_numbers(text: str, targets: Sequence[Target], fields: slice = slice(None)) -> np.ndarray:
    """The numbers (G, F) the targets' ``fields`` hold in ``text`` now (each target the same count)."""
    return np.array([[float(text[a:b]) for a, b in t.fields[fields]] for t in targets], dtype=float).reshape(
        len(targets), -1)


def _spliced(text: str, target: Target, numbers: list[str]) -> str:
    """The target's span of ``text`` with its fields' texts replaced by ``numbers`` (in the fields' order)."""
    pieces, at = [], target.start
    for (a, b), new in sorted(zip(target.fields, numbers)):  # the span left to right
        pieces += [text[at:a], new]
        at = b
    return "".join(pieces) + text[at:target.end]


DIALECT_NAMES = ("ur", "krl", "rapid", "fanuc", "inform")  # what dialects() holds (known without loading them)


def dialects() -> dict[str, Dialect]:
    """The vendor languages kincal reads, by name (:data:`DIALECT_NAMES`; the modules load when first asked)."""
    from . import program_fanuc, program_inform, program_krl, program_rapid, program_ur

    return {d.name: d for d in (program_ur.DIALECT, program_krl.DIALECT, program_rapid.DIALECT, program_fanuc.DIALECT,
                                program_inform.DIALECT)}


def _marks(program: Program, marks: dict[int, str]) -> list[tuple[int, int, str]]:
    """Insertions (at the end of each marked target's line, before its line ending) of one comment
    per line with the reasons of every marked target on it."""
    by_end: dict[int, list[str]] = {}
    if not program.comment:  # a language with no comment at the end of a target's line (FANUC /POS, INFORM //POS)
        return []
    for k, why in marks.items():
        t = program.targets[k]
        end = program.text.find("\n", t.end)
        end = len(program.text) if end < 0 else end - (program.text[end - 1:end] == "\r")
        by_end.setdefault(end, []).append(why)
    return [(e, e, f"  {program.comment} kincal: not compensated: {'; '.join(w)}") for e, w in by_end.items()]


def dialect_of(path: str) -> str:
    """The dialect whose suffixes (any case) name the file at ``path``; ValueError naming them all."""
    suffix = os.path.splitext(str(path))[1].lower()
    found = [d.name for d in dialects().values() if suffix in d.suffixes]
    if not found:
        known = ", ".join(f"{s} ({d.name})" for d in dialects().values() for s in d.suffixes)
        raise ValueError(f"{path}: a robot program's suffix says its language; kincal reads {known}")
    return found[0]


@paused_collector
def read_program(path: str, dialect: str = "ur") -> Program:
    """The program at ``path`` in the vendor ``dialect`` (:func:`dialects`: "ur", …), read byte for
    byte: UTF-8 (a byte-order mark kept), else Latin-1; line endings as they are."""
    known = dialects()
    if dialect not in known:
        raise ValueError(f"robot program dialect '{dialect}': kincal reads {', '.join(known)}")
    try:
        raw = open(path, "rb").read()
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the program ({exc.strerror})") from None
    if b"\x00" in raw:
        raise MeasurementError(f"{path}: holds binary data (an encrypted or compiled module?), not a program's text")
    try:
        text, encoding = raw.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        text, encoding = raw.decode("latin-1"), "latin-1"
    found = known[dialect].parse(path, text)
    return dataclasses.replace(found, encoding=encoding, dialect=dialect, comment=known[dialect].comment)


def write_program(path: str, program: Program, texts: dict[int, str], marks: dict[int, str] | None = None) -> None:
    """The program with the given targets replaced and the marked ones commented, in its own encoding
    (atomically)."""
    write_text_atomic(path, program.with_targets(texts, marks), program.encoding)


def line_column(text: str, at: int) -> tuple[int, int]:
    """The line and column (both from 1) of position ``at`` in ``text``."""
    line = text.count("\n", 0, at) + 1
    return line, at - (text.rfind("\n", 0, at) + 1) + 1
