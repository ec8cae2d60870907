"""Parameter covariance of a least-squares fit: σ̂²(JᵀJ)⁻¹ with σ̂² = ‖r‖²/(M − K)."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..analysis.observability import column_norms


def spd_inverse(M: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive semi-definite matrix scaled to a unit diagonal: directly
    when a Cholesky factor shows it definite, else the pseudo-inverse by SVD (LAPACK's symmetric
    eigensolver failed to converge on such a matrix: condition 776, entries from 1 down to 1e-28)."""
    try:
        np.linalg.cholesky(M)
        return np.linalg.inv(M)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(M)


def normal_inverse(J: np.ndarray) -> np.ndarray:
    """(JᵀJ)⁻¹ (pseudo-inverse) computed on unit-norm columns (stable), in the original units (the
    normal matrix scaled, not J: no copy of J)."""
    d = column_norms(J)
    d[d == 0] = 1.0
    return spd_inverse((J.T @ J) / np.outer(d, d)) / np.outer(d, d)


def parameter_statistics(J: np.ndarray, r: np.ndarray, names: Sequence[str],
                         undetermined: Sequence[str] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Standard deviations (K,) and covariance (K, K) (m, rad) of the fitted parameters ``names`` (the
    columns of J) with residual r: σ̂²(JᵀJ)⁻¹. Names in ``undetermined`` get σ = inf and zero
    rows/columns in the covariance."""
    dof = max(r.size - J.shape[1], 1)
    without = set(undetermined)
    ok = np.array([n not in without for n in names], dtype=bool)
    cov = np.where(np.outer(ok, ok), normal_inverse(J) * (float(r @ r) / dof), 0.0)
    return np.where(ok, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.inf), cov
