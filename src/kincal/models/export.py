"""Calibrated kinematics back out: URDF (the user's own file with only joint origins changed, or a new
one for DH/MDH chains) and Universal Robots' ``calibration.yaml`` (``kinematics:`` for the ROS driver).

Both are built from the joint frames of a chain at zero joint values. Jₖ is the frame whose z axis
is joint k's axis, with the joint's zero offset applied, relative to the robot's base frame (the
base frame parameters, which say where the tracker saw the robot, are not part of a robot
description). Any chain then reads J₁ Rz(q₁) (J₁⁻¹J₂) Rz(q₂) … Jₙ Rz(qₙ) (Jₙ⁻¹F), F the flange,
because everything between two joint motions is constant. Each export is checked before it is
returned: the written numbers, rebuilt by the file format's own rules, must reproduce kincal's
forward kinematics to 1e-9 m at random poses, else nothing is written.
"""
from __future__ import annotations

import hashlib
import os
import re
import xml.etree.ElementTree as ET
import xml.parsers.expat
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .._atomic import write_text_atomic
from ..errors import ModelError
from ..units import MM
from .chain import ROT
from .robot import TOOL_NAMES, Robot
from .serial import ChainRobot, SerialRobot
from .transforms import rot_zyx, zyx_from_matrix
from .urdf import ORIGIN, URDFRobot, axis_norm, fixed_frame, read_urdf, rpy_matrix
from .yaml_io import NOT_ROBOT_FILES, check_robot_output, robot_to_yaml

EXPORT_TOL = 1e-9  # m: an export must reproduce the model this closely
TOOL_LINK = "tool_point"  # the link a URDF export carries a non-zero tool point on, unless named
UR_SECTIONS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
_ALIGN = {0: rot_zyx(0.0, np.pi / 2, 0.0), 1: rot_zyx(0.0, 0.0, -np.pi / 2), 2: np.eye(3)}  # z onto x, y, z


def _h(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _motion(motion: str, axis: int, value: float) -> np.ndarray:
    if motion == ROT:
        angles = [0.0, 0.0, 0.0]  # rot_zyx takes (rz, ry, rx)
        angles[2 - axis] = value
        return _h(rot_zyx(*angles), np.zeros(3))
    return _h(np.eye(3), np.eye(3)[axis] * value)


def joint_frames(robot: Robot, slide: bool = False) -> tuple[list[np.ndarray], np.ndarray]:
    """The joint frames of a chain at zero joint values, and its flange frame.

    Jₖ is the frame whose z axis is joint k's axis, with the joint's zero offset applied; F is the end of
    the chain without the tool point. Both are relative to the robot's base frame (the base frame parameters
    are left out). Any chain then reads J₁ Rz(q₁) (J₁⁻¹J₂) Rz(q₂) … Jₙ Rz(qₙ) (Jₙ⁻¹F).

    Parameters
    ----------
    robot : Robot
        A geometric serial chain (DH/MDH or URDF).
    slide : bool, optional
        Move each Jₖ along its axis by the translation along it that follows the joint (a DH d): the link
        frames robot descriptions use, e.g. UR's shoulder_link at d1 (default False).

    Returns
    -------
    frames : list of ndarray, shape (4, 4)
        Jₖ for every joint, homogeneous transforms in the base frame, m.
    flange : ndarray, shape (4, 4)
        The flange frame F in the base frame, m.

    Raises
    ------
    ModelError
        When the robot has joint-value terms (an error model) or is not a serial chain.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.models import joint_frames
    >>> frames, flange = joint_frames(kincal.load_robot("ur5"))
    >>> len(frames), frames[0].shape
    (6, (4, 4))
    >>> np.round(frames[1][:3, 3], 6) + 0.0  # joint 2's axis passes d1 above the base, m
    array([0.      , 0.      , 0.089159])
    """
    _geometric_only(robot)
    if not isinstance(robot, ChainRobot):
        raise ModelError(f"robot '{robot.name}' ({robot.structure}) is not a serial chain: it has no URDF or UR form")
    values = robot.chain_values().copy()  # a URDF chain's joint-motion columns too
    values[robot.params.indices(robot.base_params() + TOOL_NAMES)] = 0.0
    M, frames, ops = np.eye(4), [], robot.chain.ops
    value = [op.offset + (values[op.param] if op.param >= 0 else 0.0) for op in ops]
    for k, op in enumerate(ops):
        if op.joint >= 0:
            frames.append(M @ _h(_ALIGN[op.axis], np.zeros(3)) @ _motion(op.motion, 2, value[k]))
            after = ops[k + 1] if k + 1 < len(ops) else None
            if slide and after is not None and after.motion != ROT and after.joint < 0 and after.axis == op.axis:
                frames[-1] = frames[-1] @ _motion(after.motion, 2, value[k + 1])
        M = M @ _motion(op.motion, op.axis, value[k])
    return frames, M


def _geometric_only(robot: Robot) -> None:
    if robot.error_model != "geometric":
        raise ModelError(f"robot '{robot.name}' ({robot.structure}): joint-value terms ({robot.error_model}) have no place in a "
                         f"URDF or UR file; command the robot with 'kincal compensate', or calibrate with --model geometric "
                         f"for an export")


def _xyz_rpy(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rz, ry, rx = zyx_from_matrix(T[:3, :3])
    return T[:3, 3].copy(), np.array([rx, ry, rz])


def _fmt(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def _origin_tag(xyz, rpy) -> str:
    return f'<origin xyz="{" ".join(map(_fmt, xyz))}" rpy="{" ".join(map(_fmt, rpy))}"/>'


# ---- Universal Robots calibration file ------------------------------------------------------------
def ur_calibration(robot: Robot, base_yaw: float | None = None, driver_base: np.ndarray | None = None,
                   tip_in_flange: np.ndarray | None = None) -> tuple[str, dict]:
    """Write the ``kinematics:`` calibration file of UR's ROS driver for a 6-joint revolute chain.

    The six entries (shoulder … wrist_3) are each joint's origin, the parent-to-joint transform at zero angle
    (x y z m, roll pitch yaw rad), relative to UR's Base frame: ``driver_base`` where the robot's description
    places it, else the model's base frame turned by ``base_yaw`` about z. What lies beyond the wrist-3 frame, which
    the file cannot hold, is returned in the summary for the controller. The file is checked before it is returned:
    its numbers, rebuilt by the driver's rules in UR's Base, must reproduce the model within 1e-9 m at random
    poses.

    Parameters
    ----------
    robot : Robot
        A geometric serial chain with 6 revolute joints (DH/MDH or URDF).
    base_yaw : float, optional
        Turn of UR's Base frame from the model's base frame about z, rad, for a description without UR's Base
        (default 0, right for kincal's DH ur5, whose base is UR's Base; π for a URDF whose base_link faces the
        other way); not with ``driver_base``.
    driver_base : ndarray, shape (4, 4), optional
        UR's Base as the robot's description places it (a URDF's link ``base``: :func:`controller_base`), in the
        model's base frame, m: any pose, a mounting's shift and tilt included (the file is relative to UR's Base,
        wherever the arm stands); not with ``base_yaw``.
    tip_in_flange : ndarray, shape (4, 4), optional
        The chain's tip frame in UR's tool flange frame (a URDF's link ``tool0``: :func:`ur_flange`), m; the file's
        wrist-3 frame is then that flange (as ur_description makes it ``tool0``), the rest goes into the TCP, and
        the check also compares the file's wrist-3 frame with the model's flange, within 1e-9 m and rad (default:
        the chain ends at the flange, as kincal's DH UR arms do).

    Returns
    -------
    text : str
        The file's text, ending with its ``hash:`` line.
    summary : dict
        "flange_to_tcp" (4×4 nested list, m: the chain's tip frame in the file's wrist-3 frame), "tool_point"
        (3 floats, m, in the wrist-3 frame: the TCP for the controller) and "base_yaw" (rad: UR's Base's turn
        about z from the model's base frame, of its x axis where a mounting also shifts or tilts it).

    Raises
    ------
    ModelError
        When both ``base_yaw`` and ``driver_base`` are given, the robot has joint-value terms, is not a serial
        chain, does not have 6 revolute joints, its flange
        ``tip_in_flange`` is not on the last axis, or the file would not reproduce the model in ``driver_base``.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models import ur_calibration
    >>> text, summary = ur_calibration(kincal.load_robot("ur5"))
    >>> for line in text.splitlines()[:8]:
    ...     print(line)
    kinematics:
      shoulder:
        x: 0
        y: 0
        z: 0.089159
        roll: 0
        pitch: 0
        yaw: 0
    >>> sorted(summary)
    ['base_yaw', 'flange_to_tcp', 'tool_point']
    """
    frames, flange = ur_arm(robot)
    if base_yaw is not None and driver_base is not None:
        raise ModelError(f"robot '{robot.name}': UR's Base is either placed by the description (driver_base) or "
                         f"turned by base_yaw from the model's base, not both")
    base = _h(rot_zyx(base_yaw or 0.0, 0.0, 0.0), np.zeros(3)) if driver_base is None else \
        np.asarray(driver_base, dtype=float)  # UR's Base in the model's base frame
    tip = np.eye(4) if tip_in_flange is None else np.asarray(tip_in_flange, dtype=float)
    frames, flange = ur_layout(frames, flange @ np.linalg.inv(tip), base)  # UR's link frames; flange: UR's
    chain = [np.eye(4)] + frames
    origins = [np.linalg.inv(a) @ b for a, b in zip(chain[:-1], chain[1:])]
    rest = np.linalg.inv(frames[-1]) @ flange
    d = rest[2, 3]  # a shift along the last axis commutes with its rotation: it belongs to wrist_3
    origins[-1] = origins[-1] @ _h(np.eye(3), [0.0, 0.0, d])
    rest = _h(np.eye(3), [0.0, 0.0, -d]) @ rest
    if tip_in_flange is not None:
        _on_last_axis(robot, rest)
    rest = rest @ tip  # the flange to the chain's tip: the controller's TCP frame without the tool point
    entries = {name: _xyz_rpy(T) for name, T in zip(UR_SECTIONS, origins)}
    lines = ["kinematics:"]
    for name, (xyz, rpy) in entries.items():
        lines.append(f"  {name}:")
        lines += [f"    {k}: {_fmt(v)}" for k, v in zip(ORIGIN, (*xyz, *rpy))]
    digest = hashlib.sha256("\n".join(lines).encode()).hexdigest()
    text = "\n".join(lines + [f"  hash: calib_{int(digest[:15], 16)}", ""])
    tool = robot.tool_point()
    summary = {"flange_to_tcp": rest.tolist(), "tool_point": (rest[:3, :3] @ tool + rest[:3, 3]).tolist(),
               "base_yaw": float(np.arctan2(base[1, 0], base[0, 0]))}
    _check(robot, lambda q: _ur_forward(entries, q, rest, tool), "UR calibration file", base)
    if tip_in_flange is not None:
        _check_flange(robot, entries, base, tip)
    return text, summary


def _on_last_axis(robot: Robot, rest: np.ndarray) -> None:
    """Refuse a flange (``rest``: its pose in the file's wrist-3 frame, 4x4, m) off the last joint's axis or turned
    from it: UR's tool flange sits on wrist 3's axis, z along it, and the driver puts tool0 at the wrist-3 frame."""
    R = rest[:3, :3]
    turn = float(np.arctan2(np.linalg.norm(R - R.T) / np.sqrt(8.0), (np.trace(R) - 1.0) / 2.0))  # exact near 0
    off = float(np.linalg.norm(rest[:3, 3]))
    if off > EXPORT_TOL or turn > EXPORT_TOL:
        raise ModelError(f"robot '{robot.name}': the URDF's tool flange lies {off * MM:.4g} mm off the last joint's "
                         f"axis and turns {np.degrees(turn):.4g}° from the frame on it; UR's flange (tool0) is on "
                         f"wrist 3's axis, z along it, so the driver's file cannot place it: not UR's description")


def _check_flange(robot: Robot, entries: dict, driver: np.ndarray, tip: np.ndarray) -> None:
    """The file's wrist-3 frame in UR's Base ``driver`` (the driver's tool0: ur_description's wrist_3 -> flange ->
    tool0 is the identity) must be the model's flange, its chain's tip with ``tip`` (the tip in the flange, 4x4, m)
    undone, at random poses within 1e-9 m and rad: the file checked against the URDF's own tool0, not the tool point
    alone."""
    q = robot.sample_joints(50, seed=0)
    plain = robot.with_params(dict.fromkeys(robot.base_params(), 0.0))
    points, rotations = plain.with_tool_point([0.0, 0.0, 0.0]).forward(q), plain.flange_rotation(q)
    to_base, to_flange, gap = np.linalg.inv(driver), np.linalg.inv(tip), 0.0
    for qi, p, R in zip(q, points, rotations):
        T = np.eye(4)
        for (xyz, rpy), angle in zip(entries.values(), qi):
            T = T @ _h(rpy_matrix(*rpy), xyz) @ _motion(ROT, 2, angle)
        gap = max(gap, float(np.abs(T - to_base @ _h(R, p) @ to_flange).max()))
    if not gap <= EXPORT_TOL:
        raise ModelError(f"the UR calibration file would place tool0 {gap * MM:.3g} mm from the URDF's; nothing "
                         f"written (please report this)")


PARALLEL = 0.1  # sine of the angle below which two joint axes count as parallel (no common normal of their own)
UR_AXES = (90.0, 0.0, 0.0, 90.0, 90.0)  # deg: UR's angles between neighbouring joint axes, 1 ⟂ 2 ∥ 3 ∥ 4 ⟂ 5 ⟂ 6


def ur_arm(robot: Robot) -> tuple[list[np.ndarray], np.ndarray]:
    """The joint frames and flange of a robot with UR's structure (:func:`joint_frames`): 6 revolute joints whose
    neighbouring axes are square or parallel as UR's (``UR_AXES``, each within the angle whose sine is PARALLEL),
    whatever the names; ModelError naming the angles otherwise (a spherical wrist, a KUKA's or a Kinova Jaco's 3 ⟂
    4: UR's driver would build another arm from the file)."""
    frames, flange = joint_frames(robot)  # a serial chain's (ModelError for another)
    if robot.n_joints != 6 or any(t != "revolute" for t in robot.joint_types):
        raise ModelError(f"robot '{robot.name}': a UR calibration file holds 6 revolute joints, the robot has "
                         f"{robot.n_joints} ({', '.join(robot.joint_types)})")
    z = [f[:3, 2] for f in frames]
    angles = [float(np.degrees(np.arccos(np.clip(abs(a @ b), 0.0, 1.0)))) for a, b in zip(z[:-1], z[1:])]
    if any(abs(np.sin(np.radians(a - want))) > PARALLEL for a, want in zip(angles, UR_AXES)):
        raise ModelError(f"robot '{robot.name}' is not a Universal Robots arm: UR's joint axes are 1 ⟂ 2, 2 ∥ 3 ∥ 4, "
                         f"4 ⟂ 5, 5 ⟂ 6 (angles between neighbours {', '.join(f'{a:.0f}°' for a in UR_AXES)}), this "
                         f"robot's are {', '.join(f'{a:.1f}°' for a in angles)}; UR's driver would build another arm "
                         f"from the file: export --format urdf or yaml")
    return frames, flange


def ur_layout(frames: list[np.ndarray], flange: np.ndarray, base: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The joint frames (each z on its joint's axis) moved along and turned about their axes to where UR's
    description puts its link frames (its DH layout), and the flange, both in UR's Base frame ``base`` (4x4, in the
    model's base frame): the origin where the axis meets the next one's common normal (where they intersect, the
    intersection), for an axis parallel to the next the point nearest the previous origin, for the last the point
    nearest the flange; x the previous frame's x (Base's for the first, the flange's for the last) made square to
    the axis. Any chain's
    layout (a URDF's frames lie elsewhere on the axes) then gives UR's own numbers; the motion is unchanged: a
    joint turns about the same line whatever point and x its frame takes on it."""
    to_base = np.linalg.inv(base)
    F, end = [to_base @ f for f in frames], to_base @ flange
    out, o_prev, x_prev, y_prev = [], np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    for k, f in enumerate(F):
        p, z = f[:3, 3], f[:3, 2]
        o = _foot(p, z, F[k + 1][:3, 3], F[k + 1][:3, 2]) if k + 1 < len(F) else None
        if o is None:
            target = end[:3, 3] if k + 1 == len(F) else o_prev
            o = p + z * float(np.dot(target - p, z))
        x_prev = end[:3, 0] if k + 1 == len(F) else x_prev  # the last: the flange's x (its zero in wrist_3's yaw)
        x = x_prev - z * float(x_prev @ z)
        x = x if np.linalg.norm(x) > PARALLEL else y_prev - z * float(y_prev @ z)  # x along the axis: y instead
        x = x / np.linalg.norm(x)
        out.append(_h(np.column_stack([x, np.cross(z, x), z]), o))
        o_prev, x_prev, y_prev = o, x, np.cross(z, x)
    return out, end


def _foot(p1: np.ndarray, z1: np.ndarray, p2: np.ndarray, z2: np.ndarray) -> np.ndarray | None:
    """The point on the line (p1, z1) where its common normal with the line (p2, z2) meets it; None for lines
    nearer parallel than PARALLEL (unit directions z, m)."""
    c = float(z1 @ z2)
    if np.linalg.norm(np.cross(z1, z2)) < PARALLEL:
        return None
    t, _ = np.linalg.solve(np.array([[1.0, -c], [c, -1.0]]), np.array([(p2 - p1) @ z1, (p2 - p1) @ z2]))
    return p1 + t * z1


def _ur_forward(entries: dict, q: np.ndarray, rest: np.ndarray, tool: np.ndarray) -> np.ndarray:
    """The UR file's chain in UR's Base: per joint origin and Rz(q), then flange-to-TCP and the tool."""
    out = []
    for qi in q:
        T = np.eye(4)
        for (xyz, rpy), angle in zip(entries.values(), qi):
            T = T @ _h(rpy_matrix(*rpy), xyz) @ _motion(ROT, 2, angle)
        out.append((T @ rest @ np.append(tool, 1.0))[:3])
    return np.array(out)


def _check(robot: Robot, forward, what: str, frame: np.ndarray | None = None) -> None:
    """The exported kinematics must reproduce the model (base frame removed; seen from ``frame``, 4x4 in the model's
    base frame, where given) at random poses."""
    q = robot.sample_joints(50, seed=0)
    model = robot.with_params(dict.fromkeys(robot.base_params(), 0.0)).forward(q)
    if frame is not None:
        model = model @ frame[:3, :3] - frame[:3, 3] @ frame[:3, :3]  # inv(frame) applied to each row
    gap = float(np.max(np.linalg.norm(forward(q) - model, axis=1)))
    if not gap <= EXPORT_TOL:
        raise ModelError(f"the {what} would place the tool {gap * MM:.3g} mm from the calibrated model; "
                         f"nothing written (please report this)")


# ---- URDF ----------------------------------------------------------------------------------------
def urdf_text(robot: Robot, source: str | None = None, tool_link: str | None = None,
              joint_names: Sequence[str] | None = None) -> str:
    """Write the URDF of a calibrated serial chain.

    A URDF robot needs the text it was read from: only the ``<origin>`` of its moving joints changes (comments,
    ``<gazebo>``, ``<transmission>`` … stay as they are). A DH/MDH robot gets a new URDF: base_link, one link
    per joint, flange (a UR arm, its joints named as UR's, gets UR's link names and tool0). The tool point (a
    probe, a ball the calibration fitted) becomes a fixed joint and link. The result is read back and checked
    against the model, tool point included, within 1e-9 m at random poses.

    Parameters
    ----------
    robot : Robot
        A geometric serial chain (DH/MDH or URDF).
    source : str, optional
        For a URDF robot, the text of the URDF it was read from (required there; unused otherwise).
    tool_link : str, optional
        Name of the link that carries the tool point (default "tool_point" when the tool point is not zero,
        else none).
    joint_names : sequence of str, optional
        DH/MDH robot: the URDF joints' names, one per joint, distinct (default: the robot file's
        ``names:``, else the joints' own).

    Returns
    -------
    str
        The URDF text, lengths in m and angles in rad.

    Raises
    ------
    ModelError
        When the robot has joint-value terms or is not a serial chain, a URDF robot comes without its
        ``source``, a DH/MDH joint has no velocity or effort limit, a name is not valid or taken, or the URDF
        would not reproduce the model.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.models import read_urdf, urdf_text
    >>> robot = kincal.load_robot("ur5")
    >>> text = urdf_text(robot)
    >>> text.splitlines()[2]
    '<robot name="ur5">'
    >>> back = read_urdf(text, "ur5.urdf", base_link="base_link_inertia", tip_link="tool_point")  # the DH base
    >>> q = robot.sample_joints(5, seed=1)
    >>> bool(np.allclose(back.forward(q), robot.forward(q), atol=1e-9))
    True
    """
    _geometric_only(robot)
    tool_link = tool_link_of(robot, tool_link)
    if isinstance(robot, URDFRobot):
        if source is None:
            raise ModelError(f"robot '{robot.name}' came from a URDF: give that file (--from) so only its joint "
                             f"origins change")
        text, base, tip = _edit_urdf(robot, source), robot.source.get("base_link"), robot.source.get("tip_link")
    elif isinstance(robot, SerialRobot):
        _limits_given(robot)
        text, base, tip = _new_urdf(robot, joint_names)
    else:
        raise ModelError(f"robot '{robot.name}' ({robot.structure}) is not a serial chain: it has no URDF form")
    if tool_link:
        if tip is None:
            raise ModelError(f"robot '{robot.name}': its robot file names no URDF tip link (source: tip_link) to "
                             f"attach the tool link to")
        text = _add_tool(text, robot, tip, tool_link)
    check = read_urdf(text, "exported URDF", base, tool_link or tip, (0.0, 0.0, 0.0))  # the whole chain
    _check(robot, check.forward, "exported URDF")
    return text


def tool_link_of(robot: Robot, name: str | None) -> str | None:
    """The link a URDF export puts the tool point on: ``name`` (a valid name, :func:`_urdf_name`), else TOOL_LINK
    when the tool point is not zero (it would be dropped otherwise), else none."""
    if name or not robot.has_tool_point:
        return _urdf_name(name, "tool link", "--tool-link", TOOL_LINK) if name else name
    return TOOL_LINK if np.any(robot.tool_point() != 0.0) else None


def _edit_urdf(robot: URDFRobot, source: str) -> str:
    """The URDF text with the ``<origin>`` of each moving joint (a ``<joint>`` of ``<robot>`` itself, not a
    ``<transmission>``'s reference) replaced, self-closing or not, or added, and its ``<axis xyz>`` made the unit
    vector the URDF specification asks for where the file's is not; every other byte as it was."""
    data, spans = source.encode(), _joint_spans(source)
    edits = []
    for j in robot.moving:
        if j.name not in spans:
            raise ModelError(f"the URDF has no joint '{j.name}': give the file the robot was read from (--from)")
        after_tag, origin, axis = spans[j.name]
        tag = _origin_tag(*robot.origin(j)).encode()
        edits.append((*origin, tag) if origin else (after_tag, after_tag, b"\n    " + tag))
        if axis and axis_norm(j) is not None:  # a parser that does not normalise it reads another joint
            unit = " ".join(map(_fmt, np.divide(j.axis, np.linalg.norm(j.axis))))
            edits.append((*axis, re.sub(rb"""(\bxyz\s*=\s*)(["'])[^"']*\2""", rf'\g<1>"{unit}"'.encode(),
                                        data[axis[0]:axis[1]], count=1)))
    for start, end, tag in sorted(edits, reverse=True):
        data = data[:start] + tag + data[end:]
    return data.decode()


def _joint_spans(text: str) -> dict[str, tuple[int, tuple[int, int] | None, tuple[int, int] | None]]:
    """Per ``<joint>`` child of the root: the UTF-8 byte offset after its start tag, the span of its first
    ``<origin>`` element (start tag to end tag, or the self-closing tag), None without one, and the span of its
    first ``<axis>`` start tag (None without one)."""
    data, parser = text.encode(), xml.parsers.expat.ParserCreate()
    spans: dict[str, tuple[int, tuple[int, int] | None, tuple[int, int] | None]] = {}
    path: list[tuple[str, int]] = []  # open elements: name, start offset
    joint: list[str] = []  # the root's joint being read

    def start(name: str, attrs: dict) -> None:
        at = parser.CurrentByteIndex
        if len(path) == 1 and name == "joint" and attrs.get("name") not in spans:
            joint[:] = [attrs.get("name", "")]
            spans[joint[0]] = (_tag_end(data, at), None, None)
        if len(path) == 2 and name == "axis" and joint and spans[joint[0]][2] is None:
            spans[joint[0]] = (*spans[joint[0]][:2], (at, _tag_end(data, at)))
        path.append((name, at))

    def end(name: str) -> None:
        _, at = path.pop()
        if len(path) == 2 and name == "origin" and joint and spans[joint[0]][1] is None:
            close = _tag_end(data, at)
            stop = close if data[close - 2:close] == b"/>" else data.index(b">", parser.CurrentByteIndex) + 1
            spans[joint[0]] = (spans[joint[0]][0], (at, stop), spans[joint[0]][2])
        joint[:] = [] if len(path) == 1 else joint

    parser.StartElementHandler, parser.EndElementHandler = start, end
    try:
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as exc:
        raise ModelError(f"the URDF is not valid XML ({exc})") from None
    return spans


def _tag_end(data: bytes, at: int) -> int:
    """The offset after the tag that starts at ``at`` (its '>' outside quoted attribute values)."""
    quote = None
    for k in range(at, len(data)):
        c = data[k:k + 1]
        if quote:
            quote = None if c == quote else quote
        elif c in (b'"', b"'"):
            quote = c
        elif c == b">":
            return k + 1
    raise ModelError("the URDF ends inside a tag")


UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint")
UR_LINKS = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link")
UR_TOOL0 = _h(rpy_matrix(np.pi / 2, 0.0, np.pi / 2), np.zeros(3))  # flange -> tool0 in UR's description


def _new_urdf(robot: SerialRobot, names: Sequence[str] | None = None) -> tuple[str, str, str]:
    """A URDF of a DH/MDH chain: one link per joint (its frame on the joint's axis where the DH d puts
    it), then ``flange``; joints named as the robot stack names them, with the file's velocity and
    effort limits (:func:`_limits_given`: a file without them is refused, never written as 0). A robot file that names a
    ``base_link`` frame (ROS) gets it as the root, with the DH base as link ``base``. A UR arm (its
    joints named as UR's) gets UR's description: base_link, base_link_inertia and base, the links
    shoulder_link … wrist_3_link, flange and tool0 (the DH flange frame). Returns the text, the DH
    base link's name and the tip link's."""
    frames, flange = joint_frames(robot, slide=True)
    names = _joint_names(robot, names)
    ur = tuple(names) == UR_JOINTS
    links = UR_LINKS if ur else tuple(f"link_{k + 1}" for k in range(robot.n_joints))
    ros = robot.named_frames().get("base_link")
    base = _dh_base_link(robot, names)
    lines = ['<?xml version="1.0"?>', f"<!-- {robot.name} calibrated with kincal; joint origins in m and rad -->",
             f'<robot name="{robot.name}">', '  <link name="base_link"/>']
    if ros:
        lines += _fixed("base_link", "base", np.linalg.inv(_h(*ros)))
        lines += _fixed("base_link", "base_link_inertia", np.linalg.inv(_h(*ros))) if ur else []
    parent = base
    for k, (a, b) in enumerate(zip([np.eye(4)] + frames[:-1], frames)):
        lines += _fixed(parent, links[k], np.linalg.inv(a) @ b, names[k], robot.joint_types[k],
                        ['    <axis xyz="0 0 1"/>', f"    {_limit(robot, k)}"])
        parent = links[k]
    rest = np.linalg.inv(frames[-1]) @ flange
    if ur:
        lines += _fixed(parent, "flange", rest @ np.linalg.inv(UR_TOOL0)) + _fixed("flange", "tool0", UR_TOOL0)
    else:
        lines += _fixed(parent, "flange", rest)
    return "\n".join(lines + ["</robot>", ""]), base, "tool0" if ur else "flange"


def _dh_base_link(robot: SerialRobot, names: Sequence[str]) -> str:
    """The link of a DH/MDH robot's new URDF at its DH base (where its base frame parameters put it):
    base_link_inertia for a UR arm (its joints named ``names`` as UR's), ``base`` below a robot file's ROS
    ``base_link``, else the root base_link itself."""
    ur = tuple(names) == UR_JOINTS
    return "base_link_inertia" if ur else "base" if robot.named_frames().get("base_link") else "base_link"


def _fixed(parent: str, child: str, T: np.ndarray, name: str = "", kind: str = "fixed",
           extra: Sequence[str] = ()) -> list[str]:
    """A joint (fixed unless ``kind``; named ``parent-child`` unless ``name``) from ``parent`` to a new
    link ``child`` at the transform T (4x4), with ``extra`` lines (axis, limit) in it."""
    return [f'  <link name="{child}"/>', f'  <joint name="{name or f"{parent}-{child}"}" type="{kind}">',
            f'    <parent link="{parent}"/>', f'    <child link="{child}"/>', f"    {_origin_tag(*_xyz_rpy(T))}",
            *extra, "  </joint>"]


def _urdf_name(name: str, what: str, flag: str, example: str) -> str:
    """``name`` when a URDF can hold it as written and kincal read it back (no whitespace, control character,
    ``<>&"'`` nor dot: kincal's parameter names are ``<joint>.x``, and a tool link names its joint), else a
    ModelError naming ``what`` and ``flag``."""
    bad = sorted({c for c in name if c.isspace() or not c.isprintable() or c in "<>&\"'."})
    if bad:
        raise ModelError(f"{what} name {name!r} ({flag}): a URDF name here holds no whitespace and none of "
                         f"< > & \" ' . (it has {', '.join(repr(c) for c in bad)}); choose one like '{example}'")
    return name


def _joint_names(robot: SerialRobot, names: Sequence[str] | None) -> tuple[str, ...]:
    """The URDF joint names: ``names`` (one per joint, distinct, each :func:`_urdf_name`) or the robot file's."""
    if names is None:
        return robot.stack_names
    names = tuple(_urdf_name(str(n).strip(), "joint", "--joint-names", "joint_1") for n in names)
    if len(names) != robot.n_joints or len(set(names)) != len(names) or not all(names):
        raise ModelError(f"joint names {list(names)}: give {robot.n_joints} distinct names, one per joint "
                         f"({', '.join(robot.joint_names)})")
    return names


def _limit(robot: SerialRobot, k: int) -> str:
    """The ``<limit>`` of moving joint k: position limits, velocity and effort (given: :func:`_limits_given`)."""
    joint = robot.moving[k]
    extra = f' effort="{joint.effort:.10g}" velocity="{joint.velocity:.10g}"'
    return f'<limit lower="{_fmt(robot.lower[k])}" upper="{_fmt(robot.upper[k])}"{extra}/>'


def _limits_given(robot: Robot) -> None:
    """Refuse a URDF of a DH/MDH chain with a moving joint whose velocity or effort limit the robot file does not
    give: the URDF format requires both in every ``<limit>`` (ROS's parser, urdfdom, refuses the file without)."""
    missing = [j.name for j in robot.moving if j.velocity is None or j.effort is None] \
        if isinstance(robot, SerialRobot) else []
    if missing:
        raise ModelError(f"robot '{robot.name}': a URDF needs a velocity and an effort limit on every moving joint "
                         f"(ROS's parser refuses a <limit> without them), and the robot file gives none for "
                         f"{', '.join(missing)}: add 'velocity:' (the file's angle unit per second, or its length "
                         f"unit per second for a prismatic joint) and 'effort:' (N·m, or N) to those joints, from "
                         f"the arm's data sheet")


def _add_tool(text: str, robot: Robot, tip: str, name: str) -> str:
    if re.search(rf'<link\b[^>]*\bname\s*=\s*["\']{re.escape(name)}["\']', text):
        raise ModelError(f"the URDF already has a link '{name}': choose another tool link name")
    block = _fixed(tip, name, _h(np.eye(3), robot.tool_point()))
    end = text.rindex("</robot>")
    return text[:end] + "\n".join(block) + "\n" + text[end:]


FORMATS = ("urdf", "ur", "yaml")


def export_robot(robot: Robot, path, fmt: str | None = None, source_path=None, tool_link: str | None = None,
                 base_yaw: float | None = None, length_unit: str = "m", angle_unit: str = "rad",
                 joint_names: Sequence[str] | None = None, base: Mapping[str, float] | None = None) -> dict:
    """Write a robot as a URDF, a UR calibration file or a kincal robot YAML file.

    The file is written atomically, and only after its kinematics have been checked against the model (see
    :func:`urdf_text` and :func:`ur_calibration`).

    Parameters
    ----------
    robot : Robot
        The robot (URDF and UR: a geometric serial chain).
    path : str or path-like
        The file to write.
    fmt : str, optional
        "urdf", "ur" or "yaml" (``FORMATS``); default from the file name: .urdf, .xacro or .xml is a URDF,
        anything else kincal YAML.
    source_path : str or path-like, optional
        URDF of a URDF robot: the URDF it was read from (default: the file its ``source`` names).
    tool_link : str, optional
        URDF: the link that carries the tool point (default "tool_point" when the tool point is not zero).
    base_yaw : float, optional
        UR: turn of UR's Base frame from the model's base frame about z, rad (default: :func:`ur_base_yaw`, from a
        URDF's link ``base``, else 0).
    length_unit : str, optional
        YAML: unit of the lengths in the file (default "m").
    angle_unit : str, optional
        YAML: unit of the angles in the file (default "rad").
    joint_names : sequence of str, optional
        URDF of a DH/MDH robot: the joints' names (default: the robot file's ``names:``).
    base : mapping of str to float, optional
        YAML: the base frame's parameters to write (the nominal model's: where the robot stands in its own
        description) in place of the measurement frame a calibration found, m and rad; default: as they are. The
        URDF and UR file hold no measurement frame either.

    Returns
    -------
    dict
        A summary: "format", "base_frame" (the base parameters the calibration found, m and rad: where the
        tracker saw the robot, not part of a robot description), "base_frame_link" for a URDF robot or a URDF export
        (the link those parameters place: the chain's base link, a DH robot's DH base, e.g. base_link_inertia);
        URDF: "tool_link", "root_link" (the written file's root); UR: "flange_to_tcp", "tool_point" and "base_yaw", what
        belongs on the controller.

    Raises
    ------
    ValueError
        When ``fmt`` is not one of ``FORMATS``.
    ModelError
        When the robot has no form in that format, a source URDF is missing, not readable or not the robot's (or
        given for a robot that does not come from a URDF), kincal YAML is named as a URDF or XML file, or the
        export would not reproduce the model.

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     summary = kincal.export_robot(robot, os.path.join(folder, "ur5.urdf"))
    ...     first = open(os.path.join(folder, "ur5.urdf")).readline().strip()
    >>> summary["format"], summary["tool_link"], first
    ('urdf', 'tool_point', '<?xml version="1.0"?>')
    >>> summary["base_frame"]["base.x"]
    0.0
    """
    fmt = fmt or ("urdf" if os.path.splitext(str(path))[1].lower() in NOT_ROBOT_FILES else "yaml")
    if fmt not in FORMATS:
        raise ValueError(f"format '{fmt}' is not one of {', '.join(FORMATS)}")
    summary: dict = {"format": fmt, "base_frame": {n: float(robot.params[n]) for n in robot.base_params()}}
    if isinstance(robot, URDFRobot):
        summary.update(base_frame_link=robot.source.get("base_link"))
    if fmt == "urdf":
        text = urdf_text(robot, _source(robot, source_path), tool_link, joint_names)
        summary.update(tool_link=tool_link_of(robot, tool_link), root_link=_root_link(text))
        if isinstance(robot, SerialRobot):
            summary.update(base_frame_link=_dh_base_link(robot, _joint_names(robot, joint_names)))
    elif fmt == "ur":
        ur_arm(robot)  # UR's structure first: a KUKA's URDF may have a link 'base' too
        driver = controller_base(robot, source_path)  # UR's Base as the URDF places it (None: not a URDF robot)
        yaw = ur_base_yaw(robot, base_yaw, source_path)  # a --base-yaw checked against it
        text, extra = ur_calibration(robot, yaw if driver is None else None, driver, ur_flange(robot, source_path))
        summary.update(extra)
    else:
        check_robot_output(path)
        mounted = robot.with_params({n: float(base[n]) for n in robot.base_params()}) if base else robot
        text = robot_to_yaml(mounted, length_unit, angle_unit, os.path.dirname(os.fspath(path)))
    write_text_atomic(path, text)
    return summary


def _root_link(text: str) -> str:
    """The root link of a URDF text (checked: read back by :func:`urdf_text`): the link no joint is a child of."""
    root = ET.fromstring(text)
    children = {c.get("link") for c in (j.find("child") for j in root.findall("joint")) if c is not None}
    return next(str(el.get("name")) for el in root.findall("link") if el.get("name") not in children)


CONTROLLER_BASE = "base"  # ROS-Industrial's link for the controller's base frame (UR's Base, KUKA's $ROBROOT)


def controller_base(robot: Robot, source_path: str | None = None) -> np.ndarray | None:
    """The controller's base frame (4x4, m) in a URDF robot's base frame: the pose of the URDF's link ``base``,
    composed along the fixed joints between it and the chain's base link (ROS-Industrial's descriptions hang it on
    base_link; ur_description's ``base`` is UR's Base, base_link turned 180° about z, and a chain from the root
    ``world`` reaches it through base_link); None for another robot or a URDF without that link. ModelError when
    a moving joint lies between the two links."""
    if not isinstance(robot, URDFRobot):
        return None
    text = _source(robot, source_path)
    return None if text is None else fixed_frame(text, str(robot.source.get("base_link")), CONTROLLER_BASE)


UR_FLANGES = (("tool0", np.eye(4)), ("flange", UR_TOOL0))  # ROS-Industrial's links at the tool flange, -> tool0


def ur_flange(robot: Robot, source_path: str | None = None) -> np.ndarray | None:
    """The chain's tip frame in UR's tool flange frame (4x4, m) for a URDF robot: the pose of the tip link in the
    URDF's ``tool0`` (z out of the flange, the frame the controller's TCP is given in), else in its ``flange`` (x
    out, turned to tool0 as ur_description does), composed along the fixed joints between them (a probe link below
    tool0, or wrist_3_link above it); None for another robot (its chain ends at the flange). ModelError when the
    URDF has neither link fixed to the tip: the driver's file would end at the tip, wherever it is."""
    if not isinstance(robot, URDFRobot):
        return None
    text, tip, why = _source(robot, source_path), str(robot.source.get("tip_link")), []
    for link, to_tool0 in UR_FLANGES:
        try:
            T = fixed_frame(str(text), tip, link)  # the link in the tip's frame
        except ModelError as exc:
            why.append(str(exc).removeprefix("the URDF's ").split(":")[0])
            continue
        if T is not None:
            return np.linalg.inv(T @ to_tool0)
        why.append(f"no link '{link}'")
    raise ModelError(f"robot '{robot.name}': UR's tool flange, where the driver's file ends and the controller's TCP "
                     f"starts, is the URDF's link 'tool0' or 'flange', and neither is fixed to the chain's tip "
                     f"'{tip}' ({'; '.join(why)}): calibrate with --tip-link tool0 (or a link fixed to it), or add "
                     f"ROS-Industrial's tool0 to the URDF at the flange and give it with --from")


def ur_base_yaw(robot: Robot, given: float | None, source_path: str | None = None) -> float:
    """The turn of UR's Base about z from the model's base frame, rad: from the URDF's link ``base``
    (:func:`controller_base`, UR's Base wherever a mounting puts it) where it has one, of its x axis (``given`` must
    be that turn, and is refused where the link is more than a turn about z), else ``given``, else 0 for a DH/MDH
    robot (kincal's DH UR arms stand in UR's Base). ModelError when ``given`` disagrees, or a URDF robot has neither
    (never a guessed 0: a wrong turn negates every x and y)."""
    T = controller_base(robot, source_path)
    if T is None and isinstance(robot, URDFRobot) and given is None:
        raise ModelError(f"robot '{robot.name}': its URDF has no link '{CONTROLLER_BASE}' (UR's Base, the frame the "
                         f"driver's kinematics file is in) to place the file in: give --base-yaw, the turn of UR's "
                         f"Base about z from the chain's base link '{robot.source.get('base_link')}' (ur_description:"
                         f" 180 from base_link)")
    if T is None or not isinstance(robot, URDFRobot):
        return 0.0 if given is None else given
    yaw, link = float(np.arctan2(T[1, 0], T[0, 0])), robot.source.get("base_link")
    if given is not None and np.abs(T - _h(rot_zyx(yaw, 0.0, 0.0), np.zeros(3))).max() > 1e-9:
        shift = ", ".join(f"{v * MM:.4g}" for v in T[:3, 3])
        raise ModelError(f"robot '{robot.name}': the URDF's link '{CONTROLLER_BASE}' is UR's Base, placed by the "
                         f"fixed joints from {link} (at {shift} mm: more than a turn about z, a mounting), and the "
                         f"file is written in it; --base-yaw does not apply: leave it out")
    if given is not None and abs(np.angle(np.exp(1j * (given - yaw)))) > 1e-9:
        raise ModelError(f"robot '{robot.name}': the URDF's link '{CONTROLLER_BASE}' is UR's Base, turned "
                         f"{np.degrees(yaw):.3f}° about z from {link}; --base-yaw {np.degrees(given):.3f} disagrees: "
                         f"leave it out")
    return yaw


def _source(robot: Robot, source_path) -> str | None:
    """The text of the URDF a URDF robot was read from: ``source_path`` (--from), else the file its ``source``
    records (a robot file holds it relative to its own folder); checked to be that URDF (:func:`_same_source`)."""
    if not isinstance(robot, URDFRobot):
        if source_path:
            raise ModelError(f"{source_path}: a source URDF (--from) applies to robots read from a URDF; robot "
                             f"'{robot.name}' is a {robot.structure} model, whose URDF is written new")
        return None
    path = source_path or robot.source.get("file")
    if not path:
        raise ModelError(f"robot '{robot.name}' came from a URDF: give that file (--from)")
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else "not text"
        raise ModelError(f"{path}: cannot read the URDF robot '{robot.name}' was calibrated from ({why}); give it "
                         f"with --from") from None
    _same_source(robot, text, str(path), given=bool(source_path))
    return text


def _same_source(robot: URDFRobot, text: str, label: str, given: bool) -> None:
    """ModelError unless ``text`` is the URDF the robot was read from: the sha256 its ``source`` records (a file
    found there, not given with --from, must match it), else the chain as the robot has it, every name, type,
    axis, limit and constant origin (a calibration changes only the moving joints' positions and small turns),
    and the moving joints' positions too where the recorded file is still there to give them."""
    digest = robot.source.get("sha256")
    if digest and hashlib.sha256(text.encode()).hexdigest() == digest:
        return
    recorded = robot.source.get("file", "not recorded")
    if digest and not given:
        raise ModelError(f"{label}: changed since robot '{robot.name}' was calibrated from it (its sha256 is not "
                         f"the one the robot file records); if it still describes that robot, give it with --from "
                         f"{label}")
    try:
        other = read_urdf(text, label, robot.source.get("base_link"), robot.source.get("tip_link"))
    except ModelError as exc:
        why = str(exc).removeprefix(f"{label}: ")
        if why.startswith(("not valid XML", "the root element", "a xacro file")):
            raise ModelError(f"{label}: not a URDF ({why}); --from takes the URDF robot '{robot.name}' was "
                             f"calibrated from ({recorded})") from None
        raise ModelError(f"{label}: not the URDF robot '{robot.name}' was calibrated from ({recorded}): {why}; give "
                         f"that file with --from") from None
    differ = _differences(robot, other, _recorded_chain(robot) if given else None)
    if differ:
        raise ModelError(f"{label}: not the URDF robot '{robot.name}' was calibrated from ({recorded}): "
                         f"{'; '.join(differ[:3])}{'; …' if len(differ) > 3 else ''}; give that file with --from")


def _recorded_chain(robot: URDFRobot) -> tuple | None:
    """The chain's joints as the recorded source file has them, when it is there with its recorded sha256 (the
    nominal positions of the moving joints, which the calibrated robot no longer holds); else None."""
    path, digest = robot.source.get("file"), robot.source.get("sha256")
    try:
        text = Path(str(path)).read_text(encoding="utf-8-sig") if path and digest else ""
    except (OSError, UnicodeDecodeError):
        return None
    if not text or hashlib.sha256(text.encode()).hexdigest() != digest:
        return None
    return read_urdf(text, str(path), robot.source.get("base_link"), robot.source.get("tip_link")).joints


def _differences(robot: URDFRobot, other: URDFRobot, nominal: tuple | None = None) -> list[str]:
    """What ``other`` (a URDF's chain) has unlike ``robot`` beyond what a calibration changes: names, types, limits,
    and the nominal geometry (constant origins, axes, the moving joints' turns; their positions too with
    ``nominal``, the source's joints)."""
    out = [] if other.name == robot.name else [f"the robot is '{other.name}', not '{robot.name}'"]
    names = [j.name for j in other.joints]
    if names != [j.name for j in robot.joints]:
        return out + [f"its chain is {', '.join(names)}, not {', '.join(j.name for j in robot.joints)}"]
    for a, b in zip(robot.joints, other.joints):
        if a.type != b.type:
            out.append(f"joint '{a.name}' is {b.type}, not {a.type}")
        if not np.allclose([a.lower, a.upper], [b.lower, b.upper], rtol=0.0, atol=1e-9):
            out.append(f"joint '{a.name}' has limits [{b.lower:.6g}, {b.upper:.6g}], not [{a.lower:.6g}, "
                       f"{a.upper:.6g}] (rad, m for a prismatic joint)")
    gaps = {}  # joint: (position m, turn rad) of its origin and axis against the source's
    for a, b in zip(nominal or robot.joints, other.joints):
        shift = float(np.linalg.norm(np.subtract(a.xyz, b.xyz))) if nominal or not a.moving else 0.0
        axes = [np.asarray(v, float) / np.linalg.norm(v) for v in (a.axis, b.axis)]
        turn = max(_angle(rpy_matrix(*a.rpy).T @ rpy_matrix(*b.rpy)), float(np.arccos(np.clip(axes[0] @ axes[1],
                                                                                              -1.0, 1.0))))
        if shift > 1e-9 or turn > 1e-9:
            gaps[a.name] = (shift, turn)
    if gaps:
        shift, turn = (max(g[k] for g in gaps.values()) for k in (0, 1))
        out.append(f"its nominal geometry differs by up to {shift * MM:.4g} mm and {np.degrees(turn):.4g}° "
                   f"(joint{'s' if len(gaps) > 1 else ''} {', '.join(gaps)}: origin or axis)")
    return out


def _angle(R: np.ndarray) -> float:
    """The rotation angle of a rotation matrix, rad."""
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


