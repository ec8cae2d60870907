"""How many poses to measure: Guo et al. 2024's minimum (eq. 18) and where the criterion flattens (Fig. 7)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .criteria import score
from .problem import DesignProblem


def minimum_poses(n_dof: int, k: int) -> int:
    """Eq. 18: m ≥ (n + 1)·k / 6 for n degrees of freedom and k parameters (and never below k/3,
    the count that gives as many equations as unknowns)."""
    return int(max(np.ceil((n_dof + 1) * k / 6.0), np.ceil(k / 3.0)))


@dataclass(frozen=True)
class PoseCountCurve:
    """Criterion of the first m poses of a random order, m = m_values; ``chosen`` is where the curve
    flattens: the smallest m after which adding ``window`` more poses gains less than ``rel_gain``."""

    m_values: np.ndarray
    values: np.ndarray
    chosen: int
    criterion: str
    flattened: bool = True  # False: no flattening within the curve; ``chosen`` is then its last m

    def to_dict(self) -> dict:
        return {"m": self.m_values.tolist(), "values": self.values.tolist(), "chosen": self.chosen,
                "criterion": self.criterion, "flattened": self.flattened}


def pose_count_curve(P: DesignProblem, criterion: str = "comprehensive", m_max: int = 100, seed: int | None = 0,
                     window: int = 10, rel_gain: float = 0.01) -> PoseCountCurve:
    """Guo et al. 2024, Fig. 7: criterion against the number of random poses, and the flattening point."""
    order = np.random.default_rng(seed).permutation(P.N)[:m_max]
    m_values = np.arange(1, order.size + 1)
    Ms = np.cumsum(np.einsum("nak,nal->nkl", P.J[order], P.J[order]), axis=0)
    values = np.array([float(score(Ms[i], i + 1, criterion)) for i in range(order.size)])
    for i in range(order.size - window):
        a, b = values[i], values[i + window]
        if np.isfinite(a) and a > 0 and np.isfinite(b) and (b - a) / abs(a) < rel_gain:
            return PoseCountCurve(m_values, values, int(m_values[i]), criterion)
    return PoseCountCurve(m_values, values, int(m_values[-1]), criterion, flattened=False)
