"""URScript (Universal Robots): the literal targets of movej, movel, movep, movec and servoj.

A pose literal is ``p[x, y, z, rx, ry, rz]`` (m; rotation vector in rad, the TCP in the base
frame); a joint literal is ``[q1, …, q6]`` (rad). ``movec`` has two targets (via and to). A move to a
variable assigned once, with a literal (``global home = p[…]``, ``local q0 = […]``, ``x = …``), has
that literal as its target (compensated where it is written); a variable assigned more than once or
from an expression is listed, never touched. ``set_tcp(p[…])`` sets the TCP of the moves after it
in the text. Comments (``#`` to the end of the line) and strings are skipped; anything else is left
as it is.
"""
from __future__ import annotations

import re
from typing import Sequence

import numpy as np

from ..errors import MeasurementError
from .programs import Dialect, Program, Target, old_numbers, write_fields

MOVES = {"movej": 1, "movel": 1, "movep": 1, "movec": 2, "servoj": 1}  # move -> number of target arguments
CALL = re.compile(r"\b(" + "|".join(MOVES) + r")\s*\(")
NUMBER = r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*"
POSE = re.compile(r"^\s*p\s*\[(" + NUMBER + r"(?:," + NUMBER + r"){5})\]\s*$")
JOINTS = re.compile(r"^\s*\[(" + NUMBER + r"(?:," + NUMBER + r")*)\]\s*$")
ASSIGN = re.compile(r"^[ \t]*(?:(?:global|local)[ \t]+)?([A-Za-z_]\w*)[ \t]*=(?!=)[ \t]*([^\n]*)", re.M)
NAME = re.compile(r"^\s*([A-Za-z_]\w*)\s*$")
CHANGED = re.compile(r"^[ \t]*([A-Za-z_]\w*)[ \t]*(?:\[[^\]\n]*\][ \t]*=(?!=)|[-+*/]=)", re.M)  # x[0] = …, x += …
SET_TCP = re.compile(r"\bset_tcp\s*\(")
NOT_ONE_LITERAL = "its target is an expression or a variable not assigned once with a literal: known at run time"
COMMENT_OR_STRING = re.compile(r"#[^\n]*|\"[^\"]*\"?|'[^']*'?")  # a string left open runs to the end
VALUE = re.compile(NUMBER.strip(r"\s*"))  # one number of a literal
RESOLUTION = 1e-10  # m and rad: what a rewritten number carries (0.1 nm, 0.1 nrad)


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
    """The literal targets (in the order the moves come), the non-literal moves and the TCPs set in
    a URScript program."""
    # the text with comments and string literals blanked (same length), so calls are found only in code
    code = COMMENT_OR_STRING.sub(lambda m: " " * len(m.group()), text)
    bound = _bound_literals(code, text)
    targets, not_literal, seen = [], [], set()
    uses: dict[str, list[tuple[int, int]]] = {}  # variable -> (where, line) of each move to it
    for m in CALL.finditer(code):
        move, line = m.group(1), text.count("\n", 0, m.start()) + 1
        for a, b in _arguments(code, m.end() - 1, source, line)[:MOVES[move]]:
            name = NAME.match(text[a:b])
            if name and name.group(1) in bound:
                a0, b0 = bound[name.group(1)]
                lit = _literal(text, a0, b0, text.count("\n", 0, a0) + 1, move, m.start(), name.group(1))
                uses.setdefault(name.group(1), []).append((m.start(), line))
                if lit is not None and name.group(1) not in seen:  # compensated once, where it is written
                    seen.add(name.group(1))
                    targets.append(lit)
                continue
            found = _literal(text, a, b, line, move, m.start())
            if found is None:
                not_literal.append((line, f"{move}({text[a:b].strip()})", NOT_ONE_LITERAL))
            else:
                targets.append(found)
    tcps = _tcps(code, text, source)
    torn = _under_two_tcps(uses, tcps)
    not_literal += [(t.line, t.variable, torn[t.variable]) for t in targets if t.variable in torn]
    return Program(source, text, tuple(t for t in targets if t.variable not in torn),
                   tuple(sorted(not_literal, key=lambda item: item[0])), tcps=tcps)


def _under_two_tcps(uses: dict[str, list[tuple[int, int]]], tcps) -> dict[str, str]:
    """Variables whose moves come under different TCPs (a set_tcp between them): one literal cannot be right for
    both, so each is listed, never compensated for one of them only; name -> why."""
    def tcp_at(at: int):
        before = [pose for where, pose in tcps if where < at]
        return "none" if not before else "variable" if before[-1] is None else tuple(np.round(before[-1], 12))
    out = {}
    for name, found in uses.items():
        if len({tcp_at(at) for at, _ in found}) > 1:
            lines = ", ".join(str(line) for _, line in found)
            out[name] = (f"{name} is moved to under different TCPs (lines {lines}, a set_tcp between them): one "
                         f"literal cannot be right for both; give each TCP's move its own pose")
    return out


def _literal(text: str, a: int, b: int, line: int, move: str, at: int, variable: str = "") -> Target | None:
    """The target written in text[a:b] (its span without the surrounding blanks), or None."""
    arg = text[a:b]
    pose, joints = POSE.match(arg), JOINTS.match(arg)
    found = pose or joints
    if not found:
        return None
    values = np.array([float(x) for x in found.group(1).split(",")])
    lead, tail = len(arg) - len(arg.lstrip()), len(arg) - len(arg.rstrip())
    at0 = a + found.start(1)
    fields = tuple((at0 + m.start(), at0 + m.end()) for m in VALUE.finditer(found.group(1)))
    return Target(a + lead, b - tail, line, move, "pose" if pose else "joints", values, at, variable, fields)


def _bound_literals(code: str, text: str) -> dict[str, tuple[int, int]]:
    """Variables assigned exactly once in the program, with a pose or joint literal: name -> the
    span of that literal (its statement's value up to a comment)."""
    spans: dict[str, list] = {}
    for m in ASSIGN.finditer(code):
        a = m.start(2)
        b = a + len(code[a:m.end(2)].rstrip())  # the comment after it is blank in the code
        spans.setdefault(m.group(1), []).append((a, b) if POSE.match(text[a:b]) or JOINTS.match(text[a:b]) else None)
    for m in CHANGED.finditer(code):  # an element set, or the value changed in place: not one literal
        spans.setdefault(m.group(1), []).append(None)
    return {k: v[0] for k, v in spans.items() if len(v) == 1 and v[0] is not None}


def _tcps(code: str, text: str, source: str) -> tuple[tuple[int, np.ndarray | None], ...]:
    """Each set_tcp in text order: its position and the TCP pose (6,) (None: not a literal)."""
    out = []
    for m in SET_TCP.finditer(code):
        (a, b), *_ = _arguments(code, m.end() - 1, source, text.count("\n", 0, m.start()) + 1)
        pose = POSE.match(text[a:b])
        out.append((m.start(), None if pose is None else np.array([float(x) for x in pose.group(1).split(",")])))
    return tuple(out)


def joints_literal(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.10f}" for v in values) + "]"


def _fields(text: str, targets: Sequence[Target], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The literals' numbers for new SI values (G, F): as they are (m and rad), a number that moved only by
    rounding noise (below half ``RESOLUTION``) the old one."""
    old = old_numbers(text, targets)
    return np.where(np.abs(values - old) <= RESOLUTION / 2, old, values), np.full(values.shape[1], RESOLUTION)


def write(text: str, targets: Sequence[Target], values: Sequence[np.ndarray]) -> list[str]:
    """The literals' numbers for new SI values, each in its old style with the decimals that carry it to
    ``RESOLUTION``; the separators and blanks between them as they are."""
    return write_fields(text, targets, values, _fields)


DIALECT = Dialect("ur", (".script", ".urscript"), "#", parse, write)


def measurement_program(q: np.ndarray, tool: np.ndarray, settle: float, title: str,
                        vias: Sequence[np.ndarray | None] = (), notes: Sequence[str] = ()) -> str:
    """A URScript program that moves through the joint vectors q (N, 6) rad with movej, waits
    ``settle`` s at each for the measurement, and names each pose and its predicted tool position
    (N, 3) m in a comment and a textmsg; ``title`` and ``notes`` (comment lines) head it. ``vias``, per
    move k → k + 1, a joint vector (6,) rad the arm goes through on the way (no wait), or None."""
    lines = ["def kincal_measure():", f"  # {title}", f"  # {len(q)} poses; settle {settle:g} s at each, then measure"]
    lines += [f"  # {note}" for note in notes]
    for k, (qk, tk) in enumerate(zip(q, tool), start=1):
        via = vias[k - 2] if 2 <= k <= len(vias) + 1 else None
        if via is not None:
            lines += [f"  # via on the way from pose {k - 1} to pose {k}: keeps the move inside the cell (no "
                      f"measurement)", f"  movej({joints_literal(via)}, a=0.5, v=0.5)"]
        where = ", ".join(f"{v * 1e3:.3f}" for v in tk)
        lines += [f"  # pose {k}: tool at ({where}) mm in the base frame",
                  f"  movej({joints_literal(qk)}, a=0.5, v=0.5)", f"  sleep({settle:g})",
                  f'  textmsg("kincal pose {k} of {len(q)}")']
    return "\n".join(lines + ["end", "kincal_measure()", ""])
