"""Robot programs: the move targets in a program's text, and the text with new targets put back.

One module per vendor language (``program_ur.py`` for Universal Robots' URScript) finds the moves
and their literal targets; everything else — comments, variables, speeds, blends, other commands,
spacing — stays byte for byte, because only the spans of the literal targets are replaced. A move
whose target is not a literal (a variable, an expression) is listed, never touched.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .._atomic import write_text_atomic
from ..errors import MeasurementError


@dataclass(frozen=True)
class Target:
    """One literal target: its span in the text and its line, the move, and its values: a pose (x, y,
    z in m, rotation vector in rad; ``kind`` "pose") or joint values (rad; "joints"); where the move
    is in the text (``at``) and the variable it moves to ('' for a literal in the move; the span and
    line are then those of the variable's literal)."""

    start: int
    end: int
    line: int
    move: str
    kind: str
    values: np.ndarray
    at: int = -1
    variable: str = ""


@dataclass(frozen=True)
class Program:
    """A program's text, its literal targets in the order of the moves, the moves whose targets are
    not literals (line, move, the argument's text), the TCPs it sets (position in the text, the pose
    (6,) or None when not a literal) and its language's comment mark."""

    source: str
    text: str
    targets: tuple[Target, ...]
    not_literal: tuple[tuple[int, str, str], ...] = field(default=())
    encoding: str = "utf-8"
    tcps: tuple = ()
    comment: str = "#"

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


def _marks(program: Program, marks: dict[int, str]) -> list[tuple[int, int, str]]:
    """Insertions (at the end of each marked target's line, before its line ending) of one comment
    per line with the reasons of every marked target on it."""
    by_end: dict[int, list[str]] = {}
    for k, why in marks.items():
        t = program.targets[k]
        end = program.text.find("\n", t.end)
        end = len(program.text) if end < 0 else end - (program.text[end - 1:end] == "\r")
        by_end.setdefault(end, []).append(why)
    return [(e, e, f"  {program.comment} kincal: not compensated: {'; '.join(w)}") for e, w in by_end.items()]


def read_program(path: str, dialect: str = "ur") -> Program:
    """The program at ``path`` in the vendor ``dialect`` ("ur": URScript)."""
    from . import program_ur

    readers = {"ur": program_ur.parse}
    if dialect not in readers:
        raise ValueError(f"robot program dialect '{dialect}': kincal reads {', '.join(readers)}")
    try:
        raw = open(path, "rb").read()
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the program ({exc.strerror})") from None
    try:
        text, encoding = raw.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        text, encoding = raw.decode("latin-1"), "latin-1"
    return dataclasses.replace(readers[dialect](path, text), encoding=encoding)


def write_program(path: str, program: Program, texts: dict[int, str], marks: dict[int, str] | None = None) -> None:
    """The program with the given targets replaced and the marked ones commented, in its own encoding
    (atomically)."""
    write_text_atomic(path, program.with_targets(texts, marks), program.encoding)
