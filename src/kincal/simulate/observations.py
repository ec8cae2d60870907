"""Simulated observations of every type, so a set-up can be planned before anyone measures.

Constraint data (sockets, planes) need configurations that put the tool point at a given point: found by damped
least-squares inverse kinematics on the true robot from random starts (poses that do not reach within 1 nm, or
leave the joint limits, are drawn again).
"""
from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..observe.constraints import PlaneObs, SamePointObs
from ..observe.markers import MarkersObs
from ..observe.observations import PoseObs, flange_point
from ..models.robot import Robot

IK_TOL = 1e-9  # m


def simulate_poses(true: Robot, q: np.ndarray, target_rotation: np.ndarray, std_pos: float = 0.1e-3,
                   std_rot: float = 1e-3, seed: int = 0) -> PoseObs:
    """6-D poses of a target frame (origin: the true tool point; orientation ``target_rotation`` on
    the flange) at q (N, n), with isotropic noise ``std_pos`` (m) and ``std_rot`` (rad)."""
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(seed)
    q = true.check_q(q)
    p, _, Rf = flange_point(true, q, true.params.values, true.tool_point())
    R = Rotation.from_rotvec(std_rot * rng.standard_normal((len(q), 3))).as_matrix() @ Rf @ target_rotation
    return PoseObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} poses", R=R, std_pos=std_pos, std_rot=std_rot,
                   xyz=p + std_pos * rng.standard_normal(p.shape))


def simulate_markers(true: Robot, q: np.ndarray, markers: np.ndarray, std: float = 15e-6, missing: float = 0.0,
                     seed: int = 0) -> MarkersObs:
    """k markers (``markers`` (k, 3) m in the flange frame) at q (N, n); a share ``missing`` of the
    cells is left unseen (NaN), never a whole sample."""
    rng = np.random.default_rng(seed)
    q = true.check_q(q)
    markers = np.asarray(markers, float)
    xyz = np.stack([flange_point(true, q, true.params.values, m)[0] for m in markers], axis=1)
    xyz = xyz + std * rng.standard_normal(xyz.shape)
    hide = rng.random(xyz.shape[:2]) < missing
    hide[np.all(hide, axis=1), 0] = False
    xyz[hide] = np.nan
    return MarkersObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} markers", xyz=xyz,
                      names=tuple(f"m{k + 1}" for k in range(len(markers))), std=std)


def reach(true: Robot, targets: np.ndarray, seed: int = 0, max_rounds: int = 20, strict: bool = True) -> np.ndarray:
    """(N, n) joint values within the limits that put ``true``'s tool point at ``targets`` (N, 3) m,
    each from a random start (damped least squares, each step projected onto the limits); a target
    that cannot be reached is a ModelError (``strict``) or a row of NaN."""
    rng = np.random.default_rng(seed)
    targets = np.asarray(targets, float)
    q = np.empty((len(targets), true.n_joints))
    todo = np.arange(len(targets))
    for _ in range(max_rounds):
        if not todo.size:
            return q
        x = true.sample_joints(todo.size, seed=int(rng.integers(2**31)))
        for _ in range(60):
            J = true.joint_jacobian(x)
            e = targets[todo] - true.forward(x)
            JJt = J @ J.transpose(0, 2, 1) + 1e-6 * np.eye(3)
            x = x + np.einsum("nji,nj->ni", J, np.linalg.solve(JJt, e[..., None])[..., 0])
            x = np.clip(x, true.lower, true.upper)  # projected steps: a redundant arm slides along its limits
        ok = (np.linalg.norm(targets[todo] - true.forward(x), axis=1) < IK_TOL) & true.within_limits(x)
        q[todo[ok]] = x[ok]
        todo = todo[~ok]
    q[todo] = np.nan
    if todo.size and strict:
        raise ModelError(f"{todo.size} target point(s) could not be reached by {true.name} (first: "
                         f"{targets[todo[0]].round(4).tolist()} m)")
    return q


def simulate_same_point(true: Robot, points: dict, per_point: int, distances=(), std: float = 0.05e-3,
                        std_distance: float = 0.1e-3, seed: int = 0) -> SamePointObs:
    """A ball seated ``per_point`` times, each in another configuration, at each labelled point (``points``: label
    -> (3,) m in the robot base frame), within ``std`` (m per axis); ``distances`` ((a, b, d m), …) are known."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.array(list(points), dtype=str), per_point)
    where = np.repeat(np.array([points[k] for k in points], float), per_point, axis=0)
    q = reach(true, where + std * rng.standard_normal(where.shape), seed=seed)
    return SamePointObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} sockets", labels=labels,
                        distances=tuple(distances), std=std, std_distance=std_distance)


def simulate_planes(true: Robot, planes: dict, per_plane: int, known=(), std: float = 0.05e-3,
                    seed: int = 0) -> PlaneObs:
    """Contacts of the tool point with planes (``planes``: label -> (unit normal (3,), offset c m), robot base frame)
    at random reachable points of each, within ``std`` (m) across it; labels in ``known`` are stated as known."""
    rng = np.random.default_rng(seed)
    qs = []
    for lab, (n, c) in planes.items():
        n = np.asarray(n, float) / np.linalg.norm(n)
        p = true.forward(true.sample_joints(4 * per_plane, seed=int(rng.integers(2**31))))
        on = p - (p @ n - c)[:, None] * n + std * rng.standard_normal(len(p))[:, None] * n
        q = reach(true, on, seed=seed, max_rounds=5, strict=False)
        q = q[np.all(np.isfinite(q), axis=1)][:per_plane]
        if len(q) < per_plane:
            raise ModelError(f"plane {lab}: only {len(q)} of {per_plane} contacts are within reach of {true.name}")
        qs.append(q)
    q = np.concatenate(qs)
    return PlaneObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} plane contacts",
                    labels=np.repeat(list(planes), per_plane), known={lab: planes[lab] for lab in known}, std=std)


def socket_plan(robot: Robot, placements: int = 4, spacing: float = 0.05, seed: int = 0) -> tuple[dict, tuple]:
    """Where to put a two-socket plate: ``placements`` places within comfortable reach (40–70 % of the farthest
    horizontal reach over random poses, and the middle 30 % of their heights, spread around the base, both sockets
    reached by inverse kinematics), each with sockets 0 and 1 ``spacing`` m apart across the radial direction.
    Returns (points, distances) for :func:`simulate_same_point` (labels "<placement>/<socket>")."""
    p = robot.forward(robot.sample_joints(2000, seed=seed))
    r = np.linalg.norm(p[:, :2], axis=1)
    lo, hi = np.percentile(p[:, 2], [35, 65])  # and heights in the middle: away from the edge of reach
    ok = np.flatnonzero((r > 0.4 * r.max()) & (r < 0.7 * r.max()) & (p[:, 2] > lo) & (p[:, 2] < hi))
    if len(ok) < placements:
        raise ModelError(f"{robot.name}: too few poses within comfortable reach to place {placements} plates")
    order = ok[np.argsort(np.arctan2(p[ok, 1], p[ok, 0]), kind="stable")]
    points, distances = {}, []
    for k, start in enumerate(np.linspace(0, len(order), placements, endpoint=False).astype(int)):
        for i in np.roll(order, -start)[:50]:  # the first candidate from there whose two sockets are reached
            u = np.array([-p[i, 1], p[i, 0], 0.0]) / max(r[i], 1e-9)
            pair = np.array([p[i], p[i] + spacing * u])
            if np.isfinite(reach(robot, pair, seed=seed, max_rounds=5, strict=False)).all():
                break
        else:
            raise ModelError(f"{robot.name}: no place for a plate near candidate {start} within reach")
        points[f"place{k + 1}/0"], points[f"place{k + 1}/1"] = pair
        distances.append((f"place{k + 1}/0", f"place{k + 1}/1", spacing))
    return points, tuple(distances)


def plane_plan(robot: Robot, step: float = 0.05, seed: int = 0) -> dict:
    """A table and a gauge-block step on it (horizontal planes ``step`` m apart, both known) at the
    height the tool point reaches most easily (the 30th percentile of random poses' heights)."""
    z = float(np.percentile(robot.forward(robot.sample_joints(2000, seed=seed))[:, 2], 30))
    up = np.array([0.0, 0.0, 1.0])
    return {"table": (up, z), "step": (up, z + step)}
