"""KUKA's frames held beside a program: ``$config.dat`` (``TOOL_DATA[n]``, ``BASE_DATA[n]``) and ``$machine.dat``
(``$ROBROOT_C``, the robot's base in the world).

A KRL target names its frames by number (``FDAT … TOOL_NO 1, BASE_NO 2``) or by the data itself (``$TOOL =
TOOL_DATA[1]``, ``$BASE = BASE_DATA[2]``); the values live in the controller's ``R1/System/$config.dat``. A tool
frame is in the flange and is used as written. A base frame is in the world frame, so it is turned into the
robot's base frame with ``$ROBROOT_C`` from ``$machine.dat`` (``STEU/Mada``); without that file each base
is named with why it is not known (its targets are refused with that reason, never taken as in the robot's
base). The world itself (``BASE_NO 0``, ``$BASE = $NULLFRAME``) is a base too, placed by ``$ROBROOT_C`` alone
(with or without a ``$config.dat``); without a ``$machine.dat`` it is named with why it is not known (a robot
on a riser or a ceiling stands away from the world's origin), unless the frames give it. Frames are ``{X, Y,
Z, A, B, C}`` (mm, deg, R = Rz(A)·Ry(B)·Rx(C)); a frame with a missing component or a value that is not a number
is an error naming the file, line and column.
"""
from __future__ import annotations

import os
import re

import numpy as np

from ..errors import MeasurementError
from ..models.transforms import rot_zyx
from .krl_scan import POSE_KEYS, _aggregate, _blank, _check_brackets, _check_numbers, _fail

DATA = re.compile(r"^[ \t]*(TOOL_DATA|BASE_DATA)[ \t]*\[[ \t]*(\d+)[ \t]*\][ \t]*=[ \t]*\{", re.M | re.I)
ROBROOT = re.compile(r"^[ \t]*(?:DECL[ \t]+)?(?:FRAME[ \t]+)?\$ROBROOT_C[ \t]*=[ \t]*\{", re.M | re.I)
WORLD_UNKNOWN = ("KRL's base 0 ($BASE = $NULLFRAME) is the world frame, which is the robot's base frame only where "
                 "$ROBROOT_C (the robot's base in the world, in STEU/Mada/$machine.dat) is $NULLFRAME, and no "
                 "$machine.dat was found beside the program: give the controller's folders, or BASE_NO 0 with the "
                 "frames (its pose in the robot's base frame: all zeros where $ROBROOT_C is $NULLFRAME)")
PLACES = {"$config.dat": ("", "System", os.path.join("R1", "System")),  # where each file sits, from an ancestor
          "$machine.dat": ("", "Mada", os.path.join("STEU", "Mada"), os.path.join("KRC", "STEU", "Mada"))}
LEVELS = 4  # ancestors of the program's folder searched


def sibling(program_path: str, name: str) -> str | None:
    """The controller file ``name`` ("$config.dat" or "$machine.dat", any case) for the program at
    ``program_path``: in its folder, else in System (R1/System) or Mada (STEU/Mada) of the nearest of its
    LEVELS ancestors that has one; None when there is none."""
    folder = os.path.dirname(os.path.abspath(program_path))
    for _ in range(LEVELS + 1):
        for place in PLACES[name]:
            found = _named(os.path.join(folder, place), name)
            if found:
                return found
        folder = os.path.dirname(folder)
    return None


def _named(folder: str, name: str) -> str | None:
    """The file called ``name`` in ``folder`` in any case (the first in name order), or None."""
    try:
        hits = sorted(f for f in os.listdir(folder) if f.lower() == name)
    except OSError:
        return None
    return os.path.join(folder, hits[0]) if hits else None


def _text(path: str) -> str:
    try:
        raw = open(path, "rb").read()
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the controller's frames ({exc.strerror})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _frames_in(path: str, pattern: re.Pattern) -> list[tuple[re.Match, np.ndarray]]:
    """Each assignment of a FRAME literal the pattern finds in the file, with its 4x4 pose (m)."""
    return frames_in(path, _text(path), pattern)


def frames_in(path: str, text: str, pattern: re.Pattern) -> list[tuple[re.Match, np.ndarray]]:
    """Each assignment of a FRAME literal the pattern finds in the text (of the file at ``path``), with its 4x4 pose
    (m); a frame without its six components or with a value that is not a number: MeasurementError by line."""
    code = _blank(text)
    ends = _check_brackets(path, text, code)
    out = []
    for m in pattern.finditer(code):
        agg = _aggregate(path, text, code, ends, m.end() - 1)
        missing = [k for k in POSE_KEYS if k not in agg.parts]
        if missing or agg.nested:
            raise _fail(path, text, m.end() - 1, f"a frame needs X, Y, Z, A, B and C (missing: "
                        f"{', '.join(missing) or 'none'}; nothing nested)")
        _check_numbers(path, text, agg)
        x, y, z, a, b, c = (float(text[slice(*agg.parts[k])]) for k in POSE_KEYS)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rot_zyx(*np.radians([a, b, c])), np.array([x, y, z]) * 1e-3
        out.append((m, T))
    return out


def robroot(path: str) -> np.ndarray:
    """The robot's base in the world (4x4, m): ``$ROBROOT_C`` of a ``$machine.dat`` (MeasurementError if absent)."""
    found = _frames_in(path, ROBROOT)
    if not found:
        raise MeasurementError(f"{path}: no $ROBROOT_C (the robot's base in the world) in this file")
    return found[-1][1]


def config_frames(path: str, root: np.ndarray | None) -> dict[str, np.ndarray | str]:
    """The tools and bases of a ``$config.dat`` by the names KRL targets use for them ("TOOL_DATA[1]" and
    "TOOL_NO 1", "BASE_DATA[2]" and "BASE_NO 2"; 4x4, m, in the flange and in the robot's base frame). Bases
    only with ``root`` ($ROBROOT_C), and then the world itself as "BASE_NO 0" and "$NULLFRAME"; without it,
    each base's name maps to why it is not known."""
    out: dict[str, np.ndarray | str] = {}
    inverse = None if root is None else np.linalg.inv(root)
    for m, T in _frames_in(path, DATA):
        kind, n = m.group(1).upper(), int(m.group(2))
        pose: np.ndarray | str = T if kind == "TOOL_DATA" else inverse @ T if inverse is not None else (
            f"{path} gives BASE_DATA[{n}] in the world frame, and no $machine.dat with $ROBROOT_C (the robot's base "
            f"in the world; STEU/Mada) was found beside it: give the base in the robot's base frame with the frames")
        out[f"{kind}[{n}]"] = out[f"{kind[:4]}_NO {n}"] = pose
    if inverse is not None:
        out["BASE_NO 0"] = out["$NULLFRAME"] = inverse
    return out


def program_frames(program) -> dict[str, np.ndarray | str]:
    """The frames of the ``$config.dat`` beside a KRL program (:func:`sibling`; its bases with the
    ``$machine.dat`` beside it), and the world as "BASE_NO 0" and "$NULLFRAME": placed in the robot's base by
    the ``$machine.dat``'s ``$ROBROOT_C``, else why it cannot be (:data:`WORLD_UNKNOWN`)."""
    config, machine = sibling(program.source, "$config.dat"), sibling(program.source, "$machine.dat")
    root = None if machine is None else robroot(machine)
    world: np.ndarray | str = WORLD_UNKNOWN if root is None else np.linalg.inv(root)
    return {"BASE_NO 0": world, "$NULLFRAME": world, **({} if config is None else config_frames(config, root))}
