"""Measurement sessions: held-out data taken with the measurement frame registered again, and a
named cause when a model does much worse on a session than on its training data.

A session is one file of measurements taken with the tracker (camera, probe) in one place. The
tracker may move between sessions, so a model judged on another session gets its measurement frame
(the 6 base-frame parameters) re-fitted to that session first, kinematics fixed, unless the user
says the frame is known. Both the nominal and the calibrated model are registered the same way.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..io.measurements import Measurements
from ..io.unit_checks import spread
from ..models.robot import TOOL_NAMES, Robot
from ..models.terms import extend
from ..units import MM
from .calibrate import calibrate
from .diagnosis import outlier_poses
from .options import FitOptions
from .problem import build_problem
from .registration import register_base
from .result import CalibrationResult, rejected

HELDOUT_RATIO = 10.0  # a held-out error this many times the training error needs a named cause
SCALE_TOL = 0.01  # measured vs predicted spread off by more than 1 %: a scale (unit, compensation) error
REGISTERED = "frame re-registered to these data (both models; kinematics fixed)"
AS_CALIBRATED = "frame as calibrated: told the measurement frame did not move"


def refit_frame(robot: Robot, meas: Measurements) -> Robot:
    """``robot`` with only its measurement (base) frame re-fitted to ``meas``; a robot without a
    base frame is returned as it is."""
    if not robot.base_params():
        return robot
    return calibrate(robot, meas, names=(), base="estimate", diagnose=False).robot


def _mean_error(robot: Robot, meas: Measurements) -> float:
    return float(np.mean(np.linalg.norm(meas.xyz - robot.forward(meas.q), axis=1)))


def _spread_ratio(robot: Robot, meas: Measurements) -> float:
    """Measured spread / predicted spread of the positions at the same joints."""
    return spread(meas.xyz) / max(spread(robot.forward(meas.q)), 1e-300)


def heldout_cause(robot: Robot, meas: Measurements, train_error: float, rebased: bool) -> str:
    """A sentence naming the likely cause when ``robot`` (as used on ``meas``: registered or not)
    misses ``meas`` by more than HELDOUT_RATIO times its mean training error ``train_error`` (m);
    '' otherwise. Tries, in order: the frame not re-registered, another tool point, a scale error."""
    error = _mean_error(robot, meas)
    if not train_error > 0 or error <= HELDOUT_RATIO * train_error:
        return ""
    head = (f"{meas.source}: mean error {error * MM:.3f} mm is {error / train_error:.0f}x the training error "
            f"({train_error * MM:.3f} mm)")
    if not rebased and robot.base_params():
        again = _mean_error(refit_frame(robot, meas), meas)
        if again < 0.5 * error:
            return (f"{head}; with the measurement frame re-registered it is {again * MM:.3f} mm: the tracker moved "
                    f"between sessions (leave out --same-frame so that each session's frame is registered)")
    if robot.has_tool_point and robot.base_params() and len(meas) >= 4:
        tooled = calibrate(robot, meas, names=TOOL_NAMES, base="estimate", diagnose=False).robot
        again = _mean_error(tooled, meas)
        if again < 0.5 * error:
            gap = np.linalg.norm(tooled.tool_point() - robot.tool_point())
            where = ", ".join(f"{x * MM:.2f}" for x in tooled.tool_point())
            return (f"{head}; a tool point {gap * MM:.2f} mm from the calibrated one (at {where} mm in the flange "
                    f"frame) brings it to {again * MM:.3f} mm: the target was mounted differently in this session "
                    f"(another probe, adapter or seat); give that session's tool point with --tool")
    ratio = _spread_ratio(robot, meas)
    if abs(np.log(ratio)) > SCALE_TOL:
        return (f"{head}; the measured positions spread {ratio:.4f}x the model's at the same joints: a scale error "
                f"(length unit, tracker compensation, or joint columns in another unit)")
    return (f"{head}; neither a moved frame, another tool point nor a scale error explains it: the poses may lie "
            f"outside the calibrated region (see the predicted σ), the robot may have been disturbed (collision, "
            f"re-mastering), or the joint columns differ from the training data")


MAX_ROUNDS = 30  # fits with the sessions' frames re-fitted, when the options move the kinematics
ROUND_TOL = 1e-10  # m or rad: the frames have settled when no one moves more than this


def _in_frame_of(model: Robot, registered: Robot, meas: Measurements) -> Measurements:
    """``meas`` (taken in the frame where ``registered`` sees the robot) expressed in ``model``'s frame."""
    R0, t0 = model.base_transform()
    Rs, ts = registered.base_transform()
    xyz = (meas.xyz - ts) @ Rs @ R0.T + t0
    std = None if meas.std is None else np.sqrt(meas.std**2 @ (Rs @ R0.T) ** 2)  # per-axis variances, rotated
    return Measurements(meas.q, xyz, meas.joint_names, meas.source, meas.rows, std, meas.units, meas.session)


def joined(sessions: list[Measurements]) -> Measurements:
    """Several sessions as one set of measurements (their rows keep their own files' line numbers; each
    pose is labelled with its session's source, so held-out sessions can be told apart)."""
    if len(sessions) == 1:
        return sessions[0]
    std = None if any(s.std is None for s in sessions) else np.concatenate([s.std for s in sessions])
    labels = [s.source if s.source not in [t.source for t in sessions[:i]] else f"{s.source} ({i + 1})"
              for i, s in enumerate(sessions)]
    return Measurements(np.concatenate([s.q for s in sessions]), np.concatenate([s.xyz for s in sessions]),
                        sessions[0].joint_names, " + ".join(s.source for s in sessions),
                        np.concatenate([s.rows for s in sessions]), std, sessions[0].units,
                        np.concatenate([np.full(len(s), name) for s, name in zip(sessions, labels)]))


def calibrate_sessions(robot: Robot, sessions, options: FitOptions | None = None, *,
                       use_q: np.ndarray | None = None, **changes) -> CalibrationResult:
    """Calibrate shared kinematics from several sessions, each measured in its own frame (the tracker
    moved between them). The kinematics and every session's frame are fitted together in one stacked
    least-squares problem (a frame's six parameters per later session); the sessions are then brought
    into the first one's frame and calibrated with ``options``; if that moves the kinematics (a robust
    loss, an error model, σ columns), each frame is re-fitted and the fit repeated until no frame moves
    more than ROUND_TOL. Returns the last fit (its data: the sessions in the first one's frame; its σ
    leaves out the uncertainty of the other sessions' frames). With ``error_model="auto"`` the error
    model is chosen once on the sessions aligned by the geometric model (each session also held out in
    turn) and the fit repeated with it. ``options``, ``use_q``, ``changes``: as
    :func:`kincal.calibrate`; one session is simply calibrated."""
    sessions = [sessions] if isinstance(sessions, Measurements) else list(sessions)
    options = (options or FitOptions()).replace(**changes)
    if len(sessions) == 1 or not robot.base_params():
        return calibrate(robot, joined(sessions), options, use_q=use_q)
    plain, left_out = options.replace(reject_outliers=False), {}
    if options.reject_outliers:  # found with the geometry, by session: rows repeat across files
        first = _rounds(robot, sessions, plain.replace(error_model=None), use_q)
        sessions, left_out = _without_outliers(robot, sessions, first.measurements, plain)
    return dataclasses.replace(_with_model(robot, sessions, plain, use_q), options=options, **left_out)


def _with_model(robot: Robot, sessions: list[Measurements], options: FitOptions, use_q) -> CalibrationResult:
    """The rounds with the requested error model; "auto" chooses it once, on the sessions aligned by
    the geometric model (each session held out in turn), then repeats the rounds with it."""
    spec = options.error_model
    if spec is None or spec.name != "auto":
        return _rounds(robot, sessions, options, use_q)
    geometric = _rounds(robot, sessions, options.replace(error_model=None), use_q)
    chosen = calibrate(robot, geometric.measurements, options.replace(diagnose=False), use_q=use_q)
    choice = chosen.error_model_choice
    if choice is None or choice.chosen == "geometric":  # (calibrate always compares the models for "auto")
        return chosen
    fixed = options.replace(error_model=dataclasses.replace(spec, name=choice.chosen))
    return dataclasses.replace(_rounds(robot, sessions, fixed, use_q), error_model_choice=choice)


def _without_outliers(robot: Robot, sessions: list[Measurements], aligned: Measurements, options: FitOptions):
    """The sessions less the poses a robust refit of the aligned sessions puts beyond the outlier
    limit, and the result fields that name them."""
    bad = outlier_poses(robot, aligned, options)
    if not len(bad):
        return sessions, {}
    start = np.cumsum([0] + [len(s) for s in sessions])
    kept = [s.subset(np.setdiff1d(np.arange(len(s)), bad[(bad >= a) & (bad < a + len(s))] - a))
            for s, a in zip(sessions, start)]
    return kept, rejected(aligned, bad)


def _rounds(robot: Robot, sessions: list[Measurements], options: FitOptions, use_q) -> CalibrationResult:
    """:func:`calibrate_sessions` with a fixed error model: the sessions' frames from one stacked fit of
    the kinematics and every frame (:func:`_stacked_frames`), the sessions brought into the first one's
    frame and calibrated with ``options``. When those options move the kinematics off the stacked
    least-squares fit (a robust loss, σ columns with the model error beside them), the frames are
    re-fitted to the new kinematics and the fit repeated, until no frame moves more than ROUND_TOL."""
    opts = options.replace(diagnose=False)
    model, frames = _stacked_frames(robot, sessions, opts)
    for _ in range(MAX_ROUNDS):
        data = [sessions[0]] + [_in_frame_of(model, f, s) for f, s in zip(frames, sessions[1:])]
        res = calibrate(robot, joined(data), opts, use_q=use_q)
        again = [refit_frame(res.robot, s) for s in sessions[1:]]
        moved = max(float(np.max(np.abs(_frame(a) - _frame(f) - _frame(res.robot) + _frame(model))))
                    for a, f in zip(again, frames))
        if moved < ROUND_TOL:
            return res
        model, frames = res.robot, again
    return res  # the frames still moved after MAX_ROUNDS: the last fit


def _frame(robot: Robot) -> np.ndarray:
    return robot.params.values[robot.params.indices(robot.base_params())]


def _aligned(robot: Robot, sessions: list[Measurements]) -> list[Measurements]:
    """The sessions in the first one's frame as the starting model sees them (each frame registered
    rigidly to the model's predictions)."""
    model = register_base(robot, sessions[0].q, sessions[0].xyz)
    return [sessions[0]] + [_in_frame_of(model, register_base(model, s.q, s.xyz), s) for s in sessions[1:]]


def _stacked_frames(robot: Robot, sessions: list[Measurements], options: FitOptions):
    """The kinematics and every session's frame fitted together (least squares: the parameters
    ``calibrate`` would fit on the aligned sessions, with the error model of ``options``, and a frame
    per later session; :func:`~kincal.identify.stacked.fit_observations`): the model (in the first
    session's frame) and, per later session, the model in that session's frame."""
    from ..observe import InSession, PointObs
    from .stacked import fit_observations

    aligned = joined(_aligned(robot, sessions))
    fit_robot = robot if options.error_model is None else extend(robot, options.error_model, aligned.q)
    names = build_problem(fit_robot, aligned, options).names
    points = [PointObs(s.q, s.rows, s.source, xyz=s.xyz, std=STACK_STD if s.std is None else s.std) for s in sessions]
    later = [InSession.of(o, f"{k}:{o.source}") for k, o in enumerate(points[1:], start=2)]
    fit = fit_observations(fit_robot, [points[0], *later], names=names, keep=options.keep, rank_tol=options.rank_tol,
                           prior="none")
    base = fit.robot.base_params()
    frames = [fit.robot.with_params({b: fit.nuisance[f"frame[{o.session}].{b}"] for b in base}) for o in later]
    return fit.robot, frames


STACK_STD = 15e-6  # m: the σ of points without σ columns in the stacked fit (equal σ: its value does not matter)
