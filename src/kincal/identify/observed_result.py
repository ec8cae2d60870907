"""The result of a fit from observation sets (:func:`kincal.identify.fit_observations`): the
calibrated robot, the set-up parameters, σ, per-set statistics (mm, mrad), the whitened residual per
kind, the verdict, printable and as a record for the calibrated robot file."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..analysis.identifiability import Identifiability
from ..analysis.uncertainty import ModelUncertainty
from ..models.robot import TOOL_NAMES, Robot
from ..observe.observations import Wrapper
from .._atomic import write_text_atomic
from .._csv import listed
from ..units import MM, MRAD, display
from .relevance import prior_lines
from .diagnosis import Diagnosis
from .observed_verdict import MIN_SAMPLES, component_kinds, sample_norms
from .verdict import Verdict, mounting_line, robust_z


@dataclass(frozen=True, eq=False)
class ObservationFit:
    """A calibration from observation sets: the calibrated robot, the robot parameters fitted
    (``names``), the nuisance parameters' values, σ of both (m or rad; a posteriori, σ̂² = χ²/dof),
    the identifiability of the stacked problem, the gauge freedoms, per-set statistics before and
    after (mm, mrad), the whitened residual RMS (1 when the stated σ are right), the verdict and the
    learned prior's σ per group (``prior``; with it, ``std`` and ``covariance`` are posterior).
    ``nominal`` is the model as given (its declared base: corrections are from it, and commands are
    computed in its base frame); ``registered`` the same with its measurement frame registered to the
    data, where the fit began; ``before`` the same with the target point registered too, the model
    the "before" figures are of (they do not depend on where the target was declared)."""

    robot: Robot
    nominal: Robot
    registered: Robot
    before: Robot
    names: tuple[str, ...]
    nuisance: dict
    std: dict
    identifiability: Identifiability
    gauge: tuple[str, ...]
    stats_before: tuple[dict, ...]
    stats: tuple[dict, ...]
    whitened_rms: float
    covariance: np.ndarray
    verdict: Verdict
    converged: bool
    iterations: int
    observations: tuple = ()
    weak: dict = dataclasses.field(default_factory=dict)  # kept nominal: name -> σ the data gave it (m or rad)
    prior: dict = dataclasses.field(default_factory=dict)  # learned prior σ per group (m or rad); {}: none
    whitened: dict = dataclasses.field(default_factory=dict)  # whitened RMS per kind ("pose rotation": 1.3)
    model_error: dict = dataclasses.field(default_factory=dict)  # s per kind beside the stated σ (m or rad)
    outliers: tuple = ()  # per set, the indices of its samples beyond the outlier limit
    rejected: dict = dataclasses.field(default_factory=dict)  # left out as outliers: file -> its rows
    notes: tuple[str, ...] = ()  # what the fit changed on its way (an error-model term dropped)
    whitened_residual: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))  # (M,) by the stated σ
    diagnosis: Diagnosis | None = None  # the differential diagnosis of a doubtful fit, if run
    evaluations: int = 0  # evaluations of the stacked residual (a particle swarm's included)
    message: str = ""  # how the last solver stopped
    history: tuple[float, ...] = ()  # particle swarm: best mean squared residual per iteration
    free: tuple[str, ...] = ()  # the columns fitted (robot and set-up parameters): the order of ``covariance``

    def to_dict(self) -> dict:
        return {"robot": self.robot.name, "fitted": list(self.names),
                "estimates": {n: float(self.robot.params[n]) for n in self.names},
                "corrections": {n: float(self.robot.params[n] - self.nominal.params[n]) for n in self.names},
                "nuisance": {k: float(v) for k, v in self.nuisance.items()},
                "std": {k: (float(v) if np.isfinite(v) else None) for k, v in self.std.items()},
                "gauge": list(self.gauge), "weakly_determined": {k: float(v) for k, v in self.weak.items()},
                "prior": {k: float(v) for k, v in self.prior.items()},
                "identifiability": self.identifiability.to_dict(),
                "before": list(self.stats_before), "after": list(self.stats), "whitened_rms": self.whitened_rms,
                "whitened_rms_per_kind": dict(self.whitened), "model_error": dict(self.model_error),
                "rejected_rows": {k: list(v) for k, v in self.rejected.items()}, "notes": list(self.notes),
                "diagnosis": None if self.diagnosis is None else self.diagnosis.to_dict(),
                "error_model": self.robot.error_model,
                "verdict": self.verdict.to_dict(), "converged": self.converged, "iterations": self.iterations}

    def record(self) -> dict:
        """What a calibrated robot file keeps beside the model: the robot parameters' covariance (for
        prediction σ), the nominal values, the set-up parameters and the statistics."""
        k = [i for i, n in enumerate(self.identifiability.identifiable) if n in set(self.names)]
        q = np.concatenate([o.q for o in self.observations])
        unc = ModelUncertainty.from_fit(self.robot, self.names, self.covariance[np.ix_(k, k)], q).to_dict()
        unc["envelope"]["joints"] = list(self.robot.joint_names)
        return {**unc, "nominal": self.nominal.params.as_dict(), "observations": list(self.stats),
                "nuisance": {n: float(v) for n, v in self.nuisance.items()}, "setup": self.setup(),
                "weakly_determined": {n: float(v) for n, v in self.weak.items()}}

    def setup(self) -> dict:
        """The set-up the next measurement of this robot shares, in absolute form: the 6-D probe's
        rotation on the flange (3, 3) and the marker points on the flange (m), as fitted."""
        out: dict = {"markers": {n: float(v) for n, v in self.nuisance.items() if n.startswith("marker[")}}
        poses = [_unwrapped(o) for o in self.observations if o.kind == "pose"]
        if poses:
            rot = np.array([self.nuisance[n] for n in ("target.rx", "target.ry", "target.rz")])
            out["target_rotation"] = poses[0].target(rot).tolist()
        return out


    def sample_table(self) -> list[dict]:
        """Per sample of every set: file, row, kind, position error (mm: the norm of the sample's
        position residuals, all its seen markers together), rotation error (mrad; poses), the norm
        of its residual whitened by the stated σ, its robust z within the set and the outlier flag
        (the verdict's rule)."""
        out, start = [], 0
        for obs, bad in zip(self.observations, self.outliers or ((),) * len(self.observations)):
            names, nuis0, _ = obs.nuisance(self.robot)
            r = obs.evaluate(self.robot, self.robot.params.values,
                             np.array([self.nuisance.get(n, v) for n, v in zip(names, nuis0)]))[0]
            labels, kinds = component_kinds([obs])
            owner, rot = obs.sample_rows(), np.array([kinds[k] == "pose rotation" for k in labels], bool)
            per = lambda rows: np.sqrt(np.bincount(owner[rows], r[rows] ** 2, minlength=len(obs)))  # noqa: E731
            pos, ang = per((owner >= 0) & ~rot), per((owner >= 0) & rot)
            norms = sample_norms([obs], self.whitened_residual[start:start + r.size])[0]
            start += r.size
            z = robust_z(norms) if len(obs) >= MIN_SAMPLES else np.zeros(len(obs))
            flagged = set(int(i) for i in bad)
            out += [{"file": obs.source, "row": int(obs.rows[i]), "kind": obs.kind, "position_mm": float(pos[i] * MM),
                     "rotation_mrad": float(ang[i] * MRAD) if rot.any() else None, "whitened": float(norms[i]),
                     "robust_z": float(z[i]), "outlier": i in flagged} for i in range(len(obs))]
        return out

    def write_residuals(self, path: str) -> None:
        """:meth:`sample_table` as CSV (atomically): mm, mrad, whitened norms, robust z, outlier yes/no."""
        lines = ["file,row,kind,position_error_mm,rotation_error_mrad,whitened_norm,robust_z,outlier"]
        for s in self.sample_table():
            rot = "" if s["rotation_mrad"] is None else f"{s['rotation_mrad']:.6g}"
            lines.append(",".join([_cell(s["file"]), str(s["row"]), s["kind"], f"{s['position_mm']:.6g}", rot,
                                   f"{s['whitened']:.6g}", f"{s['robust_z']:.4g}", "yes" if s["outlier"] else "no"]))
        write_text_atomic(path, "\n".join(lines) + "\n")

    def drift_lines(self) -> list[str]:
        """Each set's fitted instrument drift over its rows (first to last sample), mm with σ."""
        sets = dict.fromkeys(n.rsplit(".", 1)[0] for n in self.nuisance if n.startswith("drift["))
        return [f"{s} over the file (first to last sample): " + ", ".join(
            f"{a} {self.nuisance[f'{s}.{a}'] * MM:+.4f} ± {self.std.get(f'{s}.{a}', np.inf) * MM:.4f} mm"
            for a in "xyz" if f"{s}.{a}" in self.nuisance) for s in sets]

    @property
    def mounting(self) -> str:
        """Where the data put the target against the declared tool point, when the fit moved it; ''
        otherwise (a mounting result, not a robot error)."""
        if not self.robot.has_tool_point or not set(TOOL_NAMES) & set(self.names):
            return ""
        return mounting_line(self.nominal.tool_point(), self.robot.tool_point())

    def parameter_lines(self) -> list[str]:
        """The fitted robot parameters as a table: estimate, correction from nominal, σ (mm, deg)."""
        kinds = dict(zip(self.robot.params.names, self.robot.params.kinds))
        lines = [f"{'parameter':<22} {'estimate':>16} {'correction':>16} {'σ':>14}"]
        for n in self.names:
            k, sd = kinds[n], self.std.get(n, np.inf)
            lines.append(f"{n:<22} {display(self.robot.params[n], k):>16} "
                         f"{display(self.robot.params[n] - self.nominal.params[n], k):>16} "
                         f"{display(sd, k).lstrip('+') if np.isfinite(sd) else 'undetermined':>14}")
        return lines

    def weak_lines(self) -> list[str]:
        """The parameters kept nominal for want of information, each with the σ the data gave it."""
        kinds = dict(zip(self.robot.params.names, self.robot.params.kinds))
        return [f"{n} ±{v * MM:.1f} mm" if kinds[n] == "length" else f"{n} ±{v * MRAD:.0f} mrad"
                for n, v in self.weak.items()]

    def held_out(self, obs, robot: Robot | None = None) -> dict:
        """Statistics of a held-out set (same types) under the calibrated robot (or ``robot``, e.g. the
        nominal one): set-up parameters the fit shares with it (a target's rotation, markers) at their
        fitted values; a pose set also takes the training target's start rotation."""
        robot = self.robot if robot is None else robot
        poses = [_unwrapped(o) for o in self.observations if o.kind == "pose"]
        if obs.kind == "pose" and poses:
            obs = dataclasses.replace(obs, target_rotation=poses[0].target_rotation)
        else:
            obs = obs.prepare(robot)
        names, start, _ = obs.nuisance(robot)
        nuis = np.array([self.nuisance.get(n, v) for n, v in zip(names, start)])
        return obs.stats(robot, robot.params.values, nuis)

    def __str__(self) -> str:
        lines = [f"calibration of {self.robot.name} from {', '.join(sorted({s['type'] for s in self.stats}))} data"
                 + ("" if self.robot.error_model == "geometric" else f" ({self.robot.error_model} error model)")
                 + f": {'converged' if self.converged else 'NOT converged'} in {self.iterations} iterations; "
                 f"{len(self.names)} robot and {len(self.nuisance)} set-up parameters",
                 f"whitened residual RMS {self.whitened_rms:.3g} (1 when the stated σ are right): "
                 + ", ".join(f"{k} {v:.3g}" for k, v in self.whitened.items())]
        for b, a in zip(self.stats_before, self.stats):
            lines.append(f"  {a['type']} ({a['source']}): {stat_line(b)}  →  {stat_line(a)}")
        lines += [f"left out as outliers (a robust refit put them beyond the outlier limit): {src} row(s) {listed(rows)}"
                  for src, rows in self.rejected.items()]
        lines += [f"error model {self.robot.error_model}: " + note for note in self.notes]
        lines += self.drift_lines()
        if self.model_error:
            lines.append("weighted by 1/(σ² + s²), s what the model leaves beyond the stated σ: " + ", ".join(
                f"{k} {v * MRAD:.3g} mrad" if k.endswith("rotation") else f"{k} {v * MM:.3g} mm"
                for k, v in self.model_error.items()))
        lines += self.parameter_lines()
        if self.mounting:
            lines.append(f"mounting: {self.mounting}")
        if self.gauge:
            lines.append(f"not seen by these data (gauge freedoms, kept at their values): {', '.join(self.gauge)}")
        if self.weak:
            lines.append(f"kept at nominal, the data determine them worse than a real robot's error (10 mm, 2 deg): "
                         f"{', '.join(self.weak_lines())}")
        lines += prior_lines(self.prior)
        lines.append(f"verdict: {self.verdict.status.upper()}")
        lines += [f"  {r.level}: {r.message}" for r in self.verdict.reasons]
        return "\n".join(lines)


def _unwrapped(obs):
    """The set under its wrappers (a session's frame, a drifting instrument)."""
    while isinstance(obs, Wrapper):
        obs = obs.inner
    return obs


def _cell(text: str) -> str:
    """A CSV cell: quoted when it holds a comma or a quote."""
    return f'"{text.replace(chr(34), chr(34) * 2)}"' if "," in text or '"' in text else text


def stat_line(s: dict) -> str:
    """One set's statistics (``stats()`` of an observation type) in a few words, mm and mrad."""
    if "mean_abs_mm" in s:
        return f"mean |p − point| {s['mean_abs_mm']:.4f} mm"
    rot = f", mean {s['mean_mrad']:.4f} mrad" if "mean_mrad" in s else ""
    return f"mean {s['mean_mm']:.4f} mm{rot}"


def trained_setup(record: dict | None, where: str = "calibration record") -> tuple[dict, dict]:
    """From a calibration record's ``setup``: the set-up parameters to hold (name -> value) and the
    anchors (a 6-D probe's rotation) a held-out file is judged with, so its probe and markers stay as
    trained; ({}, {}) for a record without one. ``where`` names the file in an error."""
    setup = (record or {}).get("setup")
    if not isinstance(setup, dict):
        return {}, {}
    held = {str(k): float(v) for k, v in (setup.get("markers") or {}).items()}
    if "target_rotation" not in setup:
        return held, {}
    R = np.asarray(setup["target_rotation"], float)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6):
        raise ValueError(f"{where}: the calibration record's setup.target_rotation must be a 3x3 rotation matrix "
                         f"(edited by hand?); calibrate again to write it")
    return {**held, "target.rx": 0.0, "target.ry": 0.0, "target.rz": 0.0}, {"target_rotation": R}
