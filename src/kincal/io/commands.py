"""Joint commands out (CSV): what compensation writes for the robot, with the row, target and changes."""
from __future__ import annotations

import csv
import io as _io
import os
from typing import Sequence

import numpy as np

from .._atomic import write_text_atomic
from ..models.robot import Robot
from .measurements import _joint_columns, _joint_scale, _unit
def write_commands(
    path: str | os.PathLike,
    robot: Robot,
    rows: np.ndarray,
    targets: np.ndarray,
    q: np.ndarray,
    q_start: np.ndarray | None = None,
    orientation_change: np.ndarray | None = None,
    joint_cols: Sequence[str] | None = None,
    length_unit: str = "m",
    angle_unit: str = "rad",
) -> None:
    """Joint commands (atomically): the input row, the commanded joints (``joint_cols``, in the given
    units), the target (x, y, z), and with the nominal joints ``q_start`` the change of every joint
    (``d_<joint>``) and the predicted change of the tool orientation (mrad)."""
    cols = _joint_columns(str(path), robot, joint_cols)
    scale = 1.0 / _joint_scale(robot.joint_types, length_unit, angle_unit, str(path))
    lf = 1.0 / _unit(length_unit, "length", str(path))
    header = ["row", *cols, "x", "y", "z"]
    if q_start is not None:
        header += [f"d_{c}" for c in cols]
    if orientation_change is not None:
        header.append("orientation_change_mrad")
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for k in range(len(q)):
        cells = [int(rows[k]), *(q[k] * scale), *(targets[k] * lf)]
        cells += [] if q_start is None else list((q[k] - q_start[k]) * scale)
        cells += [] if orientation_change is None else [orientation_change[k] * 1e3]
        w.writerow([cells[0], *(repr(float(v)) for v in cells[1:])])
    write_text_atomic(path, buf.getvalue())


def write_filtered(path: str | os.PathLike, robot: Robot, rows: np.ndarray, xyz: np.ndarray, rot_cols: Sequence[str],
                   rot_values: np.ndarray, q: np.ndarray, joint_cols: Sequence[str] | None = None,
                   length_unit: str = "m", angle_unit: str = "rad") -> None:
    """Filtered poses (atomically): the input row, the pose to send the controller (x, y, z in the
    length unit and the orientation columns as given, e.g. a quaternion) and the joints its inverse
    kinematics will produce (``joint_cols``)."""
    cols = _joint_columns(str(path), robot, joint_cols)
    scale = 1.0 / _joint_scale(robot.joint_types, length_unit, angle_unit, str(path))
    lf = 1.0 / _unit(length_unit, "length", str(path))
    table = np.column_stack([xyz * lf, rot_values, q * scale])
    lines = [",".join(["row", "x", "y", "z", *rot_cols, *cols])]
    lines += [",".join([str(int(r)), *(repr(float(v)) for v in row)]) for r, row in zip(rows, table)]
    write_text_atomic(path, "\n".join(lines) + "\n")
