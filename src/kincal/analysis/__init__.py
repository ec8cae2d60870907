"""Analysis of stacked error Jacobians: identifiability (and, later, observability indices)."""
from .identifiability import Identifiability, identifiability, stacked_jacobian

__all__ = ["Identifiability", "identifiability", "stacked_jacobian"]
