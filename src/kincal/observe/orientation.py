"""Orientation columns as measuring systems write them, always with the convention named.

Conventions (``--orientation``):

* ``quat-wxyz`` (columns qw, qx, qy, qz) and ``quat-xyzw`` (qx, qy, qz, qw): unit quaternions;
* ``matrix`` (r11, r12, r13, r21, …, r33): the rotation matrix, row by row;
* ``rotvec`` (rx, ry, rz): a rotation vector in rad (the UR controller's pose); ``rotvec-deg`` the same in deg;
* ``euler-<axes>-<intrinsic|extrinsic>-<deg|rad>`` (e1, e2, e3), e.g. ``euler-zyx-intrinsic-deg`` (KUKA's A, B, C)
  or ``euler-xyz-extrinsic-deg`` (Fanuc's W, P, R): three angles about the named axes, in that order, about the
  moving (intrinsic) or the fixed (extrinsic) axes.

Nothing is guessed: :func:`convention_check` compares the declared reading with the common others on the nominal
robot and, when another one fits markedly better, names it.
"""
from __future__ import annotations

import re

import numpy as np

from ..errors import MeasurementError
from ..ties import first_best
from ..units import ANGLE_UNITS, MRAD

EULER = re.compile(r"^euler-([xyz]{3})-(intrinsic|extrinsic)-(deg|rad)$")
FIXED = {"quat-wxyz": ("qw", "qx", "qy", "qz"), "quat-xyzw": ("qx", "qy", "qz", "qw"),
         "matrix": tuple(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)),
         "rotvec": ("rx", "ry", "rz"), "rotvec-deg": ("rx", "ry", "rz")}
UNIT_NORM = 1e-3  # a quaternion farther from norm 1, or a matrix farther from orthonormal, is not one
MARKEDLY = 5.0  # another convention fits markedly better: this many times smaller rotation error
PLAUSIBLE = 50e-3  # rad: a declared reading that leaves less than this RMS against the nominal robot is kept
ON_A_LINE = 1e-3  # positions whose second principal spread is below this share of the first do not fix a frame


def check_convention(name: str) -> str:
    """Check that an orientation convention is one kincal reads.

    Parameters
    ----------
    name : str
        The convention: "quat-wxyz", "quat-xyzw", "matrix", "rotvec", "rotvec-deg" or
        ``euler-<axes>-<intrinsic|extrinsic>-<deg|rad>`` (e.g. "euler-zyx-intrinsic-deg", KUKA's A, B, C).

    Returns
    -------
    str
        ``name``, as it is.

    Raises
    ------
    ValueError
        When kincal does not read it, listing the conventions it reads.

    Examples
    --------
    >>> from kincal.observe import check_convention
    >>> check_convention("euler-xyz-extrinsic-deg")
    'euler-xyz-extrinsic-deg'
    >>> check_convention("euler-zyx-deg")
    Traceback (most recent call last):
    ...
    ValueError: orientation 'euler-zyx-deg': use quat-wxyz, quat-xyzw, matrix, rotvec, rotvec-deg or
    euler-<axes>-<intrinsic|extrinsic>-<deg|rad>, e.g. euler-zyx-intrinsic-deg
    """
    if name in FIXED or EULER.match(name):
        return name
    raise ValueError(f"orientation '{name}': use quat-wxyz, quat-xyzw, matrix, rotvec, rotvec-deg or "
                     f"euler-<axes>-<intrinsic|extrinsic>-<deg|rad>, e.g. euler-zyx-intrinsic-deg")


def default_columns(name: str) -> tuple[str, ...]:
    """The orientation columns a file of a convention has unless they are renamed.

    Parameters
    ----------
    name : str
        The convention (:func:`check_convention`).

    Returns
    -------
    tuple of str
        The columns' names: qw, qx, qy, qz (quat-wxyz); qx, qy, qz, qw (quat-xyzw); r11, r12, …, r33 (matrix,
        row by row); rx, ry, rz (rotvec, rotvec-deg); e1, e2, e3 (Euler angles).

    Raises
    ------
    ValueError
        When kincal does not read the convention.

    Examples
    --------
    >>> from kincal.observe import default_columns
    >>> default_columns("quat-wxyz"), default_columns("euler-zyx-intrinsic-deg")
    (('qw', 'qx', 'qy', 'qz'), ('e1', 'e2', 'e3'))
    """
    return FIXED.get(check_convention(name), ("e1", "e2", "e3"))


def to_matrices(values: np.ndarray, name: str, source: str, rows: np.ndarray) -> np.ndarray:
    """Rotation matrices from orientation columns read in a convention.

    Values that are no rotation in that convention are refused, naming the row: a quaternion whose norm is
    off 1 by more than ``UNIT_NORM`` (1e-3; the others are normalised), a matrix farther than that from
    orthonormal or with a negative determinant, Euler angles in rad beyond 2π.

    Parameters
    ----------
    values : ndarray, shape (N, k)
        The orientation columns, k as the convention has (:func:`default_columns`).
    name : str
        The convention (:func:`check_convention`).
    source : str
        Where the values come from (a file's path), named in messages.
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source``, named in messages.

    Returns
    -------
    ndarray, shape (N, 3, 3)
        The rotations (columns: the measured frame's axes).

    Raises
    ------
    MeasurementError
        When a row is no rotation in the convention.

    See Also
    --------
    from_matrices : The inverse.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.observe import to_matrices
    >>> R = to_matrices([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "quat-wxyz", "poses.csv", np.array([2, 3]))
    >>> R[1].tolist()  # half a turn about z
    [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]
    >>> to_matrices([[1.0, 0.0, 0.0, 0.1]], "quat-wxyz", "poses.csv", np.array([7]))
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: poses.csv: row 7: the orientation is not a unit quaternion (norm 1.005;
    quat-wxyz) (1 such row(s)); check the columns and --orientation
    """
    v = np.asarray(values, float)
    if name.startswith("quat"):
        norm = np.linalg.norm(v, axis=1)
        _refuse(source, rows, np.abs(norm - 1.0) > UNIT_NORM, f"is not a unit quaternion (norm {{}}; {name})", norm)
        return _quaternion_matrices((v if name == "quat-xyzw" else v[:, [1, 2, 3, 0]]) / norm[:, None])
    from scipy.spatial.transform import Rotation
    if name == "matrix":
        R = v.reshape(-1, 3, 3)
        dev = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
        det = np.linalg.det(R)
        _refuse(source, rows, (dev > UNIT_NORM) | (det < 0), "is not a rotation matrix (|RRᵀ − I| {})", dev)
        return R
    if name.startswith("rotvec"):
        return Rotation.from_rotvec(v * (ANGLE_UNITS["deg"] if name.endswith("deg") else 1.0)).as_matrix()
    axes, how, unit = _euler(name)
    if unit == "rad":
        big = np.abs(v).max(axis=1)
        _refuse(source, rows, big > 2 * np.pi + 1e-9, "has angles up to {} beyond 2π rad: degrees? (use ...-deg)", big)
    return Rotation.from_euler(axes.upper() if how == "intrinsic" else axes, v, degrees=unit == "deg").as_matrix()


def _euler(name: str) -> tuple[str, str, str]:
    """(axes, intrinsic|extrinsic, deg|rad) of the Euler convention ``name``; a ValueError for a name
    that is no convention (:func:`check_convention`) or a convention other than Euler angles."""
    found = EULER.match(check_convention(name))
    if found is None:
        raise ValueError(f"orientation '{name}' is not a convention of Euler angles")
    return found[1], found[2], found[3]


def _quaternion_matrices(xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of unit quaternions (N, 4), scalar last (the closed form; no
    scipy import on a long file's critical path)."""
    x, y, z, w = xyzw.T
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                     2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                     2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=1).reshape(-1, 3, 3)


def from_matrices(R: np.ndarray, name: str) -> np.ndarray:
    """The orientation columns of rotations in a convention.

    Parameters
    ----------
    R : ndarray, shape (N, 3, 3)
        The rotations.
    name : str
        The convention (:func:`check_convention`).

    Returns
    -------
    ndarray, shape (N, k)
        The orientation columns, in the order of :func:`default_columns` (rotation vectors and Euler angles in
        the convention's unit).

    Raises
    ------
    ValueError
        When kincal does not read the convention.

    See Also
    --------
    to_matrices : The inverse.
    """
    from scipy.spatial.transform import Rotation
    rot = Rotation.from_matrix(R)
    if name.startswith("quat"):
        xyzw = rot.as_quat()
        return xyzw if name == "quat-xyzw" else xyzw[:, [3, 0, 1, 2]]
    if name == "matrix":
        return np.asarray(R, float).reshape(-1, 9)
    if name.startswith("rotvec"):
        return rot.as_rotvec() / (ANGLE_UNITS["deg"] if name.endswith("deg") else 1.0)
    axes, how, unit = _euler(name)
    return rot.as_euler(axes.upper() if how == "intrinsic" else axes, degrees=unit == "deg")


def _refuse(source: str, rows: np.ndarray, bad: np.ndarray, what: str, value: np.ndarray) -> None:
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise MeasurementError(f"{source}: row {rows[k]}: the orientation {what.format(f'{value[k]:.4g}')}"
                               f" ({int(bad.sum())} such row(s)); check the columns and --orientation")


TAIT_BRYAN = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx")  # the axis orders of roll-pitch-yaw angles


def alternatives(name: str) -> list[str]:
    """The common conventions a file declared as ``name`` may really be in, in canonical order: for
    Euler angles every axis order of their family (roll-pitch-yaw, or the declared proper-Euler order
    and its reverse) intrinsic and extrinsic, then the other angle unit."""
    if name in FIXED:  # the other quaternion order or rotation-vector unit; none for a matrix
        return {"quat-wxyz": ["quat-xyzw"], "quat-xyzw": ["quat-wxyz"], "rotvec": ["rotvec-deg"],
                "rotvec-deg": ["rotvec"]}.get(name, [])
    axes, how, unit = _euler(name)
    orders = TAIT_BRYAN if axes in TAIT_BRYAN else (axes, axes[::-1])
    return [f"euler-{a}-{h}-{unit}" for a in orders for h in ("intrinsic", "extrinsic") if (a, h) != (axes, how)] + \
        [f"euler-{axes}-{how}-{'rad' if unit == 'deg' else 'deg'}"]


def orientation_misfit(R_flange: np.ndarray, R_meas: np.ndarray, frame: np.ndarray | None = None,
                       iterations: int = 30) -> float:
    """RMS angle (rad) left when measured rotations are explained as F·R_flange·T with the best
    target rotation T and the best frame rotation F (alternating chordal means), or F = ``frame``
    when the positions fix it (:func:`position_frame`: then a reading that only relabels the axes
    cannot hide in F)."""
    F, T = frame, np.eye(3)
    for _ in range(iterations if frame is None else 1):
        if frame is None:
            F = nearest_rotation(np.sum(R_meas @ (R_flange @ T).transpose(0, 2, 1), axis=0))
        T = nearest_rotation(np.sum((F @ R_flange).transpose(0, 2, 1) @ R_meas, axis=0))
    E = (F @ R_flange @ T).transpose(0, 2, 1) @ R_meas
    ang = np.arccos(np.clip((np.trace(E, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))
    return float(np.sqrt(np.mean(ang**2)))


def position_frame(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray | None:
    """The rotation (3, 3) of the measurement frame that best maps the positions ``predicted`` (N, 3)
    onto ``measured`` (N, 3) (Kabsch), or None when they cannot fix it (fewer than 3, or on a line)."""
    a, b = predicted - predicted.mean(axis=0), measured - measured.mean(axis=0)
    s = np.linalg.svd(a, compute_uv=False) if len(a) >= 3 else np.zeros(2)
    return nearest_rotation(b.T @ a) if s[1] > ON_A_LINE * s[0] else None


def nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) nearest to M (3, 3) in the Frobenius norm (a chordal mean of the matrices summed in M)."""
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def convention_check(R_flange: np.ndarray, values: np.ndarray, name: str, source: str, rows: np.ndarray,
                     frame: np.ndarray | None = None) -> float:
    """The declared reading's misfit (rad) against the nominal robot's flange rotations, in the
    measurement frame ``frame`` the positions give when known (:func:`position_frame`; else fitted);
    refused, naming the convention, when another common one fits ``MARKEDLY`` better and the declared
    one leaves more than a robot's error could (``PLAUSIBLE``). Without the positions' frame, readings
    that differ by a relabelling of the axes (zyx, xzy and yxz extrinsic) fit alike."""
    declared = orientation_misfit(R_flange, to_matrices(values, name, source, rows), frame)
    if declared <= PLAUSIBLE:
        return declared
    tried = []
    for other in alternatives(name):
        try:
            tried.append((other, orientation_misfit(R_flange, to_matrices(values, other, source, rows), frame)))
        except MeasurementError:  # not even a rotation in that convention
            continue
    if tried:
        other, misfit = tried[first_best([m for _, m in tried], maximize=False)]  # ties: the canonical order
        how = "frame and target fitted" if frame is None else "target fitted, frame from the positions"
        if misfit * MARKEDLY < declared:
            raise MeasurementError(
                f"{source}: read as {name}, the orientations differ from the robot file's by {declared * MRAD:.0f} "
                f"mrad RMS ({how}); read as {other} by {misfit * MRAD:.1f} mrad: the file looks like {other}; give "
                f"--orientation {other} (or check the columns)")
    return declared
