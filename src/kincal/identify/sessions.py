"""Measurement sessions: held-out data taken with the measurement frame registered again, and a
named cause when a model does much worse on a session than on its training data.

A session is one file of measurements taken with the tracker (camera, probe) in one place. The
tracker may move between sessions, so a model judged on another session gets its measurement frame
(the 6 base-frame parameters) re-fitted to that session first, kinematics fixed, unless the user
says the frame is known. Both the nominal and the calibrated model are registered the same way.
"""
from __future__ import annotations

import numpy as np

from ..errors import KincalError
from ..io.measurements import Measurements
from .._stats import f_sf, spread
from ..models.robot import TOOL_NAMES, Robot
from ..models.unit_checks import JUMP_ALARM
from ..units import MM
from ..ties import first_best
from .calibrate import calibrate
from .options import FitOptions
from .select import _mean_error
from .verdict import distinct_count, repeat_tolerance

HELDOUT_RATIO = 10.0  # a held-out error this many times the training error needs a named cause
SCALE_TOL = 0.005  # measured vs predicted spread off by more than 0.5 %: a scale (unit, compensation) error
REGISTERED = "frame re-registered to these data (both models, the nominal's target point too; kinematics fixed)"
AS_CALIBRATED = "frame as calibrated: told the measurement frame did not move"


def set_cause(robot: Robot, obs, setup: dict, train_error: float, rebased: bool = False,
              refit: tuple[str, ...] = ()) -> str:
    """Name the likely cause when a model misses a held-out observation set, judged in the calibration's frame
    or, ``rebased``, in the set's own frame re-fitted to it.

    :func:`heldout_cause` on the set's positions (``obs.positions()``) against the point on the flange they are
    of (``obs.positions_point``: the robot's tool point for points and poses, the markers' centroid for
    markers), so that a set whose measured point is not the model's tool point is not taken for another tool.

    Parameters
    ----------
    robot : Robot
        The model as calibrated, in the calibration's measurement frame.
    obs : Observation
        The held-out set.
    setup : dict of str to float
        The set-up parameters as calibrated (name -> m or rad, e.g. ``marker[m1].x``); the set's own start
        values stand in for the others.
    train_error : float
        The model's mean error on training data of the set's kind, m.
    rebased : bool, optional
        Whether ``robot``'s measurement frame was re-fitted to the set (default False: the calibration's).
    refit : tuple of str, optional
        Robot parameters re-fitted to the set with it (a target defined anew), as :func:`heldout_cause` takes them.

    Returns
    -------
    str
        :func:`heldout_cause`'s sentence; ``""`` for a set without positions or within the limit.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import set_cause
    >>> from kincal.simulate import simulate_markers
    >>> robot = kincal.load_robot("ur5")
    >>> points = [[0.05, 0.0, 0.1], [0.0, 0.05, 0.1], [-0.05, 0.0, 0.1]]
    >>> obs = simulate_markers(robot, robot.sample_joints(20, seed=1), points, std=0.0)
    >>> setup = {f"marker[{m}].{a}": p[i] for m, p in zip(obs.names, points) for i, a in enumerate("xyz")}
    >>> set_cause(robot, obs, setup, 20e-6)
    ''
    """
    found = obs.positions()
    if found is None:
        return ""
    ready = obs.prepare(robot)
    names, start, _ = ready.nuisance(robot)
    point = ready.positions_point({**dict(zip(names, map(float, start))), **setup})
    model = robot if point is None else robot.with_tool_point(point)
    meas = Measurements(found[0], found[1], robot.joint_names, obs.source, obs.rows)
    return heldout_cause(model, meas, train_error, rebased=rebased, refit=refit)


def refit_frame(robot: Robot, meas: Measurements) -> Robot:
    """Re-fit only the measurement (base) frame of ``robot`` to ``meas``, kinematics fixed.

    Parameters
    ----------
    robot : Robot
        The model (nominal or calibrated).
    meas : Measurements
        Measured tool positions (N, 3) m at joint values (N, n) rad (m for a prismatic joint), in a frame
        of their own; at least 3 distinct poses.

    Returns
    -------
    Robot
        ``robot`` with its six base-frame parameters fitted to ``meas``; a robot without a base frame is
        returned as it is.

    Raises
    ------
    MeasurementError
        For data that cannot belong to the robot, or fewer than 3 distinct poses.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import refit_frame
    >>> robot = kincal.load_robot("ur5")
    >>> moved = robot.with_params({"base.x": 0.5, "base.rz": 0.3})  # the tracker moved
    >>> meas = kincal.simulate(moved, robot.sample_joints(20, seed=1), seed=2)
    >>> again = refit_frame(robot, meas)
    >>> round(again.params["base.x"], 4), round(again.params["base.rz"], 4)
    (0.5, 0.3)
    """
    if not robot.base_params():
        return robot
    return calibrate(robot, meas, names=(), base="estimate", diagnose=False).robot


def _tool_fix(robot: Robot, meas: Measurements, base: str) -> tuple[float, str] | None:
    """The mean error (m) with the session's own tool point fitted (and its frame, with ``base="estimate"``), and
    what that says; None when the robot has no tool point or frame to fit, or the trial cannot be judged: fewer
    numbers than twice its unknowns (:func:`_too_few`), or a tool point that lowers the squared error of the same fit
    without it no more than noise would (the F test of its 3 numbers, below ``JUMP_ALARM``, 1 %, as
    :func:`kincal.models.unit_checks.frame_jump_test` judges a second frame)."""
    if not (robot.has_tool_point and robot.base_params() and len(meas) >= 4):
        return None
    unknowns = len(TOOL_NAMES) + (len(robot.base_params()) if base == "estimate" else 0)
    if _too_few(meas, unknowns):
        return None
    without = refit_frame(robot, meas) if base == "estimate" else robot
    tooled = calibrate(robot, meas, names=TOOL_NAMES, base=base, diagnose=False).robot
    sse_without, sse = (float(np.sum((meas.xyz - m.forward(meas.q)) ** 2)) for m in (without, tooled))
    dof = meas.xyz.size - unknowns
    f = (sse_without - sse) / len(TOOL_NAMES) / max(sse / dof, 1e-300)
    if not f_sf(f, float(len(TOOL_NAMES)), float(dof)) < JUMP_ALARM:
        return None
    again = _mean_error(tooled, meas)
    gap = np.linalg.norm(tooled.tool_point() - robot.tool_point())
    where = ", ".join(f"{x * MM:.2f}" for x in tooled.tool_point())
    return again, (f"a tool point {gap * MM:.2f} mm from the calibrated one (at {where} mm in the flange frame) brings "
                   f"it to {again * MM:.3f} mm: the target was mounted differently in this session (another probe, "
                   f"adapter or seat); give that session's tool point with --tool")


def _too_few(meas: Measurements, unknowns: int) -> bool:
    """Whether ``meas`` has fewer measured numbers than twice the ``unknowns`` a trial fits: with fewer, a fit of
    that many unknowns follows the noise (9 unknowns on 4 poses' 12 numbers leave 3) and judges nothing."""
    return meas.xyz.size < 2 * unknowns


def _tool_unjudged(robot: Robot, meas: Measurements) -> str:
    """The clause saying another tool point with the frame re-registered could not be tried on so few poses
    (:func:`_too_few`); '' when it could, or the robot has no tool point or frame."""
    unknowns = len(TOOL_NAMES) + len(robot.base_params())
    if not (robot.has_tool_point and robot.base_params()) or not _too_few(meas, unknowns):
        return ""
    return (f"; whether the target was also mounted differently cannot be judged with {len(meas)} pose(s): "
            f"{meas.xyz.size} measured numbers for {unknowns} unknowns (the frame and the tool point) need "
            f"{-(-2 * unknowns // 3)} poses at least")


def _data_mistake(robot: Robot, meas: Measurements, enough: float, rebased: bool, refit: tuple[str, ...] = ()) -> str:
    """The mistake in the file's columns or rows (:func:`kincal.identify.diagnosis.data_changes`) whose undoing
    brings the model's mean error within ``enough`` (m), judged as the held-out set was: the frame re-registered
    where it was (``rebased``), the robot parameters ``refit`` (a target's own point) re-fitted too; in words with
    the figure; the smallest error wins, ties the earlier candidate; '' when none does."""
    from .diagnosis import data_changes

    tried = []
    for cause, change in data_changes(robot, meas):
        changed = change(robot, meas, FitOptions())[1]  # a change of the data: the options pass through
        if not isinstance(changed, Measurements) or len(changed) == 0:  # a change that leaves no pose: nothing judged
            continue
        try:
            error = _mean_error(_judged_again(robot, changed, rebased, refit), changed)
        except (KincalError, ValueError, np.linalg.LinAlgError):
            continue
        tried.append((cause, error))
    fits = [(c, e) for c, e in tried if e <= enough]
    if not fits:
        return ""
    cause, error = fits[first_best([e for _, e in fits], maximize=False)]
    return f"{cause.cause} (undone, the mean error is {error * MM:.3f} mm): {cause.fix}"


def _judged_again(robot: Robot, meas: Measurements, rebased: bool, refit: tuple[str, ...]) -> Robot:
    """``robot`` re-fitted to ``meas`` as a held-out set is judged: its frame (``rebased``) and the robot parameters
    ``refit`` (a target's own point), kinematics fixed; as it is when neither."""
    if not refit:
        return refit_frame(robot, meas) if rebased else robot
    return calibrate(robot, meas, names=refit, base="estimate" if rebased else "fixed", diagnose=False).robot


def heldout_cause(robot: Robot, meas: Measurements, train_error: float, rebased: bool,
                  refit: tuple[str, ...] = ()) -> str:
    """Name the likely cause when a model misses a held-out session by far more than its training data.

    When ``robot`` misses ``meas`` by more than ``HELDOUT_RATIO`` (10) times its mean training error, tries
    in order: the frame not re-registered, another tool point, a scale error (length unit, tracker
    compensation); else says what else it may be.

    Parameters
    ----------
    robot : Robot
        The model as used on ``meas`` (registered to it or not).
    meas : Measurements
        The held-out session: tool positions (N, 3) m at joint values (N, n) rad (m for a prismatic joint).
    train_error : float
        The model's mean error on its training data, m.
    rebased : bool
        Whether the frame was already re-registered to ``meas``.
    refit : tuple of str, optional
        Robot parameters re-fitted to ``meas`` with it (a target defined anew: ``tool.x``, ``tool.y``,
        ``tool.z``), re-fitted so again where a mistake in the file's columns is tried (default none).

    Returns
    -------
    str
        A sentence naming the session, its error against the training error and the likely cause; ``""``
        when the error is within ``HELDOUT_RATIO`` times the training error (or ``train_error`` is not
        positive).

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import heldout_cause
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(20, seed=1)
    >>> heldout_cause(robot, kincal.simulate(robot, q, seed=2), 20e-6, rebased=False)
    ''
    >>> moved = kincal.simulate(robot.with_params({"base.x": 0.5}), q, seed=2)
    >>> print(heldout_cause(robot, moved, 20e-6, rebased=False))
    simulated ur5: mean error 499.99... mm is 25000x the training error (0.020 mm); with the measurement frame
    re-registered it is 0.0... mm: the tracker moved between sessions (leave out --same-frame so that each
    session's frame is registered)
    """
    error = _mean_error(robot, meas)
    if not train_error > 0 or error <= HELDOUT_RATIO * train_error:
        return ""
    head = (f"{meas.source}: mean error {error * MM:.3f} mm is {error / train_error:.0f}x the training error "
            f"({train_error * MM:.3f} mm)")
    enough = HELDOUT_RATIO * train_error  # a cause must bring the error within the limit, not just lower it
    few = 0 if rebased or not robot.base_params() else _distinct_below(robot, meas, 3)
    framed = _mean_error(refit_frame(robot, meas), meas) if not (rebased or few) and robot.base_params() else np.inf
    # registered (``rebased``), the frame was fitted with the wrong tool point: fit both again together
    trials = (("estimate", ""),) if rebased else (("fixed", ""), ("estimate", " (and the tracker moved: leave out "
                                                                               "--same-frame)"))
    for base, also in trials:
        tool = None if few else _tool_fix(robot, meas, base)
        if tool is not None and tool[0] <= enough and tool[0] < 0.5 * framed:  # the tool explains more than the frame
            return f"{head}; {tool[1]}{also}"
    if framed <= enough:
        return (f"{head}; with the measurement frame re-registered it is {framed * MM:.3f} mm: the tracker moved "
                f"between sessions (leave out --same-frame so that each session's frame is registered)"
                f"{_tool_unjudged(robot, meas)}")
    mistake = _data_mistake(robot, meas, enough, rebased, refit)
    if mistake:
        return f"{head}; {mistake}"
    return head + _unexplained(robot, meas, (error, train_error), framed, few) + ("" if few else _tool_unjudged(robot, meas))


def _distinct_below(robot: Robot, meas: Measurements, most: int) -> int:
    """The number of distinct poses of ``meas`` (the fit's repeat tolerance) when fewer than ``most``, else 0."""
    distinct = distinct_count(meas.q, repeat_tolerance(robot.joint_types, FitOptions().thresholds), most)
    return distinct if distinct < most else 0


def _unexplained(robot: Robot, meas: Measurements, errors: tuple[float, float], framed: float, few: int) -> str:
    """The rest of :func:`heldout_cause`'s sentence when neither the frame, a tool point nor a data mistake brings the
    error within the limit (``errors``: the held-out and the training mean error, m): what re-registering the frame
    gave (``framed``, m; inf when not tried), else why it could not be tried (``few``: the distinct poses, fewer than
    3), the scale."""
    moved = ""
    if np.isfinite(framed):
        moved = (f"; re-registering the measurement frame brings it to {framed * MM:.3f} mm (the tracker moved too: "
                 f"leave out --same-frame), still {framed / errors[1]:.0f}x the training error"
                 if framed < 0.5 * errors[0] else f"; re-registering the measurement frame leaves {framed * MM:.3f} mm")
    predicted = spread(robot.forward(meas.q))
    scale = spread(meas.xyz) / predicted if predicted > 0 else 1.0  # measured / predicted at the same joints
    if abs(np.log(scale)) > SCALE_TOL and few != 1:  # one distinct pose has no spread to judge
        return (f"{moved}; the measured positions spread {scale:.4f}x the model's at the same joints: a scale "
                f"error (length unit, tracker compensation, or joint columns in another unit), or another robot's data")
    if few:
        what = "a moved tracker, another tool point or a scale error" if few == 1 else \
            "no scale error explains it, and a moved tracker or another tool point"
        return (f"; {what} cannot be judged: "
                f"re-registering the measurement frame needs at least 3 distinct poses, the file has {few} "
                f"({len(meas)} row(s)); the tracker may have moved (measure 3 or more distinct poses and leave out "
                f"--same-frame), the target may sit elsewhere, the robot may have been disturbed (collision, "
                f"re-mastering), or the joint columns differ from the training data")
    return (f"{moved}; no moved frame, other tool point or scale error explains it: the poses may lie "
            f"outside the calibrated region (see the predicted σ), the robot may have been disturbed (collision, "
            f"re-mastering), or the joint columns differ from the training data")
