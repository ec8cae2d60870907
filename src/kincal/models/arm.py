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
    """A point on each joint axis (n, 3) m and its unit direction (n, 3), in the sense of the joint's positive
    turn, at joint values q (n,) rad (a transmission: its chain's axes at the joints the actuators give).
    ModelError unless every (chain) joint is revolute and q is n finite values."""
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.size != robot.n_joints or not np.all(np.isfinite(q)):
        raise ModelError(f"robot '{robot.name}': {robot.n_joints} finite joint values expected, got {q.size}")
    chain: Robot = robot
    if isinstance(robot, TransmissionRobot):
        chain, q = robot.inner, robot.chain_q(q[None])[0]
    if set(chain.joint_types) != {"revolute"}:
        raise ModelError(f"robot '{robot.name}' ({robot.structure}): the branch bits are for arms of revolute axes")
    p, _, Jp, Jw = chain.pose_and_jacobian(q)
    u = Jw.T / np.linalg.norm(Jw.T, axis=1, keepdims=True)
    return p + np.cross(u, Jp.T), u


def nearest_point(points: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The point (3,) m nearest (least squares) to the lines through ``points`` (k, 3) along the unit
    ``directions`` (k, 3): where they meet, or nearly meet (a calibrated wrist). ModelError when the lines
    are all parallel."""
    A, b = np.zeros((3, 3)), np.zeros(3)
    for c, u in zip(points, directions):
        P = np.eye(3) - np.outer(u, u)
        A, b = A + P, b + P @ c
    if np.linalg.matrix_rank(A, tol=1e-9) < 3:
        raise ModelError("the wrist's axes are parallel: the arm has no wrist centre")
    return np.linalg.solve(A, b)


def six_axes(robot: Robot, q: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(q (6,), axis points (6, 3), directions (6, 3), the wrist centre: nearest the axes 4, 5, 6) of a six-axis
    arm at joints q (rad); ModelError naming ``what`` (the bits asked for) for another joint count."""
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.size != 6 or robot.n_joints != 6:
        raise ModelError(f"robot '{robot.name}': {what} are defined for six-axis arms; got {q.size} joint values for "
                         f"{robot.n_joints} joints")
    points, axes = axis_lines(robot, q)
    return q, points, axes, nearest_point(points[3:], axes[3:])
