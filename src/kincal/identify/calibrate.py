"""Identification of kinematic parameters from measured positions: ``calibrate`` and ``evaluate``.

``calibrate`` checks every option first, builds a :class:`~kincal.identify.problem.CalibrationProblem`
(robot, measurements, free parameters, residual), runs a solver on it (LM, PSO, or PSO then LM),
optionally reweights robustly, and turns the fit into a :class:`CalibrationResult`.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np

from .._threads import blas_threads
from ..analysis.uncertainty import ModelUncertainty, envelope_warning, extrapolation_warning
from ..errors import MeasurementError
from ..io.measurements import Measurements
from ..models.robot import Robot
from ..models.terms import drop_terms, extend
from .compliance import negative_compliances
from .covariance import covariance_statistics, parameter_statistics
from .diagnosis import TRIGGERS, diagnose, outlier_poses
from .drift import with_drift, without_drift
from .lm import LMResult, fit_lm
from .noise import ROUNDS, SETTLED, extra_variance, relative_weights
from .weak import weak_note, weakest
from .options import FitOptions
from .problem import CalibrationProblem, build_problem
from .pso import fit_pso
from .relevance import RelevanceFit, with_learned_prior
from .result import CalibrationResult, EvaluationStats, rejected
from .robust import irls
from .select import select_model
from .verdict import (Reason, Verdict, correction_reasons, drift_reasons, duplicate_reasons, fitted_drift_reasons,
                      mounting_reasons, noise_level, outlier_reasons, residual_reasons, robust_z)


def calibrate(robot: Robot, meas: Measurements, options: FitOptions | None = None, *, use_q: np.ndarray | None = None,
              progress: Callable[[str], None] | None = None, **changes) -> CalibrationResult:
    """Identify ``robot``'s parameters from measured tool positions.

    options  -- a :class:`FitOptions` record (default: its defaults); ``changes`` are fields of it
                to change, e.g. ``calibrate(robot, meas, base="fixed", loss="huber")``
    use_q    -- (M, n) joint values where the calibrated model will be used: with
                ``error_model="auto"`` the prediction-σ guard judges candidate terms there (default:
                the calibration poses). Kept in ``result.use_q`` and in the calibration record
    progress -- called with a message at each stage

    Every option is checked before any work (ValueError naming it). MeasurementError for data that
    cannot belong to the robot or is too little, IdentifiabilityError for an explicit ``names`` list
    Levenberg–Marquardt cannot identify. The result carries a verdict (good, suspect, refused) with
    reasons. BLAS runs single-threaded inside: the problems are small, and threads fight for cores.
    """
    t0 = time.perf_counter()
    options = (options or FitOptions()).replace(**changes).check(robot)
    if use_q is not None:
        use_q = robot.check_q(use_q)
    say = progress or (lambda msg: None)
    with blas_threads(1):
        robot, choice = _error_model(robot, meas, options, say, use_q)
        res = dataclasses.replace(_fit(robot, meas, options, say, t0), error_model_choice=choice, use_q=use_q)
        res = _negative_compliance(res, say) or res
        if options.reject_outliers:
            res = _without_outliers(res, say)
        return _diagnosed(res, say) if options.diagnose else res


def _without_outliers(res: CalibrationResult, say) -> CalibrationResult:
    """The fit repeated without the poses a robust refit puts beyond the outlier limit (none: ``res``)."""
    meas = res.measurements
    bad = outlier_poses(res.nominal, meas, res.options)
    if not len(bad):
        return res
    say(f"leaving out {len(bad)} outlier pose(s): {meas.describe_rows(bad)}")
    again = calibrate(res.nominal, meas.subset(np.setdiff1d(np.arange(len(meas)), bad)),
                      res.options.replace(error_model=None, reject_outliers=False, diagnose=False))
    return dataclasses.replace(again, options=res.options, error_model_choice=res.error_model_choice,
                               use_q=res.use_q, error_model_notes=res.error_model_notes + again.error_model_notes,
                               **rejected(meas, bad))


def _diagnosed(res: CalibrationResult, say) -> CalibrationResult:
    """A doubtful verdict gets the differential diagnosis, its finding as the first reason."""
    if not any(r.code in TRIGGERS for r in res.verdict.reasons):
        return res
    say("trying the common input mistakes")
    found = diagnose(res)
    best = found.best
    reason = Reason(res.verdict.status, f"cause-{best.code}" if best else "cause-unknown", found.message())
    return dataclasses.replace(res, diagnosis=found, verdict=Verdict(res.verdict.status, (reason, *res.verdict.reasons)))


def _fit(robot: Robot, meas: Measurements, o: FitOptions, say, t0: float) -> CalibrationResult:
    """Build the problem (with the drift term if asked), solve it, judge the result."""
    fit_robot, fit_meas = with_drift(robot, meas) if o.drift else (robot, meas)
    problem = build_problem(fit_robot, fit_meas, o, say=say)
    w, weak, prior = None, {}, None
    if o.loss == "linear":
        fit, final, counts, history = _solve(problem, o, say)
        if o.method != "pso":
            fit, final, weak = _hold_weak(problem, final, fit, o, say)
        if fit.converged:
            problem, fit, final = _with_model_error(problem, final, fit, o, say)
        if fit.converged and o.prior == "relevance":
            fit, prior = _with_prior(problem, final, fit, o, say)
    else:  # reweight from the start: a least-squares fit pulled by outliers is a poor place to begin
        say("fitting with reweighting (robust loss)")
        final, history = problem, ()
        fit, w, *counts = irls(problem, _at(problem, problem.x0), o.loss, o.f_scale,
                               lambda x, wt: fit_lm(problem, x, wt, o.max_iter))
    res = _result(fit_robot, problem, final, fit, w, counts, history, o, time.perf_counter() - t0, weak, prior)
    res = judge(res, problem)
    if not o.drift:
        return res
    res = without_drift(res, robot, meas)
    found = fitted_drift_reasons(res.drift, noise_level(meas.std, o.thresholds)[0])
    return dataclasses.replace(res, verdict=Verdict.from_reasons(res.verdict.reasons + tuple(found)))


def _hold_weak(problem: CalibrationProblem, final: CalibrationProblem, fit: LMResult, o: FitOptions, say):
    """The fit repeated with the parameters the data hardly determine held at their start values
    (:mod:`kincal.identify.weak`), worst first: (fit, the problem fitted, held name -> its σ)."""
    weak: dict[str, float] = {}
    noise = noise_level(problem.meas.std, o.thresholds)[0]  # the instrument's σ: what the poses determine
    while (worst := weakest(final.start, final.names, fit.jacobian, fit.residual, noise)) is not None:
        weak[worst[0]] = worst[1]
        say(f"keeping {worst[0]} at nominal: the data determine it worse than a real robot's error")
        v = final.embed(fit.x)
        i = int(final.start.params.indices([worst[0]])[0])
        v[i] = problem.values0[i]
        final = final.restrict([n for n in final.names if n != worst[0]], v)
        fit = fit_lm(final, final.x0, max_iter=o.max_iter)
    return fit, final, weak


def _with_model_error(problem: CalibrationProblem, final: CalibrationProblem, fit: LMResult, o: FitOptions, say):
    """The fit repeated with weights 1/(σᵢ² + s²), s² what the model leaves unexplained beyond the
    stated σ (:mod:`kincal.identify.noise`), until s settles: (problem, fit, the problem fitted). Data
    without σ (no weights) are left as fitted."""
    meas, s_old, std, weights = problem.meas, 0.0, problem.meas.std, final.weights
    if std is None or weights is None:
        return problem, fit, final
    for _ in range(ROUNDS):
        r = meas.xyz - final.start.with_params(final.embed(fit.x)).forward(meas.q)
        s2 = extra_variance(r**2, std**2, r.size - len(final.names))
        if abs(np.sqrt(s2) - s_old) <= SETTLED * max(np.sqrt(s2), 1e-12):
            break
        s_old = float(np.sqrt(s2))
        w = relative_weights(std, s2).T.ravel()  # the residual's rows: every pose's x, then y, then z
        if np.allclose(w, weights, rtol=1e-9, atol=0.0):  # equal σ: the same weights, the same fit
            break
        say(f"refitting with {s_old * 1e3:.3g} mm of model error beside the stated σ")
        problem, final = (dataclasses.replace(p, weights=w) for p in (problem, final))
        weights = w
        fit = fit_lm(final, fit.x, max_iter=o.max_iter)
    return problem, fit, final


def _with_prior(problem: CalibrationProblem, final: CalibrationProblem, fit: LMResult, o: FitOptions, say):
    """The fit of ``final`` refitted with the prior learned from the data around the nominal values
    (:mod:`kincal.identify.relevance`), on the residual in units of the instrument's σ: (the fit at
    its solution, the prior fit); (fit, None) when no fitted parameter takes a prior (a frame alone)."""
    noise = noise_level(problem.meas.std, o.thresholds)[0]
    f = final.fun()

    def fun(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, J = f(x)
        return r / noise, J / noise
    say("learning the prior of the corrections from the data")
    scaled = dataclasses.replace(fit, residual=fit.residual / noise, jacobian=fit.jacobian / noise)
    rel = with_learned_prior(fun, scaled, problem.values0[final.cols], final.names, final.start)
    if not isinstance(rel, RelevanceFit):
        return fit, None
    return dataclasses.replace(fit, x=rel.x, residual=rel.residual * noise, jacobian=rel.jacobian * noise,
                               converged=rel.converged, message=f"{fit.message}; prior learned"), (rel, noise)


def _error_model(robot: Robot, meas: Measurements, options: FitOptions, say, use_q=None):
    """The robot with the requested error model, and the model comparison when it is "auto"."""
    spec = options.error_model
    if spec is None:
        return robot, None
    choice = None
    if spec.name == "auto":
        say("choosing the error model (joint-space blocked cross-validation)")
        choice = select_model(robot, meas, calibrate, options.replace(error_model=None, diagnose=False,
                                                                       reject_outliers=False), use_q=use_q,
                              payload=spec.payload)
        spec = dataclasses.replace(spec, name=choice.chosen)
    return extend(robot, spec, meas.q), choice


def _negative_compliance(res: CalibrationResult, say) -> CalibrationResult | None:
    """The fit repeated without the compliances ``res`` finds negative (a joint that bends against its
    load is not a spring: the term describes something else), or None when all are positive."""
    neg, notes = negative_compliances(res.names, res.estimates, res.std)
    if not neg:
        return None
    say("dropping negative compliance: " + ", ".join(neg))
    again = calibrate(drop_terms(res.nominal, neg), res.measurements,
                      res.options.replace(error_model=None, reject_outliers=False, diagnose=False))
    return dataclasses.replace(again, options=res.options, error_model_choice=res.error_model_choice,
                               use_q=res.use_q, error_model_notes=notes + again.error_model_notes)


def _solve(problem: CalibrationProblem, o: FitOptions, say):
    """Run the solver(s). Returns the fit, the problem it belongs to, (iterations, evaluations) and
    the particle swarm's best value per iteration (empty for LM)."""
    history: tuple[float, ...] = ()
    x0, counts, final = problem.x0, (0, 0), problem
    if o.method in ("pso", "pso+lm"):
        say(f"particle swarm over {len(problem.names)} parameters")
        swarm = fit_pso(problem, o.pso_settings)
        x0, counts, history = swarm.x, (swarm.iterations, swarm.evaluations), tuple(map(float, swarm.history))
        if o.method == "pso":
            return _at(problem, x0, "particle swarm finished its iterations"), problem, counts, history
        if problem.ident.dropped:  # polish only what the data determine
            final = problem.restrict(problem.ident.identifiable, problem.embed(x0))
            x0 = final.x0
    say(f"fitting {len(final.names)} parameters to {len(problem.meas)} poses")
    fit = fit_lm(final, x0, max_iter=o.max_iter)
    return fit, final, (counts[0] + fit.iterations, counts[1] + fit.evaluations), history


def _at(problem: CalibrationProblem, x: np.ndarray, message: str = "not yet fitted") -> LMResult:
    """The problem evaluated at x, as a fit without iterations."""
    r, J = problem.fun()(x)
    return LMResult(x, 0.5 * float(r @ r), r, J, 0, 0, True, message)


def _result(robot: Robot, problem: CalibrationProblem, final: CalibrationProblem, fit: LMResult, w, counts,
            history, options: FitOptions, elapsed: float, weak: dict[str, float], prior=None) -> CalibrationResult:
    """The fit as a CalibrationResult: estimates for every name of ``problem`` but those held at
    nominal (``weak``), uncertainty from the fit of ``final`` (the posterior with a learned ``prior``:
    (its fit, the noise it was scaled by); undetermined parameters of a swarm-only fit get σ = inf)."""
    v = final.embed(fit.x)
    calibrated = problem.start.with_params(v)
    names = tuple(n for n in problem.names if n not in weak)
    idx = problem.start.params.indices(names)
    ident = problem.ident if not weak else dataclasses.replace(
        problem.ident, identifiable=tuple(n for n in problem.ident.identifiable if n not in weak),
        notes=problem.ident.notes + (weak_note(problem.start, weak),))
    undetermined = problem.ident.dropped if options.method == "pso" else ()
    sd, corr, sigma2, cov = (parameter_statistics(fit.jacobian, fit.residual, final.names, names, undetermined)
                             if prior is None else covariance_statistics(prior[0].covariance, prior[0].noise2 *
                                                                         prior[1] ** 2, final.names, names))
    meas = problem.meas
    res = meas.xyz - calibrated.forward(meas.q)
    return CalibrationResult(
        robot=calibrated, nominal=robot, names=names,
        estimates={n: float(v[i]) for n, i in zip(names, idx)},
        corrections={n: float(v[i] - robot.params.values[i]) for n, i in zip(names, idx)},
        std={n: float(x) for n, x in zip(names, sd)}, correlation=corr, residuals=res,
        sigma=float(np.sqrt(sigma2 / (1.0 if w is None else np.mean(w)))),
        stats_before=EvaluationStats.from_errors(meas.xyz - problem.start.forward(meas.q)),  # frame registered
        stats_after=EvaluationStats.from_errors(res),
        iterations=counts[0], evaluations=counts[1], converged=fit.converged, message=fit.message,
        time_s=elapsed, options=options, identifiability=ident, history=history, covariance=cov,
        measurements=meas, pose_z=robust_z(np.linalg.norm(res, axis=1)), weak=dict(weak),
        prior={} if prior is None else dict(prior[0].sigma))


def judge(res: CalibrationResult, problem: CalibrationProblem) -> CalibrationResult:
    """The result with its verdict (limits: ``res.options.thresholds``) from its per-pose robust z-scores."""
    meas, th, z = problem.meas, res.options.thresholds, res.pose_z
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
    if res.mounting:
        reasons += mounting_reasons(res.nominal.tool_point(), res.robot.tool_point(), th)
    inliers = res.residuals[z <= th.outlier_limit(len(z))]  # outliers are named on their own, not smeared into σ
    pos_sigma = float(np.sqrt(np.sum(inliers**2) / max(inliers.size - len(res.names), 1)))
    reasons += drift_reasons(meas.rows, np.linalg.norm(res.residuals, axis=1))
    reasons += residual_reasons(pos_sigma, noise_level(meas.std, th), th)
    reasons += outlier_reasons(meas.rows, z, th, res.options.loss)
    reasons += duplicate_reasons(meas.rows, problem.repeated_poses)
    return dataclasses.replace(res, verdict=Verdict.from_reasons(reasons))


def evaluate(robot: Robot, meas: Measurements, rebase: bool = False,
             uncertainty: ModelUncertainty | None = None) -> EvaluationStats:
    """Position error statistics of ``robot`` on ``meas`` (m).

    rebase      -- first re-fit only the 6 base-frame parameters (the tracker moved between sessions)
    uncertainty -- the model's parameter covariance (``result.uncertainty()``, or
                   :func:`kincal.load_uncertainty` of a saved calibration): adds the predicted σ at
                   every pose and a warning naming the rows where the model extrapolates
    """
    if rebase not in (True, False):
        raise ValueError(f"rebase={rebase!r}: True or False")
    meas.check_robot(robot)
    if len(meas) == 0:
        raise MeasurementError(f"{meas.source}: no poses to evaluate on (an empty file or "
                               f"subset); give at least one measured pose")
    if rebase and robot.base_params():  # frame only, kinematics fixed (kincal.identify.refit_frame)
        robot = calibrate(robot, meas, names=(), base="estimate", diagnose=False).robot
    stats = EvaluationStats.from_errors(meas.xyz - robot.forward(meas.q))
    if uncertainty is None:
        return stats
    sigma = uncertainty.sigma(robot, meas.q)
    outside, envelope = envelope_warning(meas.rows, meas.q, robot, uncertainty)
    warnings = tuple(w for w in (extrapolation_warning(meas.rows, sigma, uncertainty, meas.q, robot), envelope) if w)
    flagged = uncertainty.extrapolated(sigma) | outside
    return dataclasses.replace(stats, predicted_sigma=tuple(map(float, sigma)),
                               extrapolated_rows=tuple(int(r) for r in meas.rows[flagged]), warnings=warnings)
