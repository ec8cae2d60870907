"""kincal: robot kinematic calibration.

The public face (``kincal.__all__``) is what a user calls::

    robot = kincal.load_robot("ur5")
    meas = kincal.read_measurements("data.csv", robot, length_unit="mm", angle_unit="deg")
    res = kincal.calibrate(robot, meas)                      # or calibrate(robot, meas, kincal.FitOptions(...))
    stats = kincal.evaluate(res.robot, test_meas)

The rooms hold the rest, each with its own ``__all__``: :mod:`kincal.models`, :mod:`kincal.analysis`,
:mod:`kincal.design`, :mod:`kincal.identify`, :mod:`kincal.compensate`, :mod:`kincal.io`,
:mod:`kincal.report` (plots and the HTML page, loaded only when used), :mod:`kincal.studies`,
:mod:`kincal.units`. Importing kincal loads numpy and PyYAML, not SciPy, matplotlib or Jinja2.
"""
from __future__ import annotations

from .analysis import identifiability
from .compensate import Compensation, compensate
from .design import Design, DesignOptions, candidate_pool, select_poses
from .errors import ConvergenceError, IdentifiabilityError, KincalError, MeasurementError, ModelError
from .identify import CalibrationResult, EvaluationStats, FitOptions, Thresholds, Verdict, calibrate, evaluate
from .io import Measurements, read_joints, read_measurements, read_positions, write_measurements
from .models import (ErrorModel, ImplicitRobot, Joint, Parameters, Robot, SerialRobot, URDFRobot, bundled_robots,
                     export_robot, extend, load_robot, save_robot)
from .simulate import perturb, simulate

__version__ = "0.2.0"

__all__ = [
    # robots, their models and files (ImplicitRobot and Robot are the extension points)
    "Robot", "ImplicitRobot", "SerialRobot", "URDFRobot", "Joint", "Parameters", "ErrorModel",
    "load_robot", "save_robot", "bundled_robots", "export_robot", "extend",
    # measurements
    "Measurements", "read_measurements", "read_joints", "read_positions", "write_measurements",
    # identification and its results
    "identifiability", "calibrate", "evaluate", "FitOptions", "CalibrationResult", "EvaluationStats", "Thresholds",
    "Verdict",
    # pose design, compensation, simulation, the report
    "select_poses", "DesignOptions", "Design", "candidate_pool", "compensate", "Compensation", "simulate", "perturb",
    "build_report",
    # errors
    "KincalError", "ModelError", "MeasurementError", "IdentifiabilityError", "ConvergenceError",
]


def __getattr__(name: str):
    if name == "build_report":  # the report room is loaded on first use (matplotlib, Jinja2)
        from .report import build_report
        return build_report
    raise AttributeError(f"module 'kincal' has no attribute '{name}'")
