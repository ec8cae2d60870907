"""Candidate pools: random feasible joint vectors, or poses a user lists in a CSV."""
from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot


def candidate_pool(robot: Robot, n: int, seed: int | None = 0, max_tries: int = 50) -> np.ndarray:
    """n joint vectors drawn uniformly within the limits and kept only where ``robot.feasible`` holds
    (coupled constraints), (n, n_joints)."""
    rng = np.random.default_rng(seed)
    kept: list[np.ndarray] = []
    have = 0
    for _ in range(max_tries):
        q = rng.uniform(robot.lower, robot.upper, size=(max(2 * (n - have), 16), robot.n_joints))
        q = q[robot.feasible(q)]
        kept.append(q)
        have += q.shape[0]
        if have >= n:
            return np.concatenate(kept)[:n]
    raise ModelError(f"{robot.name}: only {have} of {n} random joint vectors satisfy the robot's constraints; "
                     f"check the joint limits and coupled constraints")
