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
    """(JᵀJ)⁻¹ (pseudo-inverse) computed on unit-norm columns (stable), in the original units."""
    d = column_norms(J)
    d[d == 0] = 1.0
    A = J / d
    return spd_inverse(A.T @ A) / np.outer(d, d)


def parameter_statistics(J: np.ndarray, r: np.ndarray, fitted: Sequence[str], names: Sequence[str],
                         undetermined: Sequence[str] = ()) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Standard deviations (K,), correlation (K, K), σ̂² and covariance (K, K) of ``names`` from a
    fit of ``fitted`` (the columns of J) with residual r. Names not fitted, or ``undetermined``, get
    σ = inf, no correlation and zero rows/columns in the covariance."""
    dof = max(r.size - J.shape[1], 1)
    sigma2 = float(r @ r) / dof
    return covariance_statistics(normal_inverse(J) * sigma2, sigma2, fitted, names, undetermined)


def covariance_statistics(cov: np.ndarray, sigma2: float, fitted: Sequence[str], names: Sequence[str],
                          undetermined: Sequence[str] = ()) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """:func:`parameter_statistics` from a covariance of the ``fitted`` columns (e.g. a posterior)."""
    pos = {n: k for k, n in enumerate(fitted)}
    at = np.array([-1 if n in set(undetermined) else pos.get(n, -1) for n in names], dtype=int)
    ok = at >= 0
    full = np.zeros((len(names), len(names)))
    full[np.ix_(ok, ok)] = cov[np.ix_(at[ok], at[ok])]
    sd = np.where(ok, np.sqrt(np.maximum(np.diag(full), 0.0)), np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = full / np.outer(sd, sd)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return sd, corr, sigma2, full
