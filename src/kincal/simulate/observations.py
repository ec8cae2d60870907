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
from ..units import MM

IK_TOL = 1e-9  # m


def simulate_poses(true: Robot, q: np.ndarray, target_rotation: np.ndarray, std_pos: float = 0.1e-3,
                   std_rot: float = 1e-3, seed: int = 0) -> PoseObs:
    """Simulate 6-D pose measurements of a target frame on the flange.

    The target's origin is the true tool point; its orientation is ``target_rotation`` on the flange. Each
    position gets isotropic Gaussian noise of σ = ``std_pos`` per axis, each rotation a random turn about the
    world axes of σ = ``std_rot`` per axis.

    Parameters
    ----------
    true : Robot
        The robot that stands in for the real one.
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    target_rotation : ndarray, shape (3, 3)
        Orientation of the target frame in the flange frame (columns: its axes).
    std_pos : float, optional
        σ per axis of the position noise, m (default 0.1e-3).
    std_rot : float, optional
        σ per axis of the rotation noise, rad (default 1e-3).
    seed : int, optional
        Seed of the noise's random generator (default 0).

    Returns
    -------
    PoseObs
        Positions xyz (N, 3) m and rotations R (N, 3, 3) of the target in the world frame, with q, the rows
        2, 3, … and the noise levels as the observation's σ. The observation's own ``target_rotation`` is left
        at its default (identity): the calibration fits the target's orientation.

    Raises
    ------
    ModelError
        When q does not have one column per joint, or the robot has no tool point.
    """
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(seed)
    q = true.check_q(q)
    p, _, Rf = flange_point(true, q, true.params.values, true.tool_point())
    R = Rotation.from_rotvec(std_rot * rng.standard_normal((len(q), 3))).as_matrix() @ Rf @ target_rotation
    return PoseObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} poses", R=R, std_pos=std_pos, std_rot=std_rot,
                   xyz=p + std_pos * rng.standard_normal(p.shape))


def simulate_markers(true: Robot, q: np.ndarray, markers: np.ndarray, std: float = 15e-6, missing: float = 0.0,
                     seed: int = 0) -> MarkersObs:
    """Simulate a motion-capture view of k markers on the flange.

    Each marker's position at every configuration, with Gaussian noise of σ = ``std`` per axis; a share
    ``missing`` of the (sample, marker) cells is left unseen (NaN), but never every marker of one sample.

    Parameters
    ----------
    true : Robot
        The robot that stands in for the real one.
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    markers : array_like, shape (k, 3)
        The markers' positions in the flange frame, m.
    std : float, optional
        σ per axis of the position noise, m (default 15e-6).
    missing : float, optional
        Probability that a marker is not seen in a sample, 0 to 1 (default 0: every marker always seen).
    seed : int, optional
        Seed of the random generator of the noise and of the unseen cells (default 0).

    Returns
    -------
    MarkersObs
        xyz (N, k, 3) m in the world frame (NaN where unseen), the markers named m1, m2, …, with q, the rows
        2, 3, … and σ = ``std``.

    Raises
    ------
    ModelError
        When q does not have one column per joint.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import simulate_markers
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(4, seed=1)
    >>> obs = simulate_markers(robot, q, [[0.05, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 0.05]], missing=0.25)
    >>> obs.xyz.shape, obs.names
    ((4, 3, 3), ('m1', 'm2', 'm3'))
    >>> bool(np.isfinite(obs.xyz).all(axis=2).any(axis=1).all())  # every sample sees a marker
    True

    Without noise a marker is where the tool point would be at its place:

    >>> exact = simulate_markers(robot, q, [[0.05, 0.0, 0.0]], std=0.0)
    >>> bool(np.allclose(exact.xyz[:, 0], robot.with_tool_point([0.05, 0.0, 0.0]).forward(q)))
    True
    """
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
    """Find joint values that put the tool point at given points (numerical inverse kinematics).

    Each target is approached from a random start within the limits by 60 steps of damped least squares, each
    step projected onto the joint limits (a redundant arm slides along them); a target not reached within
    ``IK_TOL`` (1 nm) is tried again from a new start, up to ``max_rounds`` times.

    Parameters
    ----------
    true : Robot
        The robot whose tool point must reach the targets.
    targets : array_like, shape (N, 3)
        The points in the world frame, m.
    seed : int, optional
        Seed of the random generator of the starts (default 0).
    max_rounds : int, optional
        How many random starts each target gets at most (default 20).
    strict : bool, optional
        Raise for a target that cannot be reached (default True); when False its row is NaN.

    Returns
    -------
    ndarray, shape (N, n)
        Joint values within the limits, rad (m for a prismatic joint), one row per target (NaN rows for
        targets out of reach when not ``strict``).

    Raises
    ------
    ModelError
        When ``strict`` and a target cannot be reached; the message counts them and gives the first.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import reach
    >>> robot = kincal.load_robot("scara")
    >>> targets = robot.forward(robot.sample_joints(3, seed=2))
    >>> q = reach(robot, targets)
    >>> q.shape, bool(np.allclose(robot.forward(q), targets, atol=1e-9)), bool(robot.within_limits(q).all())
    ((3, 4), True, True)
    >>> reach(robot, [[10.0, 0.0, 0.0]], max_rounds=1, strict=False)
    array([[nan, nan, nan, nan]])
    """
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
                         f"{((targets[todo[0]] * MM).round(1) + 0.0).tolist()} mm)")  # + 0.0: no -0.0
    return q


def simulate_same_point(true: Robot, points: dict, per_point: int, distances=(), std: float = 0.05e-3,
                        std_distance: float = 0.1e-3, seed: int = 0) -> SamePointObs:
    """Simulate a ball on the tool seated in sockets: the same point reached in several configurations.

    At each labelled point the ball is seated ``per_point`` times, each time in another configuration (found by
    :func:`reach` from a random start), within Gaussian noise of σ = ``std`` per axis (how well it seats).

    Parameters
    ----------
    true : Robot
        The robot that stands in for the real one.
    points : dict
        Label (str) -> position (3,) of the socket in the world frame, m.
    per_point : int
        How many times the ball is seated at each point.
    distances : sequence of (str, str, float), optional
        Known distances between sockets: (label a, label b, distance m), ... (default none).
    std : float, optional
        σ per axis of where the ball seats, m (default 0.05e-3).
    std_distance : float, optional
        σ of the known distances, m (default 0.1e-3).
    seed : int, optional
        Seed of the random generator of the noise and of the starts of the inverse kinematics (default 0).

    Returns
    -------
    SamePointObs
        The joint values (N, n), N = ``per_point`` × the number of points, and each sample's label (the points
        in the order of ``points``), with the distances and their σ.

    Raises
    ------
    ModelError
        When a seated position cannot be reached within the joint limits.

    See Also
    --------
    socket_plan : Where to put a two-socket plate within reach.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import simulate_same_point
    >>> robot = kincal.load_robot("scara")
    >>> a = robot.forward(np.array([0.3, 0.5, 0.1, 0.0]))
    >>> b = robot.forward(np.array([-0.4, 0.8, 0.05, 0.0]))
    >>> d = float(np.linalg.norm(a - b))
    >>> obs = simulate_same_point(robot, {"a": a, "b": b}, per_point=2, distances=[("a", "b", d)])
    >>> obs.q.shape, obs.labels.tolist()
    ((4, 4), ['a', 'a', 'b', 'b'])
    >>> bool(np.all(np.linalg.norm(robot.forward(obs.q[:2]) - a, axis=1) < 0.5e-3))
    True
    """
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.array(list(points), dtype=str), per_point)
    where = np.repeat(np.array([points[k] for k in points], float), per_point, axis=0)
    q = reach(true, where + std * rng.standard_normal(where.shape), seed=seed)
    return SamePointObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} sockets", labels=labels,
                        distances=tuple(distances), std=std, std_distance=std_distance)


def simulate_planes(true: Robot, planes: dict, per_plane: int, known=(), std: float = 0.05e-3,
                    seed: int = 0) -> PlaneObs:
    """Simulate touches of the tool point on planes.

    Each plane n·x = c is touched at ``per_plane`` random points within reach (random poses projected onto the
    plane, reached by :func:`reach`), each off the plane by Gaussian noise of σ = ``std`` along its normal.

    Parameters
    ----------
    true : Robot
        The robot that stands in for the real one.
    planes : dict
        Label (str) -> (normal (3,), offset c in m): the plane n·x = c in the world frame (the normal is
        normalised here).
    per_plane : int
        How many contacts each plane gets.
    known : sequence of str, optional
        Labels of the planes the observation states as known (default none: each plane is fitted).
    std : float, optional
        σ of the contacts across the plane, m (default 0.05e-3).
    seed : int, optional
        Seed of the random generator of the points, the noise and the starts of the inverse kinematics
        (default 0).

    Returns
    -------
    PlaneObs
        The joint values (N, n), N = ``per_plane`` × the number of planes, each sample's plane label and the
        known planes as given.

    Raises
    ------
    ModelError
        When fewer than ``per_plane`` contacts of a plane are within reach.

    See Also
    --------
    plane_plan : A table and a gauge-block step at a height the tool reaches easily.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import plane_plan, simulate_planes
    >>> robot = kincal.load_robot("scara")
    >>> table = plane_plan(robot)["table"]
    >>> obs = simulate_planes(robot, {"table": table}, per_plane=3, known=["table"])
    >>> obs.q.shape, obs.labels.tolist(), list(obs.known)
    ((3, 4), ['table', 'table', 'table'], ['table'])
    >>> bool(np.all(np.abs(robot.forward(obs.q)[:, 2] - table[1]) < 0.5e-3))
    True
    """
    rng = np.random.default_rng(seed)
    qs = []
    for lab, (n, c) in planes.items():
        n = np.asarray(n, float) / np.linalg.norm(n)
        p = true.forward(true.sample_joints(4 * per_plane, seed=int(rng.integers(2**31))))
        on = p - (p @ n - c)[:, None] * n + std * rng.standard_normal(len(p))[:, None] * n
        q = reach(true, on, seed=seed, max_rounds=5, strict=False)
        q = q[np.all(np.isfinite(q), axis=1)][:per_plane]
        if len(q) < per_plane:
            raise ModelError(f"plane {lab}: only {len(q)} of {per_plane} contacts are within reach of {true.name}; "
                             f"give a plane it reaches (n·x = c in its base frame)")
        qs.append(q)
    q = np.concatenate(qs)
    return PlaneObs(q, np.arange(2, len(q) + 2), f"simulated {true.name} plane contacts",
                    labels=np.repeat(list(planes), per_plane), known={lab: planes[lab] for lab in known}, std=std)


def socket_plan(robot: Robot, placements: int = 4, spacing: float = 0.05, seed: int = 0) -> tuple[dict, tuple]:
    """Plan where to put a two-socket plate for same-point data.

    The plate goes to ``placements`` places within comfortable reach: 40–70 % of the farthest horizontal reach
    over 2000 random poses and the middle 30 % of their heights, spread around the base, both sockets reached by
    inverse kinematics. At each place, sockets 0 and 1 are ``spacing`` apart across the radial direction.

    Parameters
    ----------
    robot : Robot
        The robot that will seat its ball in the sockets.
    placements : int, optional
        How many places the plate is put at (default 4).
    spacing : float, optional
        Distance between the plate's two sockets, m (default 0.05).
    seed : int, optional
        Seed of the random poses and of the inverse kinematics (default 0).

    Returns
    -------
    points : dict
        Label "place<k>/<socket>" -> position (3,) of the socket in the world frame, m.
    distances : tuple of (str, str, float)
        The known distance between the two sockets of each place, (label a, label b, ``spacing`` m).

    Raises
    ------
    ModelError
        When too few poses lie within comfortable reach, or no place near a candidate has both sockets within
        reach.

    See Also
    --------
    simulate_same_point : The ball seated in the planned sockets.

    Examples
    --------
    >>> import kincal
    >>> from kincal.simulate import socket_plan
    >>> points, distances = socket_plan(kincal.load_robot("ur5"), placements=1)
    >>> sorted(points)
    ['place1/0', 'place1/1']
    >>> distances
    (('place1/0', 'place1/1', 0.05),)
    """
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
    """Plan a table and a gauge-block step on it for plane-contact data.

    Two horizontal planes ``step`` apart, the table at the height the tool point reaches most easily (the 30th
    percentile of the heights of 2000 random poses); both are meant to be stated as known.

    Parameters
    ----------
    robot : Robot
        The robot that will touch the planes.
    step : float, optional
        Height of the step above the table, m (default 0.05).
    seed : int, optional
        Seed of the random poses (default 0).

    Returns
    -------
    dict
        "table" and "step" -> (unit normal (3,), offset c in m), the plane n·x = c in the world frame, as
        :func:`simulate_planes` takes them.

    Examples
    --------
    >>> import kincal
    >>> from kincal.simulate import plane_plan
    >>> plan = plane_plan(kincal.load_robot("scara"))
    >>> sorted(plan)
    ['step', 'table']
    >>> plan["table"][0].tolist(), round(plan["step"][1] - plan["table"][1], 6)
    ([0.0, 0.0, 1.0], 0.05)
    """
    z = float(np.percentile(robot.forward(robot.sample_joints(2000, seed=seed))[:, 2], 30))
    up = np.array([0.0, 0.0, 1.0])
    return {"table": (up, z), "step": (up, z + step)}
