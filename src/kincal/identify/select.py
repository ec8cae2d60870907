"""Choosing the error model by joint-space blocked cross-validation, refusing to extrapolate.

Random folds flatter flexible models: every held-out pose has training neighbours. Here the folds
are regions of joint space (k-means on cos/sin of the revolute joints and the scaled prismatic
ones, deterministically seeded), so each fold tests the model where it was not fitted, as a robot
is later used. A covariate the robot reads (a temperature) is one more scaled input of the k-means,
so that ``thermal:<covariate>`` is tested where it was not fitted too: the regions, and so every
candidate's figures, then differ from those of the same poses without it, and the table says what
the regions are of. A candidate term is kept only when

* its blocked-CV mean error is below the geometric model's,
* its predicted σ (fitted to all data) at the poses where the model will be used (``use_q``;
  default the training poses) stays within ``SIGMA_FACTOR`` (1.25×) of the geometric model's: the
  prediction-σ guard. σ only propagates noise and so understates how badly flexible terms
  extrapolate: on the real UR5 grid, harmonics fitted on one half of a joint's range showed 1.3–1.6×
  the geometric σ on the other half and 2–4× its error, while inside the training region the ratio
  stayed at 1.0–1.1. Hence the tight factor (chosen on that data set; the WAM agreed). σ is judged in
  both frames the model's predictions are used in, and the worse ratio decides: the measurement frame
  (evaluate, targets in the tracker's frame) and the robot's own base frame, where ``compensate``
  computes commands by default, without the base frame's parameters
  (:func:`kincal.compensate.command_models`). A term the data cannot tell from the measurement frame
  over their range is certain only in the first: on the real UR5 grid (joint 1 over −24..56°) the
  joint-1 harmonics of ``harmonics:2`` came out as a near-constant −0.44° (joint 1's zero, which the
  data cannot tell from the tracker frame's rotation); at the 20 random poses its σ was 1.03× geometric's
  in the tracker's frame and 11.8× in the robot's, where its commands stood 4.3 mm from geometric's;
* every fold's fit converged without a refused verdict;
* when the data come from several sessions (files, set-ups, days), it is also no worse than
  geometric on any held-out session: each session is left out in turn, both models are fitted to the
  others, the left-out session's measurement frame is re-registered to each (kinematics fixed, as
  ``evaluate`` does) and their mean errors compared. Regions of one session share its temperature,
  payload, tracker set-up and mastering; a term that fits those rather than the robot shows up only on
  another session. Only sessions with at most half of the poses are held out (a model trained on the
  smaller part would be judged on how little data it had, not on whether it carries over), and a
  session whose complement cannot fit a model does not judge it;

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
from ..models.terms import ErrorModel, ExtendedRobot, extend
from ..ties import first_best, improves
from ..units import MM

SIGMA_FACTOR = 1.25
FRAMES = ("measurement", "base")  # the frames a model's predictions are used in: the instrument's, the robot's own
FRAME_WORDS = {"measurement": "in the measurement frame", "base": "in the robot's base frame"}
FOLDS = 5  # k-means regions of joint space, each held out in turn


def default_candidates(robot: Robot) -> tuple[str, ...]:
    """The models ``auto`` compares: geometric; without the automatic β tilts (DH/MDH chains that
    have them); compliance (chains with link masses) and the gravity regressor (chains); joint-angle
    harmonics of order 1 and 2; the thermal growth of each covariate the robot reads
    (``thermal:<covariate>``, :mod:`kincal.models.covariates`), judged by the same rules as any term:
    the regions of joint space are also regions of the covariate (k-means sees it as a scaled,
    non-periodic input), and leave-one-session-out holds out whole sessions (a warm-up, a cold morning)."""
    geometry = robot.inner if isinstance(robot, ExtendedRobot) else robot
    out = ["geometric"]
    if geometry.has_beta:
        out.append("nobeta")
    if geometry.has_gravity:
        out += ["compliance", "gravity-regressor"]
    return tuple(out + ["harmonics:1", "harmonics:2"] + [f"thermal:{c}" for c in robot.covariate_names])


@dataclass(frozen=True)
class ErrorModelChoice:
    """The comparison of error models by joint-space blocked cross-validation, and the model chosen.

    Made by ``calibrate(..., error_model="auto")`` and kept in ``CalibrationResult.error_model_choice``;
    printed as a table (mm), :meth:`to_dict` in SI (inf as None).

    Parameters
    ----------
    rows : tuple of dict
        One per candidate error model: ``error_model`` (its name), ``parameters`` (the count estimated),
        ``cv_mean`` and ``cv_se`` (blocked-CV mean error and its standard error, m; inf: not judged),
        ``sigma_ratio_measurement`` and ``sigma_ratio_base`` (median predicted σ where the model will be used
        over geometric's, in the measurement frame and in the robot's own base frame), ``sigma_ratio`` (the
        worse of the two) and ``sigma_frame`` (its frame: "measurement" or "base"), ``fits_ok``,
        ``sessions`` (mean error on each held-out session, m; inf: not judged) and ``decision`` (kept or
        dropped, and why); ``why`` when the model does not apply to the robot.
    chosen : str
        The name of the error model chosen.
    folds : int
        The number of joint-space regions held out in turn.
    sessions : tuple of str, optional
        The held-out sessions' labels (default empty: one session).
    not_held_out : tuple of str, optional
        The sessions kept in every fit, with more than half of the poses (default empty).
    covariates : tuple of str, optional
        The covariates the regions are regions of too (default none: of joint space alone). A covariate
        the robot reads has its ``thermal:`` candidate, so k-means sees it as one more input, and every
        candidate's figures differ from those of the same poses without it.
    """

    rows: tuple[dict, ...]
    chosen: str
    folds: int
    sessions: tuple[str, ...] = ()
    not_held_out: tuple[str, ...] = ()  # sessions with more than half of the poses
    covariates: tuple[str, ...] = ()  # the regions are of these too

    @property
    def regions(self) -> str:
        """What the regions are regions of, in words: 'joint space', or 'joint space and temperature'."""
        return "joint space" + (f" and {', '.join(self.covariates)}" if self.covariates else "")

    def to_dict(self) -> dict:
        return {"chosen": self.chosen, "folds": self.folds, "regions": self.regions, "sessions": list(self.sessions),
                "not_held_out": list(self.not_held_out),
                "candidates": [{k: _json(v) for k, v in r.items()} for r in self.rows]}

    def __str__(self) -> str:
        total = len(self.sessions) + len(self.not_held_out)
        held = f" and leave-one-session-out ({len(self.sessions)} of {total} sessions held out)" if self.sessions else ""
        how = "joint-space blocked cross-validation" if not self.covariates else "blocked cross-validation"
        regions = f"{self.folds} regions" + (f" of {self.regions}" if self.covariates else "")
        lines = [f"error model by {how} ({regions}){held}: {self.chosen}",
                 f"  {'error model':<20} {'params':>6} {'CV mean mm':>11} {'± se':>8} {'σ ratio':>8} {'σ frame':<11}"
                 + "".join(f" {f'session {i + 1} mm':>12}" for i in range(len(self.sessions))) + "  decision"]
        for r in self.rows:
            judged = np.isfinite(r["cv_mean"])  # else '-' throughout
            cells = (f"{r['parameters']:>6} {r['cv_mean'] * MM:11.4f} {r['cv_se'] * MM:8.4f} {r['sigma_ratio']:8.2f} "
                     f"{r['sigma_frame']:<11}" if judged else f"{'-':>6} {'-':>11} {'-':>8} {'-':>8} {'-':<11}")
            lines.append(f"  {r['error_model']:<20} {cells}" + "".join(f" {e * MM:12.4f}" if judged and np.isfinite(e)
                                                                       else f" {'-':>12}" for e in r["sessions"])
                         + f"  {r['decision']}")
        lines.append("  σ ratio: predicted σ where the model will be used over geometric's, the worse of the measurement "
                     "frame's and the robot's base frame's (σ frame: which)")
        lines += [f"  session {i + 1}: {name} (held out; its frame re-registered)" for i, name in enumerate(self.sessions)]
        lines += [f"  not held out: {name} (more than half of the poses: a model fitted without it would be judged "
                  f"on too little data)" for name in self.not_held_out]
        return "\n".join(lines)


def _json(v):
    """inf (not judged) as None: JSON has no inf."""
    if isinstance(v, list):
        return [_json(x) for x in v]
    return None if isinstance(v, float) and not np.isfinite(v) else v


def blocked_folds(robot: Robot, q: np.ndarray, k: int, iterations: int = 30) -> list[np.ndarray]:
    """k regions of joint space (index arrays, in pose order): deterministic k-means."""
    rev = robot.periodic
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


def select_model(robot: Robot, meas: Measurements, calibrate, options, use_q: np.ndarray | None = None,
                 payload: float = 0.0) -> ErrorModelChoice:
    """Compare the :func:`default_candidates` on ``meas`` and choose one (see the module docstring).
    ``calibrate`` is the calibration function (passed in to keep this room below it), ``options`` its
    FitOptions (without an error model); the regions are FOLDS k-means regions; ``meas.session`` labels
    (several sessions) add the leave-one-session-out test; ``payload`` (kg) loads the gravity terms (the
    candidates without one get none)."""
    regions = blocked_folds(robot, meas.q, FOLDS)
    sessions = _held_out_sessions(meas)
    use = meas.q if use_q is None else robot.check_q(use_q)
    auto = ErrorModel("auto", payload)
    rows = [_cross_validate(robot, meas, auto.named(name), regions, sessions, calibrate, options, use)
            for name in default_candidates(robot)]
    geo, reference = rows[0], rows[0]["sigma"]
    for r in rows:
        _sigma_ratio(r, None if r is geo else reference)
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
    return ErrorModelChoice(tuple(rows), chosen["error_model"], len(regions), tuple(n for n, _ in sessions),
                            tuple(n for n in meas.sessions() if n not in {m for m, _ in sessions}) if sessions else (),
                            robot.covariate_names)


def _held_out_sessions(meas: Measurements) -> list[tuple[str, np.ndarray]]:
    """(label, pose indices) of the sessions to hold out: several sessions, each at most half the poses."""
    names = meas.sessions()
    if len(names) < 2:
        return []
    held = [(name, np.flatnonzero(meas.session == name)) for name in names]
    return [(name, index) for name, index in held if 2 * len(index) <= len(meas)]


def _cross_validate(robot: Robot, meas: Measurements, spec: ErrorModel, regions, sessions, calibrate, options,
                    use) -> dict:
    """Blocked-CV errors of one error model, its held-out session errors, and its predicted σ at the
    use poses when fitted to all data."""
    model = spec.name
    try:
        ext = extend(robot, spec, meas.q)
    except KincalError as exc:  # e.g. compliance without link masses
        return _unjudged(model, 0, sessions, why=str(exc))
    if not isinstance(options.names, str):  # --params: each candidate with its own terms too, or all are geometric
        options = options.replace(names=(*options.names, *[n for n in ext.params.names if n not in robot.params.names]))
    errors, ok, estimated = [], True, 0
    for held in regions:
        try:
            res = calibrate(ext, meas.subset(np.setdiff1d(np.arange(len(meas)), held)), options)
        except KincalError:  # too little data left for this model: it cannot be judged, so not kept
            return _unjudged(model, ext.n_params, sessions)
        ok &= res.converged and res.verdict.status != "refused"
        estimated = max(estimated, len(res.names))
        errors.append(_mean_error(res.robot, meas.subset(held)))
    full = calibrate(ext, meas, options)
    e = np.array(errors)
    return {"error_model": model, "parameters": estimated, "cv_mean": float(e.mean()),
            "cv_se": float(e.std(ddof=1) / np.sqrt(len(e))) if len(e) > 1 else 0.0, "sigma": _sigmas(full, use),
            "fits_ok": bool(ok), "sessions": [_session_error(ext, meas, held, calibrate, options)
                                              for _, held in sessions]}


def _sigmas(full, use: np.ndarray) -> dict[str, float]:
    """Median predicted σ (m) at the use poses of the model fitted to all data, in each frame its predictions are
    used in: the measurement frame, and the robot's own base frame, where commands are computed
    (:func:`kincal.compensate.command_models`), without the base frame's parameters (as ``compensate`` judges them).
    A term the data cannot tell from the measurement frame's parameters over their range (a harmonic of a joint
    that turns little, in effect its zero) is certain only in the first."""
    unc = full.uncertainty()
    robot = full.robot
    return {frame: float(np.median(u.sigma(robot, use)))
            for frame, u in (("measurement", unc), ("base", unc.without(robot.base_params(), robot)))}


def _sigma_ratio(r: dict, reference: dict[str, float] | None) -> None:
    """Replace the row's σ by its ratio over geometric's (``reference``; None: the row is geometric's, 1) in each
    frame (``sigma_ratio_<frame>``), the worse of them (``sigma_ratio``) and the frame that set it
    (``sigma_frame``; ties: the measurement frame)."""
    sigma = r.pop("sigma")
    ratios = [1.0 if reference is None else sigma[f] / reference[f] for f in FRAMES]
    worse = first_best(ratios)
    r.update({f"sigma_ratio_{f}": x for f, x in zip(FRAMES, ratios)})
    r.update(sigma_ratio=ratios[worse], sigma_frame=FRAMES[worse])


def _unjudged(model: str, parameters: int, sessions, why: str | None = None) -> dict:
    row = {"error_model": model, "parameters": parameters, "cv_mean": np.inf, "cv_se": 0.0,
           "sigma": dict.fromkeys(FRAMES, np.inf),
           "fits_ok": False, "sessions": [np.inf] * len(sessions)}
    return row if why is None else {**row, "why": why}


def _mean_error(robot: Robot, test: Measurements) -> float:
    return float(np.mean(np.linalg.norm(test.xyz - robot.forward(test.q), axis=1)))


def _session_error(ext: Robot, meas: Measurements, held: np.ndarray, calibrate, options) -> float:
    """Mean error (m) on the poses ``held`` (one session) of ``ext`` fitted to the other sessions, the
    held-out session's measurement frame re-registered (kinematics fixed); inf when a fit fails."""
    try:
        res = calibrate(ext, meas.subset(np.setdiff1d(np.arange(len(meas)), held)), options)
        if not res.converged or res.verdict.status == "refused":
            return np.inf
        test, model = meas.subset(held), res.robot
        if model.base_params():
            model = calibrate(model, test, options.replace(names=(), base="estimate")).robot
        return _mean_error(model, test)
    except KincalError:
        return np.inf


def _eligibility(r: dict, geo: dict) -> str:
    """Why a candidate is kept or dropped (geometric's own decision is set by the caller)."""
    if "why" in r:
        return f"not applicable: {r['why']}"
    if not r["fits_ok"]:
        return "dropped: a fold's fit did not converge or was refused"
    if r["cv_mean"] >= geo["cv_mean"]:
        return "dropped: no better than geometric on held-out regions"
    if r["sigma_ratio"] > SIGMA_FACTOR:
        other = next(f for f in FRAMES if f != r["sigma_frame"])
        return (f"dropped: predicted σ {r['sigma_ratio']:.2f}x geometric's {FRAME_WORDS[r['sigma_frame']]} where it "
                f"would be used (limit {SIGMA_FACTOR:g}x; {r[f'sigma_ratio_{other}']:.2f}x {FRAME_WORDS[other]})")
    if not r["sessions"]:  # then the leave-one-session-out test: no held-out session worse than with geometric
        return "kept"
    judged = [(i, e, g) for i, (e, g) in enumerate(zip(r["sessions"], geo["sessions"]))
              if np.isfinite(e) and np.isfinite(g)]
    if not judged:
        return "dropped: it cannot be fitted with a session left out, so no held-out session can judge it"
    worse = [(i, e, g) for i, e, g in judged if improves(e, g)]  # larger beyond the tie band: worse
    if worse:
        i, e, g = worse[first_best([w[1] / w[2] for w in worse])]
        return f"dropped: worse than geometric on held-out session {i + 1} ({e * MM:.4f} vs {g * MM:.4f} mm)"
    return "kept"
