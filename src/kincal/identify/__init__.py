"""Identification: calibration problems, residuals, solvers (LM, PSO), robust weighting, covariance."""
from .applies import SCOPES, refuse_inapplicable
from ..analysis.changes import ALPHA
from .change import Calibrated, ChangeTest, Suspect, check, compare
from .calibrate import (RESIDUALS, calibrate, calibrate_sessions, evaluate, fit_observations, held_out_nominal,
                        held_out_stats)
from .fitting import ABSOLUTE
from .options import METHODS, PRIOR_CHOICES, FitOptions, PSOOptions
from .positions import EvaluationStats, joined
from .result import CalibrationResult, stat_change, stat_line, trained_setup, unseen_note
from .relevance import PRIORS
from .robust import LOSSES
from .select import ErrorModelChoice
from .stacked import MOUNTED, observation_identifiability
from .sessions import AS_CALIBRATED, REGISTERED, heldout_cause, refit_frame, set_cause
from .registration import register_mounting
from .verdict import Reason, Thresholds, Verdict

__all__ = ["calibrate", "evaluate", "METHODS", "FitOptions", "PSOOptions", "RESIDUALS", "CalibrationResult", "EvaluationStats", "LOSSES",
           "ErrorModelChoice", "Reason", "Thresholds", "Verdict", "refit_frame", "heldout_cause", "calibrate_sessions", "REGISTERED",
           "AS_CALIBRATED", "PRIORS", "PRIOR_CHOICES", "fit_observations", "observation_identifiability", "stat_change",
           "stat_line", "trained_setup", "unseen_note", "SCOPES", "refuse_inapplicable", "joined", "ABSOLUTE",
           "held_out_stats", "held_out_nominal", "register_mounting", "set_cause",
           "ALPHA", "MOUNTED", "Calibrated", "ChangeTest", "Suspect", "check", "compare"]
