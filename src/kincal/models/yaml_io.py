"""Robot YAML files: load, save (exact round trip in SI units) and the bundled robot library.

Format (units apply to every length/angle in the file)::

    name: ur5
    description: free text
    convention: dh            # dh (Craig: Rz Tz Tx Rx) or mdh (Rx Tx Rz Tz)
    units: {length: mm, angle: deg}
    joints:
      - {name: j1, type: revolute, theta: 0, d: 89.159, a: 0, alpha: 90, limits: [-360, 360]}
      - {name: j2, type: revolute, theta: 0, d: 0, a: -425, alpha: 0, beta: 0, limits: [-360, 360]}
    base: {x: 0, y: 0, z: 0, rx: 0, ry: 0, rz: 0}
    tool: {x: 0, y: 0.09, z: 31.0}

``beta``: a number switches Hayati's β on for that joint, ``false`` switches it off, and when the key
is absent it is switched on automatically where consecutive revolute axes are parallel. ``language``
(optional): the language of the controller's programs (``LANGUAGES``: ur, krl, rapid, fanuc, inform);
``compensate`` refuses a program in another one.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import os
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from .._atomic import write_text_atomic
from ..errors import ModelError
from ..units import DEG
from .plausible import arm_size, check_limits, check_size, size_unit
from .puu3 import PUU3Robot
from .stewart import StewartRobot
from .delta import DeltaRobot
from .robot import Robot
from .serial import CONVENTIONS, Joint, SerialRobot
from .transmission import TransmissionRobot
from .terms import ExtendedRobot
from .urdf import URDFRobot, read_urdf
from .yaml_kinds import (delta_from_dict, delta_yaml, error_model_from_dict, error_model_yaml, puu3_from_dict,
                         puu3_yaml, stewart_from_dict, stewart_yaml, transmission_from_dict, transmission_yaml,
                         urdf_from_dict, urdf_yaml)
from .yaml_values import (POSE_KEYS, base_pose, description_lines, fmt, frame_text, limits, link_mass, mass_items,
                          mapping, num, per_unit, pose_text, units)

_JOINT_KEYS = {"name", "type", "theta", "d", "a", "alpha", "beta", "limits", "mass", "com", "velocity", "effort",
               "pulses_per_degree"}
_COMMON_KEYS = {"name", "description", "type", "units", "base", "calibration", "source", "error_model"}
_TYPE_KEYS = {"serial": {"convention", "joints", "tool", "actuators", "transmission", "names", "frames", "language"},
              "puu3": {"extended", "parameters", "slider_limits"}, "urdf": {"joints", "tool"},
              "stewart": {"legs", "reading", "tool", "compliance"}, "delta": {"arms", "parameters", "arm_limits"}}  # beside the common
_TOP_KEYS = _COMMON_KEYS.union(*_TYPE_KEYS.values())
def bundled_robots() -> list[str]:
    """List the robots shipped with kincal.

    Returns
    -------
    list of str
        The bundled robots' names, sorted; each loads with :func:`load_robot`.

    Examples
    --------
    >>> import kincal
    >>> names = kincal.bundled_robots()
    >>> "ur5" in names, "puu3" in names, names == sorted(names)
    (True, True, True)
    """
    folder = resources.files("kincal.models") / "robots"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def load_robot(name_or_path: str | os.PathLike, base_link: str | None = None, tip_link: str | None = None,
               tool: tuple[float, float, float] | None = None) -> Robot:
    """Load a robot: a bundled one by name, a kincal robot YAML file or a URDF file.

    A file is a URDF when its name ends in ``.urdf`` or its text starts with ``<``; the robot is then the
    serial chain from ``base_link`` to ``tip_link``. A robot YAML file's values are checked for plausibility:
    without a ``units`` key, values that look like mm or degrees are refused with advice.

    Parameters
    ----------
    name_or_path : str or path-like
        A bundled robot's name (see :func:`bundled_robots`) or the path of a robot file. A name that is also a
        file in the current folder is refused as ambiguous (write ``./<name>`` for the file).
    base_link : str, optional
        URDF only: the chain's first link (default: the root link).
    tip_link : str, optional
        URDF only: the chain's last link (default: the only end link below the base).
    tool : tuple of 3 float, optional
        The measured point in the flange (tip link) frame, m, replacing the file's own tool point (default: the
        file's; for a URDF the tip link's origin).

    Returns
    -------
    Robot
        The robot (a SerialRobot, URDFRobot, TransmissionRobot, parallel robot, or an ExtendedRobot when the
        file has an error model), in SI units.

    Raises
    ------
    ModelError
        When the robot or file is not found or cannot be read, the file is malformed or implausible,
        ``base_link`` or ``tip_link`` is given for a file that is not a URDF, or ``tool`` is not three finite
        numbers; the message names the file.

    See Also
    --------
    save_robot : Write a robot file that loads back exactly.

    Examples
    --------
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> robot.name, robot.structure, robot.n_joints, robot.n_params
    ('ur5', 'dh', 6, 35)
    >>> [round(float(v), 6) for v in robot.tool_point()]  # a reflector on the flange, m
    [0.0, 9e-05, 0.031]
    >>> kincal.load_robot("ur5", tool=(0.0, 0.0, 0.1)).tool_point().tolist()
    [0.0, 0.0, 0.1]
    """
    text, label = _robot_text(name_or_path)
    urdf = _is_urdf(name_or_path, text)
    if (base_link or tip_link) and not urdf:
        raise ModelError(f"{label}: base_link and tip_link apply to URDF files only; a kincal robot file holds its "
                         f"own chain")
    data = {} if urdf else _parse(text, label)  # a URDF is no YAML
    try:  # a message gets the file's label unless it has it
        if urdf:
            return read_urdf(text, label, base_link, tip_link, _tool(tool))
        robot = robot_from_dict(data, label)
        _check_plausible(robot, data, label)
        return robot if tool is None else robot.with_tool_point(_tool(tool))
    except ModelError as exc:
        if str(exc).startswith(label):
            raise
        raise ModelError(f"{label}: {exc}") from None
    except (TypeError, AttributeError, KeyError, ValueError, IndexError) as exc:  # a shape no check foresaw
        if not urdf:
            raise ModelError(f"{label}: malformed robot file ({type(exc).__name__}: {exc}); see the robot YAML "
                             f"format in docs/reference/formats.md") from None
        if not isinstance(exc, (TypeError, ValueError)):
            raise
        raise ModelError(f"{label}: malformed URDF ({exc})") from None


def _tool(tool) -> tuple[float, float, float]:
    """The tool point (m) as three floats; a ModelError (the caller names the file) otherwise."""
    if tool is None:
        return (0.0, 0.0, 0.0)
    try:
        t = tuple(float(v) for v in tool)
    except (TypeError, ValueError):
        t = ()
    if len(t) != 3 or not all(np.isfinite(t)):
        raise ModelError(f"the tool point must be three finite numbers (m), got {tool!r}")
    return t


MAX_LENGTH = 100.0  # m: no robot parameter is longer
MAX_ANGLE = 4 * np.pi  # rad: no geometric angle turns further


def _check_plausible(robot: Robot, data: dict, label: str) -> None:
    """Refuse values no robot has (the file's parsed mapping ``data`` declares the units); without a ``units`` key
    say which unit the values look like."""
    has_units = "units" in data
    v, kinds = robot.params.values, robot.params.kinds
    ang = [(n, x) for n, k, x in zip(robot.params.names, kinds, v) if k == "angle" and abs(x) > MAX_ANGLE / 2]
    lng = [(n, x) for n, k, x in zip(robot.params.names, kinds, v) if k == "length" and abs(x) > 10.0]
    size = size_unit(arm_size(robot)[0]) if lng else "m"  # the unit the lengths look like (cm: check_size says)
    if not has_units and (ang or lng) and size in (None, "m", "mm"):
        n, x = (ang or lng)[0]
        what = f"{x * DEG:.0f} deg read as rad" if ang else f"{x:g} m"
        largest = max((abs(x) for x, k in zip(v, kinds) if k == "angle"), default=0.0)
        units = f"units: {{length: {'mm' if lng else 'm'}, angle: {'deg' if ang else 'rad'}}}"
        aside = "" if ang else f" (the angles, up to {largest:.3g}, read as radians; write angle: deg if they are not)"
        raise ModelError(f"{label}: {n} = {x:g} ({what}) is implausible in the default units m and rad; the values "
                         f"look like {'degrees' if ang else 'mm'}: add '{units}'{aside}")
    declared = mapping(data, "units", label)
    check_size(robot, label, str(declared.get("length", "m")), has_units)
    check_limits(robot, label, str(declared.get("length", "m")), str(declared.get("angle", "rad")), has_units)
    bad = [(n, x) for n, x in ang if abs(x) > MAX_ANGLE] + [(n, x) for n, x in lng if abs(x) > MAX_LENGTH]
    if bad:
        n, x = bad[0]
        raise ModelError(f"{label}: {n} = {x:g} (SI) is implausible for a robot; check the value and the 'units' key")


def _robot_text(name_or_path: str | os.PathLike) -> tuple[str, str]:
    """The YAML text of a bundled robot or a file, and a label for messages. A name that is both a
    bundled robot and a file here is ambiguous and refused."""
    s = str(name_or_path)
    p = Path(s)
    if s in bundled_robots():
        if p.is_file():
            raise ModelError(f"'{s}' is both a bundled robot and a file in this folder; write ./{s} for the file "
                             f"or rename it")
        return (resources.files("kincal.models") / "robots" / f"{s}.yaml").read_text(), f"bundled robot '{s}'"
    if p.is_dir():
        raise ModelError(f"'{s}' is a folder, not a robot file; give a robot YAML or URDF file, or a bundled robot "
                         f"({', '.join(bundled_robots())})")
    if not p.is_file():
        if p.suffix or len(p.parts) > 1:  # written as a path: the file is missing
            raise ModelError(f"robot file '{s}' not found (no such file; the folder it names "
                             f"{'exists' if p.parent.is_dir() else 'does not exist either'})")
        raise ModelError(f"'{s}' is neither a bundled robot ({', '.join(bundled_robots())}) nor a robot file here")
    try:
        return p.read_text(encoding="utf-8-sig"), str(p)
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{p}: cannot read the robot file ({exc})") from None


def _parse(text: str, label: str):
    """The YAML text parsed (a fresh copy each time: callers may change it); a command that reads one robot file
    for its model and its calibration record parses it once (the record's covariances dominate: 0.07 s each)."""
    return copy.deepcopy(_parsed(text, label))


@functools.lru_cache(maxsize=4)
def _parsed(text: str, label: str):
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except yaml.YAMLError as exc:
        raise ModelError(f"{label}: not valid YAML ({' '.join(str(exc).split())})") from None


class _UniqueKeys:
    """Safe YAML that refuses a key given twice in one mapping (the later value would win silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, (str, int, float, bool)) and key is not None:
                continue  # unhashable keys: the base class reports them
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"key '{key}' is given twice",
                                                        key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


# libyaml's parser (5-10x faster on a calibrated file's covariance) where PyYAML has it, else PyYAML's own
_UniqueKeyLoader = type("_UniqueKeyLoader", (_UniqueKeys, yaml.CSafeLoader if yaml.__with_libyaml__ else
                                             yaml.SafeLoader), {})


def robot_from_dict(data: dict, label: str = "robot") -> Robot:
    """Build a robot from the parsed YAML mapping; errors name ``label`` and the offending key."""
    if not isinstance(data, dict):
        raise ModelError(f"{label}: expected a mapping with keys {sorted(_TOP_KEYS)}")
    if "error_model" in data:
        geometry = robot_from_dict({k: v for k, v in data.items() if k != "error_model"}, label)
        return error_model_from_dict(geometry, data["error_model"], label)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ModelError(f"{label}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    kind = str(data.get("type", "serial"))
    foreign = sorted(set(data) - _COMMON_KEYS - _TYPE_KEYS.get(kind, _TOP_KEYS))
    if foreign:  # a key of another kind of robot would be ignored: refused instead
        raise ModelError(f"{label}: {', '.join(foreign)} do(es) not belong to a '{kind}' robot (keys of "
                         f"{', '.join(t for t, keys in _TYPE_KEYS.items() if keys & set(foreign))}); remove them or "
                         f"give the right 'type'")
    if data.get("type", "serial") == "puu3":
        return puu3_from_dict(data, label)
    if data.get("type") == "urdf":
        return urdf_from_dict(data, label)
    if data.get("type") == "stewart":
        return stewart_from_dict(data, label)
    if data.get("type") == "delta":
        return delta_from_dict(data, label)
    if data.get("type", "serial") != "serial":
        raise ModelError(f"{label}: unknown robot type '{data.get('type')}'; use 'serial' (default), 'puu3', "
                         f"'stewart', 'delta' or 'urdf'")
    for key in ("name", "convention", "joints"):
        if key not in data:
            raise ModelError(f"{label}: missing required key '{key}'")
    conv = str(data["convention"]).lower()
    if conv not in CONVENTIONS:
        raise ModelError(f"{label}: convention '{conv}' is not one of {CONVENTIONS}")
    lf, af = units(data, label)

    joints, rows, explicit_beta = _dh_joints(data["joints"], lf, af, label)
    base = base_pose(data, label, lf, af)
    tool = {k: num(v, f"{label}: tool", k) * lf for k, v in mapping(data, "tool", label).items()}
    joints = _export_names(joints, data.get("names"), label)
    robot = SerialRobot.build(str(data["name"]), conv, joints, rows, base, tool, str(data.get("description", "")),
                              _frames(data.get("frames"), lf, af, label), _language(data.get("language"), label))
    # automatic beta where axes are parallel and the file does not say otherwise
    auto = {k for k in map(robot.beta_joint, robot.parallel_pairs()) if explicit_beta[k] is None}
    if auto:
        robot = robot.with_joints([dataclasses.replace(j, beta=True) if k in auto else j
                                   for k, j in enumerate(robot.joints)])
    if ("transmission" in data) != ("actuators" in data):
        raise ModelError(f"{label}: 'actuators' and 'transmission' go together; give both or neither")
    return transmission_from_dict(robot, data, lf, af, label) if "transmission" in data else robot


LANGUAGES = ("ur", "krl", "rapid", "fanuc", "inform")  # robot programs kincal reads (kincal.io.dialects, and URScript)


def _language(value, label: str) -> str:
    """A robot file's ``language:`` (the language of its controller's programs), checked; '' when not given."""
    if value is None:
        return ""
    if str(value) not in LANGUAGES:
        raise ModelError(f"{label}: language '{value}' is not one of {', '.join(LANGUAGES)} (the language of the "
                         f"controller's programs; leave it out when it is none of them)")
    return str(value)


def _export_names(joints: list[Joint], names, label: str) -> list[Joint]:
    """The joints with their robot-stack names from a ``names:`` mapping (kincal name -> name)."""
    if names is None:
        return joints
    known = [j.name for j in joints if j.type != "fixed"]
    if not isinstance(names, dict) or set(map(str, names)) - set(known):
        raise ModelError(f"{label}: 'names' must map joint names ({', '.join(known)}) to their names in the robot "
                         f"stack, e.g. {{{known[0]}: shoulder_pan_joint}}")
    given = {str(k): str(v) for k, v in names.items()}
    if len(set(given.values())) != len(given) or any(not v.strip() for v in given.values()):
        raise ModelError(f"{label}: 'names' must give distinct, non-empty names")
    return [dataclasses.replace(j, export_name=given.get(j.name, "")) for j in joints]


def _frames(frames, lf: float, af: float, label: str) -> tuple:
    """Named frames (``frames: {base_link: {rz: 180}}``: the frame's pose in the base frame) in SI units."""
    if frames is None:
        return ()
    if not isinstance(frames, dict):
        raise ModelError(f"{label}: 'frames' must map frame names to {{x, y, z, rx, ry, rz}}")
    out = []
    for name, pose in frames.items():
        where = f"{label}: frame '{name}'"
        if not isinstance(pose, dict) or set(pose) - set(POSE_KEYS):
            raise ModelError(f"{where}: give its pose as {{x, y, z, rx, ry, rz}} (missing keys are 0)")
        out.append((str(name), tuple(num(pose.get(k, 0.0), where, k) * (lf if k in "xyz" else af)
                                     for k in POSE_KEYS)))
    return tuple(out)


def _dh_joints(entries, lf: float, af: float, label: str) -> tuple[list[Joint], list[dict], list]:
    """Joint structures, DH rows (SI) and each joint's ``beta`` as written (None: absent)."""
    joints, rows, explicit_beta = [], [], []
    if not isinstance(entries, list) or not entries:
        raise ModelError(f"{label}: 'joints' must be a non-empty list")
    names = [str(jd.get("name", f"j{k + 1}")) for k, jd in enumerate(entries) if isinstance(jd, dict)]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ModelError(f"{label}: duplicate joint names {', '.join(twice)}; every joint needs its own name")
    for k, jd in enumerate(entries):
        where = f"{label}: joint {k + 1}"
        if not isinstance(jd, dict):
            raise ModelError(f"{where}: expected a mapping")
        bad = set(jd) - _JOINT_KEYS
        if bad:
            raise ModelError(f"{where}: unknown key(s) {sorted(bad)}; allowed: {sorted(_JOINT_KEYS)}")
        jtype = str(jd.get("type", "revolute"))
        lim = jd.get("limits")
        if jtype == "fixed" and lim is not None:
            raise ModelError(f"{where}: a fixed row has no joint, so no 'limits'")
        qf = af if jtype == "revolute" else lf
        if lim is None:
            lo, hi = (-np.pi, np.pi) if jtype == "revolute" else (-1.0, 1.0)
        else:
            lo, hi = limits(lim, where, qf)
        beta = jd.get("beta", None)
        explicit_beta.append(beta)
        on = not (beta is None or beta is False)
        joints.append(Joint(str(jd.get("name", f"j{k + 1}")), jtype, on, lo, hi, *link_mass(jd, lf, where),
                            None if jd.get("velocity") is None else num(jd["velocity"], where, "velocity") * qf,
                            None if jd.get("effort") is None else num(jd["effort"], where, "effort"),
                            pulses=num(jd.get("pulses_per_degree", 0.0), where, "pulses_per_degree")))
        row = {key: num(jd.get(key, 0.0), where, key) * (lf if key in ("d", "a") else af)
               for key in ("theta", "d", "a", "alpha")}
        if on:
            row["beta"] = num(beta, where, "beta") * af
        rows.append(row)
    return joints, rows, explicit_beta


def robot_to_yaml(robot: Robot, length_unit: str = "m", angle_unit: str = "rad",
                  folder: str | os.PathLike | None = None) -> str:
    """YAML text of a robot. In SI units (the default) load(save(robot)) reproduces it exactly. A URDF chain's
    source file is written relative to ``folder``, the folder the text is saved in, else absolute."""
    if isinstance(robot, ExtendedRobot):
        return robot_to_yaml(robot.inner, length_unit, angle_unit, folder) + error_model_yaml(robot)
    if isinstance(robot, PUU3Robot):
        return puu3_yaml(robot, length_unit, angle_unit)
    if isinstance(robot, URDFRobot):
        return urdf_yaml(robot, length_unit, angle_unit, None if folder is None else str(folder))
    if isinstance(robot, StewartRobot):
        return stewart_yaml(robot, length_unit, angle_unit)
    if isinstance(robot, DeltaRobot):
        return delta_yaml(robot, length_unit, angle_unit)
    if isinstance(robot, TransmissionRobot):
        return _chain_yaml(robot.inner, length_unit, angle_unit) + transmission_yaml(robot, length_unit, angle_unit)
    if not isinstance(robot, SerialRobot):
        raise ModelError(f"robot '{robot.name}' ({robot.structure}): kincal has no robot file for this kind of model")
    return _chain_yaml(robot, length_unit, angle_unit)


def _chain_yaml(robot: SerialRobot, length_unit: str, angle_unit: str) -> str:
    lf, af = per_unit(length_unit, angle_unit)
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}", *description_lines(robot.description)]
    lines += [f"convention: {robot.convention}", f"units: {{length: {length_unit}, angle: {angle_unit}}}", "joints:"]
    for j in robot.joints:
        qf = af if j.type == "revolute" else lf
        items = [f"name: {j.name}", f"type: {j.type}"] + [f"{key}: {fmt(v[f'{j.name}.{key}'] * f)}" for key, f in
                                                           (("theta", af), ("d", lf), ("a", lf), ("alpha", af))]
        items.append(f"beta: {fmt(v[f'{j.name}.beta'] * af)}" if j.beta else "beta: false")
        if j.type != "fixed":
            items.append(f"limits: [{fmt(j.lower * qf)}, {fmt(j.upper * qf)}]")
        items += [f"velocity: {fmt(j.velocity * qf)}"] if j.velocity is not None else []
        items += [f"effort: {fmt(j.effort)}"] if j.effort is not None else []
        items += [f"pulses_per_degree: {fmt(j.pulses)}"] if j.pulses else []
        lines.append("  - {" + ", ".join(items + mass_items(j, lf)) + "}")
    lines += [frame_text(v, "base", lf, af), frame_text(v, "tool", lf, af)]
    named = {j.name: j.export_name for j in robot.joints if j.export_name}
    if named:
        lines.append("names: {" + ", ".join(f"{k}: {n}" for k, n in named.items()) + "}")
    if robot.frames:
        lines.append("frames: {" + ", ".join(f"{n}: {{{pose_text(p, lf, af)}}}" for n, p in robot.frames) + "}")
    lines += [f"language: {robot.language}"] if robot.language else []
    return "\n".join(lines + [""])


def save_robot(robot: Robot, path: str | os.PathLike, length_unit: str = "m", angle_unit: str = "rad",
               calibration: dict | None = None) -> None:
    """Save a robot as a kincal robot YAML file (written atomically).

    In SI units (the default) loading the file gives the same robot exactly; mm and degrees are easier to
    read, and round-trip to within floating-point round-off.

    Parameters
    ----------
    robot : Robot
        The robot: a DH/MDH chain (with or without a transmission), a URDF chain, a parallel robot (3-PUU,
        hexapod, delta), or any of these with an error model.
    path : str or path-like
        The file to write.
    length_unit : str, optional
        Unit of the lengths in the file, e.g. "m" (default) or "mm".
    angle_unit : str, optional
        Unit of the angles in the file, e.g. "rad" (default) or "deg".
    calibration : dict, optional
        A mapping stored under ``calibration:``, always in SI units, e.g. the parameter covariance of a
        calibrated model; read it back with :func:`load_calibration_record` (default: none).

    Raises
    ------
    ModelError
        When kincal has no robot file for this kind of model, the path is named as a URDF or XML file
        (:func:`check_robot_output`), or kincal would refuse to load the file (values beyond what the loader takes
        as plausible): nothing is written.

    See Also
    --------
    load_robot : Read the file back.

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "ur5.yaml")
    ...     kincal.save_robot(robot, path)
    ...     same = kincal.load_robot(path)
    ...     kincal.save_robot(robot, path, length_unit="mm", angle_unit="deg")
    ...     readable = kincal.load_robot(path)
    >>> same.params == robot.params, same.joint_names == robot.joint_names
    (True, True)
    >>> bool(np.allclose(readable.params.values, robot.params.values, rtol=0.0, atol=1e-12))
    True
    """
    check_robot_output(path)
    text = robot_to_yaml(robot, length_unit, angle_unit, os.path.dirname(os.fspath(path)))
    _loads_back(text, str(path))
    if calibration:
        text += yaml.safe_dump({"calibration": calibration}, default_flow_style=None, sort_keys=False, width=120)
    write_text_atomic(path, text)


def robot_from_text(text: str, label: str = "robot") -> Robot:
    """A robot from the text of a kincal robot YAML file (what :func:`robot_to_yaml` writes: in SI units, the
    same robot exactly).

    Parameters
    ----------
    text : str
        The robot file's YAML text.
    label : str, optional
        How messages name it (default "robot").

    Returns
    -------
    Robot
        The robot, in SI units.

    Raises
    ------
    ModelError
        Naming ``label``, when the text is no valid robot file.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models.yaml_io import robot_from_text, robot_to_yaml
    >>> robot = kincal.load_robot("ur5")
    >>> robot_from_text(robot_to_yaml(robot)).params == robot.params
    True
    """
    return robot_from_dict(_parse(text, label), label)


NOT_ROBOT_FILES = (".urdf", ".xacro", ".xml")  # names of files kincal (.urdf) or ROS read as XML


def check_robot_output(path: str | os.PathLike) -> None:
    """Refuse to name a kincal robot file (YAML) as a URDF or XML file: kincal would read a .urdf back as a URDF
    (and fail: not XML), and ROS tools as XML. ModelError naming the file, a .yaml name, and ``kincal export``
    for a URDF.

    Examples
    --------
    >>> from kincal.models.yaml_io import check_robot_output
    >>> check_robot_output("cal.yaml")
    >>> check_robot_output("cal.urdf")
    Traceback (most recent call last):
    ...
    kincal.errors.ModelError: cal.urdf: a kincal robot file is YAML, not .urdf: ...
    """
    p = Path(path)
    if p.suffix.lower() in NOT_ROBOT_FILES:
        yaml_name = p.with_suffix(".yaml")
        raise ModelError(f"{path}: a kincal robot file is YAML, not {p.suffix}: a URDF or XML reader (kincal's own "
                         f"for .urdf) would fail on it; name it {yaml_name}, and write the URDF from it with "
                         f"'kincal export {yaml_name} {path}'")


def _loads_back(text: str, label: str) -> None:
    """ModelError, before anything is written, for a robot file kincal would refuse to load (a calibration's
    values beyond what the loader takes as plausible: a 3.2 deg harmonic)."""
    try:
        data = _parse(text, label)
        _check_plausible(robot_from_dict(data, label), data, label)
    except ModelError as exc:
        raise ModelError(f"{label}: not written: kincal would refuse to load it ({str(exc).removeprefix(label + ': ')}); "
                         f"a fit that puts such values there took up errors its terms cannot describe: calibrate with "
                         f"fewer terms (a smaller --error-model, or auto)") from None


def read_section(name_or_path: str | os.PathLike, key: str) -> object | None:
    """A top-level section of a robot file (None for a bundled robot or when absent)."""
    text, label = _robot_text(name_or_path)
    if label.startswith("bundled") or _is_urdf(name_or_path, text):  # a URDF has no kincal sections
        return None
    data = _parse(text, label)
    return data.get(key) if isinstance(data, dict) else None


def _is_urdf(name_or_path: str | os.PathLike, text: str) -> bool:
    return str(name_or_path).lower().endswith(".urdf") or text.lstrip().startswith("<")


def load_calibration_record(name_or_path: str | os.PathLike) -> dict | None:
    """Read the ``calibration:`` section a calibrated robot file keeps.

    Parameters
    ----------
    name_or_path : str or path-like
        A robot file, or a bundled robot's name.

    Returns
    -------
    dict or None
        The section as saved (covariance, nominal values, options, data settings; see
        :meth:`kincal.CalibrationResult.record`), in SI units; None for a bundled robot, a URDF, or a file
        without one.

    Raises
    ------
    ModelError
        When the file cannot be read or parsed, or the section is not a mapping.

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> import kincal
    >>> from kincal.models import load_calibration_record
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "ur5.yaml")
    ...     kincal.save_robot(kincal.load_robot("ur5"), path, calibration={"rms": 5e-05})
    ...     record = load_calibration_record(path)
    >>> record
    {'rms': 5e-05}
    >>> load_calibration_record("ur5") is None
    True
    """
    section = read_section(name_or_path, "calibration")
    if section is not None and not isinstance(section, dict):
        raise ModelError(f"{name_or_path}: the 'calibration' section must be a mapping")
    return section
