"""Identification: Levenberg–Marquardt calibration, frame registration, covariance, evaluation."""
from .calibrate import calibrate, evaluate
from .result import CalibrationResult, EvaluationStats

__all__ = ["calibrate", "evaluate", "CalibrationResult", "EvaluationStats"]
