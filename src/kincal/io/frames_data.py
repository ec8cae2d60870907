"""Frames as a controller's own program data: a base and a tool written for KUKA KRL (a ``.dat`` of two FRAMEs),
ABB RAPID (a module with a ``wobjdata`` and a ``tooldata``) and URScript (a base pose and ``set_tcp``).

Each text is read back by the language's own reader before it is written (:func:`write_frames_data`): the
frames it gives must equal those meant to 1e-9 m and 1e-9 rad, else nothing is written. Lengths are written
to 1e-6 mm (URScript 1e-10 m), KRL angles to 1e-8 deg, RAPID quaternions to 1e-12.

What each gives: ``base`` is the frame targets are written in (the calibration's measurement frame), in the
robot's base frame: KRL's ``$BASE``/``BASE_DATA[n]`` with ``$ROBROOT_C = $NULLFRAME``, RAPID's work object
(its user frame in the world, which is the robot's base when the robot's base frame in MOC.cfg is the
identity), URScript's ``pose_trans(kincal_base, target)``; ``tool`` is the TCP frame in the flange. FANUC
and Yaskawa frames are entered on the pendant (no program data sets a frame from literals there).
"""
from __future__ import annotations

import os
import re

import numpy as np

from .._atomic import write_text_atomic
from ..models.transforms import rotation_log, rotvec_matrix, rotvec_quaternion, zyx_from_matrix

FRAMES_FORMATS = ("frames-krl", "frames-rapid", "frames-urscript")
CHECK_TOL = 1e-9  # m and rad
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,23}$")  # a KRL module's or a RAPID module's name


def frame_numbers(T: np.ndarray) -> tuple[float, ...]:
    """The six numbers a KUKA frame is written with.

    Parameters
    ----------
    T : ndarray, shape (4, 4)
        The frame (its position in m).

    Returns
    -------
    tuple of float
        x, y, z (mm) and A, B, C (deg, R = Rz(A)·Ry(B)·Rx(C)).

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.io import frame_numbers
    >>> from kincal.models.transforms import rot_zyx
    >>> T = np.eye(4)
    >>> T[:3, :3], T[:3, 3] = rot_zyx(*np.radians([90.0, 30.0, 10.0])), [0.8, -0.2, 0.05]
    >>> [round(v, 9) for v in frame_numbers(T)]
    [800.0, -200.0, 50.0, 90.0, 30.0, 10.0]
    """
    rz, ry, rx = np.degrees(zyx_from_matrix(T[:3, :3]))
    return (*(float(v) for v in T[:3, 3] * 1e3), float(rz), float(ry), float(rx))


def _krl(T: np.ndarray) -> str:
    rz, ry, rx = np.degrees(zyx_from_matrix(T[:3, :3]))
    x, y, z = T[:3, 3] * 1e3
    return f"{{X {x:.6f},Y {y:.6f},Z {z:.6f},A {rz:.8f},B {ry:.8f},C {rx:.8f}}}"


def _rapid(T: np.ndarray) -> str:
    q = rotvec_quaternion(rotation_log(T[None, :3, :3])[0])
    return "[[" + ",".join(f"{v:.6f}" for v in T[:3, 3] * 1e3) + "],[" + ",".join(f"{v:.12f}" for v in q) + "]]"


def _ur(T: np.ndarray) -> str:
    return "p[" + ", ".join(f"{v:.10f}" for v in np.concatenate([T[:3, 3], rotation_log(T[None, :3, :3])[0]])) + "]"


def frames_text(fmt: str, name: str, base: np.ndarray, tool: np.ndarray, note: list[str],
                load: tuple[float, ...] | None = None) -> str:
    """The program data of ``fmt`` (:data:`FRAMES_FORMATS`) named ``name`` holding ``base`` and ``tool`` (4x4, m),
    with ``note`` as comment lines; RAPID's tooldata takes the tool's ``load`` (mass kg, centre of gravity x, y,
    z mm in the tool frame)."""
    if fmt == "frames-krl":
        lines = ["&ACCESS RVP", f"DEFDAT  {name.upper()} PUBLIC", *(f"; {n}" for n in note),
                 f"DECL GLOBAL FRAME KINCAL_BASE={_krl(base)}", f"DECL GLOBAL FRAME KINCAL_TOOL={_krl(tool)}",
                 "ENDDAT", ""]
        return "\r\n".join(lines)
    check_frames_output(name, fmt, load)
    if fmt == "frames-rapid" and load is not None:
        mass, *cog = load
        return "\r\n".join([f"MODULE {name}", *(f"  ! {n}" for n in note),
                            f'  PERS wobjdata kincal_wobj := [FALSE,TRUE,"",{_rapid(base)},[[0,0,0],[1,0,0,0]]];',
                            f"  PERS tooldata kincal_tool := [TRUE,{_rapid(tool)},[{mass:.6g},["
                            + ",".join(f"{c:.6g}" for c in cog) + "],[1,0,0,0],0,0,0]];", "ENDMODULE", ""])
    if fmt == "frames-urscript":
        return "\n".join([*(f"# {n}" for n in note), f"kincal_base = {_ur(base)}", f"set_tcp({_ur(tool)})", ""])
    raise AssertionError(fmt)  # check_frames_output refused it


def read_frames_text(fmt: str, source: str, text: str) -> tuple[np.ndarray, np.ndarray]:
    """The base and tool (4x4, m) that the language's reader finds in frames data written by :func:`frames_text`."""
    if fmt == "frames-krl":
        from .krl_config import frames_in

        found = {m.group(1).upper(): T for m, T in frames_in(source, text, KRL_FRAME)}
        return found["KINCAL_BASE"], found["KINCAL_TOOL"]
    if fmt == "frames-rapid":
        from .program_rapid import frame_poses, parse

        poses = frame_poses(parse(source, text))
        return poses["kincal_wobj"], poses["kincal_tool"]
    from .program_ur import COMMENT_OR_STRING, POSE, _bound_literals, parse as parse_ur

    code = COMMENT_OR_STRING.sub(lambda m: " " * len(m.group()), text)
    a, b = _bound_literals(code, text)["kincal_base"]
    base = POSE.match(text[a:b])
    tool = parse_ur(source, text).tcps[-1][1]
    if base is None or tool is None:
        raise ValueError(f"{source}: the URScript frames text holds no literal base and TCP")
    return _pose(np.array([float(v) for v in base.group(1).split(",")])), _pose(tool)


KRL_FRAME = re.compile(r"^[ \t]*DECL[ \t]+GLOBAL[ \t]+FRAME[ \t]+(\w+)[ \t]*=[ \t]*\{", re.M | re.I)


def _pose(v: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotvec_matrix(v[3:6]), v[:3]
    return T


def check_frames_output(path: str, fmt: str, load: tuple[float, ...] | None = None) -> None:
    """Refuse, before any work, frames data that cannot be written.

    Parameters
    ----------
    path : str
        The file to write (a KRL or RAPID module is named after it).
    fmt : str
        The format, one of :data:`FRAMES_FORMATS`.
    load : tuple of float, optional
        The tool's load: mass (kg) and centre of gravity x, y, z (mm, in the tool frame); a RAPID tooldata
        needs it (default None).

    Raises
    ------
    ValueError
        For an unknown format, a KRL or RAPID file whose name cannot name its module (letters, digits and _, at
        most 24, not starting with a digit), a RAPID tooldata without the tool's load.

    Examples
    --------
    >>> from kincal.io import check_frames_output
    >>> check_frames_output("out/kincal_frames.dat", "frames-krl")  # nothing to say
    >>> check_frames_output("out/2nd-cell.dat", "frames-krl")
    Traceback (most recent call last):
    ...
    ValueError: out/2nd-cell.dat: a KRL module is named after its file: letters, digits and _ (at most 24, not
    starting with a digit)
    >>> check_frames_output("out/KincalFrames.mod", "frames-rapid", load=(1.5, 0.0, 0.0, 80.0))
    """
    if fmt not in FRAMES_FORMATS:
        raise ValueError(f"frames format '{fmt}': kincal writes {', '.join(FRAMES_FORMATS)}")
    name = os.path.splitext(os.path.basename(str(path)))[0]
    if fmt != "frames-urscript" and not NAME.match(name):
        raise ValueError(f"{path}: a {fmt[7:].upper()} module is named after its file: letters, digits and _ (at most "
                         f"24, not starting with a digit)")
    if fmt == "frames-rapid" and load is None:
        raise ValueError("a RAPID tooldata carries the tool's load: give --tool-load MASS,X,Y,Z (kg; centre of "
                         "gravity in mm in the tool frame) as your tool has it; kincal does not guess it")


def write_frames_data(path: str, fmt: str, base: np.ndarray, tool: np.ndarray, note: list[str],
                      load: tuple[float, ...] | None = None) -> None:
    """Write a base and a tool frame as a controller's own program data.

    The text (a KRL ``.dat`` of two FRAMEs, a RAPID module with a ``wobjdata`` and a ``tooldata``, or URScript:
    a base pose and ``set_tcp``; the module named after the file) is read back by the language's own reader
    first: it is written (atomically) only when it gives ``base`` and ``tool`` to ``CHECK_TOL`` (1e-9 m and
    1e-9 rad).

    Parameters
    ----------
    path : str
        The file to write.
    fmt : str
        The format, one of :data:`FRAMES_FORMATS`: "frames-krl", "frames-rapid" or "frames-urscript".
    base : ndarray, shape (4, 4)
        The frame targets are written in, in the robot's base frame, m.
    tool : ndarray, shape (4, 4)
        The TCP frame in the flange, m.
    note : list of str
        Comment lines written at the top.
    load : tuple of float, optional
        The tool's load for RAPID's tooldata: mass (kg) and centre of gravity x, y, z (mm, in the tool frame)
        (default None; RAPID needs it).

    Raises
    ------
    ValueError
        When :func:`check_frames_output` refuses the output, or the text read back is off (nothing written).

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from kincal.io import write_frames_data
    >>> from kincal.models.transforms import rot_zyx
    >>> base, tool = np.eye(4), np.eye(4)
    >>> base[:3, :3], base[:3, 3] = rot_zyx(*np.radians([90.0, 30.0, 10.0])), [0.8, -0.2, 0.05]
    >>> tool[:3, :3], tool[:3, 3] = rot_zyx(0.0, 0.0, np.radians(30.0)), [0.0, 0.0, 0.15]
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "kincal_frames.dat")
    ...     write_frames_data(path, "frames-krl", base, tool, ["calibrated frames"])
    ...     with open(path, newline="") as f:
    ...         print(f.read().replace("\\r\\n", "\\n"), end="")
    &ACCESS RVP
    DEFDAT  KINCAL_FRAMES PUBLIC
    ; calibrated frames
    DECL GLOBAL FRAME KINCAL_BASE={X 800.000000,Y -200.000000,Z 50.000000,A 90.00000000,B 30.00000000,C 10.00000000}
    DECL GLOBAL FRAME KINCAL_TOOL={X 0.000000,Y 0.000000,Z 150.000000,A 0.00000000,B 0.00000000,C 30.00000000}
    ENDDAT
    """
    name = os.path.splitext(os.path.basename(str(path)))[0]
    check_frames_output(path, fmt, load)
    text = frames_text(fmt, name, base, tool, note, load)
    for meant, got in zip((base, tool), read_frames_text(fmt, str(path), text)):
        miss = np.linalg.norm(got[:3, 3] - meant[:3, 3])
        turn = np.linalg.norm(rotation_log((got[:3, :3] @ meant[:3, :3].T)[None])[0])
        if not (miss <= CHECK_TOL and turn <= CHECK_TOL):
            raise ValueError(f"{path}: the {fmt} text read back is off by {miss * 1e3:.2e} mm / {turn:.2e} rad: "
                             "not written")
    write_text_atomic(path, text, "utf-8")
