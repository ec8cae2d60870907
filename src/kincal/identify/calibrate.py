"""Identification of kinematic parameters from measured positions: ``calibrate`` and ``evaluate``."""
from __future__ import annotations

import time
from typing import Callable, Sequence

import numpy as np

from ..analysis.identifiability import identifiability
from ..errors import IdentifiabilityError, MeasurementError, ModelError
from ..io.measurements import Measurements
from ..models.robot import Robot
from .lm import LMResult, levenberg_marquardt
from .pso import pso
from .registration import register_base
from .result import CalibrationResult, EvaluationStats

LOSSES = ("linear", "huber", "soft_l1")
BASE_MODES = ("fixed", "estimate")
METHODS = ("lm", "pso", "pso+lm")
RESIDUALS = ("cartesian", "joint")
PSO_HALF_WIDTH = {"length": 8e-3, "angle": 8e-3}  # the paper's position limits ±8 (mm), per kind
PSO_V_MAX = {"length": 0.5e-3, "angle": 0.5e-3}  # and velocity limits ±0.5 (mm per iteration)
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
    residual: str = "cartesian",
    pso_options: dict | None = None,
) -> CalibrationResult:
    """Identify ``robot``'s parameters from measured tool positions.

    params   -- "auto" (the identifiable set at these poses) or a list of names
    base     -- "estimate": register the measurement frame (Kabsch on the nominal predictions), then
                fit the base frame jointly with the kinematics; "fixed": the base frame is known
    loss     -- "linear" (least squares), or "huber" / "soft_l1" on each pose's 3-D residual norm
                (iteratively reweighted; ``f_scale`` in m, default 3 robust sigmas of the residuals,
                re-estimated at every reweighting)
    method   -- "lm": Levenberg–Marquardt with the analytic Jacobian and column scaling; "pso":
                particle swarm with the seed-2 settings (``pso_options`` overrides particles,
                iterations, w, c1, c2, seed); "pso+lm": PSO, then LM on the identifiable set. PSO
                accepts an explicit ``params`` list that is not identifiable (as the seed's r and R);
                those parameters get an infinite standard deviation
    residual -- "cartesian": measured − predicted positions; "joint" (seed 2, eq. 4/11): commanded
                joint values − the inverse kinematics of the measured positions (robots with a
                closed-form inverse only)
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
    if residual not in RESIDUALS:
        raise ValueError(f"residual='{residual}' is not one of {RESIDUALS}")
    if residual == "joint" and not hasattr(robot, "inverse_and_jacobian"):
        raise ValueError(f"residual='joint' needs a robot with closed-form inverse kinematics; robot "
                         f"'{robot.name}' has none: use residual='cartesian'")
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
        if ident.dropped and method == "lm":
            raise IdentifiabilityError(
                f"these parameters cannot all be identified from the {len(meas)} poses; leave out the "
                f"dropped ones or use params='auto':\n{ident}"
            )
        names = names if method != "lm" else ident.identifiable
    names = tuple(names)
    K = len(names)
    if 3 * len(meas) <= K:
        raise MeasurementError(
            f"{meas.source}: {len(meas)} poses give {3 * len(meas)} equations for {K} parameters; "
            f"measure at least {K // 3 + 1} poses (3-5 times as many is advisable)"
        )
    idx = start.params.indices(names)
    v0 = start.params.values.copy()

    def stacked(x: np.ndarray, w: np.ndarray | None, cols: np.ndarray = idx):
        """Stacked residual and Jacobian, ordered axis-major (all x, then all y, then all z) so the
        Jacobian is a transposed view of the model's parameter rows, without a copy per call."""
        if residual == "joint":
            try:
                qh, J = start.inverse_and_jacobian(xyz, _embed(x, cols))
            except ModelError:  # a trial step where some measured position is out of reach: reject it
                return np.full(q.size, np.inf), np.zeros((q.size, cols.size))
            r = (qh - q).T.ravel()
        else:
            p, J = start.forward_and_jacobian(q, _embed(x, cols))
            r = (p - xyz).T.ravel()
        Jt = J.transpose(2, 1, 0)[cols].reshape(cols.size, -1)  # (K, 3N)
        if w is not None:
            sw = np.tile(np.sqrt(w), 3)
            r, Jt = r * sw, Jt * sw
        return r, Jt.T

    def _embed(x: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """The full parameter vector with ``cols`` set to x (v0 is read when called)."""
        v = v0.copy()
        v[cols] = x
        return v

    def pose_norms(x: np.ndarray) -> np.ndarray:
        return np.linalg.norm(xyz - start.forward(q, _embed(x, idx)), axis=1)

    if residual == "joint":
        reach = start.inverse(xyz, strict=False)
        bad = ~np.all(np.isfinite(reach), axis=1)
        if bad.any():
            raise MeasurementError(
                f"{meas.source}: the positions in row(s) {', '.join(str(r) for r in meas.rows[bad][:10])} are out "
                f"of reach of the starting model, so the joint-space residual is undefined there; use "
                f"residual='cartesian' or leave those rows out")
    w = None
    x0 = v0[idx]
    iterations = evaluations = 0
    if method in ("pso", "pso+lm"):
        say(f"particle swarm over {K} parameters")
        x0, iterations, evaluations = _pso_fit(start, q, xyz, idx, v0, residual, pso_options or {})
    lm_cols = idx
    if method == "pso+lm" and ident.dropped:  # polish only what the data determine
        lm_cols = start.params.indices(ident.identifiable)
        v0 = _embed(x0, idx)
        x0 = v0[lm_cols]
    if method != "pso":
        say(f"fitting {lm_cols.size} parameters to {len(meas)} poses")
        fit = levenberg_marquardt(lambda x: stacked(x, None, lm_cols), x0, max_iter=max_iter)
        iterations, evaluations = iterations + fit.iterations, evaluations + fit.evaluations
    else:
        fit = _evaluated(stacked(x0, None), x0)
    if loss != "linear":
        if method != "lm":
            raise ValueError("robust losses are available with method='lm'")
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
            fit = levenberg_marquardt(lambda x: stacked(x, w), fit.x, max_iter=max_iter)
            iterations, evaluations = iterations + fit.iterations, evaluations + fit.evaluations

    cols = lm_cols if method != "pso" else idx
    v = v0.copy()
    v[cols] = fit.x
    calibrated = start.with_params(v)
    res = xyz - calibrated.forward(q)
    J = fit.jacobian  # weighted, at the solution, columns ``cols``
    dof = max(fit.residual.size - cols.size, 1)
    sigma2 = float(fit.residual @ fit.residual) / dof
    cov = _covariance(J) * sigma2
    sd_cols = {start.params.names[c]: float(np.sqrt(max(cov[k, k], 0.0))) for k, c in enumerate(cols)}
    undetermined = set(ident.dropped) if method == "pso" else set()
    sd = np.array([np.inf if n in undetermined else sd_cols.get(n, np.inf) for n in names])
    pos = {start.params.names[c]: k for k, c in enumerate(cols)}
    at = np.array([pos.get(n, -1) for n in names])
    ok = at >= 0
    full_cov = np.zeros((K, K))
    full_cov[np.ix_(ok, ok)] = cov[np.ix_(at[ok], at[ok])]
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = full_cov / np.outer(sd, sd)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    nominal = robot.params
    return CalibrationResult(
        robot=calibrated,
        nominal=robot,
        names=names,
        estimates={n: float(v[i]) for n, i in zip(names, idx)},
        corrections={n: float(v[i] - nominal.values[i]) for n, i in zip(names, idx)},
        std={n: float(x) for n, x in zip(names, sd)},
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


def _evaluated(rj: tuple[np.ndarray, np.ndarray], x: np.ndarray) -> LMResult:
    r, J = rj
    return LMResult(x, 0.5 * float(r @ r), r, J, 0, 0, True, "particle swarm finished its iterations")


def _pso_fit(robot: Robot, q: np.ndarray, xyz: np.ndarray, idx: np.ndarray, v0: np.ndarray, residual: str,
             options: dict) -> tuple[np.ndarray, int, int]:
    """Particle swarm on the mean squared residual; returns the best x, iterations, model evaluations."""
    kinds = [robot.params.kinds[i] for i in idx]

    def objective(x: np.ndarray) -> float:
        v = v0.copy()
        v[idx] = x
        try:
            r = robot.inverse(xyz, v, strict=False) - q if residual == "joint" else robot.forward(q, v) - xyz
        except ModelError:  # a candidate that cannot assemble some pose
            return np.inf
        val = float(np.mean(r * r))
        return val if np.isfinite(val) else np.inf

    opts = {"particles": 500, "iterations": 200, "w": 0.8, "c1": 0.5, "c2": 1.2, "seed": 0, **options}
    out = pso(objective, v0[idx], np.array([PSO_HALF_WIDTH[k] for k in kinds]),
              np.array([PSO_V_MAX[k] for k in kinds]), **opts)
    return out.x, out.iterations, out.evaluations
