"""Design criteria (larger is better) evaluated on information matrices M = JᵀJ, batched."""
from __future__ import annotations

import numpy as np

from ..analysis.observability import comprehensive_index, indices_from_singular_values

CRITERIA = ("D", "A", "E", "I", "O1", "O2", "O3", "O4", "O5", "O6", "comprehensive")
SINGULAR = 1e-12  # smallest eigenvalue of M below this times its mean: singular (criteria I and IMSE)


def score(M: np.ndarray, m: int, criterion: str, B: np.ndarray | None = None) -> np.ndarray:
    """Criterion of information matrices M (..., k, k) of m-pose designs; larger is better.

    "D" is log det M; "I" is −tr(M⁻¹B)/tr(B) (minus the average prediction variance over the region whose
    mean information is B); the others ("A", "E", "O1"…"O6", "comprehensive") come from the singular values
    of the stacked Jacobian, √eig(M) (:func:`kincal.analysis.observability.indices_from_singular_values`,
    :func:`kincal.analysis.observability.comprehensive_index`).

    Parameters
    ----------
    M : ndarray, shape (..., k, k)
        Information matrices JᵀJ of the designs (any stack of them), in the problem's units.
    m : int
        Number of poses of each design (the indices that divide by it, e.g. O1).
    criterion : str
        One of :data:`CRITERIA`: "D", "A", "E", "I", "O1"…"O6", "comprehensive".
    B : ndarray, shape (k, k), optional
        Mean information over the region of use; needed by "I" only.

    Returns
    -------
    ndarray, shape (...)
        The criterion of each matrix (a 0-d array for one matrix). A singular M scores −inf for "D", "A"
        and "I", 0 for the others.

    Raises
    ------
    ValueError
        When ``criterion`` is not one of ``CRITERIA`` (IMSE included: it needs the design's left-out terms), or
        is "I" and ``B`` is None.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.design import score
    >>> M = np.diag([4.0, 1.0])
    >>> round(float(score(M, 2, "D")), 6)  # log det M = log 4
    1.386294
    >>> score(np.stack([M, 2 * M]), 2, "D").round(4)  # a stack (2, 2, 2) gives (2,)
    array([1.3863, 2.7726])
    >>> float(score(M, 2, "I", B=np.eye(2)))  # −(1/4 + 1)/2
    -0.625
    >>> float(score(np.zeros((2, 2)), 2, "D"))
    -inf
    """
    if criterion not in CRITERIA:
        raise ValueError(f"criterion '{criterion}': score takes one of {', '.join(CRITERIA)} (IMSE scores a "
                         f"design with its left-out terms: select_poses)")
    M = np.asarray(M, dtype=float)
    if criterion == "D":
        sign, val = np.linalg.slogdet(M)
        return np.where(sign > 0, val, -np.inf)
    if criterion == "I":
        if B is None:
            raise ValueError("criterion 'I' needs B, the mean information over the region")
        with np.errstate(all="ignore"):
            try:
                X = np.linalg.solve(M, np.broadcast_to(B, M.shape))
                val = -np.trace(X, axis1=-2, axis2=-1) / np.trace(B)
            except np.linalg.LinAlgError:
                return np.full(M.shape[:-2], -np.inf)
        ok = np.linalg.eigvalsh(M)[..., 0] > SINGULAR * np.trace(M, axis1=-2, axis2=-1) / M.shape[-1]
        return np.where(ok & np.isfinite(val), val, -np.inf)
    lam = np.clip(np.linalg.eigvalsh(M), 0.0, None)  # ascending
    singular = lam[..., 0] <= 1e-14 * np.maximum(lam[..., -1], 1e-300)  # rank-deficient: a zero σ
    lam[..., 0] = np.where(singular, 0.0, lam[..., 0])
    s = np.sqrt(lam)[..., ::-1]
    return np.asarray(comprehensive_index(s, m) if criterion == "comprehensive" else
                      indices_from_singular_values(s, m)[criterion])
