"""A KRL module's structure as :mod:`kincal.io.flow` nodes, behind :mod:`kincal.io.program_krl`: which ``$TOOL`` and
``$BASE`` assignment may be in force at each move, by its routines (``DEF``/``DEFFCT``, called by name), branches
(``IF``/``ELSE``, ``SWITCH``/``CASE``/``DEFAULT``), loops (``FOR``, ``WHILE``, ``LOOP``, ``REPEAT``/``UNTIL``) and
jumps (``EXIT``, ``RETURN``); a routine an ``INTERRUPT DECL`` or ``TRIGGER`` runs may run beside any move. Each
statement is on its own line; names in any case."""
from __future__ import annotations

import re
from typing import Sequence

from . import flow

BLOCK = re.compile(r"^[ \t\ufeff]*(?:GLOBAL[ \t]+)?(DEFFCT|DEFDAT|DEF|ENDFCT|ENDDAT|ENDIF|ENDSWITCH|ENDFOR|ENDWHILE|"
                   r"ENDLOOP|END|IF|ELSE|SWITCH|CASE|DEFAULT|FOR|WHILE|LOOP|REPEAT|UNTIL|EXIT|RETURN|GOTO|INTERRUPT|"
                   r"TRIGGER)(?![\w$])", re.M | re.I)
ROUTINE = re.compile(r"^[ \t\ufeff]*(?:GLOBAL[ \t]+)?(?:DEF|DEFFCT[ \t]+\w+)[ \t]+([A-Za-z_]\w*)[ \t]*\(", re.M | re.I)
CALL = re.compile(r"(?<![\w$.#])([A-Za-z_]\w*)[ \t]*\(")
CLOSER = {"DEF": "END", "DEFFCT": "ENDFCT", "DEFDAT": "ENDDAT", "FOR": "ENDFOR", "WHILE": "ENDWHILE",
          "LOOP": "ENDLOOP", "REPEAT": "UNTIL"}
NONE_SET = flow.Setting(flow.START, "", "")  # no $TOOL or $BASE set by the module: '' (the one in force, given)


class Broken(Exception):
    """The module's blocks do not balance, or it jumps (GOTO): (position, what)."""


def reach(code: str, settings: Sequence[tuple[int, int, str, int]], moves: Sequence[int]):
    """What may be in force at each move: :func:`kincal.io.flow.reach` of the module in ``code`` (comments and
    strings blanked), by position, slot 0 the tool and 1 the base.

    Parameters
    ----------
    code : str
        The module's text, comments and strings blanked.
    settings : sequence of (int, int, str, int)
        Each ``$TOOL``/``$BASE`` assignment: (where, 0 tool or 1 base, the value as written, its line).
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
    events += [(at, flow.Set(flow.Setting(line, "".join(value.split()).upper(), value), which))
               for at, which, value, line in settings]
    events += [(at, flow.Move(at)) for at in moves]
    events += [(m.start(), flow.Call(m.group(1).upper())) for m in CALL.finditer(code)
               if m.group(1).upper() in routines]
    tree = _Tree(code, sorted(events, key=lambda e: e[0])).block(())[0]
    return flow.reach(tree, [NONE_SET, NONE_SET])


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
