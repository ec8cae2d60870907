"""Whether a robot file's numbers are a robot's, judged in the units the file declares: the arm's size (its reach,
the link lengths added up), its tool point against the flange and its joint limits (a revolute joint's against
whole turns, a prismatic joint's against metres), naming the unit that would make them plausible (degrees written
in a rad file, radians in a deg file, mm in an m file, m in a mm file, cm)."""
from __future__ import annotations

from typing import Iterator

import numpy as np

from ..errors import ModelError
from ..units import ANGLE_UNITS, LENGTH_UNITS, OTHER_LENGTHS
from .robot import Robot
from .serial import ChainRobot
from .wrapped import Wrapped

MAX_TOOL = 2.0  # m: no tool point lies farther from the flange; larger values are mm written as m
MIN_REACH = 0.005  # m: no robot arm's links add up to less (the smallest arms reach 0.3 m: written in m as mm, 0.3 mm)
MAX_REACH = 20.0  # m: ... nor to more (the largest reach about 4.7 m: written in cm as m, 470 m)
TYPICAL_REACH = 1.0  # m: of the units that make an arm plausible, the one nearest this (in ratio) is named
MAX_TURNS = 2.0  # turns each way from zero: no revolute joint's limit lies farther (UR ±1, ABB IRB 120 axis 6 ±1.11)
MAX_TRAVEL = MAX_REACH  # m: no prismatic joint's limit lies farther from zero (the longest robot tracks)
MIN_TRAVEL = 1e-3  # m: a robot whose every prismatic joint stays within this of zero was written in m as mm
# the unit a joint's limits look like when they are too large (WIDE) or, all of them, too small (NARROW) in the
# unit the file declares: degrees in a rad file, mm in an m file; radians in a deg file, m in a mm file
WIDE = {"rad": "deg", "m": "mm"}
NARROW = {"deg": "rad", "mm": "m"}


def check_limits(robot: Robot, label: str, length_unit: str = "m", angle_unit: str = "rad",
                 declared: bool = True, fmt: str = "") -> None:
    """Refuse joint limits no robot has, naming the joint, its limits as written and the unit they look like.

    A revolute joint (one that repeats every turn: a motor that drives a screw is not) whose limit lies more than
    ``MAX_TURNS`` (2) turns from zero, or a prismatic one whose limit lies more than ``MAX_TRAVEL`` (20 m) from
    zero, is refused (in a rad file the numbers look like degrees, in an m file like mm); so is a robot whose every
    revolute joint stays within 2 turns' worth of degrees (±12.57 deg: radians written in a deg file) or whose
    every prismatic joint stays within ``MIN_TRAVEL`` (1 mm: metres written in a mm file). Unlimited joints
    (±inf) and covariates are left alone. A wrapped robot's inner joints (a transmission's chain) are judged too.

    Parameters
    ----------
    robot : Robot
        The robot as read, SI units (limits in rad and m).
    label : str
        The file, named first in the message.
    length_unit : str, optional
        The length unit the file's values were read in (default "m").
    angle_unit : str, optional
        The angle unit the file's values were read in (default "rad").
    declared : bool, optional
        Whether the file declares its units (default True); without a ``units`` key the advice is to add one.
    fmt : str, optional
        The format when it fixes the units (e.g. "URDF": radians and metres); the advice is then to write the limits
        in them (default "": a kincal robot file, whose ``units`` key may say otherwise).

    Raises
    ------
    ModelError
        When a joint's limits are implausible, naming the joint, its limits in the file's unit and what to write.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models.plausible import check_limits
    >>> import dataclasses
    >>> robot = kincal.load_robot("ur5")
    >>> check_limits(robot, "ur5.yaml")  # ±360 deg, the elbow ±180 deg: nothing to say
    >>> wrong = robot.with_joints([dataclasses.replace(j, lower=j.lower * 180 / np.pi, upper=j.upper * 180 / np.pi)
    ...                            for j in robot.joints])  # the degrees read as radians
    >>> check_limits(wrong, "ur5.yaml")
    Traceback (most recent call last):
    ...
    kincal.errors.ModelError: ur5.yaml: joint j1's limits [-360, 360] rad reach 57.3 turns from zero; no ...
    """
    for level in _levels(robot):
        angle = level.periodic
        length = np.array([t == "prismatic" for t in level.joint_types], bool)
        _check_kind(level, angle, ANGLE_UNITS[angle_unit], angle_unit, MAX_TURNS * 2 * np.pi, label, declared, fmt)
        _check_kind(level, length, LENGTH_UNITS[length_unit], length_unit, MAX_TRAVEL, label, declared, fmt)


def _levels(robot: Robot) -> Iterator[Robot]:
    """The robot, then each robot it is built on (a transmission's chain, an error model's geometry)."""
    yield robot
    while isinstance(robot, Wrapped):
        robot = robot.inner
        yield robot


def _check_kind(robot: Robot, which: np.ndarray, factor: float, unit: str, bound: float, label: str,
                declared: bool, fmt: str = "") -> None:
    """One kind of joint (``which``: angles or lengths) against ``bound`` (SI, each way from zero), written in
    ``unit`` (``factor``: SI per unit): a joint beyond it, or every one within the NARROW unit's share of it."""
    if not which.any():
        return
    lo, hi = robot.lower[which], robot.upper[which]
    names = [n for n, w in zip(robot.joint_names, which) if w]
    reach = np.maximum(np.where(np.isfinite(lo), np.abs(lo), 0.0), np.where(np.isfinite(hi), np.abs(hi), 0.0))
    kind = "angles" if unit in ANGLE_UNITS else "lengths"
    table = ANGLE_UNITS if unit in ANGLE_UNITS else LENGTH_UNITS
    if reach.max() > bound:
        k = int(np.argmax(reach))
        far = (f"{reach[k] / (2 * np.pi):.3g} turns from zero; no revolute joint turns more than {MAX_TURNS:g} turns "
               f"each way" if kind == "angles" else f"{reach[k]:.3g} m from zero; no joint travels beyond "
               f"{MAX_TRAVEL:g} m")
        raise ModelError(f"{label}: joint {names[k]}'s limits {_written(lo[k], hi[k], factor)} {unit} reach {far}: "
                         + _advice(WIDE.get(unit), unit, kind, lo[k], hi[k], table, declared, fmt))
    small = NARROW.get(unit)
    if small is None or not np.all(np.isfinite(lo) & np.isfinite(hi)):
        return
    if (reach.max() / factor * table[small] <= bound) if kind == "angles" else reach.max() <= MIN_TRAVEL:
        k = int(np.argmax(reach))
        what = "revolute" if kind == "angles" else "prismatic"
        raise ModelError(f"{label}: every {what} joint's limits lie within ±{reach[k] / factor:.4g} {unit} (joint "
                         f"{names[k]}: {_written(lo[k], hi[k], factor)} {unit}); no robot moves this little in every "
                         f"joint: " + _advice(small, unit, kind, lo[k], hi[k], table, declared, fmt))


def _written(lo: float, hi: float, factor: float) -> str:
    return f"[{lo / factor:.6g}, {hi / factor:.6g}]"


def _advice(other: str | None, unit: str, kind: str, lo: float, hi: float, table: dict, declared: bool,
            fmt: str = "") -> str:
    """What to write: the limits in the file's unit when they look like ``other``, else to check them."""
    if other is None:
        return f"check the limits (the file's {kind} are in {unit})"
    meant = table[other] / table[unit]  # SI as meant per SI as read
    words = {"deg": "degrees", "rad": "radians", "mm": "mm", "m": "metres"}
    if fmt:
        return (f"the limits look like {words[other]}; {fmt} {kind} are in {words[unit]}: write them in {unit} "
                f"({_written(lo * meant, hi * meant, table[unit])})")
    key = "angle" if kind == "angles" else "length"
    where = "" if declared else " (the default: the file has no 'units' key)"
    how = f"set '{key}: {other}' in its 'units'" if declared else f"add 'units: {{{key}: {other}}}'"
    return (f"the limits look like {words[other]} while the file's {kind} are in {unit}{where}: write them in "
            f"{unit} ({_written(lo * meant, hi * meant, table[unit])}), or {how} and write every {key} in "
            f"{words[other]}")


def arm_size(robot: Robot) -> tuple[float, str]:
    """The robot's size, m, and what it is: a serial chain's reach (the distances from its base frame through each
    joint to the flange added up, prismatic joints at 0, the tool point left out), else (a closed chain) its
    largest length parameter other than the base frame's and the tool point's.

    Parameters
    ----------
    robot : Robot
        Any robot, SI units; a wrapped one (a transmission, an error model) is judged by the chain it is built on.

    Returns
    -------
    size : float
        The reach or largest length, m.
    what : str
        "reach" or "largest length".

    Examples
    --------
    >>> import kincal
    >>> from kincal.models.plausible import arm_size
    >>> size, what = arm_size(kincal.load_robot("ur5"))  # 89.159 + 425 + 392.25 + 109.15 + 94.65 + 82.3 mm
    >>> round(size, 6), what
    (1.192509, 'reach')
    >>> arm_size(kincal.load_robot("hexapod"))[1]
    'largest length'
    """
    inner = list(_levels(robot))[-1]
    if isinstance(inner, ChainRobot):  # its points: the world origin, each joint's, the tool point (here the flange)
        flange = inner.with_tool_point(np.zeros(3)) if inner.has_tool_point else inner
        points = flange.link_points(np.zeros((1, inner.n_joints)))
        if points is not None:  # a chain declares them
            return float(_norm(np.diff(points[0, 1:], axis=0)).sum()), "reach"
    own = [abs(x) for n, k, x in zip(inner.params.names, inner.params.kinds, inner.params.values)
           if k == "length" and n.split(".")[0] not in ("base", "tool")]
    return float(max(own, default=0.0)), "largest length"


def check_size(robot: Robot, label: str, length_unit: str = "m", declared: bool = True) -> None:
    """Refuse a robot whose size or tool point no robot has, naming the length unit that would make it one.

    The arm's size (:func:`arm_size`) must lie within ``MIN_REACH`` (5 mm) and ``MAX_REACH`` (20 m) (a size of 0,
    a chain without links, is not judged), and its tool point within ``MAX_TOOL`` (2 m) of the flange. Otherwise the
    unit named is the one, of m, mm, um, cm and inch, that brings the size nearest 1 m within those bounds (for
    the tool point: mm, m, cm or inch, the first that brings it within 2 m).

    Parameters
    ----------
    robot : Robot
        The robot as read, SI units.
    label : str
        The file, named first in the message.
    length_unit : str, optional
        The length unit the file's values were read in (default "m").
    declared : bool, optional
        Whether the file declares its units (default True); without a ``units`` key the advice is to add one.

    Raises
    ------
    ModelError
        When the size or the tool point is implausible, with both in m and the unit they look like.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models.plausible import check_size
    >>> robot = kincal.load_robot("ur5")
    >>> check_size(robot, "ur5.yaml")  # a reach of 1.19 m, the reflector 31 mm from the flange
    >>> check_size(robot.with_tool_point([0.0, 0.09, 31.0]), "ur5.yaml")  # the reflector written in mm
    Traceback (most recent call last):
    ...
    kincal.errors.ModelError: ur5.yaml: the tool point (0, 0.09, 31) m lies 31 m from the flange; no tool ...
    """
    factor = LENGTH_UNITS[length_unit]
    size, what = arm_size(robot)
    where = "" if declared else " (the default: the file has no 'units' key)"
    if size != 0 and not MIN_REACH <= size <= MAX_REACH:  # NaN too
        unit = size_unit(size / factor)
        look = "check the lengths and the 'units' key" if unit is None else (
            f"the lengths look like {unit} (a {what} of {size / factor * _UNITS[unit]:.3g} m): "
            + _length_advice(unit, declared))
        raise ModelError(f"{label}: the {'arm' if what == 'reach' else 'robot'}'s {what} is {size:.4g} m as read in "
                         f"{length_unit}{where}, implausible for a robot ({MIN_REACH * 1e3:g} mm to {MAX_REACH:g} m): "
                         f"{look}")
    tool = robot.tool_point() if robot.has_tool_point else np.zeros(3)
    far = float(_norm(tool))
    if far > MAX_TOOL:
        written = tool / factor
        unit = next((u for u in ("mm", "m", "cm", "inch") if u != length_unit
                     and far / factor * _UNITS[u] <= MAX_TOOL), None)
        text = ", ".join(f"{v:.6g}" for v in written)
        look = "check the tool point and the 'units' key" if unit is None else (
            f"these look like {unit}: write them in {length_unit} ("
            + ", ".join(f"{v * _UNITS[unit] / factor:.6g}" for v in written) + ")")
        raise ModelError(f"{label}: the tool point ({text}) {length_unit} lies {far:.4g} m from the flange{where}; no "
                         f"tool reaches beyond {MAX_TOOL:g} m (the {what} of the robot itself is {size:.3g} m): {look}")


_UNITS = {**LENGTH_UNITS, **OTHER_LENGTHS}  # m per unit: the units a file's lengths may be written in


def _norm(v: np.ndarray) -> np.ndarray:
    """The length of each vector (..., 3), without overflow for a value like 1e300 (its square would)."""
    return np.hypot(np.hypot(v[..., 0], v[..., 1]), v[..., 2])


def size_unit(written: float) -> str | None:
    """The length unit (m, mm, um, cm, inch) that makes a size written as ``written`` a robot's, the one nearest
    TYPICAL_REACH in ratio (None: none does)."""
    fits = [(abs(np.log(written * f / TYPICAL_REACH)), u) for u, f in _UNITS.items()
            if MIN_REACH <= written * f <= MAX_REACH]
    return min(fits)[1] if fits else None


def _length_advice(unit: str, declared: bool) -> str:
    """How to write a file's lengths that look like ``unit``."""
    if unit in LENGTH_UNITS:
        return f"set 'length: {unit}' in its 'units'" if declared else f"add 'units: {{length: {unit}}}'"
    return (f"robot files take {', '.join(LENGTH_UNITS)}: write the lengths in mm (x{_UNITS[unit] / 1e-3:g}) and "
            + ("set 'length: mm' in its 'units'" if declared else "add 'units: {length: mm}'"))
