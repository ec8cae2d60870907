"""Observability indices of a stacked position Jacobian, and Guo et al. 2024's entropy-weighted index.

All indices are functions of the singular values σ₁ ≥ … ≥ σ_k of the stacked Jacobian J (3m × k) of
m poses and k parameters. They depend on the units of J's columns: a length column is in m/m, an
angle column in m/rad. To compare designs fairly, scale the columns once with a fixed vector (e.g.
:func:`column_scale` of the candidate pool) and use the same scale for every design; the
D-efficiency of :mod:`kincal.design` does not depend on the scale at all.

Indices (larger is better), after Borm & Menq, Driels & Pathre, Nahvi & Hollerbach and Guo et al. 2024:
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

SINGULAR = 1e-300
ZERO_COLUMN = 1e-12  # per-pose RMS (m per unit) below which a column has no effect at all


def column_norms(J: np.ndarray) -> np.ndarray:
    """(k,) Euclidean norms of the columns of J (M, k), summed in place by ``einsum``: no (M, k)
    temporary of squares (10⁵ poses, 33 columns: 5 ms against 34 ms), no loop over the columns."""
    J = np.asarray(J, dtype=float)
    return np.sqrt(np.einsum("ij,ij->j", J, J))


def live_columns(J: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(k,) bool: columns of a stacked Jacobian (3m × k), times ``scale``, whose per-pose RMS exceeds
    ``ZERO_COLUMN``."""
    return column_norms(J) * scale / np.sqrt(max(np.shape(J)[0] // 3, 1)) > ZERO_COLUMN


def column_scale(J: np.ndarray) -> np.ndarray:
    """(k,) factors that give each column of a stacked Jacobian (3m × k) a unit RMS norm per pose.

    A column with no effect (see :func:`live_columns`) keeps the factor 1: scaling rounding noise up
    to unit size would make an unidentifiable parameter look well conditioned.
    """
    rms = column_norms(J) / np.sqrt(max(np.shape(J)[0] // 3, 1))
    return np.where(rms > ZERO_COLUMN, 1.0 / np.where(rms > 0, rms, 1.0), 1.0)  # rms > ZERO_COLUMN: live_columns


def indices_from_singular_values(s: np.ndarray, m: int) -> dict:
    """All indices from singular values ``s`` (k,) of a design of ``m`` poses; a stack (n, k) of
    singular values gives (n,) arrays."""
    s = -np.sort(-np.asarray(s, dtype=float), axis=-1)
    if s.shape[-1] == 0:
        s = np.zeros(s.shape[:-1] + (1,))
    sing = s[..., -1] <= SINGULAR
    with np.errstate(divide="ignore", invalid="ignore"):
        safe = np.where(sing[..., None], 1.0, s)
        out = {
            "O1": np.exp(np.mean(np.log(safe), axis=-1)) / np.sqrt(m),
            "O2": safe[..., -1] / safe[..., 0],
            "O3": safe[..., -1],
            "O4": safe[..., -1] ** 2 / safe[..., 0],
            "O5": 1.0 / np.sum(1.0 / safe, axis=-1),
            "O6": np.mean(safe**-2.0, axis=-1) ** -0.5,
            "D": 2.0 * np.sum(np.log(safe), axis=-1),
            "A": -np.sum(safe**-2.0, axis=-1),
            "E": safe[..., -1] ** 2,
        }
    worst = {"D": -np.inf, "A": -np.inf}
    for key, val in out.items():
        val = np.where(sing, worst.get(key, 0.0), val)
        out[key] = float(val) if val.ndim == 0 else val
    return out


def observability(J: np.ndarray, m: int | None = None) -> dict[str, float]:
    """All indices of a stacked Jacobian J (3m × k); m defaults to rows / 3."""
    J = np.asarray(J, dtype=float)
    return indices_from_singular_values(np.linalg.svd(J, compute_uv=False), m if m is not None else J.shape[0] // 3)


def entropy_weights(s: np.ndarray) -> np.ndarray:
    """Entropy weights (eq. 12–13) of the three feature groups {σᵢ}, {1/σᵢ}, {1/σᵢ²}: (3,), sum 1
    (or (n, 3) for a stack (n, k) of singular values).

    Each group is normalised to proportions pᵢ = xᵢ / Σx, its entropy S = −Σ pᵢ ln pᵢ / ln k lies in
    [0, 1] (1: all σ equal, no information to discriminate), and the weights are (1 − S_j) / Σ(1 − S).
    When every group has entropy 1 (all σ equal) the weights are equal, 1/3 each. The weights do not
    change when all σ are scaled by the same factor. Singular designs get equal weights.
    """
    s = np.asarray(s, dtype=float)
    k = s.shape[-1]
    if k < 2:
        return np.full(s.shape[:-1] + (3,), 1.0 / 3.0)
    bad = np.any(s <= SINGULAR, axis=-1)
    safe = np.where(bad[..., None], 1.0, s)
    X = np.stack([safe, 1.0 / safe, 1.0 / safe**2], axis=-1)  # (..., k, 3)
    P = X / X.sum(axis=-2, keepdims=True)
    S = -np.sum(P * np.log(P), axis=-2) / np.log(k)
    d = np.clip(1.0 - S, 0.0, None)
    tot = d.sum(axis=-1, keepdims=True)
    w = np.where(tot > 1e-15, d / np.where(tot > 1e-15, tot, 1.0), 1.0 / 3.0)
    return np.where(bad[..., None], 1.0 / 3.0, w)


def comprehensive_index(s: np.ndarray, m: int):
    """Guo et al. 2024's entropy-weighted comprehensive index (eq. 12–15), in [0, 3) (array for a stack).

    Interpretation (the paper is ambiguous here): the weighted matrix D = X·diag(w) scales each
    index by its weight, so the weighted indices are w₁·O1, w₂·O5, w₃·O6, and
    func = (2/π)·Σ arctan(wⱼ·Oⱼ) (eq. 15). Substituting D's columns literally into eq. 10–11 would
    divide O5 and O6 by their weights, so a larger weight would lower its index, which defeats the
    weighting. Singular designs score 0.
    """
    ind = indices_from_singular_values(s, m)
    w = entropy_weights(s)
    o = np.stack([np.asarray(ind["O1"]), np.asarray(ind["O5"]), np.asarray(ind["O6"])], axis=-1)
    val = 2.0 / np.pi * np.sum(np.arctan(w * o), axis=-1)
    val = np.where(np.asarray(ind["O3"]) == 0.0, 0.0, val)
    return float(val) if val.ndim == 0 else val
