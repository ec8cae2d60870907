"""URScript (Universal Robots): the literal targets of movej, movel, movep, movec and servoj.

A pose literal is ``p[x, y, z, rx, ry, rz]`` (m; rotation vector in rad, the TCP in the base
frame); a joint literal is ``[q1, …, q6]`` (rad). ``movec`` has two targets (via and to). A move to a
variable assigned once, with a literal (``global home = p[…]``, ``local q0 = […]``, ``x = …``), has
that literal as its target (compensated where it is written); a variable assigned more than once or
from an expression is listed, never touched. ``set_tcp(p[…])`` sets the TCP of the moves the
program runs after it, by its structure (:mod:`kincal.io.flow`): a ``set_tcp`` in a ``def`` reaches the moves
after it in that def and after each call of it; one in an ``if``/``elif``/``else`` or ``while`` block reaches
the moves after the block only as one possibility; a move where the program's paths leave different TCPs is not
compensated (its TCP says why). Comments (``#`` to the end of the line) and strings are skipped; anything else is
left as it is.
"""
from __future__ import annotations

import bisect
import re
from typing import Sequence

import numpy as np

from ..errors import MeasurementError
from . import flow
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
KEYWORD = re.compile(r"\b(def|thread|if|elif|else|while|end|return|break|continue|halt)\b")  # URScript's blocks
USE = re.compile(r"\b(run[ \t]+)?([A-Za-z_]\w*)\s*\(")  # a call (or a thread started) by name
NAMED = re.compile(r"(def|thread)\s+([A-Za-z_]\w*)")
NO_SET_TCP = flow.Setting(flow.START, "start", ())  # the TCP before any set_tcp: the controller's (or --tcp)


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
    reached = _reached(code, text, tcps, [m.start() for m in CALL.finditer(code)]) if tcps else None
    torn = _under_two_tcps(uses, reached)
    not_literal += [(t.line, t.variable, torn[t.variable]) for t in targets if t.variable in torn]
    kept = tuple(t for t in targets if t.variable not in torn)
    return Program(source, text, kept, tuple(sorted(not_literal, key=lambda item: item[0])), tcps=tcps,
                   in_force=() if reached is None else tuple(
                       (t.start, _in_force(reached, [at for at, _ in uses[t.variable]] if t.variable else [t.at]))
                       for t in kept))


def _under_two_tcps(uses: dict[str, list[tuple[int, int]]], reached) -> dict[str, str]:
    """Variables moved to under different TCPs (each move's known, a set_tcp between them): one literal cannot be
    right for both, so each is listed, never compensated for one of them only; name -> why."""
    if reached is None or isinstance(reached, str):
        return {}
    out = {}
    for name, found in uses.items():
        each = [flow.in_force(reached.get(at, (frozenset(),))[0]) for at, _ in found]
        if all(each) and len({s.key for s in each if s is not None}) > 1:
            lines = ", ".join(str(line) for _, line in found)
            out[name] = (f"{name} is moved to under different TCPs (lines {lines}, a set_tcp between them): one "
                         f"literal cannot be right for both; give each TCP's move its own pose")
    return out


def _in_force(reached, moves: list[int]):
    """The TCP of a target whose moves are at ``moves``: the pose (6,) in force at all of them, None for a set_tcp
    of a non-literal, () for none set; or why it is not known (a str: the set_tcp lines that make it ambiguous)."""
    if isinstance(reached, str):
        return reached
    possible = frozenset().union(*(reached.get(at, (frozenset(),))[0] for at in moves))
    one = flow.in_force(possible)
    if one is not None:
        return one.value
    if not possible:
        return ("no path of the program reaches this move (it comes after a return, halt or break), so no TCP is "
                "known for it")
    lines = sorted(s.line for s in possible if s.line != flow.START)
    named = ", ".join(str(line) for line in lines)
    return (f"its TCP is not known from the program's structure: the set_tcp on line{'s' * (len(lines) > 1)} {named}"
            + (" or the TCP before any set_tcp" if any(s.line == flow.START for s in possible) else "")
            + " may be in force here, as a branch, loop or call decides at run time; give it one TCP: a set_tcp of "
              "a literal that every path runs before this move")


def _reached(code: str, text: str, tcps, moves: list[int]):
    """What may be in force at each move (:func:`kincal.io.flow.reach`, by the move's position), or why the
    program's structure cannot be read (a str naming the line)."""
    try:
        tree = _Tree(code, text, tcps, moves).read()
    except _Broken as exc:
        line = text.count("\n", 0, exc.args[0]) + 1
        return (f"the TCP in force cannot be read from the program's structure: line {line}: {exc.args[1]} (its "
                f"blocks do not balance); correct the program")
    return flow.reach(tree, [NO_SET_TCP])


class _Broken(Exception):
    """The blocks do not balance: (position, what)."""


class _Tree:
    """A URScript program's structure as :mod:`kincal.io.flow` nodes: blocks by their keywords (``def``,
    ``thread``, ``if``/``elif``/``else``, ``while``, each closed by ``end``), set_tcp, moves, calls of its own
    defs (``run``: a thread started) and jumps."""

    def __init__(self, code: str, text: str, tcps, moves: list[int]) -> None:
        self.code = code
        named = {m.start(2): m.group(2) for m in NAMED.finditer(code)}
        events: list[tuple[int, object]] = [(m.start(), m.group(1)) for m in KEYWORD.finditer(code)]
        events += [(at, flow.Move(at)) for at in moves]
        breaks = [m.start() for m in re.finditer("\n", text)]
        events += [(at, flow.Set(flow.Setting(bisect.bisect_left(breaks, at) + 1, _key(at, pose), pose)))
                   for at, pose in tcps]
        events += [(m.start(), flow.Start(m.group(2)) if m.group(1) else flow.Call(m.group(2)))
                   for m in USE.finditer(code) if m.group(2) in named.values() and m.start(2) not in named]
        self.events, self.i = sorted(events, key=lambda e: e[0]), 0

    def read(self) -> list:
        return self.block(())[0]

    def block(self, stops: tuple[str, ...], opened: tuple[int, str] = (0, "")) -> tuple[list, str, int]:
        """The nodes up to one of the keywords ``stops`` (which, and where) of the block ``opened`` (where, by which
        keyword); () for the whole program."""
        nodes: list = []
        while self.i < len(self.events):
            at, event = self.events[self.i]
            self.i += 1
            if not isinstance(event, str):
                nodes.append(event)
            elif event in stops:
                return nodes, event, at
            elif event in ("if", "while", "def", "thread"):
                nodes += self.opened(event, at)
            elif event in ("return", "break", "continue", "halt"):
                nodes.append(flow.Jump(event))
            elif stops:
                raise _Broken(opened[0], f"this '{opened[1]}' block is not closed with '{stops[-1]}' before the "
                                         f"'{event}' of line {self.code.count(chr(10), 0, at) + 1}")
            else:
                raise _Broken(at, f"'{event}' with no block open before it")
        if stops:
            raise _Broken(opened[0], f"this '{opened[1]}' block is never closed with 'end'")
        return nodes, "", len(self.code)

    def opened(self, word: str, at: int) -> list:
        """The nodes of the block opened by ``word`` at ``at``, through its 'end'."""
        head = self.header(at)
        if word in ("def", "thread"):
            name = NAMED.match(self.code, at)
            if name is None:
                raise _Broken(at, f"a '{word}' with no name")
            return [flow.Define(name.group(2), tuple(self.block(("end",), (at, word))[0]))]
        if word == "while":
            return [flow.Loop(tuple(head), tuple(self.block(("end",), (at, word))[0]))]
        bodies: list[tuple] = []
        tested: list = []
        stop = "elif"  # the calls in an elif's condition run on the paths that reach it
        while stop == "elif":
            body, stop, where = self.block(("elif", "else", "end"), (at, word))
            bodies.append(tuple(tested + body))
            tested = tested + self.header(where) if stop == "elif" else tested
        if stop == "else":
            self.header(where)
            bodies.append(tuple(tested + self.block(("end",), (at, word))[0]))
        elif tested:  # no else: the path through every condition, none true
            bodies.append(tuple(tested))
        return head + [flow.Branch(tuple(bodies), complete=stop == "else" or bool(tested))]

    def header(self, at: int) -> list:
        """The nodes of the header of the block keyword at ``at`` (calls in its condition), through its ':'."""
        depth, i = 0, at
        while i < len(self.code) and not (self.code[i] == ":" and depth == 0):
            depth += (self.code[i] in "([") - (self.code[i] in ")]")
            i += 1
        if i == len(self.code):
            raise _Broken(at, "a block's first line with no ':'")
        nodes = []
        while self.i < len(self.events) and self.events[self.i][0] < i:
            if isinstance(self.events[self.i][1], str):
                raise _Broken(self.events[self.i][0], f"'{self.events[self.i][1]}' before the ':' of a block")
            nodes.append(self.events[self.i][1])
            self.i += 1
        return nodes


def _key(at: int, pose: np.ndarray | None):
    """What identifies a set_tcp's TCP: its pose (to 1e-12), or its place (a non-literal's)."""
    return ("place", at) if pose is None else tuple(np.round(pose, 12).tolist())


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
