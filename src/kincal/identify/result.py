"""The one result of a calibration (:func:`kincal.calibrate`, :func:`kincal.identify.fit_observations`):
frozen, printable in mm/deg/mrad, ``to_dict`` in SI, ``record`` for the calibrated robot file."""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .._csv import listed
from .._frozen import freeze_arrays, read_only
from ..analysis.identifiability import Identifiability
from ..analysis.uncertainty import ModelUncertainty
from ..io.measurements import Measurements, write_csv
from ..models.robot import TOOL_NAMES, Robot
from ..observe.joint import in_cartesian
from ..observe.observations import Observation, Wrapper
from ..observe.sessions import InSession
from ..units import MM, MRAD, display, in_display, number
from .diagnosis import Diagnosis
from .judge import MIN_SAMPLES, component_kinds, sample_norms, verdict_of
from .options import FitOptions
from .positions import EvaluationStats, kept_positions
from .relevance import prior_lines
from ..analysis.changes import Repeat
from .select import ErrorModelChoice
from .verdict import Verdict, mounting_line, noise_level, robust_z, undetermined_mounting_line
from .weak import weak_note

GIMBAL_NEAR = np.radians(5.0)  # the base frame's middle angle this near ±90°: its outer angles turn alike
PRIOR_HELD = 1e-7  # m or rad: a σ this small under a learned prior is the prior holding the parameter, not data
FRAME_CONVENTION = ("the robot's base frame in that file's measurement frame, as base.* is in the first file's: a point p "
                    "in the robot's frame is R·p + t there, t = (x, y, z), R = Rz(rz)·Ry(ry)·Rx(rx) (rx about x first, "
                    "then ry about y, then rz about z, all about the measurement frame's fixed axes); a file measured in "
                    "a frame moved so that its points are R'·p + t' has R = R'·R_base, t = R'·t_base + t'")


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A calibration from measurement sets of any kinds, by the one fit.

    Returned by :func:`calibrate`, :func:`calibrate_sessions` and :func:`fit_observations`; frozen,
    printable in mm/deg/mrad, :meth:`to_dict` in SI, :meth:`record` for the calibrated robot file. Data
    fitted by :func:`calibrate` also have the position view (``measurements``, ``residuals``,
    ``stats_before``, ``stats_after``…).

    Parameters
    ----------
    robot : Robot
        The calibrated robot (save it with ``kincal.save_robot``).
    nominal : Robot
        The model as given (corrections are from it; commands are in its base frame).
    registered : Robot
        The same with its measurement frame registered to the data: where the fit began.
    before : Robot
        The same with the target point registered too, its frame with the markers' points where markers were
        measured (``before_setup``): what "before" calibration is judged on.
    names : tuple of str
        The robot parameters fitted; every other kept its value.
    nuisance : dict of str to float
        The set-up parameters' values (frames of later sessions, a probe's rotation, markers, sockets,
        planes, drift), m or rad.
    std : dict of str to float
        1-σ of robot and set-up parameters, m or rad (a posteriori, or posterior with a learned
        ``prior``); inf: not determined.
    identifiability : Identifiability
        What the data determine among the robot and set-up parameters (gauge freedoms left out).
    gauge : tuple of str
        Robot parameters no set sees (gauge freedoms), kept at their values.
    per_set_before : tuple of dict
        Each set's statistics (m, rad) under the ``before`` model.
    per_set : tuple of dict
        Each set's statistics (m, rad) after the fit.
    whitened_rms : float
        RMS of the residual whitened by the stated σ (1 when they are right).
    covariance : ndarray, shape (F, F)
        Covariance over ``free`` (robot and set-up parameters fitted, in that order), SI.
    converged : bool
        Whether the last solver run converged (a particle swarm alone, which has no test of convergence: that it
        ran its iterations; :attr:`solver_state` says "stopped").
    iterations : int
        Iterations of every solver run, summed: a fit runs Levenberg–Marquardt several times (again after a
        parameter is kept nominal, the noise weights re-estimated, a robust reweighting, the identifiable set
        judged anew), then the learned prior's fit, each run at most ``options.max_iter`` iterations.
    observations : tuple of Observation, optional
        The sets fitted (outliers left out).
    weak : dict of str to float, optional
        Parameters kept nominal because the data determine them too weakly: name to the σ the data gave
        it, m or rad.
    prior : dict of str to float, optional
        The learned prior σ per group, m or rad (empty: no prior).
    whitened : dict of str to float, optional
        The whitened RMS per kind of component (e.g. ``"pose rotation"``).
    model_error : dict of str to float, optional
        Per kind, what the model leaves beyond the stated σ, m or rad.
    outliers : tuple of ndarray, optional
        Per set, the indices of the samples beyond the outlier limit.
    rejected : dict of str to tuple of int, optional
        File to the rows left out as outliers (``reject_outliers``).
    notes : tuple of str, optional
        What the fit changed on its way (an error-model term dropped, a refit).
    whitened_residual : ndarray, shape (M,), optional
        The residual whitened by the stated σ (a joint-space sample by its residual's covariance after the fit,
        the joints' σ and the measured σ through the inverse kinematics: its norm is √(rᵀ V⁻¹ r)).
    diagnosis : Diagnosis or None, optional
        The differential diagnosis of a doubtful fit, if run.
    evaluations : int, optional
        Evaluations of the stacked residual (a particle swarm's included).
    runs : int, optional
        Solver runs the ``iterations`` are summed over (a particle swarm: one).
    message : str, optional
        How the last solver stopped.
    history : tuple of float, optional
        Particle swarm: the best mean squared residual per iteration.
    free : tuple of str, optional
        The robot and set-up parameters fitted, in the order of ``covariance``.
    options : FitOptions, optional
        The options used (to reproduce the fit).
    time_s : float, optional
        Wall time of the calibration, s.
    error_model_choice : ErrorModelChoice or None, optional
        With ``error_model="auto"``: the blocked cross-validation comparison.
    use_q : ndarray, shape (M, n), optional
        Joint values where the model will be used (the prediction-σ guard), rad (m for a prismatic
        joint); None: not given.
    data : tuple of Measurements, optional
        The position data as given when fitted by :func:`calibrate` (one per session); empty for a fit
        of observation sets.
    repeat : Repeat or None, optional
        What a repeat calibration on other poses would differ by (for ``compare`` and ``check``).
    before_setup : dict of str to float, optional
        The markers' points registered with ``before`` (``marker[<name>].x/y/z``, m): the set-up its figures, and a
        held-out set's in the training frame, are judged with; empty without markers.

    Examples
    --------
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> res = kincal.calibrate(robot, kincal.simulate(true, robot.sample_joints(30, seed=2), seed=3),
    ...                        diagnose=False)
    >>> res.names[:6] == robot.base_params()  # the measurement frame is fitted too
    True
    >>> found, sd = res.corrections["j2.a"], res.std["j2.a"]  # m
    >>> truth = true.params["j2.a"] - robot.params["j2.a"]
    >>> f"j2.a {found * 1e3:+.3f} ± {sd * 1e3:.3f} mm (true {truth * 1e3:+.3f})"
    'j2.a +0.333 ± 0.004 mm (true +0.328)'
    >>> res.residuals.shape, res.covariance.shape
    ((30, 3), (26, 26))
    >>> list(res.weak)  # kept nominal: 30 poses determine it too weakly
    ['j5.theta']
    >>> print(res.verdict)
    verdict: GOOD
    """

    robot: Robot
    nominal: Robot
    registered: Robot
    before: Robot
    names: tuple[str, ...]
    nuisance: dict
    std: dict
    identifiability: Identifiability
    gauge: tuple[str, ...]
    per_set_before: tuple[dict, ...]
    per_set: tuple[dict, ...]
    whitened_rms: float
    covariance: np.ndarray
    converged: bool
    iterations: int
    observations: tuple = ()
    weak: dict = field(default_factory=dict)  # kept nominal: name -> σ the data gave it (m or rad)
    prior: dict = field(default_factory=dict)  # learned prior σ per group (m or rad); {}: none
    whitened: dict = field(default_factory=dict)  # whitened RMS per kind ("pose rotation": 1.3)
    model_error: dict = field(default_factory=dict)  # s per kind beside the stated σ (m or rad)
    outliers: tuple = ()
    rejected: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()  # what the fit changed on its way (an error-model term dropped)
    whitened_residual: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (M,) by the stated σ
    diagnosis: Diagnosis | None = None  # the differential diagnosis of a doubtful fit, if run
    evaluations: int = 0  # evaluations of the stacked residual (a particle swarm's included)
    runs: int = 0  # solver runs the iterations were summed over (a particle swarm: one)
    message: str = ""  # how the last solver stopped
    history: tuple[float, ...] = ()  # particle swarm: best mean squared residual per iteration
    free: tuple[str, ...] = ()
    options: FitOptions = field(default_factory=FitOptions)  # the options used (to reproduce the fit)
    time_s: float = 0.0
    error_model_choice: ErrorModelChoice | None = None  # error_model "auto": the blocked-CV comparison
    use_q: np.ndarray | None = None  # (M, n) where the model will be used (the prediction-σ guard)
    data: tuple[Measurements, ...] = ()
    repeat: Repeat | None = None  # what a repeat calibration on other poses would differ by (compare, check)
    before_setup: dict = field(default_factory=dict)  # the markers' points registered with ``before`` (name -> m)

    def __post_init__(self) -> None:
        freeze_arrays(self)  # the arrays it hands out: what it prints cannot drift from what it computed

    @functools.cached_property
    def verdict(self) -> Verdict:
        """Good, suspect or refused, with reasons (:func:`kincal.identify.judge.verdict_of`)."""
        return verdict_of(self)

    # --- the position view (data fitted by kincal.calibrate) ---

    @functools.cached_property
    def _kept(self) -> tuple[Measurements, np.ndarray, dict | None]:
        if not self.data:
            raise ValueError("a fit of observation sets has no position view (measurements, residuals): use "
                             "per_set and sample_table()")
        meas, err, drift = kept_positions(self, list(self.data))
        return meas, read_only(err), drift

    @property
    def measurements(self) -> Measurements:
        """The poses fitted (outliers left out) in the first session's frame."""
        return self._kept[0]

    @property
    def residuals(self) -> np.ndarray:
        """(N, 3) measured − predicted (m) at :attr:`measurements` (a fitted drift taken out)."""
        return self._kept[1]

    @property
    def drift(self) -> dict | None:
        """With ``drift``: per axis x/y/z the instrument's drift over the session (m) and its σ."""
        return self._kept[2]

    @property
    def pose_z(self) -> np.ndarray:
        """(N,) robust z-score of each pose's error norm."""
        return robust_z(np.linalg.norm(self.residuals, axis=1))

    @property
    def sigma(self) -> float:
        """The residual σ per axis (m), by the data's relative σ when given."""
        err, std = self.residuals, self.measurements.std
        stated, scale = (1.0, 1.0) if std is None else (std / float(np.median(std)), float(np.median(std)))
        return float(np.sqrt(np.sum((err / stated) ** 2) / max(err.size - len(self.names), 1)) * scale)

    @property
    def stats_before(self) -> EvaluationStats:
        """Position errors of the "before" model (frame and target point registered) on the poses; with sessions
        each in its own frame, each set judged in its own frame registered, as its per-set figures are (the merged
        figure judged a later session in the frame the fit found for it: 0.6247 mm beside per-session 0.6002 and
        0.6457)."""
        meas = self.measurements
        if not any(isinstance(o, InSession) for o in self.observations):
            return EvaluationStats.from_errors(meas.xyz - self.before.forward(meas.q))
        from .stacked import session_before  # (stacked makes results: imported when a result is read)
        errors = []
        for obs in self.observations:
            found = (obs.inner if isinstance(obs, InSession) else obs).positions()  # a session's in its own frame
            if found is not None:
                errors.append(found[1] - session_before(self.before, obs).forward(found[0]))
        return EvaluationStats.from_errors(np.concatenate(errors))

    @property
    def stats_after(self) -> EvaluationStats:
        return EvaluationStats.from_errors(self.residuals)

    @property
    def outlier_z(self) -> float:
        """The outlier limit in robust σ for this many poses (:meth:`Thresholds.outlier_limit`)."""
        return self.options.thresholds.outlier_limit(len(self.residuals))

    @property
    def rejected_rows(self) -> tuple[int, ...]:
        return tuple(r for rows in self.rejected.values() for r in rows)

    def rejected_text(self) -> str:
        """'row(s) 40 of grid.csv' (several files: each file's rows after its name); '' when none."""
        return "; ".join(f"row(s) {listed(rows)} of {src}" for src, rows in self.rejected.items())

    def pose_records(self) -> list[dict]:
        """Per pose: input row, error vector and norm (m), robust z-score, outlier flag."""
        norms = np.linalg.norm(self.residuals, axis=1)
        return [{"row": int(r), "error": e.tolist(), "norm": float(n), "z": float(zi), "outlier": bool(zi > self.outlier_z)}
                for r, e, n, zi in zip(self.measurements.rows, self.residuals, norms, self.pose_z)]

    # --- every kind ---

    @property
    def estimates(self) -> dict[str, float]:
        return {n: float(self.robot.params[n]) for n in self.names}

    @property
    def compliances(self) -> dict[str, float | None]:
        """Per joint with a compliance term: the fitted compliance, rad/(N·m); None for one kept at its nominal 0
        (not estimated: not identifiable, or determined worse than a real robot's error), which is no value."""
        return {j: c if f"{j}.compliance" in self.names else None for j, c in self.robot.compliances().items()}

    @property
    def units(self) -> dict[str, str]:
        """The SI unit of each fitted robot parameter's estimate, correction and σ: "m", "rad", "1" (a ratio), and
        what a value is per beyond it ("rad, deflection at 100 N·m" for a compliance, whose rad/(N·m) are
        ``compliances``; "1, per unit of temperature" for a thermal growth rate)."""
        si, per = {"length": "m", "angle": "rad", "ratio": "1"}, self.robot.value_units()
        kinds = dict(zip(self.robot.params.names, self.robot.params.kinds))
        return {n: si[kinds[n]] + (f", {per[n]}" if n in per else "") for n in self.names}

    @property
    def corrections(self) -> dict[str, float]:
        """Final − nominal (the model as given) per fitted robot parameter (m or rad)."""
        return {n: float(self.robot.params[n] - self.nominal.params[n]) for n in self.names}

    @property
    def correlation(self) -> np.ndarray:
        """(K, K) correlation of the fitted robot parameters, in the order of ``names``."""
        at = [self.free.index(n) for n in self.names]
        sd = np.array([self.std[n] for n in self.names])
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = np.where(np.isfinite(sd[:, None] * sd), self.covariance[np.ix_(at, at)] / np.outer(sd, sd), 0.0)
        np.fill_diagonal(corr, 1.0)
        return corr

    @property
    def mounting(self) -> str:
        """Where the data put the target against the declared tool point, when the fit determined it; that the
        data do not determine it, when it stands in a design frame whose gauge freedom the fit holds
        (:attr:`mounting_gauge`); '' otherwise (a mounting result, not a robot error)."""
        if not self.robot.has_tool_point:
            return ""
        if self.mounting_gauge[0]:
            return undetermined_mounting_line(*self.mounting_gauge)
        if not any(np.isfinite(self.std.get(n, np.inf)) for n in TOOL_NAMES if n in self.names):
            return ""
        return mounting_line(self.nominal.tool_point(), self.robot.tool_point())

    @property
    def mounting_gauge(self) -> tuple[str, tuple[str, ...]]:
        """The design frame the tool point stands in (:meth:`Robot.frame_freedoms`, in words) with the parameters
        that hold its gauge freedom in this fit, when it has one: the tool point moves with that frame, so its
        coordinates are the held parameters' choice, not the data's; ``("", ())`` for none (an arm's flange)."""
        held = self.identifiability.frames
        for what, members, _ in self.robot.frame_freedoms():
            holding = tuple(n for n in held if n in set(members))
            if holding and set(TOOL_NAMES) & set(members):
                return what, holding
        return "", ()

    def uncertainty(self) -> ModelUncertainty:
        """The calibrated model's parameter covariance, with the median predicted σ at the training
        poses (for prediction σ and extrapolation warnings where the model is used); computed once."""
        return self._uncertainty

    @functools.cached_property
    def _uncertainty(self) -> ModelUncertainty:
        # what the covariance covers: a parameter a swarm left undetermined too (σ inf), moving with those it acts like
        ok = [n for n in self.names if np.isfinite(self.std[n]) or self.covariance[self.free.index(n)][
            self.free.index(n)] > 0]
        at = [self.free.index(n) for n in ok]
        q = np.concatenate([o.q for o in self.observations])
        return ModelUncertainty.from_fit(self.robot, tuple(ok), self.covariance[np.ix_(at, at)], q)

    @functools.cached_property
    def correction_scales(self) -> dict[str, tuple[float, str]]:
        """The robot's :meth:`~kincal.Robot.correction_scales` at the data's poses: per parameter whose value is not
        the correction it makes (a compliance, the deflection at 100 N·m), what one unit of it makes there, and
        where (its joint's largest load in the data); what the verdict and the weak-parameter hold judge by."""
        q = [o.q for o in self.observations]
        return self.nominal.correction_scales(np.concatenate(q)) if q else {}

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
        at = self.robot.params.as_dict()
        nominal = self.nominal.params.as_dict()
        registered = [n for n in kept if n in nominal and at[n] != nominal[n]]  # a base frame's, where it was put
        kept = [n for n in kept if n not in registered]
        if kept:
            head += ("; " if moved else "") + f"{', '.join(kept)} not estimated (kept nominal)"
        if registered:
            head += (("; " if moved or kept else "") + f"{', '.join(registered)} not estimated (held where the "
                     f"measurement frame's registration put it: the data cannot tell it from the parameters it "
                     f"acts like, whose values hold only the rest)")
        if self.weak:  # identifiable, yet held: the count above includes them
            head += (f"; {', '.join(self.weak)} identifiable but kept nominal too (determined worse than a real "
                     f"robot's error)")
        return head + ". Each acts like the estimated ones shown:\n" + "\n".join(ident.confound_lines("  "))

    def record(self) -> dict:
        """What a calibrated robot file keeps beside the model: the robot parameters' covariance and
        the training joint ranges (for prediction σ and extrapolation warnings), the nominal values,
        the options, the set-up to share with the next measurement, each set's statistics and the
        poses of use, so the fit can be reproduced (``kincal report``)."""
        unc = self.uncertainty().to_dict()
        unc["envelope"]["joints"] = list(self.robot.joint_names)
        out = {**unc, "nominal": self.nominal.params.as_dict(), "options": self.options.to_dict(),
               "observations": list(self.per_set), "nuisance": {n: float(v) for n, v in self.nuisance.items()},
               "setup": self.setup(), "weakly_determined": {n: float(v) for n, v in self.weak.items()}}
        if self.data:
            out["training_error"] = self.stats_after.mean
        out["verdict"] = self.verdict.status  # what the commands made with this file carry
        nominal = self.nominal.params.as_dict()  # "before": its frame and target point registered on the data
        out["before_mounting"] = {n: float(v) for n, v in self.before.params.as_dict().items() if v != nominal[n]}
        if self.before_setup:  # and the markers' points registered with it
            out["before_setup"] = {n: float(v) for n, v in self.before_setup.items()}
        if self.use_q is not None:
            out["use_q"] = self.use_q.tolist()
        if self.repeat is not None:
            out["repeat"] = self.repeat.restricted([n for n in self.names if n in self.repeat.names]).to_dict()
        return out

    def setup(self) -> dict:
        """The set-up the next measurement of this robot shares, in absolute form: the 6-D probe's
        rotation on the flange (3, 3) and the marker points on the flange (m), as fitted."""
        out: dict = {"markers": {n: float(v) for n, v in self.nuisance.items() if n.startswith("marker[")}}
        pose = self._pose_set()  # a pose set, its residual in the instrument's frame or the joints'
        while isinstance(pose, Wrapper):  # the set under a session's frame or a drifting instrument
            pose = pose.inner
        if pose is not None:
            out["target_rotation"] = pose.target(np.array([self.nuisance[f"target.r{a}"] for a in "xyz"])).tolist()
        return out

    def _pose_set(self):
        """The first set that measures a body's rotation on the flange (a pose set, its residual in the
        instrument's frame or in the joints', maybe wrapped), or None."""
        return next((o for o in self.observations if "target_rotation" in o.anchors()), None)

    def sample_table(self) -> list[dict]:
        """Per sample of every set: file, row, kind, position error (mm: the norm of the sample's position residuals,
        all its seen markers together; None for a residual in joint space), rotation error (mrad; poses), joint
        error (a residual in joint space: the norm of its joints' misses, mrad or mm as the joints are; else None),
        the norm of its residual whitened by the stated σ, its robust z within the set and the outlier flag (the
        verdict's rule)."""
        out, sets = [], self.observations
        for obs, bad, norms in zip(sets, self.outliers or ((),) * len(sets), sample_norms(sets, self.whitened_residual)):
            names, nuis0, _ = obs.nuisance(self.robot)
            r = obs.evaluate(self.robot, self.robot.params.values,
                             np.array([self.nuisance.get(n, v) for n, v in zip(names, nuis0)]))[0]
            labels, kinds = component_kinds([obs])
            rot = np.array([kinds[k] == "pose rotation" for k in labels], bool)
            pos, ang = (sample_norms([obs], np.where(rot == turned, r, 0.0))[0] for turned in (False, True))
            z = robust_z(norms) if len(obs) >= MIN_SAMPLES else np.zeros(len(obs))
            flagged = set(int(i) for i in bad)
            joints = obs.kind == "joint"  # its rows are the joints' misses (rad or m): 1e3 -> mrad or mm
            out += [{"file": obs.source, "row": int(obs.rows[i]), "kind": obs.kind,
                     "position_mm": None if joints else float(pos[i] * MM),
                     "rotation_mrad": float(ang[i] * MRAD) if rot.any() else None,
                     "joint_milli": float(pos[i] * 1e3) if joints else None, "whitened": float(norms[i]),
                     "robust_z": float(z[i]), "outlier": i in flagged} for i in range(len(obs))]
        return out

    def write_residuals(self, path: str) -> None:
        """:meth:`sample_table` as CSV (atomically): mm, mrad, the joints' misses (mrad for revolute joints, mm for
        prismatic ones; a column only for a residual in joint space), whitened norms, robust z, outlier yes/no."""
        table = self.sample_table()
        types = set(self.robot.joint_types)
        joint = "joint_error_" + ("mrad" if types == {"revolute"} else "mm" if types == {"prismatic"} else "mrad_mm")
        joints = any(s["joint_milli"] is not None for s in table)
        header = ["file", "row", "kind", "position_error_mm", "rotation_error_mrad", *([joint] if joints else []),
                  "whitened_norm", "robust_z", "outlier"]

        def cell(v):
            return "" if v is None else f"{v:.6g}"
        write_csv(path, header, ([s["file"], s["row"], s["kind"], cell(s["position_mm"]), cell(s["rotation_mrad"]),
                                  *([cell(s["joint_milli"])] if joints else []), cell(s["whitened"]),
                                  f"{s['robust_z']:.4g}", "yes" if s["outlier"] else "no"] for s in table))

    def held_out(self, obs, robot: Robot | None = None) -> dict:
        """Statistics of a held-out set (same types) under the calibrated robot (or ``robot``, e.g. the
        nominal one): set-up parameters the fit shares with it (a target's rotation, markers) at their
        fitted values, or, under :attr:`before`, the markers' points as registered with it (:attr:`before_setup`);
        a pose set also takes the training target's start rotation."""
        return self.held_out_judged(obs, robot).stats()

    def held_out_judged(self, obs, robot: Robot | None = None) -> "Judged":
        """The held-out set as :meth:`held_out` judges it: prepared, with the model and the set's set-up values."""
        robot = self.robot if robot is None else robot
        setup = {**self.nuisance, **(self.before_setup if robot is self.before else {})}
        pose = self._pose_set()
        anchors: dict = {} if pose is None else pose.anchors()  # the first target's
        obs = obs.with_anchors(anchors).prepare(robot)  # anchored: prepare keeps the training target's rotation
        names, start, _ = obs.nuisance(robot)
        return Judged(obs, robot, np.array([setup.get(n, v) for n, v in zip(names, start)]))

    def to_dict(self) -> dict:
        out = {"robot": self.robot.name, "converged": self.converged, "message": self.message,
               "iterations": self.iterations, "runs": self.runs, "evaluations": self.evaluations, "time_s": self.time_s,
               "options": self.options.to_dict(), "estimated": list(self.names),
               "not_estimated": [n for n in self.robot.params.names if n not in set(self.names)],
               "estimates": self.estimates, "corrections": self.corrections, "units": self.units,
               "nuisance": {k: float(v) for k, v in self.nuisance.items()},
               "std": {k: (float(v) if np.isfinite(v) else None) for k, v in self.std.items()},  # None: undetermined
               "correlation": self.correlation.tolist(), "gauge": list(self.gauge),
               "identifiability": self.identifiability.to_dict(), "history": list(self.history),
               "sets_before": list(self.per_set_before), "sets": list(self.per_set),
               "whitened_rms": self.whitened_rms, "whitened_rms_per_kind": dict(self.whitened),
               "model_error": dict(self.model_error), "verdict": self.verdict.to_dict(),
               "structure": self.robot.structure, "error_model": self.robot.error_model,
               "error_model_choice": None if self.error_model_choice is None else self.error_model_choice.to_dict(),
               "error_model_notes": list(self.notes), "rejected_rows": {k: list(v) for k, v in self.rejected.items()},
               "diagnosis": None if self.diagnosis is None else self.diagnosis.to_dict(),
               "mounting": None if not self.mounting else {  # tool_point None: the data do not determine it
                   "tool_point": None if self.mounting_gauge[0] else self.robot.tool_point().tolist(),
                   "declared_tool_point": self.nominal.tool_point().tolist(), "text": self.mounting},
               "compliance": self.compliances,  # rad/(N·m) per joint; None: kept at nominal, not determined
               "weakly_determined": {k: float(v) for k, v in self.weak.items()},  # m or rad: the σ the data gave
               "prior": {k: float(v) for k, v in self.prior.items()},  # learned prior σ per group (m or rad)
               "session_frames": None if not self.session_frames() else {
                   "convention": FRAME_CONVENTION, "frames": {  # m and rad; std None: undetermined
                       s: {b: {"value": float(v), "std": float(sd) if np.isfinite(sd) else None}
                           for b, (v, sd) in f.items()} for s, f in self.session_frames().items()}}}
        if self.data:
            out.update(n_poses=len(self.residuals), sigma=self.sigma, before=self.stats_before.to_dict(),
                       after=self.stats_after.to_dict(), drift=self.drift, poses=self.pose_records())
        return out

    @property
    def solver_state(self) -> str:
        """How the solver ended: "converged", "not converged", or "stopped" (``method="pso"``: the particle swarm
        runs its iterations and stops, with no test of convergence; ``"pso+lm"`` polishes its best)."""
        if self.options.method == "pso":
            return "stopped"
        return "converged" if self.converged else "not converged"

    @property
    def _turning_joints(self) -> bool:
        """Whether the robot's joints all turn (a joint-space residual in rad, else in m)."""
        return all(t == "revolute" for t in self.robot.joint_types)

    def __str__(self) -> str:
        kinds = " + ".join(dict.fromkeys(s["type"] for s in self.per_set))
        lines = [f"calibration of {self.robot.name} from {kinds} data"
                 + ("" if self.robot.error_model == "geometric" else f" ({self.robot.error_model} error model)")
                 + f": {self.solver_state.replace('not converged', 'NOT CONVERGED')} ({self.message}) in {self.iterations} "
                 f"iterations over {self.runs} solver run{'s' * (self.runs != 1)}, {self.time_s * 1e3:.1f} ms; "
                 f"{len(self.names)} robot and {len(self.nuisance)} set-up "
                 f"parameters; loss {self.options.loss}, base {self.options.base}"]
        # the fitted robot parameters as a table: estimate, correction from nominal, σ (mm, deg)
        param_kinds, per = dict(zip(self.robot.params.names, self.robot.params.kinds)), self.robot.value_units()
        lines.append(f"{'parameter':<22} {'estimate':>16} {'correction':>16} {'σ':>14}")
        for n in self.names:  # a value per something more (a compliance's deflection at 100 N·m): said at the end
            k = param_kinds[n]
            lines.append(f"{n:<22} {display(self.robot.params[n], k):>16} "
                         f"{display(self.robot.params[n] - self.nominal.params[n], k):>16} "
                         f"{self.sigma_text(n) or display(self.std[n], k).lstrip('+'):>14}"
                         + (f"  ({per[n]})" if n in per else ""))
        lines += self._frame_lines()
        lines += self._data_lines()
        lines += [f"mounting: {self.mounting}"] if self.mounting else []
        if self.gauge:
            lines.append(f"not seen by these data (gauge freedoms, kept at their values): {', '.join(self.gauge)}")
        lines += [self.identifiability.frames_note] if self.identifiability.frames else []
        lines += [weak_note(self.robot, self.weak, self.correction_scales)] if self.weak else []
        lines += prior_lines(self.prior)
        if self.rejected:
            lines.append(f"left out as outliers (a robust refit put them beyond the outlier limit): "
                         f"{self.rejected_text()}")
        lines += [] if self.error_model_choice is None else [str(self.error_model_choice)]
        lines += [f"compliance of {j}: " + ("kept at nominal (not determined)" if c is None else f"{c:.3g} rad/(N·m)")
                  for j, c in self.compliances.items()]
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"note: {n}" for n in [self._gimbal_note()] if n]
        return "\n".join([*lines, str(self.verdict)])

    def session_frames(self) -> dict[str, dict[str, tuple[float, float]]]:
        """Each later session's frame as fitted: session ("2:B.csv") -> base parameter ("base.x") -> (value, σ),
        m and rad (σ inf: undetermined); :data:`FRAME_CONVENTION` says what it is. Empty with one session."""
        out: dict[str, dict[str, tuple[float, float]]] = {}
        for n, v in self.nuisance.items():
            if n.startswith("frame[") and "]." in n:
                session, base = n[len("frame["):].rsplit("].", 1)
                out.setdefault(session, {})[base] = (float(v), float(self.std.get(n, np.inf)))
        return out

    def _frame_lines(self) -> list[str]:
        """The later sessions' frames, one line each, with their σ (mm, deg) and one line of convention."""
        frames = self.session_frames()
        kinds = dict(zip(self.robot.params.names, self.robot.params.kinds))
        lines = [f"frame of each later file: {FRAME_CONVENTION}"] if frames else []
        return lines + [f"  {s}: " + ", ".join(
            f"{b.rsplit('.', 1)[-1]} {display(v, kinds[b])} ± "
            + (display(sd, kinds[b], signed=False) if np.isfinite(sd) else "undetermined") for b, (v, sd) in f.items())
            for s, f in frames.items()]

    def _gimbal_note(self) -> str:
        """A note when the base frame's middle angle (R = Rz·Ry·Rx) lies within GIMBAL_NEAR of ±90°: there base.rx
        and base.rz turn about nearly one axis, and their values, large and opposite or alike, mean only together."""
        names = self.robot.params.names
        if not {"base.rx", "base.ry", "base.rz"} <= set(names) or "base.rx" not in self.names:
            return ""
        ry = float(self.robot.params["base.ry"])
        if abs(abs(ry) - np.pi / 2) > GIMBAL_NEAR:
            return ""
        return (f"base.ry is {np.degrees(ry):.3f}°, near ±90°: base.rx and base.rz then turn about nearly the same "
                f"axis (gimbal lock), so their values mean only together (the frame they make, which the fit "
                f"determines); their σ and corrections apart do not describe the robot")

    def sigma_text(self, name: str) -> str:
        """The words for a parameter's σ where a number would mislead: 'undetermined' (not determined by the data),
        'held by the prior' (a learned prior keeps it at nominal, σ below PRIOR_HELD); '' otherwise."""
        sd = self.std.get(name, np.inf)
        if not np.isfinite(sd):
            return "undetermined"
        return "held by the prior" if self.prior and sd < PRIOR_HELD else ""

    def before_registration(self) -> str:
        """How the "before" model was registered to the data, in words (the CLI's and the report's): with poses
        (whatever residual the fit used), the frame, the target point and the target's rotation fitted to each
        file with the kinematics fixed, as ``kincal evaluate --refit-target`` judges the nominal model; with
        positions, the frame and the target point registered to them (as ``kincal evaluate`` does)."""
        fixed = self.options.base == "fixed"
        if not self.data and any(in_cartesian(o).kind == "pose" for o in self.observations):
            return ("target point and target rotation fitted to each file, frame as given (--base fixed)" if fixed
                    else "frame, target point and target rotation fitted to each file") + ", kinematics fixed"
        return "target point registered, frame as given (--base fixed)" if fixed else \
            "frame and target point registered"

    def _data_lines(self) -> list[str]:
        """The residuals: per set before → after; for position data the residual σ against the
        tracker noise, the statistics before and after and a fitted drift; σ per kind otherwise."""
        lines = [f"  {a['type']} ({a['source']}): {stat_change(b, a)}"
                 for b, a in zip(self.per_set_before, self.per_set)]
        if not self.data and any(in_cartesian(o).kind in ("point", "pose") for o in self.observations):
            lines.insert(0, f"before → after per file (before: nominal, {self.before_registration()}):")
        if self.data:
            noise = noise_level(self.measurements.std, self.options.thresholds)
            lines += [f"residual sigma per axis: {self.sigma * MM:.4f} mm (tracker noise for the verdict "
                      f"{noise[0] * MM:.3g} mm: {noise[1]})",
                      f"before (nominal, {self.before_registration()}): {self.stats_before}",
                      f"after:  {self.stats_after}"]
            if self.drift:
                lines.append("drift over the session (first to last pose): " + ", ".join(
                    f"{a} {number(d['value'] * MM, '+.4f')} ± {d['std'] * MM:.4f} mm" for a, d in self.drift.items()))
            return lines
        lines.append(f"whitened residual RMS {self.whitened_rms:.3g} (1 when the stated σ are right): "
                     + ", ".join(f"{k} {v:.3g}" for k, v in self.whitened.items()))
        if self.model_error:
            lines.append("weighted by 1/(σ² + s²), s what the model leaves beyond the stated σ: " + ", ".join(
                f"{k} {v * MRAD:.3g} mrad" if k.endswith("rotation") or (k == "joint" and self._turning_joints)
                else f"{k} {v * MM:.3g} mm" for k, v in self.model_error.items()))
        # each set's fitted instrument drift over its rows (first to last sample), mm with σ
        sets = dict.fromkeys(n.rsplit(".", 1)[0] for n in self.nuisance if n.startswith("drift["))
        return lines + [f"{s} over the file (first to last sample): " + ", ".join(
            f"{a} {number(self.nuisance[f'{s}.{a}'] * MM, '+.4f')} ± {self.std.get(f'{s}.{a}', np.inf) * MM:.4f} mm"
            for a in "xyz" if f"{s}.{a}" in self.nuisance) for s in sets]


@dataclass(frozen=True, eq=False)
class Judged:
    """An observation set as judged: the set, the model (its parameter values) and the set's set-up values
    ``nuis`` (m, rad), which its statistics and its per-sample errors share."""

    obs: Observation
    robot: Robot
    nuis: np.ndarray

    def stats(self) -> dict:
        """The set's statistics (m, rad), as its type's ``stats()`` gives them."""
        return self.obs.stats(self.robot, self.robot.params.values, self.nuis)

    def sample_errors(self) -> tuple | None:
        """Its per-sample errors (``Observation.sample_errors``: (N, 3) m measured − model, and (N,) rad or None)."""
        return self.obs.sample_errors(self.robot, self.robot.params.values, self.nuis)


def stat_line(stats: dict) -> str:
    """One set's statistics in a few words, mm and mrad.

    Parameters
    ----------
    stats : dict
        The set's statistics, as an observation type's ``stats()`` gives them (m and rad): ``mean``,
        and ``mean_rotation`` for poses, or ``mean_abs`` for data judged by an absolute deviation.

    Returns
    -------
    str
        E.g. ``"mean 0.0215 mm"``, ``"mean 0.0300 mm, mean 0.1000 mrad"``.

    Examples
    --------
    >>> from kincal.identify import stat_line
    >>> stat_line({"type": "point", "samples": 30, "mean": 21.5e-6, "rms": 24e-6, "max": 41e-6})
    'mean 0.0215 mm'
    >>> stat_line({"type": "pose", "mean": 30e-6, "mean_rotation": 0.1e-3})
    'mean 0.0300 mm, mean 0.1000 mrad'
    >>> stat_line({"type": "joint", "mean": 24.4e-6})  # a joint-space fit's set: its positions' error
    'mean position error 0.0244 mm'
    """
    s = in_display(stats)
    if "mean_abs_mm" in s:
        return f"mean |p − point| {s['mean_abs_mm']:.4f} mm"
    rot = f", mean {s['mean_mrad']:.4f} mrad" if "mean_mrad" in s else ""
    what = "position error " if stats.get("type") == "joint" else ""  # fitted in joint space, judged in position
    return f"mean {what}{s['mean_mm']:.4f} mm{rot}"


def stat_change(before: dict, after: dict) -> str:
    """A set's statistics before → after in a few words, mm and mrad.

    Parameters
    ----------
    before, after : dict
        The set's statistics under the nominal and the calibrated model (:func:`stat_line`).

    Returns
    -------
    str
        Both :func:`stat_line` texts and, when some of the set's rows were no sample, :func:`unseen_note`.

    Examples
    --------
    >>> from kincal.identify import stat_change
    >>> stat_change({"type": "markers", "mean": 2e-3}, {"type": "markers", "samples": 40, "unseen": 3, "mean": 4e-5})
    'mean 2.0000 mm  →  mean 0.0400 mm (40 samples; 3 rows saw no marker)'
    """
    return f"{stat_line(before)}  →  {stat_line(after)}{unseen_note(after)}"


def unseen_note(stats: dict) -> str:
    """How many of a set's rows were no sample: a markers row that saw no marker.

    Parameters
    ----------
    stats : dict
        The set's statistics; ``unseen`` (rows with no marker seen) and ``samples`` when there are such rows.

    Returns
    -------
    str
        ``" (N samples; K rows saw no marker)"``, or ``""`` when every row is a sample.

    Examples
    --------
    >>> from kincal.identify import unseen_note
    >>> unseen_note({"samples": 40, "unseen": 3}), unseen_note({"samples": 40})
    (' (40 samples; 3 rows saw no marker)', '')
    """
    return f" ({stats['samples']} samples; {stats['unseen']} rows saw no marker)" if stats.get("unseen") else ""


def trained_setup(record: dict | None, where: str = "calibration record") -> tuple[dict, dict]:
    """Read the set-up a held-out file is judged with from a calibration record.

    From the record's ``setup``: the set-up parameters to hold and the anchors (a 6-D probe's rotation)
    a held-out file is judged with, so its probe and markers stay as trained.

    Parameters
    ----------
    record : dict or None
        A calibration record (:meth:`CalibrationResult.record`, the ``calibration:`` section of a
        calibrated robot file), or None.
    where : str, optional
        Names the file in an error (default ``"calibration record"``).

    Returns
    -------
    held : dict of str to float
        Set-up parameters to hold at these values (m or rad): the markers, and the probe's rotation
        vector at 0 when the rotation is anchored.
    anchors : dict
        ``{"target_rotation": R}``, R (3, 3), when the record has a 6-D probe's rotation, else empty.
        Both are empty for a record without a ``setup``.

    Raises
    ------
    ValueError
        When ``setup.target_rotation`` is not a 3 x 3 rotation matrix.

    Examples
    --------
    >>> from kincal.identify import trained_setup
    >>> trained_setup(None)
    ({}, {})
    >>> held, anchors = trained_setup({"setup": {"markers": {"marker[a].x": 0.01},
    ...                                          "target_rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}})
    >>> held
    {'marker[a].x': 0.01, 'target.rx': 0.0, 'target.ry': 0.0, 'target.rz': 0.0}
    >>> anchors["target_rotation"].shape
    (3, 3)
    """
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
