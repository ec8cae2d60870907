"""The calibration report: one self-contained HTML page (inline SVG, no JavaScript, no network), the
JSON of the same numbers, and a terminal summary. Deterministic: the same input gives the same bytes
(the date is the day, or SOURCE_DATE_EPOCH when set)."""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from importlib import resources
from pathlib import Path
from typing import Sequence

import jinja2
import numpy as np

from .._atomic import json_path_for, write_text_atomic
from ..identify.calibrate import evaluate
from ..identify.judge import residual_words
from ..identify.fitting import ABSOLUTE
from ..identify.sessions import AS_CALIBRATED, REGISTERED, heldout_cause, refit_frame
from ..identify.registration import register_mounting
from ..identify.relevance import prior_lines
from ..identify.positions import EvaluationStats, session_frame
from ..identify.result import CalibrationResult
from ..identify.stacked import session_before
from ..identify.weak import weak_note
from ..identify.verdict import Thresholds, duplicate_groups, repeat_tolerance, robust_z
from ..io.measurements import Measurements
from ..models.robot import TOOL_NAMES
from ..observe.sessions import InSession
from ..observe.drifting import DRIFT
from ..units import MM, display, fine
from . import figures as F
from .observations import observation_figures, sets_part
from .study_figures import pso_fitness


@dataclass(frozen=True)
class Report:
    """A calibration report: the HTML page, the JSON of the same numbers and a terminal summary.

    Parameters
    ----------
    html : str
        The self-contained page (inline SVG, no JavaScript, no network).
    data : dict
        The same numbers, SI units (m, rad), JSON-ready.
    summary : str
        A few lines for the terminal: the verdict, its reasons and the headline errors (mm).
    json_name : str, optional
        The JSON file name the page names (``<code>name</code>``), made the written one's by :meth:`write`
        (default: none named).

    See Also
    --------
    build_report : makes it.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from kincal.report import Report
    >>> report = Report("<html><body>ur5</body></html>", {"robot": "ur5"}, "verdict: GOOD")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     written = report.write(Path(folder) / "ur5.html")
    ...     names = sorted(p.name for p in Path(folder).iterdir())
    >>> written.name, names
    ('ur5.json', ['ur5.html', 'ur5.json'])
    """

    html: str
    data: dict  # the same numbers, SI units
    summary: str  # a few lines for the terminal
    json_name: str = ""  # the JSON file the page names, as built

    def write(self, path: str | os.PathLike) -> Path:
        """Write the HTML to ``path`` and the JSON beside it (same name, .json), each atomically.

        Parameters
        ----------
        path : str or os.PathLike
            The HTML file.

        Returns
        -------
        Path
            The JSON file (:func:`json_path_for`).
        """
        json_path = json_path_for(path)
        html = self.html.replace(f"<code>{self.json_name}</code>", f"<code>{json_path.name}</code>") \
            if self.json_name else self.html  # the page names the JSON written beside it, whatever the name
        write_text_atomic(path, html)
        write_text_atomic(json_path, json.dumps(self.data, indent=2, sort_keys=True) + "\n")
        return json_path


def report_date() -> str:
    """Today (UTC), or the day of SOURCE_DATE_EPOCH (seconds since 1970) for reproducible builds."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    try:
        day = datetime.fromtimestamp(int(epoch), timezone.utc) if epoch else datetime.now(timezone.utc)
    except (ValueError, OverflowError, OSError):
        raise ValueError(f"SOURCE_DATE_EPOCH='{epoch}' is not a number of seconds since 1970; unset it or fix "
                         f"it") from None
    return day.strftime("%Y-%m-%d")


def build_report(result: CalibrationResult, test: Measurements | Sequence | None = None, info: dict | None = None,
                 html_name: str = "report.html", same_frame: bool = False, history: dict | None = None) -> Report:
    """The report of a calibration (from any kinds of data) and, if given, of held-out sessions.

    Deterministic: the same input gives the same bytes (the date is the day, or SOURCE_DATE_EPOCH when
    set). Position data give the errors before and after calibration per session, the figures, warnings,
    ISO 9283 pose accuracy and repeatability where a pose repeats, and the acquisition order; observation
    sets give their residuals per set and type.

    Parameters
    ----------
    result : CalibrationResult
        The calibration (:func:`kincal.calibrate`).
    test : Measurements or sequence, optional
        Held-out sessions: position data as one set of measurements or several, one per session; other
        kinds: observation sets of the training data's kind (default none).
    info : dict, optional
        Labels for the data section: "robot" (the robot file or name), "units", "design", and anything
        else to show (key -> text).
    html_name : str, optional
        The page's file name, which names the JSON it links to (default "report.html").
    same_frame : bool, optional
        The held-out sessions were measured in the training data's frame (the tracker did not move): the
        models are used as they are. False (default): each session's frame is re-fitted to it, for the
        nominal and the calibrated model alike (kinematics fixed).
    history : dict, optional
        The robot's history from the calibration store, shown beside the calibration: "rows" (one dict of
        display texts per record: time, kind, verdict, training, held_out, note), "figure" (a matplotlib
        Figure, :func:`kincal.history.history_figure`), "store" (where it is) and, optionally, "steps" (each
        step between consecutive calibrations as ``kincal history`` prints it: a dict of "line", its judgement
        with p, and "more", its indented lines), "judged" (the steps' :meth:`Step.to_dict`, for the JSON) and
        "alpha" (each step's false-alarm probability).

    Returns
    -------
    Report
        The HTML page, its numbers (SI) and the terminal summary; :meth:`Report.write` saves them.

    Raises
    ------
    ValueError
        When SOURCE_DATE_EPOCH is set to something that is not a number of seconds.
    """
    from .. import __version__

    tests = [test] if isinstance(test, Measurements) else list(test or [])
    part, numbers, summary = (_positions_part if result.data else sets_part)(result, tests, same_frame)
    part.setdefault("figures_params", [{"name": "correlation", "svg": F.svg(_correlation(result))}])  # every kind
    ctx = {"robot": result.robot.name, "version": __version__, "date": report_date(), "positional": bool(result.data),
           "structure": result.robot.structure, "model": _model_words(result),
           "types": list(dict.fromkeys(s["type"] for s in result.per_set)),
           "n_estimated": len(result.names), "n_setup": len(result.nuisance),
           "n_samples": sum(s["samples"] for s in result.per_set), "whitened_rms": result.whitened_rms,
           "verdict": result.verdict.to_dict(), "parameters": _parameter_rows(result), "setup": _setup(result),
           "weak": weak_note(result.robot, result.weak, result.correction_scales), "prior": prior_lines(result.prior),
           "gauge": list(result.gauge), **_dropped(result), "solver": f"{result.solver_state} ({result.message})",
           "base_fixed": result.options.base == "fixed", "json_name": json_path_for(html_name).name,
           "data": _data_rows(result, tests, dict(info or {}), same_frame),
           "error_model_choice": None if result.error_model_choice is None else result.error_model_choice.to_dict(),
           "error_model_notes": list(result.notes), "compliance": result.compliances,
           "mounting": result.mounting, "mounting_determined": not result.mounting_gauge[0],
           "frames_note": result.identifiability.frames_note if result.identifiability.frames else "",
           "covariates": _covariates(result), "residual_words": residual_words(result),
           **part,
           "history": None if history is None else {"rows": history["rows"], "store": history["store"],
                                                    "steps": history.get("steps", []), "alpha": history.get("alpha"),
                                                    "svg": F.svg(history["figure"])}}
    data = {k: ctx[k] for k in ("robot", "version", "date", "structure", "verdict", "parameters", "setup",
                                "not_estimated", "not_estimated_text", "data", "error_model_choice",
                                "error_model_notes", "compliance", "mounting", "frames_note", "whitened_rms")}
    data["covariates"] = [c.to_dict() for c in _fitted_covariates(result)]
    data["history"] = None if history is None else history["rows"]
    data["history_steps"] = None if history is None else history.get("judged", [])
    calibration = {k: v for k, v in result.to_dict().items() if k != "time_s"}  # the same numbers, the same bytes
    return Report(template().render(**ctx), {**data, **numbers, "calibration": calibration},
                  "\n".join([f"verdict: {result.verdict.status.upper()}",
                             *(f"  {r.level}: {r.message}" for r in result.verdict.reasons), *summary]),
                  ctx["json_name"])


def _model_words(result: CalibrationResult) -> str:
    """The model as the page's header names it: its structure, and the error model the fit was asked for where the
    structure does not name it (a hexapod's leg compliance is a parameter of its own: "stewart (implicit, 6-D) +
    compliance"; a serial robot's terms are in its structure, "dh + compliance")."""
    asked = result.options.error_model
    extra = asked is not None and asked.name not in ("auto", "geometric") and result.robot.error_model == "geometric"
    return result.robot.structure + (f" + {asked.name}" if extra and asked is not None else "")


def _dropped(result: CalibrationResult) -> dict:
    """What the data do not determine, in the calibration's own words (:meth:`CalibrationResult.dropped_text`, as
    the CLI prints it): its sentence and one line per parameter with what it acts like."""
    text = result.dropped_text().split("\n")
    return {"not_estimated_text": text[0], "not_estimated": [line.strip() for line in text[1:]]}


def _positions_part(result: CalibrationResult, tests: list[Measurements], same_frame: bool):
    """The position report's sections (headline, figures, warnings, ISO 9283, acquisition order), the
    numbers it adds to the JSON and its lines of the terminal summary."""
    models = _held_out_models(result, tests, same_frame)
    sets = _sets(result, tests, models, result.options.thresholds)
    headline = [_headline(s, which, result.before_registration()) for s in sets for which in ("before", "after")]
    part: dict = {"outliers": [int(r) for s in sets for r in s.rows[s.outliers]], "headline": headline,
                  "warnings": _warnings(result, tests, models), "iso": _iso9283(sets, result),
                  "acquisition": _acquisition(result), "sessions": len(result.data)}
    figs = _make_figures(sets, result)
    part.update({g: [{"name": n, "svg": F.svg(figs[n])} for n in names] for g, names in GROUPS.items()})
    numbers = {k: part[k] for k in ("outliers", "warnings", "iso", "acquisition")}
    numbers["headline"] = [{**h, **{k: h[k] / MM for k in ("mean", "rms", "max", "p95")}} for h in headline]
    numbers["figures"] = [f["name"] for g in GROUPS for f in part[g]]
    width = max(len(h["data"]) for h in headline)
    summary = [f"  {h['data']:<{width}} {h['model']:<27} mean {h['mean']:.4f} mm  rms {h['rms']:.4f} mm  "
               f"max {h['max']:.4f} mm" for h in headline]
    summary += [f"  {h['data']}: {h['registration']}" for h in headline[::2] if not h["key"].startswith("training")]
    return part, numbers, summary + [f"  warning: {w}" for w in part["warnings"]]


def _warnings(result: CalibrationResult, tests: list[Measurements], models: list[tuple]) -> list[str]:
    """Per held-out session: where the calibrated model extrapolates, and the likely cause of an error
    far above the training error (``models``: per session, as :func:`_held_out_models` gives them)."""
    out, unc = [], result.uncertainty()
    for meas, (_, model, how) in zip(tests, models):  # a frame registered to the session: its training σ does not count
        mine = unc.given(model.base_params(), model) if how == REGISTERED else unc
        out += [f"{Path(meas.source).name}: {w}" for w in evaluate(model, meas, uncertainty=mine).warnings]
        cause = heldout_cause(model, meas, result.stats_after.mean, how == REGISTERED)
        out += [cause] if cause else []
    return out


def _held_out_models(result: CalibrationResult, tests: list[Measurements], same_frame: bool) -> list[tuple]:
    """Per held-out session (nominal model, calibrated model, how their frame was set): both re-fitted
    to the session (kinematics fixed), or with ``same_frame`` as calibrated (the nominal one as the calibration
    judged the training data, ``result.before``, as the CLI judges it). Computed once: the headline, the figures
    and the warnings share them."""
    if same_frame:
        return [(result.before, result.robot, AS_CALIBRATED) for _ in tests]
    return [(register_mounting(result.nominal, m.q, m.xyz), refit_frame(result.robot, m), REGISTERED) for m in tests]


def _acquisition(result: CalibrationResult) -> dict:
    """Training residual norms in acquisition (input row) order, with their linear trend: drift of
    the tracker or a robot warming up shows here (the verdict names a warm-up)."""
    meas = result.measurements
    order = np.argsort(meas.rows, kind="stable")
    norms = np.linalg.norm(result.residuals, axis=1)[order] * MM
    slope = float(np.polyfit(np.arange(len(norms)), norms, 1)[0]) * 100 if len(norms) > 2 else 0.0
    return {"rows": meas.rows[order].tolist(), "error_mm": norms.tolist(), "trend_mm_per_100_poses": slope}


def _rotation(robot) -> np.ndarray:
    """(3, 3) the rotation of ``robot``'s base frame (the identity for a robot without one)."""
    return robot.base_transform()[0] if robot.base_params() else np.eye(3)


def _training_sets(result: CalibrationResult) -> list[F.PoseSet]:
    """One set per training session (outliers as judged by the calibration), all in the first session's frame:
    errors after calibration, and before it those of the "before" model as the calibration judged that session
    (a session in its own frame with its frame registered to it), so that each session's figures are the
    calibration's per-set ones, which the CLI prints."""
    meas, after, bad = result.measurements, result.residuals, np.asarray(result.pose_z > result.outlier_z, bool)
    fixed = result.options.base == "fixed"
    R0, several, sets, start = _rotation(result.robot), len(result.data) > 1, [], 0
    for k, (obs, session) in enumerate(zip(result.observations, result.data)):
        own = session.subset(np.flatnonzero(np.isin(session.rows, obs.rows)))  # the session's frame
        at = slice(start, start + len(own))
        start += len(own)
        before = (own.xyz - session_before(result.before, obs).forward(own.q)) @ _rotation(
            session_frame(result, obs)) @ R0.T
        frame = "frame as given (--base fixed)" if fixed else "own frame fitted with the model (nominal: registered " \
            "to this session)" if isinstance(obs, InSession) else "frame fitted with the model (nominal: registered " \
            "to these data)"
        sets.append(F.PoseSet("training", own.rows, own.q, meas.xyz[at], before, after[at], bad[at],
                              name=Path(session.source).name if several else "", registration=frame,
                              colour=F.colour("training", k), key=f"training-{k + 1}" if several else "training"))
    return sets


def _sets(result: CalibrationResult, tests: list[Measurements], models: list[tuple], th: Thresholds) -> list[F.PoseSet]:
    """The training sessions (:func:`_training_sets`) and one set per held-out session (outliers by
    robust z), each with its errors before (nominal) and after (calibrated), both models registered
    the same way (``models``: per session, from :func:`_held_out_models`). A held-out set, measured where
    its registered model sees the robot, has its positions and error vectors expressed in the frame of the
    trained model (the first session's): every set in one frame."""
    sets = _training_sets(result)
    R0, t0 = result.robot.base_transform() if result.robot.base_params() else (np.eye(3), np.zeros(3))
    for k, (meas, (nominal, model, how)) in enumerate(zip(tests, models)):
        after = meas.xyz - model.forward(meas.q)
        z = robust_z(np.linalg.norm(after, axis=1))
        Rs, ts = model.base_transform() if model.base_params() else (np.eye(3), np.zeros(3))
        M = Rs @ R0.T
        sets.append(F.PoseSet("held-out", meas.rows, meas.q, (meas.xyz - ts) @ M + t0,
                              (meas.xyz - nominal.forward(meas.q)) @ M, after @ M, z > th.outlier_limit(len(z)),
                              name=Path(meas.source).name, colour=F.colour("held-out", k),
                              registration=how, key="held-out" if len(tests) == 1 else f"held-out-{k + 1}"))
    return sets


def _headline(s: F.PoseSet, which: str, trained: str) -> dict:
    """A row of the headline table; ``trained``: how the "before" model was registered on the training data (as
    the CLI says it), which a set judged in the training frame shares."""
    errors = s.before if which == "before" else s.after
    assert errors is not None  # the report's sets (from _sets) carry both models' errors
    st = EvaluationStats.from_errors(errors)
    registered = "frame and target point registered" if s.registration == REGISTERED else trained
    model = f"nominal ({registered})" if which == "before" else "calibrated"
    return {"data": s.title, "n": st.n, "model": model, "key": f"{s.key or s.label}.{which}", "mean": st.mean * MM,
            "rms": st.rms * MM, "max": st.max * MM, "p95": st.p95 * MM, "registration": s.registration}


GROUPS = {"figures_errors": ("per_pose", "histogram", "per_axis"), "figures_where": ("vs_joints", "workspace"),
          "figures_params": ("correlation",)}


def figure_set(result: CalibrationResult, test: Measurements | Sequence[Measurements] | None = None,
               same_frame: bool = False) -> dict:
    """The report's figures as matplotlib Figures by name (``--plot`` saves them as PNG or SVG).

    Position data: errors per pose ("per_pose"), their distribution ("histogram"), per axis ("per_axis"),
    against the joints ("vs_joints"), in the workspace ("workspace") and the correlation of the estimated
    parameters ("correlation"); with a particle swarm also its fitness per iteration ("pso-fitness", the
    3-PUU paper of 2024's Fig. 7). Observation sets: the figures of the sets with positions in the robot's frame
    (:func:`observation_figures`).

    Parameters
    ----------
    result : CalibrationResult
        The calibration.
    test : Measurements or sequence, optional
        Held-out sessions of position data, or held-out observation sets (default none).
    same_frame : bool, optional
        The held-out sessions were measured in the training data's frame; False (default): each
        session's frame is re-fitted to it.

    Returns
    -------
    dict
        name -> matplotlib Figure ({} for observation sets of which none has positions).
    """
    tests = [test] if isinstance(test, Measurements) else list(test or [])
    if not result.data:
        return observation_figures(result, tests=tests, same_frame=same_frame)
    models = _held_out_models(result, tests, same_frame)
    figs = _make_figures(_sets(result, tests, models, result.options.thresholds), result)
    if result.history:
        figs["pso-fitness"] = pso_fitness(result.history)
    return figs


def evaluation_figures(robot, meas: Measurements) -> dict:
    """Figures of one model on one data set (``evaluate --plot``), in that data's measurement frame.

    Errors per pose, their distribution, per axis, against the joints and in the workspace; outliers by
    robust z (the default :class:`kincal.Thresholds`).

    Parameters
    ----------
    robot : Robot
        The model evaluated (its base frame that of the data).
    meas : Measurements
        Joint values and measured positions (N, 3), m.

    Returns
    -------
    dict
        name -> matplotlib Figure: "per_pose", "histogram", "per_axis", "vs_joints", "workspace".

    Examples
    --------
    >>> import kincal
    >>> from kincal.report import evaluation_figures
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(kincal.perturb(robot, seed=1), robot.sample_joints(20, seed=2), 15e-6, seed=3)
    >>> figures = evaluation_figures(robot, meas)
    >>> sorted(figures)
    ['histogram', 'per_axis', 'per_pose', 'vs_joints', 'workspace']
    >>> len(figures["vs_joints"].axes)  # one panel per joint
    6
    """
    after = meas.xyz - robot.forward(meas.q)
    z = robust_z(np.linalg.norm(after, axis=1))
    label = os.path.basename(str(meas.source)) if meas.source else "evaluated"  # its file: training or held out
    s = F.PoseSet(label, meas.rows, meas.q, meas.xyz, None, after, z > Thresholds().outlier_limit(len(z)),
                  colour=F.COLOURS["held-out"])
    return F.pose_figures([s], robot, "this file's measurement frame")


def _make_figures(sets: list[F.PoseSet], result: CalibrationResult) -> dict:
    return {**F.pose_figures(sets, result.robot, before=result.before_registration()),
            "correlation": _correlation(result)}


def _correlation(result: CalibrationResult):
    """The correlation matrix of the estimated robot parameters with a σ (any kind of data): a matplotlib Figure."""
    ok = np.array([np.isfinite(result.std[n]) for n in result.names], bool)
    return F.correlation([n for n, k in zip(result.names, ok) if k], result.correlation[np.ix_(ok, ok)])


def _fitted_covariates(result: CalibrationResult) -> list:
    """The covariates the calibrated model reads that were fitted on the training data (a thermal term's
    temperature): each with its reference and range, in the column's unit."""
    return [c for c in vars(result.robot).get("covariates", ()) if c.fitted]


def _covariates(result: CalibrationResult) -> list[str]:
    """Each fitted covariate in words: its range, reference and the accepted inputs (:meth:`Covariate.describe`)."""
    return [c.describe() for c in _fitted_covariates(result)]


_value = functools.partial(display, signed=False)  # the CLI's digits: 4 decimals of a mm, 5 of a degree


def _parameter_rows(result: CalibrationResult) -> list[dict]:
    th = result.options.thresholds
    kinds = dict(zip(result.robot.params.names, result.robot.params.kinds))
    base = {*result.robot.base_params(), *TOOL_NAMES}  # where the tracker stands and the target is: not errors
    rows, per = [], result.robot.value_units()  # a value per something more: a compliance's deflection at 100 N·m
    for n in result.names:
        k, c = kinds[n], result.corrections[n]
        scale = result.correction_scales.get(n, (1.0, ""))[0]  # a compliance: the deflection at the data's loads
        big = abs(c) * scale > th.suspect(k, n in result.robot.mounting_params()) and n not in base
        rows.append({"name": n, "per": per.get(n, ""), "nominal": _value(result.nominal.params[n], k),
                     "calibrated": _value(result.estimates[n], k), "correction": _value(c, k, signed=True),
                     "sigma": result.sigma_text(n) or _value(result.std[n], k),
                     "flag": "large (beyond the verdict's limit)" if big else ""})
    return rows


def _setup_kinds(result: CalibrationResult) -> dict[str, str]:
    """Each set-up parameter's kind, "length" or "angle", as the observation set that brings it declares it (a
    session's frame: its base parameters' kinds; a drift is a length)."""
    kinds: dict[str, str] = {}
    for obs in result.observations:
        names, _, declared = obs.nuisance(result.robot)
        kinds.update({n: "length" if k == DRIFT else k for n, k in zip(names, declared)})
    return kinds


def _setup(result: CalibrationResult) -> list[dict]:
    """Set-up parameters by their kind: lengths in mm, angles (frame and target rotations, plane tilts) in mrad."""
    kinds = _setup_kinds(result)
    out = []
    for n, v in result.nuisance.items():
        sd = result.std.get(n, np.inf)
        out.append({"name": n, "value": fine(v, kinds[n], ".4f"),
                    "std": fine(sd, kinds[n], ".4f") if np.isfinite(sd) else "–"})
    return out


def _file_line(data) -> str:
    """A data file (measurements or an observation set) by its path as given (the one place the page gives it: the
    tables name it by its name), size, rows and sha256."""
    path, what = Path(data.source), "poses" if isinstance(data, Measurements) else f"{data.kind} samples"
    if not path.is_file():
        return f"{data.source} ({len(data)} {what})"
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return f"{data.source} ({len(data)} {what}, rows {data.rows[0]}..{data.rows[-1]}; sha256 {digest[:16]}…)"


def _options_text(result: CalibrationResult, tests: list, same_frame: bool) -> str:
    """The fit's options (the calibration record's) in words: base, loss, method and parameters, then every other
    option with a flag that is not at its default, as its flag (--residual joint, --drift); with held-out files,
    how their frame and target were set (--same-frame, --refit-target), which changes what "held out" means."""
    o = result.options
    base = result.robot.base_params()
    unseen = bool(base) and set(base) <= set(result.gauge)  # sockets, planes: where the robot stands is not seen
    shown = ["base not seen by these data (gauge freedoms)" if unseen else f"base {o.base}", f"loss {o.loss}",
             f"method {o.method}",
             f"parameters {o.names if isinstance(o.names, str) else 'as listed'}"]
    for f in dataclasses.fields(o):
        value, flag = vars(o)[f.name], f.metadata.get("flag")
        if flag and f.name not in ("names", "base", "loss", "method") and value != f.default:
            shown.append(flag if value is True else f"{flag} {','.join(value)}" if isinstance(value, tuple) else
                         f"{flag} {value:g} (rad or m)" if f.metadata["form"] == "joint sigma" else f"{flag} {value}")
    if o.error_model is not None:
        shown.append(f"--error-model {o.error_model.name}" + (f" (payload {o.error_model.payload:g} kg)"
                                                                 if o.error_model.payload else ""))
    held = ["frame as calibrated (--same-frame)" if same_frame else "each file's frame re-fitted (kinematics fixed)"
            ] if any(isinstance(t, Measurements) or t.kind in ABSOLUTE for t in tests) else []
    held += ["its target re-fitted too (--refit-target)"] if any(vars(t).get("own_target") for t in tests) else []
    return ", ".join(shown) + ("; held out: " + ", ".join(held) if held else "")


def _data_rows(result: CalibrationResult, tests: list, info: dict, same_frame: bool) -> list[dict]:
    rows = [("robot", info.pop("robot", result.robot.name))]
    rows += [(f"training data {k + 1}" if len(result.observations) > 1 else "training data", _file_line(s))
             for k, s in enumerate(result.data or result.observations)]
    rows += [(f"held-out session {k + 1}", _file_line(t)) for k, t in enumerate(tests)]
    if result.mounting:
        rows.append(("tool point (mounting)", result.mounting))
    if result.rejected:
        rows.append(("left out as outliers", f"{result.rejected_text()}: beyond the outlier limit of a robust refit "
                                             f"(--reject-outliers)"))
    if result.diagnosis is not None:
        rows.append(("diagnosis", result.diagnosis.message()))
    rows += [("options", _options_text(result, tests, same_frame)),
             ("solver", f"{result.solver_state.replace('not converged', 'NOT converged')} ({result.message}), "
                        f"{result.iterations} iterations over {result.runs} solver run{'s' * (result.runs != 1)}"),
             ("pose design", info.pop("design", "not recorded (poses not from kincal design, or not given)"))]
    rows += [(k, str(v)) for k, v in info.items()]
    return [{"label": k, "value": v} for k, v in rows]


def _iso9283(sets: list[F.PoseSet], result: CalibrationResult) -> dict:
    """ISO 9283 pose accuracy AP and repeatability RP, per session, wherever a commanded pose repeats
    (commanded joints within the thresholds' repeat tolerance), from its n ≥ 2 attained positions:
    AP = |barycentre − commanded|; RP = l̄ + 3·S_l with l_j the distance of each attained position from
    the barycentre and S_l their sample std. The command's position is the calibrated model's as used
    on that set."""
    th = result.options.thresholds
    tol = repeat_tolerance(result.robot.joint_types, th)
    groups = []
    for s in sets:
        model = s.xyz - s.after  # the calibrated model's positions, registered as for this set
        for g in duplicate_groups(s.q, tol):
            bary = s.xyz[g].mean(axis=0)
            dist = np.linalg.norm(s.xyz[g] - bary, axis=1)
            ap = float(np.linalg.norm(bary - model[g].mean(axis=0)))
            groups.append({"session": s.title, "rows": ", ".join(str(int(r)) for r in s.rows[g]), "n": len(g),
                           "ap": ap * MM, "rp": float(dist.mean() + 3 * dist.std(ddof=1)) * MM,
                           "joint_spread": float(np.max(np.ptp(s.q[g], axis=0)))})
    rule = (f"poses whose commanded joints agree within {th.repeat_angle:g} rad (revolute) / "
            f"{th.repeat_length * MM:g} mm (prismatic) count as one pose")
    text = (f"Some poses are visited more than once ({rule}): for those, ISO 9283 pose accuracy AP (distance of "
            f"the barycentre of the attained positions from the commanded position, through the calibrated model) "
            f"and repeatability RP (mean distance from the barycentre plus three sample standard deviations) are "
            f"below, per session. The error statistics above are over different poses and are not AP." if groups else
            f"No pose is visited more than once ({rule}), so ISO 9283 pose accuracy (AP) and repeatability (RP) "
            f"cannot be computed from these data. The figures above are 3-D position errors over different poses: "
            f"they describe the model's accuracy across the workspace, which is not ISO 9283 AP.")
    summary = []  # per session: how many poses repeat, and the median and largest AP and RP (mm)
    for session in dict.fromkeys(g["session"] for g in groups):
        ap, rp = np.array([(g["ap"], g["rp"]) for g in groups if g["session"] == session]).T
        summary.append({"session": session, "poses": len(ap), "ap_median": float(np.median(ap)),
                        "ap_max": float(ap.max()), "rp_median": float(np.median(rp)), "rp_max": float(rp.max())})
    return {"text": text, "groups": groups, "summary": summary}


def template() -> jinja2.Template:
    """The report's page template (Jinja2, autoescaped, undefined names an error)."""
    folder = resources.files("kincal.report") / "templates"
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined,
                             loader=jinja2.FunctionLoader(lambda n: (folder / n).read_text()))
    return env.get_template("report.html")
