"""Compensation: joint commands that the calibrated model says reach given target positions."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot

IK_TOL = 1e-10  # m
IK_ITER = 100


@dataclass(frozen=True)
class Compensation:
    """q (N, n): commands; residual (N,): |model(q) − target| in m; method: how q was found."""

    q: np.ndarray
    residual: np.ndarray
    method: str
    iterations: int

    def to_dict(self) -> dict:
        return {"q": self.q.tolist(), "residual": self.residual.tolist(), "max_residual": float(self.residual.max()),
                "method": self.method, "iterations": self.iterations}


def compensate(robot: Robot, targets: np.ndarray, q_start: np.ndarray | None = None,
               damping: float = 1e-4) -> Compensation:
    """Joint commands that place ``robot``'s tool at targets (N, 3) m.

    Robots with a closed-form inverse (parallel robots) use it. Otherwise (serial robots) a damped
    least-squares iteration on the model, started from ``q_start`` (N, n) — normally the commands the
    nominal model gives for the targets — converges to the nearest solution; the damping (m) keeps
    steps small near singularities.
    """
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    inverse = getattr(robot, "inverse", None)
    if inverse is not None:
        q = inverse(targets)
        return Compensation(q, np.linalg.norm(robot.forward(q) - targets, axis=1), "closed-form inverse", 0)
    if q_start is None:
        raise ModelError(f"robot '{robot.name}' has no closed-form inverse: give the nominal joint values of the "
                         f"targets as the starting point")
    q = robot.check_q(q_start).copy()
    if q.shape[0] != targets.shape[0]:
        raise ModelError(f"{targets.shape[0]} targets but {q.shape[0]} starting joint vectors")
    it = 0
    for it in range(1, IK_ITER + 1):
        e = targets - robot.forward(q)
        if np.max(np.linalg.norm(e, axis=1)) < IK_TOL:
            break
        Jq = robot.joint_jacobian(q)  # (N, 3, n)
        A = Jq @ np.swapaxes(Jq, 1, 2) + damping**2 * np.eye(3)
        q = q + np.einsum("nji,nj->ni", Jq, np.linalg.solve(A, e[..., None])[..., 0])
    res = np.linalg.norm(robot.forward(q) - targets, axis=1)
    return Compensation(q, res, "damped least squares", it)
