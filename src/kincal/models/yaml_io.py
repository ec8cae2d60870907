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
is absent it is switched on automatically where consecutive revolute axes are parallel.
"""
from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from .._atomic import write_text_atomic
from ..errors import ModelError
from .puu3 import PUU3Robot, puu3_names
from .robot import Robot
from .serial import CONVENTIONS, Joint, SerialRobot
from .transmission import Map, TransmissionRobot, build_transmission_robot
from .urdf import URDFJoint, URDFRobot, read_urdf, urdf_robot

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6}
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180.0}
_JOINT_KEYS = {"name", "type", "theta", "d", "a", "alpha", "beta", "limits"}
_TOP_KEYS = {"name", "description", "convention", "units", "joints", "base", "tool", "actuators", "transmission",
             "type", "extended", "parameters", "slider_limits", "calibration", "source"}
_URDF_JOINT_KEYS = {"name", "type", "axis", "limits", "xyz", "rpy", "roll", "pitch", "yaw"}
DRIVE_PREFIX = "drive."


def bundled_robots() -> list[str]:
    """Names of the robots shipped with kincal."""
    folder = resources.files("kincal.models") / "robots"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def unit_factor(unit: str, kind: str, where: str = "") -> float:
    """SI factor of a length ('m','mm','um') or angle ('rad','deg') unit."""
    table = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
    if unit not in table:
        raise ModelError(f"{where}unknown {kind} unit '{unit}'; use one of {', '.join(table)}")
    return table[unit]


def load_robot(name_or_path: str | os.PathLike, base_link: str | None = None, tip_link: str | None = None,
               tool: tuple[float, float, float] | None = None) -> Robot:
    """A bundled robot by name (see :func:`bundled_robots`), a robot YAML file or a URDF file.

    For a URDF (a ``.urdf`` file, or any file whose text starts with ``<``): the serial chain from
    ``base_link`` (default: the root link) to ``tip_link`` (default: the only end link), with the
    tool point ``tool`` (m, in the tip link's frame; default its origin).
    """
    text, label = _robot_text(name_or_path)
    if str(name_or_path).lower().endswith(".urdf") or text.lstrip().startswith("<"):
        try:
            return read_urdf(text, label, base_link, tip_link, _tool(tool, label))
        except ModelError as exc:
            if str(exc).startswith(label):
                raise
            raise ModelError(f"{label}: {exc}") from None
        except (TypeError, ValueError) as exc:
            raise ModelError(f"{label}: malformed URDF ({exc})") from None
    if base_link or tip_link or tool is not None:
        raise ModelError(f"{label}: base_link, tip_link and tool apply to URDF files only; a kincal robot file "
                         f"holds its own base and tool")
    data = _parse(text, label)
    try:
        robot = robot_from_dict(data, label)
    except ModelError as exc:
        if str(exc).startswith(label):
            raise
        raise ModelError(f"{label}: {exc}") from None
    except (TypeError, AttributeError, KeyError, ValueError, IndexError) as exc:  # a shape no check foresaw
        raise ModelError(f"{label}: malformed robot file ({type(exc).__name__}: {exc}); see the robot YAML "
                         f"format in the README") from None
    _check_plausible(robot, isinstance(data, dict) and "units" in data, label)
    return robot


def _tool(tool, label: str) -> tuple[float, float, float]:
    if tool is None:
        return (0.0, 0.0, 0.0)
    t = tuple(float(v) for v in tool)
    if len(t) != 3 or not all(np.isfinite(t)):
        raise ModelError(f"{label}: the tool point must be three finite numbers (m), got {tool!r}")
    return t


MAX_LENGTH = 100.0  # m: no robot parameter is longer
MAX_ANGLE = 4 * np.pi  # rad: no geometric angle turns further


def _check_plausible(robot: Robot, has_units: bool, label: str) -> None:
    """Refuse values no robot has; without a ``units`` key say which unit the values look like."""
    v, kinds = robot.params.values, robot.params.kinds
    ang = [(n, x) for n, k, x in zip(robot.params.names, kinds, v) if k == "angle" and abs(x) > MAX_ANGLE / 2]
    lng = [(n, x) for n, k, x in zip(robot.params.names, kinds, v) if k == "length" and abs(x) > 10.0]
    if not has_units and (ang or lng):
        n, x = (ang or lng)[0]
        what = f"{np.rad2deg(x):.0f} deg read as rad" if ang else f"{x:g} m"
        raise ModelError(f"{label}: {n} = {x:g} ({what}) is implausible in the default units m and rad; the values "
                         f"look like {'degrees' if ang else 'mm'}: add 'units: {{length: mm, angle: deg}}'")
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
    if not p.is_file():
        raise ModelError(f"'{s}' is neither a bundled robot ({', '.join(bundled_robots())}) nor a robot YAML file")
    try:
        return p.read_text(encoding="utf-8-sig"), str(p)
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{p}: cannot read the robot file ({exc})") from None


def _parse(text: str, label: str):
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except yaml.YAMLError as exc:
        raise ModelError(f"{label}: not valid YAML ({' '.join(str(exc).split())})") from None


class _UniqueKeyLoader(yaml.SafeLoader):
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


def robot_from_dict(data: dict, label: str = "robot") -> Robot:
    """Build a robot from the parsed YAML mapping; errors name ``label`` and the offending key."""
    if not isinstance(data, dict):
        raise ModelError(f"{label}: expected a mapping with keys {sorted(_TOP_KEYS)}")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ModelError(f"{label}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    if data.get("type", "serial") == "puu3":
        return _puu3_from_dict(data, label)
    if data.get("type") == "urdf":
        return _urdf_from_dict(data, label)
    if data.get("type", "serial") != "serial":
        raise ModelError(f"{label}: unknown robot type '{data.get('type')}'; use 'serial' (default), 'puu3' or 'urdf'")
    for key in ("name", "convention", "joints"):
        if key not in data:
            raise ModelError(f"{label}: missing required key '{key}'")
    conv = str(data["convention"]).lower()
    if conv not in CONVENTIONS:
        raise ModelError(f"{label}: convention '{conv}' is not one of {CONVENTIONS}")
    lf, af = _units(data, label)

    joints, rows, explicit_beta = [], [], []
    if not isinstance(data["joints"], list) or not data["joints"]:
        raise ModelError(f"{label}: 'joints' must be a non-empty list")
    names = [str(jd.get("name", f"j{k + 1}")) for k, jd in enumerate(data["joints"]) if isinstance(jd, dict)]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ModelError(f"{label}: duplicate joint names {', '.join(twice)}; every joint needs its own name")
    for k, jd in enumerate(data["joints"]):
        where = f"{label}: joint {k + 1}"
        if not isinstance(jd, dict):
            raise ModelError(f"{where}: expected a mapping")
        bad = set(jd) - _JOINT_KEYS
        if bad:
            raise ModelError(f"{where}: unknown key(s) {sorted(bad)}; allowed: {sorted(_JOINT_KEYS)}")
        jtype = str(jd.get("type", "revolute"))
        lim = jd.get("limits")
        qf = af if jtype == "revolute" else lf
        if lim is None:
            lo, hi = (-np.pi, np.pi) if jtype == "revolute" else (-1.0, 1.0)
        else:
            if not (isinstance(lim, list) and len(lim) == 2):
                raise ModelError(f"{where}: 'limits' must be [lower, upper]")
            lo, hi = _num(lim[0], where, "limits") * qf, _num(lim[1], where, "limits") * qf
        beta = jd.get("beta", None)
        explicit_beta.append(beta)
        joints.append(Joint(str(jd.get("name", f"j{k + 1}")), jtype, not (beta is None or beta is False), lo, hi))
        row = {key: _num(jd.get(key, 0.0), where, key) * (lf if key in ("d", "a") else af)
               for key in ("theta", "d", "a", "alpha")}
        if not (beta is None or beta is False):
            row["beta"] = _num(beta, where, "beta") * af
        rows.append(row)

    base = {k: _num(v, f"{label}: base", k) * (lf if k in "xyz" else af)
            for k, v in _mapping(data, "base", label).items()}
    tool = {k: _num(v, f"{label}: tool", k) * lf for k, v in _mapping(data, "tool", label).items()}
    robot = SerialRobot.build(str(data["name"]), conv, joints, rows, base, tool, str(data.get("description", "")))
    # automatic beta where axes are parallel and the file does not say otherwise
    auto = {robot.beta_joint(pair) for pair in robot.parallel_pairs()}
    auto = {k for k in auto if explicit_beta[k] is None}
    if auto:
        joints = [Joint(j.name, j.type, True, j.lower, j.upper) if k in auto else j
                  for k, j in enumerate(robot.joints)]
        robot = robot.with_joints(joints)
    if ("transmission" in data) != ("actuators" in data):
        raise ModelError(f"{label}: 'actuators' and 'transmission' go together; give both or neither")
    if "transmission" in data:
        return _transmission_from_dict(robot, data, lf, af, label)
    return robot


_EXAMPLES = {"units": "{length: mm, angle: deg}", "base": "{x: 0, y: 0, z: 0, rx: 0, ry: 0, rz: 0}",
             "tool": "{x: 0, y: 0, z: 0}", "parameters": "{r: 100, R: 200, L1: 350}"}


def _mapping(data: dict, key: str, label: str) -> dict:
    """``data[key]`` as a mapping ({} when absent); ModelError naming the key otherwise."""
    value = data.get(key)
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ModelError(f"{label}: '{key}' must be a mapping like {_EXAMPLES.get(key, '{name: value}')}, got {value!r}")
    return value


def _units(data: dict, label: str) -> tuple[float, float]:
    """SI factors of the file's ``units: {length: …, angle: …}`` (m and rad when absent)."""
    units = _mapping(data, "units", label)
    extra = set(units) - {"length", "angle"}
    if extra:
        raise ModelError(f"{label}: 'units' takes only 'length' and 'angle', got {sorted(map(str, extra))}")
    return (unit_factor(str(units.get("length", "m")), "length", f"{label}: "),
            unit_factor(str(units.get("angle", "rad")), "angle", f"{label}: "))


def _puu3_from_dict(data: dict, label: str) -> PUU3Robot:
    lf, af = _units(data, label)
    extended = bool(data.get("extended", False))
    names, kinds = puu3_names(extended)
    kind = dict(zip(names, kinds))
    values = {}
    for key, v in _mapping(data, "parameters", label).items():
        if key not in kind:
            raise ModelError(f"{label}: unknown 3-PUU parameter '{key}'; known: {', '.join(names[6:])}")
        values[key] = _num(v, f"{label}: parameters", key) * (lf if kind[key] == "length" else af)
    for k, v in _mapping(data, "base", label).items():
        if k not in ("x", "y", "z", "rx", "ry", "rz"):
            raise ModelError(f"{label}: unknown base key '{k}'; use x, y, z, rx, ry, rz")
        values[f"base.{k}"] = _num(v, f"{label}: base", k) * (lf if k in "xyz" else af)
    lim = data.get("slider_limits", [380, 835] if lf == 1e-3 else [0.380, 0.835])
    if not (isinstance(lim, list) and len(lim) == 2):
        raise ModelError(f"{label}: 'slider_limits' must be [lower, upper]")
    lo, hi = _num(lim[0], label, "slider_limits") * lf, _num(lim[1], label, "slider_limits") * lf
    base = PUU3Robot.build(str(data.get("name", "puu3")), extended=extended, h_range=(lo, hi),
                           description=str(data.get("description", "")))
    return base.with_params(values)


def _urdf_from_dict(data: dict, label: str) -> URDFRobot:
    """A URDF chain saved by kincal (type: urdf): per joint the file's origin (xyz, rpy), axis and
    limits, and for moving joints the rotation deviations roll, pitch, yaw."""
    lf, af = _units(data, label)
    if not isinstance(data.get("joints"), list) or not data["joints"]:
        raise ModelError(f"{label}: 'joints' must be a non-empty list")
    joints, values = [], {}
    for k, jd in enumerate(data["joints"]):
        where = f"{label}: joint {k + 1}"
        if not isinstance(jd, dict) or set(jd) - _URDF_JOINT_KEYS or "name" not in jd:
            raise ModelError(f"{where}: a mapping with name and keys from {sorted(_URDF_JOINT_KEYS)}")
        jtype, name = str(jd.get("type", "revolute")), str(jd["name"])
        vec = {key: _vector(jd.get(key, [0.0, 0.0, 0.0] if key != "axis" else [1.0, 0.0, 0.0]), where, key)
               for key in ("xyz", "rpy", "axis")}
        qf = lf if jtype == "prismatic" else af
        lim = jd.get("limits")
        lo, hi = (-np.inf, np.inf) if lim is None else tuple(_num(x, where, "limits") * qf for x in _pair(lim, where))
        joints.append(URDFJoint(name, jtype, tuple(vec["xyz"] * lf), tuple(vec["rpy"] * af), tuple(vec["axis"]), lo, hi))
        if jtype != "fixed":
            values.update({f"{name}.{c}": _num(jd.get(c, 0.0), where, c) * af for c in ("roll", "pitch", "yaw")})
    src = _mapping(data, "source", label)
    tool = tuple(_num(_mapping(data, "tool", label).get(c, 0.0), f"{label}: tool", c) * lf for c in "xyz")
    robot = urdf_robot(str(data.get("name", "urdf_robot")), joints, tool, str(data.get("description", "")),
                       {str(k): str(v) for k, v in src.items()})
    base = {f"base.{k}": _num(v, f"{label}: base", k) * (lf if k in "xyz" else af)
            for k, v in _mapping(data, "base", label).items()}
    return robot.with_params({**values, **base})


def _vector(v, where: str, key: str) -> np.ndarray:
    if not (isinstance(v, list) and len(v) == 3):
        raise ModelError(f"{where}: '{key}' must be [a, b, c]")
    return np.array([_num(x, where, key) for x in v])


def _pair(v, where: str) -> list:
    if not (isinstance(v, list) and len(v) == 2):
        raise ModelError(f"{where}: 'limits' must be [lower, upper]")
    return v


def _urdf_yaml(robot: URDFRobot, length_unit: str, angle_unit: str) -> str:
    lf, af = 1.0 / unit_factor(length_unit, "length"), 1.0 / unit_factor(angle_unit, "angle")
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}", "type: urdf"]
    if robot.description:
        lines.append(f"description: {yaml.safe_dump(robot.description, default_style=chr(34)).strip()}")
    if robot.source:
        lines.append("source: {" + ", ".join(f"{k}: {yaml.safe_dump(str(x), default_style=chr(34)).strip()}"
                                             for k, x in robot.source.items()) + "}")
    lines += [f"units: {{length: {length_unit}, angle: {angle_unit}}}", "joints:"]
    vec = lambda xs, f: "[" + ", ".join(_fmt(x * f) for x in xs) + "]"  # noqa: E731
    for j in robot.joints:
        xyz = [v[f"{j.name}.{c}"] for c in "xyz"] if j.moving else j.xyz
        items = [f"name: {j.name}", f"type: {j.type}", f"axis: {vec(j.axis, 1.0)}", f"xyz: {vec(xyz, lf)}",
                 f"rpy: {vec(j.rpy, af)}"]
        if j.moving:
            items += [f"{c}: {_fmt(v[f'{j.name}.{c}'] * af)}" for c in ("roll", "pitch", "yaw")]
        qf = lf if j.type == "prismatic" else af
        if np.isfinite(j.lower) and np.isfinite(j.upper):
            items.append(f"limits: [{_fmt(j.lower * qf)}, {_fmt(j.upper * qf)}]")
        lines.append("  - {" + ", ".join(items) + "}")
    base = ", ".join(f"{k}: {_fmt(v['base.' + k] * (lf if k in 'xyz' else af))}" for k in ("x", "y", "z", "rx", "ry", "rz"))
    tool = ", ".join(f"{k}: {_fmt(v['tool.' + k] * lf)}" for k in ("x", "y", "z"))
    return "\n".join(lines + [f"base: {{{base}}}", f"tool: {{{tool}}}", ""])


def _puu3_yaml(robot: PUU3Robot, length_unit: str, angle_unit: str) -> str:
    lf, af = 1.0 / unit_factor(length_unit, "length"), 1.0 / unit_factor(angle_unit, "angle")
    v = robot.params.as_dict()
    kinds = dict(zip(robot.params.names, robot.params.kinds))
    params = ", ".join(f"{n}: {_fmt(v[n] * (lf if kinds[n] == 'length' else af))}" for n in robot.params.names[6:])
    base = ", ".join(f"{k}: {_fmt(v['base.' + k] * (lf if k in 'xyz' else af))}" for k in ("x", "y", "z", "rx", "ry", "rz"))
    lines = [f"name: {robot.name}", "type: puu3"]
    if robot.description:
        lines.append(f"description: {yaml.safe_dump(robot.description, default_style=chr(34)).strip()}")
    lines += [f"units: {{length: {length_unit}, angle: {angle_unit}}}", f"extended: {str(robot.extended).lower()}",
              f"parameters: {{{params}}}", f"slider_limits: [{_fmt(robot.h_lower * lf)}, {_fmt(robot.h_upper * lf)}]",
              f"base: {{{base}}}", ""]
    return "\n".join(lines)


def _transmission_from_dict(chain: SerialRobot, data: dict, lf: float, af: float, label: str) -> TransmissionRobot:
    acts = data["actuators"]
    tr = data["transmission"]
    if not isinstance(acts, list) or not acts or not isinstance(tr, dict):
        raise ModelError(f"{label}: 'actuators' must be a list and 'transmission' a mapping with 'parameters' and 'maps'")
    actuators = []
    for k, ad in enumerate(acts):
        where = f"{label}: actuator {k + 1}"
        lim = ad.get("limits") if isinstance(ad, dict) else None
        if not (isinstance(lim, list) and len(lim) == 2) or "name" not in ad:
            raise ModelError(f"{where}: give a name and limits: [lower, upper]")
        actuators.append((str(ad["name"]), _num(lim[0], where, "limits") * af, _num(lim[1], where, "limits") * af))
    act_index = {a[0]: i for i, a in enumerate(actuators)}
    joint_index = {j.name: i for i, j in enumerate(chain.joints)}
    drive = {DRIVE_PREFIX + str(key): (_num(v, f"{label}: transmission parameters", key) * lf, "length")
             for key, v in (tr.get("parameters") or {}).items()}
    maps = []
    for k, md in enumerate(tr.get("maps") or []):
        where = f"{label}: transmission map {k + 1}"
        try:
            a = tuple(act_index[n] for n in md["actuators"])
            j = tuple(joint_index[n] for n in md["joints"])
        except KeyError as exc:
            raise ModelError(f"{where}: unknown actuator or joint {exc}; actuators: {', '.join(act_index)}; "
                             f"joints: {', '.join(joint_index)}") from None
        roles = {"direct": (), "screw": ("lead",), "differential_screw": ("lead", "arm")}.get(md.get("type"), ())
        missing = [r for r in roles if r not in md]
        if missing:
            raise ModelError(f"{where}: missing {', '.join(missing)}")
        maps.append(Map(str(md.get("type")), a, j, tuple(DRIVE_PREFIX + str(md[r]) for r in roles)))
    return build_transmission_robot(chain, actuators, maps, drive)


def _num(v, where: str, key: str) -> float:
    if isinstance(v, str):  # YAML 1.1 reads '31e0' (no dot) as text
        try:
            v = float(v.strip())
        except ValueError:
            pass
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ModelError(f"{where}: '{key}' must be a number, got {v!r}")
    if not np.isfinite(v):
        raise ModelError(f"{where}: '{key}' must be finite, got {v!r}")
    return float(v)


def _fmt(x: float) -> str:
    """Shortest exact float text that YAML reads back as a float."""
    s = repr(float(x))
    if "e" in s and "." not in s.split("e")[0]:
        m, e = s.split("e")
        s = f"{m}.0e{e}"
    return s


def robot_to_yaml(robot: Robot, length_unit: str = "m", angle_unit: str = "rad") -> str:
    """YAML text of a robot. In SI units (the default) load(save(robot)) reproduces it exactly."""
    if isinstance(robot, PUU3Robot):
        return _puu3_yaml(robot, length_unit, angle_unit)
    if isinstance(robot, URDFRobot):
        return _urdf_yaml(robot, length_unit, angle_unit)
    if isinstance(robot, TransmissionRobot):
        return _chain_yaml(robot.chain, length_unit, angle_unit) + _transmission_yaml(robot, length_unit, angle_unit)
    return _chain_yaml(robot, length_unit, angle_unit)


def _transmission_yaml(robot: TransmissionRobot, length_unit: str, angle_unit: str) -> str:
    lf, af = 1.0 / unit_factor(length_unit, "length"), 1.0 / unit_factor(angle_unit, "angle")
    lines = ["actuators:"]
    for name, lo, hi in zip(robot.actuator_names, robot.actuator_lower, robot.actuator_upper):
        lines.append(f"  - {{name: {name}, limits: [{_fmt(lo * af)}, {_fmt(hi * af)}]}}")
    params = ", ".join(f"{n[len(DRIVE_PREFIX):]}: {_fmt(v * lf)}" for n, v in zip(robot.drive.names, robot.drive.values))
    lines += ["transmission:", f"  parameters: {{{params}}}", "  maps:"]
    roles = {"direct": (), "screw": ("lead",), "differential_screw": ("lead", "arm")}
    for mp in robot.maps:
        items = [f"type: {mp.kind}", f"actuators: [{', '.join(robot.actuator_names[a] for a in mp.actuators)}]",
                 f"joints: [{', '.join(robot.chain.joints[j].name for j in mp.joints)}]"]
        items += [f"{role}: {p[len(DRIVE_PREFIX):]}" for role, p in zip(roles[mp.kind], mp.params)]
        lines.append("    - {" + ", ".join(items) + "}")
    return "\n".join(lines) + "\n"


def _chain_yaml(robot: SerialRobot, length_unit: str, angle_unit: str) -> str:
    lf, af = 1.0 / unit_factor(length_unit, "length"), 1.0 / unit_factor(angle_unit, "angle")
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}"]
    if robot.description:
        lines.append(f"description: {yaml.safe_dump(robot.description, default_style=chr(34)).strip()}")
    lines += [f"convention: {robot.convention}", f"units: {{length: {length_unit}, angle: {angle_unit}}}", "joints:"]
    for j in robot.joints:
        qf = af if j.type == "revolute" else lf
        items = [f"name: {j.name}", f"type: {j.type}"]
        for key, f in (("theta", af), ("d", lf), ("a", lf), ("alpha", af)):
            items.append(f"{key}: {_fmt(v[f'{j.name}.{key}'] * f)}")
        items.append(f"beta: {_fmt(v[f'{j.name}.beta'] * af)}" if j.beta else "beta: false")
        items.append(f"limits: [{_fmt(j.lower * qf)}, {_fmt(j.upper * qf)}]")
        lines.append("  - {" + ", ".join(items) + "}")
    base = ", ".join(f"{k}: {_fmt(v['base.' + k] * (lf if k in 'xyz' else af))}" for k in ("x", "y", "z", "rx", "ry", "rz"))
    tool = ", ".join(f"{k}: {_fmt(v['tool.' + k] * lf)}" for k in ("x", "y", "z"))
    lines += [f"base: {{{base}}}", f"tool: {{{tool}}}", ""]
    return "\n".join(lines)


def save_robot(robot: Robot, path: str | os.PathLike, length_unit: str = "m", angle_unit: str = "rad",
               calibration: dict | None = None) -> None:
    """Save a robot YAML (atomically). SI units round-trip exactly; mm/deg are easier to read.

    calibration -- an optional mapping stored under ``calibration:`` (always SI), e.g. the parameter
                   covariance of a calibrated model (read back with :func:`read_section`)
    """
    text = robot_to_yaml(robot, length_unit, angle_unit)
    if calibration:
        text += yaml.safe_dump({"calibration": calibration}, default_flow_style=None, sort_keys=False, width=120)
    write_text_atomic(path, text)


def read_section(name_or_path: str | os.PathLike, key: str) -> object | None:
    """A top-level section of a robot file (None for a bundled robot or when absent)."""
    text, label = _robot_text(name_or_path)
    if label.startswith("bundled"):
        return None
    data = _parse(text, label)
    return data.get(key) if isinstance(data, dict) else None
