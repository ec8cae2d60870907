"""Choosing the error model by joint-space blocked cross-validation, refusing to extrapolate.

Random folds flatter flexible models: every held-out pose has training neighbours. Here the folds
are regions of joint space (k-means on cos/sin of the revolute joints and the scaled prismatic
ones, deterministically seeded), so each fold tests the model where it was not fitted, as a robot
is later used. A candidate term is kept only when

* its blocked-CV mean error is below the geometric model's,
* its predicted σ (fitted to all data) at the poses where the model will be used (``use_q``;
  default the training poses) stays within ``SIGMA_FACTOR`` (1.25×) of the geometric model's: the
  prediction-σ guard. σ only propagates noise and so understates how badly flexible terms
  extrapolate: on the real UR5 grid, harmonics fitted on one half of a joint's range showed 1.3–1.6×
  the geometric σ on the other half and 2–4× its error, while inside the training region the ratio
  stayed at 1.0–1.1. Hence the tight factor (chosen on that data set; the WAM agreed);
* every fold's fit converged without a refused verdict;

and among the models kept (geometric always is) the simplest one within one standard error of the
best CV error is chosen. The table says why each candidate was kept or dropped. The same rule
decides whether the automatic β tilts stay (candidate ``nobeta``) and whether gravity terms earn
their place (``compliance`` when the robot file has masses, ``gravity-regressor``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import KincalError
from ..io.measurements import Measurements
from ..models.robot import Robot
from ..models.terms import ErrorModel, extend
from ..ties import first_best
from ..units import MM

SIGMA_FACTOR = 1.25


def default_candidates(robot: Robot) -> tuple[str, ...]:
    """The models ``auto`` compares: geometric; without the automatic β tilts (DH/MDH chains that
    have them); compliance (chains with link masses) and the gravity regressor (chains); joint-angle
    harmonics of order 1 and 2."""
    out = ["geometric"]
    if robot.has_beta:
        out.append("nobeta")
    if robot.has_gravity:
        out += ["compliance", "gravity-regressor"]
    return tuple(out + ["harmonics:1", "harmonics:2"])


@dataclass(frozen=True)
class ErrorModelChoice:
    """The comparison: per error model its parameter count, blocked-CV mean error and standard error
    (m), predicted-σ ratio to geometric, whether it was eligible and why; and the model chosen."""

    rows: tuple[dict, ...]
    chosen: str
    folds: int

    def to_dict(self) -> dict:
        finite = lambda v: None if isinstance(v, float) and not np.isfinite(v) else v  # noqa: E731  (JSON has no inf)
        return {"chosen": self.chosen, "folds": self.folds,
                "candidates": [{k: finite(v) for k, v in r.items()} for r in self.rows]}

    def __str__(self) -> str:
        lines = [f"error model by joint-space blocked cross-validation ({self.folds} regions): {self.chosen}",
                 f"  {'error model':<20} {'params':>6} {'CV mean mm':>11} {'± se':>8} {'σ ratio':>8}  decision"]
        for r in self.rows:
            if not np.isfinite(r["cv_mean"]):
                lines.append(f"  {r['error_model']:<20} {'-':>6} {'-':>11} {'-':>8} {'-':>8}  {r['decision']}")
                continue
            lines.append(f"  {r['error_model']:<20} {r['parameters']:>6} {r['cv_mean'] * MM:11.4f} {r['cv_se'] * MM:8.4f} "
                         f"{r['sigma_ratio']:8.2f}  {r['decision']}")
        return "\n".join(lines)


def blocked_folds(robot: Robot, q: np.ndarray, k: int, iterations: int = 30) -> list[np.ndarray]:
    """k regions of joint space (index arrays, in pose order): deterministic k-means."""
    rev = np.array([t == "revolute" for t in robot.joint_types])
    span = np.ptp(q, axis=0) + 1e-12
    X = np.hstack([np.cos(q[:, rev]), np.sin(q[:, rev]), (q[:, ~rev] - q[:, ~rev].min(axis=0)) / span[~rev]])
    centres = [X[first_best(-np.sum((X - X.mean(axis=0)) ** 2, axis=1))]]
    for _ in range(1, k):  # farthest-point start: spread-out regions, no random seed
        d = np.min([np.sum((X - c) ** 2, axis=1) for c in centres], axis=0)
        centres.append(X[first_best(d)])
    C = np.array(centres)
    for _ in range(iterations):
        labels = np.argmin(((X[:, None, :] - C[None]) ** 2).sum(axis=2), axis=1)
        C = np.array([X[labels == j].mean(axis=0) if np.any(labels == j) else C[j] for j in range(k)])
    return [np.flatnonzero(labels == j) for j in range(k) if np.any(labels == j)]


def select_model(robot: Robot, meas: Measurements, calibrate, options, candidates=None, folds: int = 5,
                 use_q: np.ndarray | None = None, payload: float = 0.0) -> ErrorModelChoice:
    """Compare ``candidates`` on ``meas`` and choose one (see the module docstring). ``calibrate`` is
    the calibration function (passed in to keep this room below it), ``options`` its FitOptions
    (without an error model); ``folds`` is the number of k-means regions; ``candidates`` default to
    :func:`default_candidates`; ``payload`` (kg) loads the gravity terms."""
    regions = blocked_folds(robot, meas.q, folds)
    use = meas.q if use_q is None else robot.check_q(use_q)
    rows = [_cross_validate(robot, meas, ErrorModel(name, payload), regions, calibrate, options, use)
            for name in (candidates or default_candidates(robot))]
    geo = rows[0]
    for r in rows:
        r["sigma_ratio"] = r.pop("sigma") / geo["sigma"] if r is not geo else 1.0
        r["decision"] = _eligibility(r, geo)
    geo["decision"] = "kept (reference)"  # the fallback, whatever its folds gave
    kept = [r for r in rows if r["decision"].startswith("kept")]
    best = kept[first_best([r["cv_mean"] for r in kept], maximize=False)]
    simple = [r for r in kept if r["cv_mean"] <= best["cv_mean"] + best["cv_se"]]
    chosen = min(simple, key=lambda r: r["parameters"])
    for r in kept:
        if r is chosen:
            r["decision"] = "chosen" + ("" if r is best else ": the simplest within one standard error of the best")
        elif r is best:
            r["decision"] = "best CV, but a simpler model is within one standard error"
        else:
            r["decision"] = "kept, but more than one standard error worse than the best"
    return ErrorModelChoice(tuple(rows), chosen["error_model"], len(regions))


def _cross_validate(robot: Robot, meas: Measurements, spec: ErrorModel, regions, calibrate, options, use) -> dict:
    """Blocked-CV errors of one error model, and its predicted σ at the use poses when fitted to all data."""
    model = spec.name
    try:
        ext = extend(robot, spec, meas.q)
    except KincalError as exc:  # e.g. compliance without link masses
        return {"error_model": model, "parameters": 0, "cv_mean": np.inf, "cv_se": 0.0, "sigma": np.inf,
                "fits_ok": False, "why": str(exc)}
    errors, ok, estimated = [], True, 0
    for held in regions:
        train = meas.subset(np.setdiff1d(np.arange(len(meas)), held))
        try:
            res = calibrate(ext, train, options)
        except KincalError:  # too little data left for this model: it cannot be judged, so not kept
            return {"error_model": model, "parameters": ext.n_params, "cv_mean": np.inf, "cv_se": 0.0,
                    "sigma": np.inf, "fits_ok": False}
        ok &= res.converged and res.verdict.status != "refused"
        estimated = max(estimated, len(res.names))
        test = meas.subset(held)
        errors.append(float(np.mean(np.linalg.norm(test.xyz - res.robot.forward(test.q), axis=1))))
    full = calibrate(ext, meas, options)
    sigma = float(np.median(full.uncertainty().sigma(full.robot, use)))
    e = np.array(errors)
    return {"error_model": model, "parameters": estimated, "cv_mean": float(e.mean()),
            "cv_se": float(e.std(ddof=1) / np.sqrt(len(e))) if len(e) > 1 else 0.0, "sigma": sigma,
            "fits_ok": bool(ok)}


def _eligibility(r: dict, geo: dict) -> str:
    if r is geo:
        return "kept (reference)"
    if "why" in r:
        return f"not applicable: {r['why']}"
    if not r["fits_ok"]:
        return "dropped: a fold's fit did not converge or was refused"
    if r["cv_mean"] >= geo["cv_mean"]:
        return "dropped: no better than geometric on held-out regions"
    if r["sigma_ratio"] > SIGMA_FACTOR:
        return f"dropped: predicted σ {r['sigma_ratio']:.1f}x geometric's where it would be used (limit {SIGMA_FACTOR:g}x)"
    return "kept"
