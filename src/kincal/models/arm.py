"""The geometry of a six-axis arm at given joint values, for the branch bits controllers write (KUKA
S/T, ABB confdata, FANUC CONFIG, Yaskawa RCONF): each joint's axis line and the wrist centre.

Read from the model itself — nominal or calibrated — so a calibrated arm's bits follow its own axes:
a revolute joint's column of the tool point's Jacobian is J = u × (p − o) (u its unit axis, o a point on
it), so the joint's rotation rate column gives u and p + u × J is the foot of the perpendicular from p
on the axis. A transmission's axes are its chain's, at the chain joints its actuators give. Units: m,
rad, the robot's world frame.
"""
from __future__ import annotations

import numpy as np

from ..errors import ModelError
from .robot import Robot
from .transmission import TransmissionRobot


def axis_lines(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A point on each joint axis and its unit direction, in the sense of the joint's positive turn, at joint
    values q (n,) rad, each (n, 3); or for q (N, n), each (N, n, 3) (a transmission: its chain's axes at the
    joints the actuators give). ModelError unless every (chain) joint is revolute and q holds n finite values."""
    q = np.asarray(q, dtype=float)
    Q = np.atleast_2d(q)
    if Q.ndim != 2 or Q.shape[1] != robot.n_joints or not np.all(np.isfinite(Q)):
        raise ModelError(f"robot '{robot.name}': {robot.n_joints} finite joint values expected, got {q.shape[-1]}")
    chain: Robot = robot
    if isinstance(robot, TransmissionRobot):
        chain, Q = robot.inner, robot.chain_q(Q)
    if set(chain.joint_types) != {"revolute"}:
        raise ModelError(f"robot '{robot.name}' ({robot.structure}): the branch bits are for arms of revolute axes")
    p, _, Jp, Jw = chain.pose_and_jacobian(Q)
    u = np.swapaxes(Jw, 1, 2)
    u = u / np.linalg.norm(u, axis=2, keepdims=True)
    points = p[:, None, :] + np.cross(u, np.swapaxes(Jp, 1, 2))
    return (points[0], u[0]) if q.ndim == 1 else (points, u)


def nearest_point(points: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The point (3,) m nearest (least squares) to the lines through ``points`` (k, 3) along the unit
    ``directions`` (k, 3) — where they meet, or nearly meet (a calibrated wrist); for (N, k, 3) each, (N, 3).
    ModelError when the lines are all parallel."""
    P = np.eye(3) - directions[..., :, None] * directions[..., None, :]  # (…, k, 3, 3): across each line
    A, b = P.sum(axis=-3), np.einsum("...kij,...kj->...i", P, points)
    if np.any(np.linalg.svd(A, compute_uv=False)[..., -1] < 1e-9):
        raise ModelError("the wrist's axes are parallel: the arm has no wrist centre")
    return np.linalg.solve(A, b[..., None])[..., 0]


def six_axes(robot: Robot, q: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(q (N, 6), axis points (N, 6, 3), directions (N, 6, 3), wrist centres (N, 3): nearest the axes 4, 5, 6) of
    a six-axis arm at joints q (6,) or (N, 6) rad; ModelError naming ``what`` (the bits asked for) for another
    joint count."""
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    if Q.ndim != 2:
        raise ModelError(f"robot '{robot.name}': {what} take joints of shape (6,) or (N, 6); got shape {Q.shape}")
    if Q.shape[1] != 6 or robot.n_joints != 6:
        raise ModelError(f"robot '{robot.name}': {what} are defined for six-axis arms; got {Q.shape[-1]} joint values "
                         f"for {robot.n_joints} joints")
    points, axes = axis_lines(robot, Q)
    return Q, points, axes, nearest_point(points[:, 3:], axes[:, 3:])
