"""What a program's settings reach along its flow: which assignment of a setting (URScript's ``set_tcp``, KRL's
``$TOOL`` and ``$BASE``) may be in force at each move, by the program's structure and not by the order of its text.

A dialect reads its program into a tree of nodes — a setting (:class:`Set`), settings made from another one in
force (:class:`Derive`: KRL's ``BAS(#FRAMES)``, $TOOL and $BASE from FDAT_ACT), a move (:class:`Move`), branches
(:class:`Branch`: if/elif/else, switch), loops (:class:`Loop`), calls of the program's own routines
(:class:`Call`, :class:`Define`) and jumps out (:class:`Jump`: return, break, continue, halt) — and
:func:`reach` follows every path: a routine's settings reach the moves after each call of it (its body followed
from the state at that call), a branch's reach past the block as one of the possibilities, a loop's back to its
own start. A move takes a setting only where every path gives it the same value (:func:`in_force`); else it is
named with the lines that make it ambiguous, never compensated with a guess.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Hashable, Optional, Sequence

START = 0  # the line of the state before any setting: the controller's own


@dataclass(frozen=True)
class Setting:
    """One assignment of a setting: where it is and its value.

    Parameters
    ----------
    line : int
        Its line, from 1 (:data:`START`, 0: the value the program starts with, set by none of its lines).
    key : hashable
        What identifies its value: two settings with equal keys set the same value.
    value : object, optional
        The value as the dialect uses it (not compared; default None).
    """

    line: int
    key: Hashable
    value: object = field(default=None, compare=False)


@dataclass(frozen=True)
class Set:
    """A setting assigned: from here on ``setting`` is in force in ``slot`` (0 for a language with one setting)."""

    setting: Setting
    slot: int = 0


@dataclass(frozen=True)
class Derive:
    """Settings made from the one in force in slot ``source``: for each setting ``s`` that may be in force there,
    ``made(s)`` gives one setting per slot of ``slots`` (in that order), in force from here on; ``made(None)``: what
    it gives where the source is not known (a routine's settings gathered apart from its calls: a thread's, a
    recursion's)."""

    source: int
    slots: tuple[int, ...]
    made: Callable[[Optional[Setting]], tuple[Setting, ...]]


@dataclass(frozen=True)
class Move:
    """A move at character position ``at``: what is in force there is recorded."""

    at: int


@dataclass(frozen=True)
class Branch:
    """One of ``bodies`` runs; with ``complete`` False also none of them (an if with no else)."""

    bodies: tuple[tuple, ...]
    complete: bool


@dataclass(frozen=True)
class Loop:
    """``head`` (a loop's condition: calls in it) then ``body``, again and again; ``test`` says where it may leave:
    "head" (while: after the head, also before the first body), "tail" (repeat: after the body) or "none" (only by
    a break)."""

    head: tuple
    body: tuple
    test: str = "head"


@dataclass(frozen=True)
class Call:
    """A call of the routine ``name``: its body runs here (a name the program does not define changes nothing)."""

    name: str


@dataclass(frozen=True)
class Start:
    """A thread ``name`` started: its body runs beside the rest of the program, so what it may set may be in force
    at any move from then on."""

    name: str


@dataclass(frozen=True)
class Define:
    """The routine ``name`` defined here with ``body``: it runs where it is called (where no call of it is found,
    from the state where it is defined: a program's main routine, run by the controller)."""

    name: str
    body: tuple


@dataclass(frozen=True)
class Jump:
    """``kind`` "return", "break", "continue" or "halt": the path goes on elsewhere, or ends."""

    kind: str


State = Optional[tuple[frozenset, ...]]  # per slot, the Settings that may be in force; None: no path gets here


def _join(a: State, b: State) -> State:
    if a is None:
        return b
    if b is None:
        return a
    return tuple(x | y for x, y in zip(a, b))


@dataclass
class _Walk:
    """The walk of one program: its routines by name, and what reaches each move."""

    defs: dict[str, list[tuple]]
    moves: dict[int, State] = field(default_factory=dict)
    defined: dict[str, State] = field(default_factory=dict)
    memo: dict = field(default_factory=dict)
    stack: set = field(default_factory=set)
    called: set = field(default_factory=set)
    threads: State = None
    slots: int = 1

    def body(self, nodes: Sequence, fall: State) -> tuple[State, State, State, State]:
        """(falls through, returns, breaks, continues) after ``nodes`` entered with ``fall``."""
        ret = brk = cont = None
        for node in nodes:
            if isinstance(node, Set) and fall is not None:
                fall = tuple(frozenset([node.setting]) if k == node.slot else s for k, s in enumerate(fall))
            elif isinstance(node, Derive) and fall is not None:
                made = [node.made(s) for s in fall[node.source]]
                fall = tuple(frozenset(m[node.slots.index(k)] for m in made) if k in node.slots else s
                             for k, s in enumerate(fall))
            elif isinstance(node, Move) and fall is not None:
                self.moves[node.at] = _join(self.moves.get(node.at), fall)
            elif isinstance(node, Branch):
                outs = [self.body(b, fall) for b in node.bodies]
                fall = _joined([o[0] for o in outs] + ([] if node.complete else [fall]))
                ret, brk, cont = (_joined([ret, *(o[1] for o in outs)]), _joined([brk, *(o[2] for o in outs)]),
                                  _joined([cont, *(o[3] for o in outs)]))
            elif isinstance(node, Loop):
                fall, r = self.loop(node, fall)
                ret = _join(ret, r)
            elif isinstance(node, (Call, Start)):
                fall = self.call(node.name, fall) if isinstance(node, Call) else self.start(node.name, fall)
            elif isinstance(node, Define) and fall is not None:
                self.defined[node.name] = _join(self.defined.get(node.name), fall)
            elif isinstance(node, Jump):
                ret, brk, cont = (_join(x, fall) if node.kind == kind else x
                                  for x, kind in ((ret, "return"), (brk, "break"), (cont, "continue")))
                fall = None
        return fall, ret, brk, cont

    def loop(self, node: Loop, entry: State) -> tuple[State, State]:
        """(leaves, returns) of a loop entered with ``entry``: walked until what comes back to its start adds
        nothing."""
        while True:
            head = self.body(node.head, entry)[0]
            fall, ret, brk, cont = self.body(node.body, head)
            back = _join(fall, cont)
            again = _join(entry, back)
            if again == entry:
                break
            entry = again
        leaves = {"head": head, "tail": back, "none": None}[node.test]
        return _join(leaves, brk), ret

    def call(self, name: str, fall: State) -> State:
        """What is in force after a call of ``name`` entered with ``fall`` (its body walked from there)."""
        if fall is None or name not in self.defs:
            return fall
        if (name, fall) in self.memo:
            return self.memo[name, fall]
        if name in self.stack:  # recursion: whatever the routine may set, anywhere in it
            return _join(fall, self.settable(name, set()))
        self.stack.add(name)
        self.called.add(name)
        out = _joined([_join(*self.body(b, fall)[:2]) for b in self.defs[name]])
        self.stack.discard(name)
        self.memo[name, fall] = out
        return out

    def start(self, name: str, fall: State) -> State:
        """A thread started with ``fall``: its moves walked from there; what it may set joins every move's."""
        self.call(name, fall)
        if fall is not None and name in self.defs:
            self.threads = _join(self.threads, self.settable(name, set()))
        return fall

    def settable(self, name: str, seen: set) -> State:
        """Every setting the routine ``name`` may make, through the routines it calls (per slot)."""
        seen.add(name)
        out: State = None
        for b in self.defs.get(name, []):
            for node in _flat(b):
                if isinstance(node, (Set, Derive)):
                    sets = {node.slot: node.setting} if isinstance(node, Set) else dict(zip(node.slots,
                                                                                            node.made(None)))
                    out = _join(out, tuple(frozenset([sets[k]]) if k in sets else frozenset()
                                           for k in range(self.slots)))
                elif isinstance(node, (Call, Start)) and node.name not in seen:
                    out = _join(out, self.settable(node.name, seen))
        return out if out is not None else tuple(frozenset() for _ in range(self.slots))


def _joined(states: Sequence[State]) -> State:
    out: State = None
    for s in states:
        out = _join(out, s)
    return out


def _flat(nodes: Sequence):
    """Every node of ``nodes`` and of the blocks in them, routines defined inside left out (they run where called)."""
    for node in nodes:
        yield node
        if isinstance(node, Branch):
            for b in node.bodies:
                yield from _flat(b)
        elif isinstance(node, Loop):
            yield from _flat(node.head + node.body)


def _defines(nodes: Sequence):
    """Every :class:`Define` in ``nodes``, nested ones included, in text order."""
    for node in nodes:
        if isinstance(node, Define):
            yield node
            yield from _defines(node.body)
        elif isinstance(node, Branch):
            for b in node.bodies:
                yield from _defines(b)
        elif isinstance(node, Loop):
            yield from _defines(node.head + node.body)


def reach(tree: Sequence, start: Sequence[Setting]) -> dict[int, tuple[frozenset, ...]]:
    """The settings that may be in force at each move of a program, by its flow.

    The main flow (``tree``) is walked from ``start``; a routine where it is called, from the state at the call
    (each call on its own: what a routine sets reaches the moves after that call), and a routine no call reaches
    from the state where it is defined. A thread's settings may be in force at every move.

    Parameters
    ----------
    tree : sequence of nodes
        The program as :class:`Set`, :class:`Derive`, :class:`Move`, :class:`Branch`, :class:`Loop`, :class:`Call`,
        :class:`Start`, :class:`Define` and :class:`Jump` nodes, in the order of its text.
    start : sequence of Setting
        What is in force before the program sets anything, one per slot (line :data:`START`).

    Returns
    -------
    dict of int to tuple of frozenset of Setting
        By each move's ``at``, per slot, the settings that may be in force there (an empty one: no path reaches
        it); a move no path reaches is left out.

    Examples
    --------
    ``set_tcp(A)`` on line 2, then ``if … set_tcp(B) end`` (line 4) before a move at position 50:

    >>> from kincal.io.flow import Branch, Move, Set, Setting, in_force, reach
    >>> a, b = Setting(2, "A"), Setting(4, "B")
    >>> found = reach([Set(a), Move(10), Branch(((Set(b),),), complete=False), Move(50)], [Setting(0, "none")])
    >>> in_force(found[10][0]).key, in_force(found[50][0]), sorted(s.line for s in found[50][0])
    ('A', None, [2, 4])
    """
    defs: dict[str, list[tuple]] = {}
    order = list(_defines(tree))
    for d in order:
        defs.setdefault(d.name, []).append(d.body)
    walk = _Walk(defs, slots=len(start))
    first = tuple(frozenset([s]) for s in start)
    walk.body(tree, first)
    for d in order:  # a routine no call reached: from where it is defined
        if d.name not in walk.called:
            walk.call(d.name, walk.defined.get(d.name, first))
    return {at: s if walk.threads is None else tuple(a | b for a, b in zip(s, walk.threads))
            for at, s in walk.moves.items() if s is not None}


def in_force(possible: frozenset) -> Setting | None:
    """The setting in force where ``possible`` may be: the earliest of them when every one sets the same value, else
    None (ambiguous, or no path gets there).

    Parameters
    ----------
    possible : frozenset of Setting
        What may be in force at a move (one slot of :func:`reach`).

    Returns
    -------
    Setting or None
        The setting, or None.

    Examples
    --------
    >>> from kincal.io.flow import Setting, in_force
    >>> in_force(frozenset([Setting(5, "A"), Setting(7, "A")])).line, in_force(frozenset([Setting(5, "A"),
    ...                                                                               Setting(7, "B")]))
    (5, None)
    """
    if len({s.key for s in possible}) != 1:
        return None
    return min(possible, key=lambda s: s.line)
