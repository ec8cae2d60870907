"""Result objects of identification and evaluation (frozen, printable in mm/deg, ``to_dict`` in SI)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._csv import listed
from ..analysis.identifiability import Identifiability
from ..analysis.uncertainty import ModelUncertainty
from ..io.measurements import Measurements
from ..models.robot import TOOL_NAMES, Robot
from ..units import MM, display
from .diagnosis import Diagnosis
from .options import FitOptions
from .relevance import prior_lines
from .select import ErrorModelChoice
from .verdict import Verdict, mounting_line, noise_level
from .weak import weak_note


@dataclass(frozen=True)
class EvaluationStats:
    """3-D position error statistics over n poses (m); with a model's uncertainty also the predicted
    σ (m) at every pose and warnings where the model extrapolates."""

    mean: float
    rms: float
    max: float
    std: float
    p95: float
    n: int
    predicted_sigma: tuple[float, ...] | None = None
    extrapolated_rows: tuple[int, ...] = ()
    warnings: tuple[str, ...] = ()

    @classmethod
    def from_errors(cls, err: np.ndarray) -> "EvaluationStats":
        e = np.linalg.norm(np.asarray(err, dtype=float).reshape(-1, 3), axis=1)
        return cls(float(e.mean()), float(np.sqrt(np.mean(e**2))), float(e.max()), float(e.std()),
                   float(np.percentile(e, 95)), int(e.size))

    def to_dict(self) -> dict:
        out: dict[str, object] = {"mean": self.mean, "rms": self.rms, "max": self.max, "std": self.std,
                                  "p95": self.p95, "n": self.n}
        if self.predicted_sigma is not None:
            out.update(predicted_sigma=list(self.predicted_sigma), extrapolated_rows=list(self.extrapolated_rows))
        return {**out, "warnings": list(self.warnings)}

    def __str__(self) -> str:
        text = (f"n={self.n}  mean {self.mean * MM:.4f} mm  rms {self.rms * MM:.4f} mm  max {self.max * MM:.4f} mm"
                f"  std {self.std * MM:.4f} mm  p95 {self.p95 * MM:.4f} mm")
        if self.predicted_sigma is not None:
            s = np.asarray(self.predicted_sigma)
            text += f"\n  model's predicted σ at these poses: median {np.median(s) * MM:.4f} mm, max {s.max() * MM:.4f} mm"
        return text + "".join(f"\n  warning: {w}" for w in self.warnings)


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Outcome of :func:`kincal.calibrate`.

    robot        -- the calibrated robot (save it with ``kincal.save_robot``)
    names        -- the estimated parameters; every other parameter kept its starting value
    estimates    -- final value by name (SI); ``corrections``: final − nominal (before registration)
    std          -- 1-sigma standard deviations by name, σ̂²(JᵀJ)⁻¹ with σ̂² = ‖r‖²/(3N − K)
    correlation  -- (K, K) correlation matrix in the order of ``names``
    residuals    -- (N, 3) measured − predicted (m) at the calibration poses
    """

    robot: Robot
    nominal: Robot
    names: tuple[str, ...]
    estimates: dict[str, float]
    corrections: dict[str, float]
    std: dict[str, float]
    correlation: np.ndarray
    residuals: np.ndarray
    sigma: float
    stats_before: EvaluationStats
    stats_after: EvaluationStats
    iterations: int
    evaluations: int
    converged: bool
    message: str
    time_s: float
    identifiability: Identifiability
    measurements: Measurements  # the data fitted (rows name the input lines)
    pose_z: np.ndarray  # (N,) robust z-score of each pose's error norm
    covariance: np.ndarray  # (K, K) in the order of ``names`` (inf σ: rows/cols of zeros)
    options: FitOptions = field(default_factory=FitOptions)  # the options used (to reproduce the fit)
    history: tuple[float, ...] = ()  # particle swarm: best mean squared residual per iteration (PSO fitness)
    verdict: Verdict = Verdict("good")
    error_model_choice: ErrorModelChoice | None = None  # error_model "auto": the blocked-CV comparison
    error_model_notes: tuple[str, ...] = ()  # terms dropped after the fit, and why
    drift: dict | None = None  # drift=True: per axis x/y/z the drift over the session (m) and its std
    use_q: np.ndarray | None = None  # (M, n) where the model will be used (the prediction-σ guard)
    diagnosis: Diagnosis | None = None  # a doubtful verdict: the common mistakes tried, the one that explains
    rejected_rows: tuple[int, ...] = ()  # reject_outliers: input rows left out as outliers
    rejected_sessions: tuple[str, ...] = ()  # several sessions: the file of each rejected row
    weak: dict[str, float] = field(default_factory=dict)  # held at nominal: name -> the σ the data gave it
    prior: dict[str, float] = field(default_factory=dict)  # learned prior σ per group (m or rad); {}: none

    def rejected_text(self) -> str:
        """'row(s) 40 of grid.csv' (several sessions: each file's rows after its name); '' when none."""
        if not self.rejected_rows:
            return ""
        if not self.rejected_sessions:
            return f"row(s) {listed(self.rejected_rows)} of {self.measurements.source}"
        names = list(dict.fromkeys(self.rejected_sessions))
        return "row(s) " + "; ".join(
            f"{listed([r for r, s in zip(self.rejected_rows, self.rejected_sessions) if s == n])} of {n}" for n in names)

    def dropped_text(self) -> str:
        """What the data do not determine: kept nominal (least squares), or moved by a particle swarm
        anyway (only their combination with the parameters they act like is fitted); '' when none."""
        ident = self.identifiability
        if not ident.dropped:
            return ""
        moved = [n for n in ident.dropped if n in self.names]
        head = f"identifiable: {len(ident.identifiable)} of {len(ident.candidates)} candidate parameters; "
        if moved:
            head += (f"{', '.join(moved)} moved by the particle swarm too, but not determined by the data (σ "
                     f"undetermined): only its combination with the parameters it acts like is fitted")
        kept = [n for n in ident.dropped if n not in self.names]
        if kept:
            head += ("; " if moved else "") + f"{', '.join(kept)} not estimated (kept nominal)"
        return head + ". Each acts like the estimated ones shown:\n" + "\n".join(ident.confound_lines("  "))

    @property
    def mounting(self) -> str:
        """Where the data put the target in the flange frame against the declared tool point, when the
        tool point was estimated (a mounting result, not a robot error); '' otherwise."""
        if not self.robot.has_tool_point or not any(n in self.names and np.isfinite(self.std[n]) for n in TOOL_NAMES):
            return ""
        return mounting_line(self.nominal.tool_point(), self.robot.tool_point())

    @property
    def loss(self) -> str:
        return self.options.loss

    @property
    def base(self) -> str:
        return self.options.base

    @property
    def outlier_z(self) -> float:
        """The outlier limit in robust σ for this many poses (:meth:`Thresholds.outlier_limit`)."""
        return self.options.thresholds.outlier_limit(len(self.residuals))

    def record(self) -> dict:
        """What a calibrated robot file keeps beside the model: the parameter covariance and training σ
        (``uncertainty()``), the training joint ranges, the nominal parameter values, the options and
        the poses of use, so the fit can be reproduced (``kincal report``)."""
        unc = self.uncertainty().to_dict()  # with the envelope: where the model was fitted (joint ranges)
        unc["envelope"]["joints"] = list(self.robot.joint_names)
        out = {**unc, "nominal": self.nominal.params.as_dict(), "options": self.options.to_dict(),
               "training_error": self.stats_after.mean}
        if self.use_q is not None:
            out["use_q"] = self.use_q.tolist()
        return out

    def uncertainty(self) -> ModelUncertainty:
        """The calibrated model's parameter covariance, with the median predicted σ at the training
        poses (for prediction σ and extrapolation warnings where the model is used)."""
        ok = np.isfinite(np.array([self.std[n] for n in self.names]))
        names = tuple(n for n, k in zip(self.names, ok) if k)
        return ModelUncertainty.from_fit(self.robot, names, self.covariance[np.ix_(ok, ok)], self.measurements.q)

    def pose_records(self) -> list[dict]:
        """Per pose: input row, error vector and norm (m), robust z-score, outlier flag."""
        norms = np.linalg.norm(self.residuals, axis=1)
        return [{"row": int(r), "error": e.tolist(), "norm": float(n), "z": float(zi), "outlier": bool(zi > self.outlier_z)}
                for r, e, n, zi in zip(self.measurements.rows, self.residuals, norms, self.pose_z)]

    def to_dict(self) -> dict:
        return {
            "robot": self.robot.name,
            "converged": self.converged,
            "message": self.message,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "time_s": self.time_s,
            "loss": self.loss,
            "base": self.base,
            "options": self.options.to_dict(),
            "n_poses": int(self.residuals.shape[0]),
            "sigma": self.sigma,
            "estimated": list(self.names),
            "not_estimated": [n for n in self.robot.params.names if n not in set(self.names)],
            "estimates": self.estimates,
            "corrections": self.corrections,
            "std": {k: (v if np.isfinite(v) else None) for k, v in self.std.items()},  # None: undetermined
            "correlation": self.correlation.tolist(),
            "before": self.stats_before.to_dict(),
            "after": self.stats_after.to_dict(),
            "identifiability": self.identifiability.to_dict(),
            "history": list(self.history),
            "verdict": self.verdict.to_dict(),
            "structure": self.robot.structure,
            "error_model": self.robot.error_model,
            "error_model_choice": None if self.error_model_choice is None else self.error_model_choice.to_dict(),
            "error_model_notes": list(self.error_model_notes),
            "drift": self.drift,
            "diagnosis": None if self.diagnosis is None else self.diagnosis.to_dict(),
            "rejected_rows": list(self.rejected_rows),
            "rejected_sessions": list(self.rejected_sessions) or None,
            "mounting": None if not self.mounting else {
                "tool_point": self.robot.tool_point().tolist(), "declared_tool_point": self.nominal.tool_point().tolist(),
                "text": self.mounting},
            "compliance": self.robot.compliances(),  # rad/(N·m) per joint
            "weakly_determined": dict(self.weak),  # held at nominal (m or rad: the σ the data gave them)
            "prior": dict(self.prior),  # learned prior σ per group (m or rad)
            "poses": self.pose_records(),
        }

    def __str__(self) -> str:
        kinds = dict(zip(self.robot.params.names, self.robot.params.kinds))
        status = "converged" if self.converged else "NOT CONVERGED"
        lines = [
            f"calibration of {self.robot.name}: {status} ({self.message}) in {self.iterations} iterations, "
            f"{self.time_s * 1e3:.1f} ms; {len(self.names)} parameters from {self.residuals.shape[0]} poses, "
            f"base {self.base}, loss {self.loss}",
            f"{'parameter':<12} {'estimate':>16} {'correction':>16} {'std':>14}",
        ]
        for n in self.names:
            k = kinds[n]
            sd = display(self.std[n], k).lstrip("+") if np.isfinite(self.std[n]) else "undetermined"
            lines.append(f"{n:<12} {display(self.estimates[n], k):>16} {display(self.corrections[n], k):>16} "
                         f"{sd:>14}")
        noise = noise_level(self.measurements.std, self.options.thresholds)
        lines += [f"residual sigma per axis: {self.sigma * MM:.4f} mm (tracker noise for the verdict "
                  f"{noise[0] * MM:.3g} mm: {noise[1]})",
                  f"before (nominal, frame and target point registered): {self.stats_before}", f"after:  {self.stats_after}"]
        if self.mounting:
            lines.append(f"mounting: {self.mounting}")
        if self.weak:
            lines.append(weak_note(self.robot, self.weak))
        lines += prior_lines(self.prior)
        if self.rejected_rows:
            lines.append(f"left out as outliers (more than {self.outlier_z:.3g} robust σ off a robust refit): "
                         f"{self.rejected_text()}")
        if self.error_model_choice is not None:
            lines.append(str(self.error_model_choice))
        lines += [f"compliance of {j}: {c:.3g} rad/(N·m)" for j, c in self.robot.compliances().items()]
        lines += [f"note: {n}" for n in self.error_model_notes]
        if self.drift:
            lines.append("drift over the session (first to last pose): " + ", ".join(
                f"{a} {d['value'] * MM:+.4f} ± {d['std'] * MM:.4f} mm" for a, d in self.drift.items()))
        lines.append(str(self.verdict))
        return "\n".join(lines)


EXACT = 1e-9  # m: a validation error below this is round-off (no noise, an exact model)


def e_statistics(point_errors: dict) -> dict[str, tuple[float, float, float]]:
    """Per model the paper's Table 8 statistics of e (the signed average of the three axis errors)
    over the validation points: max |e|, mean |e|, std e (m)."""
    out = {}
    for k, err in point_errors.items():
        e = np.asarray(err).mean(axis=1)
        out[k] = (float(np.max(np.abs(e))), float(np.mean(np.abs(e))), float(np.std(e, ddof=1)))
    return out
