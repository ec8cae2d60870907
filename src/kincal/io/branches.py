"""The branch bits each vendor language writes beside a Cartesian target, from joint values: KUKA's status
and turn (S, T), ABB's confdata (cf1, cf4, cf6, cfx), FANUC's CONFIG ('N U T', turns) and Yaskawa's RCONF
digits. One function per language, ``(robot, q) -> bits`` as the language writes them, for q the
controller's joint values (rad) of a six-axis arm; the geometry (axis lines, wrist centre) is the robot's
own (:mod:`kincal.models.arm`), so a calibrated arm gives its own bits. The vendors' manuals were not all
in reach: each rule names the sources it follows and what they disagree on. :data:`BITS` gives each
dialect's rule by name (URScript has none: its poses name no branch).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..errors import ModelError
from ..models.arm import six_axes
from ..models.robot import Robot

QUADRANT_DECIMALS = 9  # deg: a jointtarget's 90 read to rad and back must stay in quadrant 1, not 0
RCONF_DIGITS = 6  # flip, upper/lower arm, front/back, R, T, S: the digits the job data format defines


def kuka_status_turn(robot: Robot, q: np.ndarray) -> tuple[int, int]:
    """(S, T) of an E6POS. T: bit k−1 set where Ak < 0. S bit 0 (overhead): the wrist root (where A4, A5, A6
    meet) lies behind A1's axis in the A1 coordinate system (its x: A1's axis × A2's axis). S bit 1: the wrist
    root is in front of the line through the A2 and A3 axes — A3 at or beyond the stretched arm (atan(35/420)
    = 4.76° on a KR AGILUS, whose A4 is 35 mm off A3), the side of the usual teach pose (A2 −90°, A3 +90°:
    S 2). S bit 2: A5 in [−180°, 0°) or [180°, 360°).

    Sources (KUKA's own KSS 8 text was not in reach): KUKA's Expert Programming manual on bit 0 as quoted in
    robot-forum.com thread 7173; the forum's status-and-turn summary (T, bit 2); Beckhoff TF5200 "Status & Turn"
    (bit 1: wrist in front of the A2–A3 line; bit 2: A5 < 0); Siemens SINUMERIK ONE 6FC5398-2EP40-0BA0 pp. 710,
    713; robot-forum thread 45777 reports some KUKA documents wrong about bit 2 and, tested on a KR 60-3, that it
    follows A5's sign; real programs carry "S 2, T 2" and "S 6, T 50"."""
    return kuka_rows(robot, np.asarray(q, dtype=float)[None])[0]


def kuka_rows(robot: Robot, q: np.ndarray) -> list[tuple]:
    """:func:`kuka_status_turn` of each row of q (N, 6)."""
    q, points, axes, wrist = six_axes(robot, q, "KUKA status and turn")
    overhead = _dot(wrist - points[:, 0], np.cross(axes[:, 0], axes[:, 1])) < 0.0
    in_front = _dot(axes[:, 2], np.cross(points[:, 2] - points[:, 1], wrist - points[:, 2])) >= 0.0
    flipped = (q[:, 4] + np.pi) % (2.0 * np.pi) < np.pi
    s = overhead.astype(int) | in_front.astype(int) << 1 | flipped.astype(int) << 2
    turn = ((q < 0.0).astype(int) << np.arange(6)).sum(axis=1)
    return [(int(a), int(b)) for a, b in zip(s, turn)]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ni,ni->n", a, b)


def quadrant(angle):
    """(See :func:`quadrants`.)"""
    return int(quadrants(np.asarray([angle], dtype=float))[0])


def quadrants(angle: np.ndarray) -> np.ndarray:
    """ABB's quadrant numbers of joint angles (rad): floor(angle / 90°) — 0 for 0..90°, −1 for 0..−90°, …
    (RAPID confdata: "the current quadrant of the axis, as a positive or negative integer"), the angle
    rounded to 1e-9° first so that a written multiple of 90° keeps its quadrant through rad. On a boundary
    the manual does not say; floor puts −90° in −1."""
    return np.floor(np.round(np.degrees(angle), QUADRANT_DECIMALS) / 90.0).astype(int)


def abb_confdata(robot: Robot, q: np.ndarray) -> tuple[int, int, int, int]:
    """(cf1, cf4, cf6, cfx) of a robtarget: the quadrants of axes 1, 4, 6 and cfx = 4a + 2b + c, a = 1 with the
    wrist centre behind axis 1 (forward: axis 2 × axis 1), b = 1 with it behind the lower arm (the plane
    through the parallel axes 2 and 3), c = 1 with axis 5 negative — the manual's eight rows, whose three
    planes are its three singularities. Source: ABB, Technical reference manual RAPID Instructions, Functions
    and Data types, ``confdata``, as reproduced in py-opw-kinematics' AXIS_CONFIGURATION.md and ARTE's
    compute_configuration.m (ABB's own text was not in reach)."""
    q = np.asarray(q, dtype=float)
    if q.ndim != 1:
        raise ModelError(f"abb_confdata takes one joint vector (6,), got shape {q.shape}; abb_rows takes (N, 6)")
    return abb_rows(robot, q[None])[0]


def abb_rows(robot: Robot, q: np.ndarray) -> list[tuple]:
    """:func:`abb_confdata` of each row of q (N, 6)."""
    q, points, axes, wrist = six_axes(robot, q, "ABB confdata")
    arm = points[:, 2] - points[:, 1]
    arm -= _dot(arm, axes[:, 1])[:, None] * axes[:, 1]  # axes 2 and 3 are parallel: their common normal
    behind_axis1 = _dot(wrist - points[:, 0], np.cross(axes[:, 1], axes[:, 0])) < 0
    behind_arm = _dot(wrist - points[:, 1], np.cross(axes[:, 1], arm)) < 0
    cfx = 4 * behind_axis1.astype(int) + 2 * behind_arm.astype(int) + (q[:, 4] < 0).astype(int)
    cf = quadrants(q[:, [0, 3, 5]])
    return [(int(a), int(b), int(c), int(x)) for (a, b, c), x in zip(cf, cfx)]


def _fanuc_turns(angle: np.ndarray) -> np.ndarray:
    """FANUC's turn numbers of joint angles (rad): 0 on (−180°, 180°), ±1 from ±180° on, every 360°."""
    deg = np.degrees(angle)
    return np.where(deg >= 0, np.floor((deg + 180.0) / 360.0), -np.floor((180.0 - deg) / 360.0)).astype(int)


def fanuc_config(robot: Robot, q: np.ndarray) -> tuple[str, int, int, int]:
    """('F|N U|D T|B', turn of J1, turn of J4, turn of J6) of a Cartesian /POS entry, for the controller's
    J1…J6 (FANUC's J3 from the horizontal, as kincal's ``fanuc_*`` robots take them). F (flip) where J5 ≥ 0,
    N where J5 < 0 (the usual tool-down pose, J5 ≈ −90°, is N); U where the wrist centre is on the side of the
    upper arm (the J2 → J3 line) it takes at the zero pose, D on the other; T where it is in front of the plane
    through J1's axis across the arm, B behind. Turns: RoboDK's FANUC R-30iA post processor (``angle_2_turn``).
    Sources: Tesseract's ``getRobotConfig`` (robot_config.h, SwRI, Apache-2.0) for the letters; FANUC's own
    manual text was not in reach, and one web page states the flip letter the other way round."""
    return fanuc_rows(robot, np.asarray(q, dtype=float)[None])[0]


def fanuc_rows(robot: Robot, q: np.ndarray) -> list[tuple]:
    """:func:`fanuc_config` of each row of q (N, 6)."""
    q, points, axes, wrist = six_axes(robot, q, "FANUC CONFIG letters")
    elbow = _dot(np.cross(points[:, 2] - points[:, 1], wrist - points[:, 2]), axes[:, 1])
    front = _dot(np.cross(axes[:, 1], axes[:, 0]), wrist - points[:, 0])
    turns = _fanuc_turns(q[:, [0, 3, 5]])
    return [(f"{'F' if j5 >= 0 else 'N'} {'U' if e > 0 else 'D'} {'T' if f >= 0 else 'B'}", int(a), int(b), int(c))
            for j5, e, f, (a, b, c) in zip(q[:, 4], elbow, front, turns)]


def _beyond_180(angle: np.ndarray) -> np.ndarray:
    """1 where an axis angle (rad) is outside −180° < θ ≤ 180° (the "≥ 180" digit), else 0."""
    return (~((-math.pi < angle) & (angle <= math.pi))).astype(int)


def yaskawa_rconf(robot: Robot, q: np.ndarray, digits: int = RCONF_DIGITS) -> tuple[int, ...]:
    """The ``///RCONF`` digits (flip, upper/lower arm, front/rear, R, T, S ≥ 180°, then zeros to ``digits``:
    jobs carry 6, 8 or 24) of the controller's S, L, U, R, B, T. Flip: 0 where B ≥ 0, 1 where B < 0. Upper/lower:
    seen along the L axis, the angle at the U axis from the L axis to the wrist centre below 180° (upper, 0) or
    above (lower, 1). Front/rear: the wrist centre in front of the S axis (along L axis × S axis: 0) or behind
    (1). R, T, S: 0 for −180° < θ ≤ 180°, else 1. Sources: the DX100/NX100 "Job Data Format" (the order),
    Yaskawa America's YMConnect SDK header (enums FlipOrNoFlip, UpperOrLower, FrontOrBack, AxisAngle); the NX100
    operator's manual (3.9) words the flip by the R axis instead, and its R/T/S table's negative side was not in
    reach."""
    return yaskawa_rows(robot, np.asarray(q, dtype=float)[None], digits)[0]


def yaskawa_rows(robot: Robot, q: np.ndarray, digits: int = RCONF_DIGITS) -> list[tuple]:
    """:func:`yaskawa_rconf` of each row of q (N, 6)."""
    q, points, axes, wrist = six_axes(robot, q, "Yaskawa RCONF digits")
    if digits < RCONF_DIGITS:
        raise ValueError(f"RCONF has at least {RCONF_DIGITS} digits, not {digits}")
    rear = (_dot(wrist - points[:, 0], np.cross(axes[:, 1], axes[:, 0])) < 0.0).astype(int)
    lower = (_dot(np.cross(points[:, 1] - points[:, 2], wrist - points[:, 2]), axes[:, 1]) > 0.0).astype(int)
    found = np.column_stack([(q[:, 4] < 0.0).astype(int), lower, rear, _beyond_180(q[:, [3, 5, 0]])])
    return [tuple(int(x) for x in row) + (0,) * (digits - RCONF_DIGITS) for row in found]


BITS: dict[str, Callable[[Robot, np.ndarray], tuple]] = {
    "krl": kuka_status_turn, "rapid": abb_confdata, "fanuc": fanuc_config, "inform": yaskawa_rconf}
ROWS: dict[str, Callable[[Robot, np.ndarray], list[tuple]]] = {
    "krl": kuka_rows, "rapid": abb_rows, "fanuc": fanuc_rows, "inform": yaskawa_rows}  # the same, row by row of (N, 6)
