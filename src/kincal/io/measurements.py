"""Measurement sets: joint values and measured tool positions; CSV read/write with units at the edge."""
from __future__ import annotations

import csv
import io as _io
import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .._atomic import write_text_atomic
from .._csv import MAX_LISTED, listed  # for messages naming rows
from .._csv import check_finite, open_table
from ..errors import MeasurementError
from ..models.robot import Robot
from ..units import joint_factors, joint_units, unit_factor
from .unit_checks import check_degrees, check_spread


@dataclass(frozen=True, eq=False, init=False)
class Measurements:
    """N measured poses: joint values q (N, n) in rad/m and positions xyz (N, 3) in m.

    ``rows`` are the 1-based line numbers in ``source`` (header = line 1) so errors can name them
    (default: 2, 3, …, as written by ``write_measurements``).
    """

    q: np.ndarray
    xyz: np.ndarray
    joint_names: tuple[str, ...]
    source: str
    rows: np.ndarray
    std: np.ndarray | None  # (N, 3) m: the instrument's σ per sample and axis, if given
    units: tuple[str, str] | None  # (length, angle) units the file was read in, for advice; None: SI
    session: np.ndarray | None  # (N,) str: the session (file) of each pose; None: one session

    def __init__(self, q: ArrayLike, xyz: ArrayLike, joint_names: Sequence[str], source: str = "<memory>",
                 rows: ArrayLike | None = None, std: ArrayLike | None = None, units: tuple[str, str] | None = None,
                 session: ArrayLike | None = None) -> None:
        q, xyz = np.array(q, dtype=float), np.array(xyz, dtype=float)
        if q.ndim != 2 or xyz.ndim != 2 or xyz.shape[1] != 3 or q.shape[0] != xyz.shape[0]:
            raise MeasurementError(f"{source}: q must be (N, n) and xyz (N, 3) with the same N; got {q.shape} and "
                                   f"{xyz.shape}")
        if q.shape[1] != len(joint_names):
            raise MeasurementError(f"{source}: {q.shape[1]} joint columns but {len(joint_names)} names")
        rows = np.arange(2, q.shape[0] + 2) if rows is None else np.asarray(rows, dtype=int)
        check_finite(source, np.column_stack([q, xyz]), rows, [*joint_names, "x", "y", "z"])
        if std is not None:
            std = np.array(std, dtype=float)
            if std.shape != xyz.shape:
                raise MeasurementError(f"{source}: σ must be (N, 3) like the positions, got {std.shape}")
            check_finite(source, std, rows, ["σ x", "σ y", "σ z"], "measurement σ")
            bad = ~np.all(std > 0, axis=1)
            if bad.any():
                raise MeasurementError(f"{source}: measurement σ must be > 0; row(s) "
                                       f"{', '.join(map(str, rows[bad][:MAX_LISTED]))} give 0 or less")
        if session is not None:
            session = np.asarray(session, dtype=str)
            if session.shape != (q.shape[0],):
                raise MeasurementError(f"{source}: one session label per pose expected, got {session.shape}")
        for name, value in (("q", q), ("xyz", xyz), ("joint_names", tuple(joint_names)), ("source", source),
                            ("rows", rows), ("std", std), ("units", units), ("session", session)):
            if isinstance(value, np.ndarray):  # the arrays read-only
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return self.q.shape[0]

    def subset(self, index: np.ndarray | Sequence[int]) -> "Measurements":
        """The measurements at the given positions (indices or boolean mask)."""
        idx = np.asarray(index)
        return Measurements(self.q[idx], self.xyz[idx], self.joint_names, self.source, self.rows[idx],
                            None if self.std is None else self.std[idx], self.units,
                            None if self.session is None else self.session[idx])

    def describe_rows(self, index: np.ndarray | Sequence[int]) -> str:
        """'row(s) 5, 17' for the poses at ``index``; with several sessions each file's rows after its name."""
        idx = np.asarray(index, dtype=int)
        if self.session is None or len(self.sessions()) < 2:
            return f"row(s) {listed(self.rows[idx])}"
        parts = [f"{listed(self.rows[idx[self.session[idx] == name]])} of {name}" for name in self.sessions()
                 if np.any(self.session[idx] == name)]
        return "row(s) " + "; ".join(parts)

    def sessions(self) -> tuple[str, ...]:
        """The session labels in order of first appearance (one session without labels: its source)."""
        if self.session is None:
            return (self.source,)
        return tuple(dict.fromkeys(self.session.tolist()))

    def without_rows(self, rows: Sequence[int]) -> "Measurements":
        """The measurements less the given input rows (file line numbers, header = 1)."""
        rows = [int(r) for r in rows]
        unknown = [r for r in rows if r not in set(self.rows.tolist())]
        if unknown:
            raise MeasurementError(f"{self.source}: row(s) {', '.join(map(str, unknown[:MAX_LISTED]))} to exclude are "
                                   f"not data rows of the file (data rows are {self.rows[0]}..{self.rows[-1]})")
        return self.subset(~np.isin(self.rows, rows))

    def check_robot(self, robot: Robot, length_unit: str | None = None, angle_unit: str | None = None) -> None:
        """Raise MeasurementError if the data cannot belong to ``robot`` or its units look wrong."""
        if self.q.shape[1] != robot.n_joints:
            raise MeasurementError(f"{self.source}: {self.q.shape[1]} joint columns but robot '{robot.name}' has "
                                   f"{robot.n_joints} joints ({', '.join(robot.joint_names)}); pass the right joint "
                                   f"columns")
        outside, why = robot.inputs_outside(self.q)
        if outside.any():
            raise MeasurementError(f"{self.source}: {self.describe_rows(np.flatnonzero(outside))}: {why}")
        check_degrees(self.source, self.q, robot, angle_unit)
        if len(self) >= 3:
            check_spread(self.source, self.q, self.xyz, robot, length_unit or (self.units[0] if self.units else None),
                         angle_unit or (self.units[1] if self.units else None), rows=self.rows)


def _joint_columns(path: str, robot: Robot, joint_cols: Sequence[str] | None, header: Sequence[str] = ()) -> list[str]:
    """The joint columns: as given, else the robot's default for this header (its joints' names, or
    their robot-stack names), checked to be one per joint; then the covariates the robot reads, by
    their names (``joint_cols`` may name the joints alone). A covariate column missing from a non-empty
    ``header`` is refused naming the file, the column and the columns present."""
    cols = list(joint_cols) if joint_cols is not None else robot.default_columns(header)
    covariates = list(robot.covariate_names)
    if covariates and len(cols) == robot.n_joints - len(covariates):
        cols += covariates
    missing = [c for c in covariates if header and c not in header]
    if missing:
        raise MeasurementError(f"{path}: no column {', '.join(missing)} (the covariate(s) the model reads); the file's "
                               f"columns are {', '.join(header)}; add it, or name the column that holds it "
                               f"(--covariate-cols)")
    if len(cols) != robot.n_joints:
        raise MeasurementError(f"{path}: {len(cols)} joint columns given ({', '.join(cols)}) but robot '{robot.name}' "
                               f"has {robot.n_joints} joints; give one column per joint")
    return cols


def _file_scales(joint_types: Sequence[str], length_unit: str, angle_unit: str, path: str) -> tuple[np.ndarray, float]:
    """Factors from SI to a file's units: per joint (angle unit for revolute joints, length unit for
    prismatic ones; both units checked; a covariate as it is) and for lengths."""
    factors = np.array(joint_factors(joint_types, length_unit, angle_unit, f"{path}: ", MeasurementError))
    factors[[t == "covariate" for t in joint_types]] = 1.0
    return 1.0 / factors, 1.0 / unit_factor(length_unit, "length", f"{path}: ", MeasurementError)


def _input_units(robot: Robot, length_unit: str, angle_unit: str, path: str) -> list:
    """The file unit of each input column: a joint's (:func:`kincal.units.joint_units`), None (the
    number as written) for a covariate."""
    units = joint_units(robot.joint_types, length_unit, angle_unit, f"{path}: ", MeasurementError)
    return [None if t == "covariate" else u for t, u in zip(robot.joint_types, units)]


def read_joints(path: str | os.PathLike, robot: Robot, joint_cols: Sequence[str] | None = None, length_unit: str = "m",
                angle_unit: str = "rad") -> np.ndarray:
    """Joint values (N, n) in rad/m from a CSV with a header (e.g. poses to measure)."""
    path = str(path)
    units = _input_units(robot, length_unit, angle_unit, path)
    table = open_table(path)
    q = table.numbers(_joint_columns(path, robot, joint_cols, table.header), units, what="joint values")
    check_degrees(path, q, robot, angle_unit)
    return q


def read_positions(path: str | os.PathLike, xyz_cols: Sequence[str] = ("x", "y", "z"),
                   length_unit: str = "m", with_rows: bool = False):
    """Positions (N, 3) in m from a CSV with a header (e.g. targets to reach); with ``with_rows``
    also their 1-based line numbers (N,)."""
    path = str(path)
    if len(xyz_cols) != 3:
        raise MeasurementError(f"{path}: give exactly three position columns, got {list(xyz_cols)}")
    unit_factor(length_unit, "length", f"{path}: ", MeasurementError)
    table = open_table(path)
    xyz = table.numbers(list(xyz_cols), [length_unit] * 3, what="positions")
    return (xyz, table.rows) if with_rows else xyz


def read_measurements(path: str | os.PathLike, robot: Robot, joint_cols: Sequence[str] | None = None,
                      xyz_cols: Sequence[str] = ("x", "y", "z"), length_unit: str = "m", angle_unit: str = "rad",
                      std_cols: Sequence[str] | None = None) -> Measurements:
    """Read a CSV (header line; comma, semicolon or tab separated) of joint values and positions.

    joint_cols default to the robot's joint names; the covariates a robot reads after its joints
    (:func:`kincal.models.with_covariates`: a temperature column) are read by their names, as written.
    Revolute joints are in ``angle_unit``, prismatic joints and positions in ``length_unit``. Values
    are returned in SI units; data whose scale looks like the wrong unit is refused with the unit to use. ``std_cols``: the instrument's σ per sample
    and axis (length unit); by default ``measurement_std_x/y/z`` when the file has them (they weight
    the fit and set the noise level of the verdict); ``[]`` ignores them. Blank and '#' lines are
    skipped; every column is checked as ``_csv.Table`` checks it, errors naming the file, row and column.
    """
    path = str(path)
    _joint_columns(path, robot, joint_cols)  # one per joint, before the file is read
    if len(xyz_cols) != 3:
        raise MeasurementError(f"{path}: give exactly three position columns, got {list(xyz_cols)}")
    if std_cols is not None and len(std_cols) not in (0, 3):
        raise MeasurementError(f"{path}: give three σ columns (x, y, z) or none, got {list(std_cols)}")
    units = _input_units(robot, length_unit, angle_unit, path)
    table = open_table(path)
    cols = _joint_columns(path, robot, joint_cols, table.header)
    if std_cols is None:  # the σ columns by their usual names when the header has all three
        std_cols = STD_COLUMNS if all(c in table.header for c in STD_COLUMNS) else ()
    data = table.numbers(cols + list(xyz_cols) + list(std_cols), units + [length_unit] * (3 + len(std_cols)))
    n = robot.n_joints
    meas = Measurements(data[:, :n], data[:, n:n + 3], robot.joint_names, path, table.rows,
                        data[:, n + 3:] if len(std_cols) else None, (length_unit, angle_unit))
    meas.check_robot(robot, length_unit, angle_unit)
    return meas


STD_COLUMNS = ("measurement_std_x", "measurement_std_y", "measurement_std_z")


def write_measurements(path: str | os.PathLike, meas: Measurements, joint_types: Sequence[str] | None = None,
                       length_unit: str = "m", angle_unit: str = "rad",
                       joint_cols: Sequence[str] | None = None, xyz_cols: Sequence[str] = ("x", "y", "z")) -> None:
    """Write measurements as a comma-separated CSV (atomically) in the given units, the positions
    under the three names ``xyz_cols``."""
    types = list(joint_types) if joint_types is not None else ["revolute"] * meas.q.shape[1]
    scale, lf = _file_scales(types, length_unit, angle_unit, str(path))
    cols = list(joint_cols) if joint_cols is not None else list(meas.joint_names)
    if len(xyz_cols) != 3:
        raise ValueError(f"{path}: three position columns are needed, got {', '.join(xyz_cols)}")
    write_csv(path, cols + list(xyz_cols), ([repr(float(v)) for v in (*qi, *pi)]
                                            for qi, pi in zip(meas.q * scale, meas.xyz * lf)))


def write_joints(path: str | os.PathLike, q: np.ndarray, robot: Robot, joint_cols: Sequence[str] | None = None,
                 length_unit: str = "m", angle_unit: str = "rad") -> None:
    """Write joint vectors (N, n) in SI units as a CSV of poses (atomically), e.g. poses to measure."""
    cols = _joint_columns(str(path), robot, joint_cols)
    scale, _ = _file_scales(robot.joint_types, length_unit, angle_unit, str(path))
    write_csv(path, cols, ([repr(float(v)) for v in qi] for qi in robot.check_q(q) * scale))


def write_selected_rows(path: str | os.PathLike, source: str | os.PathLike, indices: Sequence[int] | np.ndarray
                        ) -> None:
    """The data rows ``indices`` (0-based, in file order, blank and '#' lines not counted) of the CSV
    ``source``, in that order, every column as the user gave it (IDs, names, other columns), after
    ``input_row``: the row's line number in ``source``; written atomically with the source's separator."""
    table = open_table(str(source))
    new = "input_row" not in table.header
    picked = (table.records[int(k)] for k in indices)
    write_csv(path, ["input_row", *table.header] if new else table.header,
              ([line, *cells] if new else cells for line, cells in picked), table.delim)


def write_residuals(path: str | os.PathLike, meas: Measurements, predicted: np.ndarray, z: np.ndarray, outlier_z: float,
                    joint_types: Sequence[str], length_unit: str = "mm", angle_unit: str = "deg") -> None:
    """Per-pose residual table (atomically): input row, joints, measured, predicted, error vector and
    norm (all in the given units), robust z-score and an outlier flag."""
    scale, lf = _file_scales(joint_types, length_unit, angle_unit, str(path))
    err = meas.xyz - predicted
    u = f"_{length_unit}"
    header = ["row", *meas.joint_names, *(f"{a}_measured{u}" for a in "xyz"), *(f"{a}_predicted{u}" for a in "xyz"),
              *(f"e{a}{u}" for a in "xyz"), f"norm{u}", "robust_z", "outlier"]
    rows = ([int(r), *(f"{v:.10g}" for v in (*qi, *m, *p, *e, np.linalg.norm(e), zi)),
             "yes" if zi > outlier_z else "no"]
            for r, qi, m, p, e, zi in zip(meas.rows, meas.q * scale, meas.xyz * lf, predicted * lf, err * lf, z))
    write_csv(path, header, rows)


def write_csv(path: str | os.PathLike, header, rows, delimiter: str = ",", first: str = "") -> None:
    """``first`` (e.g. a comment line), then the CSV ``header`` and ``rows``, written atomically."""
    buf = _io.StringIO()
    buf.write(first)
    w = csv.writer(buf, delimiter=delimiter, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    write_text_atomic(path, buf.getvalue())

