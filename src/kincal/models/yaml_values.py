"""Values in robot files: units, numbers, small mappings; messages name the file and the key."""
from __future__ import annotations

import numpy as np

from .. import units as U
from ..errors import ModelError


def unit_factor(unit: str, kind: str, where: str = "") -> float:
    """SI factor of a length or angle unit in a robot file (ModelError naming the choices)."""
    return U.unit_factor(unit, kind, where, ModelError)


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
    return (unit_factor(str(units.get("length", "m")), "length", f"{label}: "),
            unit_factor(str(units.get("angle", "rad")), "angle", f"{label}: "))


def vector(v, where: str, key: str) -> np.ndarray:
    if not (isinstance(v, list) and len(v) == 3):
        raise ModelError(f"{where}: '{key}' must be [a, b, c]")
    return np.array([num(x, where, key) for x in v])


def pair(v, where: str) -> list:
    if not (isinstance(v, list) and len(v) == 2):
        raise ModelError(f"{where}: 'limits' must be [lower, upper]")
    return v


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
