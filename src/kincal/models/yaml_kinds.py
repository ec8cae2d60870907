"""Robot files for the model kinds beyond DH chains: 3-PUU, transmissions, URDF chains (kincal YAML)."""
from __future__ import annotations

import os
import re
from itertools import product

import numpy as np
import yaml

from .. import units as U
from ..errors import ModelError
from .puu3 import PUU3Robot, puu3_names
from .serial import SerialRobot
from .stewart import COMPLIANCE, StewartRobot
from .delta import DeltaRobot, delta_names
from .serial import BASE_NAMES
from .transmission import Map, TransmissionRobot, build_transmission_robot
from .robot import Robot
from .covariates import Covariate, covariate_from_dict, thermal_from_dict
from .terms import MAX_PAYLOAD, TERMS, ExtendedRobot, GravityTerm, Harmonics
from .urdf import URDFJoint, URDFRobot, urdf_robot
from .yaml_values import (base_pose, description_lines, fmt, frame_text, limits, link_mass, mapping, mass_items, num,
                          per_unit, units, vector)

URDF_JOINT_KEYS = {"name", "type", "axis", "limits", "xyz", "rpy", "roll", "pitch", "yaw", "mass", "com"}
DRIVE_PREFIX = "drive."
ROLES = {"direct": (), "screw": ("lead",), "differential_screw": ("lead", "arm"), "coupled": ()}  # drive parameters


def puu3_from_dict(data: dict, label: str) -> PUU3Robot:
    lf, af = units(data, label)
    extended = bool(data.get("extended", False))
    names, kinds = puu3_names(extended)
    kind = dict(zip(names, kinds))
    values = {}
    for key, v in mapping(data, "parameters", label).items():
        if key not in kind:
            raise ModelError(f"{label}: unknown 3-PUU parameter '{key}'; known: {', '.join(names[6:])}")
        values[key] = num(v, f"{label}: parameters", key) * (lf if kind[key] == "length" else af)
    values.update({f"base.{k}": x for k, x in base_pose(data, label, lf, af, strict=True).items()})
    lo, hi = limits(data.get("slider_limits", [380, 835] if lf == 1e-3 else [0.380, 0.835]), label, lf, "slider_limits")
    robot = PUU3Robot.build(str(data.get("name", "puu3")), extended=extended, h_range=(lo, hi),
                            description=str(data.get("description", "")))
    return robot.with_params(values)


def _parameters_text(robot: Robot, lf: float, af: float) -> str:
    """'parameters: {…}' of every parameter after the base frame, in the file's units (``lf``, ``af``: per m, rad)."""
    v, kinds = robot.params.as_dict(), dict(zip(robot.params.names, robot.params.kinds))
    return "parameters: {" + ", ".join(f"{n}: {fmt(v[n] * (lf if kinds[n] == 'length' else af))}"
                                       for n in robot.params.names[6:]) + "}"


def puu3_yaml(robot: PUU3Robot, length_unit: str, angle_unit: str) -> str:
    lf, af = per_unit(length_unit, angle_unit)
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}", "type: puu3", *description_lines(robot.description)]
    lines += [f"units: {{length: {length_unit}, angle: {angle_unit}}}", f"extended: {str(robot.extended).lower()}",
              _parameters_text(robot, lf, af), f"slider_limits: [{fmt(robot.h_lower * lf)}, {fmt(robot.h_upper * lf)}]",
              frame_text(v, "base", lf, af), ""]
    return "\n".join(lines)


def urdf_from_dict(data: dict, label: str) -> URDFRobot:
    """A URDF chain saved by kincal (type: urdf): per joint the file's origin (xyz, rpy), axis and
    limits, and for moving joints the rotation deviations roll, pitch, yaw."""
    lf, af = units(data, label)
    if not isinstance(data.get("joints"), list) or not data["joints"]:
        raise ModelError(f"{label}: 'joints' must be a non-empty list")
    joints, values = [], {}
    for k, jd in enumerate(data["joints"]):
        where = f"{label}: joint {k + 1}"
        if not isinstance(jd, dict) or set(jd) - URDF_JOINT_KEYS or "name" not in jd:
            raise ModelError(f"{where}: a mapping with name and keys from {sorted(URDF_JOINT_KEYS)}")
        jtype, name = str(jd.get("type", "revolute")), str(jd["name"])
        vec = {key: vector(jd.get(key, [0.0, 0.0, 0.0] if key != "axis" else [1.0, 0.0, 0.0]), where, key)
               for key in ("xyz", "rpy", "axis")}
        qf = lf if jtype == "prismatic" else af
        lim = jd.get("limits")
        lo, hi = (-np.inf, np.inf) if lim is None else limits(lim, where, qf)
        joints.append(URDFJoint(name, jtype, tuple(vec["xyz"] * lf), tuple(vec["rpy"] * af), tuple(vec["axis"]), lo, hi,
                                *link_mass(jd, lf, where)))
        if jtype != "fixed":
            values.update({f"{name}.{c}": num(jd.get(c, 0.0), where, c) * af for c in ("roll", "pitch", "yaw")})
    src = {str(k): str(v) for k, v in mapping(data, "source", label).items()}
    if "file" in src and not os.path.isabs(src["file"]):  # written relative to the robot file's folder
        src["file"] = os.path.join(os.path.dirname(label), src["file"])
    tool = tuple(num(mapping(data, "tool", label).get(c, 0.0), f"{label}: tool", c) * lf for c in "xyz")
    robot = urdf_robot(str(data.get("name", "urdf_robot")), joints, tool, str(data.get("description", "")), src)
    base = {f"base.{k}": x for k, x in base_pose(data, label, lf, af).items()}
    return robot.with_params({**values, **base})


def urdf_yaml(robot: URDFRobot, length_unit: str, angle_unit: str, folder: str | None = None) -> str:
    """The kincal YAML of a URDF chain; its source URDF's path relative to ``folder``, the folder of the robot file
    written (where loading resolves it), else absolute."""
    lf, af = per_unit(length_unit, angle_unit)
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}", "type: urdf", *description_lines(robot.description)]
    if robot.source:
        src = {**robot.source, **({"file": _path_from(robot.source["file"], folder)} if "file" in robot.source else {})}
        lines.append("source: {" + ", ".join(f"{k}: {yaml.safe_dump(str(x), default_style=chr(34)).strip()}"
                                             for k, x in src.items()) + "}")
    lines += [f"units: {{length: {length_unit}, angle: {angle_unit}}}", "joints:"]
    vec = lambda xs, f: "[" + ", ".join(fmt(x * f) for x in xs) + "]"  # noqa: E731
    for j in robot.joints:
        xyz = [v[f"{j.name}.{c}"] for c in "xyz"] if j.moving else j.xyz
        items = [f"name: {j.name}", f"type: {j.type}", f"axis: {vec(j.axis, 1.0)}", f"xyz: {vec(xyz, lf)}",
                 f"rpy: {vec(j.rpy, af)}"]
        if j.moving:
            items += [f"{c}: {fmt(v[f'{j.name}.{c}'] * af)}" for c in ("roll", "pitch", "yaw")]
        qf = lf if j.type == "prismatic" else af
        if np.isfinite(j.lower) and np.isfinite(j.upper):
            items.append(f"limits: [{fmt(j.lower * qf)}, {fmt(j.upper * qf)}]")
        lines.append("  - {" + ", ".join(items + mass_items(j, lf)) + "}")
    return "\n".join(lines + [frame_text(v, "base", lf, af), frame_text(v, "tool", lf, af), ""])


def _path_from(path: str, folder: str | None) -> str:
    """``path`` relative to ``folder`` (absolute without one, or on another drive)."""
    if folder is None:
        return os.path.abspath(path)
    try:
        return os.path.relpath(os.path.abspath(path), os.path.abspath(folder or "."))
    except ValueError:  # Windows: another drive
        return os.path.abspath(path)


def transmission_from_dict(chain: SerialRobot, data: dict, lf: float, af: float, label: str) -> TransmissionRobot:
    acts, tr = data["actuators"], data["transmission"]
    if not isinstance(acts, list) or not acts or not isinstance(tr, dict):
        raise ModelError(f"{label}: 'actuators' must be a list and 'transmission' a mapping with 'parameters' and 'maps'")
    actuators = []
    for k, ad in enumerate(acts):
        where = f"{label}: actuator {k + 1}"
        lim = ad.get("limits") if isinstance(ad, dict) else None
        if not (isinstance(lim, list) and len(lim) == 2) or "name" not in ad:
            raise ModelError(f"{where}: give a name and limits: [lower, upper]")
        actuators.append((str(ad["name"]), *limits(lim, where, af)))
    act_index = {a[0]: i for i, a in enumerate(actuators)}
    joint_index = {name: i for i, name in enumerate(chain.joint_names)}
    drive = {DRIVE_PREFIX + str(key): (num(v, f"{label}: transmission parameters", key) * lf, "length")
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
        roles = ROLES.get(md.get("type"), ())
        missing = [r for r in roles if r not in md]
        if missing:
            raise ModelError(f"{where}: missing {', '.join(missing)}")
        factor = num(md["factor"], where, "factor") if "factor" in md else 1.0  # coupled: qb = φb + factor·φa
        maps.append(Map(str(md.get("type")), a, j, tuple(DRIVE_PREFIX + str(md[r]) for r in roles), factor))
    return build_transmission_robot(chain, actuators, maps, drive)


def transmission_yaml(robot: TransmissionRobot, length_unit: str, angle_unit: str) -> str:
    lf, af = per_unit(length_unit, angle_unit)
    lines = ["actuators:"] + [f"  - {{name: {name}, limits: [{fmt(lo * af)}, {fmt(hi * af)}]}}"
                              for name, lo, hi in zip(robot.joint_names, robot.lower, robot.upper)]
    params = ", ".join(f"{n[len(DRIVE_PREFIX):]}: {fmt(v * lf)}" for n, v in zip(robot.drive.names, robot.drive.values))
    lines += ["transmission:", f"  parameters: {{{params}}}", "  maps:"]
    for mp in robot.maps:
        items = [f"type: {mp.type}", f"actuators: [{', '.join(robot.joint_names[a] for a in mp.actuators)}]",
                 f"joints: [{', '.join(robot.inner.joint_names[j] for j in mp.chain_joints)}]"]
        items += [f"{role}: {p[len(DRIVE_PREFIX):]}" for role, p in zip(ROLES[mp.type], mp.param_names)]
        items += [f"factor: {fmt(mp.factor)}"] if mp.type == "coupled" else []
        lines.append("    - {" + ", ".join(items) + "}")
    return "\n".join(lines) + "\n"


def error_model_yaml(robot: ExtendedRobot) -> str:
    """The non-geometric terms (always SI: rad, kg, m; a thermal term per unit of its covariate), the
    geometry their gravity loads and thermal growth use, and the covariates the robot reads with the
    reference and range they were fitted on (in the column's unit)."""
    block: dict = {"terms": [t.to_dict() for t in robot.terms]}
    if robot.covariates:
        block["covariates"] = [c.to_dict() for c in robot.covariates]
    refs = [t.reference for t in robot.terms if t.reference is not None]
    if refs:
        block["reference"] = {n: float(v) for n, v in zip(refs[0].params.names, refs[0].params.values)}
    block["values"] = {n: float(robot.params[n]) for n in robot.term_names}
    return yaml.safe_dump({"error_model": block}, default_flow_style=None, sort_keys=False, width=120)


def error_model_from_dict(geometry: Robot, data, label: str) -> ExtendedRobot:
    where = f"{label}: error_model"
    if not isinstance(data, dict) or set(data) - {"terms", "reference", "values", "covariates"} \
            or not isinstance(data.get("terms"), list) or not isinstance(data.get("covariates", []), list):
        raise ModelError(f"{where}: a mapping with terms, values, (for gravity and thermal terms) reference and "
                         f"(for covariates the model reads) covariates")
    values = {str(k): num(v, where, str(k)) for k, v in mapping(data, "values", where).items()}
    covariates = tuple(covariate_from_dict(c, f"{where}: covariate {k + 1}")
                       for k, c in enumerate(data.get("covariates", [])))
    reference = None
    if "reference" in data:
        ref = {str(k): num(v, f"{where}: reference", str(k)) for k, v in mapping(data, "reference", where).items()}
        if set(ref) != set(geometry.params.names):
            raise ModelError(f"{where}: 'reference' must give every parameter of the robot ({len(geometry.params)})")
        reference = geometry.with_params(ref)
    terms = [term_from_dict(geometry, reference, t, f"{where}: term {k + 1}", covariates)
             for k, t in enumerate(data["terms"])]
    if not terms and not covariates:
        raise ModelError(f"{where}: no terms and no covariates: leave the error_model section out")
    robot = ExtendedRobot.build(geometry, terms, covariates=covariates)
    unknown = sorted(set(values) - set(robot.term_names))
    if unknown:
        raise ModelError(f"{where}: unknown term(s) {', '.join(unknown)}")
    big = [n for n, v in values.items() if re.fullmatch(r".+\.h\d[sc]", n) and abs(v) > MAX_HARMONIC]
    if big:
        raise ModelError(f"{where}: harmonic amplitude(s) {', '.join(f'{n} = {values[n]:g} rad' for n in big)} are "
                         f"implausible (limit {MAX_HARMONIC:g} rad; real transmission errors are below 0.01 rad): the "
                         f"values are in rad, or calibrate again")
    return robot.with_params(values)


MAX_HARMONIC = 0.05  # rad: a joint-angle harmonic beyond this is not a transmission error (3 deg)


LEG_KEYS = {"base", "platform", "zero", "scale", "lead", "range"}


def stewart_from_dict(data: dict, label: str) -> StewartRobot:
    """A hexapod (type: stewart): six ``legs`` ({base, platform: [x, y, z], zero, range: [lower, upper],
    with a motor ``reading`` also lead (length per reading unit), optionally scale}) in the file's units;
    ``compliance``: the legs' give under the platform's whole weight (a length), which adds that term."""
    lf, af = units(data, label)
    reading = mapping(data, "reading", label)
    rf = U.unit_factor(str(reading.get("unit", "rad")), "angle", f"{label}: reading: ", ModelError) if reading else lf
    legs = data.get("legs")
    if not (isinstance(legs, list) and len(legs) == 6 and all(isinstance(leg, dict) for leg in legs)):
        raise ModelError(f"{label}: 'legs' must list the six legs, each like {{base: [x, y, z], platform: [x, y, z], "
                         f"zero: …, range: [lower, upper]{', lead: …' if reading else ''}}}")
    values: dict[str, float] = {}
    lo, hi, lead = [], [], []
    for i, leg in enumerate(legs, 1):
        where = f"{label}: legs[{i}]"
        if extra := set(leg) - LEG_KEYS:
            raise ModelError(f"{where}: unknown key(s) {sorted(map(str, extra))}; use {', '.join(sorted(LEG_KEYS))}")
        if ("lead" in leg) != bool(reading):
            raise ModelError(f"{where}: 'lead' (travel per reading unit) goes with a motor 'reading: {{unit: rev}}'; "
                             f"{'give it' if reading else 'leave it out for legs read as lengths'}")
        for key, ax in (("base", "b"), ("platform", "p")):
            values.update(zip((f"leg{i}.{ax}{c}" for c in "xyz"), vector(leg.get(key), where, key) * lf))
        values[f"leg{i}.zero"] = num(leg.get("zero"), where, "zero") * lf
        values[f"leg{i}.scale"] = num(leg.get("scale", 1.0), where, "scale")
        if not 0.5 < values[f"leg{i}.scale"] < 2.0:
            raise ModelError(f"{where}: 'scale' {values[f'leg{i}.scale']:g} is the ratio of the leg's true travel to "
                             f"its nominal one (1 nominal); a leg off by a factor of 2 has the wrong lead or unit")
        lo_hi = limits(leg.get("range"), where, rf, "range")
        lo.append(lo_hi[0])
        hi.append(lo_hi[1])
        lead.append(num(leg["lead"], where, "lead") * lf / rf if reading else 1.0)
    values.update({f"base.{k}": x for k, x in base_pose(data, label, lf, af, strict=True).items()})
    values.update({f"tool.{k}": num(v, f"{label}: tool", k) * lf for k, v in mapping(data, "tool", label).items()})
    b = [[values[f"leg{i}.b{c}"] for c in "xyz"] for i in range(1, 7)]
    p = [[values[f"leg{i}.p{c}"] for c in "xyz"] for i in range(1, 7)]
    robot = StewartRobot.build(str(data.get("name", "stewart")), b, p, [values[f"leg{i}.zero"] for i in range(1, 7)],
                               (lo, hi), lead if reading else None, str(data.get("description", "")))
    if "compliance" in data:
        robot = robot.with_load_compliance()
        values[COMPLIANCE] = num(data["compliance"], label, "compliance") * lf
    return robot.with_params(values)


def stewart_yaml(robot: StewartRobot, length_unit: str, angle_unit: str, reading_unit: str = "rev") -> str:
    """The robot file of a hexapod (legs read as motor angles are written in ``reading_unit``)."""
    lf, af = per_unit(length_unit, angle_unit)
    motor = robot.motor
    rf = 1.0 / U.unit_factor(reading_unit, "angle", "", ModelError) if motor else lf
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}", "type: stewart", *description_lines(robot.description),
             f"units: {{length: {length_unit}, angle: {angle_unit}}}"]
    lines += [f"reading: {{unit: {reading_unit}}}"] if motor else []
    lines.append("legs:")
    for i in range(1, 7):
        items = [f"{key}: [{', '.join(fmt(v[f'leg{i}.{ax}{c}'] * lf) for c in 'xyz')}]"
                 for key, ax in (("base", "b"), ("platform", "p"))]
        items += [f"zero: {fmt(v[f'leg{i}.zero'] * lf)}", f"scale: {fmt(v[f'leg{i}.scale'])}"]
        items += [f"lead: {fmt(robot.lead[i - 1] * lf / rf)}"] if motor else []
        items.append(f"range: [{fmt(robot.lower[i - 1] * rf)}, {fmt(robot.upper[i - 1] * rf)}]")
        lines.append(f"  - {{{', '.join(items)}}}")
    lines += [f"compliance: {fmt(v[COMPLIANCE] * lf)}  # the legs' give under the platform's whole weight"] \
        if robot.compliance else []
    lines += [frame_text(v, "base", lf, af), frame_text(v, "tool", lf, af), ""]
    return "\n".join(lines)


def delta_from_dict(data: dict, label: str) -> DeltaRobot:
    """A delta robot (type: delta): the design ``arms: {R, r, L, l}`` shared by the three arms, per-arm
    ``parameters`` (arm<i>.R … arm<i>.phi) on top, ``arm_limits: [lower, upper]`` in the file's units."""
    lf, af = units(data, label)
    names, kinds = delta_names()
    kind = dict(zip(names, kinds))
    design = mapping(data, "arms", label)
    if extra := set(design) - {"R", "r", "L", "l"}:
        raise ModelError(f"{label}: 'arms' takes R, r, L and l (the design shared by the three arms), got "
                         f"{sorted(map(str, extra))}")
    values = {f"arm{i}.{k}": num(x, f"{label}: arms", k) * lf for k, x in design.items() for i in (1, 2, 3)}
    for key, v in mapping(data, "parameters", label).items():
        if key not in kind or key in BASE_NAMES:
            raise ModelError(f"{label}: unknown delta parameter '{key}'; known: {', '.join(names[6:])}")
        values[key] = num(v, f"{label}: parameters", key) * (lf if kind[key] == "length" else af)
    values.update({f"base.{k}": x for k, x in base_pose(data, label, lf, af, strict=True).items()})
    robot = DeltaRobot.build(str(data.get("name", "delta")), q_range=limits(data.get("arm_limits"), label, af,
                                                                            "arm_limits"),
                             description=str(data.get("description", "")))
    return robot.with_params(values)


def delta_yaml(robot: DeltaRobot, length_unit: str, angle_unit: str) -> str:
    lf, af = per_unit(length_unit, angle_unit)
    v = robot.params.as_dict()
    lines = [f"name: {robot.name}", "type: delta", *description_lines(robot.description),
             f"units: {{length: {length_unit}, angle: {angle_unit}}}", _parameters_text(robot, lf, af),
             f"arm_limits: [{fmt(robot.q_lower * af)}, {fmt(robot.q_upper * af)}]",
             frame_text(v, "base", lf, af), ""]
    return "\n".join(lines)


def term_from_dict(geometry: Robot, reference: Robot | None, data: dict, where: str,
                   covariates: tuple[Covariate, ...] = ()):
    """A term saved by :meth:`to_dict` (``reference``: the geometry of its gravity loads and thermal
    growth; ``covariates``: the robot's, for a thermal term)."""
    term_type = data.get("type") if isinstance(data, dict) else None
    if term_type == "thermal":
        return thermal_from_dict(geometry if reference is None else reference, covariates, data, where)
    index = {j: i for i, j in enumerate(geometry.joint_names)}
    joints = data.get("joints", []) if isinstance(data, dict) else None
    if term_type not in TERMS or not isinstance(joints, list) or any(j not in index for j in joints):
        raise ModelError(f"{where}: a term is {{type: harmonics|compliance|gravity-regressor|thermal, ...}} on joints "
                         f"of "
                         f"the robot ({', '.join(geometry.joint_names)})")
    if term_type == "harmonics":
        order = data.get("order")
        if not isinstance(order, int) or isinstance(order, bool) or not 1 <= order <= 4:
            raise ModelError(f"{where}: harmonics 'order' must be a whole number from 1 to 4")
        return Harmonics(order, tuple(index[j] for j in joints), tuple(joints))
    payload = data.get("payload", 0.0)
    if reference is None or not reference.has_gravity or isinstance(payload, bool) \
            or not isinstance(payload, (int, float)) or not 0 <= payload <= MAX_PAYLOAD:
        raise ModelError(f"{where}: a gravity term needs a serial chain, its 'reference' geometry and a payload in kg "
                         f"(0 to {MAX_PAYLOAD:g})")
    gravity = reference.gravity(float(payload))
    if term_type == "compliance":
        return GravityTerm(term_type, gravity, tuple((index[j], 0, 0) for j in joints))
    every = GravityTerm(term_type, gravity, tuple(product(range(len(index)), range(len(gravity.links())), range(4))))
    known = dict(zip(every.names, every.columns))  # <joint>.g_<link>_<m|x|y|z> -> column
    names = [str(n) for n in data["columns"]] if isinstance(data.get("columns"), list) else ["None"]
    for name in names:
        if name not in known:
            raise ModelError(f"{where}: gravity-regressor column '{name}' is not <joint>.g_<link>_<m|x|y|z>")
    return GravityTerm(term_type, gravity, tuple(known[n] for n in names))
