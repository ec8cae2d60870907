"""ABB RAPID (``.mod``, ``.modx``, ``.sys``, ``.prg``): the literal robtargets and jointtargets of a module.

What is read
    * ``robtarget`` literals ``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, …, eax_f]]``
      (mm; the quaternion q1..q4 = w, x, y, z; the configuration; external axes, ``9E9``/``9E+09`` where
      unused) and ``jointtarget`` literals ``[[rax_1, …, rax_6], [eax_a, …, eax_f]]`` (deg).
    * Declarations ``[LOCAL|TASK] CONST|PERS|VAR robtarget|jointtarget name[{n[,m]}] [:= value];`` at module
      level or inside a PROC/FUNC/TRAP (local there: a routine's names hide the module's), arrays included.
    * The moves MoveJ, MoveL, MoveC (two targets: the circle point and the end point), MoveAbsJ (a
      jointtarget), MoveJDO/MoveLDO/MoveCDO, MoveJSync/…, MoveJAO/…, MoveJGO/…, TriggJ/TriggL/TriggC and
      SearchL/SearchC (their ToPoint; SearchPoint is an output): the target argument(s), the tool argument
      and ``\\WObj:=`` (or ``\\WObj?name``) give a target's ``frames`` (tool, work object) as written ('' for
      a work object not named: wobj0, the controller's default). MoveExtJ moves external axes only: its
      jointtarget is not a robot target.
    * ``tooldata`` and ``wobjdata`` declarations are read and checked (a broken one is an error); their
      frames are NOT targets (compensating a move must not move the tool or the work object) and are not
      put in ``Program.tcps`` (RAPID names the tool in every move, not once before it): they are exposed by
      :func:`declared_frames` (tool frame, user and object frames, in SI), by the names the targets'
      ``frames`` use.

What is a target (``Program.targets``, in text order)
    * every literal in a move's target argument (``variable`` '', ``move`` the instruction as written);
    * every robtarget/jointtarget declared with a literal and never changed in the file (``move``
      "robtarget"/"jointtarget", ``variable`` its name, ``p{2}`` for an array element; ``at`` the first
      move to it, else the declaration; ``frames`` those of the first move to it, directly or as the base
      of ``Offs``/``RelTool``). A declared point is a target even when no move of this file uses it
      (modules keep data apart from motion) or when the moves use it only as the base of
      ``Offs``/``RelTool`` (compensating the base carries the displaced moves along); but not when the module
      uses it otherwise too (a comparison ``IF jt.robax<>pHome.robax``, a field read, an argument of a call,
      another declaration's value, ``MoveExtJ``): a data target is compensated only when every use of it in the
      file is a move's target; else it is listed with its first other use
      (:func:`kincal.io.programs.used_otherwise`, as KRL lists a module's point no move goes to).

What is listed (``Program.not_literal``: line, what, why) and never touched
    * moves to ``Offs()``, ``RelTool()``, ``CRobT()``, ``CJointT()``, ``CalcRobT()``, any other function or
      expression (computed at run time); a move to ``Offs(pA, …)`` or ``RelTool(pA, …)`` of a literal target pA
      goes with pA's compensation at run time, and its reason says so (only the offset is not corrected);
    * moves to a variable assigned at run time (``p := …``, ``p.trans.x := …``, ``p{i} := …``, the
      SearchPoint of a search), to a routine parameter, to data declared without a value or not in this
      file; a declared literal that is assigned at run time (at its declaration);
    * a literal built from names (``[[x0, 0, 0], …]``), a declaration from an expression;
    * a later move to a declared point with another tool or work object than the first (the point is
      compensated for the first);
    * a robtarget-shaped literal (or a jointtarget-shaped one with an unused-axis ``9E9``) anywhere else: an
      assignment, a call of a routine of the program.

Refused (``Program.in_force`` says why): a pose target whose tool or work object the module sets at run time
(``t1.tframe.trans := …``, ``w1 := …``, ``MToolTCPCalib …, t1, …``), at every move to it: its routines run in any
order, main again and again, and a PERS keeps its value; a frame's given value is not the one in force.

Conventions: ``values`` of a pose are x, y, z (m) and the rotation vector (rad) of the unit quaternion
(the written one divided by its norm); ``fields`` are the spans of x, y, z, q1, q2, q3, q4; ``config``
(cf1, cf4, cf6, cfx) as ints. Joints are rax_1..rax_6 in rad (an axis written 9E9, unused, is not one);
external axes are never fields. A quaternion is written back in the hemisphere of the old numbers and
with their norm, so an unchanged target is written byte for byte. Names and keywords are
case-insensitive; comments (``!`` to the end of the line) and strings are skipped. A ``.modx`` is read
as RAPID text (the ones seen are plain modules); an XML file is refused. Broken input raises
:class:`~kincal.errors.MeasurementError` "source: line L, column C: what is wrong".
"""
from __future__ import annotations

import re
from typing import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import MeasurementError
from ..models.transforms import quaternion_rotvec, rotvec_matrix, rotvec_quaternion
from .jump_flow import Write, unknown_frames
from .programs import Dialect, Program, Target, old_numbers, used_otherwise, write_fields
from .rapid_scan import (Decl, FORMS, FrameData, Node, SHAPES, UNUSED, Use, _Scan, _aggregate, _closing, _literal,
                         _number, _pieces, _shaped)

ASSIGN = re.compile(r"(?<![\w.\\])([A-Za-z]\w*)\s*(?:\{[^}]*\})?\s*(?:\.\s*\w+\s*)*:=")
NAME = re.compile(r"([A-Za-z]\w*)\s*(?:\{([^}]*)\})?")
CALL = re.compile(r"([A-Za-z]\w*)\s*\(")
# instruction -> (its target arguments, its tool argument), as positions among its positional arguments
MOVES = {**{m: ((0,), 3) for m in ("movej", "movel", "moveabsj", "movejdo", "moveldo", "movejsync", "movelsync",
                                   "movejao", "movelao", "movejgo", "movelgo")},
         **{m: ((0, 1), 4) for m in ("movec", "movecdo", "movecsync", "movecao", "movecgo")},
         "triggj": ((0,), 4), "triggl": ((0,), 4), "triggc": ((0, 1), 5), "searchl": ((2,), 4),
         "searchc": ((2, 3), 5)}
SEARCH_POINT = {"searchl": 1, "searchc": 1}  # the output argument of a search: changed at run time
MOVE = re.compile(r"(?<![\w.\\%])(" + "|".join(MOVES) + r")\b", re.I)
RUNTIME = {"offs": "Offs() displaces {base} at run time", "reltool": "RelTool() displaces {base} at run time",
           "crobt": "CRobT() reads the robot's position at run time",
           "cjointt": "CJointT() reads the robot's joints at run time",
           "calcrobt": "CalcRobT() computes it at run time", "calcjointt": "CalcJointT() computes it at run time"}
CALIBRATES = re.compile(r"(?<![\w.])(MToolTCPCalib|MToolRotCalib|SToolTCPCalib|SToolRotCalib)\b", re.I)  # write a tool
LENGTH_RES, ANGLE_RES, QUATERNION_RES = 1e-7, 1e-8, 1e-10  # mm, deg, quaternion component


@dataclass
class _Move:
    """One move: its instruction as written, where it is, its target arguments' spans, its frames."""

    name: str
    at: int
    targets: list[tuple[int, int]]
    frames: tuple[str, str]


def _moves(s: _Scan) -> list[_Move]:
    """Every move of the table :data:`MOVES`, with its target arguments and frames."""
    found = list(MOVE.finditer(s.code))
    out = []
    for k, m in enumerate(found):
        end = s.end_of_statement(m.end(), m.group(1))
        if k + 1 < len(found) and found[k + 1].start() < end:
            raise s.fail(m.start(), f"{m.group(1)} without its closing ';' before the {found[k + 1].group(1)} "
                                    f"of line {s.line(found[k + 1].start())}")
        pieces = _pieces(s.code, m.end(), end)
        empty = next((h for h, opts in pieces if h[0] == h[1] and not opts), None)
        if empty is not None and s.code[m.end():end].strip():
            raise s.fail(empty[0], f"an empty argument of {m.group(1)}")
        heads = [h for h, _ in pieces if h[0] < h[1]]
        targets, tool_at = MOVES[m.group(1).lower()]
        if len(heads) <= max(targets):
            raise s.fail(m.start(), f"{m.group(1)} without its target argument")
        wobj = next((v for _, opts in pieces for n, v in opts if n == "wobj"), "")
        tool = s.words(*heads[tool_at]) if len(heads) > tool_at else ""
        out.append(_Move(m.group(1), m.start(), [heads[t] for t in targets], (tool, wobj)))
        search = SEARCH_POINT.get(m.group(1).lower())
        if search is not None and len(heads) > search:
            _changed_by(s, heads[search][0], s.code[heads[search][0]:heads[search][1]], m.start())
    return out


def _changed_by(s: _Scan, at: int, written: str, where: int) -> None:
    """Mark the variable written at ``at`` (``p``, ``p{i}``, ``p.trans``) as set at run time."""
    name = NAME.match(written)
    found = s.resolve(at, name.group(1)) if name else None
    if isinstance(found, Decl) and not found.changed:
        found.changed = s.line(where)


def _assignments(s: _Scan) -> None:
    """Mark every declared variable that a statement assigns (``p := …``, ``p.trans.x := …``)."""
    names = {d.name_at for d in s.decls}
    for m in ASSIGN.finditer(s.code):
        if m.start(1) not in names:
            _changed_by(s, m.start(1), m.group(1), m.start())


def _elements(s: _Scan, d: Decl) -> list[tuple[str, tuple[int, ...], Node]] | str:
    """A declared value's literal aggregates: (name, index, node) per element, or why it is not one."""
    assert d.value is not None
    a, b = d.value
    if s.code[a] != "[" or _closing(s.code, a) + 1 != b:
        return f"declared from an expression ({s.words(a, b)}), not a literal"
    nodes: list[tuple[tuple[int, ...], Node]] = [((), _aggregate(s, a))]
    for size in d.dims:
        nested: list[tuple[tuple[int, ...], Node]] = []
        for index, node in nodes:
            if node.items is None or len(node.items) != size:
                n = "an expression" if node.items is None else len(node.items)
                raise s.fail(node.start, f"{d.name} is declared with {size} elements here; the value has {n}")
            nested += [(index + (k + 1,), item) for k, item in enumerate(node.items)]
        nodes = nested
    return [(d.name + ("{" + ",".join(map(str, i)) + "}" if i else ""), i, n) for i, n in nodes]


def _index(s: _Scan, text: str | None) -> tuple[int, ...] | None:
    """The literal index of ``p{1}``/``p{2,3}`` (() for none), or None for a computed one."""
    if text is None:
        return ()
    parts = [x.strip() for x in text.split(",")]
    return tuple(int(x) for x in parts) if all(x.isdigit() for x in parts) else None


def _use(uses: dict, key: tuple[int, tuple[int, ...] | None], move: _Move, direct: bool) -> None:
    """Record a move to a declared point (``key``: the declaration and its index; None: any element)."""
    first = uses.get(key)
    if first is None or (direct and not first.direct):
        uses[key] = Use(move.at, move.frames, direct, first.later if first else [])
    elif direct:
        first.later.append((move.at, move.name, move.frames))


def _argument(s: _Scan, move: _Move, a: int, b: int, uses: dict, out: list, listed: list,
              otherwise: dict[int, int]) -> None:
    """One target argument of a move: a literal (a target), a declared point (a use) or listed (``otherwise``: the
    declarations used otherwise than as a move's target, :func:`_otherwise`, which are no targets)."""
    word = s.words(a, b)
    kind = "jointtarget" if move.name.lower() == "moveabsj" else "robtarget"
    what, line = f"{move.name} {word}", s.line(move.at)
    name, call = NAME.fullmatch(s.code[a:b].strip()), CALL.match(s.code[a:b])
    if s.code[a] == "[" and _closing(s.code, a) + 1 == b:
        found = _literal(s, _aggregate(s, a), kind, move.name, move.at, "", move.frames)
        out.append(found) if isinstance(found, Target) else listed.append((line, what, found))
    elif name:
        listed += _named(s, move, name, uses, what)
    elif call:
        listed.append((line, what, _call_reason(s, move, call, a, uses, otherwise)))
    else:
        listed.append((line, what, "an expression computed at run time"))


def _named(s: _Scan, move: _Move, name: re.Match, uses: dict, what: str) -> list[tuple[int, str, str]]:
    found, line = s.resolve(move.at, name.group(1)), s.line(move.at)
    if found == "param":
        return [(line, what, f"{name.group(1)} is a parameter of the routine: its value comes from the caller")]
    if found is None:
        return [(line, what, f"{name.group(1)} is not declared in this file (data of another module?): it is a "
                             "target of the file that declares it")]
    assert isinstance(found, Decl)
    if found.changed:
        return [(line, what, f"{found.name} is assigned at run time (line {found.changed})")]
    if found.value is None:
        return [(line, what, f"{found.name} is declared without a value (line {found.line})")]
    _use(uses, (id(found), _index(s, name.group(2))), move, True)
    return []


def _call_reason(s: _Scan, move: _Move, call: re.Match, a: int, uses: dict, otherwise: dict[int, int]) -> str:
    """Why a move to a function's result is listed (and the base of Offs/RelTool recorded as a use): a base that is
    a literal target of its own (declared with a literal, never changed nor used otherwise) is compensated, and the
    move goes with it at run time; only the offset is not corrected."""
    low = call.group(1).lower()
    if low not in RUNTIME:
        return f"{call.group(1)}() computes it at run time"
    base = ""
    if low in ("offs", "reltool"):
        open_at = a + call.end() - 1
        first = _pieces(s.code, open_at + 1, _closing(s.code, open_at))[0][0]
        base = s.words(*first)
        name = NAME.fullmatch(base)
        found = s.resolve(a, name.group(1)) if name else None
        if name and isinstance(found, Decl) and found.value is not None and not found.changed:
            _use(uses, (id(found), _index(s, name.group(2))), move, False)
            if id(found) not in otherwise:
                shift = "offset" if low == "offs" else "displacement"
                return (RUNTIME[low].format(base=base) + f": the move goes with {base}'s compensation (a literal "
                        f"target of its own, line {found.line}); the {shift} itself is not corrected")
    return RUNTIME[low].format(base=base or "its base") + "; only literal targets are compensated"


def _moved_at(s: _Scan, a: int, b: int) -> int | None:
    """Where the name a move's target argument (span a, b) goes to starts: the argument itself (``p``, ``p{2}``) or
    the base of its ``Offs``/``RelTool``; None for any other argument."""
    head = a + len(s.code[a:b]) - len(s.code[a:b].lstrip())
    if NAME.fullmatch(s.code[a:b].strip()):
        return head
    call = CALL.match(s.code, head, b)
    if not call or call.group(1).lower() not in ("offs", "reltool"):
        return None
    open_at = call.end() - 1
    (x, y), _ = _pieces(s.code, open_at + 1, _closing(s.code, open_at))[0]
    return x + len(s.code[x:y]) - len(s.code[x:y].lstrip()) if NAME.fullmatch(s.code[x:y].strip()) else None


def _otherwise(s: _Scan, moves: list[_Move]) -> dict[int, int]:
    """For each declared robtarget and jointtarget (by id) that the module uses otherwise than as a move's target
    (:func:`_moved_at`; a comparison, a field read, an argument of a call, a value of other data, MoveExtJ), where
    the first such use is."""
    moved = {_moved_at(s, a, b) for m in moves for a, b in m.targets}
    out: dict[int, int] = {}
    for m in re.finditer(r"(?<![\w.\\%])[A-Za-z]\w*", s.code):
        d = s.resolve(m.start(), m.group()) if m.start() not in moved else None
        if isinstance(d, Decl) and d.kind in SHAPES and m.start() != d.name_at:
            out.setdefault(id(d), m.start())
    return out


def _declared(s: _Scan, uses: dict, out: list, listed: list, otherwise: dict[int, int]) -> list[tuple[int, int]]:
    """The targets declared with literals (and the listed declarations: assigned at run time, or used otherwise
    than as a move's target, ``otherwise`` of :func:`_otherwise`); the spans of the values read."""
    spans = []
    for d in s.decls:
        if d.kind not in SHAPES or d.value is None:
            continue
        spans.append(d.value)
        what = f"{d.kind} {d.name}"
        if d.changed:
            listed.append((d.line, what, f"declared with a literal but assigned at run time (line {d.changed}): "
                                         "the moves use the value set then"))
            continue
        if id(d) in otherwise:
            at = otherwise[id(d)]
            start = max(s.code.rfind(c, 0, at) for c in ";\n") + 1
            end = min(p for p in (*(s.code.find(c, at) for c in ";\n"), len(s.code)) if p >= 0)
            listed.append((d.line, what, used_otherwise(f"line {s.line(at)} uses {d.name} otherwise than as a move's "
                                                        f"target ({s.words(start, end)})")))
            continue
        elements = _elements(s, d)
        if isinstance(elements, str):
            listed.append((d.line, what, elements))
            continue
        for name, index, node in elements:
            use = uses.get((id(d), index)) or uses.get((id(d), None))
            at, frames = (use.at, use.frames) if use else (d.start, ("", ""))
            found = _literal(s, node, d.kind, d.kind, at, name, frames)
            out.append(found) if isinstance(found, Target) else listed.append((s.line(node.start), what, found))
            for later_at, move, other in (use.later if use else []):
                if other != frames:
                    listed.append((s.line(later_at), f"{move} {name}",
                                   f"with tool {other[0] or '(none)'} and work object {other[1] or 'wobj0'}, but "
                                   f"{name} is compensated for {frames[0] or '(none)'} and {frames[1] or 'wobj0'} "
                                   f"(line {s.line(at)})"))
    return spans


def _strays(s: _Scan, claimed: list[tuple[int, int]]) -> list[tuple[int, str, str]]:
    """Target-shaped literals outside the moves and declarations read: an assignment, a routine call."""
    out, after = [], -1
    for m in re.finditer(r"\[\s*\[", s.code):
        if m.start() < after or any(a <= m.start() < b for a, b in claimed):
            continue
        node = _aggregate(s, m.start())
        after = node.end
        for kind, sizes in SHAPES.items():
            parts = node.items or []
            if len(parts) != len(sizes) or any(p.items is None or len(p.items) != n for p, n in zip(parts, sizes)):
                continue
            values = [_number(s, x) if x.items is None else None for p in parts for x in p.items or []]
            if kind == "jointtarget" and not any(v is not None and abs(v) >= UNUSED for v in values[6:]):
                continue
            out.append((s.line(m.start()), f"{kind} literal {s.words(node.start, node.end)}",
                        "outside a move or a robtarget/jointtarget declaration (an assignment or a call of a "
                        "routine of the program): not compensated"))
    return out


def parse(source: str, text: str) -> Program:
    """The literal targets (text order) and the listed moves and declarations of a RAPID module."""
    s = _Scan(source, text)
    _frames(s)  # tooldata and wobjdata are checked (and exposed by declared_frames)
    moves = _moves(s)
    _assignments(s)
    targets: list[Target] = []
    listed: list[tuple[int, str, str]] = []
    uses: dict = {}
    otherwise = _otherwise(s, moves)
    for move in moves:
        for a, b in move.targets:
            _argument(s, move, a, b, uses, targets, listed, otherwise)
    claimed = _declared(s, uses, targets, listed, otherwise)
    claimed += [(m.at, s.end_of_statement(m.at, m.name)) for m in moves]
    claimed += [d.value for d in s.decls if d.value is not None]
    listed += _strays(s, claimed)
    targets.sort(key=lambda t: t.start)
    whys = unknown_frames(_frames_written(s), [(0, "open", None), (len(text), "close", None)],
                          [(t.frames if t.kind == "pose" else (), (t.at,))
                           for t in targets])
    return Program(source, text, tuple(targets), tuple(sorted(listed, key=lambda x: x[0])), comment="!",
                   dialect="rapid", in_force=tuple((t.start, why) for t, why in zip(targets, whys) if why))


def _statement_end(s: _Scan, at: int) -> int:
    """Where the statement at ``at`` ends: its ';' (the end of the text without one)."""
    end = s.code.find(";", at)
    return len(s.code) if end < 0 else end


def _frames_written(s: _Scan) -> list[Write]:
    """The tools and work objects (any variable, by name) the module sets at run time: assigned
    (``tool1.tframe.trans := …``, ``wobj1 := …``) or calibrated (``MToolTCPCalib``, …: a name among the arguments).
    Its routines run in an order its text does not give, so each may be in force at every move
    (:func:`kincal.io.jump_flow.unknown_frames`, the whole module one loop)."""
    names = {d.name_at for d in s.decls}
    out = []
    for m in ASSIGN.finditer(s.code):
        if m.start(1) not in names:
            end = _statement_end(s, m.start())
            out.append(Write(m.start(), s.line(m.start()), m.group(1), " ".join(s.text[m.start():end].split())))
    for m in CALIBRATES.finditer(s.code):
        end = _statement_end(s, m.end())
        out += [Write(m.start(), s.line(m.start()), n, " ".join(s.text[m.start():end].split()))
                for n in re.findall(r"(?<![\w.\\])[A-Za-z]\w*", s.code[m.end():end])]
    return out


def _frames(s: _Scan) -> list[FrameData]:
    """The tooldata and wobjdata declarations, read (a broken literal is an error)."""
    out = []
    for d in s.decls:
        if d.kind in SHAPES:
            continue
        robhold, frame, oframe = None, None, None
        if d.value is not None and not d.dims and s.code[d.value[0]] == "[":
            node = _aggregate(s, d.value[0])
            sizes = (3, 5)[d.kind == "wobjdata"]
            if node.items is None or len(node.items) != sizes:
                raise s.fail(node.start, f"a {d.kind} is {FORMS[d.kind]}: this one has {len(node.items or [])} parts")
            word = s.code[node.items[0].start:node.items[0].end].strip().upper()
            robhold = {"TRUE": True, "FALSE": False}.get(word)
            poses = node.items[1:2] if d.kind == "tooldata" else node.items[3:5]
            found = [_pose(s, p, d.kind) for p in poses]
            frame, oframe = found[0], (found[1] if d.kind == "wobjdata" else None)
        out.append(FrameData(d.name, d.kind, d.line, robhold, frame, oframe, d.changed))
    return out


def _pose(s: _Scan, node: Node, kind: str) -> np.ndarray | None:
    """A pose [[x,y,z],[q1..q4]] as x, y, z (m) and a rotation vector (rad); None if not literal."""
    parts = node.items or []
    if len(parts) != 2 or [len(p.items or []) for p in parts] != [3, 4]:
        raise s.fail(node.start, f"a {kind} is {FORMS[kind]}: this frame is not [[x,y,z],[q1,q2,q3,q4]]")
    values = [_number(s, x) for p in parts for x in p.items or []]
    if any(v is None for v in values):
        return None
    v = np.array(values, dtype=float)
    if not np.linalg.norm(v[3:]) > 0:
        raise s.fail(parts[1].start, "a quaternion of norm 0 is no orientation")
    return np.concatenate([v[:3] * 1e-3, quaternion_rotvec(v[3:])])


def declared_frames(program: Program) -> dict[str, FrameData]:
    """The tooldata and wobjdata declared in a RAPID program, by name in lower case (the names its
    targets' ``frames`` use; RAPID names are case-insensitive). The built-in tool0 and wobj0 (the
    flange, the world frame) are not declared in a module and not here."""
    s = _Scan(program.source, program.text)
    _moves(s)
    _assignments(s)
    out: dict[str, FrameData] = {}
    for f in _frames(s):
        out.setdefault(f.name.lower(), f)
    return out


def _fields(text: str, targets: Sequence[Target], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fields of targets of one kind for new SI values (G, V): rax (deg) or x, y, z (mm) and the quaternion
    (in the old numbers' hemisphere and with their norm); a zero keeps its written sign."""
    old = old_numbers(text, targets)
    if targets[0].kind == "joints":
        if values.shape[1] != old.shape[1]:
            raise ValueError(f"a jointtarget of {old.shape[1]} axes cannot take {values.shape[1]} values")
        numbers, resolution = np.degrees(values), np.full(values.shape[1], ANGLE_RES)
    else:
        if values.shape[1] != 6:
            raise ValueError(f"a robtarget takes 6 values (x, y, z, rotation vector), not {values.shape[1]}")
        q = rotvec_quaternion(values[:, 3:])
        q *= np.where(np.einsum("ni,ni->n", q, old[:, 3:]) < 0, -1.0, 1.0)[:, None]
        numbers = np.concatenate([values[:, :3] * 1e3, q * np.linalg.norm(old[:, 3:], axis=1)[:, None]], axis=1)
        resolution = np.array([LENGTH_RES] * 3 + [QUATERNION_RES] * 4)
    return np.where(numbers == 0, np.copysign(0.0, old), numbers), resolution


def write(text: str, targets: Sequence[Target], values: Sequence[np.ndarray]) -> list[str]:
    """The targets' spans for new SI values (:func:`_fields`), each number in its old style; every other byte
    of the span as it was."""
    return write_fields(text, targets, values, _fields)


def frame_poses(program: Program) -> dict[str, np.ndarray]:
    """The tools (their tool frame) and work objects (user frame · object frame) the module declares with
    literal values and never changes at run time, as 4x4 poses (m) by lower-case name; a stationary tool or a
    work object moved by the robot (robhold, not the usual way round) is left out: its targets are refused."""
    out = {}
    for name, f in declared_frames(program).items():
        if f.frame is None or f.changed or (f.oframe is None) != (f.kind == "tooldata") \
                or f.robhold is None or f.robhold != (f.kind == "tooldata"):
            continue
        parts = [f.frame] if f.oframe is None else [f.frame, f.oframe]
        T = np.eye(4)
        for x in parts:
            step = np.eye(4)
            step[:3, :3], step[:3, 3] = rotvec_matrix(x[3:6]), x[:3]
            T = T @ step
        out[name] = T
    return out


DIALECT = Dialect("rapid", (".mod", ".modx", ".prg", ".sys"), "!", parse, write, frame_poses)
