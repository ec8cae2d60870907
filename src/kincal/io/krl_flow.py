"""A KRL module's structure as :mod:`kincal.io.flow` nodes, behind :mod:`kincal.io.program_krl`: which ``$TOOL`` and
``$BASE`` may be in force at each move, by its routines (``DEF``/``DEFFCT``, called by name), branches
(``IF``/``ELSE``, ``SWITCH``/``CASE``/``DEFAULT``), loops (``FOR``, ``WHILE``, ``LOOP``, ``REPEAT``/``UNTIL``) and
jumps (``EXIT``, ``RETURN``); a routine an ``INTERRUPT DECL`` or ``TRIGGER`` runs may run beside any move. Each
statement is on its own line; names in any case.

What sets them (:func:`nodes`): the assignments ``$TOOL = …`` and ``$BASE = …`` (the value as written), and KUKA's
``BAS`` calls (its BAS.SRC): ``BAS(#TOOL, n)`` sets ``$TOOL = TOOL_DATA[n]`` and ``BAS(#BASE, n)`` ``$BASE =
BASE_DATA[n]`` ($NULLFRAME for 0: the flange, the world); ``BAS(#FRAMES)``, and ``BAS(#PTP_PARAMS, v)`` and
``BAS(#CP_PARAMS, v)`` of the inline forms, set both from the TOOL_NO and BASE_NO of the FDAT that ``FDAT_ACT = F…``
leaves in force. A value known only at run time — ``BAS(#TOOL, n)`` with a variable ``n``, a component changed
(``$TOOL.Z = …``), ``BAS(#FRAMES)`` where FDAT_ACT is not one known FDAT — is :class:`Unknown`, with why."""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import Callable, Sequence

from . import flow

BLOCK = re.compile(r"^[ \t\ufeff]*(?:GLOBAL[ \t]+)?(DEFFCT|DEFDAT|DEF|ENDFCT|ENDDAT|ENDIF|ENDSWITCH|ENDFOR|ENDWHILE|"
                   r"ENDLOOP|END|IF|ELSE|SWITCH|CASE|DEFAULT|FOR|WHILE|LOOP|REPEAT|UNTIL|EXIT|RETURN|GOTO|INTERRUPT|"
                   r"TRIGGER)(?![\w$])", re.M | re.I)
ROUTINE = re.compile(r"^[ \t\ufeff]*(?:GLOBAL[ \t]+)?(?:DEF|DEFFCT[ \t]+\w+)[ \t]+([A-Za-z_]\w*)[ \t]*\(", re.M | re.I)
CALL = re.compile(r"(?<![\w$.#])([A-Za-z_]\w*)[ \t]*\(")
CLOSER = {"DEF": "END", "DEFFCT": "ENDFCT", "DEFDAT": "ENDDAT", "FOR": "ENDFOR", "WHILE": "ENDWHILE",
          "LOOP": "ENDLOOP", "REPEAT": "UNTIL"}
NONE_SET = flow.Setting(flow.START, "", "")  # no $TOOL or $BASE set by the module: '' (the one in force, given)
SLOTS = ("$TOOL", "$BASE", "FDAT_ACT")  # the settings followed, by slot
ASSIGNED = re.compile(r"^[ \t]*(\$TOOL|\$BASE|FDAT_ACT)[ \t]*((?:\.[ \t]*\w+[ \t]*)*)=(?!=)[ \t]*([^\n]*?)[ \t\r]*$",
                      re.M | re.I)
BAS = re.compile(r"^[ \t]*BAS[ \t]*\([ \t]*#(TOOL|BASE|FRAMES|PTP_PARAMS|CP_PARAMS)[ \t]*(?:,[ \t]*([^\n]*?)[ \t]*)?\)"
                 r"[ \t\r]*$", re.M | re.I)
NUMBER = re.compile(r"\+?(\d+)(?:\.0*)?")  # a tool's or base's number written out (BAS takes a REAL)


@dataclass(frozen=True)
class Unknown:
    """A setting's value known only at run time: ``why``, in words with its line."""

    why: str


def _setting(line: int, value: str | Unknown) -> flow.Setting:
    """A Setting on ``line``: a value as written keyed as KRL compares it (upper case, no blanks); an Unknown keyed
    by its why (the same statement, the same key)."""
    key = ("run time", value.why) if isinstance(value, Unknown) else "".join(value.split()).upper()
    return flow.Setting(line, key, value)


def nodes(code: str, text: str, line: Callable[[int], int],
          fdat: Callable[[str], tuple[str, str] | str]) -> list[tuple[int, object]]:
    """Each statement of a module that sets ``$TOOL`` (slot 0), ``$BASE`` (1) or ``FDAT_ACT`` (2), as a
    :mod:`kincal.io.flow` node by its position (module docstring).

    Parameters
    ----------
    code : str
        The module's text, comments and strings blanked.
    text : str
        The module's text as written (the values are taken from it).
    line : callable
        ``line(position) -> int``: the line (from 1) of a position.
    fdat : callable
        ``fdat(name) -> (tool, base) | str``: the TOOL_NO and BASE_NO of the FDAT named as written ("TOOL_NO 1",
        "BASE_NO 2"; '' where it gives none), or why it is not known.

    Returns
    -------
    list of (int, Set or Derive)
        By position, in text order.

    Examples
    --------
    >>> text = "DEF p()\\nBAS (#tool, 2 )\\nBAS(#BASE,n)\\nEND"
    >>> [(n.slot, n.setting.value) for _, n in nodes(text, text, lambda at: text.count(chr(10), 0, at) + 1, dict)]
    [(0, 'TOOL_DATA[2]'), (1, Unknown(why="line 3's BAS(#BASE,n) sets the base numbered by n"))]
    """
    out: list[tuple[int, object]] = []
    for m in ASSIGNED.finditer(code):
        n, value = line(m.start()), text[m.start(3):m.end(3)]
        part = "".join(m.group(2).split())
        made = Unknown(f"line {n}'s {m.group(1)}{part} = {value} changes it") if part else value
        out.append((m.start(), flow.Set(_setting(n, made), SLOTS.index(m.group(1).upper()))))
    for m in BAS.finditer(code):
        n, word, shown = line(m.start()), m.group(1).upper(), text[m.start():m.end()].strip()
        if word in ("TOOL", "BASE"):
            arg = text[m.start(2):m.end(2)] if m.group(2) else ""
            got = _numbered(word, NUMBER.fullmatch("".join(arg.split())),
                            f"line {n}'s {shown} sets the {word.lower()} numbered by {arg or 'nothing'}")
            out.append((m.start(), flow.Set(_setting(n, got), int(word == "BASE"))))
        else:
            out.append((m.start(), flow.Derive(2, (0, 1), functools.partial(_from_fdat, n, shown, fdat))))
    return sorted(out, key=lambda e: e[0])


def _numbered(word: str, number: re.Match | None, why: str) -> str | Unknown:
    """The frame KUKA's BAS.SRC sets for the ``word`` (TOOL or BASE) numbered by the match ``number`` of
    :data:`NUMBER`: TOOL_DATA[n] or BASE_DATA[n], $NULLFRAME for 0 (the flange, the world); without a number,
    Unknown with ``why``."""
    if number is None:
        return Unknown(why)
    return "$NULLFRAME" if int(number.group(1)) == 0 else f"{word}_DATA[{int(number.group(1))}]"


def _from_fdat(line: int, shown: str, fdat: Callable[[str], tuple[str, str] | str],
               source: flow.Setting | None) -> tuple[flow.Setting, flow.Setting]:
    """The $TOOL and $BASE that ``shown`` (BAS(#FRAMES) and the like, on ``line``) sets from the FDAT_ACT in force
    ``source`` (None: not known): TOOL_DATA[TOOL_NO] and BASE_DATA[BASE_NO] ($NULLFRAME for 0), else why not."""
    head = f"line {line}'s {shown} sets it from FDAT_ACT"
    if source is None:
        return (_setting(line, Unknown(f"{head}, not known where its routine runs (an interrupt's, a trigger's, or "
                                       f"one that calls itself)")),) * 2
    if source.line == flow.START:
        return (_setting(line, Unknown(f"{head}, which no line of the module sets before it")),) * 2
    if isinstance(source.value, Unknown):
        return (_setting(line, Unknown(f"{head}, and {source.value.why}")),) * 2
    found = fdat(str(source.value))
    out = []
    for k, word in enumerate(("TOOL", "BASE")):
        given = found if isinstance(found, str) else found[k]
        number = re.fullmatch(rf"{word}_NO[ \t]+{NUMBER.pattern}", given.strip(), re.I)
        out.append(_setting(line, _numbered(word, number, f"{head} = {source.value} (line {source.line}), " + (
            found if isinstance(found, str) else f"whose {word}_NO is not a number written out" if given else
            f"which gives no {word}_NO"))))
    return out[0], out[1]


class Broken(Exception):
    """The module's blocks do not balance, or it jumps (GOTO): (position, what)."""


def reach(code: str, settings: Sequence[tuple[int, object]], moves: Sequence[int]):
    """What may be in force at each move: :func:`kincal.io.flow.reach` of the module in ``code`` (comments and
    strings blanked), by position, slot 0 the tool, 1 the base and 2 FDAT_ACT.

    Parameters
    ----------
    code : str
        The module's text, comments and strings blanked.
    settings : sequence of (int, node)
        Each statement that sets them, as :func:`nodes` gives: (where, its Set or Derive node).
    moves : sequence of int
        Where each move (or point whose frames are asked for) is.

    Returns
    -------
    dict of int to tuple of frozenset
        As :func:`kincal.io.flow.reach`.

    Raises
    ------
    Broken
        When the blocks do not balance or a GOTO jumps: the position and what.
    """
    routines = {m.group(1).upper() for m in ROUTINE.finditer(code)}
    events: list[tuple[int, object]] = [(m.start(1), m.group(1).upper()) for m in BLOCK.finditer(code)]
    events += list(settings)
    events += [(at, flow.Move(at)) for at in moves]
    events += [(m.start(), flow.Call(m.group(1).upper())) for m in CALL.finditer(code)
               if m.group(1).upper() in routines]
    tree = _Tree(code, sorted(events, key=lambda e: e[0])).block(())[0]
    return flow.reach(tree, [NONE_SET] * len(SLOTS))


class _Tree:
    """The nodes of a KRL module from its events (position, keyword or node) in text order."""

    def __init__(self, code: str, events: list[tuple[int, object]]) -> None:
        self.code, self.events, self.i = code, events, 0

    def block(self, stops: tuple[str, ...], opened: tuple[int, str] = (0, "")) -> tuple[list, str, int]:
        """The nodes up to one of the keywords ``stops`` (which, and where) of the block ``opened``."""
        nodes: list = []
        while self.i < len(self.events):
            at, event = self.events[self.i]
            self.i += 1
            if not isinstance(event, str):
                nodes.append(event)
            elif event in stops:
                return nodes, event, at
            elif event in ("EXIT", "RETURN"):
                self.header(at)
                nodes.append(flow.Jump("break" if event == "EXIT" else "return"))
            elif event in ("INTERRUPT", "TRIGGER"):  # the routine it runs runs beside the moves
                nodes += [flow.Start(n.name) if isinstance(n, flow.Call) else n for n in self.header(at)]
            elif event == "GOTO":
                raise Broken(at, "a GOTO jumps")
            elif event in ("IF", "SWITCH") or event in CLOSER:
                nodes += self.opened(event, at)
            elif stops:
                raise Broken(opened[0], f"this {opened[1]} is not closed with {stops[-1]} before the {event} of "
                                        f"line {self.code.count(chr(10), 0, at) + 1}")
            else:
                raise Broken(at, f"{event} with no block open before it")
        if stops:
            raise Broken(opened[0], f"this {opened[1]} is never closed with {stops[-1]}")
        return nodes, "", len(self.code)

    def opened(self, word: str, at: int) -> list:
        """The nodes of the block opened by ``word`` at ``at``, through its closing keyword."""
        head = self.header(at)
        if word in ("DEF", "DEFFCT"):
            name = ROUTINE.match(self.code, self.code.rfind("\n", 0, at) + 1)
            routine = self.block((CLOSER[word],), (at, word))[0]
            return [flow.Define(name.group(1).upper(), tuple(routine))] if name else routine
        if word == "DEFDAT":
            return self.block(("ENDDAT",), (at, word))[0]
        if word == "REPEAT":
            repeated, _, until = self.block(("UNTIL",), (at, word))
            return [flow.Loop((), tuple(repeated + self.header(until)), "tail")]
        if word in ("FOR", "WHILE", "LOOP"):
            return [flow.Loop(tuple(head), tuple(self.block((CLOSER[word],), (at, word))[0]),
                              "none" if word == "LOOP" else "head")]
        if word == "IF":
            body, stop, _ = self.block(("ELSE", "ENDIF"), (at, word))
            other = self.block(("ENDIF",), (at, word))[0] if stop == "ELSE" else None
            return head + [flow.Branch((tuple(body),) if other is None else (tuple(body), tuple(other)),
                                       complete=other is not None)]
        return head + [self.cases(at)]

    def cases(self, at: int) -> flow.Branch:
        """The CASE and DEFAULT bodies of a SWITCH at ``at``, through its ENDSWITCH."""
        _, stop, where = self.block(("CASE", "DEFAULT", "ENDSWITCH"), (at, "SWITCH"))
        bodies, complete = [], False
        while stop != "ENDSWITCH":
            complete = complete or stop == "DEFAULT"
            self.header(where)
            body, stop, where = self.block(("CASE", "DEFAULT", "ENDSWITCH"), (at, "SWITCH"))
            bodies.append(tuple(body))
        return flow.Branch(tuple(bodies), complete)

    def header(self, at: int) -> list:
        """The nodes on the rest of the line of the keyword at ``at`` (calls in its condition)."""
        end = self.code.find("\n", at)
        end = len(self.code) if end < 0 else end
        nodes = []
        while self.i < len(self.events) and self.events[self.i][0] < end:
            if isinstance(self.events[self.i][1], str):
                raise Broken(self.events[self.i][0], f"{self.events[self.i][1]} on the line of another statement")
            nodes.append(self.events[self.i][1])
            self.i += 1
        return nodes
