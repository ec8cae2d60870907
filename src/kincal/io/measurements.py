"""Measurement sets: joint values and measured tool positions; CSV read/write with units at the edge."""
from __future__ import annotations

import csv
import io as _io
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .._atomic import write_text_atomic
from ..errors import MeasurementError
from ..models.robot import Robot
from ..models.yaml_io import unit_factor

MAX_LISTED = 10  # rows named in an error message


@dataclass(frozen=True, eq=False)
class Measurements:
    """N measured poses: joint values q (N, n) in rad/m and positions xyz (N, 3) in m.

    ``rows`` are the 1-based line numbers in ``source`` (header = line 1) so errors can name them.
    """

    q: np.ndarray
    xyz: np.ndarray
    joint_names: tuple[str, ...]
    source: str = "<memory>"
    rows: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        q = np.array(self.q, dtype=float)
        xyz = np.array(self.xyz, dtype=float)
        if q.ndim != 2 or xyz.ndim != 2 or xyz.shape[1] != 3 or q.shape[0] != xyz.shape[0]:
            raise MeasurementError(
                f"{self.source}: q must be (N, n) and xyz (N, 3) with the same N; got {q.shape} and {xyz.shape}"
            )
        if q.shape[1] != len(self.joint_names):
            raise MeasurementError(f"{self.source}: {q.shape[1]} joint columns but {len(self.joint_names)} names")
        rows = np.arange(2, q.shape[0] + 2) if self.rows is None else np.asarray(self.rows, dtype=int)
        bad = ~(np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(xyz), axis=1))
        if bad.any():
            listed = ", ".join(str(r) for r in rows[bad][:MAX_LISTED])
            more = f" and {bad.sum() - MAX_LISTED} more" if bad.sum() > MAX_LISTED else ""
            raise MeasurementError(
                f"{self.source}: NaN or infinite values in row(s) {listed}{more}; remove or fix those rows"
            )
        for a in (q, xyz, rows):
            a.setflags(write=False)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))

    def __len__(self) -> int:
        return self.q.shape[0]

    def subset(self, index: np.ndarray | Sequence[int]) -> "Measurements":
        """The measurements at the given positions (indices or boolean mask)."""
        idx = np.asarray(index)
        return Measurements(self.q[idx], self.xyz[idx], self.joint_names, self.source, self.rows[idx])

    def check_robot(self, robot: Robot, length_unit: str | None = None, angle_unit: str | None = None) -> None:
        """Raise MeasurementError if the data cannot belong to ``robot`` or its units look wrong."""
        if self.q.shape[1] != robot.n_joints:
            raise MeasurementError(
                f"{self.source}: {self.q.shape[1]} joint columns but robot '{robot.name}' has {robot.n_joints} "
                f"joints ({', '.join(robot.joint_names)}); pass the right joint columns"
            )
        rev = np.array([t == "revolute" for t in robot.joint_types])
        if rev.any():
            qmax = float(np.max(np.abs(self.q[:, rev])))
            if qmax > 4 * np.pi:
                given = f" ('{angle_unit}' was given)" if angle_unit else ""
                raise MeasurementError(
                    f"{self.source}: revolute joint values reach {qmax:.4g} rad{given}, more than two turns: "
                    f"they look like degrees; use angle unit 'deg' (CLI: --angle-unit deg)"
                )
        if len(self) >= 3:
            pred = robot.forward(self.q)
            spread_m = _spread(self.xyz)
            spread_p = _spread(pred)
            if spread_p > 0 and spread_m > 0:
                ratio = spread_m / spread_p
                unit = f" with length unit '{length_unit}'" if length_unit else ""
                if ratio > 30:
                    raise MeasurementError(
                        f"{self.source}: measured positions spread {ratio:.0f}x more than the robot can move{unit}; "
                        f"they look like mm read as m: use length unit 'mm' (CLI: --length-unit mm)"
                    )
                if ratio < 1 / 30:
                    raise MeasurementError(
                        f"{self.source}: measured positions spread {1 / ratio:.0f}x less than the robot moves{unit}; "
                        f"they look like m read as mm: use length unit 'm' (CLI: --length-unit m)"
                    )


def _spread(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((x - x.mean(axis=0)) ** 2, axis=1))))


def _sniff_delimiter(header: str, path: str) -> str:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    if counts[best] == 0:
        raise MeasurementError(f"{path}: cannot find a ',', ';' or tab separator in the header line")
    return best


def read_measurements(
    path: str | os.PathLike,
    robot: Robot,
    joint_cols: Sequence[str] | None = None,
    xyz_cols: Sequence[str] = ("x", "y", "z"),
    length_unit: str = "m",
    angle_unit: str = "rad",
) -> Measurements:
    """Read a CSV (header line; comma, semicolon or tab separated) of joint values and positions.

    joint_cols default to the robot's joint names. Revolute joints are in ``angle_unit``, prismatic
    joints and positions in ``length_unit``. Values are returned in SI units.
    """
    path = str(path)
    lf = _unit(length_unit, "length", path)
    af = _unit(angle_unit, "angle", path)
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the file ({exc.strerror})") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise MeasurementError(f"{path}: the file is empty; expected a header line and one row per pose")
    delim = _sniff_delimiter(lines[0], path)
    reader = csv.reader(_io.StringIO(text), delimiter=delim)
    header = [h.strip() for h in next(reader)]
    joint_cols = list(joint_cols) if joint_cols is not None else list(robot.joint_names)
    if len(joint_cols) != robot.n_joints:
        raise MeasurementError(
            f"{path}: {len(joint_cols)} joint columns given ({', '.join(joint_cols)}) but robot '{robot.name}' "
            f"has {robot.n_joints} joints; give one column per joint"
        )
    if len(xyz_cols) != 3:
        raise MeasurementError(f"{path}: give exactly three position columns, got {list(xyz_cols)}")
    missing = [c for c in list(joint_cols) + list(xyz_cols) if c not in header]
    if missing:
        raise MeasurementError(
            f"{path}: column(s) {', '.join(missing)} not found; the header has: {', '.join(header)}"
        )
    jidx = [header.index(c) for c in joint_cols]
    pidx = [header.index(c) for c in xyz_cols]
    q_rows, p_rows, line_no = [], [], []
    for k, rec in enumerate(reader, start=2):
        if not rec or all(not c.strip() for c in rec):
            continue
        if len(rec) < len(header):
            raise MeasurementError(f"{path}: row {k} has {len(rec)} fields, the header has {len(header)}")
        try:
            q_rows.append([float(rec[i]) for i in jidx])
            p_rows.append([float(rec[i]) for i in pidx])
        except ValueError:
            col = next(header[i] for i in jidx + pidx if not _is_float(rec[i]))
            raise MeasurementError(
                f"{path}: row {k}, column '{col}': '{rec[header.index(col)]}' is not a number"
            ) from None
        line_no.append(k)
    if not q_rows:
        raise MeasurementError(f"{path}: no data rows after the header")
    q = np.array(q_rows)
    scale = np.array([af if t == "revolute" else lf for t in robot.joint_types])
    meas = Measurements(q * scale, np.array(p_rows) * lf, robot.joint_names, path, np.array(line_no))
    meas.check_robot(robot, length_unit, angle_unit)
    return meas


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _unit(unit: str, kind: str, path: str) -> float:
    try:
        return unit_factor(unit, kind)
    except Exception as exc:  # ModelError from the shared unit table
        raise MeasurementError(f"{path}: {exc}") from None


def write_measurements(
    path: str | os.PathLike,
    meas: Measurements,
    joint_types: Sequence[str] | None = None,
    length_unit: str = "m",
    angle_unit: str = "rad",
    joint_cols: Sequence[str] | None = None,
) -> None:
    """Write measurements as a comma-separated CSV (atomically) in the given units."""
    lf = 1.0 / _unit(length_unit, "length", str(path))
    af = 1.0 / _unit(angle_unit, "angle", str(path))
    types = list(joint_types) if joint_types is not None else ["revolute"] * meas.q.shape[1]
    scale = np.array([af if t == "revolute" else lf for t in types])
    cols = list(joint_cols) if joint_cols is not None else list(meas.joint_names)
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols + ["x", "y", "z"])
    for qi, pi in zip(meas.q * scale, meas.xyz * lf):
        w.writerow([repr(float(v)) for v in qi] + [repr(float(v)) for v in pi])
    write_text_atomic(path, buf.getvalue())
