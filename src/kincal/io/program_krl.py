"""KUKA KRL (``.src``, ``.dat``, ``.sub``): the literal targets of a module file, one file at a time.

What is read. Comments (``;`` to the end of the line) and strings (``"…"``) are blanked first, so
nothing in them (the ``;FOLD PTP P1 Vel=100 %`` lines of the inline forms included) is a move. Names
are case-insensitive. A position aggregate is ``{X …, Y …, Z …, A …, B …, C …, S …, T …, E1 …}``
(E6POS, POS, FRAME) or ``{A1 …, …, A6 …, E1 …}`` (E6AXIS, AXIS), with or without its type
(``{AXIS: A1 0, …}``), components in any order.

What is a target (kind "pose" or "joints"):

* the literal of a move: ``PTP {A1 0, A2 -90, …}``, ``LIN {X …}``, both points of ``CIRC``/``SCIRC``,
  ``SPTP``, ``SLIN``, ``SPL`` (``move`` the instruction, ``variable`` '');
* a point variable of type E6POS, POS, E6AXIS or AXIS given one literal in the file: a ``.dat``
  declaration (``DECL E6POS XP1={…}``, ``GLOBAL E6AXIS …``, or with no DECL keyword), an array element
  (``XP[3]={…}``), or an assignment in a ``.src`` (``HOME = {AXIS: …}``); also an undeclared variable
  given one position-shaped literal (its type read from its components). ``move`` is the first move of
  the file that goes to it, or else its type ("E6POS", …); ``variable`` its name (with the index).
  A ``.dat`` point is a target even though its moves are in its module's ``.src`` (the file of the same
  name beside it), unless that ``.src`` assigns it too, whole or in part (``ROS_Meas_Vel = ROS_getVel()``):
  then it is filled or changed at run time (a measured position, a velocity, a torque) and listed, like a
  variable assigned twice in one file; or unless it is not ``GLOBAL`` (only its module sees it) and no move of
  that ``.src`` names it: a value the module uses otherwise (a limit in an ``IF``, a speed, a record), listed.
  A ``.dat`` with no ``.src`` beside it is read alone: each point is a target.
* a FRAME variable is tool or base data (``TOOL_DATA[1]``, a base), not a place the robot goes to:
  it is a target only where a move of this file moves to it (``LIN F1``: KRL takes a FRAME as a
  Cartesian target); otherwise it is listed, never changed.

Frames: a point ``X<name>`` with a ``DECL FDAT F<name>={TOOL_NO t, BASE_NO b, …}`` in the same file
(the inline forms' naming) has ``frames`` ("TOOL_NO t", "BASE_NO b"). Any other target has the values
assigned to ``$TOOL`` and ``$BASE`` as written (e.g. "TOOL_DATA[1]", "$NULLFRAME"; KUKA's ``BAS(#TOOL, n)``,
``BAS(#BASE, n)`` and ``BAS(#FRAMES)`` set them too, the last from FDAT_ACT's FDAT in the file or its module's
``.dat``) that the module's flow leaves in force at its moves (:mod:`kincal.io.krl_flow`: an assignment in a
``DEF`` reaches the moves after each call of it, one in an ``IF``, ``SWITCH`` or loop the moves after the block
only as one possibility), or '' where the file sets none; where its paths leave different ones, one known only at
run time (``BAS(#TOOL, nTool)``), or the module jumps with ``GOTO``, the target's ``Program.in_force_of`` says
why, and it is refused. A ``.src`` move ``PTP XP1 … C_PTP`` whose point and
FDAT are in the ``.dat`` is listed in the ``.src`` (its literal is compensated in the ``.dat``). A ``.dat`` point
with no FDAT of its own that its module's ``.src`` moves to takes the $TOOL and $BASE the ``.src``'s flow leaves in
force at every one of those moves (a move to ``XP[i]``, an index computed at run time, is one to each element of
``XP``); where they differ between its moves or are not known, '' and ``in_force_of`` names the ``.src`` and its
lines. Only a ``.dat`` point no move of the ``.src`` uses (a GLOBAL one other modules move to) is read as the
``.dat`` alone.

Listed in ``not_literal`` (line, what, why), never changed: relative moves (``PTP_REL``, ``LIN_REL``,
…: an offset from wherever the robot is at run time); moves to the current position (``$POS_ACT``,
``$AXIS_ACT``, ``$AXIS_ACT_MEAS``, any ``$`` variable); moves to a variable with no single literal in
the file (declared in another file, filled or changed at run time: ``robopos.X = start.X + dx``,
assigned more than once); frame products ``{…}:{…}`` and calls; partial literals (``{A1 10}``: the
axes not written keep their run-time values); and every other position-shaped literal that is no
target: FRAMEs no move uses, controller settings (``$stiffness.maxforce = {X 300.0, …}``, ``$TOOL =
{…}``), positions inside other data (``JPos_log[1]={cmdIdx 71, cmdPos {A1 …}}``, a log: no move goes
to it as a literal).

Conventions: X, Y, Z in mm, A, B, C in degrees with R = Rz(A)·Ry(B)·Rx(C); A1..A6 in degrees.
``values`` are SI: a pose is [x, y, z (m), rotation vector (rad)], joints [A1..A6] (rad). ``fields``
are X, Y, Z, A, B, C or A1..A6 (in that order); S, T and E1..E6 stay byte for byte; ``config`` is
(S, T) as ints (``'B010'`` read as binary), () when neither is written.
"""
from __future__ import annotations

import bisect
import dataclasses
import functools
import os
import re
from typing import Mapping, Sequence

import numpy as np

from ..errors import MeasurementError
from ..models.transforms import rot_zyx, rotation_log, rotvec_matrix
from . import flow, krl_flow
from .programs import Dialect, Program, Target, controller_angles, old_numbers, used_otherwise, write_fields
from .krl_scan import (AXIS_KEYS, EXTERNAL, POSE_KEYS, _Aggregate, _aggregate, _blank, _check_brackets, _check_numbers,
                       _fail, _integer)

POINT_TYPES = ("E6POS", "POS", "E6AXIS", "AXIS", "FRAME")
MOVE = re.compile(r"^[ \t]*(PTP_REL|LIN_REL|CIRC_REL|SPTP_REL|SLIN_REL|SCIRC_REL|PTP|LIN|CIRC|SPTP|SLIN|SCIRC|SPL)"
                  r"(?![\w$])", re.M | re.I)
DECLARE = re.compile(r"^[ \t]*(?:GLOBAL[ \t]+)?(?:DECL[ \t]+)?(?:GLOBAL[ \t]+)?(E6POS|POS|E6AXIS|AXIS|FRAME)[ \t]+"
                     r"([A-Za-z_]\w*(?:[ \t]*\[[^\]\n]*\])?(?:[ \t]*,[ \t]*[A-Za-z_]\w*(?:[ \t]*\[[^\]\n]*\])?)*)",
                     re.M | re.I)
ASSIGN = re.compile(r"^[ \t]*(?:(?:GLOBAL|DECL)[ \t]+)*(?:[A-Za-z_]\w*[ \t]+)?(\$?[A-Za-z_]\w*)[ \t]*(\[[^\]\n]*\])?"
                    r"((?:[ \t]*\.[ \t]*\w+)*)[ \t]*=(?!=)[ \t]*", re.M | re.I)
OPERAND = re.compile(r"\$?[A-Za-z_]\w*(?:[ \t]*\[[^\]\n]*\])?(?:[ \t]*\.[ \t]*\w+)*")
FDAT = re.compile(r"^[ \t]*(?:GLOBAL[ \t]+)?DECL[ \t]+(?:GLOBAL[ \t]+)?FDAT[ \t]+([A-Za-z_]\w*)[ \t]*=[ \t]*\{",
                  re.M | re.I)
RUN_TIME = "the robot's position when the move starts, read at run time"


def _target(text: str, agg: _Aggregate, move: str, at: int, variable: str, frames: tuple[str, str],
            line: int) -> Target:
    """The Target of a complete position aggregate (checked already) on ``line``, its values as written (mm,
    deg: :func:`_in_si` converts them all at once)."""
    parts = agg.parts
    fields = tuple([parts[k] for k in (POSE_KEYS if agg.shape == "pose" else AXIS_KEYS)])
    values = np.array([float(text[a:b]) for a, b in fields])
    config: tuple = ()
    if "S" in parts or "T" in parts:
        config = tuple([_integer(text[parts[k][0]:parts[k][1]]) if k in parts else None for k in ("S", "T")])
    return Target(agg.start, agg.end, line, move, agg.shape, values, at, variable, fields, config, frames)


def _in_si(targets: list[Target]) -> list[Target]:
    """The targets with their values as written (X, Y, Z mm, A, B, C deg; A1..A6 deg) turned into SI in place
    (the arrays are this reader's own until it returns them): a pose as x, y, z (m) and a rotation vector (rad)
    of Rz(A)·Ry(B)·Rx(C), joints in rad; all at once."""
    poses = [t for t in targets if t.kind == "pose"]
    for t in targets:
        if t.kind != "pose":
            t.values[:] = np.radians(t.values)
    if poses:
        raw = np.array([t.values for t in poses])
        a, b, c = np.radians(raw[:, 3:6]).T
        rot = rotation_log(np.moveaxis(rot_zyx(a, b, c), -1, 0))
        for t, xyz, r in zip(poses, raw[:, :3] * 1e-3, rot):
            t.values[:3], t.values[3:] = xyz, r
    return targets


def _operand(code: str, i: int, ends: dict[int, int]) -> int:
    """The end of one operand (an aggregate, a name with index/components, a call) from ``i``."""
    if code[i:i + 1] == "{":
        return ends[i]
    m = OPERAND.match(code, i)
    if not m:
        return i
    j = m.end()
    k = len(code[j:]) - len(code[j:].lstrip(" \t"))
    if code[j + k:j + k + 1] == "(":
        depth = 0
        for j in range(j + k, len(code)):
            depth += {"(": 1, ")": -1}.get(code[j], 0)
            if depth == 0 or code[j] == "\n":
                return j + 1
    return j


def _move_arguments(source: str, text: str, code: str, ends: dict[int, int], m: re.Match) -> list[tuple[int, int]]:
    """Spans of the target arguments of the move ``m`` (two for CIRC/SCIRC), with frame products ':'."""
    count = 2 if m.group(1).upper() in ("CIRC", "SCIRC", "CIRC_REL", "SCIRC_REL") else 1
    spans, i = [], m.end()
    for n in range(count):
        while code[i:i + 1] in (" ", "\t"):
            i += 1
        a, j = i, _operand(code, i, ends)
        if j == a:
            raise _fail(source, text, a, f"{m.group(1)} without its {'auxiliary point' if n < count - 1 else 'target'}")
        while True:  # frame products a:b:c
            k = j + len(code[j:]) - len(code[j:].lstrip(" \t"))
            if code[k:k + 1] != ":":
                break
            k += 1 + len(code[k + 1:]) - len(code[k + 1:].lstrip(" \t"))
            j = _operand(code, k, ends)
        spans.append((a, j))
        i = j + len(code[j:]) - len(code[j:].lstrip(" \t"))
        if n < count - 1:
            if code[i:i + 1] != ",":
                raise _fail(source, text, i, f"{m.group(1)} needs an auxiliary point and a target, separated by ','")
            i += 1
    return spans


def _key(name: str) -> str:
    """A variable's name as KRL compares it: upper case, no blanks."""
    return "".join(name.split()).upper()


def _declared(code: str) -> dict[str, str]:
    """Point variables declared in the file: NAME -> type (E6POS, POS, E6AXIS, AXIS, FRAME)."""
    out = {}
    for m in DECLARE.finditer(code):
        for name in re.findall(r"[A-Za-z_]\w*(?=[ \t]*(?:\[[^\]\n]*\])?[ \t]*(?:,|$))", m.group(2)):
            out[name.upper()] = m.group(1).upper()
    return out


def _assignments(code: str, ends: dict[int, int]) -> list[tuple[str, str, int, int, str]]:
    """Every assignment: (variable as compared, e.g. "XP[1]", the component set ('' for the whole
    variable), where its statement starts, the start of its '{' literal or -1 for any other value, the
    variable as written)."""
    out = []
    for m in ASSIGN.finditer(code):
        name, index, part = m.group(1, 2, 3)
        shown = "".join((name + (index or "")).split())
        var, part = shown.upper(), _key(part) if part else ""
        literal = m.end() if code[m.end():m.end() + 1] == "{" else -1
        if literal >= 0:
            line_end = code.find("\n", ends[literal])
            after = code[ends[literal]:line_end if line_end >= 0 else len(code)]
            literal = literal if after.strip() == "" else -1  # {…}:{…}, {…} + …: computed
        out.append((var, part, m.start(1), literal, shown))
    return out


@dataclasses.dataclass
class _File:
    """One file being read: its text, the blanked code, its aggregates and assignments, and what the
    passes found (targets, listed items, aggregates used, the first move to each variable)."""

    source: str
    text: str
    code: str
    ends: dict[int, int]
    aggs: dict[int, _Aggregate]
    declared: dict[str, str]
    assigns: list[tuple[str, str, int, int, str]]
    module: "_Module | None" = None  # what the module's .src (beside a .dat) does with its variables
    targets: list[Target] = dataclasses.field(default_factory=list)
    listed: list[tuple[int, str, str]] = dataclasses.field(default_factory=list)
    used: set[int] = dataclasses.field(default_factory=set)
    first_move: dict[str, tuple[str, int]] = dataclasses.field(default_factory=dict)
    moves_to: dict[str, list[int]] = dataclasses.field(default_factory=dict)  # each move to a variable, where
    unknown: dict[int, str] = dataclasses.field(default_factory=dict)  # a target's start -> why its frames are not
    # known: its moves' paths leave different $TOOL or $BASE values

    @functools.cached_property
    def _breaks(self) -> list[int]:
        """Where each line break is (a line is found by bisection: a long .dat is read in linear time)."""
        return [m.start() for m in re.finditer("\n", self.text)]

    @functools.cached_property
    def _fdat(self) -> dict[str, tuple[str, str]]:
        """Each FDAT declared in the file -> its (tool, base) (:func:`_fdats`)."""
        return _fdats(self.text, self.code, self.aggs)

    @functools.cached_property
    def _module_fdat(self) -> dict[str, tuple[str, str]] | str:
        """For a ``.src``: the FDATs of its module's ``.dat`` (:func:`_fdats`; {} without one), or why they cannot
        be read."""
        path = _module_data(self.source)
        if path is None:
            return {}
        try:
            with open(path, "rb") as fh:
                text = fh.read().decode("latin-1")  # names and numbers are ASCII; comments may be anything
            code = _blank(text)
            ends = _check_brackets(path, text, code)
            return _fdats(text, code, {m.end() - 1: _aggregate(path, text, code, ends, m.end() - 1)
                                       for m in FDAT.finditer(code)})
        except (OSError, MeasurementError) as exc:
            return f"its module's {os.path.basename(path)} cannot be read ({exc})"

    def fdat(self, name: str) -> tuple[str, str] | str:
        """The (tool, base) of the FDAT named ``name`` as written (an FDAT literal's own), from this file or its
        module's ``.dat``, or why it is not known."""
        literal = re.fullmatch(r"\{([^{}]*)\}", name.strip())
        if literal:
            got = [re.search(rf"(?<!\w){k}[ \t]+([^,\s]+)", literal.group(1), re.I) for k in ("TOOL_NO", "BASE_NO")]
            return (f"TOOL_NO {got[0].group(1)}" if got[0] else "", f"BASE_NO {got[1].group(1)}" if got[1] else "")
        other = self._module_fdat
        found = {**(other if isinstance(other, dict) else {}), **self._fdat}.get(_key(name))
        if found is not None:
            return found
        if isinstance(other, str):
            return other
        where = _module_data(self.source)
        return f"which no DECL FDAT of this file{' or of ' + os.path.basename(where) if where else ''} declares"

    @functools.cached_property
    def _nodes(self) -> list[tuple[int, object]]:
        """Each statement setting $TOOL, $BASE or FDAT_ACT, as flow nodes by position (:func:`kincal.io.krl_flow.nodes`)."""
        return krl_flow.nodes(self.code, self.text, self.line, self.fdat)

    def line(self, at: int) -> int:
        return bisect.bisect_left(self._breaks, at) + 1

    def note(self, at: int, what: str, why: str) -> None:
        self.listed.append((self.line(at), " ".join(what.split()), why))

    @functools.cached_property
    def bound(self) -> dict[str, int]:
        """Variables (not $ system variables) assigned exactly once in the file, whole, with a literal:
        name (with index) -> the literal's '{'."""
        count: dict[str, list[int]] = {}
        for var, part, _, literal, _ in self.assigns:
            count.setdefault(var, []).append(literal if not part else -1)
        return {v: s[0] for v, s in count.items()
                if len(s) == 1 and s[0] >= 0 and not v.startswith("$") and not self.elsewhere(v)}

    def elsewhere(self, var: str) -> str:
        """Where the module's ``.src`` assigns the variable ``var`` (compared upper case), in words, or ''."""
        if self.module is None:
            return ""
        line = self.module.assigned.get(var) or self.module.assigned.get(var.split("[")[0])
        return f"{self.module.name} line {line}" if line else ""

    def unmoved(self, var: str) -> bool:
        """Whether ``var`` is local to a module whose ``.src`` moves to it nowhere (False without a module)."""
        name = var.split("[")[0]
        return self.module is not None and name not in self.module.moved and name not in self.globals

    @functools.cached_property
    def globals(self) -> frozenset[str]:
        """The point variables (upper case) the file declares GLOBAL: other modules see them."""
        return frozenset(name.upper() for m in DECLARE.finditer(self.code) if "GLOBAL" in m.group(0).upper()
                         for name in re.findall(r"[A-Za-z_]\w*", re.sub(r"\[[^\]]*\]", "", m.group(2))))

    def frames(self, ats: list[int], variable: str, start: int) -> tuple[str, str]:
        """(tool, base) of the target at ``start`` whose moves are at ``ats``: the FDAT F<name> of a point X<name>,
        else, for a ``.dat`` point its module's ``.src`` moves to, the $TOOL and $BASE in force at those moves
        (:meth:`_Module.frames`), else the $TOOL and $BASE the module's flow leaves in force at every one of them
        ('' for none set; :mod:`kincal.io.krl_flow`); where its paths leave different ones, '' and why in
        ``unknown``."""
        name = variable.split("[")[0].upper()
        if name[:1] == "X" and "F" + name[1:] in self._fdat:
            return self._fdat["F" + name[1:]]
        moved = self.module.frames(_key(variable)) if self.module is not None and variable else None
        tool, base, why = moved if moved is not None else self.in_force(ats)
        if why:
            self.unknown[start] = why
        return tool, base

    def in_force(self, ats: list[int]) -> tuple[str, str, str]:
        """The $TOOL and $BASE this module's flow leaves in force at every one of the moves at ``ats`` ('' for none
        set) and why one is not known ('' where both are)."""
        reached = self._reached
        if not isinstance(reached, dict):
            return "", "", reached or ""
        out, why = [], []
        for slot, what in ((0, "$TOOL"), (1, "$BASE")):
            possible = frozenset().union(*(reached.get(at, (frozenset(), frozenset()))[slot] for at in ats))
            one = flow.in_force(possible)
            one = None if one is None or isinstance(one.value, krl_flow.Unknown) else one
            out.append("" if one is None else str(one.value))
            why += [] if one is not None else [_ambiguous(what, possible, len(ats) > 1)]
        return out[0], out[1], "; ".join(why)

    @functools.cached_property
    def _reached(self) -> dict | str | None:
        """What may be in force at each move and bound point (:func:`kincal.io.krl_flow.reach`), None for a module
        that sets no $TOOL or $BASE, or why its structure cannot be read."""
        if not any(isinstance(n, flow.Derive) or (isinstance(n, flow.Set) and n.slot < 2) for _, n in self._nodes):
            return None
        moves = [m.start() for m in MOVE.finditer(self.code)] + list(self.bound.values())
        try:
            return krl_flow.reach(self.code, self._nodes, moves)
        except krl_flow.Broken as exc:
            return (f"the $TOOL and $BASE in force cannot be read from the module's structure: line "
                    f"{self.line(exc.args[0])}: {exc.args[1]}")


def _fdats(text: str, code: str, aggs: Mapping[int, _Aggregate]) -> dict[str, tuple[str, str]]:
    """Each ``DECL FDAT`` of a file (its text, blanked code and aggregates by their '{') -> its (tool, base) as
    written ("TOOL_NO 1", "BASE_NO 2"; '' where it names none), by upper-case name; the first of a name."""
    out: dict[str, tuple[str, str]] = {}
    for m in FDAT.finditer(code):
        parts = aggs[m.end() - 1].parts
        got = [f"{k} {text[slice(*parts[k])]}" if k in parts else "" for k in ("TOOL_NO", "BASE_NO")]
        out.setdefault(m.group(1).upper(), (got[0], got[1]))
    return out


def _ambiguous(what: str, possible: frozenset, shared: bool = False) -> str:
    """Why the ``what`` ($TOOL or $BASE) in force at a target is not known: the lines whose values may be (at the
    moves to it, ``shared``: a point moved to more than once)."""
    if not possible:
        return f"no path of the module reaches this move, so no {what} is known for it"
    unknown = [why for _, why in sorted({(s.line, s.value.why) for s in possible
                                         if isinstance(s.value, krl_flow.Unknown)})]
    example = "BAS(#TOOL,2) or $TOOL = TOOL_DATA[2]" if what == "$TOOL" else "BAS(#BASE,1) or $BASE = BASE_DATA[1]"
    if unknown and len({s.key for s in possible}) == 1:
        return (f"its {what} is known only at run time: {unknown[0]}; give it with its number written out ({example}) "
                f"on every path before this move")
    lines = sorted({s.line for s in possible if s.line != flow.START})
    return (f"its {what} is not known from the module's structure: the {what} assignment"
            f"{'s' * (len(lines) > 1)} on line{'s' * (len(lines) > 1)} {', '.join(map(str, lines))}"
            + (f" or the {what} in force before any" if any(s.line == flow.START for s in possible) else "")
            + (f" may be in force at the moves to it, one literal for each; give each its own point, after a {what} "
               f"assignment that every path to it runs" if shared else
               f" may be in force here, as a branch, loop or call decides at run time; give it one: a {what} "
               f"assignment that every path runs before this move")
            + (f" ({'; '.join(unknown)}: known only at run time)" if unknown else ""))


def _variable_reason(f: _File, var: str, shown: str) -> str:
    """Why a move to the variable ``var`` (compared upper case; ``shown`` as written) with no single
    literal in the file is not compensated."""
    if var.startswith("$"):
        if re.match(r"\$(POS|AXIS)_", var):
            return f"{shown} is {RUN_TIME}"
        return f"{shown} is a system variable, set by the controller at run time"
    if any(a[0] == var for a in f.assigns):
        return f"{shown} is filled or changed at run time in this file (not one literal)"
    if var.split("[")[0] in f.declared:
        return f"{shown} has no literal in this file: it is filled at run time"
    return (f"{shown} is not declared in this file: its literal (and its FDAT) are where it is declared, "
            "e.g. the module's .dat, and are compensated there")


def _moves(f: _File) -> None:
    """Each move's targets: inline literals become targets; everything else is listed."""
    bound = f.bound
    for m in MOVE.finditer(f.code):
        move = m.group(1).upper()
        for a, b in _move_arguments(f.source, f.text, f.code, f.ends, m):
            arg = f.code[a:b]
            inside = [s for s in f.aggs if a <= s < b]
            f.used.update(inside)
            if move.endswith("_REL"):
                f.note(a, f"{move} {arg}", f"a relative move: an offset from {RUN_TIME}")
            elif arg.startswith("{") and f.ends[a] == b:
                _inline(f, f.aggs[a], move, m.start())
            elif inside or "(" in arg or ":" in arg:
                f.note(a, f"{move} {arg}", "a target computed at run time (a frame product ':' or a call)")
            elif _key(arg) in bound:
                f.first_move.setdefault(_key(arg), (move, m.start()))
                f.moves_to.setdefault(_key(arg), []).append(m.start())
            else:
                f.note(a, f"{move} {arg}", _variable_reason(f, _key(arg), "".join(arg.split())))


def _inline(f: _File, agg: _Aggregate, move: str, at: int) -> None:
    """A literal written in a move: a target, or listed when partial; not a position: an error."""
    if not agg.shape:
        raise _fail(f.source, f.text, agg.start, f"the {move} target is not a position (components "
                    f"{', '.join(agg.parts) or 'none'}; a position has X, Y, Z, A, B, C or A1..A6)")
    if agg.missing:
        f.note(agg.start, f"{move} {f.text[agg.start:agg.end]}", _partial(agg))
        return
    f.targets.append(_target(f.text, agg, move, at, "", f.frames([at], "", agg.start), f.line(agg.start)))


def _partial(agg: _Aggregate) -> str:
    return (f"a partial target: {', '.join(agg.missing)} not written, so the controller keeps their values "
            "at run time")


def _points(f: _File) -> None:
    """Variables given one literal: targets (point types, FRAMEs a move uses), else listed."""
    names = {literal: name for *_, literal, name in f.assigns}
    for var, a in f.bound.items():
        agg, shown = f.aggs[a], names[a]
        kind = f.declared.get(var.split("[")[0]) or agg.typed
        if not agg.shape:
            if kind in POINT_TYPES:
                raise _fail(f.source, f.text, a, f"{shown} ({kind}) is not given a position (components "
                            f"{', '.join(agg.parts) or 'none'})")
            continue
        if kind in POINT_TYPES and (kind in ("E6AXIS", "AXIS")) != (agg.shape == "joints"):
            raise _fail(f.source, f.text, a, f"{shown} is {kind} but is given {', '.join(agg.parts)}")
        f.used.add(a)
        move, at = f.first_move.get(var, ("", -1))
        if kind and kind not in POINT_TYPES:
            f.note(a, shown, f"a position-like value of type {kind}, not a move target")
        elif kind == "FRAME" and not move:
            f.note(a, shown, "a FRAME (tool or base data), not a move target: no move of this file goes to it")
        elif agg.missing:
            f.note(a, shown, _partial(agg))
        elif f.unmoved(var):
            f.note(a, shown, used_otherwise(f"no move of its module ({f.module.name if f.module else ''}) goes to "
                                            f"it, and it is not GLOBAL"))
        else:
            kind = kind or ("E6" if set(agg.parts) & set(EXTERNAL) else "") + ("POS" if agg.shape == "pose" else "AXIS")
            f.targets.append(_target(f.text, agg, move or kind, at if move else a, shown,
                                     f.frames(f.moves_to.get(var) or [a], var, a),
                                     f.line(agg.start)))


def _leftovers(f: _File) -> None:
    """Every position-shaped literal that is no target and not listed yet, listed with why."""
    nested = {s for agg in f.aggs.values() for s in agg.nested}
    by_literal = {literal: (var, part, name) for var, part, _, literal, name in f.assigns if literal >= 0}
    counts: dict[str, int] = {}
    for var, *_ in f.assigns:
        counts[var] = counts.get(var, 0) + 1
    for a, agg in sorted(f.aggs.items()):
        if not agg.shape or a in f.used:
            continue
        what, why = f.text[a:agg.end], "a position that no move of this file goes to"
        if a in nested:
            why = "a position inside other data (a structure field, e.g. a log): no move goes to it as a literal"
        elif a in by_literal:
            var, part, name = by_literal[a]
            what = name + part
            if var.startswith("$") or part:
                why = f"sets {name}{part}: a controller setting or frame, not a move target"
            elif f.elsewhere(var):
                why = (f"{name} is filled or changed at run time by its module ({f.elsewhere(var)}): not one "
                       f"literal")
            elif counts[var] > 1:
                why = f"{name} is assigned more than once or changed in this file: not one literal"
        f.note(a, what, why)


@dataclasses.dataclass(frozen=True)
class _Module:
    """What the ``.src`` of a ``.dat``'s module (beside it, the same name) does with the ``.dat``'s variables."""

    name: str  # the .src's file name
    assigned: dict[str, int]  # each variable it assigns, whole or in part, as compared ("XP[1]"; the bare name for
    # an index computed at run time) -> the line of the first
    moved: frozenset[str]  # the names (upper case) its moves' lines hold
    moves: dict[str, list[int]] | str  # each variable its moves go to, as compared ("XP[3]"; "XP[]" for an index
    # computed at run time) -> where those moves are; or why its moves cannot be read
    src: "_File | None" = None  # the .src, read for the $TOOL and $BASE its flow leaves in force

    def frames(self, var: str) -> tuple[str, str, str] | None:
        """The (tool, base) in force at every move of the ``.src`` to the ``.dat``'s variable ``var`` (as compared;
        an element also at the moves to the array's element an index computed at run time picks) and why one is not
        known, naming the moves' lines ('' where both are); None where no move of the ``.src`` goes to it."""
        name = var.split("[")[0]
        if isinstance(self.moves, str) or self.src is None:
            return ("", "", f"at the moves to it in {self.name}: {self.moves}") if name in self.moved else None
        ats = sorted(set(self.moves.get(var, []) + (self.moves.get(name + "[]", []) if "[" in var else [])))
        if not ats:
            return None
        tool, base, why = self.src.in_force(ats)
        lines = ", ".join(str(n) for n in sorted({self.src.line(at) for at in ats}))
        return tool, base, why and f"at the moves to it in {self.name} (line{'s' * (len(ats) > 1)} {lines}): {why}"


def _module_source(source: str) -> str | None:
    """For a ``.dat``: the path of its module's ``.src`` (the same name beside it, in KUKA's cases); None for any
    other file or a ``.dat`` without one."""
    folder, name = os.path.split(source)
    stem, suffix = os.path.splitext(name)
    if suffix.lower() != ".dat":
        return None
    return next((p for p in (os.path.join(folder, stem + s) for s in (".src", ".SRC", ".Src")) if os.path.isfile(p)),
                None)


def _module_data(source: str) -> str | None:
    """For a ``.src`` or ``.sub``: the path of its module's ``.dat`` (the same name beside it, in KUKA's cases); None
    for a ``.dat`` or a module without one."""
    folder, name = os.path.split(source)
    stem, suffix = os.path.splitext(name)
    if suffix.lower() not in (".src", ".sub"):
        return None
    return next((p for p in (os.path.join(folder, stem + s) for s in (".dat", ".DAT", ".Dat")) if os.path.isfile(p)),
                None)


def _module(source: str) -> _Module | None:
    """For a ``.dat``: its module's ``.src``, as :class:`_Module`; None for any other file or a ``.dat`` without one."""
    path = _module_source(source)
    if path is None:
        return None
    try:
        with open(path, "rb") as fh:
            text = fh.read().decode("latin-1")  # names are ASCII; comments may be anything
    except OSError:
        return None
    code = _blank(text)
    assigned: dict[str, int] = {}
    for m in ASSIGN.finditer(code):
        index = "".join((m.group(2) or "").split())
        var = m.group(1).upper() + (index if index[1:-1].isdigit() else "")
        assigned.setdefault(var, code.count("\n", 0, m.start()) + 1)
    ends = [(m.end(), code.find("\n", m.end())) for m in MOVE.finditer(code)]  # each move's line after its word
    moved = {n.upper() for a, b in ends for n in re.findall(r"[A-Za-z_]\w*", code[a:b if b >= 0 else None])}
    try:
        src, moves = _source_moves(path, text, code)
    except MeasurementError as exc:
        return _Module(os.path.basename(path), assigned, frozenset(moved), f"its moves cannot be read ({exc})")
    return _Module(os.path.basename(path), assigned, frozenset(moved), moves, src)


def _source_moves(path: str, text: str, code: str) -> tuple[_File, dict[str, list[int]]]:
    """A module's ``.src`` (its path, text and blanked code) as a :class:`_File`, read as far as its flow needs, and
    each variable its moves go to -> where those moves are (:attr:`_Module.moves`)."""
    ends = _check_brackets(path, text, code)
    aggs = {a: _aggregate(path, text, code, ends, a) for a in sorted(ends) if code[a] == "{"}
    moves: dict[str, list[int]] = {}
    for m in MOVE.finditer(code):
        for a, b in _move_arguments(path, text, code, ends, m):
            arg = _key(code[a:b])
            if re.fullmatch(r"[A-Z_]\w*(\[[\d,]+\])?", arg):
                moves.setdefault(arg, []).append(m.start())
            elif re.fullmatch(r"[A-Z_]\w*\[[^\]]*\]", arg):
                moves.setdefault(arg.split("[")[0] + "[]", []).append(m.start())
    return _File(path, text, code, ends, aggs, _declared(code), _assignments(code, ends)), moves


def parse(source: str, text: str) -> Program:
    """The literal targets (text order) and the listed moves and positions of one KRL file."""
    code = _blank(text)
    ends = _check_brackets(source, text, code)
    aggs = {a: _aggregate(source, text, code, ends, a) for a in sorted(ends) if code[a] == "{"}
    for agg in aggs.values():
        if agg.shape:
            _check_numbers(source, text, agg)
    f = _File(source, text, code, ends, aggs, _declared(code), _assignments(code, ends), _module(source))
    _moves(f)
    _points(f)
    _leftovers(f)
    targets = _in_si(sorted(f.targets, key=lambda t: t.start))
    return Program(source, text, tuple(targets), tuple(sorted(f.listed, key=lambda x: x[0])),
                   in_force=tuple(sorted(f.unknown.items())))


def _fields(text: str, targets: Sequence[Target], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fields of targets of one kind for new SI values (G, V): X, Y, Z (mm, to 1e-7), A, B, C (deg, to
    1e-8; the triple nearest the old numbers, in KUKA's ranges: A and C in [-180, 180], B in [-90, 90]) or
    A1..A6 (deg, to 1e-8)."""
    if targets[0].kind != "pose":
        return np.degrees(values), np.full(values.shape[1], 1e-8)
    angles = controller_angles(rotvec_matrix(values[:, 3:6]), old_numbers(text, targets, slice(3, 6)), middle=90.0)
    return np.concatenate([values[:, :3] * 1e3, angles], axis=1), np.array([1e-7] * 3 + [1e-8] * 3)


def write(text: str, targets: Sequence[Target], values: Sequence[np.ndarray]) -> list[str]:
    """The targets' spans for new SI values, each number in its old style (:func:`_fields`); every other
    byte (S, T, E1..E6) as it is."""
    return write_fields(text, targets, values, _fields)


def _frames(program: Program) -> dict[str, np.ndarray | str]:
    """The tools and bases of the controller's $config.dat beside the program (:mod:`kincal.io.krl_config`)."""
    from .krl_config import program_frames

    return program_frames(program)


SPELLED = re.compile(r"(TOOL|BASE)(?:_DATA[ \t]*\[[ \t]*(\d+)[ \t]*\]|_NO[ \t]+(\d+))", re.I)  # a tool or base by number


def spellings(frames: Mapping[str, object]) -> dict[str, object]:
    """The frames by name with each tool and base also under KRL's other name of it: ``TOOL_DATA[n]`` (a ``$TOOL``
    assignment's) and ``TOOL_NO n`` (an FDAT's) are one tool, ``BASE_DATA[n]`` and ``BASE_NO n`` one base; a name
    the mapping has in any case is kept as it is.

    Raises
    ------
    ValueError
        When two names of one tool or base carry different values (the controller holds one of them).

    Examples
    --------
    >>> import numpy as np
    >>> tool, base = np.eye(4), np.diag([1.0, -1.0, -1.0, 1.0])
    >>> sorted(spellings({"TOOL_NO 1": tool, "base_data[2]": base, "BASE_NO 2": base, "$NULLFRAME": tool}))
    ['$NULLFRAME', 'BASE_NO 2', 'TOOL_DATA[1]', 'TOOL_NO 1', 'base_data[2]']
    >>> spellings({"TOOL_NO 1": tool, "TOOL_DATA[1]": base})
    Traceback (most recent call last):
    ...
    ValueError: the frames give 'TOOL_NO 1' and 'TOOL_DATA[1]', KRL's two names of tool 1, different values: ...
    """
    out = dict(frames)
    named = {k.lower() for k in frames}
    seen: dict[tuple[str, int], str] = {}
    for name, value in frames.items():
        m = SPELLED.fullmatch(name.strip())
        if m:
            kind, n = m.group(1).upper(), int(m.group(2) or m.group(3))
            other = seen.setdefault((kind, n), name)
            if not _same_frame(frames[other], value):
                raise ValueError(f"the frames give {other!r} and {name!r}, KRL's two names of {kind.lower()} {n}, "
                                 f"different values: the controller holds one {kind.lower()} {n}; give it once")
            out.update({o: value for o in (f"{kind}_DATA[{n}]", f"{kind}_NO {n}") if o.lower() not in named})
    return out


def _same_frame(a: object, b: object) -> bool:
    """Whether two frames' values are the same: poses (4, 4) equal to the last bit, anything else the same object."""
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    return a is b


def _beside(source: str) -> tuple[str, ...]:
    """The files reading the program at ``source`` reads besides it: a ``.dat``'s module ``.src``
    (:func:`_module_source`), a ``.src``'s module ``.dat`` (:func:`_module_data`: its FDATs) and the controller's ``$config.dat`` and ``$machine.dat``
    (:func:`kincal.io.krl_config.sibling`), those that exist."""
    from .krl_config import sibling

    found = (_module_source(source), _module_data(source), sibling(source, "$config.dat"),
             sibling(source, "$machine.dat"))
    return tuple(p for p in found if p is not None)


DIALECT = Dialect("krl", (".src", ".dat", ".sub"), ";", parse, write, _frames, beside=_beside, spellings=spellings)
