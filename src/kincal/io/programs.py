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
    """One literal target: its span in the text, the line, the move, and its values: a pose
    (x, y, z in m, rotation vector in rad; ``kind`` "pose") or joint values (rad; "joints")."""

    start: int
    end: int
    line: int
    move: str
    kind: str
    values: np.ndarray


@dataclass(frozen=True)
class Program:
    """A program's text, its literal targets in order, and the moves whose targets are not literals
    (line, move, the argument's text)."""

    source: str
    text: str
    targets: tuple[Target, ...]
    not_literal: tuple[tuple[int, str, str], ...] = field(default=())
    encoding: str = "utf-8"

    def with_targets(self, texts: dict[int, str]) -> str:
        """The text with target k's span replaced by ``texts[k]`` (the others as they are)."""
        out, at = [], 0
        for k, t in enumerate(self.targets):
            if k in texts:
                out += [self.text[at:t.start], texts[k]]
                at = t.end
        return "".join(out) + self.text[at:]


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


def write_program(path: str, program: Program, texts: dict[int, str]) -> None:
    """The program with the given targets replaced, in its own encoding (atomically)."""
    write_text_atomic(path, program.with_targets(texts), program.encoding)
