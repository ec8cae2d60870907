"""Candidate pools: random feasible joint vectors, or poses a user lists in a CSV."""
from __future__ import annotations

import numpy as np

from ..models.robot import Robot


def candidate_pool(robot: Robot, n: int, seed: int | None = 0) -> np.ndarray:
    """n joint vectors drawn uniformly within the limits and kept only where ``robot.feasible`` holds
    (coupled constraints, assembly), (n, n_joints): ``robot.sample_joints``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n={n!r}: give the number of candidates, 1 or more")
    return robot.sample_joints(int(n), seed)
