"""Candidate pools: random feasible joint vectors, or poses a user lists in a CSV."""
from __future__ import annotations

import numpy as np

from ..checks import whole
from ..models.robot import Robot


def candidate_pool(robot: Robot, n: int, seed: int | None = 0) -> np.ndarray:
    """n joint vectors drawn uniformly within the limits and kept only where ``robot.feasible`` holds
    (coupled constraints, assembly), (n, n_joints): ``robot.sample_joints``."""
    return robot.sample_joints(whole("n", n, 1), seed)
