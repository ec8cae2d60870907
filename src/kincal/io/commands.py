"""Joint commands out (CSV): what compensation writes for the robot, with the row, target and changes.

Numbers are written with 10 decimals (1e-10 rad, deg, m or mm in the file's units): far below any
controller's resolution, and formatted a whole block at a time, so a million rows take about a second.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._numtext import fixed_lines

DECIMALS = 10


@dataclass(frozen=True)
class CommandColumns:
    """The layout of a commands file. ``kind`` "joints": row, the joints (``joint_cols``), the target
    x, y, z, with ``changes`` the change of every joint from the nominal command (``d_<joint>``) and
    with ``orientation_change`` the predicted change of the tool orientation (mrad); "cartesian":
    row, the pose to send (x, y, z and ``rot_cols``) and the joints it gives. Values are SI inside;
    ``joint_scale`` and ``length_scale`` turn them into the file's units."""

    kind: str
    joint_cols: tuple[str, ...]
    joint_scale: np.ndarray
    length_scale: float
    changes: bool = False
    orientation_change: bool = False
    rot_cols: tuple[str, ...] = ()

    def header(self) -> str:
        j = list(self.joint_cols)
        if self.kind == "cartesian":
            return ",".join(["row", "x", "y", "z", *self.rot_cols, *j]) + "\n"
        return ",".join(["row", *j, "x", "y", "z", *(f"d_{c}" for c in j if self.changes),
                         *(["orientation_change_mrad"] if self.orientation_change else [])]) + "\n"

    def text(self, rows: np.ndarray, q: np.ndarray, xyz: np.ndarray, q_start: np.ndarray | None = None,
             orientation_change: np.ndarray | None = None, rot_values: np.ndarray | None = None) -> str:
        """The lines of ``rows`` (N,): commands q (N, n), targets or poses to send xyz (N, 3) m, the
        nominal commands, orientation changes (N,) rad or the orientation columns (N, k), as the layout says."""
        rows = np.asarray(rows)
        if self.kind == "cartesian":
            parts: list = [xyz * self.length_scale, rot_values, q * self.joint_scale]
        else:
            parts = [q * self.joint_scale, xyz * self.length_scale]
            if self.changes:
                parts.append((q - _given(q_start, "q_start")) * self.joint_scale)
            if self.orientation_change:
                parts.append(_given(orientation_change, "orientation_change")[:, None] * 1e3)
        table = np.column_stack(parts)
        text = fixed_lines(rows, table, DECIMALS)
        if text is None:  # a value beyond ~1e5 in the file's unit: printf, slower
            line = ",".join(["%d"] + [f"%.{DECIMALS}f"] * table.shape[1]) + "\n"
            text = (line * len(table)) % tuple(np.column_stack([rows, table]).ravel().tolist())
        return text


def _given(values: np.ndarray | None, what: str) -> np.ndarray:
    if values is None:
        raise ValueError(f"this commands layout has a column for {what}: give it")
    return values
