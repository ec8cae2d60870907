"""Small rotation helpers shared by the rooms: fixed-axis roll/pitch/yaw (R = Rz(rz) Ry(ry) Rx(rx)),
cross-product matrices, the matrix of a rotation vector, the rotation vectors of matrices, the
roll/pitch/yaw of a rotation nearest given ones (a program's angles written again), and quaternions
(w, x, y, z) to rotation vectors and back."""
from __future__ import annotations

import numpy as np

from ..ties import tie_tolerance


def rot_zyx(rz: float | np.ndarray, ry: float | np.ndarray, rx: float | np.ndarray) -> np.ndarray:
    """3x3 rotation Rz(rz) @ Ry(ry) @ Rx(rx) (angles in rad); angle arrays of shape (M,) give (3, 3, M)."""
    cz, sz, cy, sy, cx, sx = np.cos(rz), np.sin(rz), np.cos(ry), np.sin(ry), np.cos(rx), np.sin(rx)
    return np.array([
        [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
        [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
        [-sy, cy * sx, cy * cx],
    ])


def zyx_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """(rz, ry, rx) with R = Rz Ry Rx; ry in [-pi/2, pi/2] (gimbal lock at |ry| = pi/2 puts all of it in rz)."""
    ry = float(np.arcsin(np.clip(-R[2, 0], -1.0, 1.0)))
    if abs(R[2, 0]) < 1.0 - 1e-12:
        rz = float(np.arctan2(R[1, 0], R[0, 0]))
        rx = float(np.arctan2(R[2, 1], R[2, 2]))
    else:
        rz = float(np.arctan2(-R[0, 1], R[1, 1]))
        rx = 0.0
    return rz, ry, rx


def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R (3,3) and translation t (3,) minimising Σ‖R pᵢ + t − qᵢ‖² for P, Q (N,3), N ≥ 3."""
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    H = (P - cp).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, cq - R @ cp


def skew(v: np.ndarray) -> np.ndarray:
    """(…, 3) → (…, 3, 3) cross-product matrices."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def rotvec_matrix(w: np.ndarray) -> np.ndarray:
    """The rotation matrices (…, 3, 3) of rotation vectors w (…, 3) rad (Rodrigues; (3,) gives (3, 3))."""
    w = np.asarray(w, dtype=float)
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = skew(w)
    small = th < 1e-12
    safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0, np.sin(safe) / safe)
    b = np.where(small, 0.0, (1 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of rotation matrices (N, 3, 3) (rad): in closed form from the skew part
    (θ / (2 sin θ) · vee(R − Rᵀ), its series near 0); angles near π, where that part vanishes, by
    scipy's Rotation."""
    v = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(cos)
    small = theta < 1e-4
    f = np.where(small, 0.5 + theta**2 / 12.0, theta / (2.0 * np.sin(np.where(small, 1.0, theta))))
    out = v * f[:, None]
    wide = theta > 3.0
    if wide.any():
        from scipy.spatial.transform import Rotation
        out[wide] = Rotation.from_matrix(R[wide]).as_rotvec()
    return out


def zyx_nearest(R: np.ndarray, old: np.ndarray) -> np.ndarray:
    """(rz, ry, rx) rad (…, 3) with R (…, 3, 3) = Rz Ry Rx, the triple nearest ``old`` (…, 3) rad — what a
    program writes again where it wrote ``old``: ``old`` itself when it is R (to 1e-12 rad); else of R's two
    triples, each with the whole turns that bring it nearest, the nearer (ties, :func:`kincal.ties.first_best`'s
    rule row by row: the one with |ry| ≤ π/2), ry to full precision near ±π/2 (atan2, where an arcsine loses
    half the digits), and at ±π/2, where only rz ∓ rx is defined, the old rx kept. Row by row, all at once."""
    R, old = np.asarray(R, dtype=float), np.asarray(old, dtype=float)
    shape = old.shape
    R, old = R.reshape(-1, 3, 3), old.reshape(-1, 3)
    was = np.moveaxis(rot_zyx(old[:, 0], old[:, 1], old[:, 2]), -1, 0)
    same = np.linalg.norm(rotation_log(np.swapaxes(was, 1, 2) @ R), axis=1) < 1e-12
    cy = np.hypot(R[:, 0, 0], R[:, 1, 0])
    ry = np.arctan2(-R[:, 2, 0], cy)
    lock = cy < 1e-10
    rx = np.where(lock, old[:, 2], np.arctan2(R[:, 2, 1], R[:, 2, 2]))
    rz = np.where(lock, np.arctan2(-R[:, 0, 1], R[:, 1, 1]) + np.copysign(1.0, ry) * old[:, 2],
                  np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    one = np.stack([rz, ry, rx], axis=1)
    other = np.stack([rz + np.pi, np.pi - ry, rx + np.pi], axis=1)
    one, other = (o + 2 * np.pi * np.round((old - o) / (2 * np.pi)) for o in (one, other))
    d_one, d_other = np.abs(one - old).sum(axis=1), np.abs(other - old).sum(axis=1)
    wins = ~lock & (d_one > d_other + tie_tolerance(d_other))  # the other only when nearer beyond a tie
    out = np.where(same[:, None], old, np.where(wins[:, None], other, one))
    return out.reshape(shape)


def quaternion_rotvec(q: np.ndarray) -> np.ndarray:
    """The rotation vector (rad) of the quaternion q = (w, x, y, z) (any norm > 0; angle in [0, pi])."""
    q = q / np.linalg.norm(q)
    q = -q if q[0] < 0 else q
    s = float(np.linalg.norm(q[1:]))
    return q[1:] * (2.0 * np.arctan2(s, q[0]) / s if s > 1e-12 else 2.0 / q[0])


def rotvec_quaternion(w: np.ndarray) -> np.ndarray:
    """The unit quaternions (w, x, y, z) (…, 4) of the rotation vectors ``w`` (…, 3) rad."""
    w = np.asarray(w, dtype=float)
    th = np.linalg.norm(w, axis=-1, keepdims=True)
    return np.concatenate([np.cos(th / 2), w * 0.5 * np.sinc(th / (2 * np.pi))], axis=-1)
