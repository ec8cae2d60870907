"""The differential diagnosis of a doubtful fit of observation sets, on the positions the data have.

The common input mistakes (units, joint signs, zeros and order, mirrored or shifted positions,
another robot, a few bad poses: :mod:`kincal.identify.diagnosis`) show in the measured positions
whatever else a sample measures, so a file of points or 6-D poses in the robot's frame is screened
as position data by the one diagnosis, and its finding is the first reason of the fit's verdict.
Markers (no one tool point), sockets and planes (no absolute position) and sessions in their own
frames are not screened.
"""
from __future__ import annotations

import dataclasses

from ..io.measurements import Measurements
from ..models.robot import Robot
from ..observe.sessions import InSession
from .diagnosis import TRIGGERS, diagnose
from .result import CalibrationResult
from .verdict import Reason, Verdict

MIN_SAMPLES = 10  # fewer positions screen nothing reliably


def diagnosed(fit: CalibrationResult, robot: Robot, calibrate) -> CalibrationResult:
    """``fit`` with the diagnosis of its positions as the first reason of its verdict, when the
    verdict doubts the data (:data:`TRIGGERS`) and one file has points or poses in the robot's frame;
    ``robot`` is the model as given (the position fit registers its own frame), ``calibrate`` the
    position fit (passed in: it is this module's caller)."""
    if not any(r.code in TRIGGERS for r in fit.verdict.reasons):
        return fit
    sets = [o for o in fit.observations if o.kind in ("point", "pose") and not isinstance(o, InSession)]
    if len(sets) != 1 or len(sets[0]) < MIN_SAMPLES:
        return fit
    obs = sets[0]
    q, xyz = obs.positions()
    meas = Measurements(q, xyz, robot.joint_names, obs.source, obs.rows)
    found = diagnose(calibrate(robot, meas, diagnose=False))
    best = found.best
    reason = Reason(fit.verdict.status, f"cause-{best.code}" if best else "cause-unknown",
                    f"{found.message()} (screened on the measured positions)")
    return dataclasses.replace(fit, verdict=Verdict(fit.verdict.status, (reason, *fit.verdict.reasons)),
                               diagnosis=found)
