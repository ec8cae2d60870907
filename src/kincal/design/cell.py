"""The cell around the robot: where a measurement pose may put the target, as one predicate on joint
vectors that candidate pools, exchange designs and IDE all obey.

A pose is allowed when its joints keep ``joint_margin`` from the limits, the target (the robot's
tool point, in its base frame) lies on the allowed side of every half-space (a floor, a wall:
n·p ≥ c) and outside every keep-out box, the arm does too — every link after the first joint's
frame, as the segments between the robot's link points (:meth:`Robot.link_points`: its joint
frames and the tool point) thickened by ``link_radius`` —, and, with a ``tracker``, the target is
within the tracker's range and seen by it: the reflector's opening (``reflector_axis`` in the
flange frame) points within ``cone`` of the line from the target to the tracker, no link crosses that
line, and the arm keeps out of the tracker's head (the arm's checks run with a half-space or a box);
nor may the wrist or the target come within two link radii of the robot's own base column.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._frozen import freeze_arrays
from ..checks import whole
from ..errors import ModelError
from ..models.robot import Robot
from ..ties import first_best


TRACKER_HALF = 0.15  # m: a tracker's head as a box this far each way from its position, which the arm keeps out of
BEAM_START = 0.1  # m: the line of sight is kept clear of the links from this far out from the target (the wrist
# behind the reflector is not in it)


@dataclass(frozen=True, eq=False)
class Cell:
    """The constraints of the cell around the robot, SI, in the robot's base frame.

    A pose is allowed when its joints keep ``joint_margin`` from the limits, the target (the tool point)
    and the arm (its links as segments thickened by ``link_radius``) lie on the allowed side of every
    half-space and outside every keep-out box, and, with a ``tracker``, the target is within its range and
    seen by it (see the module's description).

    Parameters
    ----------
    half_spaces : tuple of (array_like, float), optional
        ((normal (3,), c), ...): the points p with n·p ≥ c are kept (n normalised; c in m), e.g. a floor
        or a wall (default none).
    keep_out : tuple of (array_like, array_like), optional
        ((lower (3,), upper (3,)), ...): boxes, m, that the target and the arm may not enter (default
        none).
    tracker : ndarray, shape (3,), optional
        Position of the tracker, m, or None (default: no tracker, no range or line-of-sight check).
    tracker_range : tuple of float, optional
        (min, max) distance of the target from the tracker, m, with 0 ≤ min < max (default (0, inf)).
    cone : float, optional
        Half-angle of the reflector's acceptance, rad, in (0, π] (default 30° = 0.5236 rad).
    reflector_axis : tuple of float, optional
        The reflector's opening (3,) in the flange frame, non-zero (default (0, 0, 1)).
    joint_margin : float, optional
        Kept from each revolute joint's limits, rad, ≥ 0 (default 0).
    link_radius : float, optional
        The arm's links as segments this thick, m, in [0, 1) (default 0.05).
    labels : tuple of (str, str), optional
        ((constraint, how the user gave it), ...), e.g. (('half-space 1', '--floor'),): the words messages
        use for a constraint (default: its own name, 'half-space k', 'keep-out k', ...).

    Attributes
    ----------
    empty : bool
        True when the cell has no half-space, box, tracker or joint margin (it allows what the robot
        allows).

    Raises
    ------
    ValueError
        When a half-space, box, range, cone, axis, margin or radius is not valid.

    Examples
    --------
    >>> import kincal
    >>> from kincal.design import Cell
    >>> robot = kincal.load_robot("ur5")
    >>> cell = Cell(half_spaces=(((0.0, 0.0, 1.0), 0.0),))  # a floor through the base: z ≥ 0 m
    >>> q = cell.pool(robot, 50, seed=0)
    >>> q.shape, bool(cell.allows(robot, q).all()), bool((robot.forward(q)[:, 2] >= 0.0).all())
    ((50, 6), True, True)
    >>> sorted(cell.violations(robot, q))
    ['arm into its own base', 'arm through half-space 1', 'half-space 1', 'joint margin']
    >>> Cell(tracker_range=(2.0, 1.0))
    Traceback (most recent call last):
        ...
    ValueError: tracker range 2.0..1.0 m: give 0 ≤ min < max
    """

    half_spaces: tuple = ()
    keep_out: tuple = ()
    tracker: np.ndarray | None = None
    tracker_range: tuple[float, float] = (0.0, np.inf)
    cone: float = np.deg2rad(30.0)
    reflector_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    joint_margin: float = 0.0
    link_radius: float = 0.05  # m: the arm's links as segments this thick
    labels: tuple = ()  # ((constraint, how the user gave it), ...)

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place
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
        if not np.linalg.norm(self.reflector_axis) > 0:
            raise ValueError(f"reflector axis {tuple(map(float, self.reflector_axis))}: give a non-zero direction")
        if not self.joint_margin >= 0:
            raise ValueError(f"joint margin {self.joint_margin:g} rad: give 0 or more")
        if not 0 <= self.link_radius < 1:
            raise ValueError(f"link radius {self.link_radius:g} m: give 0 or more, below 1 m")

    @property
    def empty(self) -> bool:
        """Whether the cell adds no constraint to the robot's own."""
        return not (self.half_spaces or self.keep_out or self.tracker is not None or self.joint_margin)

    def violations(self, robot: Robot, q: np.ndarray) -> dict[str, np.ndarray]:
        """(N,) bool per constraint broken by the poses q (N, n): 'joint margin', 'half-space k', 'keep-out k' (and
        their arm's), 'arm into its own base' (with a half-space or a box and a link radius), 'arm into the tracker'
        (its head a box TRACKER_HALF each way, with a half-space or a box), 'tracker range', 'line of sight' (the
        reflector facing the tracker) and 'arm across the line of sight' (a link within its radius of the beam)."""
        q = robot.check_q(q)
        m = np.where(robot.revolute, self.joint_margin, 0.0)
        out = {"joint margin": ~np.all((q >= robot.lower + m) & (q <= robot.upper - m), axis=1)}
        p, pts, r = robot.forward(q), self._points(robot, q), self.link_radius
        arm = None if pts is None else (pts[:, 2:-1], pts[:, 3:])
        for k, (n, c) in enumerate(self.half_spaces):
            unit = np.asarray(n, float) / np.linalg.norm(n)
            out[f"half-space {k + 1}"] = p @ unit < c
            if arm is not None:  # a straight segment is lowest at one of its ends
                out[f"arm through half-space {k + 1}"] = np.any(np.minimum(arm[0] @ unit, arm[1] @ unit) < c + r, axis=1)
        if pts is not None and r > 0:
            out["arm into its own base"] = _into_base(pts, p, r)
        for k, (lo, hi) in enumerate(self.keep_out):
            out[f"keep-out {k + 1}"] = np.all((p > lo) & (p < hi), axis=1)
            if arm is not None:
                out[f"arm in keep-out {k + 1}"] = np.any(_crosses(*arm, np.asarray(lo) - r, np.asarray(hi) + r), axis=1)
        if self.tracker is not None and arm is not None:  # the tracker's head as a box the arm keeps out of
            head = np.asarray(self.tracker, float)
            reach = TRACKER_HALF + r
            out["arm into the tracker"] = np.any(_crosses(*arm, head - reach, head + reach), axis=1)
        if self.tracker is not None:
            if not robot.has_tool_point:
                raise ModelError(f"robot '{robot.name}' has no flange frame: a tracker's line of sight needs it")
            ray = np.asarray(self.tracker, float) - p
            dist = np.linalg.norm(ray, axis=1)
            out["tracker range"] = (dist < self.tracker_range[0]) | (dist > self.tracker_range[1])
            axis = robot.flange_rotation(q) @ (np.asarray(self.reflector_axis, float) / np.linalg.norm(self.reflector_axis))
            cos = np.einsum("ni,ni->n", axis, ray) / np.maximum(dist, 1e-300)
            out["line of sight"] = cos < np.cos(self.cone)
            if arm is not None:  # the beam, from BEAM_START out from the target to the tracker, clear of the links
                start = p + ray * (np.minimum(BEAM_START, dist / 2) / np.maximum(dist, 1e-300))[:, None]
                gap = _segments_gap(*arm, start[:, None], np.broadcast_to(self.tracker, p.shape)[:, None])
                out["arm across the line of sight"] = np.any(gap < r, axis=1)
        return out

    def said(self, name: str) -> str:
        """A constraint of :meth:`violations` in the user's words (its label: 'arm through --floor'), else its
        own name."""
        for key, label in self.labels:
            for lead in ("", "arm through ", "arm in "):
                if name == lead + key:
                    return lead + label
        return name

    def _points(self, robot: Robot, q: np.ndarray) -> np.ndarray | None:
        """The robot's link points (N, P, 3) when the arm is checked (a half-space or a box, and at least four
        points: links after the first joint's frame); None otherwise."""
        pts = robot.link_points(q) if self.half_spaces or self.keep_out else None
        return None if pts is None or pts.shape[1] < 4 else pts

    def _arm(self, robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The links after the first joint's frame as segments between the robot's link points: their
        starts and ends (N, S, 3) each; None for a robot that declares none or a cell with no
        half-space or box."""
        pts = self._points(robot, q)
        return None if pts is None else (pts[:, 2:-1], pts[:, 3:])

    def allows(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """(N,) bool: the robot's own constraints and every constraint of the cell hold."""
        ok = robot.feasible(q)
        return ok if self.empty else ok & ~np.any(list(self.violations(robot, q).values()), axis=0)

    def pool(self, robot: Robot, n: int, seed: int | None = 0, max_draws: int = 2_000_000,
             within: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """n random poses (n, n_joints) the cell allows, by rejection from uniform feasible draws (within the joint
        limits, or the ranges ``within`` = (lower, upper)); an error naming the constraint that removes most when
        fewer than 1 in 10⁴ draws pass (the arm's own links, when they break it at every draw and the target
        does not)."""
        rng = np.random.default_rng(seed)
        kept, have, drawn = [], 0, 0
        while have < n and drawn < max_draws:
            q = _draw(robot, max(4 * (n - have), 1000), int(rng.integers(2**31)), within)
            drawn += max(4 * (n - have), 1000)
            q = q[self.allows(robot, q)]
            kept.append(q)
            have += len(q)
            if drawn >= 20_000 and have < drawn * 1e-4:
                break
        if have < n:
            raise ValueError(f"only {have} of {drawn} random poses fit the cell; "
                             f"{self._what_removes(robot, _draw(robot, 2000, seed, within))}")
        return np.concatenate(kept)[:n]

    def _what_removes(self, robot: Robot, q: np.ndarray) -> str:
        """What keeps the draws q out of the cell: the constraint that removes most of them, or, when the arm's own
        links break a half-space or box at every draw and the target does not, that (with the arm's lowest link
        height against a half-space)."""
        broken = self.violations(robot, q)
        name = list(broken)[first_best([float(v.mean()) for v in broken.values()])]
        share = f"'{self.said(name)}' removes {100 * broken[name].mean():.0f} % of them"
        own = name.split(" ", 2)[-1]
        if not (name.startswith("arm ") and broken[name].all() and not broken[own].all()):
            return f"{share}: check its values and units"
        if own.startswith("keep-out"):
            return (f"the arm's own links enter {self.said(own)} at every pose ({share}; the target only "
                    f"{100 * broken[own].mean():.0f} %): does the box hold the robot's base or its first links? "
                    f"Check its corners, and the {self.link_radius * 1e3:g} mm link radius")
        k = int(own.split()[-1]) - 1
        n, c = self.half_spaces[k]
        arm = self._arm(robot, q)
        assert arm is not None  # an 'arm' constraint was checked
        unit = np.asarray(n, float) / np.linalg.norm(n)
        low = float(np.minimum(arm[0] @ unit, arm[1] @ unit).min(axis=1).max())
        return (f"the arm's own links sit below {self.said(own)} ({c * 1e3:g} mm) at every pose: their lowest "
                f"point is at most {low * 1e3:.0f} mm high in {len(q)} draws, {(low - self.link_radius) * 1e3:.0f} mm "
                f"with the {self.link_radius * 1e3:g} mm link radius (the target only breaks it in "
                f"{100 * broken[own].mean():.0f} %): give a floor the arm stands above (the mounting plane: 0mm), "
                f"or a smaller link radius")


def candidate_pool(robot: Robot, n: int, seed: int | None = 0) -> np.ndarray:
    """The candidate pool of no cell: n feasible joint vectors drawn uniformly within the limits.

    Draws are kept only where ``robot.feasible`` holds (coupled constraints, assembly):
    ``robot.sample_joints``. A :class:`Cell` draws its own pool with :meth:`Cell.pool`.

    Parameters
    ----------
    robot : Robot
        The robot whose limits and constraints the poses keep.
    n : int
        Number of poses, 1 or more.
    seed : int or None, optional
        Random seed (default 0; None draws a fresh one).

    Returns
    -------
    ndarray, shape (n, n_joints)
        Joint values, rad (m for a prismatic joint).

    Raises
    ------
    ValueError
        When ``n`` is not a whole number of 1 or more.

    Examples
    --------
    >>> import kincal
    >>> from kincal.design import candidate_pool
    >>> robot = kincal.load_robot("ur5")
    >>> pool = candidate_pool(robot, 200, seed=1)
    >>> pool.shape, bool(robot.feasible(pool).all())
    ((200, 6), True)
    >>> bool((candidate_pool(robot, 200, seed=1) == pool).all())  # the same seed, the same pool
    True
    """
    return robot.sample_joints(whole("n", n, 1), seed)


def _segments_gap(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """(N, S): the least distance, m, between the segments a0→a1 and b0→b1 (broadcast over (N, S, 3)): the closest
    points' parameters solved on the lines, clamped to the segments (each end tried in turn)."""
    u, v, w = a1 - a0, b1 - b0, a0 - b0
    a, b, c = (np.einsum("...i,...i->...", x, y) for x, y in ((u, u), (u, v), (v, v)))
    d, e = np.einsum("...i,...i->...", u, w), np.einsum("...i,...i->...", v, w)
    den = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(den > 1e-12 * np.maximum(a * c, 1e-300), np.clip((b * e - c * d) / den, 0.0, 1.0), 0.0)
        t = np.where(c > 1e-300, (b * s + e) / c, 0.0)
        t = np.clip(t, 0.0, 1.0)  # then s again, for the clamped t
        s = np.where(a > 1e-300, np.clip((b * t - d) / a, 0.0, 1.0), 0.0)
    return np.linalg.norm(w + s[..., None] * u - t[..., None] * v, axis=-1)


def _into_base(pts: np.ndarray, tool: np.ndarray, r: float) -> np.ndarray:
    """(N,) bool: the wrist's link points (from the fourth joint's on) or the target (N, 3) come within two link
    radii ``r`` (m) of the robot's base column, the segment from its base to the second joint's frame (link points
    ``pts`` (N, P, 3)): the arm folded into its own base (a UR5's tool 61 mm from its axis at 79 mm height)."""
    a, b = pts[:, 0], pts[:, 2]
    x = np.concatenate([pts[:, 4:], tool[:, None]], axis=1)  # (N, K, 3)
    d = b - a
    t = np.clip(np.einsum("nkj,nj->nk", x - a[:, None], d) / np.maximum(np.einsum("nj,nj->n", d, d), 1e-300)[:, None],
                0.0, 1.0)
    near = a[:, None] + t[..., None] * d[:, None]
    return np.any(np.linalg.norm(x - near, axis=2) < 2 * r, axis=1)


def _crosses(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(N, S) bool: the segments a→b (N, S, 3) meet the box lo..hi (slab test: the parameter ranges in
    which each axis is inside overlap within [0, 1])."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - a) / d, (hi - a) / d
    parallel = d == 0  # inside the slab for every t, or for none
    inside = (a >= lo) & (a <= hi)
    enter = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)).max(axis=2)
    leave = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)).min(axis=2)
    return (enter <= leave) & (leave >= 0.0) & (enter <= 1.0)


def _draw(robot: Robot, n: int, seed: int | None, within: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """Feasible random poses of n draws, uniform within the joint limits or within the ranges ``within``."""
    if within is None:
        return robot.sample_joints(n, seed=seed)
    lo, hi = np.maximum(within[0], robot.lower), np.minimum(within[1], robot.upper)
    q = np.random.default_rng(seed).uniform(lo, hi, size=(n, len(lo)))
    return q[robot.feasible(q)]
