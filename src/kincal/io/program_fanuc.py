"""FANUC TP programs in their ASCII form (``.ls``): the taught positions of ``/POS`` and the moves of ``/MN``.

What is read. A ``.ls`` file has the sections ``/PROG``, ``/ATTR`` (and ``/APPL``), ``/MN`` (the
instructions, numbered ``  1:J P[1] 100% FINE    ;`` or not, ``  : L P[2] …``) and ``/POS`` (the
positions), closed by ``/END``. Only ``/MN`` and ``/POS`` are read; every other byte (``/ATTR``
with its ``LINE_COUNT``, ``PROG_SIZE``; the instructions; spacing, tabs, line endings) stays as it is,
because only the numbers of the robot group are written again, each in its own style.

A ``/POS`` entry is ``P[n]{ GP1: UF : u, UT : t, CONFIG : 'N U T, 0, 0, 0', X = 1.0 mm, Y = … mm,
Z = … mm, W = … deg, P = … deg, R = … deg };`` (Cartesian) or ``P[n]{ GP1: UF : u, UT : t, J1 = … deg,
…, J6 = … deg };`` (joints, no CONFIG); ``P[n:"comment"]`` names it. Only group 1 (``GP1``) is the
robot: ``GP2``… (positioners, rails) and the extended axes ``E1``… of ``GP1`` are kept byte for byte
and are not fields.

What is a target. Every ``/POS`` entry with a taught ``GP1`` is one literal target, in the order of
``/POS``: its span is its ``{``…``}``, its line the line of ``P[n]``, ``variable`` "P[n]", ``move`` the
motion letter (J, L, C, A) and ``at`` the offset of the first plain move that uses it; an entry no move
uses is a target too (move "P[n]", ``at`` its own offset: a point taught for later use). ``kind``
"pose": x, y, z (m) and the rotation vector (rad) of the TCP in user frame ``UF`` with tool ``UT``
(``frames`` = ("UT t", "UF u")), from X, Y, Z (mm) and W, P, R (deg) with R = Rz(R)·Ry(P)·Rx(W) (fixed
axes X, Y, Z); ``config`` = ('N U T', turn1, turn2, turn3) as written. ``kind`` "joints": J1…Jn in rad
(an axis written in mm: m). ``fields`` are the spans of X, Y, Z, W, P, R or J1…Jn.

What is listed (``not_literal``: line, the move and its position, why), never touched: a move to a
position register ``PR[i]`` (its value lives in the controller), to ``P[R[i]]`` (chosen at run time),
to a ``P[n]`` with no ``/POS`` entry, not taught (``********``) or without ``GP1``; a move with
``INC`` (an increment, not a place), ``Offset`` / ``Offset,PR[i]``, ``Tool_Offset`` /
``Tool_Offset,PR[i]`` or ``VOFFSET`` (the controller adds an offset at run time). A ``P[n]`` used only
by such moves is not a target; one also used by a plain move is (and the listing says so). An untaught
or group-1-less ``/POS`` entry no move uses is listed too.

Frames set at run time. ``UTOOL[n]=PR[i]`` and ``UFRAME[n]=PR[i]`` (``UTOOL[R[k]]=…``: any n), and the system
variables ``$MNUTOOL[1,n]=…`` and ``$MNUFRAME[1,n]=…`` (group 1; ``$MNUTOOL[1,n].X=…``, one of its numbers, too)
give a tool or user frame a value only the controller knows: a Cartesian target in that frame whose moves the write may reach,
by the program's labels, jumps and ``FOR`` loops (:mod:`kincal.io.jump_flow`), says why in ``in_force`` and is
refused, never compensated with the frame's given value (one no move uses: wherever the program writes its
frame). ``UTOOL_NUM``/``UFRAME_NUM`` only select a frame: a position names its own (``UT``, ``UF``), and the
controller refuses to move to it in another.

Skipped when searching ``/MN``: comments (``!…`` at the start of a statement or after its ``;``),
lines commented out (``//…``, ``--…``), strings, the comments of registers (``PR[2:name]``) and the
text of ``MESSAGE[…]``. Units are mm and deg, numbers in any style (``-.242``, ``1e3``).

A note kincal adds to a target it leaves as it is (:meth:`Program.with_targets`) is appended at the
end of the target's line, here after the ``};`` in ``/POS``, where TP has no comments: such a file does
not load. A TP comment is a ``/MN`` statement of its own (``   : ! text ;``), which also changes the
numbering and ``LINE_COUNT``; write FANUC programs without marks.
"""
from __future__ import annotations

import math
import re
from typing import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import MeasurementError
from ..models.transforms import rot_zyx, rotation_log, rotvec_matrix
from .jump_flow import Write, unknown_frames
from .programs import Dialect, Program, Target, controller_angles, line_column, old_numbers, write_fields

SECTION = re.compile(r"^[ \t]*/(PROG|ATTR|APPL|MN|POS|END)\b", re.M | re.I)
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
UNTAUGHT = re.compile(r"\*+")
HEAD = re.compile(r"P\[[ \t]*(\d+)[ \t]*(?::[ \t]*(?:\"[^\"\n]*\"|[^\]\n]*))?\][ \t]*\{")
GROUP = re.compile(r"\bGP(\d+)[ \t]*:")
ITEM = re.compile(r"([A-Za-z]\w*)[ \t]*([:=])[ \t]*('[^'\n]*'|[^\s,;]*)[ \t]*(mm|deg)?")
STATEMENT_START = r"^[ \t]*(?:\d*[ \t]*:)?[ \t]*"
BLANKS = [re.compile(STATEMENT_START + r"((?:!|//|--)[^\n]*)", re.M),  # comment lines, lines commented out
          re.compile(r"('[^'\n]*'?|\"[^\"\n]*\"?)"),  # strings
          re.compile(r";[ \t]*(![^\n]*)"),  # a comment after the statement
          re.compile(r"\[[ \t]*\d+[ \t]*(:[^\[\]\n]*)\]"),  # the comment of a register
          re.compile(r"\bMESSAGE\[([^\]\n]*)\]", re.I)]
MOVE = re.compile(STATEMENT_START + r"([JLCA])[ \t]+(?=P\[|PR\[)", re.M | re.I)
REF = re.compile(r"\b(PR|P)\[", re.I)
OPTION = re.compile(r"\b(Tool_Offset|Offset|VOFFSET|INC)\b(\s*,\s*(?:PR|VR)\[(?:[^\[\]\n]|\[[^\[\]\n]*\])*\])?",
                    re.I)
INDEX = r"((?:[^\[\],\n]|\[[^\[\]\n]*\])*)"  # a frame's or group's number: 2, R[4]
FRAME_WRITE = re.compile(  # UTOOL[2]=PR[9], $MNUTOOL[1,2]=PR[9], $MNUFRAME[1,R[4]].X=0: a frame's value set at run time
    r"(?:(?<![\w\[$])(UTOOL|UFRAME)[ \t]*\[[ \t]*(?:GP(\d+)[ \t]*:[ \t]*)?"
    r"|\$MN(UTOOL|UFRAME)[ \t]*\[" + INDEX + ",)" + INDEX + r"\](?:[ \t]*\.[ \t]*\w+)?[ \t]*=(?!=)[^;\n]*", re.I)
LABEL = re.compile(STATEMENT_START + r"LBL[ \t]*\[[ \t]*(\d+)[ \t]*\]", re.M | re.I)
JUMP = re.compile(r"\bLBL[ \t]*\[[ \t]*(\d+)?", re.I)  # any other LBL[…]: JMP, IF …,JMP, SELECT, Skip, TIMEOUT
LOOP = re.compile(STATEMENT_START + r"(FOR|ENDFOR)\b", re.M | re.I)
POSE_FIELDS = ("X", "Y", "Z", "W", "P", "R")
LENGTH_RES, ANGLE_RES = 1e-3, 1e-3  # mm, deg: the controller's step, to which its own .ls files write positions


@dataclass
class _Entry:
    """One /POS entry: its number, where it is, and its robot group (None: not taught or no GP1)."""

    number: int
    head: int
    brace: tuple[int, int]
    target: Target | None = None
    why: str = ""


@dataclass
class _Use:
    """One position of a move: the motion letter, where the move and the position are, the position's
    text, its number (None: a register or chosen at run time) and the run-time options that change it."""

    letter: str
    at: int
    ref: tuple[int, int]
    number: int | None
    why: list[str] = field(default_factory=list)


def _fail(source: str, text: str, at: int, what: str) -> MeasurementError:
    line, column = line_column(text, at)
    return MeasurementError(f"{source}: line {line}, column {column}: {what}")


def _sections(text: str) -> dict[str, tuple[int, int]]:
    """The span of each section's body (after its header line, up to the next header), by name."""
    heads = list(SECTION.finditer(text))
    out: dict[str, tuple[int, int]] = {}
    for k, m in enumerate(heads):
        end = heads[k + 1].start() if k + 1 < len(heads) else len(text)
        out.setdefault(m.group(1).upper(), (m.end(), end))
    return out


def parse(source: str, text: str) -> Program:
    """The targets (the taught /POS entries), the moves not to a literal and why, of a .ls program."""
    sections = _sections(text)
    entries = _positions(source, text, *sections.get("POS", (0, 0)))
    uses = _moves(source, text, *sections.get("MN", (0, 0)))
    by_number = {e.number: e for e in entries}
    plain: dict[int, _Use] = {}
    for u in uses:
        entry = by_number.get(u.number) if u.number is not None else None
        if u.number is not None and entry is None:
            u.why.insert(0, f"P[{u.number}] has no entry in /POS")
        elif entry is not None and entry.target is None:
            u.why.insert(0, entry.why)
        elif u.number is not None and not u.why:
            plain.setdefault(u.number, u)
    not_literal = []
    for u in uses:
        if u.why:
            also = f"; P[{u.number}] itself is compensated for its plain moves" if u.number in plain else ""
            not_literal.append((line_column(text, u.ref[0])[0], f"{u.letter} {text[u.ref[0]:u.ref[1]]}",
                                "; ".join(u.why) + also))
    used = {u.number for u in uses}
    targets = []
    for e in entries:
        if e.target is None:
            if e.number not in used:
                not_literal.append((line_column(text, e.head)[0], f"P[{e.number}]", e.why))
        elif e.number in plain:
            targets.append(_with_move(e.target, plain[e.number]))
        elif e.number not in used:
            targets.append(e.target)
    not_literal.sort(key=lambda n: n[0])
    at = {n: tuple(u.at for u in uses if u.number == n and not u.why) for n in plain}
    whys = _run_time_frames(text, *sections.get("MN", (0, 0)), [
        (t.frames if t.kind == "pose" else (), at.get(int(t.variable[2:-1]), ())) for t in targets])
    return Program(source, text, tuple(targets), tuple(not_literal), comment="", dialect="fanuc",
                   in_force=tuple((t.start, why) for t, why in zip(targets, whys) if why))


def _run_time_frames(text: str, a: int, b: int, targets: list[tuple[tuple[str, ...], tuple[int, ...]]]) -> list[str]:
    """Why each target (its frames, its moves' positions) is in a tool or user frame that /MN (text[a:b]) may have
    written at run time (``UTOOL[n]=…``, ``UFRAME[n]=…``, ``$MNUTOOL[1,n]=…``, ``$MNUFRAME[1,n]=…``:
    :func:`kincal.io.jump_flow.unknown_frames`), or ''."""
    code = " " * a + _code(text, a, b)
    writes = [Write(m.start(), line_column(text, m.start())[0],
                    {"UTOOL": "UT", "UFRAME": "UF"}[(m.group(1) or m.group(3)).upper()]
                    + (f" {int(m.group(5))}" if m.group(5).strip().isdigit() else ""), text[m.start():m.end()].strip())
              for m in FRAME_WRITE.finditer(code, a, b) if _group_1(m.group(2) or m.group(4) or "1")]
    if not writes:
        return [""] * len(targets)
    labels = {m.start(1) for m in LABEL.finditer(code, a, b)}
    marks: list[tuple[int, str, str | None]] = [(m.start(1), "label", str(int(m.group(1))))
                                                for m in LABEL.finditer(code, a, b)]
    marks += [(m.start(), "jump", m.group(1) and str(int(m.group(1)))) for m in JUMP.finditer(code, a, b)
              if m.start(1) not in labels]
    marks += [(m.start(1), "open" if m.group(1).upper() == "FOR" else "close", None) for m in LOOP.finditer(code, a, b)]
    return unknown_frames(writes, marks, targets)


def _group_1(group: str) -> bool:
    """Whether a frame write's motion group (``GP2:``; ``$MNUTOOL[2,…]``) may be the robot's, group 1 (a register
    may)."""
    return not group.strip().isdigit() or int(group) == 1


def _with_move(t: Target, use: _Use) -> Target:
    return Target(t.start, t.end, t.line, use.letter, t.kind, t.values, use.at, t.variable, t.fields, t.config,
                  t.frames)


# --- /POS ---------------------------------------------------------------------------------------

def _positions(source: str, text: str, a: int, b: int) -> list[_Entry]:
    """The /POS entries in text[a:b], in order."""
    out: list[_Entry] = []
    at = a
    while True:
        at = _skip(text, at, b, " \t\r\n")
        if at >= b:
            return out
        head = HEAD.match(text, at, b)
        if head is None:
            raise _fail(source, text, at, "expected a position P[n]{ … }; in /POS")
        number, brace = int(head.group(1)), head.end() - 1
        close = _closing(source, text, brace, b, number)
        if any(e.number == number for e in out):
            raise _fail(source, text, at, f"P[{number}] is in /POS twice")
        out.append(_entry(source, text, number, at, (brace, close)))
        at = _skip(text, close + 1, b, " \t")
        if text[at:at + 1] != ";":
            raise _fail(source, text, close, f"P[{number}]: '}}' without its ';'")
        at += 1


def _skip(text: str, at: int, b: int, chars: str) -> int:
    """The first position from ``at`` (before ``b``) whose character is not one of ``chars``."""
    while at < b and text[at] in chars:
        at += 1
    return at


def _closing(source: str, text: str, brace: int, b: int, number: int) -> int:
    """The position of the '}' that closes the entry opened at ``brace``."""
    for i in range(brace + 1, b):
        if text[i] == "}":
            return i
        if text[i] == "{" or text.startswith("/END", i) or (text[i] == "P" and HEAD.match(text, i, b)):
            break
    raise _fail(source, text, brace, f"P[{number}] has no closing '}};'")


def _entry(source: str, text: str, number: int, head: int, brace: tuple[int, int]) -> _Entry:
    """A /POS entry with its GP1 read (the other groups are kept as they are)."""
    a, b = brace[0] + 1, brace[1]
    groups = list(GROUP.finditer(text, a, b))
    before = text[a:groups[0].start() if groups else b]
    if not groups or before.strip():
        raise _fail(source, text, a + len(before) - len(before.lstrip()), f"P[{number}]: expected a group GP1: … GPn:")
    entry = _Entry(number, head, brace)
    one = [k for k, g in enumerate(groups) if g.group(1) == "1"]
    if not one:
        entry.why = f"P[{number}] has no GP1 (the robot's group): only other motion groups"
        return entry
    k = one[0]
    end = groups[k + 1].start() if k + 1 < len(groups) else b
    items = _items(source, text, groups[k].end(), end, number)
    if any(UNTAUGHT.fullmatch(v) for _, _, v, _ in items):
        entry.why = f"P[{number}] is not taught (its /POS entry holds ********)"
        return entry
    entry.target = _robot(source, text, number, head, brace, items)
    return entry


def _items(source: str, text: str, a: int, b: int, number: int) -> list[tuple[str, int, str, str]]:
    """The items ``name = value unit`` / ``name : value`` of a group: (name, value's offset, value, unit)."""
    out: list[tuple[str, int, str, str]] = []
    at = a
    while True:
        at = _skip(text, at, b, " \t\r\n,")
        if at >= b:
            return out
        m = ITEM.match(text, at, b)
        if m is None:
            raise _fail(source, text, at, f"P[{number}]: expected 'name = number unit' or 'name : value'")
        name, value = m.group(1).upper(), m.group(3)
        if not value:
            raise _fail(source, text, m.start(3), f"P[{number}]: {m.group(1)} has no value")
        if m.group(2) == "=" and not (NUMBER.fullmatch(value) or UNTAUGHT.fullmatch(value)):
            raise _fail(source, text, m.start(3), f"P[{number}]: {m.group(1)} = '{value}' is not a number")
        out.append((name, m.start(3), value, m.group(4) or ""))
        at = m.end()


def _robot(source: str, text: str, number: int, head: int, brace: tuple[int, int],
           items: list[tuple[str, int, str, str]]) -> Target:
    """The target of a taught GP1: Cartesian (X…R and CONFIG) or joints (J1…Jn); E1… are not fields."""
    by_name = {name: (at, value) for name, at, value, _ in items}
    frames = (f"UT {by_name['UT'][1]}" if "UT" in by_name else "", f"UF {by_name['UF'][1]}" if "UF" in by_name else "")
    axes = [i for i in items if i[0] not in ("UF", "UT", "CONFIG") and not re.fullmatch(r"E\d+", i[0])]
    names = [i[0] for i in axes]
    first = axes[0][1] if axes else brace[0]
    config: tuple = ()
    if "X" in names:
        if names != list(POSE_FIELDS):
            raise _fail(source, text, first, f"P[{number}]: a Cartesian position needs X, Y, Z, W, P, R in this order")
        if "CONFIG" not in by_name:
            raise _fail(source, text, first, f"P[{number}]: a Cartesian position without its CONFIG")
        _units(source, text, number, axes, ("mm",) * 3 + ("deg",) * 3)
        v = np.array([float(i[2]) for i in axes])
        values = np.concatenate([v[:3] * 1e-3, rotation_log(rot_zyx(*np.deg2rad(v[[5, 4, 3]]))[None])[0]])
        kind, config = "pose", _config(source, text, number, *by_name["CONFIG"])
    elif names and names == [f"J{k}" for k in range(1, len(names) + 1)]:
        _units(source, text, number, axes, ("",) * len(axes))
        values = np.array([float(value) * (1e-3 if unit == "mm" else np.pi / 180) for _, _, value, unit in axes])
        kind = "joints"
    else:
        raise _fail(source, text, first,
                    f"P[{number}]: expected X, Y, Z, W, P, R or J1, J2, … in GP1, found {', '.join(names) or 'none'}")
    return Target(brace[0], brace[1] + 1, line_column(text, head)[0], f"P[{number}]", kind, values, head,
                  f"P[{number}]", tuple((at, at + len(value)) for _, at, value, _ in axes), config, frames)


def _units(source: str, text: str, number: int, axes: list, units: tuple[str, ...]) -> None:
    """Each axis in its unit ('' where mm or deg will do; an axis written without one is taken as it)."""
    for (name, at, value, unit), want in zip(axes, units):
        if unit and want and unit != want:
            raise _fail(source, text, at, f"P[{number}]: {name} in {unit}; FANUC writes it in {want}")


def _config(source: str, text: str, number: int, at: int, value: str) -> tuple:
    """('N U T', turn1, turn2, turn3) from CONFIG : 'N U T, 0, 0, 0'."""
    parts = [p.strip() for p in value.strip("'").split(",")]
    if len(parts) < 2 or not all(re.fullmatch(r"[-+]?\d+", p) for p in parts[1:]):
        raise _fail(source, text, at, f"P[{number}]: CONFIG {value} is not 'flip up top, turn, turn, turn'")
    return (parts[0], *(int(p) for p in parts[1:]))


# --- /MN ----------------------------------------------------------------------------------------

def _code(text: str, a: int, b: int) -> str:
    """text[a:b] with comments, strings and register comments blanked (same length)."""
    code = text[a:b]
    for pattern in BLANKS:
        code = pattern.sub(_blank, code)
    return code


def _blank(m: re.Match) -> str:
    """The match with its group 1 blanked (line endings kept)."""
    s, e = m.start(1) - m.start(), m.end(1) - m.start()
    return m.group()[:s] + re.sub(r"[^\r\n]", " ", m.group()[s:e]) + m.group()[e:]


def _moves(source: str, text: str, a: int, b: int) -> list[_Use]:
    """The positions of the moves of /MN (text[a:b]) in text order, with what makes them not literal."""
    code = " " * a + _code(text, a, b)
    starts = list(MOVE.finditer(code, a))
    uses = []
    for k, m in enumerate(starts):
        stop = starts[k + 1].start() if k + 1 < len(starts) else b
        end = code.find(";", m.end(), stop)
        end = stop if end < 0 else end
        letter = m.group(1).upper()
        refs = [_ref(source, text, code, m.end(), end)]
        if letter == "C":
            refs.append(_end_point(source, text, code, refs[0][1], end, m.start(1)))
        for j, (r0, r1) in enumerate(refs):
            seg_end = refs[j + 1][0] if j + 1 < len(refs) else end
            uses.append(_use(text, code, letter, m.start(1), (r0, r1), seg_end))
    return uses


def _ref(source: str, text: str, code: str, at: int, end: int) -> tuple[int, int]:
    """The span of the position reference P[…] / PR[…] at ``at`` (brackets matched)."""
    depth = 0
    for i in range(code.index("[", at), end):
        depth += {"[": 1, "]": -1}.get(code[i], 0)
        if depth == 0:
            return at, i + 1
    raise _fail(source, text, at, "a position reference without its closing ']'")


def _end_point(source: str, text: str, code: str, after: int, end: int, move: int) -> tuple[int, int]:
    """The end position of a circular move: next to its via point or at the start of the next line."""
    near = re.compile(r"[\s:]*").match(code, after, end)
    at = near.end() if near else after
    if REF.match(code, at, end) is None:
        line = re.compile(r"\n[ \t]*:?[ \t]*(?=P\[|PR\[)", re.I).search(code, after, end)
        if line is None:
            raise _fail(source, text, move, "a circular move (C) without its end position")
        at = line.end()
    return _ref(source, text, code, at, end)


def _use(text: str, code: str, letter: str, at: int, ref: tuple[int, int], seg_end: int) -> _Use:
    """One position of a move, with the reasons it cannot be compensated as a literal."""
    inner = code[code.index("[", ref[0]) + 1:ref[1] - 1].strip()
    is_register = code[ref[0]:ref[0] + 2].upper() == "PR"
    number = int(inner) if inner.isdigit() and not is_register else None
    use = _Use(letter, at, ref, number)
    shown = text[ref[0]:ref[1]]
    if is_register:
        use.why.append(f"{shown} is a position register: its value is held by the controller, not in this program")
    elif number is None:
        use.why.append(f"{shown}: the position number is read from a register at run time")
    for m in OPTION.finditer(code, ref[1], seg_end):
        option, arg = m.group(1).upper(), text[m.start():m.end()]
        use.why.append("INC: the position is an increment from where the robot is, not a place in a frame"
                       if option == "INC" else
                       f"{arg}: the controller adds a vision offset at run time" if option == "VOFFSET" else
                       f"{arg}: the controller adds an offset in the tool frame at run time"
                       if option == "TOOL_OFFSET" else
                       f"{arg}: the controller adds an offset at run time"
                       + ("" if m.group(2) else " (the register of OFFSET CONDITION)"))
    return use


# --- writing ------------------------------------------------------------------------------------

def _fields(text: str, targets: Sequence[Target], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fields of targets of one kind for new SI values (G, V): X, Y, Z in mm and W, P, R in deg (the
    triple nearest the old numbers, each in FANUC's [-180, 180]), or J1…Jn in deg (mm for an axis written in mm)."""
    if targets[0].kind == "joints":
        scale = np.array([[1e3 if re.match(r"[ \t]*mm\b", text[b:b + 8]) else 180 / np.pi for _, b in t.fields]
                          for t in targets])
        return values * scale, np.where(scale == 1e3, LENGTH_RES, ANGLE_RES)
    old = old_numbers(text, targets, slice(5, 2, -1))  # R, P, W: about z, y, x
    angles = controller_angles(rotvec_matrix(values[:, 3:6]), old)[:, ::-1]
    return np.concatenate([values[:, :3] * 1e3, angles], axis=1), np.array([LENGTH_RES] * 3 + [ANGLE_RES] * 3)


def write(text: str, targets: Sequence[Target], values: Sequence[np.ndarray]) -> list[str]:
    """The targets' {…} with their fields written for new SI values (:func:`_fields`), each number in its old
    style; every other byte as it is."""
    return write_fields(text, targets, values, _fields)


# no comment mark: TP allows none after a /POS entry
DIALECT = Dialect("fanuc", (".ls",), "", parse, write,
                  step=(LENGTH_RES * 1e-3, math.radians(ANGLE_RES)))
