"""A noise model that cannot make a fit worse: stated σ plus what the model cannot describe.

A tracker's σ per sample (its repeatability, 2–60 µm) are measurement noise. The residuals of a
calibrated model also hold what the model cannot describe (0.1–0.3 mm on a real arm), the same at
every sample whatever the instrument's σ. Weighting by 1/σᵢ² alone lets the few most precise samples
steer the fit by their model error; weighting by 1/(σᵢ² + s²) with s² estimated from the residuals
gives the stated σ their weight only where they dominate. s² is estimated from the median of
rᵢ² / (σᵢ² + s²), so a few outliers are named as outliers, not taken for model error.
"""
from __future__ import annotations

from statistics import NormalDist
from typing import Callable

import numpy as np


def extra_variance(r2: np.ndarray, var: np.ndarray, dof: float) -> float:
    """s² ≥ 0 (m² or rad²): the variance the stated ``var`` (same shape as the squared residual
    components ``r2``) do not explain, estimated robustly so that a few outliers do not pass for model
    error: the median of r2 / (var + s²) equals the median of χ²₁ scaled by ``dof`` / n (the degrees of
    freedom the fit left); 0 when the stated σ explain the residuals (χ²/dof within SIGNIFICANT
    standard errors of 1: the stated σ are kept as they are unless the data clearly contradict them)."""
    r2, var = np.asarray(r2, float).ravel(), np.asarray(var, float).ravel()
    if dof <= 0 or r2.size == 0:
        return 0.0
    target = CHI2_1_MEDIAN * dof / r2.size
    chi2 = float(np.sum(r2 / var)) / dof  # 1 ± √(2/dof) when the stated σ are right
    if chi2 <= 1.0 + SIGNIFICANT * np.sqrt(2.0 / dof) or float(np.median(r2 / var)) <= target:
        return 0.0
    hi = float(np.max(r2)) / target  # at hi every ratio is below the target
    return decreasing_root(lambda s2: float(np.median(r2 / (var + s2))) - target, 0.0, hi, 1e-12)


def decreasing_root(f: Callable[[float], float], lo: float, hi: float, rtol: float = 0.0) -> float:
    """The root of a decreasing ``f`` in [lo, hi] by bisection: 200 halvings (round-off), or until the
    bracket is within ``rtol`` of its upper end."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
        if hi - lo <= rtol * hi:
            break
    return 0.5 * (lo + hi)


SIGNIFICANT = 3.0  # the residuals must exceed the stated σ by this many standard errors of χ²/dof
CHI2_1_MEDIAN = NormalDist().inv_cdf(0.75) ** 2  # the median of χ² with one degree of freedom (0.4549)
