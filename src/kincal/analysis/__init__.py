"""Analysis of stacked error Jacobians: identifiability, observability indices, GCN separation,
sensitivity, and the prediction uncertainty of a calibrated model."""
from .identifiability import BASE_MODES, RANK_TOL, Identifiability, free_parameters, identifiability, stacked_jacobian
from .sensitivity import Sensitivity, sensitivity
from .separation import Separation, separate_ill_conditioned
from .uncertainty import EXTRAPOLATION_RATIO, ModelUncertainty, envelope_warning, load_uncertainty

__all__ = ["BASE_MODES", "RANK_TOL", "Identifiability", "free_parameters", "identifiability", "stacked_jacobian",
           "Sensitivity", "sensitivity", "Separation", "separate_ill_conditioned", "EXTRAPOLATION_RATIO",
           "ModelUncertainty", "load_uncertainty", "envelope_warning"]
