"""Robots from URDF: the serial chain between two links, with the origin deviations of every moving joint.

A URDF joint places its child frame at ``origin`` (xyz, then rpy: R = Rz(yaw) Ry(pitch) Rx(roll)) in
the parent frame and then moves about or along ``axis``. kincal builds that chain from the standard
library's XML parser, with these parameters (stable names from the URDF joint names):

* the base frame ``base.x … base.rz`` (where the chain's base link stands in the measurement frame);
* per moving joint its origin: ``<joint>.x .y .z``, the position in the parent frame (nominal: the
  file's xyz), and ``<joint>.roll .pitch .yaw``, small rotations about the x, y and z axes of the
  joint's frame applied after the file's rpy (nominal 0). Deviations about the frame's own axes
  describe every small misalignment at any nominal orientation; deviations of the rpy angles
  themselves would lose one direction where a pitch is ±90° (as in most UR URDFs);
* the tool point ``tool.x/y/z`` in the tip link's frame.

A zero offset of the joint value is a rotation about (or translation along) the joint axis and is
therefore already one of these six. Fixed joints inside the chain are constant motions without
parameters: their deviations act like those of the next moving joint's origin. Continuous joints
are revolute joints without limits. An axis that is not +x, +y or +z is reached by constant
rotations around the joint motion; one that is not a unit vector is read as its direction (the URDF
specification's meaning), with a structure note naming the joint. ``mimic`` joints, closed loops, ``floating`` and ``planar``
joints are refused with the element's name. Identifiability then says which of these parameters
position data can determine (for a UR5: 27, as for DH with Hayati's β).
"""
from __future__ import annotations

import hashlib
import math
import re
import xml.etree.ElementTree as ET
from types import MappingProxyType
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .chain import AXES, ROT, TRANS, Chain, Op
from .parameters import Parameters
from .joint_space import JointSpace
from .plausible import MAX_REACH, check_limits
from .serial import POSE_KINDS, ChainRobot, chain_layout, check_mass
from .transforms import rot_zyx, zyx_from_matrix

ORIGIN = ("x", "y", "z", "roll", "pitch", "yaw")
MOVING = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
KNOWN = set(MOVING) | {"fixed", "floating", "planar"}


@dataclass(frozen=True)
class URDFJoint:
    """One joint of a URDF chain, as the file gives it.

    Parameters
    ----------
    name : str
        The joint's name in the URDF (parameter names are ``<name>.x`` …).
    type : str
        "revolute", "continuous" (revolute without limits), "prismatic" or "fixed".
    xyz : tuple of 3 float, optional
        The origin's position in the parent link's frame, m (default 0).
    rpy : tuple of 3 float, optional
        The origin's roll, pitch, yaw, rad: R = Rz(yaw) Ry(pitch) Rx(roll) (default 0).
    axis : tuple of 3 float, optional
        The joint axis in the joint's frame (default +x, as in URDF).
    lower : float, optional
        Lower limit, rad (m for a prismatic joint) (default -inf: unlimited).
    upper : float, optional
        Upper limit in the same unit (default +inf).
    mass : float, optional
        Mass of the child link, kg (URDF ``<inertial>``; default 0).
    com : tuple of 3 float, optional
        Centre of mass of the child link in its frame, m (default the origin).

    Raises
    ------
    ModelError
        When the mass is negative or not finite, or the centre of mass is not three finite numbers.

    Examples
    --------
    >>> from kincal.models import URDFJoint
    >>> elbow = URDFJoint("elbow", "revolute", xyz=(0.4, 0.0, 0.0), axis=(0.0, 0.0, 1.0), lower=-3.0, upper=3.0)
    >>> elbow.moving, elbow.rpy
    (True, (0.0, 0.0, 0.0))
    """

    name: str
    type: str  # revolute | continuous | prismatic | fixed
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    lower: float = -math.inf
    upper: float = math.inf
    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "com", check_mass(self.mass, self.com, f"joint '{self.name}'"))

    @property
    def moving(self) -> bool:
        return self.type != "fixed"


def _param_layout(joints: Sequence[URDFJoint]) -> tuple[list[str], list[str]]:
    return chain_layout((f"{j.name}.{k}", kind) for j in joints if j.moving for k, kind in zip(ORIGIN, POSE_KINDS))


@dataclass(frozen=True, eq=False, repr=False)
class URDFRobot(ChainRobot):
    """A serial chain read from a URDF (or from its kincal YAML), with the origin deviations of every moving joint.

    Read one with :func:`read_urdf` or :func:`load_robot`. Its parameters are the base frame, per moving joint
    ``<joint>.x .y .z`` (the origin's position, m) and ``<joint>.roll .pitch .yaw`` (small rotations about the
    joint frame's axes after the file's rpy, rad), then the tool point ``tool.x/y/z`` in the tip link's frame.

    Parameters
    ----------
    name : str
        The robot's name (the URDF's ``<robot name>``).
    joints : tuple of URDFJoint
        The chain's joints from the base link to the tip link, fixed ones included; at least one moves.
    params : Parameters
        The parameters in the layout above, SI units.
    description : str, optional
        Free text (default "").
    source : mapping of str to str, optional
        Where the chain came from: "file", "base_link", "tip_link", "sha256" (default empty); stored read-only.

    Attributes
    ----------
    joint_space : JointSpace
        The moving joints' names, types and limits.
    chain : Chain
        The compiled op sequence (each joint motion with a column of its own after the parameters).

    Raises
    ------
    ModelError
        When the parameters do not match the joints, no joint moves, or a joint name is empty or has a dot.

    Examples
    --------
    >>> from kincal.models import read_urdf
    >>> text = ('<robot name="turntable"> <link name="floor"/> <link name="plate"/>'
    ...         ' <joint name="turn" type="continuous"> <parent link="floor"/> <child link="plate"/>'
    ...         ' <origin xyz="0 0 0.2" rpy="0 0 0"/> <axis xyz="0 0 1"/> </joint> </robot>')
    >>> robot = read_urdf(text, "turntable.urdf", tool=(0.1, 0.0, 0.0))
    >>> type(robot).__name__, robot.structure, robot.joint_names, robot.joints[0].xyz
    ('URDFRobot', 'urdf', ('turn',), (0.0, 0.0, 0.2))
    >>> robot.params.names[6:12]
    ('turn.x', 'turn.y', 'turn.z', 'turn.roll', 'turn.pitch', 'turn.yaw')
    >>> robot.lower, robot.upper  # a continuous joint has no limits
    (array([-inf]), array([inf]))
    """

    name: str
    joints: tuple[URDFJoint, ...]
    params: Parameters
    description: str = ""
    source: Mapping[str, str] = field(default_factory=dict)  # file, base_link, tip_link
    joint_space: JointSpace = field(init=False, repr=False)
    chain: Chain = field(init=False, repr=False)

    def __post_init__(self) -> None:
        names, kinds = _param_layout(self.joints)
        if self.params.names != tuple(names) or self.params.kinds != tuple(kinds):
            raise ModelError(f"robot '{self.name}': parameters do not match the URDF chain")
        if not self.moving:
            raise ModelError(f"robot '{self.name}': the chain has no moving joint")
        for j in self.joints:
            if "." in j.name or not j.name:
                raise ModelError(f"robot '{self.name}': joint name '{j.name}' must be non-empty and contain no '.'")
        object.__setattr__(self, "source", MappingProxyType(dict(self.source)))
        # each joint motion gets a column of its own after the parameters: ∂p/∂q (joint_jacobian)
        self._compile([MOVING[j.type] for j in self.moving], len(self.params) + len(self.moving))

    @property
    def structure(self) -> str:
        return "urdf"

    def _joint_ops(self, j: URDFJoint, k: int) -> list[Op]:
        """The ops of one joint (k: its index among the moving joints); they end in its child link's
        frame, the link named by the joint."""
        if not j.moving:
            return _constant_origin(j.xyz, j.rpy)
        idx = self.params.index
        ops = [Op(TRANS, AXES[c], idx(f"{j.name}.{c}")) for c in "xyz"] + _constant_origin((0, 0, 0), j.rpy)
        ops += [Op(ROT, AXES[c], idx(f"{j.name}.{r}")) for c, r in zip("xyz", ("roll", "pitch", "yaw"))]
        kind = ROT if MOVING[j.type] == "revolute" else TRANS
        pre, axis, post = _align(j.axis, f"robot '{self.name}', joint '{j.name}'")
        return ops + pre + [Op(kind, axis, len(self.params) + k, k)] + post

    def structure_notes(self) -> list[str]:
        """A moving joint whose axis is not a unit vector: kincal reads its direction (the URDF specification's
        meaning); another parser may not normalise it."""
        notes = []
        for j in self.moving:
            norm = axis_norm(j)
            if norm is not None:
                unit = " ".join(f"{v:.6g}" for v in np.divide(j.axis, norm))
                far = f" (yourdfpy: {norm:.6g} times as far)" if j.type == "prismatic" else ""
                notes.append(f"joint '{j.name}': its axis xyz='{' '.join(f'{v:g}' for v in j.axis)}' is not a unit "
                             f"vector (length {norm:.6g}), which the URDF specification asks for; kincal reads its "
                             f"direction ({unit}); a parser that does not normalise it reads another motion{far}: "
                             f"write the unit vector (kincal export does)")
        return notes

    def chain_values(self, values: np.ndarray | None = None) -> np.ndarray:
        """Parameter values followed by a zero per joint (the joint motions' own columns)."""
        return np.concatenate([self.param_values(values), np.zeros(self.n_joints)])

    def origin(self, joint: URDFJoint, values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """A moving joint's origin with its deviations as URDF xyz (3,) and rpy (3,): the file's rpy
        composed with the small rotations about the joint frame's axes."""
        v = self.params.as_dict() if values is None else dict(zip(self.params.names, values))
        xyz = np.array([v[f"{joint.name}.{c}"] for c in "xyz"])
        R = rpy_matrix(*joint.rpy) @ rot_zyx(0.0, 0.0, v[f"{joint.name}.roll"]) \
            @ rot_zyx(0.0, v[f"{joint.name}.pitch"], 0.0) @ rot_zyx(v[f"{joint.name}.yaw"], 0.0, 0.0)
        rz, ry, rx = zyx_from_matrix(R)
        return xyz, np.array([rx, ry, rz])


AXIS_TOL = 1e-4  # an axis whose length differs from 1 by more is not a unit vector (4-digit 0.7071 0.7071 0 is)


def axis_norm(joint: URDFJoint) -> float | None:
    """The length of a joint's axis when it is not a unit vector (beyond AXIS_TOL), else None."""
    norm = float(np.linalg.norm(joint.axis))
    return norm if abs(norm - 1.0) > AXIS_TOL else None


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis rpy: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_zyx(yaw, pitch, roll)


def _constant_origin(xyz, rpy) -> list[Op]:
    """Tx Ty Tz Rz(yaw) Ry(pitch) Rx(roll) as constant motions (zero motions left out)."""
    order = [(TRANS, a, v) for a, v in zip("xyz", xyz)] + [(ROT, a, v) for a, v in zip("zyx", rpy[::-1])]
    return [Op(kind, AXES[a], -1, offset=float(v)) for kind, a, v in order if v != 0.0]


def _align(axis: Sequence[float], where: str) -> tuple[list[Op], int, list[Op]]:
    """Constant ops before/after a motion about local ``k`` that make it a motion about ``axis``."""
    a = np.asarray(axis, dtype=float)
    n = float(np.linalg.norm(a))
    if not (np.isfinite(n) and n > 1e-9):
        raise ModelError(f"{where}: the axis {list(a)} must be a non-zero vector")
    a = a / n
    k = int(np.argmax(a))
    if a[k] > 1.0 - 1e-12:  # along a frame axis already
        return [], k, []
    phi, theta = math.atan2(a[1], a[0]), math.acos(max(-1.0, min(1.0, a[2])))
    pre = [Op(ROT, AXES["z"], -1, offset=phi), Op(ROT, AXES["y"], -1, offset=theta)]
    post = [Op(ROT, AXES["y"], -1, offset=-theta), Op(ROT, AXES["z"], -1, offset=-phi)]
    return pre, AXES["z"], post


def urdf_robot(name: str, joints: Sequence[URDFJoint], tool: Sequence[float] = (0.0, 0.0, 0.0),
               description: str = "", source: Mapping[str, str] | None = None) -> URDFRobot:
    """A URDFRobot with its joints' nominal origins (no rotation deviations), base at the origin."""
    names, kinds = _param_layout(joints)
    values = dict.fromkeys(names, 0.0)
    values.update({f"{j.name}.{c}": float(v) for j in joints if j.moving for c, v in zip("xyz", j.xyz)})
    values.update({f"tool.{c}": float(v) for c, v in zip("xyz", tool)})
    return URDFRobot(name, tuple(joints), Parameters(names, [values[n] for n in names], kinds), description,
                     dict(source or {}))


# ---- reading URDF --------------------------------------------------------------------------------
def read_urdf(text: str, label: str, base_link: str | None = None, tip_link: str | None = None,
              tool: Sequence[float] | None = None) -> URDFRobot:
    """Read the serial chain between two links of a URDF document.

    Revolute, continuous, prismatic and fixed joints are read with their origins, axes, limits and the
    ``<inertial>`` mass of their child links; the chain's joints start at their nominal origins, its base
    frame at the origin.

    Parameters
    ----------
    text : str
        The URDF document (XML; a xacro file must be expanded first).
    label : str
        The file's name, for messages and the robot's ``source``.
    base_link : str, optional
        The chain's first link (default: the root link).
    tip_link : str, optional
        The chain's last link (default: the only end link below the base).
    tool : sequence of 3 float, optional
        The tool point in the tip link's frame, m (default: the tip link's origin).

    Returns
    -------
    URDFRobot
        The chain, named as the URDF's ``<robot>``, with ``source`` {"file", "base_link", "tip_link", "sha256"
        (of the text, UTF-8: an export checks that the file it edits is still this one)}.

    Raises
    ------
    ModelError
        When the text is not a URDF (not XML, a xacro file, another root element), an element is missing or
        malformed, the links do not form one chain from base to tip (closed loops, several roots or tips), a
        joint is mimic, floating or planar, or the numbers are no robot's: the lengths add up to more than a
        robot's (e.g. written in mm), an origin's rpy angle turns beyond MAX_RPY (1.25 turns) or a revolute joint's
        limit beyond 2 turns (degrees written where URDF wants radians); messages name the file and the element.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.models import read_urdf
    >>> text = ('<robot name="two_link"> <link name="base"/> <link name="upper"/> <link name="fore"/>'
    ...         ' <joint name="shoulder" type="revolute"> <parent link="base"/> <child link="upper"/>'
    ...         ' <origin xyz="0 0 0.1"/> <axis xyz="0 0 1"/> <limit lower="-3" upper="3"/> </joint>'
    ...         ' <joint name="elbow" type="revolute"> <parent link="upper"/> <child link="fore"/>'
    ...         ' <origin xyz="0.4 0 0"/> <axis xyz="0 0 1"/> <limit lower="-3" upper="3"/> </joint> </robot>')
    >>> robot = read_urdf(text, "two_link.urdf", tool=(0.3, 0.0, 0.0))
    >>> robot.name, robot.joint_names, robot.n_params
    ('two_link', ('shoulder', 'elbow'), 21)
    >>> dict(robot.source)
    {'file': 'two_link.urdf', 'base_link': 'base', 'tip_link': 'fore', 'sha256': '...'}
    >>> np.round(robot.forward([0.0, np.pi / 2]), 6).tolist()
    [0.4, 0.3, 0.1]
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        found = re.search(r"<xacro:[\w.-]+", text)  # a xacro element without its namespace declared
        if found:
            raise ModelError(_xacro_advice(label, f"<{found.group()[1:]}>")) from None
        raise ModelError(f"{label}: not valid XML ({exc})") from None
    sign = _xacro_sign(root)
    if sign:
        raise ModelError(_xacro_advice(label, sign))
    if root.tag != "robot":
        raise ModelError(f"{label}: the root element is <{root.tag}>, a URDF has <robot>")
    links = _links(root, label)
    joints = {}
    for el in root.findall("joint"):
        name, parsed = _joint(el, label, links)
        if name in joints:
            raise ModelError(f"{label}: joint '{name}' is defined twice")
        joints[name] = parsed
    parent_of = _parents(joints, label)
    base = base_link or _root(links, parent_of, label)
    tip = tip_link or _tip(base, joints, label)
    for what, link in (("base_link", base), ("tip_link", tip)):
        if link not in links:
            raise ModelError(f"{label}: {what} '{link}' is not a link of the file (links: {', '.join(sorted(links))})")
    chain = _chain_between(base, tip, joints, parent_of, label)
    for j in chain:
        if j["mimic"]:
            raise ModelError(f"{label}: joint '{j['joint'].name}' is a mimic joint; kincal does not model mimic "
                             f"joints yet")
    _check_lengths([j["joint"] for j in chain], label)
    _check_rpy([j["joint"] for j in chain], label)
    source = {"file": label, "base_link": base, "tip_link": tip, "sha256": hashlib.sha256(text.encode()).hexdigest()}
    robot = urdf_robot(root.get("name") or "urdf_robot", [j["joint"] for j in chain], tool or (0.0, 0.0, 0.0),
                       f"URDF chain {base} -> {tip} from {label}", source)
    check_limits(robot, label, fmt="URDF")  # a revolute joint's beyond 2 turns: degrees
    return robot


def _xacro_sign(root: ET.Element) -> str | None:
    """What shows ``root`` to be a xacro document: its first element of a xacro namespace (``<xacro:include>``;
    ROS's URIs differ, all end in 'xacro') or attribute with a ``${…}`` expression or ``$(…)`` substitution, in
    words; None for a URDF (one written by xacro may still declare the namespace, unused)."""
    for el in root.iter():
        if el.tag.startswith("{") and el.tag[1:].split("}")[0].rstrip("/#").endswith("xacro"):
            return f"<xacro:{el.tag.split('}')[1]}>"
        for key, value in el.attrib.items():
            if "${" in value or "$(" in value:
                return f"<{el.tag} {key}='{value}'>"
    return None


def _xacro_advice(label: str, sign: str) -> str:
    return (f"{label}: a xacro file ({sign}: macros and expressions, not yet a URDF); expand it first, e.g. 'xacro "
            f"{label} > robot.urdf' (or 'ros2 run xacro xacro ...'), and give the URDF")


def fixed_frame(text: str, parent: str, child: str) -> np.ndarray | None:
    """The 4x4 pose (m) of link ``child`` in link ``parent`` of the URDF document ``text``, composed along the
    joints that join them in the link tree (up from ``parent`` to the links' common ancestor, then down to
    ``child``), as ROS-Industrial's link ``base`` (the controller's base frame) hangs under ``base_link``, however
    far from the chain's base link; None when ``child`` is not a link of the file.

    Raises
    ------
    ModelError
        When the text is not XML, ``parent`` is not a link of the file, the two links are not in one tree, or a
        joint between them moves (the pose would depend on a joint value), naming the joint.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ModelError(f"the URDF is not valid XML ({exc})") from None
    links = {el.get("name") for el in root.findall("link")}
    if child not in links:
        return None
    if parent not in links:
        raise ModelError(f"the URDF has no link '{parent}'")
    up: dict[str | None, ET.Element] = {}  # child link -> its joint element
    for el in root.findall("joint"):
        node = el.find("child")
        up.setdefault(node.get("link") if node is not None else None, el)
    above = [_path_up(parent, up), _path_up(child, up)]
    if above[0][-1][0] != above[1][-1][0]:
        raise ModelError(f"the URDF's links '{parent}' and '{child}' are not in one tree")
    while len(above[0]) > 1 and len(above[1]) > 1 and above[0][-2][0] == above[1][-2][0]:
        above = [above[0][:-1], above[1][:-1]]  # drop the common ancestors above the nearest
    poses = [_pose_along(path, parent, child) for path in above]  # each in the nearest common ancestor
    return np.linalg.inv(poses[0]) @ poses[1]


def _pose_along(path: list[tuple[str | None, ET.Element | None]], parent: str, child: str) -> np.ndarray:
    """The pose (4x4, m) of the first link of ``path`` (:func:`_path_up`) in its last, through fixed joints only."""
    T = np.eye(4)
    for _, joint in path[:-1]:
        assert joint is not None  # every link but the last has its joint
        where = f"joint '{joint.get('name')}'"
        if joint.get("type") != "fixed":
            raise ModelError(f"the URDF's {where} ({joint.get('type')}) lies between links '{parent}' and "
                             f"'{child}': '{child}' moves with it, it is no fixed frame of '{parent}'")
        J = np.eye(4)
        J[:3, :3] = rpy_matrix(*_triple(joint.find("origin"), "rpy", where, (0.0, 0.0, 0.0)))
        J[:3, 3] = _triple(joint.find("origin"), "xyz", where, (0.0, 0.0, 0.0))
        T = J @ T
    return T


def _path_up(link: str | None, up: dict[str | None, ET.Element]) -> list[tuple[str | None, ET.Element | None]]:
    """(link, the joint above it) from ``link`` up to the root link (its joint None); a loop ends it."""
    path: list[tuple[str | None, ET.Element | None]] = []
    while link in up and all(link != seen for seen, _ in path):
        el = up[link]
        path.append((link, el))
        node = el.find("parent")
        link = node.get("link") if node is not None else None
    return path + [(link, None)]


MM_REACH = 100.0  # m: ... and one this long was written in mm (URDF lengths are in metres)


def _check_lengths(chain: Sequence[URDFJoint], label: str) -> None:
    """The chain's origins add up to a robot's size: refuse one written in mm, or absurd values."""
    lengths = [float(np.max(np.abs(j.xyz))) for j in chain]  # the largest component: no overflow
    total = sum(lengths)
    if total <= MAX_REACH:
        return
    worst = chain[int(np.argmax(lengths))]
    if MM_REACH < total < 1e5:
        raise ModelError(f"{label}: the chain's joint origins add up to {total:.4g} m (joint '{worst.name}' at "
                         f"{max(lengths):.4g} m): they look like mm; URDF lengths are in metres (divide by 1000)")
    raise ModelError(f"{label}: joint '{worst.name}' has its origin {max(lengths):.4g} m away (the chain adds up to "
                     f"{total:.4g} m): implausible for a robot; check the <origin xyz> values (metres)")


MAX_RPY = 2.5 * math.pi  # rad (450°): no origin turns further about an axis (real files: up to 3π/2, TALOS's wrist)


def _check_rpy(chain: Sequence[URDFJoint], label: str) -> None:
    """Refuse an origin's rpy angle beyond MAX_RPY: degrees written where URDF wants radians."""
    for j in chain:
        far = max(abs(v) for v in j.rpy)
        if far > MAX_RPY:
            written, meant = (" ".join(f"{v:.6g}" for v in values) for values in (j.rpy, np.radians(j.rpy)))
            raise ModelError(f"{label}: joint '{j.name}': origin rpy='{written}' turns {far:.6g} rad "
                             f"({far / (2 * math.pi):.3g} turns) about one axis; no origin turns beyond "
                             f"{MAX_RPY / (2 * math.pi):g} turns: the angles look like degrees; URDF angles are in "
                             f"radians: write rpy='{meant}'")


def _links(root, label: str) -> dict[str, tuple[float, tuple[float, float, float]]]:
    """Each link's mass (kg) and centre of mass (see :func:`_inertial`) by name."""
    names = [el.get("name") for el in root.findall("link")]
    if any(not n for n in names):
        raise ModelError(f"{label}: a <link> has no name")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ModelError(f"{label}: link(s) {', '.join(twice)} defined twice")
    return {el.get("name"): _inertial(el, label) for el in root.findall("link")}


def _inertial(link, label: str) -> tuple[float, tuple[float, float, float]]:
    """A link's mass (kg) and centre of mass (m, link frame) from ``<inertial>``; (0, 0) without one."""
    node = link.find("inertial")
    if node is None:
        return 0.0, (0.0, 0.0, 0.0)
    where = f"{label}: link '{link.get('name')}' <inertial>"
    mass = _floats(node.find("mass"), "value", 1, where)[0]
    if mass < 0.0:
        raise ModelError(f"{where}: mass {mass} kg is negative")
    return mass, _triple(node.find("origin"), "xyz", where, (0.0, 0.0, 0.0))


def _joint(el, label: str, links: dict) -> tuple[str, dict]:
    name, jtype = el.get("name"), el.get("type")
    where = f"{label}: joint '{name}'"
    if not name:
        raise ModelError(f"{label}: a <joint> has no name")
    if jtype not in KNOWN:
        raise ModelError(f"{where}: unknown type '{jtype}' (URDF types: {', '.join(sorted(KNOWN))})")
    ends = {}
    for tag in ("parent", "child"):
        node = el.find(tag)
        link = node.get("link") if node is not None else None
        if not link:
            raise ModelError(f"{where}: missing <{tag} link=...>")
        if link not in links:
            raise ModelError(f"{where}: {tag} link '{link}' is not defined")
        ends[tag] = link
    origin = el.find("origin")
    xyz = _triple(origin, "xyz", where, (0.0, 0.0, 0.0))
    rpy = _triple(origin, "rpy", where, (0.0, 0.0, 0.0))
    axis = _triple(el.find("axis"), "xyz", where, (1.0, 0.0, 0.0))
    lower, upper = -math.inf, math.inf
    if jtype in ("revolute", "prismatic"):
        limit = el.find("limit")
        if limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise ModelError(f"{where}: a {jtype} joint needs <limit lower=... upper=...>")
        lower, upper = _floats(limit, "lower", 1, where)[0], _floats(limit, "upper", 1, where)[0]
        if not lower < upper:
            raise ModelError(f"{where}: limit lower {lower} must be below upper {upper}")
    joint = URDFJoint(name, jtype, xyz, rpy, axis, lower, upper, *links[ends["child"]])
    return name, {"joint": joint, "mimic": el.find("mimic") is not None, **ends}


def _triple(node, attr: str, where: str, default: tuple[float, float, float]) -> tuple[float, float, float]:
    x, y, z = _floats(node, attr, 3, where, default)
    return x, y, z


def _floats(node, attr: str, n: int, where: str, default: tuple[float, ...] | None = None) -> tuple[float, ...]:
    text = node.get(attr) if node is not None else None
    if text is None:
        if default is None:
            raise ModelError(f"{where}: missing attribute '{attr}'")
        return default
    try:
        vals = tuple(float(v) for v in text.split())
    except ValueError:
        raise ModelError(f"{where}: {node.tag} {attr}='{text}' is not {n} number(s)") from None
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise ModelError(f"{where}: {node.tag} {attr}='{text}' must be {n} finite number(s)")
    return vals


def _parents(joints: dict, label: str) -> dict[str, str]:
    """child link -> joint name; a link with two parent joints is a closed loop."""
    parent_of: dict[str, str] = {}
    for name, j in joints.items():
        if j["child"] in parent_of:
            raise ModelError(f"{label}: link '{j['child']}' is the child of joints '{parent_of[j['child']]}' and "
                             f"'{name}': closed loops are not supported")
        parent_of[j["child"]] = name
    return parent_of


def _root(links: dict, parent_of: dict[str, str], label: str) -> str:
    roots = sorted(links.keys() - parent_of.keys())
    if len(roots) != 1:
        raise ModelError(f"{label}: {len(roots)} root links ({', '.join(roots) or 'none: the joints form a loop'}); "
                         f"choose the chain's base with base_link (CLI: --base-link)")
    return roots[0]


def _tip(base: str, joints: dict, label: str) -> str:
    children: dict[str, list[str]] = {}
    for j in joints.values():
        children.setdefault(j["parent"], []).append(j["child"])
    leaves, stack = [], [base]
    while stack:
        link = stack.pop()
        below = children.get(link, [])
        leaves += [] if below else [link]
        stack += below
    if len(leaves) != 1:
        raise ModelError(f"{label}: several end links below '{base}' ({', '.join(sorted(leaves))}); choose one with "
                         f"tip_link (CLI: --tip-link)")
    return leaves[0]


def _chain_between(base: str, tip: str, joints: dict, parent_of: dict[str, str], label: str) -> list[dict]:
    chain, link, seen = [], tip, set()
    while link != base:
        if link not in parent_of or link in seen:
            raise ModelError(f"{label}: broken chain: tip_link '{tip}' is not below base_link '{base}' (stopped at "
                             f"link '{link}')")
        seen.add(link)
        j = joints[parent_of[link]]
        if j["joint"].type in ("floating", "planar"):
            raise ModelError(f"{label}: joint '{j['joint'].name}' is {j['joint'].type}; only revolute, continuous, "
                             f"prismatic and fixed joints can be calibrated")
        chain.append(j)
        link = j["parent"]
    return chain[::-1]
