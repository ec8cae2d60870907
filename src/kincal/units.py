"""Units at the edges: the one home of length and angle units, their SI factors and display.

Inside kincal every length is in m and every angle in rad. Files, flags and printed text use the
units engineers read; this module converts between the two and nothing else does:

* ``LENGTH_UNITS`` / ``ANGLE_UNITS``: the SI value of one unit (``"mm": 1e-3`` m);
  :func:`unit_factor` looks one up and names the choices when a unit is unknown;
* :func:`joint_units` / :func:`joint_factors`: each joint's unit (and its SI factor) by the joint's type;
  :func:`joint_shown`: the unit kincal shows a joint's values in (deg, mm, rev for a multi-turn motor);
* ``MM``, ``DEG``: display factors, an SI value times the factor is in that unit
  (``0.0012 * MM == 1.2`` mm; ``1.2 / MM`` m); ``MRAD`` likewise (1 rad = 1000 mrad);
* :func:`number` formats a number, a value that rounds to zero without a sign ("0.0000", never "-0.0000");
  :func:`display` writes a parameter value as mm or deg by its kind; :func:`in_display` turns a
  set's statistics (m, rad) into mm and mrad, each key named with its unit;
* :func:`length_mistakes`: the factors positions read in the wrong length unit are off by.

A leaf module: it imports nothing of kincal.
"""
from __future__ import annotations

import math
import re
from typing import Iterable

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6}  # SI value (m) of one unit
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "rev": 2.0 * math.pi}  # SI value (rad) of one unit (rev: a motor's revolutions)
OTHER_LENGTHS = {"cm": 1e-2, "inch": 0.0254}  # units files are sometimes written in: named in advice only

MM = 1e3  # mm per m
DEG = 180.0 / math.pi  # deg per rad
MRAD = 1e3  # mrad per rad


def unit_factor(unit: str, kind: str, where: str = "", error: type[Exception] = ValueError) -> float:
    """SI factor of a length ('m', 'mm', 'um') or angle ('rad', 'deg') unit; ``error`` (prefixed with
    ``where``) names the choices when the unit is unknown."""
    table = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
    if unit not in table:
        raise error(f"{where}unknown {kind} unit '{unit}'; use one of {', '.join(table)}")
    return table[unit]


def joint_units(types: Iterable[str], length_unit: str, angle_unit: str, where: str = "",
                error: type[Exception] = ValueError) -> list[str | None]:
    """Each input's unit: ``angle_unit`` for a revolute joint, ``length_unit`` for a prismatic one, None for a
    covariate (a temperature or a time: its number as written); both units are checked first, length then angle
    (:func:`unit_factor`, with ``where`` and ``error``)."""
    unit_factor(length_unit, "length", where, error), unit_factor(angle_unit, "angle", where, error)
    return [angle_unit if t == "revolute" else None if t == "covariate" else length_unit for t in types]


def joint_shown(types: Iterable[str], periodic: Iterable[bool]) -> list[tuple[str, float]]:
    """Each joint's unit as kincal shows its values, with the factor from SI (a value in rad or m times it):
    "deg" for a revolute joint, "mm" for a prismatic one, "rev" for a revolute joint that does not repeat every
    turn (``periodic`` False: a motor driving a travel through a screw, a hexapod leg's, whose turns add up).

    >>> [(u, round(f, 4)) for u, f in joint_shown(["revolute", "prismatic", "revolute"], [True, False, False])]
    [('deg', 57.2958), ('mm', 1000.0), ('rev', 0.1592)]
    """
    return [("mm", MM) if t != "revolute" else ("deg", DEG) if p else ("rev", 1.0 / ANGLE_UNITS["rev"])
            for t, p in zip(types, periodic)]


def joint_factors(types: Iterable[str], length_unit: str, angle_unit: str, where: str = "",
                  error: type[Exception] = ValueError) -> list[float]:
    """SI factor of each input's unit (:func:`joint_units`, both units checked; rad or m per unit, 1 for a
    covariate)."""
    units = joint_units(types, length_unit, angle_unit, where, error)
    return [1.0 if u is None else {**LENGTH_UNITS, **ANGLE_UNITS}[u] for u in units]


SHOWN = {"length": ("mm", MM), "angle": ("deg", DEG), "ratio": ("%", 100.0)}  # a parameter's value by its kind
FINE = {"length": ("mm", MM), "angle": ("mrad", MRAD), "ratio": ("‰", 1e3)}  # its small changes: σ, steps, limits


def number(value: float, spec: str = "") -> str:
    """``value`` formatted by ``spec`` (Python's format mini-language), a value that rounds to zero without a sign.

    Every number kincal writes for a person goes through it: a correction of -1e-9 mm is "0.0000", not
    "-0.0000" (nor "+0.0000"), whatever ``spec`` asks for its sign.

    Parameters
    ----------
    value : float
        The number, in the unit it is shown in.
    spec : str, optional
        The format specification, e.g. ".4f" or "+.2f" (default "": Python's ``str``).

    Returns
    -------
    str
        The text.

    Examples
    --------
    >>> number(-0.00002, ".4f"), number(-0.00002, "+.4f"), number(-0.2, "+.4f"), number(-0.0, "g")
    ('0.0000', '0.0000', '-0.2000', '0')
    """
    text = f"{value:{spec}}"
    mantissa = re.split("[eE]", text)[0]
    if re.search("[1-9]", mantissa) or not re.search("[0-9]", mantissa):  # a digit of its own, or inf/nan
        return text
    return f"{0.0:{spec.replace('+', '')}}"  # (a '+' in a spec is its sign: kincal pads with spaces)


def display(value: float, kind: str, signed: bool = True, digits: tuple[int, int] = (4, 5)) -> str:
    """A parameter value as engineers read it: lengths in mm, angles in deg, ratios (an actuator's
    scale) in % (``kind``: "length", "angle" or "ratio"); ``digits``: decimals for mm and % and for deg."""
    unit, factor = SHOWN[kind]
    spec = f"{'+' if signed else ''}.{digits[kind == 'angle']}f"
    return f"{number(value * factor, spec)} {unit}"


def fine(value: float, kind: str, spec: str = ".3g") -> str:
    """A small change of a parameter (a σ, a step, a limit) in mm, mrad or ‰ by its ``kind``, formatted by ``spec``."""
    unit, factor = FINE[kind]
    return f"{number(value * factor, spec)} {unit}"


STAT_UNITS = {"mean": "mm", "rms": "mm", "max": "mm", "mean_abs": "mm", "distance_error": "mm", "drift": "mm",
              "mean_rotation": "mrad", "rms_rotation": "mrad", "max_rotation": "mrad"}  # statistics in m or rad


def in_display(stats: dict) -> dict:
    """A set's statistics (an observation type's ``stats()``: m and rad, :data:`STAT_UNITS`) with those
    values in mm and mrad under keys that name the unit ("mean" -> "mean_mm", "mean_rotation" ->
    "mean_mrad"), per-group statistics too; other keys as they are; None stays None."""
    def shown(key: str, value):
        factor = MM if STAT_UNITS[key] == "mm" else MRAD
        return None if value is None else [v * factor for v in value] if isinstance(value, list) else value * factor
    out = {}
    for key, value in stats.items():
        if key in STAT_UNITS:
            out[f"{key.removesuffix('_rotation')}_{STAT_UNITS[key]}"] = shown(key, value)
        else:
            out[key] = [in_display(g) for g in value] if key == "groups" else value
    return out


def length_mistakes() -> dict[float, tuple[tuple[str, str], ...]]:
    """The factors by which positions read in the wrong length unit must be multiplied to be right, nearest 1 first:
    each with its (unit the numbers are in, unit they were read in) pairs; read in one of LENGTH_UNITS, written in
    any length unit kincal names (OTHER_LENGTHS too).

    Examples
    --------
    >>> from kincal.units import length_mistakes
    >>> length_mistakes()[0.001]
    (('mm', 'm'), ('um', 'mm'))
    """
    table = {**LENGTH_UNITS, **OTHER_LENGTHS}
    out: dict[float, tuple[tuple[str, str], ...]] = {}
    for real, a in table.items():
        for read in (u for u in LENGTH_UNITS if u != real):
            f = float(f"{a / LENGTH_UNITS[read]:.12g}")
            out[f] = out.get(f, ()) + ((real, read),)
    return {f: out[f] for f in sorted(out, key=lambda f: abs(math.log(f)))}
