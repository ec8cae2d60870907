"""The KRL scanner behind :mod:`kincal.io.program_krl`: comments and strings blanked, brackets matched, the
position aggregates ({X …, A …, S …, T …}, {A1 …}) read into their parts with their spans and checked (numbers,
S/T bits), every error one line with the file, line and column."""
from __future__ import annotations

import dataclasses
import functools
import re

from ..errors import MeasurementError
from .programs import line_column

POSE_KEYS = ("X", "Y", "Z", "A", "B", "C")
AXIS_KEYS = ("A1", "A2", "A3", "A4", "A5", "A6")
EXTERNAL = ("E1", "E2", "E3", "E4", "E5", "E6")
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
BITS = re.compile(r"'([BbHh])([0-9A-Fa-f]+)'")
_PART = rf"\s*(?:[A-Za-z_]\w*\s*{NUMBER.pattern}|[ST]\s*'[BbHh][0-9A-Fa-f]+')\s*"
ALL_NUMBERS = re.compile(rf"(?:[ \t]*[A-Za-z_]\w*[ \t]*:)?{_PART}(?:,{_PART})*", re.I)  # a body of numbers (and bits)
TYPED = re.compile(r"[ \t]*([A-Za-z_]\w*)[ \t]*:(?!=)")  # {E6POS: …}
KEY = re.compile(r"\s*([A-Za-z_$]\w*)(\[\])?\s*")  # a component's name
BRACKET = re.compile(r"[{}\[\]]")
# a component: (the name and the blanks after it, the name, the value without blanks around it, the blanks after)
COMPONENT = re.compile(r"(\s*([A-Za-z_$]\w*)(?:\[\])?\s*)((?:[^,{}\[\]\s]|\s+(?=[^,{}\[\]\s]))*)(\s*)(?:,|$)")
SEPARATOR = re.compile(r"[,}{\[]")  # what ends a component's value, or opens a nested one
COMMENT_OR_STRING = re.compile(r"\"[^\"\n]*\"?|;[^\n]*")


def _fail(source: str, text: str, at: int, what: str) -> MeasurementError:
    line, column = line_column(text, at)
    return MeasurementError(f"{source}: line {line}, column {column}: {what}")


def _blank(text: str) -> str:
    """The text with comments and strings replaced by blanks of the same length."""
    return COMMENT_OR_STRING.sub(lambda m: " " * len(m.group()), text)


def _check_brackets(source: str, text: str, code: str) -> dict[int, int]:
    """Every '{' and '[' closed by its own kind (else MeasurementError at the culprit): the end (after
    the '}') of each '{' by its position."""
    stack: list[int] = []
    ends: dict[int, int] = {}
    for m in BRACKET.finditer(code):
        i, c = m.start(), m.group()
        if c in "{[":
            stack.append(i)
        else:
            if not stack or code[stack[-1]] != {"}": "{", "]": "["}[c]:
                raise _fail(source, text, i, f"a '{c}' with no '{'{' if c == '}' else '['}' open before it")
            a = stack.pop()
            ends[a] = i + 1
    if stack:
        raise _fail(source, text, stack[-1], f"a '{code[stack[-1]]}' that is never closed")
    return ends


@dataclasses.dataclass
class _Aggregate:
    """An aggregate {…}: its span, the type written before ':', its components (KEY -> value span), the
    aggregates nested in them, its shape ("pose" or "joints": only position components; else '') and the
    position components it lacks."""

    start: int
    end: int
    typed: str
    parts: dict[str, tuple[int, int]]
    nested: list[int]  # starts of aggregates that are component values
    shape: str = dataclasses.field(init=False)
    missing: tuple[str, ...] = dataclasses.field(init=False)

    def __post_init__(self) -> None:
        self.shape, self.missing = ("", ()) if self.nested else _shape(frozenset(self.parts))


@functools.lru_cache(maxsize=256)
def _shape(keys: frozenset[str]) -> tuple[str, tuple[str, ...]]:
    """The shape of an aggregate with these component names, and the position components it lacks."""
    if keys and keys <= set(POSE_KEYS + EXTERNAL + ("S", "T")) and keys & set(POSE_KEYS):
        return "pose", tuple(k for k in POSE_KEYS if k not in keys)
    if keys and keys <= set(AXIS_KEYS + EXTERNAL) and keys & set(AXIS_KEYS):
        return "joints", tuple(k for k in AXIS_KEYS if k not in keys)
    return "", ()


def _aggregate(source: str, text: str, code: str, ends: dict[int, int], a: int) -> _Aggregate:
    """The aggregate whose '{' is at ``a``; MeasurementError for a component without a value."""
    b = ends[a]
    i, typed = a + 1, ""
    m = TYPED.match(code, i)
    if m:
        typed, i = m.group(1).upper(), m.end()
    flat = _flat(code, i, b)
    if flat is not None:
        return _Aggregate(a, b, typed, flat, [])
    parts: dict[str, tuple[int, int]] = {}
    nested: list[int] = []
    while i < b - 1:
        k = KEY.match(code, i)
        if not k:
            return _Aggregate(a, b, typed, {}, [])  # not name-value components: not a position
        j = k.end()
        if code[j] == "{":
            nested.append(j)
            j = ends[j]
        while code[j] not in ",}":
            j = ends[j] if code[j] in "{[" else _next_separator(code, j)
        lo, hi = k.end(), j
        while hi > lo and code[hi - 1].isspace():
            hi -= 1
        if lo == hi and not k.group(2):
            raise _fail(source, text, k.start(1), f"the component {k.group(1)} has no value")
        parts[k.group(1).upper()] = (lo, hi)
        i = j + 1
    return _Aggregate(a, b, typed, parts, nested)


def _next_separator(code: str, j: int) -> int:
    """Where the next ',', '}', '{' or '[' after j is (an aggregate's closing '}' is always there)."""
    m = SEPARATOR.search(code, j)
    return len(code) if m is None else m.start()


def _flat(code: str, i: int, b: int) -> dict[str, tuple[int, int]] | None:
    """The components (KEY -> value span) of an aggregate from ``i`` to its '}' at b - 1 when each is a name
    and a value without brackets (the common case, in one scan); else None (read part by part)."""
    parts, at = {}, i
    for head, key, value, tail in COMPONENT.findall(code, i, b - 1):
        lo = at + len(head)
        at = lo + len(value)
        if not value and not head.rstrip().endswith("[]"):
            return None
        parts[key.upper()] = (lo, at)
        at += len(tail) + 1
    return parts if at == b and parts else None


def _check_numbers(source: str, text: str, agg: _Aggregate) -> None:
    """Every component of a position is a number (S and T may be 'B…' bits)."""
    if ALL_NUMBERS.fullmatch(text, agg.start + 1, agg.end - 1):  # the common case, in one scan
        return
    for k, (lo, hi) in agg.parts.items():
        value = text[lo:hi]
        if NUMBER.fullmatch(value) or (k in ("S", "T") and BITS.fullmatch(value)):
            continue
        raise _fail(source, text, lo, f"'{value}' is not a number (component {k} of a position)")


def _integer(value: str) -> int:
    if value.isdigit():
        return int(value)
    bits = BITS.fullmatch(value)
    if bits:
        return int(bits.group(2), 2 if bits.group(1) in "Bb" else 16)
    return int(float(value))
