"""A noise model that cannot make a fit worse: stated σ plus what the model cannot describe.

A tracker's σ per sample (its repeatability, 2–60 µm) are measurement noise. The residuals of a
calibrated model also hold what the model cannot describe (0.1–0.3 mm on a real arm), the same at
every sample whatever the instrument's σ. Weighting by 1/σᵢ² alone lets the few most precise samples
steer the fit by their model error; weighting by 1/(σᵢ² + s²) with s² estimated from the residuals
gives the stated σ their weight only where they dominate. s² is the moment estimate:
Σ rᵢ² / (σᵢ² + s²) = degrees of freedom (0 when the stated σ explain the residuals).
"""
from __future__ import annotations

import numpy as np

ROUNDS = 3  # fits with the extra variance re-estimated (it settles within one or two)
SETTLED = 0.05  # relative change of s that ends the rounds


def extra_variance(r2: np.ndarray, var: np.ndarray, dof: float) -> float:
    """s² ≥ 0 (m² or rad²) with Σ r2 / (var + s²) = dof: the variance the stated ``var`` (same shape
    as the squared residuals ``r2``) do not explain; 0 when they explain it."""
    r2, var = np.asarray(r2, float).ravel(), np.asarray(var, float).ravel()
    if dof <= 0 or float(np.sum(r2 / var)) <= dof:
        return 0.0
    lo, hi = 0.0, float(np.sum(r2)) / dof  # at hi every term is below r2/hi: the sum is below dof
    for _ in range(200):  # bisection on a decreasing function; 200 halvings reach round-off
        mid = 0.5 * (lo + hi)
        if float(np.sum(r2 / (var + mid))) > dof:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)


def relative_weights(std: np.ndarray, s2: float) -> np.ndarray:
    """(N, 3) weights 1/(σ² + s²) scaled to a median of 1 (the fit's σ̂ stays in m)."""
    var = np.asarray(std, float) ** 2 + s2
    return float(np.median(var)) / var
