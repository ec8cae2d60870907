"""Identification of kinematic parameters from measured positions: ``calibrate`` and ``evaluate``.

``calibrate`` checks every option first, turns the measured positions of each session into an observation set (a
:class:`~kincal.observe.PointObs`, or a :class:`~kincal.observe.JointObs` for the joint-space residual; later sessions
in their own frames, :class:`~kincal.observe.InSession`), runs the one fit (:func:`kincal.identify.fitting.fit_stack`),
and reads it as a :class:`CalibrationResult` with the data as given: the residuals of every pose in the first
session's frame, the verdict of position data, and the differential diagnosis of a doubtful fit.
``fit_observations`` is the same fit for observation sets of any kinds.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable, Mapping, Sequence

import numpy as np

from .._threads import blas_threads
from ..analysis.uncertainty import ModelUncertainty, envelope_warning, extrapolation_warning
from ..checks import kind_of
from ..errors import MeasurementError
from ..io.measurements import Measurements
from ..models.unit_checks import joints_in_radians
from ..models.robot import Robot
from ..models.terms import check_payload
from ..observe import InSession, JointObs, PointObs, PoseObs
from ..observe.observations import Wrapper
from .diagnosis import TRIGGERS, diagnose, diagnose_samples
from .fitting import ABSOLUTE, fit_stack
from .options import FitOptions
from .positions import EvaluationStats, joined
from .result import CalibrationResult, Judged
from .select import select_model
from .verdict import distinct_count, repeat_tolerance

RESIDUALS = {"cartesian": PointObs, "joint": JointObs}  # FitOptions.residual -> the observation type fitted


def calibrate(robot: Robot, meas: Measurements, options: FitOptions | None = None, *, use_q: np.ndarray | None = None,
              progress: Callable[[str], None] | None = None, **changes) -> CalibrationResult:
    """Identify ``robot``'s parameters from measured tool positions.

    Several sessions joined in one frame (``meas.session`` labels) are one set each. Every option is
    checked before any work. The result carries a verdict (good, suspect, refused) with reasons. BLAS
    runs single-threaded inside: the problems are small, and threads fight for cores.

    Parameters
    ----------
    robot : Robot
        The nominal robot (the model as given; corrections are from it).
    meas : Measurements
        The measured tool positions (N, 3) m at joint values (N, n) rad (m for a prismatic joint).
    options : FitOptions, optional
        How to calibrate (default: ``FitOptions()``).
    use_q : ndarray, shape (M, n), optional
        Joint values where the calibrated model will be used, rad (m for a prismatic joint): with
        ``error_model="auto"`` the prediction-σ guard judges candidate terms there (default: the
        calibration poses). Kept in ``result.use_q`` and in the calibration record.
    progress : callable, optional
        Called with a message (str) at each stage (default: silent).
    **changes
        Fields of ``options`` to change, e.g. ``calibrate(robot, meas, base="fixed", loss="huber")``.

    Returns
    -------
    CalibrationResult
        The calibrated robot, the estimates with their σ and covariance, the residuals of every pose in
        the first session's frame and the verdict (with the differential diagnosis of a doubtful fit
        when ``diagnose``).

    Raises
    ------
    ValueError
        For an unknown or invalid option, naming it.
    ModelError
        For an unknown parameter name in ``names`` or ``keep``.
    MeasurementError
        For data that cannot belong to the robot, or too little of it (fewer than 3 distinct poses to
        register the frame, fewer equations than parameters).
    IdentifiabilityError
        When an explicit ``names`` list fitted by Levenberg–Marquardt cannot be identified.

    See Also
    --------
    evaluate : Error statistics of a model on other measurements.
    calibrate_sessions : Sessions measured in different frames.
    fit_observations : Observation sets of any kinds.

    Examples
    --------
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)  # errors up to 0.5 mm and 0.05 deg
    >>> meas = kincal.simulate(true, robot.sample_joints(30, seed=2), seed=3)  # σ 15 µm per axis
    >>> res = kincal.calibrate(robot, meas, diagnose=False)
    >>> res.converged, res.verdict.status
    (True, 'good')
    >>> f"mean error {res.stats_before.mean * 1e3:.2f} mm -> {res.stats_after.mean * 1e3:.3f} mm"
    'mean error 0.91 mm -> 0.022 mm'
    >>> kincal.calibrate(robot, meas, loss="cauchy")
    Traceback (most recent call last):
    ...
    ValueError: loss='cauchy' is not one of linear, huber, soft_l1
    """
    _arguments(robot, meas, options)
    parts = [meas] if meas.session is None or len(meas.sessions()) < 2 else \
        [dataclasses.replace(meas.subset(np.flatnonzero(meas.session == s)), source=s) for s in meas.sessions()]
    return _calibrate(robot, parts, False, options, use_q, progress, changes)


def calibrate_sessions(robot: Robot, sessions, options: FitOptions | None = None, *,
                       use_q: np.ndarray | None = None, progress: Callable[[str], None] | None = None,
                       **changes) -> CalibrationResult:
    """Calibrate shared kinematics from several sessions, each measured in its own frame.

    The tracker moved between the sessions: every later session's frame is six set-up parameters of
    the one fit (``frame[k:source].base.x`` … in ``result.nuisance``, m and rad). The result's data are
    the sessions in the first one's frame. One session is simply calibrated.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    sessions : Measurements or sequence of Measurements
        The sessions, each in its own measurement frame; the first one's frame is the robot's.
    options : FitOptions, optional
        How to calibrate (default: ``FitOptions()``), as :func:`calibrate`.
    use_q : ndarray, shape (M, n), optional
        Joint values where the model will be used, rad (m for a prismatic joint), as :func:`calibrate`.
    progress : callable, optional
        Called with a message (str) at each stage (default: silent).
    **changes
        Fields of ``options`` to change, as :func:`calibrate`.

    Returns
    -------
    CalibrationResult
        The calibrated robot (in the first session's frame) and the later sessions' frames.

    Raises
    ------
    ValueError, ModelError, MeasurementError, IdentifiabilityError
        As :func:`calibrate`.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import calibrate_sessions
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> first = kincal.simulate(true, robot.sample_joints(30, seed=2), seed=3)
    >>> moved = true.with_params({"base.x": 0.5, "base.rz": 0.3})  # the tracker 0.5 m and 0.3 rad away
    >>> second = kincal.simulate(moved, robot.sample_joints(20, seed=6), seed=7)
    >>> res = calibrate_sessions(robot, [first, second], diagnose=False)
    >>> res.verdict.status, len(res.measurements)
    ('good', 50)
    >>> frame = {k.rsplit(".", 1)[1]: round(float(v), 3) for k, v in res.nuisance.items()}
    >>> frame["x"], frame["rz"]
    (0.5, 0.3)
    """
    sessions = [sessions] if isinstance(sessions, Measurements) else list(sessions)
    return _calibrate(robot, sessions, len(sessions) > 1 and bool(robot.base_params()), options, use_q, progress,
                      changes)


def _calibrate(robot: Robot, sessions: list[Measurements], own_frames: bool, options, use_q, progress,
               changes) -> CalibrationResult:
    t0 = time.perf_counter()
    options = (options or FitOptions()).replace(**changes).check(robot)
    use_q = None if use_q is None else robot.check_q(use_q)
    if use_q is not None:
        joints_in_radians("use_q", use_q, robot)
    say = progress or (lambda msg: None)
    for s in sessions:
        s.check_robot(robot)
    with blas_threads(1):
        spec, choice = _error_model(robot, sessions, own_frames, options, say, use_q)
        fit_options = options.replace(error_model=spec, diagnose=False)  # fit_stack extends the robot by it
        fit = fit_stack(robot, _sets(sessions, own_frames, options, robot), fit_options, say=say)
        res = dataclasses.replace(fit, options=options, error_model_choice=choice, use_q=use_q,
                                  data=tuple(sessions), time_s=time.perf_counter() - t0)
        return diagnosed(res, robot, say) if options.diagnose else res


def _sets(sessions: list[Measurements], own_frames: bool, o: FitOptions, robot: Robot) -> list:
    """One observation set per session (later ones in their own frames with ``own_frames``), after
    the check that registering the frame needs: 3 distinct poses. The fit turns them into the
    ``o.residual`` type (:data:`RESIDUALS`, :func:`kincal.observe.in_joint_space`)."""
    q = np.concatenate([s.q for s in sessions])
    distinct = distinct_count(q, repeat_tolerance(robot.joint_types, o.thresholds), 3)
    if o.base == "estimate" and robot.base_params() and distinct < 3:
        raise MeasurementError(f"{sessions[0].source}: registering the base frame needs at least 3 distinct poses, "
                               f"got {distinct} ({len(q)} rows); measure poses spread over the workspace")
    sets = [PointObs(s.q, s.rows, s.source, xyz=s.xyz, std=o.thresholds.tracker_noise if s.std is None else s.std)
            for s in sessions]
    return [sets[0], *(InSession.of(x, f"{k}:{x.source}") for k, x in enumerate(sets[1:], 2))] if own_frames else sets


def _error_model(robot: Robot, sessions: list[Measurements], own_frames: bool, options: FitOptions, say, use_q):
    """The requested error model (for "auto" the one chosen), and the model comparison when it is "auto"
    (on the sessions in the first one's frame as the geometric fit aligns them)."""
    spec = options.error_model
    if spec is None or spec.name != "auto":
        return spec, None
    check_payload(robot, spec.payload, np.concatenate([s.q for s in sessions]))  # a named model's: when extended
    say("choosing the error model (joint-space blocked cross-validation)")
    quiet = options.replace(error_model=None, diagnose=False, reject_outliers=False)
    data = _calibrate(robot, sessions, True, quiet, None, None, {}).measurements if own_frames else joined(sessions)
    choice = select_model(robot, data, calibrate, quiet, use_q=use_q, payload=spec.payload)
    return spec.named(choice.chosen), choice


def fit_observations(robot: Robot, observations: Sequence, options: FitOptions | None = None, *,
                     held: Mapping[str, float] | None = None, progress: Callable[[str], None] | None = None,
                     **changes) -> CalibrationResult:
    """Calibrate ``robot`` from observation sets of any kinds (:mod:`kincal.observe`) by the one fit.

    Defaults of this entry: the prior "auto" (learned for poses, markers, sockets and planes; none for
    positions alone), no diagnosis. With ``diagnose`` a doubtful fit of one point or pose file is screened
    for the common input mistakes on its measured positions. ``base="fixed"`` leaves the base frame out;
    ``residual`` and ``f_scale`` belong to position data (:func:`calibrate`). Identifiability is judged at
    the start and again at the solution (see :func:`kincal.identify.stacked.fit_sets`).

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    observations : sequence of Observation
        The observation sets (points, poses, markers, sockets, planes, sessions in their own frames).
    options : FitOptions, optional
        How to calibrate (default: ``FitOptions(diagnose=False)``).
    held : mapping of str to float, optional
        Set-up parameters held at these values (m or rad), not fitted: a held-out file judged with the
        probe's rotation and the markers as trained (default none).
    progress : callable, optional
        Called with a message (str) at each stage (default: silent).
    **changes
        Fields of ``options`` to change.

    Returns
    -------
    CalibrationResult
        The fit; its position view (``measurements``, ``residuals``) is empty, ``per_set`` gives each
        set's statistics (m, rad).

    Raises
    ------
    ValueError
        For an unknown or invalid option, naming it.
    MeasurementError
        For no observations, data that do not fix the length scale, or too few samples.
    IdentifiabilityError
        When an explicit ``names`` list fitted by Levenberg–Marquardt cannot be identified.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import fit_observations, stat_line
    >>> from kincal.observe import PointObs
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(kincal.perturb(robot, seed=1), robot.sample_joints(30, seed=2), seed=3)
    >>> points = PointObs(meas.q, meas.rows, "tracker.csv", xyz=meas.xyz, std=15e-6)
    >>> fit = fit_observations(robot, [points])
    >>> fit.verdict.status, fit.per_set[0]["samples"]
    ('good', 30)
    >>> stat_line(fit.per_set_before[0]), stat_line(fit.per_set[0])
    ('mean 0.9125 mm', 'mean 0.0215 mm')
    """
    t0 = time.perf_counter()
    options = (options or FitOptions(diagnose=False)).replace(**changes).check(robot)
    fit = fit_stack(robot, observations, options, held, progress or (lambda msg: None))
    fit = dataclasses.replace(fit, time_s=time.perf_counter() - t0)
    return diagnosed(fit, robot) if options.diagnose else fit


def diagnosed(res: CalibrationResult, robot: Robot, say=lambda msg: None) -> CalibrationResult:
    """``res`` with the differential diagnosis as the first reason of its verdict, when the verdict
    doubts the data (:data:`TRIGGERS`). Position data are screened as fitted; other kinds on the
    positions of their point, 6-D pose or markers files in the robot's frame (:func:`_positions_of`, fitted as
    positions from ``robot``, the model as given); sockets, planes, joint-space residuals and sessions in their own
    frames for a few bad samples of the fit itself (:func:`kincal.identify.diagnosis.diagnose_samples`). The verdict
    puts the diagnosis first (:func:`kincal.identify.judge.verdict_of`)."""
    if not any(r.code in TRIGGERS for r in res.verdict.reasons):
        return res
    position = res if res.data else _positions_of(res, robot)
    if position is None:  # no positions to screen: a few bad samples of the fit itself
        say("looking for a few bad samples")
        found = diagnose_samples(res)
        return res if found is None else dataclasses.replace(res, diagnosis=found)
    say("trying the common input mistakes")
    return dataclasses.replace(res, diagnosis=diagnose(position))


def _positions_of(res: CalibrationResult, robot: Robot) -> CalibrationResult | None:
    """The fit of the measured positions of ``res``'s point, pose or markers files in the robot's frame (at least
    10 of them), or None: one file, or several given in one frame (--same-frame) as sessions of that frame, so the
    diagnosis tries each in a frame of its own as it does for position files (the camera moved between them);
    files that measure one point on the flange only (a markers file's centroid is another than a pose's target)."""
    sets = [o for o in res.observations if o.kind in ABSOLUTE and not isinstance(o, InSession)]
    points, found = [o.positions_point(res.nuisance) for o in sets], [o.positions() for o in sets]
    if not sets or None in found or not all(
            p is None if points[0] is None else p is not None and np.allclose(p, points[0], atol=1e-9) for p in points):
        return None
    parts = [Measurements(f[0], f[1], robot.joint_names, o.source, o.position_rows()) for o, f in zip(sets, found)
             if f is not None]
    meas = parts[0] if len(parts) == 1 else joined(parts)
    if len(meas) < 10:
        return None
    robot = robot if points[0] is None else robot.with_tool_point(points[0])  # markers: their centroid as fitted
    return calibrate(robot, meas, diagnose=False, base=res.options.base)  # the set-up as the user gave it: --base
    # fixed is one of the causes


def _arguments(robot: Robot, meas: Measurements, options: FitOptions | None) -> None:
    """TypeError for a call whose arguments are of the wrong kind, saying what to give."""
    kind_of("robot", robot, Robot, "load it first, e.g. kincal.load_robot('ur5')")
    kind_of("meas", meas, Measurements, "read the file first: kincal.read_measurements(path, robot, ...)")
    if options is not None:
        kind_of("options", options, FitOptions, "a FitOptions record; or give its fields as keywords, e.g. "
                                                "calibrate(robot, meas, loss='huber')")


def evaluate(robot: Robot, meas: Measurements, rebase: bool = False,
             uncertainty: ModelUncertainty | None = None) -> EvaluationStats:
    """Position error statistics of ``robot`` on ``meas`` (m).

    Parameters
    ----------
    robot : Robot
        The model to judge (a calibrated one, or the nominal).
    meas : Measurements
        Measured tool positions (N, 3) m at joint values (N, n) rad (m for a prismatic joint).
    rebase : bool, optional
        First re-fit only the 6 base-frame parameters, kinematics fixed: the tracker moved between
        sessions (default False).
    uncertainty : ModelUncertainty, optional
        The model's parameter covariance (``result.uncertainty()``, or
        :func:`kincal.analysis.load_uncertainty` of a saved calibration): adds the predicted σ at every
        pose and a warning naming the rows where the model extrapolates (default None). With ``rebase`` the
        base-frame parameters are taken as known in it (:meth:`~kincal.analysis.ModelUncertainty.given`): the frame
        is these data's, and where the tracker stood changes no predicted σ; a model registered by the caller
        (:func:`kincal.identify.refit_frame`) is given such an uncertainty.

    Returns
    -------
    EvaluationStats
        Mean, RMS, maximum, standard deviation and 95th percentile of the 3-D error norms, m; with
        ``uncertainty`` also the predicted σ per pose (m), the rows flagged as extrapolated and the
        warnings.

    Raises
    ------
    ValueError
        When ``rebase`` is not True or False.
    MeasurementError
        For data that cannot belong to the robot, or no poses.

    Examples
    --------
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> res = kincal.calibrate(robot, kincal.simulate(true, robot.sample_joints(30, seed=2), seed=3),
    ...                        diagnose=False)
    >>> unseen = kincal.simulate(true, robot.sample_joints(20, seed=4), seed=5)
    >>> stats = kincal.evaluate(res.robot, unseen, uncertainty=res.uncertainty())
    >>> stats.n, f"{stats.mean * 1e3:.3f} mm", len(stats.predicted_sigma), stats.warnings
    (20, '0.032 mm', 20, ())
    >>> moved = kincal.simulate(true.with_params({"base.x": 0.2}), unseen.q, seed=5)  # the tracker moved
    >>> f"{kincal.evaluate(res.robot, moved, rebase=True).mean * 1e3:.3f} mm"
    '0.029 mm'
    """
    kind_of("robot", robot, Robot, "the model to judge; of a calibration: evaluate(result.robot, meas, "
                                   "uncertainty=result.uncertainty())")
    _arguments(robot, meas, None)
    if rebase not in (True, False):
        raise ValueError(f"rebase={rebase!r}: True or False")
    meas.check_robot(robot)
    if len(meas) == 0:
        raise MeasurementError(f"{meas.source}: no poses to evaluate on (an empty file or "
                               f"subset); give at least one measured pose")
    if rebase and robot.base_params():  # frame only, kinematics fixed (kincal.identify.refit_frame)
        robot = calibrate(robot, meas, names=(), base="estimate", diagnose=False).robot
        # the frame is these data's now: the training frame's σ no longer counts (a rigid relabelling changes no σ)
        uncertainty = None if uncertainty is None else uncertainty.given(robot.base_params(), robot)
    stats = EvaluationStats.from_errors(meas.xyz - robot.forward(meas.q))
    if uncertainty is None:
        return stats
    sigma = uncertainty.sigma(robot, meas.q)
    outside, envelope = envelope_warning(meas.rows, meas.q, robot, uncertainty)
    warnings = tuple(w for w in (extrapolation_warning(meas.rows, sigma, uncertainty, meas.q, robot), envelope) if w)
    flagged = uncertainty.extrapolated(sigma) | outside
    return dataclasses.replace(stats, predicted_sigma=tuple(map(float, sigma)),
                               extrapolated_rows=tuple(int(r) for r in meas.rows[flagged]), warnings=warnings)


def held_out_nominal(fit: CalibrationResult, obs, same_frame: bool, judge=None):
    """A held-out set's statistics (m, rad) under the nominal kinematics, judged as the training file's "before"
    and ``kincal evaluate``'s nominal line judge it.

    With ``same_frame``: the frame and target as registered on the training data (``fit.before``). Otherwise
    poses are judged with the frame, the target point and the target's rotation fitted to the set, kinematics
    fixed, from the declared point (a learned prior on the point is centred where its fit starts: from the
    training's point the Jugglebot's S2 read 2.4090 mm against evaluate's 2.4066 mm): the calibrated target
    rotation belongs to the calibrated kinematics (with it the nominal model read 3.53 mm on S2, with its own
    2.41 mm); other sets with their frame fitted, as :func:`held_out_stats` fits it.

    Parameters
    ----------
    fit : CalibrationResult
        The fit of the training sets.
    obs : Observation
        The held-out set.
    same_frame : bool
        Whether the held-out set was measured in the training frame.
    judge : callable, optional
        What to make of the set under the nominal model so registered: :func:`held_out_stats` (default, its
        statistics) or :func:`held_out_judged` (the set as judged, for the report's figures).

    Returns
    -------
    dict or Judged
        The set's statistics as :func:`held_out_stats` gives them (or ``judge``'s answer).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.identify import fit_observations, held_out_nominal
    >>> from kincal.observe import PoseObs
    >>> robot = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.1])
    >>> true = kincal.perturb(robot, seed=1).with_tool_point([0.01, 0.0, 0.12])
    >>> sets = []
    >>> for n, s in ((30, 2), (20, 4)):
    ...     q = robot.sample_joints(n, seed=s)
    ...     p, R, _, _ = true.pose_and_jacobian(q)
    ...     sets.append(PoseObs(q, np.arange(2, n + 2), f"{s}.csv", xyz=p, R=R))
    >>> fit = fit_observations(robot, sets[:1])
    >>> alone = fit_observations(robot, sets[1:], names=(*robot.base_params(), "tool.x", "tool.y", "tool.z"))
    >>> round(held_out_nominal(fit, sets[1], False)["mean"] / alone.per_set[0]["mean"], 6)
    1.0
    """
    judge = judge or held_out_stats
    if same_frame or obs.kind not in ABSOLUTE or not isinstance(_innermost(obs), PoseObs):
        return judge(fit, obs, fit.before, same_frame)
    start = fit.before.with_tool_point(fit.nominal.tool_point()) if fit.before.has_tool_point else fit.before
    return judge(fit, _own_target(obs), start, False)


def _innermost(obs):
    """The set a wrapper (a session's frame, a drifting instrument) is built on; ``obs`` itself if none."""
    return _innermost(obs.inner) if isinstance(obs, Wrapper) else obs


def _own_target(obs):
    """The pose set ``obs`` with its target's point and rotation its own (re-fitted, as --refit-target)."""
    if isinstance(obs, Wrapper):
        return dataclasses.replace(obs, inner=_own_target(obs.inner))
    return dataclasses.replace(obs, own_target=True) if isinstance(obs, PoseObs) else obs


def held_out_stats(fit: CalibrationResult, obs, robot: Robot, same_frame: bool) -> dict:
    """A held-out set's statistics (m, rad) under ``robot``.

    In the training frame with the training set-up parameters (``same_frame``; sockets and planes need
    no frame), else with its own frame fitted (the tracker or camera may have moved), the kinematics
    fixed and the set-up parameters it shares with the training files (a target's rotation, markers)
    held as trained. A target the set defines anew (``refit_target``) is its own, fitted either way: with
    ``same_frame`` only that target, the frame as calibrated. ``fit.before`` is judged as "before" calibration:
    with the markers' points registered with it on the training sets (``fit.before_setup``) in the training frame,
    else registered to this set.

    Parameters
    ----------
    fit : CalibrationResult
        The fit of the training sets.
    obs : Observation
        The held-out set (of a kind the fit was trained on).
    robot : Robot
        The model to judge: the calibrated one (``fit.robot``) or ``fit.before``.
    same_frame : bool
        Whether the held-out set was measured in the training frame.

    Returns
    -------
    dict
        The set's statistics as its type's ``stats()`` gives them: ``type``, ``source``, ``samples``
        and errors in m (and rad for rotations), e.g. ``mean``, ``rms``, ``max``.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import fit_observations, held_out_stats
    >>> from kincal.observe import PointObs
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> train, test = (kincal.simulate(true, robot.sample_joints(n, seed=s), seed=s) for n, s in ((30, 2), (20, 4)))
    >>> fit = fit_observations(robot, [PointObs(train.q, train.rows, "train.csv", xyz=train.xyz)])
    >>> stats = held_out_stats(fit, PointObs(test.q, test.rows, "test.csv", xyz=test.xyz), fit.robot, True)
    >>> stats["source"], stats["samples"], bool(stats["mean"] < 0.05e-3)
    ('test.csv', 20, True)
    """
    own = obs.refitted(robot)  # a target defined anew: its point and rotation are the set's own
    kept = same_frame or obs.kind not in ABSOLUTE  # the frame as calibrated
    return fit.held_out(obs, robot) if kept and not own else _held_out_fit(fit, obs, robot, kept, own).per_set[0]


def held_out_judged(fit: CalibrationResult, obs, robot: Robot, same_frame: bool) -> Judged:
    """A held-out set as :func:`held_out_stats` judges it under ``robot``: the set, the model (its frame fitted to
    the set unless kept, so positions in the set's own frame) and the set's set-up values, which the report's
    figures draw (their statistics are :func:`held_out_stats`'s)."""
    own = obs.refitted(robot)
    kept = same_frame or obs.kind not in ABSOLUTE
    if kept and not own:
        return fit.held_out_judged(obs, robot)
    judged = _held_out_fit(fit, obs, robot, kept, own)
    inner = judged.observations[0]
    return Judged(inner, judged.robot, np.array([judged.nuisance[n] for n in inner.nuisance(judged.robot)[0]]))


def _held_out_fit(fit: CalibrationResult, obs, robot: Robot, kept: bool, own: tuple[str, ...]) -> CalibrationResult:
    """The fit of a held-out set's own frame (unless ``kept``) and its own target (``own``), the kinematics fixed."""
    anchors = {k: v for o in fit.observations for k, v in o.anchors().items()}
    mounted = fit.before_setup if robot is fit.before and not kept else {}  # the nominal's markers: the set's
    held = {n: v for n, v in fit.nuisance.items()
            if not n.startswith(("frame[", "drift[")) and n not in own and n not in mounted}
    names = (*(() if kept else robot.base_params()), *(n for n in own if n in robot.params))
    return fit_observations(robot, [obs.with_anchors(anchors)], names=names, held=held,
                            base="fixed" if kept else "estimate")
