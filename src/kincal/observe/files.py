"""Observation files: one CSV per set, its columns declared by the type (``ObservationFormat``).

Every type has the robot's joint columns (or ``joint_cols``) in ``angle_unit`` / ``length_unit``:

* ``point``: x, y, z (``xyz_cols``), the measured point;
* ``pose``: x, y, z and the orientation columns of the declared convention (see
  :mod:`kincal.observe.orientation`; ``rot_cols`` renames them);
* ``markers``: NAME.x, NAME.y, NAME.z for every marker NAME (all such triplets in the header, or
  ``markers``); an empty cell is a marker not seen in that sample;
* ``same-point``: a label column (``label_col``, default ``point``) and optionally a group column (``group_col``,
  e.g. the plate placement); ``distances`` are known distances between labels, applied inside every group;
* ``plane``: a label column (``label_col``, default ``plane``); ``planes`` gives the known ones (unit normal and
  offset, n·p = c in the robot's base frame); the others are fitted.

σ are stated (``std_pos`` m, ``std_rot`` rad: a statement wins), or read per sample from the columns ``std_pos``
(the file's length unit) and, for poses, ``std_rot_mrad`` (mrad) — points: measurement_std_x/y/z —, or the type's
default. A file whose columns do not fit the declared type is refused in one line.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._atomic import write_text_atomic
from .._csv import LIMIT, Table, open_table
from ..errors import MeasurementError, ModelError
from ..models.robot import Robot
from ..models.unit_checks import check_joints, check_spread
from ..units import fine, joint_factors, joint_units, unit_factor
from .constraints import PlaneObs, SamePointObs
from .joint import unassembled_rows
from .markers import MarkersObs
from .observations import Observation, PointObs, PoseObs, flange_point
from .orientation import (check_convention, convention_check, default_columns, from_matrices, position_frame,
                          to_matrices)

KINDS = ("point", "pose", "markers", "same-point", "plane")
DEFAULT_STD = {"point": (15e-6, None), "pose": (0.1e-3, 1e-3), "markers": (50e-6, None),
               "same-point": (50e-6, None), "plane": (50e-6, None)}
POINT_STD = ("measurement_std_x", "measurement_std_y", "measurement_std_z")


def check_pose_columns(orientation: str, length_unit: str, angle_unit: str, xyz_cols, rot_cols) -> None:
    """The settings shared by files of positions and poses: a known orientation convention and units,
    three position columns, and as many orientation columns as the convention has (ValueError)."""
    check_convention(orientation)
    unit_factor(length_unit, "length")
    unit_factor(angle_unit, "angle")
    if len(xyz_cols) != 3:
        raise ValueError(f"give three position columns, got {list(xyz_cols)}")
    if rot_cols is not None and len(rot_cols) != len(default_columns(orientation)):
        raise ValueError(f"{orientation} has {len(default_columns(orientation))} columns, got {list(rot_cols)}")


@dataclass(frozen=True)
class ObservationFormat:
    """How to read (and write) one observation file: its type, columns and units.

    A frozen record; every setting is checked when it is built (ValueError). The columns each type has are
    listed in :mod:`kincal.observe.files`.

    Parameters
    ----------
    kind : str, optional
        The type, one of :data:`KINDS`: "point", "pose", "markers", "same-point" or "plane" (default "point").
    joint_cols : tuple of str, optional
        The joint columns (default None: the robot's default for the file's header, its joint names).
    length_unit : str, optional
        The file's length unit, "m", "mm" or "um": positions, prismatic joints, ``std_pos`` columns,
        ``distances`` and the planes' offsets (default "m").
    angle_unit : str, optional
        The file's unit of revolute joints, "rad", "deg" or "rev" (default None: "rad", and a message about the
        values in another unit says none was given; ``angle_default`` records it).
    xyz_cols : tuple of str, optional
        The three position columns of points and poses (default ("x", "y", "z")).
    orientation : str, optional
        The orientation convention of poses (:func:`check_convention`; default "quat-wxyz").
    rot_cols : tuple of str, optional
        The orientation columns, as many as the convention has (default None: :func:`default_columns`).
    markers : tuple of str, optional
        The markers' names (default None: every NAME with NAME.x, NAME.y, NAME.z columns in the header).
    label_col : str, optional
        The label column of same-point and plane files (default None: "point" and "plane").
    group_col : str, optional
        A same-point file's group column, e.g. the plate placement (default None: one group).
    distances : tuple of (str, str, float), optional
        Known distances between same-point labels, in ``length_unit``, applied inside every group: each pair
        once (in either order; a repeat with the same length is dropped), a length > 0 that a robot can span
        (default ()).
    planes : dict, optional
        The known planes: label -> (normal (3,), offset c in ``length_unit``), n·p = c in the robot's base
        frame; the others are fitted (default {}).
    std_pos : float, optional
        σ of positions, m: a statement wins over the file's columns (default None: per sample from the
        file's ``std_pos`` column, in its length unit (points: measurement_std_x/y/z), else the type's
        default).
    std_rot : float, optional
        σ of rotations, rad (default None: per sample from a pose file's ``std_rot_mrad`` column, mrad, else
        the type's default).
    own_target : bool, optional
        A held-out pose file: its target's frame on the flange is its own, re-fitted (default False).

    Raises
    ------
    ValueError
        For an unknown type, convention or unit, not three position columns, orientation columns that do not
        fit the convention, a σ that is not > 0 or beyond any instrument's, a distance that is not > 0 between
        two labels, beyond any robot's span or given twice with two lengths, a plane without a non-zero normal
        or with an offset beyond reach.

    Examples
    --------
    >>> from kincal.observe import ObservationFormat
    >>> fmt = ObservationFormat(kind="same-point", length_unit="mm", distances=[("a", "b", 50.0), ("b", "a", 50.0)])
    >>> fmt.distances, fmt.label, fmt.std()
    ((('a', 'b', 50.0),), 'point', (5e-05, None))
    >>> ObservationFormat(kind="sphere")
    Traceback (most recent call last):
    ...
    ValueError: measurement type 'sphere': use one of point, pose, markers, same-point, plane
    """

    kind: str = "point"
    joint_cols: tuple[str, ...] | None = None
    length_unit: str = "m"
    angle_unit: str = None  # type: ignore[assignment]  # None: "rad", not given (__post_init__ sets it)
    xyz_cols: tuple[str, ...] = ("x", "y", "z")
    orientation: str = "quat-wxyz"
    rot_cols: tuple[str, ...] | None = None
    markers: tuple[str, ...] | None = None
    label_col: str | None = None
    group_col: str | None = None
    distances: tuple[tuple[str, str, float], ...] = ()
    planes: dict = field(default_factory=dict)  # label -> (normal (3,), offset)
    std_pos: float | None = None  # m
    std_rot: float | None = None  # rad
    own_target: bool = False  # pose, held out: its target's frame on the flange is its own (re-fitted)
    angle_default: bool = field(init=False, default=False)  # no angle unit was given: "rad" is the default

    def __post_init__(self) -> None:
        """Every setting checked (ValueError): a known type, convention and units, σ > 0 that an instrument can
        have; known distances: two labels, a length > 0 that a robot can span, each pair once (in either order;
        a repeat with the same length is dropped); known planes: a normal and an offset a robot can reach."""
        if self.kind not in KINDS:
            raise ValueError(f"measurement type '{self.kind}': use one of {', '.join(KINDS)}")
        if self.angle_unit is None:  # frozen: set once, here
            object.__setattr__(self, "angle_unit", "rad")
            object.__setattr__(self, "angle_default", True)
        check_pose_columns(self.orientation, self.length_unit, self.angle_unit, self.xyz_cols, self.rot_cols)
        for what, v in (("std_pos", self.std_pos), ("std_rot", self.std_rot)):
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{what} must be a positive number, got {v}")
        lf = unit_factor(self.length_unit, "length")
        kept: dict[frozenset, tuple[str, str, float]] = {}
        for a, b, d in self.distances:
            if not (np.isfinite(d) and d > 0) or a == b:
                raise ValueError(f"distance {a}–{b}: give two different labels and a length > 0, got {d}")
            if d * lf > LIMIT["length"]:
                raise ValueError(f"distance {a}–{b}: {d:g} {self.length_unit} is more than any robot spans; give it "
                                 f"in the file's length unit ({self.length_unit})")
            key = frozenset((a, b))
            if key in kept and kept[key][2] != d:
                raise ValueError(f"distance {a}–{b} is given twice, as {kept[key][2]:g} and {d:g}; give each known "
                                 f"distance once")
            kept.setdefault(key, (a, b, d))
        object.__setattr__(self, "distances", tuple(kept.values()))
        for label, (n, c) in self.planes.items():
            n = np.asarray(n, float)
            if n.shape != (3,) or not np.isfinite(n).all() or not np.linalg.norm(n) or not np.isfinite(c) \
                    or abs(c) * lf > LIMIT["length"]:
                raise ValueError(f"plane {label}: give a non-zero normal and an offset a robot can reach (in "
                                 f"{self.length_unit}), got {', '.join(f'{v:g}' for v in n)}, {c:g}")
        if self.std_pos is not None and self.std_pos > LIMIT["length"]:
            raise ValueError(f"std_pos {fine(self.std_pos, 'length', 'g')}: more than any instrument's σ (at most "
                             f"{LIMIT['length'] / 1e3:g} km)")

    @property
    def label(self) -> str:
        return self.label_col or ("plane" if self.kind == "plane" else "point")

    def std(self) -> tuple[float, float | None]:
        pos, rot = DEFAULT_STD[self.kind]
        return (self.std_pos or pos), (self.std_rot or rot)


def _stds(t: Table, fmt: ObservationFormat):
    """The σ (m, rad) of position and rotation, as the module docstring says."""
    def column(col: str, unit: str, value, stated: float | None):
        if stated is not None or col not in t.header:
            return value
        v = t.numbers([col], unit)[:, 0]
        if (v <= 0).any():
            raise MeasurementError(f"{t.path}: row {t.rows[np.flatnonzero(v <= 0)[0]]}, column '{col}': a σ must "
                                   f"be > 0")
        return v
    pos, rot = fmt.std()
    return column("std_pos", fmt.length_unit, pos, fmt.std_pos), column("std_rot_mrad", "mrad", rot, fmt.std_rot)


def read_observations(path: str, robot: Robot, fmt: ObservationFormat = ObservationFormat()) -> Observation:
    """Read one set of observations from a CSV file, as its format declares it.

    The columns of each type are listed in :mod:`kincal.observe.files`; each column is read as ``_csv.Table``
    reads it: named once in the header, used for one thing, present, a number as a CSV cell writes it,
    finite, physical. Values come back in SI. Pose orientations are checked against the nominal robot
    (another common convention that fits markedly better is named).

    Parameters
    ----------
    path : str
        The CSV file.
    robot : Robot
        The robot the data belong to (its joints and, for poses, its nominal flange rotations).
    fmt : ObservationFormat, optional
        The file's type, columns and units (default: points, m and rad).

    Returns
    -------
    Observation
        A :class:`PointObs`, :class:`PoseObs`, :class:`MarkersObs`, :class:`SamePointObs` (labels
        "<group>/<label>" with a group column; distances in m) or :class:`PlaneObs` (known planes' offsets in
        m), with the file's path as ``source`` and the data's line numbers as ``rows``.

    Raises
    ------
    MeasurementError
        When the file cannot be read, its columns do not fit the type (named, with the option that names
        them), a cell is not a finite number or a σ is not > 0, a marker has some coordinates empty, a label
        is empty, a known distance or plane names a label the file does not have, an orientation is no
        rotation in its convention or looks like another convention, or the joints or positions look like another
        unit than ``fmt``'s (degrees read as radians and the reverse; positions whose spread is 1000 times the
        robot's own at the same joints), the checks the point reader makes.

    See Also
    --------
    write_observations : The inverse.
    describe : What a file of a type must hold.

    Examples
    --------
    Two sockets 0.31 m apart, reached by a SCARA, written in mm and deg and read back (the known distance is
    stated in the file's unit):

    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import ObservationFormat, read_observations, write_observations
    >>> from kincal.simulate import simulate_same_point
    >>> robot = kincal.load_robot("scara")
    >>> a, b = robot.forward(np.array([[0.3, 0.5, 0.1, 0.0], [-0.4, 0.8, 0.05, 0.0]]))
    >>> obs = simulate_same_point(robot, {"a": a, "b": b}, per_point=2)
    >>> d = round(float(np.linalg.norm(a - b)) * 1e3, 3)
    >>> fmt = ObservationFormat(kind="same-point", length_unit="mm", angle_unit="deg", distances=[("a", "b", d)])
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "sockets.csv")
    ...     write_observations(path, obs, robot, fmt)
    ...     back = read_observations(path, robot, fmt)
    >>> type(back).__name__, back.labels.tolist(), back.rows.tolist()
    ('SamePointObs', ['a', 'a', 'b', 'b'], [2, 3, 4, 5])
    >>> [(x, y, round(m, 9)) for x, y, m in back.distances], bool(np.allclose(back.q, obs.q, rtol=0.0, atol=1e-9))
    ([('a', 'b', 0.313686)], True)
    """
    table = open_table(str(path), "joint, position, orientation, marker, label or σ")  # what its columns may be
    q = _joints(table, robot, fmt)
    lf = unit_factor(fmt.length_unit, "length")
    reader = {"point": _point, "pose": _pose, "markers": _markers, "same-point": _same_point, "plane": _plane}
    obs = reader[fmt.kind](table, robot, fmt, q, lf)
    _check_units(obs, robot, fmt)
    return obs


def _check_units(obs: Observation, robot: Robot, fmt: ObservationFormat) -> None:
    """The readers' unit checks, as the point reader makes them: the measured positions' spread against the robot's
    own at the same joints (where the kind has positions: they name the unit first), then the joints' unit, then
    two joint columns swapped where a closed chain does not assemble at some rows."""
    found = obs.positions()
    if found is not None:
        check_spread(obs.source, *found, robot, fmt.length_unit, fmt.angle_unit, rows=obs.rows)
    check_joints(obs.source, obs.q, robot, fmt.length_unit, fmt.angle_unit, suggest=found is None,
                 angle_default=fmt.angle_default)
    swap = None if found is None else unassembled_rows(obs.source, *found, robot, obs.rows,
                                                       (fmt.length_unit, fmt.angle_unit))
    if swap is not None and swap[1]:  # two joint columns swapped: the whole file's mistake (a few rows that do not
        raise swap[0]  # assemble are left to the fit, which names them, to leave out with --exclude)


def _joints(t: Table, robot: Robot, fmt: ObservationFormat) -> np.ndarray:
    cols = list(fmt.joint_cols or robot.default_columns(t.header))
    if len(cols) != robot.n_joints:
        raise MeasurementError(f"{t.path}: {len(cols)} joint columns given ({', '.join(cols)}) but robot "
                               f"'{robot.name}' has {robot.n_joints} joints; give one column per joint")
    t.need(cols, f"--type {fmt.kind} needs the joint columns, named by --joint-cols")
    return t.numbers(cols, joint_units(robot.joint_types, fmt.length_unit, fmt.angle_unit))


def _point(t: Table, robot: Robot, fmt: ObservationFormat, q, lf) -> PointObs:
    t.need(fmt.xyz_cols, f"--type {fmt.kind} needs the position columns (--xyz-cols)")
    xyz = t.numbers(fmt.xyz_cols, fmt.length_unit)
    columns = fmt.std_pos is None and all(c in t.header for c in POINT_STD)
    std = t.numbers(POINT_STD, fmt.length_unit) if columns else fmt.std()[0]
    return PointObs(q, t.rows, t.path, xyz=xyz, std=std)


def _pose(t: Table, robot: Robot, fmt: ObservationFormat, q, lf) -> PoseObs:
    cols = list(fmt.rot_cols or default_columns(fmt.orientation))
    t.need(fmt.xyz_cols, f"--type {fmt.kind} needs the position columns (--xyz-cols)")
    t.need(cols, f"--type pose needs orientation columns {', '.join(cols)} for --orientation {fmt.orientation} (other "
                 f"names: --rot-cols; position only: --type point)")
    xyz = t.numbers(fmt.xyz_cols, fmt.length_unit)
    values = t.numbers(cols)
    try:
        p, _, Rf = flange_point(robot, q, robot.params.values, robot.tool_point())
    except ModelError:  # a closed chain that does not assemble at the file's joints: the joints' checks name why
        pass
    else:
        convention_check(Rf, values, fmt.orientation, t.path, t.rows, position_frame(p, xyz))
    pos, rot = _stds(t, fmt)
    return PoseObs(q, t.rows, t.path, xyz=xyz, R=to_matrices(values, fmt.orientation, t.path, t.rows), std_pos=pos,
                   std_rot=rot, own_target=fmt.own_target)


def _markers(t: Table, robot: Robot, fmt: ObservationFormat, q, lf) -> MarkersObs:
    names = fmt.markers or tuple(dict.fromkeys(c[:-2] for c in t.header if c.endswith(".x") and f"{c[:-2]}.y" in
                                               t.header and f"{c[:-2]}.z" in t.header))
    if not names:
        raise MeasurementError(f"{t.path}: --type markers needs columns NAME.x, NAME.y, NAME.z per marker (none "
                               f"found); the header has: {', '.join(t.header)}")
    cols = [f"{m}.{a}" for m in names for a in "xyz"]
    t.need(cols, "--type markers needs the marker columns NAME.x, NAME.y, NAME.z")
    xyz = t.numbers(cols, fmt.length_unit, empty_ok=True).reshape(len(t.records), len(names), 3)
    partial = np.isnan(xyz).any(axis=2) & ~np.isnan(xyz).all(axis=2)
    if partial.any():
        r, m = np.argwhere(partial)[0]
        raise MeasurementError(f"{t.path}: row {t.rows[r]}: marker {names[m]} has some coordinates empty, not all; "
                               f"a marker not seen leaves all three empty")
    _no_copies(t.path, xyz, names)
    return MarkersObs(q, t.rows, t.path, xyz=xyz, names=tuple(names), std=_stds(t, fmt)[0])


def _no_copies(path: str, xyz: np.ndarray, names) -> None:
    """MeasurementError for a marker whose columns repeat another's (seen in the same rows, the same numbers): one
    marker under two names counts its noise twice and passes for a nest it is not."""
    seen = ~np.isnan(xyz).any(axis=2)  # (N, k)
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            if seen[:, a].any() and np.array_equal(seen[:, a], seen[:, b]) and \
                    np.array_equal(xyz[seen[:, a], a], xyz[seen[:, b], b]):
                raise MeasurementError(f"{path}: the columns of marker {names[b]} repeat those of {names[a]} in every "
                                       f"row: one marker under two names; leave the copy out (--markers)")


def _labels(t: Table, fmt: ObservationFormat) -> tuple[np.ndarray, np.ndarray | None]:
    t.need([fmt.label] + ([fmt.group_col] if fmt.group_col else []), f"--type {fmt.kind} needs a label column "
           f"('{fmt.label}', --label-col)" + (" and the group column" if fmt.group_col else ""))
    labels = t.text(fmt.label)
    if (labels == "").any():
        raise MeasurementError(f"{t.path}: row {t.rows[np.flatnonzero(labels == '')[0]]}: empty label in column "
                               f"'{fmt.label}'")
    return labels, (t.text(fmt.group_col) if fmt.group_col else None)


def _same_point(t: Table, robot: Robot, fmt: ObservationFormat, q, lf) -> SamePointObs:
    labels, group = _labels(t, fmt)
    known = set(labels.tolist())
    for a, b, _ in fmt.distances:
        unknown = [x for x in (a, b) if x not in known]
        if unknown:
            raise MeasurementError(f"{t.path}: the distance {a}–{b} names label(s) {', '.join(unknown)} that column "
                                   f"'{fmt.label}' does not have (it has: {', '.join(sorted(known))})")
    dist = tuple((a, b, d * lf) for a, b, d in fmt.distances)
    if group is not None:  # labels "<group>/<label>", each distance applied inside every group that has both
        labels = np.array([f"{g}/{lab}" for g, lab in zip(group, labels)])
        have = set(labels.tolist())
        dist = tuple((f"{g}/{a}", f"{g}/{b}", d) for g in dict.fromkeys(group.tolist()) for a, b, d in dist
                     if f"{g}/{a}" in have and f"{g}/{b}" in have)
    return SamePointObs(q, t.rows, t.path, labels=labels, distances=dist, group=group, std=_stds(t, fmt)[0])


def _plane(t: Table, robot: Robot, fmt: ObservationFormat, q, lf) -> PlaneObs:
    labels, _ = _labels(t, fmt)
    missing = [lab for lab in fmt.planes if lab not in set(labels.tolist())]
    if missing:
        raise MeasurementError(f"{t.path}: known plane(s) {', '.join(missing)} not in column '{fmt.label}' (it has: "
                               f"{', '.join(sorted(set(labels.tolist())))})")
    known = {lab: (np.asarray(n, float), float(c) * lf) for lab, (n, c) in fmt.planes.items()}
    return PlaneObs(q, t.rows, t.path, labels=labels, known=known, std=_stds(t, fmt)[0])


def write_observations(path: str, obs: Observation, robot: Robot, fmt: ObservationFormat = ObservationFormat()) -> None:
    """Write a set of observations in the columns :func:`read_observations` reads with a format (atomically).

    What ``kincal simulate --type`` writes, so a planned set-up can be calibrated: the type's own columns
    (positions, orientations, markers, labels) then the joints, in the format's units, numbers to 12
    significant digits (an unseen marker as an empty cell). Known distances and planes are not written: they
    are the format's.

    Parameters
    ----------
    path : str
        The file to write.
    obs : Observation
        The set (its type: ``obs.kind``), in SI.
    robot : Robot
        The robot (its joint names and types).
    fmt : ObservationFormat, optional
        The file's columns and units (default: m and rad, the default column names).

    Raises
    ------
    ValueError
        When the set is of no type a file holds (a :class:`JointObs`, or a wrapper: a session's or a
        drifting set).

    See Also
    --------
    read_observations : The inverse.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import ObservationFormat, PointObs, read_observations, write_observations
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(4, seed=1), seed=0)
    >>> obs = PointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz)
    >>> fmt = ObservationFormat(length_unit="mm", angle_unit="deg")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "points.csv")
    ...     write_observations(path, obs, robot, fmt)
    ...     with open(path) as f:
    ...         header = f.readline().strip()
    ...     back = read_observations(path, robot, fmt)
    >>> header
    'x,y,z,j1,j2,j3,j4,j5,j6'
    >>> type(back).__name__, bool(np.allclose(back.xyz, obs.xyz, rtol=0.0, atol=1e-9)), back.std
    ('PointObs', True, 1.5e-05)
    """
    lf = unit_factor(fmt.length_unit, "length")
    scale = np.array(joint_factors(robot.joint_types, fmt.length_unit, fmt.angle_unit))
    header = list(fmt.joint_cols or robot.joint_names)
    cells = [[f"{v:.12g}" for v in row] for row in obs.q / scale]
    extra_h, extra = _columns_of(obs, fmt, lf)
    lines = [",".join(extra_h + header)] + [",".join(e + c) for e, c in zip(extra, cells)]
    write_text_atomic(path, "\n".join(lines) + "\n")


def _columns_of(obs: Observation, fmt: ObservationFormat, lf: float) -> tuple[list[str], list[list[str]]]:
    """The type's own columns (before the joints) and their cells, per sample."""
    num = lambda a: [["" if not np.isfinite(v) else f"{v:.12g}" for v in row] for row in a]  # noqa: E731
    if isinstance(obs, (PointObs, PoseObs)):
        values = obs.xyz / lf
        header = list(fmt.xyz_cols)
        if isinstance(obs, PoseObs):
            values = np.column_stack([values, from_matrices(obs.R, fmt.orientation)])
            header += list(fmt.rot_cols or default_columns(fmt.orientation))
        return header, num(values)
    if isinstance(obs, MarkersObs):
        return [f"{m}.{a}" for m in obs.names for a in "xyz"], num(obs.xyz.reshape(len(obs.q), -1) / lf)
    if not isinstance(obs, (SamePointObs, PlaneObs)):
        raise ValueError(f"cannot write observations of the type {obs.kind}")
    if isinstance(obs, SamePointObs) and obs.group is not None:
        labels = [lab.split("/", 1)[1] for lab in obs.labels]
        return [fmt.group_col or "placement", fmt.label], [[g, lab] for g, lab in zip(obs.group, labels)]
    return [fmt.label], [[lab] for lab in obs.labels]


SETUP = {"point": "none (the measurement frame is the robot's base frame, fitted)",
         "pose": "target.rx, target.ry, target.rz: the target frame's orientation on the flange (its origin is the "
                 "tool point); the measurement frame is the robot's base frame",
         "markers": "marker[NAME].x/y/z: each marker's point on the flange (the tool point is then not seen)",
         "same-point": "point[LABEL].x/y/z: each socket's position (the base is not seen)",
         "plane": "plane[LABEL].a/b/c for each plane not given with --plane (tilt in rad, offset in m)"}
SCALE = {"point": "yes", "pose": "yes", "markers": "yes",
         "same-point": "only with a known distance (--distance): without, the fit is refused",
         "plane": "only with two known parallel planes at different offsets (--plane, e.g. a table and a gauge-block "
                  "step): without, the fit is refused"}


def describe(robot: Robot, fmt: ObservationFormat) -> list[str]:
    """What a file of a type must hold for a robot, and what the fit adds.

    Parameters
    ----------
    robot : Robot
        The robot (its joint names).
    fmt : ObservationFormat
        The file's type, columns and units.

    Returns
    -------
    list of str
        Four lines: the columns, the set-up parameters fitted with the robot, whether the type fixes the
        length scale, and the σ used.

    Examples
    --------
    >>> import kincal
    >>> from kincal.observe import ObservationFormat, describe
    >>> for line in describe(kincal.load_robot("ur5"), ObservationFormat(kind="pose", angle_unit="deg")):
    ...     print(line)
    pose files: columns j1, j2, j3, j4, j5, j6 (deg / m) and x, y, z, qw, qx, qy, qz (quat-wxyz)
    set-up parameters fitted with the robot: target.rx, target.ry, target.rz: the target frame's orientation on
    the flange (its origin is the tool point); the measurement frame is the robot's base frame
    fixes the length scale: yes
    σ used: 0.1 mm, 1 mrad (--std-pos, --std-rot)
    """
    joints = ", ".join(fmt.joint_cols or robot.joint_names)
    own = {"point": ", ".join(fmt.xyz_cols), "pose": ", ".join(list(fmt.xyz_cols) + list(
               fmt.rot_cols or default_columns(fmt.orientation))) + f" ({fmt.orientation})",
           "markers": (", ".join(f"{m}.x, {m}.y, {m}.z" for m in fmt.markers) if fmt.markers else
                       "NAME.x, NAME.y, NAME.z per marker") + " (empty: not seen)",
           "same-point": f"{fmt.label}" + (f", {fmt.group_col}" if fmt.group_col else " (and a group column for "
                                                                                     "plate placements)"),
           "plane": fmt.label}[fmt.kind]
    pos, rot = fmt.std()
    sigma = f"{pos * 1e3:g} mm" + (f", {rot * 1e3:g} mrad" if rot else "")
    flags = ("per axis: --std-cols, else calibrate --tracker-noise" if fmt.kind == "point" else
             "--std-pos, --std-rot" if rot else "--std-pos")
    return [f"{fmt.kind} files: columns {joints} ({fmt.angle_unit} / {fmt.length_unit}) and {own}",
            f"set-up parameters fitted with the robot: {SETUP[fmt.kind]}",
            f"fixes the length scale: {SCALE[fmt.kind]}",
            f"σ used: {sigma} ({flags})"]
