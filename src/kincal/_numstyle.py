"""A number written again in the style it was written in (a leaf module).

Robot programs write their numbers in many ways: ``90``, ``-41.7453308``, ``-.242`` (no leading
zero), ``+5.0``, ``9E9``, ``9E+09``, ``1.5e-3``, ``90.`` (a point and no decimals). A program whose
targets are corrected keeps each field's style: :func:`restyle` writes a new value with the old
text's sign convention, leading zero, point, number of decimals and exponent (the same exponent, so
``9E9`` stays ``…E9``). It adds decimals only where the old number of decimals cannot carry the value
to ``resolution`` (in the field's own unit), and says how many it used.

Written again with its own value, every number reads back as the same text (tests over every number of
the bundled robot programs).
"""
from __future__ import annotations

import math
import re
from typing import NamedTuple, Sequence

import numpy as np

NUMBER = re.compile(r"([-+]?)(\d*)(?:(\.)(\d*))?(?:([eE])([-+]?\d+))?")  # sign, whole, point, decimals, e, exponent
MANY = re.compile(r"^([-+]?)(?=\d|\.\d)(\d*)(?:(\.)(\d*))?(?:([eE])([-+]?\d+))?\n", re.M)  # numbers, one a line
MAX_DECIMALS = 12  # a field never gets more decimals than this (1 pm in mm)


class Style(NamedTuple):
    """How one number is written: an explicit '+' (``plus``), digits before the point (``lead``:
    False for ``-.242``), how many at least (``width``: 2 for ``05``, else 1), a point (``dot``), the decimals,
    and the exponent as written ('' if none). (A named tuple: one is made for every number written.)"""

    plus: bool
    lead: bool
    width: int
    dot: bool
    decimals: int
    exponent: str

    @classmethod
    def of(cls, text: str) -> Style:
        """The style of ``text``, a plain decimal number (ValueError otherwise)."""
        m = NUMBER.fullmatch(text)
        if m is None:
            raise ValueError(f"'{text}' is not a number")
        sign, whole, dot, frac, e, exp = m.groups()
        if not (whole or frac):
            raise ValueError(f"'{text}' is not a number")
        width = len(whole) if whole.startswith("0") else 1  # zero-padded ("05") keeps its width; "10" is not padded
        return cls(sign == "+", bool(whole), width, bool(dot), len(frac or ""), (e or "") + (exp or ""))

    def write(self, value: float, resolution: float) -> tuple[str, int]:
        """``value`` in this style with the fewest decimals (at least this style's) that carry it to
        ``resolution``; the text and the decimals used. ValueError for a value that is not finite."""
        if not math.isfinite(value):
            raise ValueError(f"{value} cannot be written as a number of a program")
        scale = 10.0 ** int(self.exponent[1:]) if self.exponent else 1.0
        mantissa, tol = value / scale, resolution / scale
        d = self.decimals
        if d < MAX_DECIMALS and abs(round(mantissa, d) - mantissa) > tol:
            d = _fewest(mantissa, tol, d + 1)
        return _text(mantissa, d, self.width, self.dot, self.lead, self.plus) + self.exponent, d


def _fewest(x: float, tol: float, lo: int) -> int:
    """The fewest decimals from ``lo`` (at most MAX_DECIMALS) that carry x to ``tol``, by bisection: x rounded
    to d decimals is also a number of d + 1 decimals, so the error only falls as d grows, and
    ceil(log10(0.5 / tol)) decimals always carry it (the error is at most half their last digit)."""
    hi = max(lo, min(MAX_DECIMALS, math.ceil(math.log10(0.5 / tol)) if tol > 0 else MAX_DECIMALS))
    while lo < hi:
        mid = (lo + hi) // 2
        if abs(round(x, mid) - x) > tol:
            lo = mid + 1
        else:
            hi = mid
    return lo


def restyle(old: str, value: float, resolution: float) -> str:
    """``value`` written in the style of the number ``old`` (see the module docstring)."""
    return Style.of(old).write(value, resolution)[0]


def restyle_all(olds: Sequence[str], values: np.ndarray, resolution: np.ndarray) -> list[str]:
    """Each value (M,) written in the style of its old number, to its resolution (M,): :func:`restyle` for many
    numbers at once, the same texts (the styles read by one scan, the decimals chosen by array operations where
    scaled rounding is exact, |mantissa| · 10^MAX_DECIMALS < 2^52, and one by one elsewhere)."""
    values, resolution = np.asarray(values, dtype=float), np.asarray(resolution, dtype=float)
    found = MANY.findall("\n".join(olds) + "\n")
    if len(found) != len(olds) or not np.isfinite(values).all():  # the culprit named, one by one
        return [restyle(o, float(v), float(r)) for o, v, r in zip(olds, values, resolution)]
    exponent = [e + x for *_, e, x in found]
    scale = np.array([10.0 ** int(x[1:]) if x else 1.0 for x in exponent])
    mantissa, tol = values / scale, resolution / scale
    decimals = np.array([len(f[3]) for f in found])
    d = np.arange(MAX_DECIMALS + 1)
    carried = np.abs(np.round(mantissa[:, None] * 10.0 ** d) / 10.0 ** d - mantissa[:, None]) <= tol[:, None]
    carried |= d == MAX_DECIMALS
    need = np.maximum(decimals, np.argmax(carried & (d >= decimals[:, None]), axis=1))
    exact = np.abs(mantissa) * 10.0 ** MAX_DECIMALS < 2.0**52
    out = []
    for (sign, whole, dot, frac, _, _), x, m, t, k, ok in zip(found, exponent, mantissa.tolist(), tol.tolist(),
                                                             need.tolist(), exact.tolist()):
        if not ok:
            k = len(frac) if len(frac) >= MAX_DECIMALS or abs(round(m, len(frac)) - m) <= t else _fewest(
                m, t, len(frac) + 1)
        out.append(_text(m, k, len(whole) if whole.startswith("0") else 1, bool(dot), bool(whole), sign == "+") + x)
    return out


def _text(mantissa: float, decimals: int, width: int, dot: bool, lead: bool, plus: bool) -> str:
    """A mantissa with ``decimals`` decimals, at least ``width`` digits before the point, a point without
    decimals when ``dot``, no leading zero unless ``lead``, a '+' when ``plus``; '-' for a negative number that
    is not written as zero (and for -0.0)."""
    digits = "%0*.*f" % (width + (decimals > 0) + decimals, decimals, abs(mantissa))
    if decimals == 0 and dot:
        digits += "."
    if not lead and digits.startswith("0."):
        digits = digits[1:]
    negative = math.copysign(1.0, mantissa) < 0 and (mantissa == 0.0 or digits.strip("0.") != "")
    return ("-" if negative else "+" if plus else "") + digits
