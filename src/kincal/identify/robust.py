"""Robust losses by iteratively reweighted least squares on each sample's whitened residual block
(a point's three rows, a 6-D pose's six, a marker sample's seen markers, a seat's three).

Weights follow scipy's conventions, z = (‖rᵢ‖/f_scale)²: "huber" ρ'(z) = 1 for z ≤ 1, z^-½ beyond;
"soft_l1" ρ'(z) = (1 + z)^-½. Without an ``f_scale`` it is 3 robust sigmas of the current residuals
(the median of a d-dimensional Gaussian norm is about √(d (1 − 2/(9d))³) σ: 1.54 σ for d = 3),
re-estimated at every reweighting.
"""
from __future__ import annotations

import numpy as np

LOSSES = ("linear", "huber", "soft_l1")
MAX_IRLS = 20
WEIGHT_TOL = 1e-4  # reweighting stops when no weight changes by more than this


def chi_median(d: np.ndarray) -> np.ndarray:
    """The median of the norm of d independent unit Gaussians (Wilson–Hilferty; within 2 % for d ≥ 1)."""
    d = np.asarray(d, float)
    return np.sqrt(d * (1.0 - 2.0 / (9.0 * d)) ** 3)


def block_weights(r: np.ndarray, owner: np.ndarray, n: int, loss: str, scale: float | None = None) -> np.ndarray:
    """(M,) IRLS row factors √ρ'(z) for the whitened residual r (M,): each of the ``n`` samples' block
    (the rows whose ``owner`` is that sample; −1: a row of no sample, factor 1) weighed by its norm
    against ``scale`` (whitened), by default 3 robust σ, σ the median over samples of norm /
    :func:`chi_median` of its rows."""
    mine = owner >= 0
    norms = np.sqrt(np.bincount(owner[mine], r[mine] ** 2, minlength=n))
    dims = np.bincount(owner[mine], minlength=n)
    has = dims > 0
    sigma = float(np.median(norms[has] / chi_median(dims[has]))) if has.any() else 0.0
    w = np.ones(n)  # the IRLS weights ρ'(z), z = (‖rᵢ‖/scale)² (linear: 1)
    z = (norms[has] / (max(3.0 * sigma, 1e-12) if scale is None else scale)) ** 2
    if loss == "huber":
        w[has] = np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
    elif loss == "soft_l1":
        w[has] = 1.0 / np.sqrt(1.0 + z)
    out = np.ones(r.size)
    out[mine] = np.sqrt(w[owner[mine]])
    return out
