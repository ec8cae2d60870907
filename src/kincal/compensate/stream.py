"""Compensation of a targets file of any length: read, solved, checked and written block by block
(about 4 MB of text at a time, so memory stays bounded), in worker processes when the file has
several blocks, while the next blocks are read.

Each target's command depends on its own row only, a path's continuity check carries the previous
block's last row over, and the blocks are written in their order: the output does not depend on the
number of workers. The orientation convention is checked on the file's first rows; everything else
(reach, limits, branch, model residual, orientation, TCP/frame mismatch, continuity) on every row.
"""
from __future__ import annotations

import dataclasses
import os
import sys
from collections import deque
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from .._atomic import AtomicFile
from .._csv import BLOCK_BYTES, Block, Stream, check_once, check_present, open_stream
from .._frozen import freeze_arrays
from .._memory import keep_freed_memory
from .._threads import blas_threads
from ..analysis.uncertainty import ModelUncertainty, envelope_warning, extrapolation_warning
from ..errors import MeasurementError, ModelError
from ..io.commands import CommandColumns
from ..io.measurements import _file_scales, _joint_columns
from ..models.unit_checks import SPREAD_RATIO, check_degrees, check_radians, check_spread
from ..models.robot import Robot
from ..observe.files import check_pose_columns
from ..observe.orientation import convention_check, default_columns, from_matrices, position_frame, to_matrices
from ..units import joint_units
from .commands import compensate, path_checked, refuse_covariates, uncontrolled_warning

CONVENTION_ROWS = 500  # the orientation convention is judged on the file's first rows
IN_FLIGHT = 2  # blocks queued per worker


@dataclass(frozen=True)
class TargetsFormat:
    """The columns of a targets file and their units.

    Parameters
    ----------
    pose : bool, optional
        The targets are full poses: the file has orientation columns too (default False: positions).
    joint_cols : tuple of str, optional
        The columns of the nominal commands, one per joint (default: the robot's joint names).
    xyz_cols : tuple of str, optional
        The columns of the target position (default ("x", "y", "z")).
    orientation : str, optional
        The orientation convention of pose targets: "quat-wxyz" (the default), "quat-xyzw", "matrix",
        "rotvec", "rotvec-deg" or ``"euler-<axes>-<intrinsic|extrinsic>-<deg|rad>"``.
    rot_cols : tuple of str, optional
        The orientation columns (default: the convention's, :attr:`orientation_cols`).
    length_unit : str, optional
        The unit of the positions and prismatic joints: "m" (the default), "mm" or "um".
    angle_unit : str, optional
        The unit of the revolute joints: "rad", "deg" or "rev" (default None: "rad", and a message about the values
        in another unit says none was given; ``angle_default`` records it).

    Raises
    ------
    ValueError
        When a unit or the orientation convention is unknown, or ``rot_cols`` does not fit the convention.

    Examples
    --------
    >>> from kincal.compensate import TargetsFormat
    >>> TargetsFormat(pose=True).orientation_cols
    ('qw', 'qx', 'qy', 'qz')
    >>> TargetsFormat(pose=True, orientation="rotvec", length_unit="mm").orientation_cols
    ('rx', 'ry', 'rz')
    >>> TargetsFormat(length_unit="furlong")
    Traceback (most recent call last):
    ...
    ValueError: unknown length unit 'furlong'; use one of m, mm, um
    """

    pose: bool = False
    joint_cols: tuple[str, ...] | None = None
    xyz_cols: tuple[str, ...] = ("x", "y", "z")
    orientation: str = "quat-wxyz"
    rot_cols: tuple[str, ...] | None = None
    length_unit: str = "m"
    angle_unit: str = None  # type: ignore[assignment]  # None: "rad", not given (__post_init__ sets it)
    angle_default: bool = field(init=False, default=False)  # no angle unit was given: "rad" is the default

    def __post_init__(self) -> None:
        if self.angle_unit is None:  # frozen: set once, here
            object.__setattr__(self, "angle_unit", "rad")
            object.__setattr__(self, "angle_default", True)
        check_pose_columns(self.orientation, self.length_unit, self.angle_unit, self.xyz_cols, self.rot_cols)

    @property
    def orientation_cols(self) -> tuple[str, ...]:
        """The orientation columns: ``rot_cols``, or the convention's."""
        return tuple(self.rot_cols or default_columns(self.orientation))


@dataclass(frozen=True)
class StreamJob:
    """What to do with every target of a targets file.

    Parameters
    ----------
    robot : Robot
        The calibrated model (where the robot really goes), in the targets' frame (:func:`command_models`).
    nominal : Robot or None
        The controller's model, same frame and TCP (None: no set-up check, no orientation change).
    targets : TargetsFormat, optional
        The file's columns and units (default: joints by the robot's names, x, y, z; m and rad).
    uncertainty : ModelUncertainty, optional
        The model's uncertainty: the predicted σ of every accepted command is summed up.
    kind : str, optional
        What to write: "joints" (the corrected commands, the default) or "cartesian" (the filtered poses to
        send a controller moving with ``nominal``; needs pose targets).
    path : bool, optional
        The rows are consecutive targets of one path: continuity is checked (:func:`path_checked`).
    orientation : Robot or None, optional
        For pose targets, the model whose flange is turned to the target rotations (default: ``robot``); the
        nominal model when the calibration measured no orientation (:func:`compensate_poses`).
    body : ndarray, shape (3, 3), optional
        For pose targets that are poses of the measured body (a 6-D probe's, in the measurement frame): its
        rotation on the flange (the calibration's ``target_rotation``); the flange's target rotation is then
        R · bodyᵀ (default None: the target rotations are the flange's).
    measured : ndarray, shape (3,), optional
        With ``orientation``: the point the calibration measured, m in the flange frame; ``robot``'s position is
        trusted there and the TCP carried on from it by ``orientation``'s turn (:func:`compensate_poses`; default:
        the TCP itself).

    Raises
    ------
    ValueError
        When ``kind`` is neither, or "cartesian" without pose targets and a nominal model, or ``body`` is not a
        rotation or is given for position targets.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import StreamJob, TargetsFormat
    >>> nominal = kincal.load_robot("ur5")
    >>> job = StreamJob(kincal.perturb(nominal, seed=1), nominal, TargetsFormat(length_unit="mm", angle_unit="deg"))
    >>> job.needs_joints
    True
    >>> print(job.layout("commands.csv").header(), end="")
    row,j1,j2,j3,j4,j5,j6,x,y,z,d_j1,d_j2,d_j3,d_j4,d_j5,d_j6,orientation_change_mrad
    >>> StreamJob(nominal, nominal, kind="cartesian")
    Traceback (most recent call last):
    ...
    ValueError: kind='cartesian' (CLI: --output-kind cartesian) writes filtered poses: give targets with orientation
    (TargetsFormat(pose=True); CLI: --pose)
    """

    robot: Robot
    nominal: Robot | None
    targets: TargetsFormat = TargetsFormat()
    uncertainty: ModelUncertainty | None = None
    kind: str = "joints"
    path: bool = False
    orientation: Robot | None = None
    body: np.ndarray | None = None
    measured: np.ndarray | None = None

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place
        if self.body is not None and (not self.targets.pose or np.shape(self.body) != (3, 3) or not np.allclose(
                np.asarray(self.body) @ np.asarray(self.body).T, np.eye(3), atol=1e-9)):
            raise ValueError("body: a rotation (3, 3) of the measured body on the flange, for pose targets")
        if self.kind not in ("joints", "cartesian"):
            raise ValueError(f"output kind '{self.kind}': use joints or cartesian")
        if self.kind == "cartesian" and not (self.targets.pose and self.nominal is not None):
            raise ValueError("kind='cartesian' (CLI: --output-kind cartesian) writes filtered poses: give targets "
                             "with orientation (TargetsFormat(pose=True); CLI: --pose)")

    @property
    def needs_joints(self) -> bool:
        """True when the file must give the nominal joints (pose targets, or a robot without an inverse)."""
        if self.robot.has_pose_inverse:  # a hexapod: its legs follow from the pose alone
            return False
        return self.targets.pose or not self.robot.has_inverse

    def layout(self, dst: str) -> CommandColumns:
        """The commands file's layout at ``dst`` (its joint columns, one per joint, and units checked)."""
        t, robot = self.targets, self.robot
        change = not t.pose and not robot.has_inverse and self.nominal is not None and robot.has_tool_point
        cols = tuple(_joint_columns(dst, robot, t.joint_cols))
        scale, lf = _file_scales(robot.joint_types, t.length_unit, t.angle_unit, dst)
        return CommandColumns(self.kind, cols, scale, lf, self.needs_joints, change,
                              t.orientation_cols if self.kind == "cartesian" else ())


@dataclass(frozen=True)
class _Part:
    """One block's outcome: its output lines and what the summary needs (the σ of accepted rows; the
    rows, σ and joints of those that extrapolate or leave the training envelope; the largest values)."""

    text: str
    n: int
    n_ok: int
    problems: tuple[str, ...]
    sigma: np.ndarray
    extrapolated: tuple[np.ndarray, np.ndarray, np.ndarray]
    outside: tuple[np.ndarray, np.ndarray]
    largest: dict
    method: str
    iterations: int
    end: int

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place


@dataclass(frozen=True)
class StreamResult:
    """The summary of a streamed compensation (:func:`compensate_file`).

    Parameters
    ----------
    targets : int
        Targets read.
    accepted : int
        Targets whose commands passed every check.
    written : bool
        Whether the commands file was written.
    problems : tuple of str
        The refused rows' reasons ("row r: why"), each message once.
    warnings : tuple of str
        Warnings: joint columns the file has that are not read (a parallel robot's joints follow from each target
        alone), where the model extrapolates or leaves its data's joint envelope, rotations a robot with fewer than
        six joints does not control.
    method : str
        How the commands were found (:attr:`Compensation.method`).
    iterations : int
        The most iterations of any block.
    largest : dict, optional
        The largest value over the accepted rows, by name: "residual" (m), "rotation_residual" (rad),
        "orientation_change" (rad) and "change" (per joint, list: rad or m).
    sigma_median : float, optional
        The median predicted σ of the accepted commands, m (None without the model's uncertainty).
    sigma_max : float, optional
        The largest predicted σ, m (None without the model's uncertainty).

    Examples
    --------
    See :func:`compensate_file`; the summary as plain JSON values:

    >>> from kincal.compensate import StreamResult
    >>> res = StreamResult(3, 2, False, ("row 4: ...",), (), "damped least squares", 3, {"residual": 1e-12})
    >>> res.all_ok
    False
    >>> res.to_dict()["written"], res.to_dict()["max_residual"]
    (0, 1e-12)
    """

    targets: int
    accepted: int
    written: bool
    problems: tuple[str, ...]
    warnings: tuple[str, ...]
    method: str
    iterations: int
    largest: dict = field(default_factory=dict)
    sigma_median: float | None = None
    sigma_max: float | None = None

    @property
    def all_ok(self) -> bool:
        """True when every target was accepted."""
        return self.accepted == self.targets

    def to_dict(self) -> dict:
        """The summary as plain JSON values (``written``: the commands written, 0 when none; ``max_<name>``)."""
        return {"targets": self.targets, "accepted": self.accepted, "written": self.accepted if self.written else 0,
                "problems": list(self.problems), "warnings": list(self.warnings), "method": self.method,
                "iterations": self.iterations, **{f"max_{k}": v for k, v in self.largest.items()},
                "predicted_sigma": None if self.sigma_median is None else
                {"median": self.sigma_median, "max": self.sigma_max}}


def compensate_file(job: StreamJob, src: str, dst: str, *, skip_unreachable: bool = False, workers: int | None = None,
                    progress: Callable[[int, int], None] | None = None, block_bytes: int = BLOCK_BYTES) -> StreamResult:
    """Compensate every target of a CSV targets file and write the commands, block by block.

    Never half a file: ``dst`` is written only when every row passes, or with ``skip_unreachable`` the rows
    that pass. Each row is checked like a target of :func:`compensate` (reach, limits, branch, model
    residual, orientation, TCP/frame mismatch, and continuity for a path); the units and the orientation
    convention are checked on the file's first rows (module docstring). For a file of several blocks the
    calling process, like the workers, keeps freed memory for the next block (glibc's thresholds,
    :mod:`kincal._memory`).

    Parameters
    ----------
    job : StreamJob
        The models, the file's columns and units, and what to write.
    src : str
        The targets file (CSV with a header line).
    dst : str
        The commands file to write (atomically): a row column (the targets' line numbers), then the
        commands and targets (or the filtered poses) in the targets' units.
    skip_unreachable : bool, optional
        Write the rows that pass even when some are refused (default False: nothing is written then).
    workers : int, optional
        Processes sharing the blocks of a file longer than one block (default: one per core); the output
        does not depend on them.
    progress : callable, optional
        ``progress(bytes done, bytes total)``, called after each block.
    block_bytes : int, optional
        The text of one block, bytes (default about 4 MB).

    Returns
    -------
    StreamResult
        Targets read and accepted, whether the file was written, the refused rows' reasons, warnings and the
        largest values.

    Raises
    ------
    MeasurementError
        When the file has no data rows, misses a column the job reads or names one twice, or its units or
        orientation convention do not fit the robot.

    Examples
    --------
    Four targets of a UR5 whose nominal commands reach them, one of them moved 50 mm (a target that does not
    belong to its joints), written into a temporary folder:

    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import StreamJob, compensate_file
    >>> nominal = kincal.load_robot("ur5")
    >>> job = StreamJob(kincal.perturb(nominal, seed=1), nominal)
    >>> q0 = nominal.sample_joints(4, seed=2)
    >>> xyz = nominal.forward(q0)
    >>> xyz[2, 2] += 0.05
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     src, dst = os.path.join(folder, "targets.csv"), os.path.join(folder, "commands.csv")
    ...     np.savetxt(src, np.column_stack([q0, xyz]), delimiter=",", header="j1,j2,j3,j4,j5,j6,x,y,z",
    ...                comments="")
    ...     refused = compensate_file(job, src, dst)
    ...     written = os.path.exists(dst)
    ...     res = compensate_file(job, src, dst, skip_unreachable=True)
    ...     with open(dst) as f:
    ...         lines = f.read().splitlines()
    >>> refused.accepted, refused.written, written
    (3, False, False)
    >>> print(refused.problems[0])
    row 4: the nominal command lands 50.000 mm from the target through the nominal model: the joint values and
    the target do not belong together (units, column order, TCP or frame?)
    >>> res.targets, res.accepted, res.written
    (4, 3, True)
    >>> lines[0]
    'row,j1,j2,j3,j4,j5,j6,x,y,z,d_j1,d_j2,d_j3,d_j4,d_j5,d_j6,orientation_change_mrad'
    >>> [line.split(",")[0] for line in lines[1:]]  # the targets' lines in the file read
    ['2', '3', '5']
    >>> round(res.largest["orientation_change"] * 1e3, 2)  # mrad
    3.36
    """
    refuse_covariates(job.robot)  # before reading: the targets' columns are the joints'
    stream = open_stream(src, block_bytes)
    _check_columns(job, stream)
    unread = _unread_joints(job, stream)
    if stream.size - stream.offset > block_bytes:
        keep_freed_memory()  # a long file: this process reads and writes every block
    layout = job.layout(dst)
    parts = []
    with AtomicFile(dst) as out:
        out.write(layout.header())
        for part in _parts(job, stream, layout, _workers(workers, stream)):
            out.write(part.text)
            parts.append(dataclasses.replace(part, text=""))  # the summary only: the text is written
            if progress:
                progress(part.end, stream.size)
        n, n_ok = sum(p.n for p in parts), sum(p.n_ok for p in parts)
        written = n > 0 and (n_ok == n or (skip_unreachable and n_ok > 0))
        if written:
            out.keep()
    if n == 0:
        raise MeasurementError(f"{src}: no data rows after the header")
    return _result(job, parts, written, unread)


def _unread_joints(job: StreamJob, stream: Stream) -> str:
    """What to say of joint columns the file has but the job does not read ('' when none): a parallel robot's joints
    follow from each target alone, so the file's are neither a start nor compared with the commands."""
    header = stream.header
    cols = [c for c in (job.targets.joint_cols or job.robot.default_columns(header)) if c in header]
    if job.needs_joints or not cols:
        return ""
    return (f"the file's joint columns {', '.join(cols)} are not read: {job.robot.name}'s joints follow from each "
            f"target alone (closed form), so the commands written are the model's for the targets, not these values "
            f"corrected")


def _check_columns(job: StreamJob, stream: Stream) -> None:
    """Every column the job reads is in the header once and read once, else one line saying which."""
    t, robot, path, header = job.targets, job.robot, stream.path, stream.header
    joints = list(t.joint_cols or robot.joint_names) if job.needs_joints else []
    cols = [*joints, *t.xyz_cols, *(t.orientation_cols if t.pose else ())]
    check_once(path, header, cols, "joint, position or orientation")
    if job.needs_joints:
        _joint_columns(path, robot, joints)  # one per joint
        check_present(path, header, joints, "needs the nominal joint values (joint_cols names them; CLI: "
                                                      "--joint-cols)")
    check_present(path, header, t.xyz_cols, "needs the target position columns (xyz_cols; CLI: --xyz-cols)")
    if t.pose:
        rot = t.orientation_cols
        check_present(path, header, rot, f"needs orientation columns {', '.join(rot)} for --orientation "
                                         f"{t.orientation} (other names: rot_cols, CLI: --rot-cols; position only: "
                                         f"pose=False, CLI: leave out --pose)")


def _workers(workers: int | None, stream: Stream) -> int:
    if stream.size - stream.offset <= stream.block_bytes:
        return 1  # one block: no process to start
    if workers is None:
        try:
            workers = len(os.sched_getaffinity(0))  # the cores this process may use
        except AttributeError:  # not on this system
            workers = os.cpu_count() or 1
    return max(1, int(workers))


def _tasks(stream: Stream) -> Iterator[tuple[Block, Block | None, bool, int]]:
    """(block, the previous block's last data line as a block (None for the first), first?, bytes done)."""
    previous = None
    for k, (block, last) in enumerate(stream.blocks()):
        yield block, previous, k == 0, block.offset + block.nbytes
        previous = last


def _parts(job: StreamJob, stream: Stream, layout: CommandColumns, workers: int) -> Iterator[_Part]:
    """The blocks' outcomes in file order: in this process, or from ``workers`` processes with at most
    IN_FLIGHT blocks queued each."""
    if workers <= 1:
        for task in _tasks(stream):
            yield _block(job, stream, layout, *task)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    method = "fork" if sys.platform.startswith("linux") else "spawn"  # fork: no re-import, no __main__ guard needed
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context(method), initializer=_init,
                               initargs=(job, stream, layout))
    try:
        pending: deque = deque()
        for task in _tasks(stream):
            pending.append(pool.submit(_in_worker, *task))
            if len(pending) >= IN_FLIGHT * workers:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


_WORK: tuple[StreamJob, Stream, CommandColumns] | None = None  # a worker's job, set by _init


def _init(job: StreamJob, stream: Stream, layout: CommandColumns) -> None:
    """A worker process: the job once, one BLAS thread (the workers share the cores), freed memory
    kept for the next block, Ctrl-C left to the main process."""
    global _WORK
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the main process's to handle (it stops the pool)
    blas_threads(1)
    keep_freed_memory()
    _WORK = (job, stream, layout)


def _in_worker(block: Block, previous: Block | None, first: bool, end: int) -> _Part:
    assert _WORK is not None  # the pool runs _init in every worker first
    return _block(*_WORK, block, previous, first, end)


def _block(job: StreamJob, stream: Stream, layout: CommandColumns, block: Block, previous: Block | None,
           first: bool, end: int) -> _Part:
    """One block compensated (the previous block's last row first when the rows are a path, to check
    continuity into this block; its own outcome belongs to the previous block)."""
    ctx = job.path and previous is not None
    rows, q0, xyz, R, rot = _read(job, stream, block, previous if ctx else None)
    if first:
        _first_checks(job, stream, rows, q0, xyz, rot)
    comp = compensate(job.robot, xyz, q0, rows=rows, rotations=R, nominal=job.nominal, uncertainty=job.uncertainty,
                      orientation=job.orientation if R is not None else None, measured=job.measured)
    if rot is not None and not comp.all_ok:
        comp = _read_as_degrees(job, stream.path, comp, rows, q0, xyz, rot)
    if job.path and q0 is not None:
        comp = path_checked(job.robot, comp, q0)
    k = 1 if ctx else 0
    problems = tuple(p for p in comp.problems if not (ctx and p.startswith(f"row {rows[0]}: ")))
    return _summary(job, layout, comp, rows[k:], None if q0 is None else q0[k:], xyz[k:], k, problems, end)


def _first_checks(job: StreamJob, stream: Stream, rows, q0, xyz, rot) -> None:
    """On the file's first rows: the units (degrees read as radians and back, positions whose spread
    is not the robot's at the nominal joints: the unit they are really in is named) and the
    orientation convention (another that fits markedly better is named). The spread is first judged by
    the median distance from the median: a few rows far off are refused by row later, not taken for a unit."""
    if q0 is None:
        return
    t, robot, m = job.targets, job.nominal or job.robot, CONVENTION_ROWS
    q0, xyz = q0[:m], xyz[:m]
    check_degrees(stream.path, q0, robot, t.angle_unit, t.angle_default)
    check_radians(stream.path, q0, robot, t.angle_unit)
    size = lambda x: float(np.median(np.linalg.norm(x - np.median(x, axis=0), axis=1)))  # noqa: E731
    p0 = robot.forward(q0)
    if not 1 / SPREAD_RATIO < size(xyz) / max(size(p0), 1e-300) < SPREAD_RATIO:
        check_spread(stream.path, q0, xyz, robot, t.length_unit, t.angle_unit, "target positions")
    if t.pose and job.nominal is not None:
        convention_check(job.nominal.flange_rotation(q0), rot[:m], t.orientation, stream.path, rows[:m],
                         position_frame(p0, xyz))  # (a relabelling of the axes cannot hide in a frame)


def _read_as_degrees(job: StreamJob, path: str, comp, rows: np.ndarray, q0, xyz: np.ndarray, rot: np.ndarray):
    """The compensation with the refused pose targets whose orientation, read as degrees, every check passes saying
    so (a file in degrees declared in radians: angles within 2π pass the reader's own check; such a row is out of
    reach or past the joint limits as read)."""
    name = job.targets.orientation
    other = "rotvec-deg" if name == "rotvec" else f"{name[:-4]}-deg" if name.startswith("euler-") and \
        name.endswith("-rad") else ""
    bad = np.flatnonzero(~comp.ok)
    if not other or not bad.size:
        return comp
    R = to_matrices(rot[bad], other, path, rows[bad])
    R = R if job.body is None else R @ np.asarray(job.body).T
    try:
        again = compensate(job.robot, xyz[bad], None if q0 is None else q0[bad], rows=rows[bad], rotations=R,
                           nominal=job.nominal, orientation=job.orientation, measured=job.measured)
    except ModelError:  # (no reading of the file's: nothing to add)
        return comp
    reached = set(rows[bad][again.ok].tolist())
    hint = (f"; read as degrees its orientation is reached: the angles look like degrees (orientation='{other}'; "
            f"CLI: --orientation {other})")
    return dataclasses.replace(comp, problems=tuple(p + hint if _row_of(p) in {(1, r) for r in reached} else p
                                                    for p in comp.problems))


def _read(job: StreamJob, stream: Stream, block: Block, previous: Block | None):
    """Rows (N,), nominal joints (N, n) rad/m (None when not read), target positions (N, 3) m,
    rotations (N, 3, 3) and the orientation columns as read (None for position targets) of the
    block, after ``previous`` when given."""
    t, robot = job.targets, job.robot
    jcols = list(t.joint_cols or robot.joint_names) if job.needs_joints else []
    cols = jcols + list(t.xyz_cols) + (list(t.orientation_cols) if t.pose else [])
    units = [*(joint_units(robot.joint_types, t.length_unit, t.angle_unit) if jcols else []), *[t.length_unit] * 3,
             *[None] * (len(cols) - len(jcols) - 3)]
    parts = [stream.numbers(b, cols, units) for b in ((previous, block) if previous is not None else (block,))]
    rows, v = (np.concatenate(a) for a in zip(*parts))  # SI (the orientation's values as written)
    n = len(jcols)
    q0 = v[:, :n] if n else None
    xyz = v[:, n:n + 3]
    R = to_matrices(v[:, n + 3:], t.orientation, stream.path, rows) if t.pose else None
    if R is not None and job.body is not None:  # the measured body's rotations: the flange's are R · bodyᵀ
        R = R @ np.asarray(job.body).T
    return rows, q0, xyz, R, (v[:, n + 3:] if t.pose else None)


def _row_of(problem: str) -> tuple[int, int]:
    """Sort key of a problem: messages about every row first, then those of one row by its number."""
    head = problem.split(":", 1)[0]
    return (1, int(head[4:])) if head.startswith("row ") and head[4:].isdigit() else (0, 0)


def _summary(job: StreamJob, layout: CommandColumns, comp, rows, q0, xyz, k: int, problems, end: int) -> _Part:
    """The block's output lines and summary (``k`` leading context rows of ``comp`` dropped)."""
    ok = comp.ok[k:]

    def kept(a):  # the block's accepted rows
        return None if a is None else a[k:][ok]
    q, change = kept(comp.q), kept(comp.orientation_change)
    if job.kind == "cartesian":
        p, Rf = (kept(a) for a in comp.filtered)
        text = layout.text(rows[ok], q, p, rot_values=from_matrices(Rf, job.targets.orientation))
    else:
        oc = np.zeros(0) if change is None and layout.orientation_change else change  # none: nothing was corrected
        text = layout.text(rows[ok], q, xyz[ok], None if q0 is None else q0[ok], oc)
    sigma = np.zeros(0) if comp.predicted_sigma is None else kept(comp.predicted_sigma)
    unc, none = job.uncertainty, np.zeros(len(sigma), bool)
    ext = none if unc is None else unc.extrapolated(sigma)
    out = none if unc is None else unc.outside(q, job.robot.periodic)
    values = (("residual", kept(comp.residual)), ("rotation_residual", kept(comp.rotation_residual)),
              ("orientation_change", change))
    largest = {n: float(v.max()) for n, v in values if v is not None and v.size}
    if q0 is not None and ok.any():
        largest["change"] = np.abs(q - q0[ok]).max(axis=0)
    return _Part(text, len(rows), int(ok.sum()), problems, sigma, (rows[ok][ext], sigma[ext], q[ext]),
                 (rows[ok][out], q[out]), largest, comp.method, comp.iterations, end)


def _result(job: StreamJob, parts: list[_Part], written: bool, unread: str = "") -> StreamResult:
    """The blocks' summaries (at least one) added up, in file order (``unread``: the joint columns not read, said
    first)."""
    sigma = np.concatenate([p.sigma for p in parts])
    largest: dict = {}
    for part in parts:
        for name, v in part.largest.items():
            largest[name] = v if name not in largest else np.maximum(largest[name], v)
    warnings: list[str | None] = [unread]
    unc, robot = job.uncertainty, job.robot
    if unc is not None and sigma.size:
        rows, s, q = (np.concatenate(a) for a in zip(*(p.extrapolated for p in parts)))
        warnings.append(extrapolation_warning(rows, s, unc, q if len(q) else None, robot))
        rows, q = (np.concatenate(a) for a in zip(*(p.outside for p in parts)))
        warnings.append(envelope_warning(rows, q.reshape(-1, robot.n_joints), robot, unc)[1])
    if job.targets.pose and robot.n_joints < 6 and "rotation_residual" in largest:
        warnings.append(uncontrolled_warning(robot, largest["rotation_residual"]))
    problems = dict.fromkeys(sorted((p for part in parts for p in part.problems), key=_row_of))  # a block-wide
    # message once; the rows in file order (each check names its rows in turn)
    return StreamResult(sum(p.n for p in parts), sum(p.n_ok for p in parts), written, tuple(problems),
                        tuple(w for w in warnings if w), parts[-1].method, max(p.iterations for p in parts),
                        {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in largest.items()},
                        float(np.median(sigma)) if sigma.size else None, float(sigma.max()) if sigma.size else None)
