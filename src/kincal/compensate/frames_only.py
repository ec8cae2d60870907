"""A calibration as a controller can hold it without new kinematics: a corrected base and a corrected tool.

A controller moves with its own (nominal) kinematics; most accept no link lengths or joint zeros from outside,
but every one holds a base (work object, user frame) and a tool. :func:`fit_frames_only` finds the base B
(the nominal robot's base in the calibration's base frame, the measurement frame) and the tool U (the TCP in
the nominal flange) that bring the nominal model nearest the calibrated one over the joint ranges: the TCP
positions and the flange's rotation (weighted by ``ROT_LEVER`` m per rad), by least squares over sampled
joints (within the joint ranges the calibration's data cover, where its model is trusted, when given).
What the frames cannot carry (link lengths, joint zeros, twists) is left: its RMS and largest size over
the samples say how much of the calibration the controller then gets; the full model needs
the commands compensated (``kincal compensate``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._frozen import freeze_arrays
from ..errors import ModelError
from ..models.implicit import ImplicitRobot
from ..models.robot import Robot
from ..models.wrapped import Wrapped
from ..models.transforms import rotation_log, rotvec_matrix

ROT_LEVER = 0.1  # m per rad: the flange's rotation error counts as a point this far out
SAMPLES = 500  # joint vectors within the limits the frames are fitted on and the residual measured over


@dataclass(frozen=True)
class FramesOnly:
    """A calibration as a controller can hold it without new kinematics: a corrected base and tool.

    Parameters
    ----------
    base : ndarray, shape (4, 4)
        The nominal robot's base in the calibration's base (measurement) frame, m.
    tool : ndarray, shape (4, 4)
        The TCP frame in the nominal flange, m (its rotation: the calibrated flange's).
    before_rms : float
        RMS TCP position error of the nominal model with the calibration's base frame and tool point, m.
    before_max : float
        The largest such error, m.
    after_rms : float
        RMS TCP position error left with the fitted frames, m.
    after_max : float
        The largest error left, m.
    rotation_after : float
        The largest flange rotation error left, rad.
    samples : int
        The joint vectors the frames were fitted on and the errors measured over.

    See Also
    --------
    fit_frames_only : Makes it.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.compensate import FramesOnly
    >>> frames = FramesOnly(np.eye(4), np.eye(4), 1.4e-3, 2.3e-3, 1.0e-3, 1.7e-3, 2.3e-3, 100)
    >>> sorted(frames.to_dict())
    ['after_max_m', 'after_rms_m', 'base', 'before_max_m', 'before_rms_m', 'rotation_after_rad', 'samples', 'tool']
    """

    base: np.ndarray
    tool: np.ndarray
    before_rms: float
    before_max: float
    after_rms: float
    after_max: float
    rotation_after: float
    samples: int

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def to_dict(self) -> dict:
        """The frames and errors as plain JSON values (m, rad)."""
        return {"base": self.base.tolist(), "tool": self.tool.tolist(), "before_rms_m": self.before_rms,
                "before_max_m": self.before_max, "after_rms_m": self.after_rms, "after_max_m": self.after_max,
                "rotation_after_rad": self.rotation_after, "samples": self.samples}


def _frame(x: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotvec_matrix(x[3:6]), x[:3]
    return T


def _errors(x: np.ndarray, nominal: Robot, q: np.ndarray, target) -> np.ndarray:
    """TCP position errors (N, 3) m and ROT_LEVER × flange rotation errors (N, 3) of B·N(q)·U against the target."""
    B, U = _frame(x[:6]), _frame(x[6:])
    p_n, R_n = target[2], target[3]
    R = B[:3, :3] @ R_n @ U[:3, :3]
    p = (B[:3, :3] @ (p_n + R_n @ U[:3, 3])[..., None])[..., 0] + B[:3, 3]
    return np.concatenate([p - target[0], ROT_LEVER * rotation_log(R @ np.swapaxes(target[1], 1, 2))], axis=1)


def fit_frames_only(calibrated: Robot, nominal: Robot, samples: int = SAMPLES, seed: int = 0,
                    region: tuple[np.ndarray, np.ndarray] | None = None) -> FramesOnly:
    """Fit the base and tool that bring a serial arm's nominal model nearest its calibrated one.

    The base B and tool U minimise, by least squares over sampled joints, the TCP position errors and the
    flange rotation errors (weighted by ``ROT_LEVER``, 0.1 m per rad) of B·N(q)·U against the calibrated model
    (module docstring).

    Parameters
    ----------
    calibrated : Robot
        The calibrated model, with a tool point: the TCP.
    nominal : Robot
        The controller's (nominal) model, with a tool point.
    samples : int, optional
        Joint vectors drawn uniformly (default ``SAMPLES``, 500).
    seed : int, optional
        Random seed of the draw (default 0).
    region : tuple of ndarray, optional
        (lower, upper), each (n,) rad (m for a prismatic joint): the joint ranges the calibration's data
        cover, where its model is trusted (default: the calibrated robot's limits).

    Returns
    -------
    FramesOnly
        The base and tool (4, 4), m, and the errors before and after, m and rad.

    Raises
    ------
    ModelError
        When the robot is a parallel robot (its controller takes its own leg geometry).

    Examples
    --------
    A robot that differs from its nominal only by its base and tool point is matched exactly:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import fit_frames_only
    >>> nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])
    >>> moved = nominal.with_params({"base.x": 1.2, "base.y": -0.4, "base.rz": 0.7})
    >>> fit = fit_frames_only(moved.with_tool_point([0.011, -0.004, 0.182]), nominal, samples=50, seed=3)
    >>> np.round(fit.base[:2, 3], 6), round(float(np.arctan2(fit.base[1, 0], fit.base[0, 0])), 6)
    (array([ 1.2, -0.4]), 0.7)
    >>> np.round(fit.tool[:3, 3] * 1e3, 3)  # mm
    array([ 11.,  -4., 182.])
    >>> bool(fit.after_max < 1e-9)
    True

    With link and joint-zero errors as well, the frames carry only part of the calibration:

    >>> real = kincal.perturb(nominal, seed=1)
    >>> fit = fit_frames_only(real, nominal, samples=100)
    >>> round(fit.before_rms * 1e3, 3), round(fit.after_rms * 1e3, 3)  # mm
    (1.395, 0.996)
    """
    from scipy.optimize import least_squares

    inner = calibrated
    while isinstance(inner, Wrapped):  # a robot with error-model terms: the one they are on
        inner = inner.inner
    if isinstance(inner, ImplicitRobot):
        raise ModelError(f"robot '{calibrated.name}' ({calibrated.structure}): frames data are a serial arm's base "
                         f"and tool; a parallel robot's controller takes its own leg geometry (compensate its "
                         f"commands instead)")
    q = calibrated.sample_joints(samples, seed=seed) if region is None else \
        np.random.default_rng(seed).uniform(region[0], region[1], (samples, len(region[0])))
    p_c, R_c, _, _ = calibrated.pose_and_jacobian(q)  # the TCP, and the flange's rotation
    p_n, R_n, _, _ = nominal.with_tool_point(np.zeros(3)).pose_and_jacobian(q)  # the nominal flange
    target = (p_c, R_c, p_n, R_n)
    x0 = np.concatenate([np.zeros(6), calibrated.tool_point(), np.zeros(3)])
    fit = least_squares(lambda x: _errors(x, nominal, q, target).ravel(), x0, method="lm", xtol=1e-15, ftol=1e-15)
    after = _errors(fit.x, nominal, q, target)
    registered = nominal.with_params({n: calibrated.params[n] for n in calibrated.base_params()})
    p_before, _, _, _ = registered.with_tool_point(calibrated.tool_point()).pose_and_jacobian(q)
    before = np.linalg.norm(p_before - p_c, axis=1)
    left = np.linalg.norm(after[:, :3], axis=1)
    return FramesOnly(_frame(fit.x[:6]), _frame(fit.x[6:]), float(np.sqrt(np.mean(before**2))), float(before.max()),
                      float(np.sqrt(np.mean(left**2))), float(left.max()),
                      float(np.linalg.norm(after[:, 3:], axis=1).max() / ROT_LEVER), samples)
