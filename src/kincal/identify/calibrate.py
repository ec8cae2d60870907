"""Identification of kinematic parameters from measured positions: ``calibrate`` and ``evaluate``."""
from __future__ import annotations

import time
from typing import Callable, Sequence

import numpy as np

from ..analysis.identifiability import identifiability
from ..errors import IdentifiabilityError, MeasurementError
from ..io.measurements import Measurements
from ..models.robot import Robot
from .lm import levenberg_marquardt
from .registration import register_base
from .result import CalibrationResult, EvaluationStats

LOSSES = ("linear", "huber", "soft_l1")
BASE_MODES = ("fixed", "estimate")
METHODS = ("lm",)
MAX_IRLS = 20
PRACTICAL_TOL = 3e-5  # directions weaker than this (relative, scaled) are not fitted by default


def _robust_weights(norms: np.ndarray, loss: str, f_scale: float) -> np.ndarray:
    """IRLS weights ρ'(z), z = (‖rᵢ‖/f_scale)², per pose (scipy's conventions for huber and soft_l1)."""
    z = (norms / f_scale) ** 2
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z)
    return np.ones_like(z)


def calibrate(
    robot: Robot,
    meas: Measurements,
    params: str | Sequence[str] = "auto",
    base: str = "estimate",
    loss: str = "linear",
    method: str = "lm",
    f_scale: float | None = None,
    keep: Sequence[str] = (),
    tol: float = PRACTICAL_TOL,
    max_iter: int = 100,
    progress: Callable[[str], None] | None = None,
) -> CalibrationResult:
    """Identify ``robot``'s parameters from measured tool positions.

    params   -- "auto" (the identifiable set at these poses) or a list of names
    base     -- "estimate": register the measurement frame (Kabsch on the nominal predictions), then
                fit the base frame jointly with the kinematics; "fixed": the base frame is known
    loss     -- "linear" (least squares), or "huber" / "soft_l1" on each pose's 3-D residual norm
                (iteratively reweighted; ``f_scale`` in m, default 3 robust sigmas of the residuals,
                re-estimated at every reweighting)
    method   -- "lm": Levenberg–Marquardt with the analytic Jacobian and column scaling
    max_iter -- LM iteration limit; a fit that stops there is returned with ``converged=False``
    progress -- called with a short message at each stage (the CLI shows it)

    Returns a :class:`CalibrationResult`. Raises MeasurementError for data that cannot belong to the
    robot or is too little, IdentifiabilityError when an explicit ``params`` list is not identifiable.
    keep     -- names to prefer when choosing among confounded parameters
    tol      -- relative singular-value tolerance of the identifiability check (column-scaled); the
                default also leaves out parameters the poses determine only very weakly, which would
                otherwise wander along a flat valley of the cost to absurd values
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    if base not in BASE_MODES:
        raise ValueError(f"base='{base}' is not one of {BASE_MODES}")
    if loss not in LOSSES:
        raise ValueError(f"loss='{loss}' is not one of {LOSSES}")
    if method not in METHODS:
        raise ValueError(f"method='{method}' is not one of {METHODS}")
    meas.check_robot(robot)
    q, xyz = meas.q, meas.xyz
    base_names = robot.base_params()
    start = robot
    if base == "estimate":
        if len(meas) < 3:
            raise MeasurementError(f"{meas.source}: registering the base frame needs at least 3 poses, got {len(meas)}")
        say("registering the measurement frame")
        start = register_base(robot, q, xyz)

    say("checking identifiability")
    if isinstance(params, str):
        if params != "auto":
            raise ValueError(f"params='{params}': use 'auto' or a list of parameter names")
        ident = identifiability(start, q, exclude=base_names if base == "fixed" else (),
                                keep=list(keep) + (list(base_names) if base == "estimate" else []), tol=tol)
        names = ident.identifiable
    else:
        names = list(params)
        clash = [n for n in names if n in set(base_names)] if base == "fixed" else []
        if clash:
            raise ValueError(f"{', '.join(clash)} listed with base='fixed'; use base='estimate' to fit the base")
        if base == "estimate":
            names = list(base_names) + [n for n in names if n not in set(base_names)]
        ident = identifiability(start, q, params=names, keep=keep, tol=tol)
        if ident.dropped:
            raise IdentifiabilityError(
                f"these parameters cannot all be identified from the {len(meas)} poses; leave out the "
                f"dropped ones or use params='auto':\n{ident}"
            )
        names = ident.identifiable
    names = tuple(names)
    K = len(names)
    if 3 * len(meas) <= K:
        raise MeasurementError(
            f"{meas.source}: {len(meas)} poses give {3 * len(meas)} equations for {K} parameters; "
            f"measure at least {K // 3 + 1} poses (3-5 times as many is advisable)"
        )
    idx = start.params.indices(names)
    v0 = start.params.values.copy()

    def values(x: np.ndarray) -> np.ndarray:
        v = v0.copy()
        v[idx] = x
        return v

    def residual(x: np.ndarray, w: np.ndarray | None):
        """Stacked residual and Jacobian, ordered axis-major (all x, then all y, then all z) so the
        Jacobian is a transposed view of the model's parameter rows, without a copy per call."""
        p, J = start.forward_and_jacobian(q, values(x))
        r = (p - xyz).T.ravel()
        Jt = J.transpose(2, 1, 0)[idx].reshape(K, -1)  # (K, 3N)
        if w is not None:
            sw = np.tile(np.sqrt(w), 3)
            r, Jt = r * sw, Jt * sw
        return r, Jt.T

    def pose_norms(x: np.ndarray) -> np.ndarray:
        return np.linalg.norm(xyz - start.forward(q, values(x)), axis=1)

    say(f"fitting {K} parameters to {len(meas)} poses")
    w = None
    fit = levenberg_marquardt(lambda x: residual(x, None), v0[idx], max_iter=max_iter)
    iterations, evaluations = fit.iterations, fit.evaluations
    if loss != "linear":
        auto_scale = f_scale is None
        w = np.ones(len(meas))
        for _ in range(MAX_IRLS):
            norms = pose_norms(fit.x)
            if auto_scale:  # 3 robust sigmas; the median of a 3-D Gaussian norm is 1.538 sigma
                f_scale = max(3.0 * float(np.median(norms)) / 1.538, 1e-9)
            w_new = _robust_weights(norms, loss, f_scale)
            if np.max(np.abs(w_new - w)) < 1e-4:
                break
            w = w_new
            fit = levenberg_marquardt(lambda x: residual(x, w), fit.x, max_iter=max_iter)
            iterations, evaluations = iterations + fit.iterations, evaluations + fit.evaluations

    v = v0.copy()
    v[idx] = fit.x
    calibrated = start.with_params(v)
    res = xyz - calibrated.forward(q)
    J = fit.jacobian  # weighted, at the solution
    dof = 3 * len(meas) - K
    sigma2 = float(fit.residual @ fit.residual) / dof
    cov = _covariance(J) * sigma2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    nominal = robot.params
    return CalibrationResult(
        robot=calibrated,
        nominal=robot,
        names=names,
        estimates={n: float(v[i]) for n, i in zip(names, idx)},
        corrections={n: float(v[i] - nominal.values[i]) for n, i in zip(names, idx)},
        std={n: float(s) for n, s in zip(names, sd)},
        correlation=corr,
        residuals=res,
        sigma=float(np.sqrt(sigma2 / (1.0 if w is None else np.mean(w)))),
        stats_before=EvaluationStats.from_errors(xyz - robot.forward(q)),
        stats_after=EvaluationStats.from_errors(res),
        iterations=iterations,
        evaluations=evaluations,
        converged=fit.converged,
        message=fit.message,
        time_s=time.perf_counter() - t0,
        loss=loss,
        base=base,
        identifiability=ident,
    )


def _covariance(J: np.ndarray) -> np.ndarray:
    """(JᵀJ)⁻¹ computed on unit-norm columns (stable), returned in the original units."""
    d = np.linalg.norm(J, axis=0)
    d[d == 0] = 1.0
    A = J / d
    return np.linalg.pinv(A.T @ A, hermitian=True) / np.outer(d, d)


def evaluate(robot: Robot, meas: Measurements, rebase: bool = False) -> EvaluationStats:
    """Position error statistics of ``robot`` on ``meas`` (m).

    rebase -- first re-fit only the 6 base-frame parameters (the tracker moved between sessions).
    """
    meas.check_robot(robot)
    if rebase:
        robot = calibrate(robot, meas, params=(), base="estimate").robot
    return EvaluationStats.from_errors(meas.xyz - robot.forward(meas.q))
