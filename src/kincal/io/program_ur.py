"""URScript (Universal Robots): the literal targets of movej, movel, movep, movec and servoj.

A pose literal is ``p[x, y, z, rx, ry, rz]`` (m; rotation vector in rad, the TCP in the base
frame); a joint literal is ``[q1, …, q6]`` (rad). ``movec`` has two targets (via and to). Comments
(``#`` to the end of the line) and strings are skipped; anything else is left as it is.
"""
from __future__ import annotations

import re

import numpy as np

from ..errors import MeasurementError
from .programs import Program, Target

MOVES = {"movej": 1, "movel": 1, "movep": 1, "movec": 2, "servoj": 1}  # move -> number of target arguments
CALL = re.compile(r"\b(" + "|".join(MOVES) + r")\s*\(")
NUMBER = r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*"
POSE = re.compile(r"^\s*p\s*\[(" + NUMBER + r"(?:," + NUMBER + r"){5})\]\s*$")
JOINTS = re.compile(r"^\s*\[(" + NUMBER + r"(?:," + NUMBER + r")*)\]\s*$")


def _masked(text: str) -> str:
    """The text with comments and string literals blanked (same length), so calls are found only in code."""
    out = list(text)
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == "#":
            j = text.find("\n", i)
            j = n if j < 0 else j
            out[i:j] = " " * (j - i)
            i = j
        elif c in "\"'":
            j = text.find(c, i + 1)
            j = n - 1 if j < 0 else j
            out[i:j + 1] = " " * (j + 1 - i)
            i = j + 1
        else:
            i += 1
    return "".join(out)


def _arguments(code: str, open_at: int, source: str, line: int) -> list[tuple[int, int]]:
    """Spans of the top-level arguments of the call whose '(' is at ``open_at``."""
    depth, start, spans = 0, open_at + 1, []
    for i in range(open_at + 1, len(code)):
        c = code[i]
        if c in "([":
            depth += 1
        elif c in ")]":
            if depth == 0:
                spans.append((start, i))
                return spans
            depth -= 1
        elif c == "," and depth == 0:
            spans.append((start, i))
            start = i + 1
    raise MeasurementError(f"{source}: line {line}: a move call without its closing ')'")


def parse(source: str, text: str) -> Program:
    """The literal targets and the non-literal moves of a URScript program."""
    code = _masked(text)
    targets, not_literal = [], []
    for m in CALL.finditer(code):
        move, line = m.group(1), text.count("\n", 0, m.start()) + 1
        for a, b in _arguments(code, m.end() - 1, source, line)[:MOVES[move]]:
            arg = text[a:b]
            pose, joints = POSE.match(arg), JOINTS.match(arg)
            found = pose or joints
            if found:
                values = np.array([float(x) for x in found.group(1).split(",")])
                lead = len(arg) - len(arg.lstrip())
                tail = len(arg) - len(arg.rstrip())
                targets.append(Target(a + lead, b - tail, line, move, "pose" if pose else "joints", values))
            else:
                not_literal.append((line, move, arg.strip()))
    return Program(source, text, tuple(targets), tuple(not_literal))


def pose_literal(values: np.ndarray) -> str:
    """p[x, y, z, rx, ry, rz] with 10 decimals (0.1 nm, 0.1 nrad)."""
    return "p[" + ", ".join(f"{v:.10f}" for v in values) + "]"


def joints_literal(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.10f}" for v in values) + "]"
