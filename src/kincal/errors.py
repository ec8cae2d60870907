"""Exceptions raised by kincal. Every message says what was wrong and what to do.

This module is a leaf: every room may import it.
"""


class KincalError(Exception):
    """Base class of all kincal errors."""


class ModelError(KincalError):
    """A robot model or robot file is invalid, or a parameter name is unknown."""


class MeasurementError(KincalError):
    """Measurement data is unusable (missing columns, NaN rows, wrong units, too few rows)."""


class IdentifiabilityError(KincalError):
    """The requested parameters cannot be identified from the given poses."""


class ConvergenceError(KincalError):
    """An iterative solver failed to converge where a result is required."""
