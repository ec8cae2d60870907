"""Whether a robot file's numbers are a robot's, judged in the units the file declares: its joint limits (a
revolute joint's against whole turns, a prismatic joint's against metres), naming the unit that would make them
plausible (degrees written in a rad file, radians in a deg file, mm in an m file, m in a mm file)."""
from __future__ import annotations

from typing import Iterator

import numpy as np

from ..errors import ModelError
from ..units import ANGLE_UNITS, LENGTH_UNITS
from .robot import Robot
from .wrapped import Wrapped

MAX_TURNS = 2.0  # turns each way from zero: no revolute joint's limit lies farther (UR ±1, ABB IRB 120 axis 6 ±1.11)
MAX_TRAVEL = 20.0  # m: no prismatic joint's limit lies farther from zero (the longest robot tracks)
MIN_TRAVEL = 1e-3  # m: a robot whose every prismatic joint stays within this of zero was written in m as mm
# the unit a joint's limits look like when they are too large (WIDE) or, all of them, too small (NARROW) in the
# unit the file declares: degrees in a rad file, mm in an m file; radians in a deg file, m in a mm file
WIDE = {"rad": "deg", "m": "mm"}
NARROW = {"deg": "rad", "mm": "m"}


def check_limits(robot: Robot, label: str, length_unit: str = "m", angle_unit: str = "rad",
                 declared: bool = True) -> None:
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
        _check_kind(level, angle, ANGLE_UNITS[angle_unit], angle_unit, MAX_TURNS * 2 * np.pi, label, declared)
        _check_kind(level, length, LENGTH_UNITS[length_unit], length_unit, MAX_TRAVEL, label, declared)


def _levels(robot: Robot) -> Iterator[Robot]:
    """The robot, then each robot it is built on (a transmission's chain, an error model's geometry)."""
    yield robot
    while isinstance(robot, Wrapped):
        robot = robot.inner
        yield robot


def _check_kind(robot: Robot, which: np.ndarray, factor: float, unit: str, bound: float, label: str,
                declared: bool) -> None:
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
                         + _advice(WIDE.get(unit), unit, kind, lo[k], hi[k], table, declared))
    small = NARROW.get(unit)
    if small is None or not np.all(np.isfinite(lo) & np.isfinite(hi)):
        return
    if (reach.max() / factor * table[small] <= bound) if kind == "angles" else reach.max() <= MIN_TRAVEL:
        k = int(np.argmax(reach))
        what = "revolute" if kind == "angles" else "prismatic"
        raise ModelError(f"{label}: every {what} joint's limits lie within ±{reach[k] / factor:.4g} {unit} (joint "
                         f"{names[k]}: {_written(lo[k], hi[k], factor)} {unit}); no robot moves this little in every "
                         f"joint: " + _advice(small, unit, kind, lo[k], hi[k], table, declared))


def _written(lo: float, hi: float, factor: float) -> str:
    return f"[{lo / factor:.6g}, {hi / factor:.6g}]"


def _advice(other: str | None, unit: str, kind: str, lo: float, hi: float, table: dict, declared: bool) -> str:
    """What to write: the limits in the file's unit when they look like ``other``, else to check them."""
    if other is None:
        return f"check the limits (the file's {kind} are in {unit})"
    meant = table[other] / table[unit]  # SI as meant per SI as read
    words = {"deg": "degrees", "rad": "radians", "mm": "mm", "m": "metres"}
    key = "angle" if kind == "angles" else "length"
    where = "" if declared else " (the default: the file has no 'units' key)"
    how = f"set '{key}: {other}' in its 'units'" if declared else f"add 'units: {{{key}: {other}}}'"
    return (f"the limits look like {words[other]} while the file's {kind} are in {unit}{where}: write them in "
            f"{unit} ({_written(lo * meant, hi * meant, table[unit])}), or {how} and write every {key} in "
            f"{words[other]}")
