"""Rigid registration of the measurement frame (Kabsch / Umeyama without scale)."""
from __future__ import annotations

import numpy as np

from ..models.robot import TOOL_NAMES, Robot
from ..models.transforms import kabsch, rotvec_matrix, skew


def register_base(robot: Robot, q: np.ndarray, xyz: np.ndarray, miss: np.ndarray | None = None) -> Robot:
    """``robot`` with its base frame moved so its predictions at q best match xyz (N,3) rigidly (Kabsch, exact
    for any turn); ``miss`` (N,3), m: what it is known to miss there, in its base frame (turned with it),
    added to its predictions first."""
    Rb, tb = robot.base_transform()
    P = robot.forward(q) if miss is None else robot.forward(q) + miss @ Rb.T
    R, t = kabsch(P, xyz)
    return robot.with_base_transform(R @ Rb, R @ tb + t)


MOUNTING_STEPS = 20  # Gauss–Newton steps at most for the frame and the target point
MOUNTING_TOL = 1e-12  # m: a step this small ends them
MOUNTING_POSES = 200  # poses per point the frame and the points are fitted to at most (9 unknowns per point: plenty)


def register_mounting(robot: Robot, q: np.ndarray, xyz: np.ndarray, frame: bool = True) -> Robot:
    """Register the measurement frame and the target's mounting to measured positions, kinematics as they are.

    The set-up a model is judged "before" calibration with, so the figure does not depend on where the
    target was declared. The flange frames are computed once; Gauss–Newton on the frame's rotation and
    translation and the point (9 unknowns), from the frame registered with the declared point
    (:func:`register_points` with one point). Without
    a tool point, or with fewer than 3 poses: the frame alone (rigid registration, Kabsch); with
    ``frame`` False (the base is known) or a robot without a base frame: the point alone. On a long file
    both are fitted to ``MOUNTING_POSES`` (200) poses spread evenly over it (a reference figure: the
    difference is far below the noise; 10⁵ poses in a few ms instead of 0.45 s).

    Parameters
    ----------
    robot : Robot
        The model whose frame and tool point to move.
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    xyz : ndarray, shape (N, 3)
        Measured tool positions at ``q``, m.
    frame : bool, optional
        Whether to fit the base (measurement) frame too (default True); False: the base is known.

    Returns
    -------
    Robot
        ``robot`` with its base frame and tool point moved so its predictions at ``q`` best match
        ``xyz`` in the least-squares sense.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.identify import register_mounting
    >>> robot = kincal.load_robot("ur5")
    >>> seen = robot.with_params({"base.x": 0.4, "base.rz": 0.2}).with_tool_point([0.0, 0.02, 0.1])
    >>> q = robot.sample_joints(20, seed=1)
    >>> mounted = register_mounting(robot, q, seen.forward(q))
    >>> np.round(mounted.tool_point(), 6) + 0.0  # m in the flange frame
    array([0.  , 0.02, 0.1 ])
    >>> round(mounted.params["base.x"], 6), round(mounted.params["base.rz"], 6)
    (0.4, 0.2)
    """
    frame = frame and bool(robot.base_params())
    if not robot.has_tool_point or len(q) < 3:
        return register_base(robot, q, xyz) if frame else robot
    moved, point = register_points(robot, q, xyz, np.zeros(len(q), int), robot.tool_point()[None], frame)
    return moved.with_tool_point(point[0])


def register_points(robot: Robot, q: np.ndarray, xyz: np.ndarray, which: np.ndarray, points: np.ndarray,
                    frame: bool = True) -> tuple[Robot, np.ndarray]:
    """Register the measurement frame and several points on the flange to measured positions, kinematics as they are.

    :func:`register_mounting` with one point per group of rows (markers on the flange, each seen in its own rows,
    beside the robot's tool point): the flange frames are computed once; Gauss–Newton on the frame's rotation and
    translation and the K points (6 + 3K unknowns), from the frame registered rigidly with the points' starts. Each
    point's rows are thinned to ``MOUNTING_POSES`` (200) spread evenly over them.

    Parameters
    ----------
    robot : Robot
        The model whose frame to move; it has a tool point (``tool.x/y/z``), whose value is not used.
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    xyz : ndarray, shape (N, 3)
        The measured position of row k's point at ``q[k]``, m.
    which : ndarray of int, shape (N,)
        The point each row measured, 0..K-1.
    points : ndarray, shape (K, 3)
        The points' start values in the flange frame, m.
    frame : bool, optional
        Whether to fit the base (measurement) frame too (default True); False: the base is known, the points alone.

    Returns
    -------
    robot : Robot
        ``robot`` with its base frame moved (as it is with ``frame`` False or without a base frame).
    points : ndarray, shape (K, 3)
        The registered points in the flange frame, m.

    Examples
    --------
    Two markers seen by a tracker standing elsewhere:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.identify.registration import register_points
    >>> robot = kincal.load_robot("ur5")
    >>> seen = robot.with_params({"base.y": -0.3, "base.rx": 0.1})
    >>> q = robot.sample_joints(10, seed=2)
    >>> xyz = np.concatenate([seen.with_tool_point(m).forward(q) for m in ([0.04, 0, 0.03], [0, 0.04, 0.03])])
    >>> moved, points = register_points(robot, np.vstack([q, q]), xyz, np.repeat([0, 1], 10), np.zeros((2, 3)))
    >>> np.round(points, 6) + 0.0  # m in the flange frame
    array([[0.04, 0.  , 0.03],
           [0.  , 0.04, 0.03]])
    >>> round(moved.params["base.y"], 6), round(moved.params["base.rx"], 6)
    (-0.3, 0.1)
    """
    frame = frame and bool(robot.base_params())
    pick = np.concatenate([rows[np.unique(np.linspace(0, len(rows) - 1, min(len(rows), MOUNTING_POSES)).round()
                                          .astype(int))] for rows in (np.flatnonzero(which == k)
                                                                      for k in range(len(points))) if len(rows)])
    q, xyz, which = q[pick], xyz[pick], which[pick]
    p, Jp = robot.forward_and_jacobian(q)  # the flange frames, once: d p / d tool point = the flange rotation
    Rf = Jp[:, :, robot.params.indices(TOOL_NAMES)]
    origin = p - Rf @ robot.tool_point()
    points = np.array(points, float)
    n, cols = len(q), 6 + 3 * which[:, None, None] + np.arange(3)  # each row's point columns

    def at(points: np.ndarray) -> np.ndarray:  # (N, 3) each row's point before the correction (R, t)
        return np.einsum("nij,nj->ni", Rf, points[which]) + origin
    R, t = kabsch(at(points), xyz) if frame else (np.eye(3), np.zeros(3))  # registered with the points' starts
    for _ in range(MOUNTING_STEPS):
        a = at(points)
        e = a @ R.T + t - xyz
        J = np.zeros((n, 3, 6 + 3 * len(points)))
        if frame:
            J[:, :, :3] = -skew(a @ R.T)
            J[:, :, 3:6] = np.eye(3)
        J[np.arange(n)[:, None, None], np.arange(3)[None, :, None], cols] = R @ Rf
        J2 = J.reshape(-1, J.shape[2])
        H, g = J2.T @ J2, J2.T @ e.ravel()  # the normal equations (frame columns 0: the points alone)
        step = np.linalg.lstsq(H, -g, rcond=None)[0]  # (a point the poses cannot tell from the frame: least norm)
        R, t, points = rotvec_matrix(step[:3]) @ R, t + step[3:6], points + step[6:].reshape(-1, 3)
        if np.linalg.norm(step) < MOUNTING_TOL:
            break
    if not frame:
        return robot, points
    Rb, tb = robot.base_transform()
    return robot.with_base_transform(R @ Rb, R @ tb + t), points
