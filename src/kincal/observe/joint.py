"""The joint-space residual as an observation type: measured positions against commanded joints.

The 3-PUU error-model verification paper (eq. 4/11) compares the joint values that reach each measured point, by
the model's closed-form inverse kinematics, with the commanded ones. The data are a :class:`~kincal.observe.PointObs`'s
(joint values and measured positions); only the residual differs: robots with a closed-form inverse (``has_inverse``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MeasurementError, ModelError
from ..models.robot import Robot
from .observations import MeasuredPositions, component_major, mean_square


@dataclass(frozen=True, eq=False)
class JointObs(MeasuredPositions):
    """Measured positions xyz (N, 3) m at commanded joints q (N, n); residual: inverse kinematics of
    xyz − q, (N, n) rad or m. σ (rad or m, one number): the joints' reading noise, stated. Its statistics
    are the position errors (m)."""

    std: float = 1e-4
    kind = "joint"

    def sample_rows(self) -> np.ndarray:
        return np.tile(np.arange(len(self)), self.q.shape[1])

    def sigma(self) -> np.ndarray:
        return np.full(self.q.size, float(self.std))

    def evaluate_cols(self, robot: Robot, values: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        try:
            qh, J = robot.inverse_and_jacobian(self.xyz, values)
        except ModelError:  # a trial step where some measured position is out of reach: reject it
            return np.full(self.q.size, np.inf), np.zeros((self.q.size, len(cols)))
        return component_major(qh - self.q, J, cols)

    def batch_cost(self, robot: Robot, values: np.ndarray) -> np.ndarray:
        return mean_square(robot.inverse_batch(self.xyz, values) - self.q)

    def check(self, robot: Robot, values: np.ndarray) -> None:
        bad = ~np.all(np.isfinite(robot.inverse(self.xyz, values, strict=False)), axis=1)
        if bad.any():
            raise MeasurementError(
                f"{self.source}: the positions in row(s) {', '.join(str(r) for r in self.rows[bad][:10])} are out of "
                f"reach of the starting model, so the joint-space residual is undefined there; use "
                f"residual='cartesian' or leave those rows out")
