"""Identification: calibration problems, residuals, solvers (LM, PSO), robust weighting, covariance."""
from .applies import SCOPES, refuse_inapplicable
from .calibrate import calibrate, evaluate
from .options import METHODS, FitOptions, PSOOptions
from .problem import RESIDUALS, CalibrationProblem, build_problem
from .result import CalibrationResult, EvaluationStats
from .relevance import PRIORS
from .robust import LOSSES
from .select import ErrorModelChoice
from .observed_result import ObservationFit, stat_line
from .stacked import fit_observations, observation_identifiability
from .sessions import AS_CALIBRATED, REGISTERED, calibrate_sessions, heldout_cause, joined, refit_frame
from .verdict import Reason, Thresholds, Verdict

__all__ = ["calibrate", "evaluate", "METHODS", "FitOptions", "PSOOptions", "CalibrationProblem", "build_problem",
           "RESIDUALS", "CalibrationResult", "EvaluationStats", "LOSSES",
           "ErrorModelChoice", "Reason", "Thresholds", "Verdict", "refit_frame", "heldout_cause", "calibrate_sessions", "REGISTERED",
           "AS_CALIBRATED", "PRIORS", "fit_observations", "ObservationFit", "observation_identifiability", "stat_line",
           "SCOPES", "refuse_inapplicable", "joined"]
