"""Differential diagnosis of a refused or suspect calibration: which common mistake explains the data.

A fit whose verdict says the data and the robot disagree (implausible corrections, a residual far above
the instrument noise, outliers) gets the cheap candidate causes tried one by one, and
the one that explains the data is named with its fix and the figure that shows it ("without row 39
the residual σ falls from 1.18 mm to 0.011 mm"). Each candidate is a changed copy of the data or of the
fit's set-up, listed in this canonical order (ties go to the earlier one, :mod:`kincal.ties`):

1. length unit: the positions are in another unit (m, mm, µm, cm, inch) than the declared one;
2. angle unit: all revolute joint columns, or one of them, are in the other angle unit;
3. joint columns: one negated, one offset by +90°, −90° or 180°, two swapped;
4. mirrored positions: a left-handed measurement frame (two axes swapped, or one negated: with the
   frame fitted these are one and the same mistake);
5. rows shifted: each position belongs to the joints one row above or below;
6. the robot file: a bundled robot with the same joint types fits the data, whatever its model (a URDF chain is
   compared with the bundled DH robots);
7. the frame: ``base="fixed"`` on data measured in another frame (a tracker's);
8. the tool point: not estimated, and mounted elsewhere than declared;
9. a frame that jumps inside the file (two set-ups, a bumped tracker): the split
   (:func:`kincal.models.unit_checks.frame_jump` on the fitted model) fitted as two sessions; several files
   fitted in one frame (``--same-frame``; points, 6-D poses or markers, by their positions): each in a frame of
   its own;
10. a few bad poses: the rows a robust refit puts beyond ``outlier_z`` robust σ, left out.

Kinds without measured positions to screen (sockets, planes, a joint-space residual of poses) get the last
candidate alone, on the fit itself (:func:`diagnose_samples`): the samples a robust refit of the observations puts
beyond the outlier limit, left out, judged by the whitened residual RMS with the same rule.

Two stages keep it cheap. Candidates 1–6 change the data; each is screened by registering the
nominal model to it (measurement frame and tool point only, ~10 ms for 80 poses). The MAX_FULL best
screens that beat the data as given, and candidates 7–10, then get a full calibration with the user's
options. A candidate explains the data when its verdict is better than the original one with a
residual σ no more than NOT_WORSE times the original, or when its σ falls below EXPLAIN_RATIO times
the original; those that do are ranked by verdict, then σ. The trials run Levenberg–Marquardt: a particle
swarm's fit (``method="pso"``) is replaced as "the original" by Levenberg–Marquardt's fit of the unchanged data
(a better optimum is not a data mistake), and that refit is itself a cause when it explains the swarm's fit (the
swarm stopped short of the best fit).
"""
from __future__ import annotations

import functools
import itertools
import math
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..errors import KincalError
from .._csv import listed
from ..io.measurements import Measurements
from ..models.unit_checks import frame_jump
from ..models.robot import TOOL_NAMES, Robot
from ..units import ANGLE_UNITS, LENGTH_UNITS, MM, OTHER_LENGTHS
from ..ties import order_with_ties
from .options import FitOptions
from .verdict import MAX_OUTLIER_SHARE, STATUSES, Thresholds, robust_z

if TYPE_CHECKING:  # the result holds a Diagnosis: result imports this module
    from .result import CalibrationResult

EXPLAIN_RATIO = 0.5  # a candidate whose fit leaves less than half the residual σ explains the data
NOT_WORSE = 2.0  # ... or one with a better verdict and a residual σ at most this many times the original
MAX_FULL = 3  # screened data changes that get a full calibration
TRIGGERS = ("implausible-correction", "large-correction", "residual", "outliers", "frame-jump")
SCREEN_POSES = 200  # the screen registers the nominal model to the first this many poses
SCREEN_ITERATIONS = 8  # ... in this many steps: enough to tell a fitting change from the rest


@dataclass(frozen=True)
class Cause:
    """One candidate mistake: a short code, what went wrong, what to do, and — once tried — the
    residual σ per axis (m) and the verdict of the fit with the mistake undone."""

    code: str
    cause: str
    fix: str
    sigma: float = math.nan
    status: str = ""
    rows: tuple[int, ...] = ()

    def to_dict(self) -> dict:
        return {**asdict(self), "rows": list(self.rows)}


@dataclass(frozen=True)
class Diagnosis:
    """The fit as given (σ per axis, m; verdict) and the causes that explain it, best first; ``whitened``: the σ
    are whitened residual RMS (1 when the stated σ are right), of the fit itself (:func:`diagnose_samples`)."""

    sigma: float
    status: str
    found: tuple[Cause, ...]
    tried: int
    whitened: bool = False

    @property
    def best(self) -> Cause | None:
        return self.found[0] if self.found else None

    def message(self) -> str:
        """One sentence for the verdict: the likely cause with its figure and fix, or what was tried."""
        c = self.best
        if c is None:
            return (f"none of the {self.tried} common input mistakes kincal tried (joint columns, position frame, "
                    f"rows, tool point, bad poses, robot file) explains the data better")
        if self.whitened:
            what, before, after = "whitened residual RMS", f"{self.sigma:.3g}", f"{c.sigma:.3g} (1 when the stated σ " \
                                                                                  f"are right)"
        else:
            what, before, after = "residual σ per axis", f"{self.sigma * MM:.4g} mm", f"{c.sigma * MM:.4g} mm"
        if c.sigma < EXPLAIN_RATIO * self.sigma:
            figure = f"the {what} falls from {before} to {after}"
        else:
            figure = f"the verdict becomes {c.status} ({what} {after})"
        return f"likely cause: {c.cause}; with that undone {figure}. Fix: {c.fix}"

    def to_dict(self) -> dict:
        return {"sigma": self.sigma, "status": self.status, "tried": self.tried, "whitened": self.whitened,
                "found": [c.to_dict() for c in self.found]}


Change = Callable[[Robot, Measurements, FitOptions], tuple[Robot, "Measurements | list[Measurements]", FitOptions]]


def _data(change: Callable[..., Measurements], **bound) -> Change:
    """The data changed to ``change(meas, **bound)``."""
    return lambda robot, meas, options: (robot, change(meas, **bound), options)


def _columns(cols: list[int], f: Callable[..., np.ndarray], **bound) -> Change:
    """The joint columns ``cols`` replaced by ``f(columns, **bound)``."""
    def changed(m: Measurements) -> Measurements:
        q = m.q.copy()
        q[:, cols] = f(m.q[:, cols], **bound)
        return replace(m, q=q)
    return _data(changed)


def _other_robot(other: Robot) -> Change:
    """The fit with ``other`` in place of the robot; parameter names ``other`` lacks (another class's: a URDF chain's
    against a DH one's) give way to its identifiable set."""
    def change(r: Robot, m: Measurements, o: FitOptions) -> tuple[Robot, Measurements, FitOptions]:
        names = () if o.names == "auto" else o.names
        if set(names) | set(o.keep) <= set(other.params.names):
            return other, m, o
        return other, m, o.replace(names="auto", keep=())
    return change


def _length_units(meas: Measurements) -> list[tuple[Cause, Change]]:
    table = {**LENGTH_UNITS, **OTHER_LENGTHS}
    declared = meas.units[0] if meas.units else "m"
    return [(Cause("length-unit", f"the positions are in {name}, read as {declared}",
                   f"read them with --length-unit {name}" if name in LENGTH_UNITS else
                   f"convert them to mm (x{f / 1e-3:g}) and read them with --length-unit mm"),
             _data(lambda m, k: replace(m, xyz=m.xyz * k), k=f / table[declared]))
            for name, f in table.items() if name != declared]


def _angle_units(robot: Robot, meas: Measurements) -> list[tuple[Cause, Change]]:
    declared = meas.units[1] if meas.units else "rad"
    other = "rad" if declared == "deg" else "deg"
    k = ANGLE_UNITS[other] / ANGLE_UNITS[declared]
    rev = [j for j, t in enumerate(robot.joint_types) if t == "revolute"]
    if not rev:
        return []
    out = [(Cause("angle-unit", f"the joint values are in {other}, read as {declared}",
                  f"read them with --angle-unit {other}"), _columns(rev, lambda c: c * k))]
    for j in rev:
        name = robot.joint_names[j]
        out.append((Cause("joint-unit", f"{name}'s column is in {other}, the other joints' in {declared}",
                          f"convert {name}'s column to {declared}"), _columns([j], lambda c: c * k)))
    return out


def _joint_columns(robot: Robot) -> list[tuple[Cause, Change]]:
    names = robot.joint_names
    out = [(Cause("joint-sign", f"{name} counts the other way (its column is negated)",
                  f"negate {name}'s column, or check its axis direction in the robot file"), _columns([j], np.negative))
           for j, name in enumerate(names)]
    out += [(Cause("joint-zero", f"{name}'s column is {deg:g} deg short of the robot file's joint angle "
                                 f"(the controller's zero differs)",
                   f"add {deg:g} deg to {name}'s column, or move the joint's zero in the robot file"),
             _columns([j], lambda c, rad: c + rad, rad=np.deg2rad(deg)))
            for j, name in enumerate(names) if robot.joint_types[j] == "revolute" for deg in (90.0, -90.0, 180.0)]
    for a, b in itertools.combinations(range(len(names)), 2):
        order = [b if i == a else a if i == b else i for i in range(len(names))]
        out.append((Cause("joint-order", f"the columns of {names[a]} and {names[b]} are swapped",
                          "swap them (give --joint-cols in the robot's joint order)"),
                    _data(lambda m, order: replace(m, q=m.q[:, order]), order=order)))
    return out


def _frame_and_rows() -> list[tuple[Cause, Change]]:
    return [
        (Cause("mirrored", "the positions are mirrored (a left-handed measurement frame: two axes swapped or one "
                           "negated)", "check the instrument's axis order and signs; kincal needs a right-handed "
                                       "frame"), _data(lambda m: replace(m, xyz=m.xyz * [1.0, 1.0, -1.0]))),
        (Cause("row-shift", "each position is one row late (it belongs to the joints one row above)",
               "move the position columns up by one row (check the export's timing)"),
         _data(lambda m: replace(m.subset(np.arange(1, len(m))), q=m.q[:-1]))),
        (Cause("row-shift", "each position is one row early (it belongs to the joints one row below)",
               "move the position columns down by one row (check the export's timing)"),
         _data(lambda m: replace(m.subset(np.arange(len(m) - 1)), q=m.q[1:]))),
    ]


@functools.lru_cache(maxsize=None)
def data_changes(robot: Robot, meas: Measurements) -> list[tuple[Cause, Change]]:
    """The candidate mistakes in a file's columns and rows, each with its change of the data (in the canonical
    order): an angle unit, a joint column negated, offset or swapped with another, the positions mirrored, the
    rows shifted; what a model with fixed kinematics (a held-out file) can be judged against."""
    return _angle_units(robot, meas) + _joint_columns(robot) + _frame_and_rows()


def input_changes(robot: Robot, meas: Measurements) -> list[tuple[Cause, Change]]:
    """The candidate input mistakes of a file judged against a model with fixed kinematics (a check): the positions'
    length unit (:func:`_length_units`) and :func:`data_changes`, in the canonical order."""
    return _length_units(meas) + data_changes(robot, meas)


def _bundled(name: str) -> Robot:
    from ..models.yaml_io import load_robot
    return load_robot(name)


def _robot_files(robot: Robot) -> list[tuple[Cause, Change]]:
    from ..models.yaml_io import bundled_robots
    out: list[tuple[Cause, Change]] = []
    for name in bundled_robots():
        other = _bundled(name)
        if name == robot.name or other.joint_types != robot.joint_types:  # by kinematics, whatever the class
            continue
        if robot.has_tool_point and other.has_tool_point:
            other = other.with_tool_point(robot.tool_point())
        out.append((Cause("robot-file", f"the data belong to another robot: they fit the bundled '{name}'",
                          f"calibrate with robot '{name}', or check the robot file's lengths"),
                    _other_robot(other)))
    return out


def _setups(robot: Robot, options: FitOptions) -> list[tuple[Cause, Change]]:
    """Changes of the fit's set-up (full calibration only): the frame, the tool point."""
    out: list[tuple[Cause, Change]] = []
    if options.base == "fixed" and robot.base_params():
        out.append((Cause("frame", "the positions are not in the robot's base frame (--base fixed on data measured "
                                   "in the instrument's own frame)", "leave out --base fixed: the measurement frame "
                                                                     "is then fitted"),
                    lambda r, m, o: (r, m, o.replace(base="estimate"))))
    tool = [n for n in TOOL_NAMES if n in robot.params.names]
    if tool and options.names != "auto" and not set(tool) <= set(options.names):
        out.append((Cause("tool-point", "the target is not at the declared tool point",
                          "estimate it (add tool.x,tool.y,tool.z to --params) or declare it with --tool"),
                    lambda r, m, o: (r, m, o.replace(names=tuple(o.names) + tuple(tool)))))
    return out


def _jump(res: CalibrationResult) -> list[tuple[Cause, Change]]:
    """A frame that jumps inside one file: the file as two sessions, split where one rigid frame each fits the
    fitted model best (tried whatever the split leaves: a fit the jump has bent hides part of it, and the
    nominal model's own error the rest; the trial fit decides)."""
    meas = res.measurements
    found = frame_jump(meas.xyz, res.robot.forward(meas.q), ratio=1.0) if meas.session is None else None
    if found is None:
        return []
    k, row = found[0], int(meas.rows[found[0]])
    parts = [meas.subset(np.arange(k)), meas.subset(np.arange(k, len(meas)))]
    return [(Cause("frame-jump", f"the measurement frame jumps at row {row} (two set-ups in one file, or the tracker "
                                 f"or camera was moved or bumped there)", f"split the file at row {row}: one file per session "
                                                                f"(each gets its own frame)", rows=(row,)),
             lambda r, m, o: (r, parts, o))]


def _sessions(res: CalibrationResult) -> list[tuple[Cause, Change]]:
    """Several files fitted in one frame (--same-frame): each in a frame of its own (the tracker moved between
    them)."""
    meas = res.measurements
    labels = list(dict.fromkeys(meas.session)) if meas.session is not None else []
    if len(labels) < 2:
        return []
    parts = [meas.subset(np.flatnonzero(meas.session == s)) for s in labels]
    return [(Cause("same-frame", "the files were not measured in one frame (the tracker or camera moved between "
                                 "them)", "fit them as sessions, each in its own measurement frame: "
                                               "kincal.identify.calibrate_sessions(robot, sessions), one "
                                               "Measurements per file (CLI: leave out --same-frame)"),
             lambda r, m, o: (r, parts, o))]


def outlier_poses(robot: Robot, meas: Measurements, options: FitOptions) -> np.ndarray:
    """Indices into ``meas`` of the poses a robust (Huber) refit puts more than ``outlier_z`` robust σ
    off (:func:`few_bad` of their error norms). Indices, not file rows: several sessions repeat their files' line
    numbers."""
    from .calibrate import calibrate
    robust = calibrate(robot, meas, _quiet(options).replace(loss="huber", method="lm", f_scale=None))
    return few_bad(np.linalg.norm(robust.residuals, axis=1), options.thresholds)


def few_bad(norms: np.ndarray, thresholds: Thresholds | None = None, dim: int = 3) -> np.ndarray:
    """Indices of the samples whose error ``norms`` (N,) of ``dim``-D residual blocks lie beyond
    ``thresholds.outlier_limit`` robust σ (:func:`kincal.identify.verdict.robust_z`), when they are a few: at most
    MAX_OUTLIER_SHARE of the samples (none when more are that far off: then it is not a few bad samples).

    Examples
    --------
    >>> few_bad(np.array([1.0, 1.1, 0.9, 1.05, 0.95, 1.0, 1.02, 0.98, 1.01, 0.99, 40.0])).tolist()
    [10]
    """
    z = robust_z(np.asarray(norms, float))
    bad = np.flatnonzero(z > (thresholds or Thresholds()).outlier_limit(len(z), dim))
    return bad if 0 < len(bad) <= max(1, int(MAX_OUTLIER_SHARE * len(z))) else bad[:0]


def bad_rows(meas: Measurements, bad: np.ndarray, what: str = "poses") -> Cause:
    """The cause "a few bad ``what``" for the samples at indices ``bad`` of ``meas`` (their file rows named, as the
    fix's --exclude), without its σ and verdict."""
    rows = meas.rows[bad]
    exclude = f"--exclude {','.join(map(str, rows))}" if meas.session is None else "--exclude in their files"
    return Cause("outliers", f"a few bad {what}: {meas.describe_rows(bad)} lie far off the rest",
                 f"leave them out (--reject-outliers, or {exclude}) and check how they were measured",
                 rows=tuple(int(r) for r in rows))


def _quiet(options: FitOptions) -> FitOptions:
    """The options for a trial fit: no diagnosis, no model choice, no drift, nothing left out."""
    return options.replace(diagnose=False, reject_outliers=False, error_model=None, drift=False, pso=None,
                           method="lm" if options.method == "pso" else options.method)


def _screen(robot: Robot, meas: "Measurements | list[Measurements]") -> float:
    """Residual σ per axis (m) of the nominal model registered to ``meas`` (measurement frame and tool
    point fitted, kinematics fixed); inf when that fit is impossible (or ``meas`` is several sessions)."""
    from .calibrate import calibrate
    if isinstance(meas, list):
        return math.inf
    tool = tuple(n for n in TOOL_NAMES if n in robot.params.names)
    base = "estimate" if robot.base_params() else "fixed"
    try:
        return calibrate(robot, meas, names=tool, base=base, diagnose=False, max_iter=SCREEN_ITERATIONS).sigma
    except (KincalError, ValueError, np.linalg.LinAlgError):
        return math.inf


def _full(cause: Cause, change: Change, robot: Robot, meas: Measurements, options: FitOptions) -> Cause | None:
    """``cause`` with the σ and verdict of the full calibration with its change applied (None if impossible)."""
    from .calibrate import calibrate, calibrate_sessions
    try:
        r, m, o = change(robot, meas, _quiet(options))
        res = calibrate_sessions(r, m, o) if isinstance(m, list) else calibrate(r, m, o)
    except (KincalError, ValueError, np.linalg.LinAlgError):
        return None
    return replace(cause, sigma=res.sigma, status=res.verdict.status)


def _refit(res: CalibrationResult) -> Cause | None:
    """A particle swarm's fit: the unchanged data fitted as the trials are (:func:`_quiet`: Levenberg–Marquardt from
    the nominal values), the fit the trials are judged against (a better optimum is not a data mistake) and itself a
    cause when it explains the data (the swarm stopped short of the best fit). None for the other solvers: the
    trials run the fit's own."""
    if res.options.method != "pso":
        return None
    return _full(Cause("solver", "the particle swarm stopped short of the best fit (Levenberg–Marquardt fits the same "
                                 "data from the nominal values)", "refit with --method pso+lm (Levenberg–Marquardt "
                                                                  "from the swarm's best) or --method lm"),
                 lambda r, m, o: (r, m, o), res.nominal, res.measurements, res.options)


def diagnose(res: CalibrationResult) -> Diagnosis:
    """Try the candidate causes of a doubtful fit ``res`` (a :class:`CalibrationResult` with its
    measurements) and rank those that explain the data; see the module docstring."""
    robot, meas, options = res.nominal, res.measurements, res.options
    data = (_length_units(meas) + _angle_units(robot, meas) + _joint_columns(robot) + _frame_and_rows()
            + _robot_files(robot))
    block = meas.subset(np.arange(min(len(meas), SCREEN_POSES)))  # consecutive: row shifts stay row shifts
    screened = [_screen(*change(robot, block, options)[:2]) for _, change in data]
    as_given = _screen(robot, block)
    order = [k for k in order_with_ties(screened, descending=False) if screened[k] < EXPLAIN_RATIO * as_given]
    trials = [data[k] for k in sorted(order[:MAX_FULL])] + _setups(robot, options) + _jump(res) + _sessions(res)
    bad = outlier_poses(robot, meas, options) if len(meas) > 10 else np.zeros(0, dtype=int)
    if len(bad):
        trials.append((bad_rows(meas, bad), lambda r, m, o: (r, m.subset(np.setdiff1d(np.arange(len(m)), bad)), o)))
    tried = [c for c in (_full(cause, change, robot, meas, options) for cause, change in trials) if c is not None]
    n_tried = len(data) + len(trials) - min(len(order), MAX_FULL)  # the screened ones counted once
    refit = _refit(res)
    ref = (res.sigma, res.verdict.status) if refit is None else (refit.sigma, refit.status)
    good = [c for c in tried if _explains(c, *ref)]
    good += [refit] if refit is not None and _explains(refit, res.sigma, res.verdict.status) else []
    return Diagnosis(res.sigma, res.verdict.status, _ranked(good), n_tried + (refit is not None))


def diagnose_samples(res: CalibrationResult) -> Diagnosis | None:
    """The diagnosis of a doubtful fit ``res`` of observation sets with no measured positions to screen (sockets,
    planes, a joint-space residual): the samples a robust (Huber) refit puts beyond the outlier limit, when they are
    a few of their set's (:func:`few_bad` of :func:`kincal.identify.judge.sample_norms`), left out and fitted again;
    the cause when that explains the fit by the whitened residual RMS (:func:`_explains`), else None (nothing said:
    the one candidate did not explain it)."""
    from .fitting import fit_stack
    from .judge import MIN_SAMPLES, block_size, sample_norms
    sets, options = list(res.observations), _quiet(res.options)
    try:
        robust = fit_stack(res.nominal, sets, options.replace(loss="huber", method="lm", f_scale=None))
    except (KincalError, ValueError, np.linalg.LinAlgError):
        return None
    bad = [few_bad(norms, options.thresholds, block_size(obs)) if len(obs) >= MIN_SAMPLES else np.zeros(0, int)
           for obs, norms in zip(sets, sample_norms(sets, robust.whitened_residual))]
    if not any(len(b) for b in bad):
        return None
    kept = [o.subset(np.setdiff1d(np.arange(len(o)), b)) if len(b) else o for o, b in zip(sets, bad)]
    try:
        trial = fit_stack(res.nominal, kept, options)
    except (KincalError, ValueError, np.linalg.LinAlgError):
        return None
    named = [(o, o.rows[b]) for o, b in zip(sets, bad) if len(b)]
    where = "; ".join(f"{listed(rows)} of {o.source}" for o, rows in named)
    exclude = f"--exclude {','.join(map(str, named[0][1]))}" if len(sets) == 1 else "--exclude in their files"
    cause = Cause("outliers", f"a few bad poses: row(s) {where} lie far off the rest",
                  f"leave them out (--reject-outliers, or {exclude}) and check how they were measured",
                  trial.whitened_rms, trial.verdict.status, tuple(int(r) for _, rows in named for r in rows))
    rms = res.whitened_rms
    return Diagnosis(rms, res.verdict.status, (cause,), 1, True) if _explains(cause, rms, res.verdict.status) else None


def _explains(c: Cause, sigma: float, status: str) -> bool:
    """Whether the trial ``c`` explains the data against a fit of residual σ ``sigma`` (m) and verdict ``status``:
    a σ below EXPLAIN_RATIO times it, or a better verdict with a σ at most NOT_WORSE times it."""
    return c.sigma < EXPLAIN_RATIO * sigma or (STATUSES.index(c.status) < STATUSES.index(status)
                                               and c.sigma <= NOT_WORSE * sigma)


def _ranked(good: list[Cause]) -> tuple[Cause, ...]:
    """The causes that explain the data, best verdict first, then smallest σ; ties (kincal.ties) keep
    the canonical order."""
    out: list[Cause] = []
    for status in STATUSES:
        same = [c for c in good if c.status == status]
        out += [same[k] for k in order_with_ties([c.sigma for c in same], descending=False)]
    return tuple(out)
