"""Checks of option values, shared by every options record and entry point (a leaf module).

Each returns the value in its canonical type or raises ValueError naming the option and saying what
to give.
"""
from __future__ import annotations

import math
import numbers


def whole(name: str, value, least: int = 0) -> int:
    """A whole number ``least`` or more (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least:
        raise ValueError(f"{name}={value!r}: give a whole number, {least} or more")
    return int(value)


def number(name: str, value, positive: bool = True, unit: str = "") -> float:
    """A finite real number, > 0 (``positive``) or >= 0 (not a bool); ``unit`` is named in the message."""
    ok = not isinstance(value, bool) and isinstance(value, numbers.Real) and math.isfinite(value)
    if not ok or value < 0 or (positive and value == 0):
        raise ValueError(f"{name}={value!r}: give a finite number {'> 0' if positive else '>= 0'}"
                         f"{f' ({unit})' if unit else ''}")
    return float(value)


def one_of(name: str, value, allowed) -> str:
    """One of the ``allowed`` choices."""
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not one of {', '.join(map(str, allowed))}")
    return value


def kind_of(name: str, value, expected: type, hint: str = "") -> None:
    """TypeError unless ``value`` is an ``expected`` (a wrong argument in a Python call: a file path where the data
    read from it belong, a robot's name where the robot does), naming the argument, what it got and ``hint``."""
    if not isinstance(value, expected):
        raise TypeError(f"{name}: a {expected.__name__} is wanted, got {type(value).__name__}"
                        + (f": {hint}" if hint else ""))
