"""Identification: calibration problems, residuals, solvers (LM, PSO), robust weighting, covariance."""
from .calibrate import METHODS, calibrate, check_options, evaluate
from .problem import CalibrationProblem, build_problem
from .residuals import RESIDUALS, CartesianResidual, JointResidual
from .result import CalibrationResult, EvaluationStats
from .robust import LOSSES

__all__ = ["METHODS", "calibrate", "check_options", "evaluate", "CalibrationProblem", "build_problem", "RESIDUALS",
           "CartesianResidual", "JointResidual", "CalibrationResult", "EvaluationStats", "LOSSES"]
