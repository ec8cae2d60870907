"""The cell around the robot: where a measurement pose may put the target, as one predicate on joint
vectors that candidate pools, exchange designs and IDE all obey.

A pose is allowed when its joints keep ``joint_margin`` from the limits, the target (the robot's
tool point, in its base frame) lies on the allowed side of every half-space (a floor, a wall:
n·p ≥ c) and outside every keep-out box, and, with a ``tracker``, within the tracker's range and
seen by it: the reflector's opening (``reflector_axis`` in the flange frame) points within
``cone`` of the line from the target to the tracker.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot
from ..ties import first_best


@dataclass(frozen=True, eq=False)
class Cell:
    """Constraints of the cell (SI, robot base frame): half_spaces ((normal (3,), c): n·p ≥ c kept),
    keep_out ((lower (3,), upper (3,)) boxes the target may not enter), tracker (3,) position or None,
    tracker_range (min, max) m, cone (rad, half-angle of the reflector's acceptance), reflector_axis
    (3,) in the flange frame, joint_margin (rad kept from each revolute joint's limits)."""

    half_spaces: tuple = ()
    keep_out: tuple = ()
    tracker: np.ndarray | None = None
    tracker_range: tuple[float, float] = (0.0, np.inf)
    cone: float = np.deg2rad(30.0)
    reflector_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    joint_margin: float = 0.0

    def __post_init__(self) -> None:
        for n, c in self.half_spaces:
            if np.shape(n) != (3,) or not np.linalg.norm(n) > 0 or not np.isfinite(c):
                raise ValueError(f"half-space ({n}, {c}): give a non-zero normal (3 numbers) and a finite offset")
        for lo, hi in self.keep_out:
            if np.shape(lo) != (3,) or np.shape(hi) != (3,) or not np.all(np.asarray(lo) < np.asarray(hi)):
                raise ValueError(f"keep-out box {lo}..{hi}: give the lower corner below the upper one on every axis")
        lo, hi = self.tracker_range
        if not 0 <= lo < hi:
            raise ValueError(f"tracker range {lo}..{hi} m: give 0 ≤ min < max")
        if not 0 < self.cone <= np.pi:
            raise ValueError(f"cone {np.rad2deg(self.cone):g} deg: give a half-angle in (0, 180] deg")
        if not np.linalg.norm(self.reflector_axis) > 0 or self.joint_margin < 0:
            raise ValueError("the reflector axis must be non-zero and the joint margin ≥ 0")

    @property
    def empty(self) -> bool:
        return not (self.half_spaces or self.keep_out or self.tracker is not None or self.joint_margin)

    def violations(self, robot: Robot, q: np.ndarray) -> dict[str, np.ndarray]:
        """(N,) bool per constraint broken by the poses q (N, n): 'joint margin', 'half-space k',
        'keep-out k', 'tracker range', 'line of sight'."""
        q = robot.check_q(q)
        m = np.where([t == "revolute" for t in robot.joint_types], self.joint_margin, 0.0)
        out = {"joint margin": ~np.all((q >= robot.lower + m) & (q <= robot.upper - m), axis=1)}
        p = robot.forward(q)
        for k, (n, c) in enumerate(self.half_spaces):
            out[f"half-space {k + 1}"] = p @ (np.asarray(n, float) / np.linalg.norm(n)) < c
        for k, (lo, hi) in enumerate(self.keep_out):
            out[f"keep-out {k + 1}"] = np.all((p > lo) & (p < hi), axis=1)
        if self.tracker is not None:
            if not robot.has_tool_point:
                raise ModelError(f"robot '{robot.name}' has no flange frame: a tracker's line of sight needs it")
            ray = np.asarray(self.tracker, float) - p
            dist = np.linalg.norm(ray, axis=1)
            out["tracker range"] = (dist < self.tracker_range[0]) | (dist > self.tracker_range[1])
            axis = robot.flange_rotation(q) @ (np.asarray(self.reflector_axis, float) / np.linalg.norm(self.reflector_axis))
            cos = np.einsum("ni,ni->n", axis, ray) / np.maximum(dist, 1e-300)
            out["line of sight"] = cos < np.cos(self.cone)
        return out

    def allows(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """(N,) bool: the robot's own constraints and every constraint of the cell hold."""
        ok = robot.feasible(q)
        if self.empty:
            return ok
        return ok & ~np.any(list(self.violations(robot, q).values()), axis=0)

    def pool(self, robot: Robot, n: int, seed: int | None = 0, max_draws: int = 2_000_000) -> np.ndarray:
        """n random poses (n, n_joints) the cell allows, by rejection from uniform feasible draws; an
        error naming the constraint that removes most when fewer than 1 in 10⁴ draws pass."""
        rng = np.random.default_rng(seed)
        kept, have, drawn = [], 0, 0
        while have < n and drawn < max_draws:
            q = robot.sample_joints(max(4 * (n - have), 1000), seed=int(rng.integers(2**31)))
            drawn += len(q)
            q = q[self.allows(robot, q)]
            kept.append(q)
            have += len(q)
            if drawn >= 20_000 and have < drawn * 1e-4:
                break
        if have < n:
            broken = self.violations(robot, robot.sample_joints(2000, seed))
            name = list(broken)[first_best([float(v.mean()) for v in broken.values()])]
            raise ValueError(f"only {have} of {drawn} random poses fit the cell; '{name}' removes "
                             f"{100 * broken[name].mean():.0f} % of them: check its values and units")
        return np.concatenate(kept)[:n]
