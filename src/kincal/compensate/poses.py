"""Full-pose compensation: joint commands that put the calibrated model's TCP at target poses, and the
"filtered" poses to send to a controller that moves with its own (nominal or factory) model.

The solver is batched Newton on the 6-D pose error (damped least squares), iterating only the
targets not yet converged. Six joints solve all six components; a redundant arm takes the smallest
step from its start (the nominal command), so it stays near it in the null space; a robot with fewer
joints reaches the position first and the rotation components it controls, and the rest of the
rotation error is reported, per target, as not controlled.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot

POS_TOL = 1e-12  # m: converged (commands then agree to ~1e-10 rad)
ROT_TOL = 1e-12  # rad
MAX_ITER = 50
DAMPING = 1e-9  # keeps a step finite at an exact singularity; far below the scale of a correction
ROT_WEIGHT = {True: 0.1, False: 1e-4}  # m per rad: full pose (≥ 6 joints) / position first (fewer joints)
STALL = 1e-13  # m: a step moving the tool this little ends a least-squares solve (fewer than 6 joints)
MAX_MOVE = 0.02  # m: no joint may move the tool point more than this in one step (a full step near a
#                   singularity would leave the branch); joints are scaled by their lever (m per rad or m)
ROT_LEVER = 0.1  # m per rad: a wrist joint turning the tool counts as moving a point this far out


@dataclass(frozen=True)
class PoseSolution:
    """q (N, n) commands; position and rotation errors left at them (N,) m and rad; converged (N,);
    iterations made; for robots with fewer than six joints the rotation error they cannot remove."""

    q: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray
    converged: np.ndarray
    iterations: int


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of rotation matrices (N, 3, 3) (rad)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(R).as_rotvec()


def pose_errors(model: Robot, q: np.ndarray, p_t: np.ndarray, R_t: np.ndarray):
    """Position errors (N, 3) m and world-frame rotation errors (N, 3) rad of the model at q against
    the targets, with the model's pose Jacobians (N, 3, n) each."""
    p, R, Jp, Jw = model.pose_and_jacobian(q)
    return p_t - p, rotation_log(R_t @ np.swapaxes(R, 1, 2)), Jp, Jw


def solve_poses(model: Robot, p_t: np.ndarray, R_t: np.ndarray, q0: np.ndarray, max_iter: int = MAX_ITER,
                fixed: tuple[int, ...] = ()) -> PoseSolution:
    """Commands q (N, n) that put ``model``'s tool point at p_t (N, 3) m with its flange at R_t
    (N, 3, 3), by Newton steps from q0 (N, n); only unconverged targets iterate. Joints in ``fixed``
    keep their start values (a redundant arm's controller takes one as its redundancy parameter)."""
    if not model.has_tool_point:
        raise ModelError(f"robot '{model.name}' has no tool point and flange frame: give position targets")
    q = np.array(q0, dtype=float)
    moving = np.ones(q.shape[1], bool)
    moving[list(fixed)] = False
    n_j = int(moving.sum())
    w = ROT_WEIGHT[n_j >= 6]
    converged = np.zeros(len(q), bool)
    active = np.arange(len(q))
    it = 0
    for it in range(1, max_iter + 1):
        ep, er, Jp, Jw = pose_errors(model, q[active], p_t[active], R_t[active])
        done = (np.linalg.norm(ep, axis=1) < POS_TOL) & (np.linalg.norm(er, axis=1) < ROT_TOL)
        J = np.concatenate([Jp, w * Jw], axis=1) * moving
        e = np.concatenate([ep, w * er], axis=1)
        dq = _step(J, e)
        lever = np.linalg.norm(Jp, axis=1) + ROT_LEVER * np.linalg.norm(Jw, axis=1)  # (N, n): per unit of each joint
        dq *= np.minimum(1.0, MAX_MOVE / np.maximum((np.abs(dq) * lever).max(axis=1), 1e-300))[:, None]
        if n_j < 6:
            done |= (np.abs(dq) * lever).max(axis=1) < STALL
        converged[active[done]] = True
        keep = ~done
        q[active[keep]] += dq[keep]
        active = active[keep]
        if not active.size:
            break
    ep, er, _, _ = pose_errors(model, q, p_t, R_t)
    return PoseSolution(q, np.linalg.norm(ep, axis=1), np.linalg.norm(er, axis=1), converged, it)


def _step(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Damped least-squares steps (N, n) for Jacobians J (N, 6, n) and errors e (N, 6): the smallest
    step that removes the error when the robot has six joints or more, the least-squares one else."""
    n = J.shape[2]
    Jt = np.swapaxes(J, 1, 2)
    if n >= 6:
        A = J @ Jt + DAMPING**2 * np.eye(6)
        return np.einsum("nij,nj->ni", Jt, np.linalg.solve(A, e[..., None])[..., 0])
    A = Jt @ J + DAMPING**2 * np.eye(n)
    return np.linalg.solve(A, np.einsum("nij,nj->ni", Jt, e)[..., None])[..., 0]


def filtered_poses(controller: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The poses to send to a controller that moves with ``controller``'s kinematics so that its inverse
    kinematics produce the commands q (N, n): its own forward kinematics at q (positions m, rotations)."""
    p, R, _, _ = controller.pose_and_jacobian(q)
    return p, R
