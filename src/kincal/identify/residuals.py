"""Residual objects: what a calibration minimises, as small cost-function rooms.

Every residual is a frozen value over a robot and its measurements with

* ``evaluate(values, cols) -> (r (M,), J (M, K))``: the stacked residual and its Jacobian for the
  parameter columns ``cols``, ordered component-major (every configuration's first component, then
  the second, …), so J is the transposed view of one contiguous copy of the model's Jacobian;
* ``pose_errors(values)``: (N, 3) measured − predicted positions, whatever is minimised;
* ``components``: residual components per configuration (3 for positions, n for joints);
* ``batch_cost(values (S, P)) -> (S,)``: mean squared residual of many parameter vectors at once
  (a particle swarm), ``inf`` where a vector cannot be evaluated;
* ``check(values)``: a MeasurementError, before any work, when the residual is undefined somewhere.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MeasurementError, ModelError
from ..io.measurements import Measurements
from ..models.robot import Robot


def _stack(r: np.ndarray, J: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, c) residuals and (N, c, P) derivatives -> (N·c,) and (N·c, K) for columns ``cols``."""
    return r.T.ravel(), J.transpose(2, 1, 0)[cols].reshape(len(cols), -1).T


def _mean_square(r: np.ndarray) -> np.ndarray:
    """(S,) mean of r² over every axis but the first; non-finite rows give inf."""
    with np.errstate(invalid="ignore", over="ignore"):
        val = np.mean(r.reshape(r.shape[0], -1) ** 2, axis=1)
    return np.where(np.isfinite(val), val, np.inf)


@dataclass(frozen=True, eq=False)
class _Residual:
    robot: Robot
    meas: Measurements

    def pose_errors(self, values: np.ndarray) -> np.ndarray:
        """(N, 3) measured − predicted positions."""
        return self.meas.xyz - self.robot.forward(self.meas.q, values)

    def check(self, values: np.ndarray) -> None:
        """Raise a MeasurementError when the residual is undefined at some measurement."""


@dataclass(frozen=True, eq=False)
class CartesianResidual(_Residual):
    """Predicted − measured tool positions (m)."""

    name: str = "cartesian"
    components: int = 3

    def evaluate(self, values: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, J = self.robot.forward_and_jacobian(self.meas.q, values)
        return _stack(p - self.meas.xyz, J, cols)

    def batch_cost(self, values: np.ndarray) -> np.ndarray:
        return _mean_square(self.robot.forward_batch(self.meas.q, values) - self.meas.xyz)


@dataclass(frozen=True, eq=False)
class JointResidual(_Residual):
    """Inverse kinematics of the measured positions − commanded joint values (the 3-PUU error-model
    verification paper, eq. 4/11); robots with a closed-form inverse (``has_inverse``) only."""

    name: str = "joint"

    @property
    def components(self) -> int:
        return self.robot.n_joints

    def evaluate(self, values: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        try:
            qh, J = self.robot.inverse_and_jacobian(self.meas.xyz, values)
        except ModelError:  # a trial step where some measured position is out of reach: reject it
            m = self.meas.q.size
            return np.full(m, np.inf), np.zeros((m, len(cols)))
        return _stack(qh - self.meas.q, J, cols)

    def batch_cost(self, values: np.ndarray) -> np.ndarray:
        return _mean_square(self.robot.inverse_batch(self.meas.xyz, values) - self.meas.q)

    def check(self, values: np.ndarray) -> None:
        reach = self.robot.inverse(self.meas.xyz, values, strict=False)
        bad = ~np.all(np.isfinite(reach), axis=1)
        if bad.any():
            raise MeasurementError(
                f"{self.meas.source}: the positions in row(s) {', '.join(str(r) for r in self.meas.rows[bad][:10])} "
                f"are out of reach of the starting model, so the joint-space residual is undefined there; use "
                f"residual='cartesian' or leave those rows out")


RESIDUALS = {"cartesian": CartesianResidual, "joint": JointResidual}
