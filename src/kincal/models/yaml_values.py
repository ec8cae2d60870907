"""Values in robot files: units, numbers, small mappings; messages name the file and the key."""
from __future__ import annotations

import numpy as np
import yaml

from .. import units as U
from ..errors import ModelError


def per_unit(length_unit: str, angle_unit: str) -> tuple[float, float]:
    """File units per m and per rad, to write a robot file in ``length_unit`` and ``angle_unit`` (a
    ModelError naming the choices for an unknown unit)."""
    return (1.0 / U.unit_factor(length_unit, "length", "", ModelError),
            1.0 / U.unit_factor(angle_unit, "angle", "", ModelError))


POSE_KEYS = ("x", "y", "z", "rx", "ry", "rz")  # a frame's pose in a robot file: position, then rotations


EXAMPLES = {"units": "{length: mm, angle: deg}", "base": "{x: 0, y: 0, z: 0, rx: 0, ry: 0, rz: 0}",
             "tool": "{x: 0, y: 0, z: 0}", "parameters": "{r: 100, R: 200, L1: 350}"}


def mapping(data: dict, key: str, label: str) -> dict:
    """``data[key]`` as a mapping ({} when absent); ModelError naming the key otherwise."""
    value = data.get(key)
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ModelError(f"{label}: '{key}' must be a mapping like {EXAMPLES.get(key, '{name: value}')}, got {value!r}")
    return value


def units(data: dict, label: str) -> tuple[float, float]:
    """SI factors of the file's ``units: {length: …, angle: …}`` (m and rad when absent)."""
    units = mapping(data, "units", label)
    extra = set(units) - {"length", "angle"}
    if extra:
        raise ModelError(f"{label}: 'units' takes only 'length' and 'angle', got {sorted(map(str, extra))}")
    return (U.unit_factor(str(units.get("length", "m")), "length", f"{label}: ", ModelError),
            U.unit_factor(str(units.get("angle", "rad")), "angle", f"{label}: ", ModelError))


def base_pose(data: dict, label: str, lf: float, af: float, strict: bool = False) -> dict:
    """The file's ``base: {x, y, z, rx, ry, rz}`` in SI (m, rad; ``lf``, ``af``: SI per file unit) by
    key, the keys given only; with ``strict`` a key not of these is refused here."""
    out = {}
    for k, v in mapping(data, "base", label).items():
        if strict and k not in POSE_KEYS:
            raise ModelError(f"{label}: unknown base key '{k}'; use x, y, z, rx, ry, rz")
        out[k] = num(v, f"{label}: base", k) * (lf if k in "xyz" else af)
    return out


def vector(v, where: str, key: str) -> np.ndarray:
    if not (isinstance(v, list) and len(v) == 3):
        raise ModelError(f"{where}: '{key}' must be [a, b, c]")
    return np.array([num(x, where, key) for x in v])


def limits(v, where: str, factor: float, key: str = "limits") -> tuple[float, float]:
    """``[lower, upper]`` in SI (``factor``: SI per file unit)."""
    if not (isinstance(v, list) and len(v) == 2):
        raise ModelError(f"{where}: '{key}' must be [lower, upper]")
    return num(v[0], where, key) * factor, num(v[1], where, key) * factor


def num(v, where: str, key: str) -> float:
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


def fmt(x: float) -> str:
    """Shortest exact float text that YAML reads back as a float."""
    s = repr(float(x))
    if "e" in s and "." not in s.split("e")[0]:
        m, e = s.split("e")
        s = f"{m}.0e{e}"
    return s


def description_lines(description: str) -> list[str]:
    """The ``description:`` line of a robot file (none without a description)."""
    return [f"description: {yaml.safe_dump(description, default_style=chr(34)).strip()}"] if description else []


def pose_text(pose, lf: float, af: float) -> str:
    """'x: …, y: …, z: …, rx: …, ry: …, rz: …' of a pose (SI; three values: a point) in the file's
    units (``lf``, ``af``: file units per m and per rad)."""
    return ", ".join(f"{k}: {fmt(x * (lf if k in 'xyz' else af))}" for k, x in zip(POSE_KEYS, pose))


def frame_text(values: dict, frame: str, lf: float, af: float) -> str:
    """The ``base: {x … rz}`` or ``tool: {x, y, z}`` line of the parameters in ``values`` (SI): :func:`pose_text`."""
    keys = POSE_KEYS if frame == "base" else POSE_KEYS[:3]
    return f"{frame}: {{{pose_text([values[f'{frame}.{k}'] for k in keys], lf, af)}}}"


def link_mass(jd: dict, lf: float, where: str) -> tuple[float, tuple[float, float, float]]:
    """A joint entry's optional link ``mass`` (kg) and ``com`` (length unit of the file)."""
    mass = num(jd.get("mass", 0.0), where, "mass")
    if mass < 0.0:
        raise ModelError(f"{where}: 'mass' {mass} kg is negative; give the link's mass in kg (0 if unknown)")
    com = vector(jd.get("com", [0.0, 0.0, 0.0]), where, "com") * lf
    return mass, (float(com[0]), float(com[1]), float(com[2]))


def mass_items(joint, lf: float) -> list[str]:
    """``mass`` and ``com`` items of a joint entry (none when the link has no mass)."""
    if joint.mass == 0.0 and not any(joint.com):
        return []
    return [f"mass: {fmt(joint.mass)}", "com: [" + ", ".join(fmt(c * lf) for c in joint.com) + "]"]
