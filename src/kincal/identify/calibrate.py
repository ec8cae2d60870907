"""Identification of kinematic parameters from measured positions: ``calibrate`` and ``evaluate``.

``calibrate`` checks every option first, builds a :class:`~kincal.identify.problem.CalibrationProblem`
(robot, measurements, free parameters, residual), runs a solver on it (LM, PSO, or PSO then LM),
optionally reweights robustly, and turns the fit into a :class:`CalibrationResult`.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable, Sequence

import numpy as np

from .._threads import blas_threads
from ..analysis.identifiability import BASE_MODES
from ..analysis.uncertainty import ModelUncertainty, envelope_warning, extrapolation_warning
from ..io.measurements import Measurements
from ..models.robot import Robot
from ..models.terms import TAU_REF, drop_terms, extend, parse_model
from .covariance import parameter_statistics
from .drift import with_drift, without_drift
from .lm import LMResult, fit_lm
from .problem import CalibrationProblem, build_problem
from .pso import OPTIONS as PSO_OPTIONS
from .pso import fit_pso
from .residuals import RESIDUALS, supports
from .result import CalibrationResult, EvaluationStats
from .robust import LOSSES, irls
from .select import select_model
from .verdict import (Reason, Thresholds, Verdict, correction_reasons, drift_reasons, duplicate_reasons,
                      outlier_reasons, residual_reasons, robust_z)

METHODS = ("lm", "pso", "pso+lm")
PRACTICAL_TOL = 3e-5  # directions weaker than this (relative, scaled) are not fitted by default


def check_options(robot: Robot, params, base: str, loss: str, method: str, residual: str, f_scale: float | None,
                  tol: float, max_iter: int, pso_options: dict | None, thresholds: Thresholds | None = None,
                  keep: Sequence[str] = (), model: str | None = None, payload: float = 0.0,
                  drift: bool = False) -> dict:
    """Every option of :func:`calibrate`, checked before any work (ValueError names the option), and
    returned as the record that reproduces the fit."""
    for name, value, allowed in (("base", base, BASE_MODES), ("loss", loss, LOSSES), ("method", method, METHODS),
                                 ("residual", residual, tuple(RESIDUALS))):
        if value not in allowed:
            raise ValueError(f"{name}='{value}' is not one of {allowed}")
    if loss != "linear" and method != "lm":
        raise ValueError(f"loss='{loss}' needs method='lm' (got method='{method}'): robust reweighting refits with "
                         f"Levenberg-Marquardt; use loss='linear' with '{method}', or method='lm'")
    if not supports(robot, residual):
        raise ValueError(f"residual='{residual}' needs a robot with closed-form inverse kinematics; robot "
                         f"'{robot.name}' has none: use residual='cartesian'")
    if isinstance(params, str):
        if params != "auto":
            raise ValueError(f"params='{params}': use 'auto' or a list of parameter names")
    else:
        robot.params.indices(list(params))  # unknown names raise, naming them
    robot.params.indices(list(keep))
    if model is not None and model != "auto":
        parse_model(model)
    if drift not in (True, False) or (drift and residual != "cartesian"):
        raise ValueError(f"drift={drift!r}: True or False; the drift term needs residual='cartesian'")
    if isinstance(payload, bool) or not isinstance(payload, (int, float)) or not (np.isfinite(payload) and payload >= 0):
        raise ValueError(f"payload={payload}: give the payload at the tool in kg (0 or more)")
    if f_scale is not None and not (np.isfinite(f_scale) and f_scale > 0):
        raise ValueError(f"f_scale={f_scale}: give a positive residual scale in m, or None for automatic")
    if not 0 < tol < 1:
        raise ValueError(f"tol={tol}: the relative singular-value tolerance must lie in (0, 1)")
    if int(max_iter) != max_iter or max_iter < 1:
        raise ValueError(f"max_iter={max_iter}: give a positive whole number of iterations")
    if thresholds is not None and not isinstance(thresholds, Thresholds):
        raise ValueError("thresholds: give a kincal.Thresholds value")
    unknown = sorted(set(pso_options or {}) - set(PSO_OPTIONS))
    if unknown or (pso_options and method == "lm"):
        raise ValueError(f"pso_options {unknown or sorted(pso_options)}: " + (
            f"known are {', '.join(PSO_OPTIONS)}" if unknown else "apply to method='pso' or 'pso+lm' only"))
    return {"params": params if isinstance(params, str) else list(params), "base": base, "loss": loss,
            "method": method, "f_scale": f_scale, "keep": list(keep), "tol": tol, "max_iter": max_iter,
            "residual": residual, "model": model, "payload": float(payload), "drift": bool(drift),
            "pso_options": dict(pso_options or {}), "thresholds": (thresholds or Thresholds()).to_dict()}


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
    thresholds: Thresholds | None = None,
    model: str | None = None,
    use_q: np.ndarray | None = None,
    payload: float = 0.0,
    drift: bool = False,
) -> CalibrationResult:
    """Identify ``robot``'s parameters from measured tool positions.

    params   -- "auto" (the identifiable set at these poses) or a list of names; ``keep``: names to
                prefer among confounded ones; ``tol``: relative singular-value tolerance (the default
                also leaves out directions so weak they would drift to absurd values)
    base     -- "estimate": register the tracker frame (Kabsch), then fit the base frame with the rest;
                "fixed": the base frame is known
    loss     -- "linear", or "huber" / "soft_l1" on each pose's 3-D residual (reweighted from the start;
                ``f_scale`` m, default 3 robust sigmas); method "lm" only
    method   -- "lm" (Levenberg–Marquardt), "pso" (seed-2 particle swarm; ``pso_options``), "pso+lm".
                PSO accepts an explicit, unidentifiable ``params`` list (σ = inf for those)
    residual -- "cartesian" (positions) or "joint" (seed 2: commanded − inverse of the measured positions)
    model    -- None (the robot as given), a name for :func:`kincal.extend` ("compliance+harmonics:2"), or
                "auto" (blocked cross-validation: ``model_selection``); ``payload`` kg for gravity terms.
                A negative compliance is dropped and the fit repeated (``model_notes``)
    drift    -- also fit a base drift over acquisition (row) order (``result.drift``; kincal.identify.drift)
    max_iter -- LM iteration limit; ``progress``: called with a message at each stage
    thresholds -- the verdict's limits; the result's ``verdict`` is good, suspect or refused with reasons

    Options are checked before any work (ValueError); MeasurementError for data that cannot belong to
    the robot or is too little, IdentifiabilityError for an explicit ``params`` list LM cannot
    identify. BLAS runs single-threaded inside: small problems, and threads fight for the cores.
    """

    t0 = time.perf_counter()
    options = check_options(robot, params, base, loss, method, residual, f_scale, tol, max_iter, pso_options,
                            thresholds, keep, model, payload, drift)
    say = progress or (lambda msg: None)
    with blas_threads(1):
        robot, choice = _error_model(robot, meas, model, options, say, use_q)
        res = dataclasses.replace(_fit(robot, meas, options, say, t0), options=options, model_selection=choice)
        return _negative_compliance(res, options, choice, say) or res


def _fit(robot: Robot, meas: Measurements, o: dict, say, t0: float) -> CalibrationResult:
    """Build the problem (with the drift term if asked), solve it, judge the result."""
    fit_robot, fit_meas = with_drift(robot, meas) if o["drift"] else (robot, meas)
    problem = build_problem(fit_robot, fit_meas, o["params"], o["base"], o["keep"], o["tol"], o["residual"],
                            strict=o["method"] == "lm", say=say)
    w = None
    if o["loss"] == "linear":
        fit, final, counts, history = _solve(problem, o["method"], o["max_iter"], o["pso_options"], say)
    else:  # reweight from the start: a least-squares fit pulled by outliers is a poor place to begin
        say("fitting with reweighting (robust loss)")
        final, history = problem, ()
        fit, w, *counts = irls(problem, _at(problem, problem.x0), o["loss"], o["f_scale"],
                               lambda x, wt: fit_lm(problem, x, wt, o["max_iter"]))
    res = _result(fit_robot, problem, final, fit, w, counts, history, o["method"], o["loss"],
                  time.perf_counter() - t0)
    res = judge(res, problem, Thresholds(**o["thresholds"]))
    return without_drift(res, robot, meas) if o["drift"] else res


def _error_model(robot: Robot, meas: Measurements, model: str | None, options: dict, say, use_q=None):
    """The robot with the requested error model, and the model comparison when ``model="auto"``."""
    if model is None:
        return robot, None
    choice = None
    if model == "auto":
        say("choosing the error model (joint-space blocked cross-validation)")
        fold_options = {k: v for k, v in options.items() if k not in ("thresholds", "model")}
        choice = select_model(robot, meas, calibrate, use_q=use_q, thresholds=Thresholds(**options["thresholds"]),
                              **fold_options)
        model = choice.chosen
    return extend(robot, model, meas.q, options["payload"]), choice


def _negative_compliance(res: CalibrationResult, options: dict, choice, say) -> CalibrationResult | None:
    """The fit repeated without the compliances ``res`` finds negative (a joint that bends against its
    load is not a spring: the term describes something else), or None when all are positive."""
    neg = [n for n in res.names if n.endswith(".compliance") and res.estimates[n] < 0.0]
    if not neg:
        return None
    notes = tuple(f"{n.split('.')[0]}: compliance came out negative ({res.estimates[n] / TAU_REF:+.3g} rad/(N·m), "
                  f"σ {res.std[n] / TAU_REF:.2g}) and was dropped; the fit was repeated without it" for n in neg)
    say("dropping negative compliance: " + ", ".join(neg))
    args = {k: v for k, v in options.items() if k not in ("model", "thresholds")}
    again = calibrate(drop_terms(res.nominal, neg), res.measurements, thresholds=Thresholds(**options["thresholds"]),
                      **args)
    return dataclasses.replace(again, options=options, model_selection=choice, model_notes=notes + again.model_notes)


def _solve(problem: CalibrationProblem, method: str, max_iter: int, pso_options: dict, say):
    """Run the solver(s). Returns the fit, the problem it belongs to, (iterations, evaluations) and
    the particle swarm's best value per iteration (empty for LM)."""
    history: tuple[float, ...] = ()
    x0, counts, final = problem.x0, (0, 0), problem
    if method in ("pso", "pso+lm"):
        say(f"particle swarm over {len(problem.names)} parameters")
        swarm = fit_pso(problem, pso_options)
        x0, counts, history = swarm.x, (swarm.iterations, swarm.evaluations), tuple(map(float, swarm.history))
        if method == "pso":
            return _at(problem, x0, "particle swarm finished its iterations"), problem, counts, history
        if problem.ident.dropped:  # polish only what the data determine
            final = problem.restrict(problem.ident.identifiable, problem.embed(x0))
            x0 = final.x0
    say(f"fitting {len(final.names)} parameters to {len(problem.meas)} poses")
    fit = fit_lm(final, x0, max_iter=max_iter)
    return fit, final, (counts[0] + fit.iterations, counts[1] + fit.evaluations), history


def _at(problem: CalibrationProblem, x: np.ndarray, message: str = "not yet fitted") -> LMResult:
    """The problem evaluated at x, as a fit without iterations."""
    r, J = problem.fun()(x)
    return LMResult(x, 0.5 * float(r @ r), r, J, 0, 0, True, message)


def _result(robot: Robot, problem: CalibrationProblem, final: CalibrationProblem, fit: LMResult, w, counts,
            history, method: str, loss: str, elapsed: float) -> CalibrationResult:
    """The fit as a CalibrationResult: estimates for every name of ``problem``, uncertainty from
    the fit of ``final`` (undetermined parameters of a swarm-only fit get σ = inf)."""
    v = final.embed(fit.x)
    calibrated = problem.start.with_params(v)
    names, idx = problem.names, problem.cols
    undetermined = problem.ident.dropped if method == "pso" else ()
    sd, corr, sigma2, cov = parameter_statistics(fit.jacobian, fit.residual, final.names, names, undetermined)
    meas = problem.meas
    res = meas.xyz - calibrated.forward(meas.q)
    return CalibrationResult(
        robot=calibrated, nominal=robot, names=names,
        estimates={n: float(v[i]) for n, i in zip(names, idx)},
        corrections={n: float(v[i] - robot.params.values[i]) for n, i in zip(names, idx)},
        std={n: float(x) for n, x in zip(names, sd)}, correlation=corr, residuals=res,
        sigma=float(np.sqrt(sigma2 / (1.0 if w is None else np.mean(w)))),
        stats_before=EvaluationStats.from_errors(meas.xyz - robot.forward(meas.q)),
        stats_after=EvaluationStats.from_errors(res),
        iterations=counts[0], evaluations=counts[1], converged=fit.converged, message=fit.message,
        time_s=elapsed, loss=loss, base=problem.base, identifiability=problem.ident, history=history, covariance=cov)


def judge(res: CalibrationResult, problem: CalibrationProblem, th: Thresholds) -> CalibrationResult:
    """The result with its verdict and per-pose robust z-scores."""
    meas = problem.meas
    z = robust_z(np.linalg.norm(res.residuals, axis=1))
    reasons = [] if res.converged else [Reason("refused", "not-converged", f"the fit did not converge "
                                                                             f"({res.message})")]
    if problem.base == "estimate":
        loose = [n for n in problem.start.base_params() if n in problem.ident.dropped]
        if loose:
            reasons.append(Reason("refused", "base-underdetermined",
                                  f"the poses leave the base frame underdetermined ({', '.join(loose)}): measure "
                                  f"poses spread over the workspace, or use --base fixed if the base is known"))
    reasons += correction_reasons(problem.start, {n: res.corrections[n] for n in res.names
                                                  if np.isfinite(res.std[n])}, th)
    inliers = res.residuals[z <= th.outlier_z]  # outliers are named on their own, not smeared into σ
    pos_sigma = float(np.sqrt(np.sum(inliers**2) / max(inliers.size - len(res.names), 1)))
    reasons += drift_reasons(meas.rows, np.linalg.norm(res.residuals, axis=1))
    reasons += residual_reasons(pos_sigma, th) + outlier_reasons(meas.rows, z, th) + duplicate_reasons(meas.rows, problem.repeats)
    return dataclasses.replace(res, verdict=Verdict.from_reasons(reasons), measurements=meas, pose_z=z,
                               outlier_z=th.outlier_z)


def evaluate(robot: Robot, meas: Measurements, rebase: bool = False,
             uncertainty: ModelUncertainty | None = None) -> EvaluationStats:
    """Position error statistics of ``robot`` on ``meas`` (m).

    rebase      -- first re-fit only the 6 base-frame parameters (the tracker moved between sessions)
    uncertainty -- the model's parameter covariance (``result.uncertainty()``, or
                   :func:`kincal.load_uncertainty` of a saved calibration): adds the predicted σ at
                   every pose and a warning naming the rows where the model extrapolates
    """
    meas.check_robot(robot)
    if rebase:
        robot = calibrate(robot, meas, params=(), base="estimate").robot
    stats = EvaluationStats.from_errors(meas.xyz - robot.forward(meas.q))
    if uncertainty is None:
        return stats
    sigma = uncertainty.sigma(robot, meas.q)
    outside, envelope = envelope_warning(meas.rows, meas.q, robot, uncertainty)
    warnings = tuple(w for w in (extrapolation_warning(meas.rows, sigma, uncertainty), envelope) if w)
    flagged = uncertainty.extrapolated(sigma) | outside
    return dataclasses.replace(stats, predicted_sigma=tuple(map(float, sigma)),
                               extrapolated_rows=tuple(int(r) for r in meas.rows[flagged]), warnings=warnings)
