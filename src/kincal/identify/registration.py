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
MOUNTING_POSES = 200  # poses the frame and the point are fitted to at most (9 unknowns: plenty)


def register_mounting(robot: Robot, q: np.ndarray, xyz: np.ndarray, frame: bool = True) -> Robot:
    """Register the measurement frame and the target's mounting to measured positions, kinematics as they are.

    The set-up a model is judged "before" calibration with, so the figure does not depend on where the
    target was declared. The flange frames are computed once; Gauss–Newton on the frame's rotation and
    translation and the point (9 unknowns), from the frame registered with the declared point. Without
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
    if len(q) > MOUNTING_POSES:
        pick = np.unique(np.linspace(0, len(q) - 1, MOUNTING_POSES).round().astype(int))
        q, xyz = q[pick], xyz[pick]
    frame = frame and bool(robot.base_params())
    if not robot.has_tool_point or len(q) < 3:
        return register_base(robot, q, xyz) if frame else robot
    p, Jp = robot.forward_and_jacobian(q)  # the flange frames, once: d p / d tool point = the flange rotation
    Rf = Jp[:, :, robot.params.indices(TOOL_NAMES)]
    origin = p - Rf @ robot.tool_point()
    R, t = kabsch(p, xyz) if frame else (np.eye(3), np.zeros(3))  # the frame registered with the declared point
    point = robot.tool_point()
    for _ in range(MOUNTING_STEPS):
        a = Rf @ point + origin  # (N, 3) the point before the correction (R, t)
        e = a @ R.T + t - xyz
        J = np.zeros((len(q), 3, 9))
        if frame:
            J[:, :, :3] = -skew(a @ R.T)
            J[:, :, 3:6] = np.eye(3)
        J[:, :, 6:] = R @ Rf
        J2 = J.reshape(-1, 9)
        H, g = J2.T @ J2, J2.T @ e.ravel()  # the 9 x 9 normal equations (frame columns 0: the point alone)
        step = np.linalg.lstsq(H, -g, rcond=None)[0]  # (a point the poses cannot tell from the frame: least norm)
        R, t, point = rotvec_matrix(step[:3]) @ R, t + step[3:6], point + step[6:]
        if np.linalg.norm(step) < MOUNTING_TOL:
            break
    if not frame:
        return robot.with_tool_point(point)
    Rb, tb = robot.base_transform()
    return robot.with_base_transform(R @ Rb, R @ tb + t).with_tool_point(point)
