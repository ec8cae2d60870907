"""Analysis of stacked error Jacobians: identifiability, observability indices, separation, sensitivity."""
from .identifiability import BASE_MODES, Identifiability, free_parameters, identifiability, stacked_jacobian

__all__ = ["BASE_MODES", "Identifiability", "free_parameters", "identifiability", "stacked_jacobian"]
