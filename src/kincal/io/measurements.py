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
from ..checks import kind_of
from ..errors import MeasurementError
from ..models.robot import Robot
from ..units import joint_factors, joint_units, unit_factor
from ..models.unit_checks import check_degrees, check_spread


@dataclass(frozen=True, eq=False, init=False)
class Measurements:
    """N measured poses: joint values q (N, n) in rad/m and positions xyz (N, 3) in m.

    A frozen record, checked when it is built; its arrays are read-only copies. ``rows`` are the 1-based
    line numbers in ``source`` (header = line 1) so errors can name them.

    Parameters
    ----------
    q : array_like, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    xyz : array_like, shape (N, 3)
        Measured positions of the tool point in the measurement frame, m.
    joint_names : sequence of str
        One name per column of ``q``.
    source : str, optional
        Where the data come from (a file's path), named in every error (default "<memory>").
    rows : array_like of int, shape (N,), optional
        The 1-based line number of each pose in ``source``, header = line 1 (default None: 2, 3, …, as
        written by :func:`write_measurements`).
    std : array_like, shape (N, 3), optional
        The instrument's σ per sample and axis, m, each > 0 (default None: not given).
    units : tuple of (str, str), optional
        The (length, angle) units the file was read in, for advice in messages (default None: SI).
    session : array_like of str, shape (N,), optional
        The session (file) of each pose (default None: one session).

    Raises
    ------
    MeasurementError
        When ``q`` is not (N, n) and ``xyz`` (N, 3) with the same N, ``joint_names`` does not name every
        column of ``q``, a value is NaN or infinite (named by row and column), ``std`` is not (N, 3) of finite
        values > 0, or ``session`` does not give one label per pose.

    See Also
    --------
    read_measurements : Measurements from a CSV file, in its units.
    kincal.simulate : Simulated measurements of a robot.

    Examples
    --------
    >>> import kincal
    >>> from kincal.io import Measurements
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(4, seed=1)
    >>> meas = Measurements(q, robot.forward(q), robot.joint_names, source="poses.csv")
    >>> len(meas), meas.q.shape, meas.xyz.shape, meas.rows.tolist()
    (4, (4, 6), (4, 3), [2, 3, 4, 5])
    >>> meas.subset([0, 2]).rows.tolist(), meas.without_rows([3]).rows.tolist()
    ([2, 4], [2, 4, 5])
    >>> meas.describe_rows([1, 3])
    'row(s) 3, 5'
    >>> meas.q.flags.writeable
    False

    Every check names the source:

    >>> Measurements(q, robot.forward(q)[:3], robot.joint_names, source="poses.csv")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: poses.csv: q must be (N, n) and xyz (N, 3) with the same N; got (4, 6) and (3, 3)
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

    def check_robot(self, robot: Robot, length_unit: str | None = None, angle_unit: str | None = None,
                    angle_default: bool = False) -> None:
        """Raise MeasurementError if the data cannot belong to ``robot`` or its units look wrong (``angle_default``:
        ``angle_unit`` is a reader's default, not given, and the message says so)."""
        if self.q.shape[1] != robot.n_joints:
            raise MeasurementError(f"{self.source}: {self.q.shape[1]} joint columns but robot '{robot.name}' has "
                                   f"{robot.n_joints} joints ({', '.join(robot.joint_names)}); pass the right joint "
                                   f"columns")
        outside, why = robot.inputs_outside(self.q)
        if outside.any():
            raise MeasurementError(f"{self.source}: {self.describe_rows(np.flatnonzero(outside))}: {why}")
        check_degrees(self.source, self.q, robot, angle_unit, angle_default)
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
    return 1.0 / factors, 1.0 / unit_factor(length_unit, "length", f"{path}: ", MeasurementError)


def read_joints(path: str | os.PathLike, robot: Robot, joint_cols: Sequence[str] | None = None, length_unit: str = "m",
                angle_unit: str | None = None) -> np.ndarray:
    """Read joint values from a CSV with a header (e.g. poses to measure).

    The file is read as :func:`read_measurements` reads it (comma, semicolon or tab separated; blank and '#'
    lines skipped; every value checked, errors naming the file, row and column). Revolute joints are read in
    ``angle_unit``, prismatic joints in ``length_unit``; the values come back in SI.

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file.
    robot : Robot
        The robot the joint values are for (its joints' number, types and limits).
    joint_cols : sequence of str, optional
        The joint columns, one per joint (default None: the robot's default for the file's header, its joint
        names; the covariates a robot reads after its joints by their names).
    length_unit : str, optional
        The file's unit of prismatic joints: "m", "mm" or "um" (default "m").
    angle_unit : str, optional
        The file's unit of revolute joints: "rad", "deg" or "rev" (default None: "rad", and a message that finds the
        values in another unit says none was given).

    Returns
    -------
    ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).

    Raises
    ------
    MeasurementError
        When the file cannot be read, a unit is unknown, the joint columns are not one per joint or are
        missing, a cell is not a finite number, or the values look like degrees read as radians
        (:func:`check_degrees`).

    See Also
    --------
    write_joints : The inverse: joint values written as a CSV of poses.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import read_joints, write_joints
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(3, seed=1)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "poses.csv")
    ...     write_joints(path, q, robot, angle_unit="deg")
    ...     back = read_joints(path, robot, angle_unit="deg")
    >>> back.shape, bool(np.allclose(back, q, rtol=0.0, atol=1e-12))
    ((3, 6), True)
    """
    path, angle_default = str(path), angle_unit is None
    angle_unit = "rad" if angle_unit is None else angle_unit
    units = joint_units(robot.joint_types, length_unit, angle_unit, f"{path}: ", MeasurementError)
    table = open_table(path)
    q = table.numbers(_joint_columns(path, robot, joint_cols, table.header), units, what="joint values")
    check_degrees(path, q, robot, angle_unit, angle_default)
    return q


def read_positions(path: str | os.PathLike, xyz_cols: Sequence[str] = ("x", "y", "z"),
                   length_unit: str = "m", with_rows: bool = False):
    """Read positions from a CSV with a header (e.g. targets to reach).

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file (comma, semicolon or tab separated; blank and '#' lines skipped).
    xyz_cols : sequence of str, optional
        The three position columns (default ("x", "y", "z")).
    length_unit : str, optional
        The file's length unit: "m", "mm" or "um" (default "m").
    with_rows : bool, optional
        Also return the positions' line numbers (default False).

    Returns
    -------
    xyz : ndarray, shape (N, 3)
        The positions, m.
    rows : ndarray of int, shape (N,)
        Their 1-based line numbers in the file, header = line 1; only with ``with_rows``.

    Raises
    ------
    MeasurementError
        When not exactly three position columns are given, the unit is unknown, the file cannot be read, a
        column is missing or a cell is not a finite number.

    Examples
    --------
    >>> import os, tempfile
    >>> from kincal.io import read_positions
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "targets.csv")
    ...     with open(path, "w") as f:
    ...         _ = f.write("name;x;y;z\\n# the first two\\nA;400;-100;300\\nB;450;-100;300\\n")
    ...     xyz, rows = read_positions(path, length_unit="mm", with_rows=True)
    >>> xyz.tolist(), rows.tolist()
    ([[0.4, -0.1, 0.3], [0.45, -0.1, 0.3]], [3, 4])
    """
    path = str(path)
    if len(xyz_cols) != 3:
        raise MeasurementError(f"{path}: give exactly three position columns, got {list(xyz_cols)}")
    unit_factor(length_unit, "length", f"{path}: ", MeasurementError)
    table = open_table(path)
    xyz = table.numbers(list(xyz_cols), [length_unit] * 3, what="positions")
    return (xyz, table.rows) if with_rows else xyz


def read_measurements(path: str | os.PathLike, robot: Robot, joint_cols: Sequence[str] | None = None,
                      xyz_cols: Sequence[str] = ("x", "y", "z"), length_unit: str = "m",
                      angle_unit: str | None = None, std_cols: Sequence[str] | None = None) -> Measurements:
    """Read a CSV (header line; comma, semicolon or tab separated) of joint values and positions.

    Revolute joints are in ``angle_unit``, prismatic joints and positions in ``length_unit``; values are
    returned in SI units, and data whose scale looks like the wrong unit is refused with the unit to use
    (:func:`check_degrees`, :func:`check_spread`). Blank and '#' lines are skipped; every column is checked
    as ``_csv.Table`` checks it (named once, present, a number, finite, physically possible), errors naming
    the file, row and column.

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file.
    robot : Robot
        The robot the data belong to (its joints' number, types and limits, its reach).
    joint_cols : sequence of str, optional
        The joint columns (default None: the robot's joint names); the covariates a robot reads after its
        joints (:func:`kincal.models.with_covariates`: a temperature column) are read by their names, as
        written.
    xyz_cols : sequence of str, optional
        The three position columns (default ("x", "y", "z")).
    length_unit : str, optional
        The file's unit of positions and prismatic joints: "m", "mm" or "um" (default "m").
    angle_unit : str, optional
        The file's unit of revolute joints: "rad", "deg" or "rev" (default None: "rad", and a message that finds the
        values in another unit says none was given).
    std_cols : sequence of str, optional
        Three columns of the instrument's σ per sample and axis, in ``length_unit`` (they weight the fit and
        set the noise level of the verdict); ``[]`` ignores them (default None: ``measurement_std_x/y/z``
        when the file has all three).

    Returns
    -------
    Measurements
        q (N, n) rad/m, xyz (N, 3) m, σ (N, 3) m or None, with the file's path as ``source``, the data's line
        numbers as ``rows`` and (``length_unit``, ``angle_unit``) as ``units``.

    Raises
    ------
    MeasurementError
        When the columns are not one per joint and three positions (and three σ or none), a unit is unknown,
        the file cannot be read, a cell is missing, not a number or not finite, a joint value is outside what
        the robot can take, or the data look like another unit (named, with the option to use).

    See Also
    --------
    write_measurements : The inverse: measurements written as a CSV in given units.

    Examples
    --------
    Simulated "ur5" data written in mm and deg, read back in SI:

    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import read_measurements, write_measurements
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(5, seed=1), seed=0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "ur5.csv")
    ...     write_measurements(path, meas, robot.joint_types, length_unit="mm", angle_unit="deg")
    ...     back = read_measurements(path, robot, length_unit="mm", angle_unit="deg")
    ...     read_measurements(path, robot, angle_unit="deg")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: ...ur5.csv: measured positions spread 1e+03x more than the robot moves at the
    same joint values (read as 'm'): they look like mm; use length unit 'mm' (CLI: --length-unit mm)
    >>> back.units, back.rows.tolist()
    (('mm', 'deg'), [2, 3, 4, 5, 6])
    >>> float(np.abs(back.q - meas.q).max()) < 1e-12, float(np.abs(back.xyz - meas.xyz).max()) < 1e-12
    (True, True)
    """
    kind_of("robot", robot, Robot, "load it first, e.g. kincal.read_measurements(path, kincal.load_robot('ur5'))")
    path, angle_default = str(path), angle_unit is None
    angle_unit = "rad" if angle_unit is None else angle_unit
    _joint_columns(path, robot, joint_cols)  # one per joint, before the file is read
    if len(xyz_cols) != 3:
        raise MeasurementError(f"{path}: give exactly three position columns, got {list(xyz_cols)}")
    if std_cols is not None and len(std_cols) not in (0, 3):
        raise MeasurementError(f"{path}: give three σ columns (x, y, z) or none, got {list(std_cols)}")
    units = joint_units(robot.joint_types, length_unit, angle_unit, f"{path}: ", MeasurementError)
    table = open_table(path)
    cols = _joint_columns(path, robot, joint_cols, table.header)
    if std_cols is None:  # the σ columns by their usual names when the header has all three
        std_cols = STD_COLUMNS if all(c in table.header for c in STD_COLUMNS) else ()
    data = table.numbers(cols + list(xyz_cols) + list(std_cols), units + [length_unit] * (3 + len(std_cols)))
    n = robot.n_joints
    meas = Measurements(data[:, :n], data[:, n:n + 3], robot.joint_names, path, table.rows,
                        data[:, n + 3:] if len(std_cols) else None, (length_unit, angle_unit))
    meas.check_robot(robot, length_unit, angle_unit, angle_default)
    return meas


STD_COLUMNS = ("measurement_std_x", "measurement_std_y", "measurement_std_z")


def write_measurements(path: str | os.PathLike, meas: Measurements, joint_types: Sequence[str] | None = None,
                       length_unit: str = "m", angle_unit: str = "rad",
                       joint_cols: Sequence[str] | None = None, xyz_cols: Sequence[str] = ("x", "y", "z")) -> None:
    """Write measurements as a comma-separated CSV (atomically) in the given units.

    The header is the joint columns, then the three names ``xyz_cols``; each value is written in full
    precision (``repr``), so :func:`read_measurements` gives the same numbers back (up to the unit
    conversion's round-off).

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (replaced whole, or left as it was).
    meas : Measurements
        The measurements (SI).
    joint_types : sequence of str, optional
        Each joint's type, "revolute" or "prismatic" ("covariate": a covariate column, written as it is)
        (default None: all revolute).
    length_unit : str, optional
        The file's unit of positions and prismatic joints: "m", "mm" or "um" (default "m").
    angle_unit : str, optional
        The file's unit of revolute joints: "rad", "deg" or "rev" (default "rad").
    joint_cols : sequence of str, optional
        The joint columns' names (default None: ``meas.joint_names``).
    xyz_cols : sequence of str, optional
        The three position columns' names (default ("x", "y", "z")).

    Raises
    ------
    MeasurementError
        When a unit is unknown.
    ValueError
        When ``xyz_cols`` does not name three columns.

    See Also
    --------
    read_measurements : The inverse.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import write_measurements
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(2, seed=1), seed=0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "ur5.csv")
    ...     write_measurements(path, meas, robot.joint_types, length_unit="mm", angle_unit="deg",
    ...                        xyz_cols=("X", "Y", "Z"))
    ...     with open(path) as f:
    ...         lines = f.read().splitlines()
    >>> lines[0], len(lines)
    ('j1,j2,j3,j4,j5,j6,X,Y,Z', 3)
    >>> first = np.array(lines[1].split(","), dtype=float)
    >>> bool(np.allclose(np.radians(first[:6]), meas.q[0])), bool(np.allclose(first[6:] / 1e3, meas.xyz[0]))
    (True, True)
    """
    types = list(joint_types) if joint_types is not None else ["revolute"] * meas.q.shape[1]
    scale, lf = _file_scales(types, length_unit, angle_unit, str(path))
    cols = list(joint_cols) if joint_cols is not None else list(meas.joint_names)
    if len(xyz_cols) != 3:
        raise ValueError(f"{path}: three position columns are needed, got {', '.join(xyz_cols)}")
    write_csv(path, cols + list(xyz_cols), ([repr(float(v)) for v in (*qi, *pi)]
                                            for qi, pi in zip(meas.q * scale, meas.xyz * lf)))


def write_joints(path: str | os.PathLike, q: np.ndarray, robot: Robot, joint_cols: Sequence[str] | None = None,
                 length_unit: str = "m", angle_unit: str = "rad") -> None:
    """Write joint vectors in SI units as a CSV of poses (atomically), e.g. poses to measure.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (replaced whole, or left as it was).
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint); a single (n,) vector is one pose.
    robot : Robot
        The robot (its joints' number and types).
    joint_cols : sequence of str, optional
        The columns' names, one per joint (default None: the robot's joint names).
    length_unit : str, optional
        The file's unit of prismatic joints: "m", "mm" or "um" (default "m").
    angle_unit : str, optional
        The file's unit of revolute joints: "rad", "deg" or "rev" (default "rad").

    Raises
    ------
    MeasurementError
        When the columns are not one per joint or a unit is unknown.
    ModelError
        When ``q`` does not have one column per joint.

    See Also
    --------
    read_joints : The inverse.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import write_joints
    >>> robot = kincal.load_robot("ur5")
    >>> q = np.radians([[0.0, -90.0, 90.0, -90.0, -90.0, 0.0]])
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "poses.csv")
    ...     write_joints(path, q, robot, joint_cols=["A1", "A2", "A3", "A4", "A5", "A6"], angle_unit="deg")
    ...     with open(path) as f:
    ...         header, row = f.read().splitlines()
    >>> header
    'A1,A2,A3,A4,A5,A6'
    >>> [round(float(v), 9) for v in row.split(",")]
    [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]
    """
    cols = _joint_columns(str(path), robot, joint_cols)
    scale, _ = _file_scales(robot.joint_types, length_unit, angle_unit, str(path))
    write_csv(path, cols, ([repr(float(v)) for v in qi] for qi in robot.check_q(q) * scale))


def write_selected_rows(path: str | os.PathLike, source: str | os.PathLike, indices: Sequence[int] | np.ndarray
                        ) -> None:
    """Write chosen data rows of a CSV, every column as the user gave it (IDs, names, other columns).

    The rows come in the order of ``indices``, each after ``input_row``: its line number in ``source``
    (header = line 1; a source that has an ``input_row`` column keeps its own). Written atomically with the
    source's separator.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    source : str or os.PathLike
        The CSV the rows come from.
    indices : sequence of int or ndarray
        The data rows to write, 0-based in file order (blank and '#' lines not counted).

    Raises
    ------
    MeasurementError
        When ``source`` cannot be read as a CSV.
    IndexError
        When an index is negative or beyond the source's data rows (nothing is written).

    Examples
    --------
    >>> import os, tempfile
    >>> from kincal.io import write_selected_rows
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     source, path = os.path.join(tmp, "all.csv"), os.path.join(tmp, "chosen.csv")
    ...     with open(source, "w") as f:
    ...         _ = f.write("id;j1\\nP1;0.1\\n# skipped\\nP2;0.2\\nP3;0.3\\n")
    ...     write_selected_rows(path, source, [2, 0])
    ...     with open(path) as f:
    ...         print(f.read(), end="")
    input_row;id;j1
    5;P3;0.3
    2;P1;0.1
    """
    table = open_table(str(source))
    new = "input_row" not in table.header
    wrong = [int(k) for k in indices if not 0 <= int(k) < len(table.records)]
    if wrong:  # a negative index would silently count from the end
        raise IndexError(f"{source}: data row index {wrong[0]} is outside 0..{len(table.records) - 1} (0-based, file "
                         f"order)")
    picked = (table.records[int(k)] for k in indices)
    write_csv(path, ["input_row", *table.header] if new else table.header,
              ([line, *cells] if new else cells for line, cells in picked), table.delim)


def write_residuals(path: str | os.PathLike, meas: Measurements, predicted: np.ndarray, z: np.ndarray, outlier_z: float,
                    joint_types: Sequence[str], length_unit: str = "mm", angle_unit: str = "deg") -> None:
    """Write the per-pose residual table (atomically).

    One row per pose: its input row, joints, measured and predicted positions, the error vector (measured −
    predicted) and its norm, all in the given units (the position columns' names end in ``_<length_unit>``),
    then the robust z-score and an outlier flag ("yes" where z > ``outlier_z``).

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    meas : Measurements
        The measurements (SI).
    predicted : ndarray, shape (N, 3)
        The positions a model predicts at the poses, m.
    z : ndarray, shape (N,)
        The robust z-score of each pose's error.
    outlier_z : float
        The z-score beyond which a pose is flagged as an outlier.
    joint_types : sequence of str
        Each joint's type, "revolute" or "prismatic" ("covariate": written as it is).
    length_unit : str, optional
        The table's length unit: "m", "mm" or "um" (default "mm").
    angle_unit : str, optional
        The table's unit of revolute joints: "rad", "deg" or "rev" (default "deg").

    Raises
    ------
    MeasurementError
        When a unit is unknown.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import write_residuals
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(3, seed=1), seed=0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "residuals.csv")
    ...     write_residuals(path, meas, robot.forward(meas.q), np.array([0.5, 4.0, 1.0]), 3.5, robot.joint_types)
    ...     with open(path) as f:
    ...         lines = f.read().splitlines()
    >>> print(*lines[0].split(","))
    row j1 j2 j3 j4 j5 j6 x_measured_mm y_measured_mm z_measured_mm x_predicted_mm y_predicted_mm z_predicted_mm
    ex_mm ey_mm ez_mm norm_mm robust_z outlier
    >>> [line.split(",")[-1] for line in lines[1:]]
    ['no', 'yes', 'no']
    """
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

