"""The RAPID module scanner behind :mod:`kincal.io.program_rapid`: the text with comments blanked and strings
filled, brackets matched, routines, declarations and a call's arguments found, and the literal aggregates
(robtarget, jointtarget, tooldata, wobjdata) read into trees of numbers with their spans, each checked for
its shape (a robot target made of it) — every error one line with the file, line and column."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import MeasurementError
from ..models.transforms import quaternion_rotvec
from .programs import Target, line_column

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


BROKEN_NUMBER = re.compile(r"[-+]?[\d.][\w.]*(?:[eE][-+][\w.]*)?")  # starts like a number: must be one


COMMENT_OR_STRING = re.compile(r'!.*|"(?:[^"\n]|"")*"|"')  # a lone '"': a string not closed on its line


OPEN = {"]": "[", ")": "(", "}": "{"}


ROUTINE = re.compile(r"\b(?:PROC|TRAP|FUNC\s+\w+)\s+(\w+)", re.I)


ROUTINE_END = re.compile(r"\bEND(?:PROC|TRAP|FUNC)\b", re.I)


DECL = re.compile(r"\b(CONST|PERS|VAR)\s+(robtarget|jointtarget|tooldata|wobjdata)\s+(\w+)\s*(?:\{([^}]*)\})?"
                  r"\s*(:=)?", re.I)


SHAPES = {"robtarget": (3, 4, 4, 6), "jointtarget": (6, 6)}


FORMS = {"robtarget": "[[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,…,eax_f]]",
         "jointtarget": "[[rax_1,…,rax_6],[eax_a,…,eax_f]]",
         "tooldata": "[robhold,[[x,y,z],[q1,q2,q3,q4]],[mass,[x,y,z],[q1,q2,q3,q4],ix,iy,iz]]",
         "wobjdata": "[robhold,ufprog,ufmec,[[x,y,z],[q1,q2,q3,q4]],[[x,y,z],[q1,q2,q3,q4]]]"}


UNUSED = 8.9e9  # an axis written 9E9 (or more) is not there


@dataclass
class Node:
    """An aggregate ``[…]`` (``items``) or a leaf (an expression: ``items`` None), spans in the text."""

    start: int
    end: int
    items: list[Node] | None = None


@dataclass
class Decl:
    """A declaration: type (lower case), name as written, scope (routine index, -1: the module), the
    position of the declaration and of its name, array sizes, its value (None: none) and its line."""

    kind: str
    name: str
    scope: int
    start: int
    name_at: int
    dims: tuple[int, ...]
    value: tuple[int, int] | None
    line: int
    changed: int = 0  # the line where it is first set at run time (0: never)


@dataclass
class Use:
    """The moves to one declared point: the first one's position and frames, and the later moves."""

    at: int
    frames: tuple[str, str]
    direct: bool
    later: list[tuple[int, str, tuple[str, str]]] = field(default_factory=list)


@dataclass(frozen=True)
class FrameData:
    """A tooldata or wobjdata declaration: name, kind, line, robhold (None: not a literal), the tool
    frame (tooldata) or user frame (wobjdata) and the object frame (wobjdata; None for a tool) as
    x, y, z (m) and rotation vector (rad) (None: not a literal), and the line where the program changes
    it at run time (0: never)."""

    name: str
    kind: str
    line: int
    robhold: bool | None
    frame: np.ndarray | None
    oframe: np.ndarray | None
    changed: int


class _Scan:
    """One module's text, the text with comments blanked and strings filled (``code``: the same
    length, nothing in them found), its routines and its declarations."""

    def __init__(self, source: str, text: str) -> None:
        self.source, self.text = source, text
        if text.lstrip("\ufeff \t\r\n").startswith("<?xml"):
            raise self.fail(text.find("<"), "an XML file, not RAPID text (a .modx is read as a plain module)")
        self.code = COMMENT_OR_STRING.sub(self._blank, text)
        _check_brackets(self)
        self.routines = _routines(self)
        self.decls = _declarations(self)
        self.by_name = {(d.scope, d.name.lower()): d for d in self.decls}

    def _blank(self, m: re.Match) -> str:
        if m.group() == '"':
            raise self.fail(m.start(), "a string not closed on its line")
        if m.group().startswith("!"):
            return " " * len(m.group())
        return '"' + "_" * (len(m.group()) - 2) + '"'  # a string keeps its quotes: a field, not a blank

    def fail(self, at: int, what: str) -> MeasurementError:
        line, column = line_column(self.text, at)
        return MeasurementError(f"{self.source}: line {line}, column {column}: {what}")

    def line(self, at: int) -> int:
        return self.text.count("\n", 0, at) + 1

    def words(self, a: int, b: int) -> str:
        """The code of a span with its blanks collapsed (for messages)."""
        return " ".join(self.code[a:b].split())

    def end_of_statement(self, at: int, what: str) -> int:
        end = self.code.find(";", at)
        if end < 0:
            raise self.fail(at, f"{what} without its closing ';'")
        return end

    def scope_of(self, at: int) -> int:
        return next((k for k, (a, b, _, _) in enumerate(self.routines) if a <= at < b), -1)

    def resolve(self, at: int, name: str) -> Decl | str | None:
        """The declaration ``name`` means at position ``at``, "param" for a routine parameter, or None."""
        k, low = self.scope_of(at), name.lower()
        if k >= 0 and low in self.routines[k][3]:
            return "param"
        return self.by_name.get((k, low)) or self.by_name.get((-1, low))


def _check_brackets(s: _Scan) -> None:
    """Every '[', '(' and '{' closed by its own kind, and none open at a ';'."""
    stack: list[int] = []
    for m in re.finditer(r"[\[\](){};]", s.code):
        c = m.group()
        if c in "[({":
            stack.append(m.start())
        elif c == ";" and stack:
            raise s.fail(stack[-1], f"'{s.code[stack[-1]]}' not closed before the ';' of line {s.line(m.start())}")
        elif c != ";":
            if not stack or s.code[stack[-1]] != OPEN[c]:
                raise s.fail(m.start(), f"'{c}' without its opening '{OPEN[c]}'")
            stack.pop()
    if stack:
        raise s.fail(stack[-1], f"'{s.code[stack[-1]]}' never closed")


def _closing(code: str, at: int) -> int:
    """The position of the bracket that closes the one at ``at`` (brackets are balanced)."""
    depth = 0
    for i in range(at, len(code)):
        depth += (code[i] in "[({") - (code[i] in "])}")
        if depth == 0:
            return i
    return len(code)


def _routines(s: _Scan) -> list[tuple[int, int, tuple[int, int], set[str]]]:
    """Each PROC/FUNC/TRAP: its span, the span of its parameter list and its parameters' names (lower)."""
    out = []
    for m in ROUTINE.finditer(s.code):
        end = ROUTINE_END.search(s.code, m.end())
        if end is None:
            raise s.fail(m.start(), f"routine {m.group(1)} without its END")
        rest = s.code[m.end():end.start()]
        params, names = (m.end(), m.end()), set()
        if rest.lstrip().startswith("("):
            a = m.end() + rest.index("(")
            params = (a, _closing(s.code, a))
            for piece in re.split(r"[,\\|]", re.sub(r"\{[^}]*\}", "", s.code[a + 1:params[1]])):
                words = re.findall(r"\w+", piece)
                names |= {words[-1].lower()} if words else set()
        out.append((m.start(), end.end(), params, names))
    return out


def _declarations(s: _Scan) -> list[Decl]:
    """The robtarget, jointtarget, tooldata and wobjdata declarations (not a routine's parameters)."""
    out = []
    for m in DECL.finditer(s.code):
        if any(a < m.start() < b for _, _, (a, b), _ in s.routines):
            continue
        kind, name = m.group(2).lower(), m.group(3)
        end = s.end_of_statement(m.start(), f"the declaration of {name}")
        if not m.group(5) and s.code[m.end():end].strip():
            raise s.fail(m.end(), f"':=' or ';' expected after {name}")
        dims = _dims(s, m) if m.group(4) is not None else ()
        value = None
        if m.group(5):
            a = m.end() + len(s.code[m.end():end]) - len(s.code[m.end():end].lstrip())
            value = (a, end - (len(s.code[a:end]) - len(s.code[a:end].rstrip())))
            if value[0] >= value[1]:
                raise s.fail(end, f"no value after ':=' for {name}")
        out.append(Decl(kind, name, s.scope_of(m.start()), m.start(), m.start(3), dims, value, s.line(m.start())))
    return out


def _dims(s: _Scan, m: re.Match) -> tuple[int, ...]:
    sizes = [x.strip() for x in m.group(4).split(",")]
    if not all(x.isdigit() and int(x) > 0 for x in sizes):
        raise s.fail(m.start(4), f"array sizes of {m.group(3)} must be whole numbers: {{{m.group(4)}}}")
    return tuple(int(x) for x in sizes)


def _aggregate(s: _Scan, at: int) -> Node:
    """The aggregate whose '[' is at ``at``: its items, nested aggregates or leaves."""
    node, i = Node(at, _closing(s.code, at) + 1, []), at + 1
    items: list[Node] = []
    while True:
        while s.code[i] in " \t\r\n":
            i += 1
        if s.code[i] == "]" and not items and s.code[at + 1:i].strip() == "":
            break
        if s.code[i] == "[":
            item = _aggregate(s, i)
            j = item.end
        else:
            j = i
            while s.code[j] not in ",]":
                j = _closing(s.code, j) + 1 if s.code[j] in "({[" else j + 1
            b = j - (len(s.code[i:j]) - len(s.code[i:j].rstrip()))
            if b <= i:
                raise s.fail(i, "an empty field in an aggregate")
            item = Node(i, b)
        items.append(item)
        while s.code[j] in " \t\r\n":
            j += 1
        if s.code[j] not in ",]":
            raise s.fail(j, "',' or ']' expected in an aggregate")
        if s.code[j] == "]":
            break
        i = j + 1
    node.items = items
    return node


def _number(s: _Scan, leaf: Node) -> float | None:
    """The number a leaf is written as, None for an expression; a broken number is an error."""
    word = s.code[leaf.start:leaf.end]
    if NUMBER.fullmatch(word):
        return float(word)
    if BROKEN_NUMBER.fullmatch(word):
        raise s.fail(leaf.start, f"'{word}' is not a number")
    return None


def _shaped(s: _Scan, node: Node, kind: str) -> None:
    """Check that ``node`` has the shape of a robtarget or jointtarget (an error says where not)."""
    sizes = SHAPES[kind]
    if node.items is None or len(node.items) != len(sizes):
        n = "an expression" if node.items is None else f"{len(node.items)} parts"
        raise s.fail(node.start, f"a {kind} is {FORMS[kind]}: this one has {n}")
    for part, size in zip(node.items, sizes):
        if part.items is None or len(part.items) != size or any(x.items is not None for x in part.items):
            n = "an expression" if part.items is None else f"{len(part.items)} values"
            raise s.fail(part.start, f"a {kind} is {FORMS[kind]}: this part has {n}, not {size} numbers")


def _pieces(code: str, a: int, b: int) -> list[tuple[tuple[int, int], list[tuple[str, str]]]]:
    """The comma-separated arguments of code[a:b]: each its positional part's span (empty: none) and
    its optional arguments (name, value)."""
    out, start, i = [], a, a
    while i <= b:
        if i == b or code[i] == ",":
            out.append(_piece(code, start, i))
            start = i + 1
        if i < b and code[i] in "([{":
            i = _closing(code, i)
        i += 1
    return out


def _piece(code: str, a: int, b: int) -> tuple[tuple[int, int], list[tuple[str, str]]]:
    cuts, i = [], a
    while i < b:
        if code[i] in "([{":
            i = _closing(code, i)
        elif code[i] == "\\":
            cuts.append(i)
        i += 1
    head_end = cuts[0] if cuts else b
    lead = len(code[a:head_end]) - len(code[a:head_end].lstrip())
    head = (a + lead, head_end - (len(code[a:head_end]) - len(code[a:head_end].rstrip())))
    options = []
    for c, d in zip(cuts, cuts[1:] + [b]):
        m = re.match(r"\\\s*(\w+)\s*(?::=|\?)?\s*", code[c:d])
        if m:
            options.append((m.group(1).lower(), " ".join(code[c + m.end():d].split())))
    return (head if head[0] < head[1] else (head[0], head[0])), options


def _literal(s: _Scan, node: Node, kind: str, move: str, at: int, variable: str = "",
             frames: tuple[str, str] = ("", "")) -> Target | str:
    """The target written as ``node`` (a robtarget or jointtarget), or why it is not a literal."""
    _shaped(s, node, kind)
    assert node.items is not None
    parts = [p.items or [] for p in node.items]
    numbers = [[_number(s, x) for x in p] for p in parts]
    fixed = numbers[0] + numbers[1] + (numbers[2] if kind == "robtarget" else [])
    if any(v is None for v in fixed):
        names = [s.code[x.start:x.end] for x, v in zip(parts[0] + parts[1] + parts[2][:len(fixed) - 7], fixed)
                 if v is None]
        return f"the {kind} is built from values computed at run time ({', '.join(names)})"
    line = s.line(node.start)
    if kind == "jointtarget":
        axes = [(x, v) for x, v in zip(parts[0], fixed) if v is not None and abs(v) < UNUSED]
        return Target(node.start, node.end, line, move, "joints", np.radians([v for _, v in axes]), at, variable,
                      tuple((x.start, x.end) for x, _ in axes), (), frames)
    q = np.array(fixed[3:7], dtype=float)
    if not np.linalg.norm(q) > 0:
        raise s.fail(parts[1][0].start, "a quaternion of norm 0 is no orientation")
    config = [float(v) for v in fixed[7:] if v is not None]
    bad = next((x for x, v in zip(parts[2], config) if not v.is_integer()), None)
    if bad is not None:
        raise s.fail(bad.start, "cf1, cf4, cf6 and cfx must be whole numbers")
    values = np.concatenate([np.array(fixed[:3], dtype=float) * 1e-3, quaternion_rotvec(q)])
    return Target(node.start, node.end, line, move, "pose", values, at, variable,
                  tuple((x.start, x.end) for x in parts[0] + parts[1]), tuple(int(v) for v in config), frames)
