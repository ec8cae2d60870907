"""How many poses to measure: Guo et al. 2024's minimum (eq. 18) and where the criterion flattens (Fig. 7)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .criteria import score
from .problem import DesignProblem
from .._frozen import freeze_arrays


def minimum_poses(n_dof: int, k: int) -> int:
    """The fewest poses to measure: Guo et al. 2024's eq. 18, m ≥ (n + 1)·k / 6.

    Never below k/3, the count whose three position equations per pose are as many as the unknowns.

    Parameters
    ----------
    n_dof : int
        Degrees of freedom of the robot (n).
    k : int
        Number of parameters to identify.

    Returns
    -------
    int
        max(⌈(n + 1)·k / 6⌉, ⌈k / 3⌉).

    Examples
    --------
    >>> from kincal.design import minimum_poses
    >>> minimum_poses(6, 27)  # a six-axis arm, 27 parameters: ⌈7·27/6⌉
    32
    >>> minimum_poses(3, 11)  # a 3-DOF parallel robot, 11 parameters: ⌈4·11/6⌉
    8
    """
    return int(max(np.ceil((n_dof + 1) * k / 6.0), np.ceil(k / 3.0)))


@dataclass(frozen=True)
class PoseCountCurve:
    """The criterion of the first m poses of a random order against m (Guo et al. 2024, Fig. 7).

    Parameters
    ----------
    m_values : ndarray, shape (L,)
        The numbers of poses, 1 … L.
    values : ndarray, shape (L,)
        The criterion of the first m poses for each m (−inf or 0 while the design is singular).
    chosen : int
        Where the curve flattens: the smallest m after which adding ``window`` more poses gains less than
        ``rel_gain`` (relative), see :func:`pose_count_curve`; the last m when it does not flatten.
    criterion : str
        The criterion of ``values`` (one of :data:`CRITERIA`).
    flattened : bool, optional
        False when the curve does not flatten within its poses; ``chosen`` is then its last m
        (default True).
    """

    m_values: np.ndarray
    values: np.ndarray
    chosen: int
    criterion: str
    flattened: bool = True  # False: no flattening within the curve; ``chosen`` is then its last m

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def to_dict(self) -> dict:
        """The curve as JSON-ready values: m, values, chosen, criterion, flattened."""
        return {"m": self.m_values.tolist(), "values": self.values.tolist(), "chosen": self.chosen,
                "criterion": self.criterion, "flattened": self.flattened}


def pose_count_curve(P: DesignProblem, criterion: str = "comprehensive", m_max: int = 100, seed: int | None = 0,
                     window: int = 10, rel_gain: float = 0.01) -> PoseCountCurve:
    """The criterion against the number of random poses, and where it flattens (Guo et al. 2024, Fig. 7).

    The candidates are taken in a random order; the criterion of the first m of them is computed for
    m = 1 … min(m_max, N). The curve flattens at the smallest m whose criterion a is positive and finite
    and gains less than ``rel_gain`` × ``abs(a)`` over the next ``window`` poses.

    Parameters
    ----------
    P : DesignProblem
        The candidates and their scaled Jacobian blocks.
    criterion : str, optional
        One of :data:`CRITERIA` (default "comprehensive", Guo et al. 2024's index).
    m_max : int, optional
        Most poses on the curve (default 100; at most the pool's N).
    seed : int or None, optional
        Random seed of the order of the candidates (default 0; None draws a fresh one).
    window : int, optional
        Poses added when the gain is judged (default 10).
    rel_gain : float, optional
        Relative gain below which the curve counts as flat (default 0.01).

    Returns
    -------
    PoseCountCurve
        The criterion per m and the m where it flattens.

    Examples
    --------
    >>> import kincal
    >>> from kincal.design import candidate_pool, design_problem, pose_count_curve
    >>> robot = kincal.load_robot("ur5")
    >>> P = design_problem(robot, candidate_pool(robot, 60, seed=1),
    ...                    names=["j2.theta", "j3.theta", "j4.theta", "j2.a", "j3.a"])
    >>> curve = pose_count_curve(P, m_max=40, window=5, rel_gain=0.05)
    >>> curve.m_values.shape, curve.flattened, curve.chosen
    ((40,), True, 17)
    """
    order = np.random.default_rng(seed).permutation(P.N)[:m_max]
    m_values = np.arange(1, order.size + 1)
    Ms = np.cumsum(np.einsum("nak,nal->nkl", P.J[order], P.J[order]), axis=0)
    values = np.array([float(score(Ms[i], i + 1, criterion)) for i in range(order.size)])
    for i in range(order.size - window):
        a, b = values[i], values[i + window]
        if np.isfinite(a) and a > 0 and np.isfinite(b) and (b - a) / abs(a) < rel_gain:
            return PoseCountCurve(m_values, values, int(m_values[i]), criterion)
    return PoseCountCurve(m_values, values, int(m_values[-1]), criterion, flattened=False)
