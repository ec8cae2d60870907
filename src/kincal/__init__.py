"""kincal: robot kinematic calibration.

The stable API::

    robot = kincal.load_robot("ur5")
    meas = kincal.read_measurements("data.csv", robot, length_unit="mm", angle_unit="deg")
    res = kincal.calibrate(robot, meas)
    stats = kincal.evaluate(res.robot, test_meas)
"""
from .analysis import BASE_MODES, Identifiability, free_parameters, identifiability
from .errors import ConvergenceError, IdentifiabilityError, KincalError, MeasurementError, ModelError
from .identify import LOSSES, RESIDUALS, CalibrationProblem, CalibrationResult, EvaluationStats, calibrate, evaluate
from .identify import METHODS as CALIBRATION_METHODS
from .io import (Measurements, read_joints, read_measurements, read_positions, write_joints, write_measurements,
                 write_residuals)
from .identify.verdict import Reason, Thresholds, Verdict
from .analysis.uncertainty import EXTRAPOLATION_RATIO, ModelUncertainty, load_uncertainty
from .models import (Joint, Parameters, Robot, SerialRobot, URDFRobot, bundled_robots, load_calibration_record,
                     load_robot, save_robot,
                     export_robot, ur_calibration, urdf_text)
from .models import FORMATS as EXPORT_FORMATS
from .simulate import perturb, simulate
from .design import Design, candidate_pool, design_bound, select_poses
from .analysis.separation import Separation, separate_ill_conditioned
from .analysis.sensitivity import Sensitivity, sensitivity
from .compensate import Compensation, compensate
from .compensate.verify import Verification, VerificationPlan, verification_plan
from .studies import Seed1Study, seed1_study
from .models.terms import MODELS as ERROR_MODELS
from .models.terms import parse_model
from .models.terms import ExtendedRobot, extend
from .report import Report, build_report, evaluation_figures, figure_set, json_path_for, save_figure

__version__ = "0.1.0"

__all__ = [
    "BASE_MODES", "free_parameters", "LOSSES", "RESIDUALS", "CALIBRATION_METHODS", "CalibrationProblem",
    "ERROR_MODELS", "parse_model", "ExtendedRobot", "extend", "URDFRobot", "load_calibration_record", "build_report", "figure_set", "evaluation_figures", "Report", "json_path_for", "save_figure", "ur_calibration", "urdf_text", "export_robot", "EXPORT_FORMATS", "Seed1Study", "seed1_study", "write_residuals", "Reason", "Thresholds", "Verdict",
    "EXTRAPOLATION_RATIO", "ModelUncertainty", "load_uncertainty", "Identifiability", "identifiability", "ConvergenceError", "IdentifiabilityError", "KincalError",
    "MeasurementError", "ModelError", "CalibrationResult", "EvaluationStats", "calibrate", "evaluate",
    "Measurements", "read_joints", "read_measurements", "read_positions", "write_joints", "write_measurements", "Joint", "Parameters", "Robot", "SerialRobot",
    "bundled_robots", "load_robot", "save_robot", "perturb", "simulate", "Design", "candidate_pool",
    "design_bound", "select_poses", "Separation", "separate_ill_conditioned", "Sensitivity", "sensitivity",
    "Compensation", "compensate", "Verification", "VerificationPlan", "verification_plan",
]
