"""The frames file of ``kincal compensate --program …``: the tool and base frames a program names.

YAML, one entry per frame name: ``{x, y, z, rx, ry, rz}`` (the frame in the flange or in the robot's base
frame; R = Rz(rz)·Ry(ry)·Rx(rx)), lengths in mm and angles in deg unless ``units: {length: …, angle: …}``
says otherwise; missing coordinates are 0. Or a KUKA ``$config.dat`` (:mod:`kincal.io.krl_config`).

A frame taught on the robot is itself a measurement: the controller computed it from where its nominal model
put the TCP, while the TCP really was where the calibrated model puts it. Such an entry says how it was taught
(``taught:``): the joints of its teach poses (in the file's angle unit, as the controller shows them), the rule
(``origin-x-xy``: a base from its origin, a point on +x and a point in the xy plane with y > 0, as KUKA's and
FANUC's three-point methods; ``x1-x2-y1``: ABB's user frame from two points on x and one on y, the origin the
foot of y1 on the x line; ``fixed-point``: a tool's TCP from four or more flange poses touching one point,
the TCP's axes the flange's) and, for a base, the tool it was taught with (a frame name of this file). Its
values (x … rz), when given, are the controller's frame, checked against the one the taught joints give.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Mapping

import numpy as np

KEYS = ("x", "y", "z", "rx", "ry", "rz")
RULES = {"origin-x-xy": ("base", 3), "x1-x2-y1": ("base", 3), "fixed-point": ("tool", 4)}  # -> kind, least poses


@dataclass(frozen=True)
class TaughtFrame:
    """A frame taught on the robot, as a frames file's ``taught:`` entry gives it.

    Parameters
    ----------
    name : str
        The frame's name in the file.
    rule : str
        How it was taught, one of :data:`RULES`: "origin-x-xy" and "x1-x2-y1" (a base, 3 teach poses),
        "fixed-point" (a tool, 4 or more).
    joints : ndarray, shape (K, n)
        The joints of its teach poses, rad.
    tool : str
        The tool a base was taught with (a frame name of the same file); '' for a tool.
    declared : ndarray, shape (4, 4) or None
        The controller's frame as written, m (None when the file gives none: the taught joints then give it).

    See Also
    --------
    read_frames : The frames file that holds it.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.io import TaughtFrame
    >>> joints = np.radians([[0, -90, 90, 0, 45, 0], [10, -90, 90, 0, 45, 0], [0, -80, 90, 0, 45, 0]])
    >>> plate = TaughtFrame("plate", "origin-x-xy", joints, tool="gripper", declared=None)
    >>> plate.kind, plate.joints.shape
    ('base', (3, 6))
    """

    name: str
    rule: str
    joints: np.ndarray
    tool: str
    declared: np.ndarray | None

    @property
    def kind(self) -> str:
        return RULES[self.rule][0]


def frames_read(path: str) -> tuple[str, ...]:
    """The files :func:`read_frames` reads for ``path``: the file, and for a KUKA ``$config.dat`` the ``$machine.dat``
    beside it (:func:`kincal.io.krl_config.sibling`) when there is one.

    Parameters
    ----------
    path : str
        The frames file.

    Returns
    -------
    tuple of str
        The paths, ``path`` first.

    Examples
    --------
    >>> from kincal.io.frames_file import frames_read
    >>> frames_read("cell/frames.yaml")
    ('cell/frames.yaml',)
    """
    if os.path.basename(str(path)).lower() != "$config.dat":
        return (str(path),)
    from .krl_config import sibling

    machine = sibling(str(path), "$machine.dat")
    return (str(path),) + (() if machine is None else (machine,))


def read_frames(path: str) -> Mapping[str, np.ndarray | str | TaughtFrame]:
    """Read the frames of a frames file, by name.

    A YAML file maps each frame's name to ``{x, y, z, rx, ry, rz}`` (the frame in the flange or in the
    robot's base frame; R = Rz(rz)·Ry(ry)·Rx(rx); missing coordinates are 0), lengths in mm and angles in deg
    unless ``units: {length: …, angle: …}`` says otherwise, and a frame taught on the robot has a ``taught:``
    entry (``{rule, joints: [[…], …], tool}``, the joints in the file's angle unit). A file named
    ``$config.dat`` is read as KUKA's (:mod:`kincal.io.krl_config`), its bases turned into the robot's base
    frame with the ``$ROBROOT_C`` of the ``$machine.dat`` beside it.

    Parameters
    ----------
    path : str
        The frames file.

    Returns
    -------
    Mapping of str to ndarray, TaughtFrame or str
        Each frame by name: its pose (4, 4), m; a taught frame's :class:`TaughtFrame`; or (a ``$config.dat``'s
        base without ``$ROBROOT_C``) a str: why it is not known.

    Raises
    ------
    ValueError
        When the file cannot be read or is not such a mapping, a unit is unknown, or an entry is not a frame
        (naming the file and the frame): unknown keys, values that are not numbers, a ``taught:`` entry with an
        unknown rule, too few teach poses, a base without the tool it was taught with (or one the file does not
        give), a taught tool without its x, y, z.
    MeasurementError
        When a ``$config.dat`` or its ``$machine.dat`` cannot be read, or a frame in it lacks a component.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from kincal.io import frame_numbers, read_frames
    >>> text = "\\n".join([
    ...     "units: {length: mm, angle: deg}",
    ...     "table: {x: 800, y: -200, z: 50, rz: 90}",
    ...     "gripper: {z: 150, rx: 30}",
    ...     "plate:",
    ...     "  x: 600",
    ...     "  taught:",
    ...     "    rule: origin-x-xy",
    ...     "    tool: gripper",
    ...     "    joints: [[0, -90, 90, 0, 45, 0], [10, -90, 90, 0, 45, 0], [0, -80, 90, 0, 45, 0]]"])
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "frames.yaml")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     frames = read_frames(path)
    >>> list(frames)
    ['table', 'gripper', 'plate']
    >>> frames["table"][:3, 3].tolist()
    [0.8, -0.2, 0.05]
    >>> [round(v, 9) for v in frame_numbers(frames["gripper"])]
    [0.0, 0.0, 150.0, 0.0, 0.0, 30.0]
    >>> plate = frames["plate"]
    >>> plate.rule, plate.tool, np.round(np.degrees(plate.joints[1]), 9).tolist(), plate.declared[:3, 3].tolist()
    ('origin-x-xy', 'gripper', [10.0, -90.0, 90.0, 0.0, 45.0, 0.0], [0.6, 0.0, 0.0])
    """
    import yaml

    if os.path.basename(str(path)).lower() == "$config.dat":
        from .krl_config import config_frames, robroot, sibling

        machine = sibling(str(path), "$machine.dat")
        return config_frames(str(path), None if machine is None else robroot(machine))
    from ..units import unit_factor

    try:
        data = yaml.safe_load(open(path, encoding="utf-8").read())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read the frames file ({exc})") from None
    units = data.pop("units", {}) if isinstance(data, dict) else {}
    if not isinstance(data, dict) or not isinstance(units, dict):
        raise ValueError(f"{path}: a frames file maps each frame's name to {{x, y, z, rx, ry, rz}} (mm, deg)")
    lf = unit_factor(str(units.get("length", "mm")), "length", f"{path}: ")
    af = unit_factor(str(units.get("angle", "deg")), "angle", f"{path}: ")
    out: dict[str, np.ndarray | str | TaughtFrame] = {}
    for name, f in data.items():
        out[str(name)] = _entry(path, str(name), f, lf, af)
    if "length" not in units:
        _not_metres(str(path), out)
    for name, f in out.items():
        if isinstance(f, TaughtFrame) and f.kind == "base" and f.tool not in out:
            raise ValueError(f"{path}: frame {name!r} was taught with tool {f.tool!r}, which the file does not give")
    if str(units.get("angle", "deg")) == "deg":
        _not_radians(str(path), out)
    return out


METRES_LOOK = 2e-3  # m: a frame whose translation, read as mm, is within this (and not 0) was written in metres


def _not_metres(path: str, frames: dict) -> None:
    """Refuse, in a file read in the default mm, each frame whose translation is within METRES_LOOK of its origin and
    not 0, judged on its own: no tool's TCP and no base lies that close unless it is the origin itself, so it was
    written in metres (a 150 mm tool as z: 0.15), whether the file's other frames are in mm or all in metres. A
    frame really this small is taken once the file says 'units: {length: mm}'."""
    sizes = {n: float(np.linalg.norm(f[:3, 3])) for n, f in frames.items() if isinstance(f, np.ndarray)}
    small = [n for n, d in sizes.items() if 0.0 < d <= METRES_LOOK]
    large = [n for n, d in sizes.items() if d > METRES_LOOK]
    if not small:
        return
    if not large:
        raise ValueError(f"{path}: every frame's translation is within {max(sizes.values()) * 1e3:.3g} mm as read in "
                         f"mm (the default): they look like metres; say so with 'units: {{length: m}}' (or, if they "
                         f"really are this small, 'units: {{length: mm}}')")
    shown = "; ".join(f"{n!r} {{{_xyz(frames[n][:3, 3] * 1e3)}}}, {sizes[n] * 1e3:.3g} mm from its origin, in metres "
                      f"{{{_xyz(frames[n][:3, 3] * 1e6)}}} mm" for n in small[:3])
    raise ValueError(f"{path}: {len(small)} frame(s) read in mm (the default) lie within {METRES_LOOK * 1e3:g} mm of "
                     f"their origin, where no tool's TCP or base does unless it is the origin itself, beside "
                     f"{large[0]!r} {sizes[large[0]] * 1e3:.4g} mm out: {shown}: written in metres? Write them in mm "
                     f"(or, if they really are this small, give the file 'units: {{length: mm}}')")


def _not_radians(path: str, frames: dict) -> None:
    """Refuse a taught frame whose teach poses, in a file whose angles are degrees, look like radians
    (:func:`kincal.models.unit_checks.radians_as_degrees`, the readers' check): taken as degrees they barely move the
    robot, and the frame they give is wrong by as much as the robot then is."""
    from ..models.unit_checks import radians_as_degrees

    for name, f in frames.items():
        if isinstance(f, TaughtFrame) and radians_as_degrees(np.degrees(f.joints)):
            raise ValueError(f"{path}: frame {name!r}: the joints of its {len(f.joints)} teach poses all lie within "
                             f"±{2 * np.pi:.2f} as written (largest {np.degrees(np.abs(f.joints)).max():.4g}), read in "
                             f"degrees (the file's angle unit): they look like radians; write them in degrees as the "
                             f"controller shows them (or, if every angle of the file is in radians, give it 'units: "
                             f"{{angle: rad}}')")


def _xyz(v: np.ndarray) -> str:
    """x, y, z as a frames file writes them: 'x: 20, y: 10, z: 120'."""
    return ", ".join(f"{k}: {float(x):.6g}" for k, x in zip("xyz", v))


def _entry(path: str, name: str, f, lf: float, af: float) -> np.ndarray | TaughtFrame:
    """One frame of the file: its 4x4 pose, or its TaughtFrame."""
    from ..models.transforms import rot_zyx

    if not isinstance(f, dict) or set(f) - set(KEYS) - {"taught"} or not all(_number(f.get(k, 0.0)) for k in KEYS):
        raise ValueError(f"{path}: frame {name!r} must be {{x, y, z, rx, ry, rz}} with numbers (missing ones 0), "
                         f"and 'taught:' for a frame taught on the robot")
    v = [float(f.get(k, 0.0)) for k in KEYS]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rot_zyx(v[5] * af, v[4] * af, v[3] * af), np.array(v[:3]) * lf
    if "taught" not in f:
        return T
    taught = f["taught"]
    if isinstance(taught, dict) and taught.get("rule") == "fixed-point" and not set(f) & set(KEYS):
        raise ValueError(f"{path}: frame {name!r}: a taught tool needs its x, y, z as the controller shows them (its "
                         f"fit of the teach poses is the controller's own); 'taught:' then corrects it")
    return _taught(path, name, taught, af, T if set(f) & set(KEYS) else None)


def _taught(path: str, name: str, t, af: float, declared: np.ndarray | None) -> TaughtFrame:
    """A frame's 'taught:' entry: {rule, joints: [[…], …], tool (a base's)}."""
    where = f"{path}: frame {name!r}: taught"
    if not isinstance(t, dict) or set(t) - {"rule", "joints", "tool"} or t.get("rule") not in RULES:
        raise ValueError(f"{where} needs {{rule: {' | '.join(RULES)}, joints: [[…], …], tool: NAME (a base's)}}")
    kind, least = RULES[t["rule"]]
    joints = t.get("joints")
    if not (isinstance(joints, list) and joints and all(isinstance(j, list) and j and all(map(_number, j))
                                                         and len(j) == len(joints[0]) for j in joints)):
        raise ValueError(f"{where}: joints must be a list of teach poses, each a list of joint values")
    if len(joints) < least or (kind == "base" and len(joints) != 3):
        raise ValueError(f"{where}: the {t['rule']} rule takes {'3' if kind == 'base' else 'at least 4'} teach poses, "
                         f"not {len(joints)}")
    if (kind == "base") != ("tool" in t):
        raise ValueError(f"{where}: " + ("a base names the tool it was taught with (tool: NAME)" if kind == "base"
                                         else "a tool is taught with the flange: no tool"))
    return TaughtFrame(name, t["rule"], np.array(joints, dtype=float) * af, str(t.get("tool", "")), declared)


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))
