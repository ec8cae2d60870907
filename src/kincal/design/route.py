"""The route of a measurement program through designed poses: their order, the turn of each joint, and the moves
between them checked against the cell.

A joint move (``movej``) goes along the straight line in joint space between two poses, so a cell that allows both
poses may still be left between them. :func:`plan_route` orders the poses to keep the travel short (nearest
neighbour from the pose nearest the middle of the joint ranges, then 2-opt exchanges; the travel of a move is its
largest joint move, which sets a ``movej``'s duration; ties go to the earliest pose, :mod:`kincal.ties`), takes each
periodic joint whose limits span more than a turn at the equivalent value (±2π, within the limits) nearest the
previous pose's among those that keep the joint's whole turning the least the limits allow (:func:`turned`: a UR
joint's ±360° range holds two values of most angles, and a joint should neither swing a whole turn between two
poses nor drift to a limit and then turn back the long way), and samples every move finely (``step``, 1° by
default, of its largest joint move) against the cell's floor, walls and keep-out boxes (the tool point and the arm's links,
:meth:`Cell.violations`). A move that leaves the cell gets a via pose — a cell pose (of the pool, or one with the
first joint of either end) that keeps both halves inside, the one with the shortest travel — or is refused, naming
it. The tracker's range and line of sight are not checked on the way: nothing is measured while moving.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._frozen import freeze_arrays
from ..models.robot import Robot
from ..ties import TIE_RTOL, first_best, improves, order_with_ties, tie_tolerance
from .cell import Cell

STEP = np.deg2rad(1.0)  # rad: the largest joint move between two samples of a move
STEP_LENGTH = 1e-3  # m: the same for a prismatic joint
VIA_TRIES = 512  # via poses tried per move that leaves the cell, shortest travel first
TURN = 2.0 * np.pi


@dataclass(frozen=True, eq=False)
class Route:
    """The poses of a measurement program in the order they are visited, with the via poses between them.

    Parameters
    ----------
    order : ndarray of int, shape (m,)
        The input poses in the order they are visited.
    q : ndarray, shape (m, n)
        Their joint values in that order (periodic joints turned by :func:`turned` when the route turns them), rad
        or m.
    vias : tuple of (ndarray or None)
        Per move k → k + 1 (m − 1 of them): the via pose (n,) the arm goes through on the way, or None.
    checked : bool
        Whether the moves were checked against a cell (one with a floor, wall or keep-out box).
    travel : float
        The route's travel: the sum over its moves (vias included) of each one's largest joint move, rad (m for a
        prismatic joint).
    travel_given : float
        The same for the poses in the order and with the values they were given.

    Attributes
    ----------
    n_vias : int
        How many moves needed a via pose to stay inside the cell.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.design import Cell, plan_route
    >>> robot = kincal.load_robot("ur5")
    >>> cell = Cell(half_spaces=(((0.0, 0.0, 1.0), 0.0),))
    >>> q = cell.pool(robot, 12, seed=3)
    >>> route = plan_route(robot, q, cell, vias=cell.pool(robot, 500, seed=4))
    >>> route.order.tolist(), route.checked, route.n_vias
    ([10, 11, 8, 4, 3, 1, 9, 5, 2, 6, 7, 0], True, 0)
    >>> np.rad2deg([route.travel, route.travel_given]).round(0)  # deg: the largest joint moves, summed
    array([1514., 4816.])
    """

    order: np.ndarray
    q: np.ndarray
    vias: tuple
    checked: bool
    travel: float
    travel_given: float

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @property
    def n_vias(self) -> int:
        """How many moves needed a via pose."""
        return sum(v is not None for v in self.vias)

    def targets(self) -> np.ndarray:
        """(m + vias, n): every joint target of the program in order, vias included."""
        return _through(self.q, self.vias)


def _through(q: np.ndarray, vias) -> np.ndarray:
    """The targets of moves through the poses q (m, n) with the vias (m − 1: a pose or None) between them."""
    return np.array([q[0]] + [t for via, b in zip(vias, q[1:]) for t in ([] if via is None else [via]) + [b]])


def plan_route(robot: Robot, q: np.ndarray, cell: Cell | None = None, vias: np.ndarray | None = None,
               turn: bool = True, step: float = STEP) -> Route:
    """Order measurement poses for a short travel, turn their joints no more than needed, and keep every move
    between them inside the cell (see the module's description).

    Parameters
    ----------
    robot : Robot
        The robot, its base frame the cell's.
    q : ndarray, shape (m, n)
        The poses, rad (m for a prismatic joint).
    cell : Cell, optional
        The cell; without one (or one with no half-space or box) the moves are not checked.
    vias : ndarray, shape (P, n), optional
        Poses to try as vias (a design's pool); the poses themselves are tried too.
    turn : bool, optional
        Take each periodic joint spanning more than a turn at the equivalent value :func:`turned` chooses (default
        True); False keeps the poses' values (rows of a user's file).
    step : float, optional
        The largest joint move between two samples of a move, rad (default 1°).

    Returns
    -------
    Route
        The order, the joint values, the vias and the travel.

    Raises
    ------
    ValueError
        When a move leaves the cell and no via pose keeps it inside: the move (pose numbers in the route's order),
        the constraint it breaks, the lowest point on the way and what to do.
    """
    q = robot.check_q(q)
    order = travel_order(robot, q)
    geo = None if cell is None or not (cell.half_spaces or cell.keep_out) else cell
    tried = q if vias is None else np.vstack([robot.check_q(vias), q])
    poses = turned(robot, q[order], cell) if turn else q[order]
    via_list: list[np.ndarray | None] = []
    for k in range(1, len(poses)):
        a, b = poses[k - 1], poses[k]
        via = None
        if geo is not None and not _clear(robot, geo, a[None], b[None], step)[0]:
            via = _via(robot, geo, a, b, tried, step)
            if via is None:
                raise ValueError(_refusal(robot, geo, a, b, k, step))
        via_list.append(via)
    return Route(order, poses, tuple(via_list), geo is not None, _travel(robot, _through(poses, via_list)),
                 _travel(robot, q))


def turned(robot: Robot, q: np.ndarray, cell: Cell | None = None) -> np.ndarray:
    """Turn each periodic joint of poses visited in order no more than the limits make it.

    Each periodic joint whose limits span more than a turn is taken at the equivalent value (q ± 2πk, within the
    limits less the cell's joint margin) nearest the previous pose's among those that keep the joint's whole
    turning (the sum of its moves) the least the limits allow, so no joint drifts to a limit and then turns back
    the long way. The first pose's value is the one nearest the middle of the joint's range among those; ties
    (:data:`kincal.ties.TIE_RTOL` of a turn) go to the nearest value. The poses are the same: only whole turns of
    periodic joints change.

    Parameters
    ----------
    robot : Robot
        The robot (its joint limits and which joints are periodic).
    q : ndarray, shape (m, n)
        The poses in the order they are visited, rad (m for a prismatic joint).
    cell : Cell, optional
        The cell whose joint margin the values keep (default: none).

    Returns
    -------
    ndarray, shape (m, n)
        The poses with their periodic joints turned.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.design import turned
    >>> robot = kincal.load_robot("ur5")  # joint 1: ±360°
    >>> q = np.zeros((3, 6))
    >>> q[:, 0] = np.deg2rad([-170.0, 175.0, -175.0])
    >>> np.rad2deg(turned(robot, q)[:, 0]).round(3).tolist()  # 15° and 10°, not 345° and 350°
    [-170.0, -185.0, -175.0]
    """
    q = robot.check_q(q)
    margin = np.where(robot.revolute, 0.0 if cell is None else cell.joint_margin, 0.0)
    ks = np.arange(-3, 4)
    c = q[:, :, None] + TURN * ks  # (m, n, 7) the equivalents
    ok = (ks == 0) | (_wide(robot)[:, None] & (c >= (robot.lower + margin)[:, None])
                      & (c <= (robot.upper - margin)[:, None]))
    togo = np.zeros(c.shape)  # the least turning from each equivalent to the route's end
    for i in range(len(q) - 2, -1, -1):
        step_cost = np.abs(c[i][:, :, None] - c[i + 1][:, None, :]) + togo[i + 1][:, None, :]
        togo[i] = np.where(ok[i + 1][:, None, :], step_cost, np.inf).min(axis=2)
    out, prev = np.empty_like(q), _middle(robot)
    for i in range(len(q)):
        total = np.where(ok[i], togo[i] + (np.abs(c[i] - prev[:, None]) if i else 0.0), np.inf)
        tied = total <= total.min(axis=1, keepdims=True) + TIE_RTOL * TURN
        pick = np.argmin(np.where(tied, np.abs(c[i] - prev[:, None]), np.inf), axis=1)
        out[i] = prev = c[i][np.arange(q.shape[1]), pick]
    return out


def travel_order(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Order poses for a short travel between them.

    Nearest neighbour from the pose nearest the middle of the joint ranges, then 2-opt exchanges until none
    shortens the travel beyond the tie band; the end nearer the middle comes first. A move's travel is its largest
    joint move (what sets a joint move's duration), a periodic joint spanning more than a turn counted the short
    way round. Deterministic: ties go to the earliest pose (:mod:`kincal.ties`).

    Parameters
    ----------
    robot : Robot
        The robot (its joint limits and types).
    q : ndarray, shape (m, n)
        The poses, rad (m for a prismatic joint).

    Returns
    -------
    ndarray of int, shape (m,)
        The poses' indices in the order they are visited.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.design import travel_order
    >>> robot = kincal.load_robot("ur5")
    >>> q = np.zeros((4, 6))
    >>> q[:, 1] = [0.9, 0.1, 0.6, 0.3]
    >>> travel_order(robot, q).tolist()
    [1, 3, 2, 0]
    """
    q = robot.check_q(q)
    D = _distance(robot, q[:, None], q[None])
    home = _distance(robot, q, _middle(robot))
    path = [first_best(home, maximize=False)]
    rest = [k for k in range(len(q)) if k != path[0]]
    while rest:
        path.append(rest.pop(first_best(D[path[-1], rest], maximize=False)))
    path = _two_opt(D, path)
    if improves(float(home[path[-1]]), float(home[path[0]]), maximize=False):
        path.reverse()
    return np.array(path, dtype=int)


def _two_opt(D: np.ndarray, path: list[int]) -> list[int]:
    """An open path improved by reversing stretches of it while one shortens it beyond the tie band (the first
    such reversal in path order each time)."""
    m = len(path)
    for _ in range(50 * m):
        p = np.array(path)
        done = True
        for i in range(m - 1):
            j = np.arange(i + 1, m)
            before_i = D[p[i - 1], p[i]] if i > 0 else 0.0
            after_j = np.where(j < m - 1, D[p[j], p[np.minimum(j + 1, m - 1)]], 0.0)
            new_i = D[p[i - 1], p[j]] if i > 0 else np.zeros(len(j))
            new_j = np.where(j < m - 1, D[p[i], p[np.minimum(j + 1, m - 1)]], 0.0)
            gain = before_i + after_j - new_i - new_j
            band = tie_tolerance(float(D.max()))
            better = np.flatnonzero(gain > band)
            if better.size:
                jj = int(j[better[0]])
                path = path[:i] + path[i:jj + 1][::-1] + path[jj + 1:]
                done = False
                break
        if done:
            break
    return path


def _distance(robot: Robot, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The largest joint move from a to b (broadcast, last axis the joints); a periodic joint spanning more than a
    turn the short way round."""
    d = np.abs(np.asarray(b, float) - np.asarray(a, float))
    d = np.where(_wide(robot), np.abs((d + np.pi) % TURN - np.pi), d)
    return np.where(_moving(robot), d, 0.0).max(axis=-1)


def _wide(robot: Robot) -> np.ndarray:
    """(n,) bool: periodic joints whose limits span more than a turn."""
    return robot.periodic & (robot.upper - robot.lower > TURN)


def _moving(robot: Robot) -> np.ndarray:
    """(n,) bool: the joints a move moves (revolute and prismatic, not covariates)."""
    return np.array([t in ("revolute", "prismatic") for t in robot.joint_types], bool)


def _middle(robot: Robot) -> np.ndarray:
    """(n,) the middle of each joint's range (0 for an unlimited one)."""
    lo, hi = robot.lower, robot.upper
    return np.where(np.isfinite(lo) & np.isfinite(hi), (lo + hi) / 2.0, 0.0)


def _equivalent(robot: Robot, x: np.ndarray, ref: np.ndarray, cell: Cell | None) -> np.ndarray:
    """x (..., n) with each periodic joint spanning more than a turn at the equivalent value (x ± 2πk) nearest
    ``ref`` that keeps the limits (less the cell's joint margin); x's own value when none is nearer."""
    margin = np.where(robot.revolute, 0.0 if cell is None else cell.joint_margin, 0.0)
    lo, hi = robot.lower + margin, robot.upper - margin
    x = np.asarray(x, float)
    k0 = np.round((ref - x) / TURN)
    best, cost = x.copy(), np.abs(x - ref)
    for k in (k0 - 1, k0, k0 + 1):
        c = x + TURN * k
        ok = _wide(robot) & (c >= lo) & (c <= hi) & (np.abs(c - ref) < cost - 1e-12)
        best, cost = np.where(ok, c, best), np.where(ok, np.abs(c - ref), cost)
    return best


def _travel(robot: Robot, q: np.ndarray) -> float:
    """The travel of moves through the targets q (m, n) in order: the sum of each move's largest joint move."""
    d = np.abs(np.diff(q, axis=0))
    return float(np.where(_moving(robot), d, 0.0).max(axis=1).sum()) if len(q) > 1 else 0.0


def _samples(robot: Robot, a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """(s, n) points along the joint-space line a → b, both ends included, no joint moving more than ``step``
    (rad; 1 mm for a prismatic joint) between two."""
    d = np.abs(b - a)
    per = np.where(robot.revolute, d / step, np.where(_moving(robot), d / STEP_LENGTH, 0.0))
    n = max(int(np.ceil(per.max())), 1)
    return a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)


def _clear(robot: Robot, geo: Cell, A: np.ndarray, B: np.ndarray, step: float) -> np.ndarray:
    """(K,) bool: the moves A[k] → B[k] (K, n) keep the robot's constraints, the cell's floor, walls and boxes and
    its joint margin at every sample (the tracker is not checked: nothing is measured on the way)."""
    parts = [_samples(robot, a, b, step) for a, b in zip(A, B)]
    ok = _ground(geo).allows(robot, np.vstack(parts))
    ends = np.cumsum([len(p) for p in parts])
    return np.array([bool(ok[e - len(p):e].all()) for p, e in zip(parts, ends)])


def _ground(cell: Cell) -> Cell:
    """The cell without its tracker: what a move must keep."""
    return Cell(cell.half_spaces, cell.keep_out, joint_margin=cell.joint_margin, link_radius=cell.link_radius,
                labels=cell.labels)


def _via(robot: Robot, geo: Cell, a: np.ndarray, b: np.ndarray, pool: np.ndarray, step: float) -> np.ndarray | None:
    """A via pose for the move a → b that keeps both halves inside the cell, of the pool and the pool with the
    first joint of a or of b, at its equivalent nearest a (shortest travel first, ties to the earliest); None when
    none of ``VIA_TRIES`` does."""
    c = np.vstack([pool] + [np.column_stack([np.full(len(pool), e[0]), pool[:, 1:]]) for e in (a, b)])
    c = _equivalent(robot, c[_ground(geo).allows(robot, c)], a, geo)
    c = c[np.sort(np.unique(c, axis=0, return_index=True)[1])]  # each pose once, in canonical order
    if not len(c):
        return None
    cost = _distance(robot, a, c) + np.abs(b - c).max(axis=1)
    near = np.sort(np.argsort(cost, kind="stable")[:2 * VIA_TRIES])  # the shortest, in canonical order
    ranked = near[order_with_ties(cost[near], descending=False)][:VIA_TRIES]
    for s in range(0, len(ranked), 64):
        idx = ranked[s:s + 64]
        ok = _clear(robot, geo, np.broadcast_to(a, (len(idx), len(a))), c[idx], step)
        ok[ok] &= _clear(robot, geo, c[idx[ok]], np.broadcast_to(b, (int(ok.sum()), len(b))), step)
        if ok.any():
            return c[int(idx[np.flatnonzero(ok)[0]])]
    return None


def _refusal(robot: Robot, geo: Cell, a: np.ndarray, b: np.ndarray, k: int, step: float) -> str:
    """Why the move to the route's pose k + 1 (1-based) is refused: the constraints it breaks, where it first
    leaves the cell, the lowest point of the arm and tool on the way, and what to do."""
    s = _samples(robot, a, b, step)
    broken = _ground(geo).violations(robot, s)
    bad = [name for name, v in broken.items() if v.any()]
    first = min(int(np.flatnonzero(broken[name])[0]) for name in bad) if bad else 0
    pts = robot.link_points(s)
    z = robot.forward(s)[:, 2] if pts is None else np.minimum(pts[:, 2:, 2].min(axis=1), robot.forward(s)[:, 2])
    what = ", ".join(geo.said(name) for name in bad) or "the robot's own constraints"
    return (f"the move from pose {k} to pose {k + 1} (the route's order) leaves the cell: {what}, from "
            f"{100 * first / max(len(s) - 1, 1):.0f} % of the way (the arm's lowest point on it: z = "
            f"{z.min() * 1e3:.0f} mm in the base frame), and none of the via poses tried keeps both halves of it "
            f"inside: draw the poses again (another seed or a larger pool), or move the arm between these two poses "
            f"by hand and leave the program out")
