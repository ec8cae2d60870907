"""Parameter covariance of a least-squares fit: σ̂²(JᵀJ)⁻¹ with σ̂² = ‖r‖²/(M − K)."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..analysis.observability import column_norms


def spd_inverse(M: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive semi-definite matrix M, computed on M scaled to a unit
    diagonal by ``d`` (its diagonal's square roots; 0 taken as 1), in M's units: directly when a
    Cholesky factor shows it definite, else the pseudo-inverse by SVD (LAPACK's symmetric
    eigensolver failed to converge on such a matrix: condition 776, entries from 1 down to 1e-28)."""
    d = np.where(d == 0, 1.0, d)
    s = np.outer(d, d)
    A = M / s
    try:
        np.linalg.cholesky(A)
        return np.linalg.inv(A) / s
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A) / s


def normal_inverse(J: np.ndarray) -> np.ndarray:
    """(JᵀJ)⁻¹ (pseudo-inverse) computed on unit-norm columns (stable), in the original units (the
    normal matrix scaled, not J: no copy of J)."""
    return spd_inverse(J.T @ J, column_norms(J))


def parameter_statistics(J: np.ndarray, r: np.ndarray, names: Sequence[str], undetermined: Sequence[str] = (),
                         drift: Sequence[tuple[str, float, Sequence[tuple[str, float]]]] = ()
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Standard deviations (K,) and covariance (K, K) (m, rad) of the fitted parameters ``names`` (the
    columns of J) with residual r: σ̂²(JᵀJ)⁻¹. Names in ``undetermined`` get σ = inf, the others' covariance is
    taken with those where they are (their columns left out). Each (name, variance, combination) in ``drift`` is an
    undetermined parameter left anywhere along its confound (a particle swarm's search box: the variance of its
    value) and the determined parameters it acts like, with their coefficients c: the covariance gains variance ·
    v vᵀ along the direction v that moves it by 1 and each of those by −c, which leaves every prediction as it is
    (its rows are the undetermined parameter's only entries)."""
    dof = max(r.size - J.shape[1], 1)
    without = set(undetermined)
    ok = np.array([n not in without for n in names], dtype=bool)
    cov = np.zeros((len(names), len(names)))
    cov[np.ix_(ok, ok)] = normal_inverse(J[:, ok]) * (float(r @ r) / dof)
    where = {n: k for k, n in enumerate(names)}
    for name, variance, combination in drift:
        v = np.zeros(len(names))
        v[where[name]] = 1.0
        for n, coefficient in combination:
            if n in where and ok[where[n]]:
                v[where[n]] = -coefficient
        cov += variance * np.outer(v, v)
    return np.where(ok, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.inf), cov
