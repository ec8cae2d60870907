"""Observability indices of a stacked position Jacobian, and the seed paper's entropy-weighted index.

All indices are functions of the singular values σ₁ ≥ … ≥ σ_k of the stacked Jacobian J (3m × k) of
m poses and k parameters. They depend on the units of J's columns: a length column is in m/m, an
angle column in m/rad. To compare designs fairly, scale the columns once with a fixed vector (e.g.
:func:`column_scale` of the candidate pool) and use the same scale for every design; the
D-efficiency of :mod:`kincal.design` does not depend on the scale at all.

Indices (larger is better), after Borm & Menq, Driels & Pathre, Nahvi & Hollerbach and the seed:
    O1 = (σ₁⋯σ_k)^(1/k) / √m          (eq. 9; D-optimality)
    O2 = σ_min / σ_max                 (inverse condition number)
    O3 = σ_min                         (E-optimality)
    O4 = σ_min² / σ_max                (noise amplification index)
    O5 = 1 / Σ 1/σᵢ                    (eq. 10)
    O6 = (Σ σᵢ⁻² / k)^(-1/2)           (eq. 11; A-optimality, Φ_p with p = 2)
    D = log det JᵀJ, A = −tr (JᵀJ)⁻¹, E = λ_min(JᵀJ)
A rank-deficient J gives 0 for O1…O6 and E, −inf for D and A.
"""
from __future__ import annotations

import numpy as np

INDICES = ("O1", "O2", "O3", "O4", "O5", "O6", "D", "A", "E")
SINGULAR = 1e-300


def column_scale(J: np.ndarray) -> np.ndarray:
    """(k,) factors that give each column of a stacked Jacobian (3m × k) a unit RMS norm per pose."""
    J = np.asarray(J, dtype=float)
    rms = np.sqrt(np.sum(J**2, axis=0) / max(J.shape[0] // 3, 1))
    return 1.0 / np.where(rms > 0, rms, 1.0)


def singular_values(J: np.ndarray) -> np.ndarray:
    """Singular values of J, descending."""
    return np.linalg.svd(np.asarray(J, dtype=float), compute_uv=False)


def indices_from_singular_values(s: np.ndarray, m: int) -> dict[str, float]:
    """All indices from singular values ``s`` (k,) of a design of ``m`` poses."""
    s = np.sort(np.asarray(s, dtype=float))[::-1]
    k = s.size
    if k == 0 or s[-1] <= SINGULAR:
        return {"O1": 0.0, "O2": 0.0, "O3": 0.0, "O4": 0.0, "O5": 0.0, "O6": 0.0,
                "D": -np.inf, "A": -np.inf, "E": 0.0}
    return {
        "O1": float(np.exp(np.mean(np.log(s))) / np.sqrt(m)),
        "O2": float(s[-1] / s[0]),
        "O3": float(s[-1]),
        "O4": float(s[-1] ** 2 / s[0]),
        "O5": float(1.0 / np.sum(1.0 / s)),
        "O6": float(np.mean(s**-2.0) ** -0.5),
        "D": float(2.0 * np.sum(np.log(s))),
        "A": float(-np.sum(s**-2.0)),
        "E": float(s[-1] ** 2),
    }


def observability(J: np.ndarray, m: int | None = None) -> dict[str, float]:
    """All indices of a stacked Jacobian J (3m × k); m defaults to rows / 3."""
    J = np.asarray(J, dtype=float)
    return indices_from_singular_values(singular_values(J), m if m is not None else J.shape[0] // 3)


def entropy_weights(s: np.ndarray) -> np.ndarray:
    """Entropy weights (eq. 12–13) of the three feature groups {σᵢ}, {1/σᵢ}, {1/σᵢ²}: (3,), sum 1.

    Each group is normalised to proportions pᵢ = xᵢ / Σx, its entropy S = −Σ pᵢ ln pᵢ / ln k lies in
    [0, 1] (1: all σ equal, no information to discriminate), and the weights are (1 − S_j) / Σ(1 − S).
    When every group has entropy 1 (all σ equal) the weights are equal, 1/3 each. The weights do not
    change when all σ are scaled by the same factor.
    """
    s = np.asarray(s, dtype=float)
    k = s.size
    if k < 2 or np.any(s <= SINGULAR):
        return np.full(3, 1.0 / 3.0)
    X = np.column_stack([s, 1.0 / s, 1.0 / s**2])
    P = X / X.sum(axis=0)
    S = -np.sum(P * np.log(P), axis=0) / np.log(k)
    d = np.clip(1.0 - S, 0.0, None)
    return d / d.sum() if d.sum() > 1e-15 else np.full(3, 1.0 / 3.0)


def comprehensive_index(s: np.ndarray, m: int) -> float:
    """The seed's entropy-weighted comprehensive index (eq. 12–15), in [0, 3).

    Interpretation (the paper is ambiguous here): the weighted matrix D = X·diag(w) scales each
    index by its weight, so the weighted indices are w₁·O1, w₂·O5, w₃·O6, and
    func = (2/π)·Σ arctan(wⱼ·Oⱼ) (eq. 15). Substituting D's columns literally into eq. 10–11 would
    divide O5 and O6 by their weights, so a larger weight would lower its index, which defeats the
    weighting. Singular designs score 0.
    """
    s = np.asarray(s, dtype=float)
    ind = indices_from_singular_values(s, m)
    if ind["O3"] == 0.0:
        return 0.0
    w = entropy_weights(s)
    o = np.array([ind["O1"], ind["O5"], ind["O6"]])
    return float(2.0 / np.pi * np.sum(np.arctan(w * o)))
