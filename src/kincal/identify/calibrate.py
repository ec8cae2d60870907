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
from ..errors import MeasurementError
from ..io.measurements import Measurements
from ..models.robot import Robot
from ..observe import InSession, JointObs, PointObs
from .diagnosis import TRIGGERS, diagnose
from .fitting import ABSOLUTE, fit_stack
from .options import FitOptions
from .positions import EvaluationStats, joined
from .result import CalibrationResult
from .select import select_model
from .verdict import distinct_count, repeat_tolerance

RESIDUALS = {"cartesian": PointObs, "joint": JointObs}  # FitOptions.residual -> the observation type fitted


def calibrate(robot: Robot, meas: Measurements, options: FitOptions | None = None, *, use_q: np.ndarray | None = None,
              progress: Callable[[str], None] | None = None, **changes) -> CalibrationResult:
    """Identify ``robot``'s parameters from measured tool positions.

    options  -- a :class:`FitOptions` record (default: its defaults); ``changes`` are fields of it
                to change, e.g. ``calibrate(robot, meas, base="fixed", loss="huber")``
    use_q    -- (M, n) joint values where the calibrated model will be used: with
                ``error_model="auto"`` the prediction-σ guard judges candidate terms there (default:
                the calibration poses). Kept in ``result.use_q`` and in the calibration record
    progress -- called with a message at each stage

    Several sessions joined in one frame (``meas.session`` labels) are one set each. Every option is
    checked before any work (ValueError naming it). MeasurementError for data that cannot belong to
    the robot or is too little, IdentifiabilityError for an explicit ``names`` list
    Levenberg–Marquardt cannot identify. The result carries a verdict (good, suspect, refused) with
    reasons. BLAS runs single-threaded inside: the problems are small, and threads fight for cores.
    """
    parts = [meas] if meas.session is None or len(meas.sessions()) < 2 else \
        [dataclasses.replace(meas.subset(np.flatnonzero(meas.session == s)), source=s) for s in meas.sessions()]
    return _calibrate(robot, parts, False, options, use_q, progress, changes)


def calibrate_sessions(robot: Robot, sessions, options: FitOptions | None = None, *,
                       use_q: np.ndarray | None = None, progress: Callable[[str], None] | None = None,
                       **changes) -> CalibrationResult:
    """Calibrate shared kinematics from several sessions, each measured in its own frame (the tracker
    moved between them): every later session's frame is six set-up parameters of the one fit. The
    result's data are the sessions in the first one's frame. ``options``, ``use_q``, ``changes``: as
    :func:`calibrate`; one session is simply calibrated."""
    sessions = [sessions] if isinstance(sessions, Measurements) else list(sessions)
    return _calibrate(robot, sessions, len(sessions) > 1 and bool(robot.base_params()), options, use_q, progress,
                      changes)


def _calibrate(robot: Robot, sessions: list[Measurements], own_frames: bool, options, use_q, progress,
               changes) -> CalibrationResult:
    t0 = time.perf_counter()
    options = (options or FitOptions()).replace(**changes).check(robot)
    use_q = None if use_q is None else robot.check_q(use_q)
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
    say("choosing the error model (joint-space blocked cross-validation)")
    quiet = options.replace(error_model=None, diagnose=False, reject_outliers=False)
    data = _calibrate(robot, sessions, True, quiet, None, None, {}).measurements if own_frames else joined(sessions)
    choice = select_model(robot, data, calibrate, quiet, use_q=use_q, payload=spec.payload)
    return dataclasses.replace(spec, name=choice.chosen), choice


def fit_observations(robot: Robot, observations: Sequence, options: FitOptions | None = None, *,
                     held: Mapping[str, float] | None = None, progress: Callable[[str], None] | None = None,
                     **changes) -> CalibrationResult:
    """Calibrate ``robot`` from observation sets of any kinds (:mod:`kincal.observe`) by the one fit, with
    ``options`` (a :class:`FitOptions`; ``changes`` are fields of it to change). Defaults of this entry: the prior
    "auto" (learned for poses, markers, sockets and planes; none for positions alone), no diagnosis. With
    ``diagnose`` a doubtful fit of one point or pose file is screened for the common input mistakes on its measured
    positions. ``held``: set-up parameters held at these values, not fitted (a held-out file judged with the probe's
    rotation and the markers as trained). ``base="fixed"`` leaves the base frame out; ``residual`` and ``f_scale``
    belong to position data (:func:`calibrate`). Identifiability is judged at the start and again at the solution
    (see :func:`kincal.identify.stacked.fit_sets`)."""
    t0 = time.perf_counter()
    options = (options or FitOptions(diagnose=False)).replace(**changes).check(robot)
    fit = fit_stack(robot, observations, options, held, progress or (lambda msg: None))
    fit = dataclasses.replace(fit, time_s=time.perf_counter() - t0)
    return diagnosed(fit, robot) if options.diagnose else fit


def diagnosed(res: CalibrationResult, robot: Robot, say=lambda msg: None) -> CalibrationResult:
    """``res`` with the differential diagnosis as the first reason of its verdict, when the verdict
    doubts the data (:data:`TRIGGERS`). Position data are screened as fitted; other kinds on the
    positions of their one point or 6-D pose file in the robot's frame (fitted as positions from
    ``robot``, the model as given); markers, sockets, planes and sessions in their own frames are
    not (the verdict puts the diagnosis first: :func:`kincal.identify.judge.verdict_of`)."""
    if not any(r.code in TRIGGERS for r in res.verdict.reasons):
        return res
    position = res if res.data else _positions_of(res, robot)
    if position is None:
        return res
    say("trying the common input mistakes")
    return dataclasses.replace(res, diagnosis=diagnose(position))


def _positions_of(res: CalibrationResult, robot: Robot) -> CalibrationResult | None:
    """The fit of the measured positions of ``res``'s one point or pose file in the robot's frame
    (at least 10 of them), or None."""
    sets = [o for o in res.observations if o.kind in ("point", "pose") and not isinstance(o, InSession)]
    if len(sets) != 1 or len(sets[0]) < 10:
        return None
    q, xyz = sets[0].positions()
    return calibrate(robot, Measurements(q, xyz, robot.joint_names, sets[0].source, sets[0].rows), diagnose=False)


def evaluate(robot: Robot, meas: Measurements, rebase: bool = False,
             uncertainty: ModelUncertainty | None = None) -> EvaluationStats:
    """Position error statistics of ``robot`` on ``meas`` (m).

    rebase      -- first re-fit only the 6 base-frame parameters (the tracker moved between sessions)
    uncertainty -- the model's parameter covariance (``result.uncertainty()``, or
                   :func:`kincal.load_uncertainty` of a saved calibration): adds the predicted σ at
                   every pose and a warning naming the rows where the model extrapolates
    """
    if rebase not in (True, False):
        raise ValueError(f"rebase={rebase!r}: True or False")
    meas.check_robot(robot)
    if len(meas) == 0:
        raise MeasurementError(f"{meas.source}: no poses to evaluate on (an empty file or "
                               f"subset); give at least one measured pose")
    if rebase and robot.base_params():  # frame only, kinematics fixed (kincal.identify.refit_frame)
        robot = calibrate(robot, meas, names=(), base="estimate", diagnose=False).robot
    stats = EvaluationStats.from_errors(meas.xyz - robot.forward(meas.q))
    if uncertainty is None:
        return stats
    sigma = uncertainty.sigma(robot, meas.q)
    outside, envelope = envelope_warning(meas.rows, meas.q, robot, uncertainty)
    warnings = tuple(w for w in (extrapolation_warning(meas.rows, sigma, uncertainty, meas.q, robot), envelope) if w)
    flagged = uncertainty.extrapolated(sigma) | outside
    return dataclasses.replace(stats, predicted_sigma=tuple(map(float, sigma)),
                               extrapolated_rows=tuple(int(r) for r in meas.rows[flagged]), warnings=warnings)


def held_out_stats(fit: CalibrationResult, obs, robot: Robot, same_frame: bool) -> dict:
    """A held-out set's statistics (m, rad) under ``robot`` (the calibrated model, or ``fit.before``): in the training
    frame with the training set-up parameters (``same_frame``; sockets and planes need no frame), else with its own
    frame fitted (the tracker or camera may have moved), the kinematics fixed and the set-up parameters it shares with
    the training files (a target's rotation, markers) held as trained."""
    if same_frame or obs.kind not in ABSOLUTE:
        return fit.held_out(obs, robot)
    anchors = {k: v for o in fit.observations for k, v in o.anchors().items()}
    own = obs.refitted(robot)  # a target defined anew: its point and rotation are the set's own
    held = {n: v for n, v in fit.nuisance.items() if not n.startswith(("frame[", "drift[")) and n not in own}
    names = (*robot.base_params(), *(n for n in own if n in robot.params))
    return fit_observations(robot, [obs.with_anchors(anchors)], names=names, held=held).per_set[0]
