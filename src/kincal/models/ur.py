"""Universal Robots arms in closed form: the eight inverse-kinematics branches of a six-revolute
standard-DH chain with UR's structure (twists 90°, 0, 0, 90°, −90°, 0; link lengths a2, a3 only;
offsets d1, d4, d5, d6; no joint offset, no β), as a UR controller solves a pose target.

Derivation (frames i of the DH table, A_i = Rz(θi) Tz(di) Tx(ai) Rx(αi)), for the flange pose (R, p)
in the DH base: the axes of joints 2, 3, 4 are all z1 = (sin θ1, −cos θ1, 0), and every origin up to
frame 5 lies in the plane through the base normal to z1 except for d4 along it, so the point
p5 = p − d6 z6 obeys p5·z1 = d4 (θ1: two solutions, the shoulder). The flange axis z6 = z5 makes
cos θ5 = z6·z1 (two: the wrist). z1 seen in the flange frame is (cos θ6 sin θ5, −sin θ6 sin θ5,
cos θ5), which gives θ6. What remains, T14 = A1⁻¹ T A6⁻¹ A5⁻¹, is a planar 3R arm: frame 3's origin
o4 − d4 z1 at distance √(a2² + a3² + 2 a2 a3 cos θ3) (two: the elbow) and θ2 + θ3 + θ4 the angle
of x4 about z1. Every branch is checked by the forward kinematics.
"""
from __future__ import annotations

import numpy as np

from .robot import Robot

UR_TWISTS = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
EXACT = 1e-12  # a nominal value this close to UR's structure counts as it
CHECK = 1e-9  # m and rad: a branch reproduces the target this closely, or it is not a solution
SINGULAR = 1e-9  # |sin θ5| below this: the wrist is singular, θ6 taken from the reference joints


def ur_lengths(robot: Robot) -> tuple[float, float, float, float, float, float] | None:
    """(d1, a2, a3, d4, d5, d6) in m when ``robot`` has a UR arm's structure (module docstring) and no
    terms beyond its geometry; None otherwise (its inverse is found numerically)."""
    if robot.structure != "dh" or robot.joint_types != ("revolute",) * 6 or robot.error_model != "geometric":
        return None
    p = robot.params.as_dict()
    heads = [n[:-len(".theta")] for n in robot.params.names if n.endswith(".theta")]
    if len(heads) != 6 or not robot.has_tool_point:
        return None
    zero = [f"{h}.theta" for h in heads] + [f"{heads[k]}.a" for k in (0, 3, 4, 5)] + [f"{heads[k]}.d" for k in (1, 2)]
    zero += [n for n in p if n.endswith(".beta")]
    twists = [p[f"{h}.alpha"] for h in heads]
    if any(abs(p[n]) > EXACT for n in zero) or any(abs(a - b) > EXACT for a, b in zip(twists, UR_TWISTS)):
        return None
    return (p[f"{heads[0]}.d"], p[f"{heads[1]}.a"], p[f"{heads[2]}.a"], p[f"{heads[3]}.d"], p[f"{heads[4]}.d"],
            p[f"{heads[5]}.d"])


def _dh(theta: np.ndarray, d: float, a: float, alpha: float) -> np.ndarray:
    """(N, 4, 4) standard DH transforms Rz(θ) Tz(d) Tx(a) Rx(α) for angles θ (N,)."""
    c, s, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    T = np.zeros((theta.size, 4, 4))
    T[:, 0] = np.stack([c, -s * ca, s * sa, a * c], -1)
    T[:, 1] = np.stack([s, c * ca, -c * sa, a * s], -1)
    T[:, 2, 1:] = sa, ca, d
    T[:, 3, 3] = 1.0
    return T


def ur_inverse(robot: Robot, p: np.ndarray, R: np.ndarray, near: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The eight branches (N, 8, 6) rad of the tool point at p (N, 3) m with the flange at R (N, 3, 3),
    each joint taken the whole turns nearest ``near`` (N, 6) rad (a singular wrist's θ6 from it), and
    which branches are solutions (N, 8): real, within the joint limits, reproducing the pose to 1e-9.
    Branch k: shoulder k // 4, wrist (k // 2) % 2, elbow k % 2 (0: the + root). A ValueError for a
    robot without UR's structure (:func:`ur_lengths`)."""
    lengths = ur_lengths(robot)
    if lengths is None:
        raise ValueError(f"robot '{robot.name}' does not have a UR arm's structure: no closed-form inverse")
    d1, a2, a3, d4, d5, d6 = lengths
    Rb, tb = robot.base_transform()
    Rf = np.einsum("ji,njk->nik", Rb, R)  # the flange in the DH base
    pf = (p - np.einsum("nij,j->ni", R, robot.tool_point()) - tb) @ Rb
    q = np.full((len(p), 8, 6), np.nan)
    p5 = pf - d6 * Rf[:, :, 2]
    r, phi = np.hypot(p5[:, 0], p5[:, 1]), np.arctan2(p5[:, 1], p5[:, 0])
    shoulder = np.arcsin(np.clip(d4 / np.maximum(r, 1e-300), -1.0, 1.0))
    for i, t1 in enumerate((phi + shoulder, phi + np.pi - shoulder)):
        z1 = np.stack([np.sin(t1), -np.cos(t1), np.zeros_like(t1)], -1)
        wrist = np.arccos(np.clip(np.einsum("ni,ni->n", Rf[:, :, 2], z1), -1.0, 1.0))
        for j, t5 in enumerate((wrist, -wrist)):
            v = np.einsum("nji,nj->ni", Rf, z1)  # z1 in the flange frame
            s5 = np.sin(t5)
            t6 = np.where(np.abs(s5) > SINGULAR, np.arctan2(-v[:, 1] * np.sign(s5), v[:, 0] * np.sign(s5)),
                          near[:, 5])
            T = np.zeros((len(p), 4, 4))
            T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = Rf, pf, 1.0
            T14 = (np.linalg.inv(_dh(t1, d1, 0.0, UR_TWISTS[0])) @ T @ np.linalg.inv(_dh(t6, d6, 0.0, 0.0))
                   @ np.linalg.inv(_dh(t5, d5, 0.0, UR_TWISTS[4])))
            o3 = T14[:, :2, 3]  # frame 3's origin in frame 1 (o4 is d4 above it along z1)
            c3 = (np.sum(o3**2, axis=1) - a2**2 - a3**2) / (2 * a2 * a3)
            for k, t3 in enumerate((np.arccos(np.clip(c3, -1.0, 1.0)), -np.arccos(np.clip(c3, -1.0, 1.0)))):
                t2 = np.arctan2(o3[:, 1], o3[:, 0]) - np.arctan2(a3 * np.sin(t3), a2 + a3 * np.cos(t3))
                t4 = np.arctan2(T14[:, 1, 0], T14[:, 0, 0]) - t2 - t3
                q[:, 4 * i + 2 * j + k] = np.stack([t1, t2, t3, t4, t5, t6], -1)
    return _checked(robot, p, R, nearest_turns(q, near[:, None, :], robot.lower, robot.upper))


def nearest_turns(q: np.ndarray, near: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Each angle of q the whole turns nearest ``near`` (broadcast), a turn back inside the limits
    (lower, upper; rad) when that one falls outside them."""
    out = q - 2 * np.pi * np.round((q - near) / (2 * np.pi))
    out = np.where(out > upper, out - 2 * np.pi, out)
    return np.where(out < lower, out + 2 * np.pi, out)


def _checked(robot: Robot, p: np.ndarray, R: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The branches and which are solutions: finite, within the limits, reproducing (p, R) to CHECK."""
    flat = q.reshape(-1, 6)
    ok = np.all(np.isfinite(flat), axis=1)
    safe = np.where(ok[:, None], flat, 0.0)
    pp, RR, _, _ = robot.pose_and_jacobian(safe)
    n = q.shape[1]
    dp = np.linalg.norm(pp - np.repeat(p, n, axis=0), axis=1)
    dR = np.linalg.norm(RR - np.repeat(R, n, axis=0), axis=(1, 2))
    ok &= (dp < CHECK) & (dR < CHECK) & robot.within_limits(safe)
    return q, ok.reshape(q.shape[:2])
