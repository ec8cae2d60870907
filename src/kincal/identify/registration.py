"""Rigid registration of the measurement frame (Kabsch / Umeyama without scale)."""
from __future__ import annotations

import numpy as np

from ..models.robot import Robot


def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R (3,3) and translation t (3,) minimising Σ‖R pᵢ + t − qᵢ‖² for P, Q (N,3), N ≥ 3."""
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    H = (P - cp).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, cq - R @ cp


def register_base(robot: Robot, q: np.ndarray, xyz: np.ndarray) -> Robot:
    """``robot`` with its base frame moved so its predictions at q best match xyz (N,3) rigidly."""
    R, t = kabsch(robot.forward(q), xyz)
    Rb, tb = robot.base_transform()
    return robot.with_base_transform(R @ Rb, R @ tb + t)
