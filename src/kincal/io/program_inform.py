"""Yaskawa Motoman INFORM job files (``.JBI``): the taught Cartesian positions of MOVJ/MOVL/MOVC/MOVS.

A job is ``/JOB``, ``//NAME``, a position section ``//POS`` and an instruction section ``//INST``
(other sections, e.g. ``//ARGINFO``, are kept and not read). The position section holds:

- ``///NPOS c,bc,ec,p,bp,ex``: how many robot (C), base-axis (BC) and station (EC) teaching positions
  and robot (P), base (BP) and station (EX) position variables follow. It is checked against the lines
  (a job whose counts disagree does not load); positions are never added or removed, so it stays right.
- pseudo-instructions in force for the positions after them: ``///TOOL n``, ``///USER n``,
  ``///POSTYPE PULSE|BASE|ROBOT|USER|TOOL|MTOOL``, ``///PULSE`` / ``///RECTAN`` (the data form) and
  ``///RCONF l,m,n,o,p,q,…`` (flip, upper/lower arm, front/rear, R/T/S >= 180°, then unused digits).
- position lines ``C00000=…``, ``BC00000=…``, ``EC00000=…``, ``P00025=…``, ``BP0001=…``, ``EX0001=…``.

**Targets.** A C position in RECTAN form (``Cnnnnn=X,Y,Z,Rx,Ry,Rz[,Re]``: mm and degrees, R =
Rz(Rz)·Ry(Ry)·Rx(Rx), fixed axes X then Y then Z) under ``///POSTYPE BASE``, ``ROBOT`` or ``USER`` that a
MOVJ, MOVL, MOVC or MOVS of the instruction section moves to (``MOVL C0003 V=…``: instructions may write
the number with another width; C positions are matched by number). Its ``move`` is the instruction, its
``variable`` the name in the position section (``C00003``), ``at`` the instruction's offset, its span and
line those of the position line's numbers; ``fields`` are X, Y, Z, Rx, Ry, Rz (the 7-axis arms' Re, and
BC/EC base and station axes, stay byte for byte); ``config`` the first six digits of the ``///RCONF`` in force
(() before any; jobs write 6, 8 or 24, the digits past the sixth unused by a six-axis arm and kept as written);
``frames`` ("TOOL n", "USER m" | "BASE" | "ROBOT") from ``///TOOL``/``///USER``/``///POSTYPE`` ('' where the job
names no tool), ``///POSTYPE BASE`` named "ROBOT" in a job whose groups have no base axis (no ``BSn`` in a
``///GROUPn`` line): without a travel track the base frame is the robot frame. A C position used by two moves is compensated once, where it is written.
Values: x, y, z in m and the rotation vector (rad) of the TCP in that frame.

A C position in PULSE form that a move goes to is a target of kind "pulses": its values are the encoder
counts as written (every count a field, written back as whole counts); turning them into joint angles
needs each joint's pulses per degree, the controller's parameters, which a robot file gives
(``pulses_per_degree``): without them the compensation refuses it with that reason.

**Listed, never touched** (``not_literal``: line, what, why):
- C positions in TOOL or MTOOL coordinates (a frame that moves with the robot or another manipulator);
- C positions used by an instruction that is not MOVJ/MOVL/MOVC/MOVS (e.g. ``REFP``, ``SMOVL``), and C
  positions no instruction uses (at their position line);
- robot position variables in instructions (``P025``, ``LP000``, ``PX001``, ``P[I000]``): P variables are
  global — shared by every job and changeable at run time — so the copy a job file carries is not what a
  move is sure to read; local ones are filled at run time. Each use is listed with what it is: a move to
  it, an assignment at run time (SET, SETE, ADD, SUB, MUL, DIV, CNVRT, GETS, MSHIFT, CLEAR…), a user frame
  made at run time (MFRAME), a run-time shift (SFTON: the literal C targets up to SFTOF are compensated as
  written, not where the shift puts them), an incremental move (IMOV); P variables the job carries but
  does not use are listed at their position line.

**Frames set at run time.** ``MFRAME UF#(n) …`` makes user frame n, ``SETTOOL TL#(n) …`` sets tool n (``UF#(B000)``:
any n): a target in that frame whose moves the write may reach, by the job's labels, jumps (``*L1`` … ``JUMP
*L1``) and loops (:mod:`kincal.io.jump_flow`), says why in ``in_force`` and is refused, never compensated with the
frame's given value.

Base-axis and station positions and variables (BC, EC, BP, EX) are external axes: not targets, not listed.
Comments (``'`` to the end of the line) and strings are blanked before instructions are searched; names
are matched case-insensitively. Broken input (a non-number, a truncated Cartesian position, an RCONF
that is not digits, NPOS counts that disagree, a move to a C position the job does not hold, a USER
position with no ``///USER``, an unclosed string) raises :class:`kincal.errors.MeasurementError` naming
the file, line and column.
"""
from __future__ import annotations

import math
import re
from typing import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import MeasurementError
from ..models.transforms import rot_zyx, rotation_log, rotvec_matrix
from .branches import RCONF_DIGITS
from .jump_flow import Write, unknown_frames
from .programs import Dialect, Program, Target, controller_angles, line_column, old_numbers, write_fields

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
SECTION = re.compile(r"[ \t\ufeff]*//(?!/)[ \t]*([A-Za-z]*)")
PSEUDO = re.compile(r"[ \t]*///[ \t]*([A-Za-z]+)[ \t]*(.*?)[ \t]*$")
POSITION = re.compile(r"[ \t]*(C|BC|EC|P|BP|EX)(\d+)[ \t]*=", re.I)
# a position reference in an instruction: not after a letter, digit, '$' (system variable), '*' (label),
# ':' (CALL JOB:name) or '#'
REFERENCE = re.compile(r"(?<![\w$*:#.])(?:(LPX|LBP|LEX|LP|PX|BP|BC|EC|EX|C|P)(\d+)\b"
                       r"|(LPX|LBP|LEX|LP|PX|BP|EX|P)\[[^\]\n]*\])", re.I)
STRING_OR_COMMENT = re.compile(r"\"[^\"]*\"?|'.*$")
WORD = re.compile(r"[ \t]*([A-Za-z]\w*)")
PLUS_MOVE = re.compile(r"\+[ \t]*(S?MOV[JLCS])\b", re.I)
MOVES = ("MOVJ", "MOVL", "MOVC", "MOVS")
POSTYPES = ("PULSE", "BASE", "ROBOT", "USER", "TOOL", "MTOOL")
BASE_AXIS = re.compile(r"^[ \t]*///GROUP\d+[ \t]+[^\n]*\bBS\d", re.M | re.I)  # a group with a base axis (travel track)
NPOS_KINDS = ("C", "BC", "EC", "P", "BP", "EX")
ROBOT_VARIABLES = ("P", "LP", "PX", "LPX")
ASSIGNS = ("SET", "SETE", "ADD", "SUB", "MUL", "DIV", "CNVRT", "GETS", "MSHIFT", "CLEAR", "SETEXPRESS")
FRAME_WRITE = re.compile(r"[ \t]*(MFRAME|SETTOOL)[ \t]+(UF|TL)#[ \t]*\(([^)\n]*)\)", re.I)  # a frame set at run time
LABEL = re.compile(r"[ \t]*\*[ \t]*(\w+)")
JUMP = re.compile(r"\bJUMP[ \t]+(?:\*[ \t]*(\w+)|(?!JOB[ \t]*:))", re.I)  # to a label: named, or chosen at run time
LOOP = re.compile(r"[ \t]*(FOR|NEXT|WHILE|ENDWHILE)\b", re.I)
RESOLUTION = np.array([1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4])  # mm, deg: the controller's step (its own .JBI files)


@dataclass(frozen=True)
class _Position:
    """One line of the position section: its kind (C, BC, …), its name as written and number, its line,
    the span of its values, the spans and values of its numbers and the pseudo-instructions in force."""

    kind: str
    name: str
    number: int
    line: int
    start: int
    end: int
    numbers: tuple[tuple[int, int, float], ...]
    form: str  # "PULSE" or "RECTAN"
    postype: str
    tool: str
    user: str
    rconf: tuple[int, ...]


@dataclass(frozen=True)
class _Reference:
    """A position named in an instruction: its kind and number ('' / -1 for an indirect one), the text,
    the instruction that names it and where that is, and the line."""

    kind: str
    number: int
    text: str
    word: str
    at: int
    line: int
    where: int


def _fail(source: str, text: str, at: int, what: str) -> MeasurementError:
    line, column = line_column(text, at)
    return MeasurementError(f"{source}: line {line}, column {column}: {what}")


def _lines(text: str) -> list[tuple[int, int]]:
    """(start, end) of every line, without its line ending (LF or CRLF)."""
    out, at = [], 0
    for piece in text.split("\n"):
        out.append((at, at + len(piece) - piece.endswith("\r")))
        at += len(piece) + 1
    return out


def _sections(text: str) -> dict[str, list[tuple[int, int]]]:
    """The lines of each section (//POS, //INST, …) by name (upper case), the section line excluded."""
    out: dict[str, list[tuple[int, int]]] = {}
    current = ""
    for a, b in _lines(text):
        m = SECTION.match(text, a, b)
        if m:
            current = m.group(1).upper()
            out.setdefault(current, [])
        elif current:
            out[current].append((a, b))
    return out


def _numbers(source: str, text: str, a: int, b: int) -> tuple[tuple[int, int, float], ...]:
    """The comma-separated numbers in text[a:b]: (start, end, value) each."""
    out, at = [], a
    for piece in text[a:b].split(","):
        lead = len(piece) - len(piece.lstrip(" \t"))
        body = piece.strip(" \t")
        if not body:
            raise _fail(source, text, at + lead, "a number is missing")
        if not NUMBER.fullmatch(body):
            raise _fail(source, text, at + lead, f"'{body}' is not a number")
        out.append((at + lead, at + lead + len(body), float(body)))
        at += len(piece) + 1
    return tuple(out)


def _integers(source: str, text: str, m: re.Match, what: str) -> tuple[int, ...]:
    """The comma-separated whole numbers of a pseudo-instruction's argument (group 2 of ``m``)."""
    values = []
    for a, b, v in _numbers(source, text, m.start(2), m.end(2)):
        if not re.fullmatch(r"[-+]?\d+", text[a:b]):
            raise _fail(source, text, a, f"{what} takes whole numbers, not '{text[a:b]}'")
        values.append(int(v))
    return tuple(values)


def _pseudo(source: str, text: str, m: re.Match, state: dict) -> None:
    """Apply one ///pseudo-instruction of the position section to ``state``."""
    name, arg = m.group(1).upper(), m.group(2)
    if name == "NPOS":
        counts = _integers(source, text, m, "///NPOS")
        if len(counts) != 6:
            raise _fail(source, text, m.start(2), f"///NPOS needs 6 counts (C,BC,EC,P,BP,EX), found {len(counts)}")
        state["npos"] = (counts, m.start(1))
    elif name in ("TOOL", "USER"):
        number = _integers(source, text, m, f"///{name}")
        if len(number) != 1:
            raise _fail(source, text, m.start(2), f"///{name} needs one frame number")
        state[name.lower()] = f"{name} {number[0]}"
    elif name == "POSTYPE":
        if arg.upper() not in POSTYPES:
            raise _fail(source, text, m.start(2), f"///POSTYPE '{arg}' is not one of {', '.join(POSTYPES)}")
        state["postype"] = arg.upper()
    elif name in ("PULSE", "RECTAN"):
        state["form"] = name
    elif name == "RCONF":
        state["rconf"] = _integers(source, text, m, "///RCONF")


def _position(source: str, text: str, m: re.Match, b: int, state: dict) -> _Position:
    """The position on the line whose name ``m`` matched (the line ends at ``b``)."""
    kind = m.group(1).upper()
    form = state["form"] or ("PULSE" if state["postype"] == "PULSE" else "RECTAN" if state["postype"] else "")
    if not form:
        raise _fail(source, text, m.start(1), "a position before any ///POSTYPE, ///PULSE or ///RECTAN")
    end = m.end() + len(text[m.end():b].rstrip(" \t"))
    numbers = _numbers(source, text, m.end(), end)
    robot = kind in ("C", "P")
    if robot and form == "RECTAN":
        if not 6 <= len(numbers) <= 7:
            raise _fail(source, text, end, f"a Cartesian position is X,Y,Z,Rx,Ry,Rz[,Re]: {len(numbers)} numbers")
        if state["postype"] in ("", "PULSE"):
            raise _fail(source, text, m.start(1), "a Cartesian (///RECTAN) position with no Cartesian ///POSTYPE")
        if state["postype"] == "USER" and not state["user"]:
            raise _fail(source, text, m.start(1), "a position in a user frame with no ///USER number before it")
    line = text.count("\n", 0, m.start()) + 1
    return _Position(kind, text[m.start(1):m.end(2)], int(m.group(2)), line, numbers[0][0], end, numbers, form,
                     state["postype"], state["tool"], state["user"], state["rconf"])


def _positions(source: str, text: str, lines: list[tuple[int, int]]) -> dict[tuple[str, int], _Position]:
    """The positions of the //POS section by (kind, number), checked against ///NPOS."""
    state: dict = {"npos": None, "tool": "", "user": "", "postype": "", "form": "", "rconf": ()}
    found: dict[tuple[str, int], _Position] = {}
    for a, b in lines:
        pseudo, pos = PSEUDO.match(text, a, b), POSITION.match(text, a, b)
        if pseudo:
            _pseudo(source, text, pseudo, state)
        elif pos:
            p = _position(source, text, pos, b, state)
            if (p.kind, p.number) in found:
                raise _fail(source, text, pos.start(1), f"{p.name} is defined twice")
            found[(p.kind, p.number)] = p
        elif text[a:b].strip():
            raise _fail(source, text, a + len(text[a:b]) - len(text[a:b].lstrip()),
                        "not a position line or a ///pseudo-instruction of the //POS section")
    if state["npos"] is None:
        if found:
            raise _fail(source, text, lines[0][0], "positions without a ///NPOS line")
        return found
    counts, at = state["npos"]
    for kind, declared in zip(NPOS_KINDS, counts):
        held = sum(k == kind for k, _ in found)
        if held != declared:
            raise _fail(source, text, at, f"///NPOS declares {declared} {kind} positions, the //POS section has {held}")
    return found


def _code(source: str, text: str, a: int, b: int) -> str:
    """text[a:b] with its strings and its comment blanked (same length)."""
    def blank(m: re.Match) -> str:
        s = m.group()
        if s.startswith('"') and (len(s) == 1 or not s.endswith('"')):
            raise _fail(source, text, a + m.start(), "a string without its closing '\"'")
        return " " * len(s)
    return STRING_OR_COMMENT.sub(blank, text[a:b])


def _references(source: str, text: str, lines: list[tuple[int, int]]) -> list[_Reference]:
    """The robot, base and station positions named in the //INST section, each with its instruction."""
    out = []
    for a, b in lines:
        if PSEUDO.match(text, a, b):
            continue
        code = _code(source, text, a, b)
        first = WORD.match(code)
        words = ([(first.start(1), first.group(1).upper())] if first else [])
        words += [(w.start(1), w.group(1).upper()) for w in PLUS_MOVE.finditer(code)]
        line = text.count("\n", 0, a) + 1
        for m in REFERENCE.finditer(code):
            before = [w for w in words if w[0] < m.start()]
            at, word = before[-1] if before else (m.start(), "")
            kind, number = (m.group(1) or m.group(3)).upper(), int(m.group(2)) if m.group(2) else -1
            out.append(_Reference(kind, number, m.group(), word, a + at, line, a + m.start()))
    return out


def _variable_why(ref: _Reference) -> str:
    """Why a move or another instruction that names a robot position variable is not compensated."""
    name = ref.text.upper()
    if ref.number < 0:
        return f"{name}: a position variable chosen at run time (indirect designation)"
    if ref.word in ASSIGNS:
        return f"{name} is assigned at run time by {ref.word}"
    if ref.word == "MFRAME":
        return f"a user frame made at run time from position variables ({name}): targets in it depend on it"
    if ref.word == "SFTON":
        return (f"a shift by {name} at run time: the targets up to SFTOF are compensated as written, "
                "not where the shift puts them")
    if ref.word == "IMOV":
        return f"an incremental move by {name}: the target is computed at run time from where the robot is"
    if ref.kind in ("LP", "LPX"):
        return f"{name} is a local position variable, filled at run time"
    return (f"{name} is a global position variable (shared by every job, changeable at run time): "
            "the copy this job carries is not compensated")


def _pose(p: _Position) -> np.ndarray:
    """x, y, z (m) and rotation vector (rad) of a RECTAN position."""
    x, y, z, rx, ry, rz = (v for _, _, v in p.numbers[:6])
    R = rot_zyx(math.radians(rz), math.radians(ry), math.radians(rx))
    return np.concatenate([np.array([x, y, z]) * 1e-3, rotation_log(np.asarray(R)[None])[0]])


def _target(p: _Position, ref: _Reference, base_axis: bool) -> Target:
    base = p.user if p.postype == "USER" else "ROBOT" if p.postype == "BASE" and not base_axis else p.postype
    return Target(p.start, p.end, p.line, ref.word, "pose", _pose(p), ref.at, p.name,
                  tuple((a, b) for a, b, _ in p.numbers[:6]), p.rconf[:RCONF_DIGITS], (p.tool, base))


def _pulse_target(p: _Position, ref: _Reference) -> Target:
    """A PULSE position's target: its encoder counts as written (kind "pulses"), every count a field."""
    return Target(p.start, p.end, p.line, ref.word, "pulses", np.array([v for _, _, v in p.numbers]), ref.at, p.name,
                  tuple((a, b) for a, b, _ in p.numbers))


def _moves(found: dict, refs: list[_Reference], base_axis: bool) -> tuple[list, list, set]:
    """Targets and listed items of the C positions that moves and other instructions name (``base_axis``: the
    job moves a base axis); the keys of the positions accounted for."""
    targets, listed, used = [], [], set()
    for r in refs:
        if r.kind != "C":
            continue
        p, what = found[("C", r.number)], f"{r.word} {r.text}"
        if r.word not in MOVES:
            listed.append((r.line, what, f"a taught position used by {r.word or 'no instruction'}, not by a move: "
                                         "kincal compensates the targets of MOVJ, MOVL, MOVC and MOVS"))
        elif ("C", r.number) in used:
            continue
        elif p.form == "PULSE":
            targets.append(_pulse_target(p, r))
        elif p.postype in ("TOOL", "MTOOL"):
            listed.append((r.line, what, f"a position in {p.postype} coordinates, a frame that moves with the "
                                         "robot: not a fixed target"))
        else:
            targets.append(_target(p, r, base_axis))
        used.add(("C", r.number))
    return targets, listed, used


def parse(source: str, text: str) -> Program:
    """The literal targets (text order), and the listed positions, of an INFORM job."""
    sections = _sections(text)
    found = _positions(source, text, sections.get("POS", []))
    refs = _references(source, text, sections.get("INST", []))
    for r in refs:
        if r.kind == "C" and ("C", r.number) not in found:
            raise _fail(source, text, r.where, f"{r.text}: the job's //POS section holds no such C position")
    targets, listed, used = _moves(found, refs, bool(BASE_AXIS.search(text)))
    variables = set()
    for r in refs:
        if r.kind in ROBOT_VARIABLES:
            listed.append((r.line, f"{r.word} {r.text}".strip(), _variable_why(r)))
            variables.add(r.number)
    for (kind, n), p in found.items():
        if kind == "C" and (kind, n) not in used:
            listed.append((p.line, p.name, "a taught position no instruction of this job uses"))
        if kind == "P" and n not in variables:
            listed.append((p.line, p.name, "a global position variable this job carries and does not use"))
    targets.sort(key=lambda t: t.start)
    at: dict[int, tuple[int, ...]] = {}
    for r in refs:
        if r.kind == "C" and r.word in MOVES:
            at[r.number] = at.get(r.number, ()) + (r.at,)
    whys = _run_time_frames(source, text, sections.get("INST", []),
                            [(t.frames if t.kind == "pose" else (), at.get(int(t.variable[1:]), ())) for t in targets])
    return Program(source, text, tuple(targets), tuple(sorted(listed, key=lambda item: item[0])), comment="",
                   dialect="inform", in_force=tuple((t.start, why) for t, why in zip(targets, whys) if why))


def _run_time_frames(source: str, text: str, lines: list[tuple[int, int]],
                     targets: list[tuple[tuple[str, ...], tuple[int, ...]]]) -> list[str]:
    """Why each target (its frames, its moves' positions) is in a tool or user frame the //INST section (``lines``)
    may have set at run time (``MFRAME UF#(n)``, ``SETTOOL TL#(n)``: :func:`kincal.io.jump_flow.unknown_frames`),
    or ''."""
    writes, marks = [], []
    for a, b in lines:
        code = _code(source, text, a, b)
        m = FRAME_WRITE.match(code)
        if m:
            kind = {"UF": "USER", "TL": "TOOL"}[m.group(2).upper()]
            number = m.group(3).strip()
            frame = kind + (f" {int(number)}" if number.isdigit() else "")  # B000: any of them
            writes.append(Write(a + m.start(1), text.count("\n", 0, a) + 1, frame, code.strip()))
        label, loop = LABEL.match(code), LOOP.match(code)
        marks += [(a + label.start(1), "label", label.group(1).upper())] if label else []
        marks += [(a + j.start(), "jump", j.group(1) and j.group(1).upper()) for j in JUMP.finditer(code)]
        marks += [(a + loop.start(1), "open" if loop.group(1).upper() in ("FOR", "WHILE") else "close", None)] \
            if loop else []
    return unknown_frames(writes, marks, targets) if writes else [""] * len(targets)


def _fields(text: str, targets: Sequence[Target], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positions' numbers for new SI values (G, 6): X, Y, Z (mm; 1e-3 mm) and Rx, Ry, Rz (deg; 1e-4°), the
    equivalent angle triple nearest the old one, each in [-180, 180]; a number that moved only by rounding noise
    stays the old one."""
    if targets[0].kind == "pulses":  # whole counts
        return np.round(values), np.full(values.shape[1], 0.5)
    old = old_numbers(text, targets)
    angles = controller_angles(rotvec_matrix(values[:, 3:6]), old[:, 5:2:-1])[:, ::-1]
    numbers = np.concatenate([values[:, :3] * 1e3, angles], axis=1)  # Rx, Ry, Rz from (rz, ry, rx)
    return np.where(np.abs(numbers - old) <= RESOLUTION / 2, old, numbers), RESOLUTION


def write(text: str, targets: Sequence[Target], values: Sequence[np.ndarray]) -> list[str]:
    """The positions' numbers for new SI values (:func:`_fields`), each in its old style; the rest of the
    line as it is."""
    return write_fields(text, targets, values, _fields)


# no comment mark: INFORM allows none after a position line
DIALECT = Dialect("inform", (".jbi",), "", parse, write,
                  step=(float(RESOLUTION[0]) * 1e-3, math.radians(RESOLUTION[3])))
