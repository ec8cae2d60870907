"""The joint-space residual as an observation type: measured positions against commanded joints.

The 3-PUU error-model verification paper (eq. 4/11) compares the joint values that reach each measured point, by
the model's closed-form inverse kinematics, with the commanded ones. The data are a :class:`~kincal.observe.PointObs`'s
(joint values and measured positions); only the residual differs: robots with a closed-form inverse (``has_inverse``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..errors import MeasurementError, ModelError
from ..models.robot import Robot
from .observations import MeasuredPositions, PointObs, PoseObs, Wrapper, component_major, mean_square, so3_right


class InJoints:
    """What a residual in joint space is, whatever was measured: one row per sample and joint, each with
    the joints' reading noise ``std`` (rad or m) as its σ."""

    kind = "joint"
    q: np.ndarray
    std: float

    def sample_rows(self) -> np.ndarray:
        return np.tile(np.arange(len(self.q)), self.q.shape[1])

    def sigma(self) -> np.ndarray:
        return np.full(self.q.size, float(self.std))


@dataclass(frozen=True, eq=False)
class JointObs(InJoints, MeasuredPositions):
    """Measured positions xyz (N, 3) m at commanded joints q (N, n); residual: inverse kinematics of
    xyz − q, (N, n) rad or m. σ (rad or m, one number): the joints' reading noise, stated. Its statistics
    are the position errors (m)."""

    std: float = 1e-4

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


@dataclass(frozen=True, eq=False)
class PoseJointObs(InJoints, PoseObs):
    """Measured 6-D poses (xyz (N, 3) m, R (N, 3, 3)) at read joints q (N, n); residual: the joints that
    put the platform at the measured pose by the model's closed-form inverse (a hexapod's legs from its
    pose, no forward solve) − q, (N, n) m or rad. The platform's frame is the measured one turned back
    by the target's rotation (a set-up parameter, as for :class:`PoseObs`). σ (m or rad, one number):
    the joints' reading noise, stated. Its statistics are the pose errors (forward kinematics)."""

    std: float = 1e-4

    def position_axes(self) -> np.ndarray:
        return np.full(self.q.size, -1)

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        Rm = self.R @ self.target(nuis).transpose()  # the platform frame the measurement implies
        try:
            qh, Js, Jw = robot.inverse_pose_and_jacobian(Rm, self.xyz, values)
        except ModelError:  # a trial step where some measured pose is out of reach: reject it
            return np.full(self.q.size, np.inf), np.zeros((self.q.size, robot.n_params)), np.zeros((self.q.size, 3))
        # a turn dn of the target turns the platform frame by −R J_r(n) dn (world axes)
        Jn = -Jw @ (self.R @ so3_right(nuis[:3]))
        r, J = component_major(qh - self.q, Js, np.arange(robot.n_params))
        return r, J, Jn.transpose(1, 0, 2).reshape(-1, 3)

    def check(self, robot: Robot, values: np.ndarray) -> None:
        bad = ~np.all(np.isfinite(robot.inverse_pose(self.R @ self.target(np.zeros(3)).T, self.xyz, values,
                                                     strict=False)), axis=1)
        if bad.any():
            raise MeasurementError(
                f"{self.source}: the poses in row(s) {', '.join(str(r) for r in self.rows[bad][:10])} are out of "
                f"reach of the starting model, so the joint-space residual is undefined there; use "
                f"residual='cartesian' or leave those rows out")


def in_joint_space(obs):
    """``obs`` with its residual in joint space (``residual='joint'``): points as :class:`JointObs`, 6-D poses as
    :class:`PoseJointObs` (σ the joints' reading noise, ``std``), a session's set inside its session; a set
    already in joint space as it is. A ValueError for the kinds that measure no pose to invert."""
    if obs.kind == "joint":
        return obs
    if isinstance(obs, Wrapper):
        return dataclasses.replace(obs, inner=in_joint_space(obs.inner))
    if isinstance(obs, PoseObs):
        return PoseJointObs(q=obs.q, rows=obs.rows, source=obs.source, xyz=obs.xyz, R=obs.R,
                            target_rotation=obs.target_rotation, anchored=obs.anchored, own_target=obs.own_target)
    if isinstance(obs, PointObs):
        return JointObs(q=obs.q, rows=obs.rows, source=obs.source, xyz=obs.xyz)
    raise ValueError(f"residual='joint' inverts measured positions or poses; {obs.kind} data ({obs.source}) have "
                     f"none to invert: use residual='cartesian'")
