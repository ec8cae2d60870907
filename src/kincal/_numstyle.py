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
from dataclasses import dataclass

NUMBER = re.compile(r"(?P<sign>[-+]?)(?P<int>\d*)(?:(?P<dot>\.)(?P<frac>\d*))?(?:(?P<e>[eE])(?P<exp>[-+]?\d+))?")
MAX_DECIMALS = 12  # a field never gets more decimals than this (1 pm in mm)


@dataclass(frozen=True)
class Style:
    """How one number is written: an explicit '+' (``plus``), digits before the point (``lead``:
    False for ``-.242``), how many at least (``width``: 2 for ``05``, else 1), a point (``dot``), the decimals,
    and the exponent as written ('' if none)."""

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
        if m is None or not (m.group("int") or m.group("frac")):
            raise ValueError(f"'{text}' is not a number")
        whole = m.group("int")
        width = len(whole) if whole.startswith("0") else 1  # zero-padded ("05") keeps its width; "10" is not padded
        return cls(m.group("sign") == "+", bool(whole), width, bool(m.group("dot")), len(m.group("frac") or ""),
                   (m.group("e") or "") + (m.group("exp") or ""))

    def write(self, value: float, resolution: float) -> tuple[str, int]:
        """``value`` in this style with the fewest decimals (at least this style's) that carry it to
        ``resolution``; the text and the decimals used. ValueError for a value that is not finite."""
        if not math.isfinite(value):
            raise ValueError(f"{value} cannot be written as a number of a program")
        scale = 10.0 ** int(self.exponent[1:]) if self.exponent else 1.0
        mantissa, tol = value / scale, resolution / scale
        d = self.decimals
        while d < MAX_DECIMALS and abs(round(mantissa, d) - mantissa) > tol:
            d += 1
        digits = f"{abs(mantissa):0{self.width + (d > 0) + d}.{d}f}"
        if d == 0 and self.dot:
            digits += "."
        if not self.lead and digits.startswith("0."):
            digits = digits[1:]
        negative = math.copysign(1.0, mantissa) < 0 and (float(digits) != 0.0 or mantissa == 0.0)
        sign = "-" if negative else "+" if self.plus else ""
        return sign + digits + self.exponent, d


def restyle(old: str, value: float, resolution: float) -> str:
    """``value`` written in the style of the number ``old`` (see the module docstring)."""
    return Style.of(old).write(value, resolution)[0]
