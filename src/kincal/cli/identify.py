"""Commands that identify and judge a model: calibrate, evaluate."""
from __future__ import annotations

import argparse
import dataclasses
import operator
from functools import partial
from pathlib import Path

import numpy as np

import kincal
import kincal.analysis
import kincal.identify
import kincal.io
import kincal.models
from kincal._atomic import json_path_for
from kincal.history import calibration_record, evaluation_record, fingerprint
from kincal.identify import held_out_nominal, held_out_stats, stat_change
from kincal.units import DEG, LENGTH_UNITS, MM

from .common import (EXIT_NOT_CONVERGED, EXIT_REFUSED, angle_unit, checked, covariates_read, csv_list, emit, err,
                     verdict_exit, hidden_alias, judged, load_robot, nonneg_float, positive_float, positive_int, progress, read, robot_inputs,
                     row_list, unread_joints)
from . import observe
from .history import add_store_flag, store_file, store_record
from .report import add_session_flags, data_record, nominal_model, save_figures, write_outputs


error_model_name = checked(lambda s: kincal.ErrorModel(s).name)  # argparse type: an error model name or auto


class JointSigma(float):
    """A joint reading's σ in SI (rad or m) that remembers its kind ("angle" or "length"), to be judged against
    the robot's joints (:func:`joint_std_for`), and the flag's value as written, for the messages."""

    kind = "angle"
    written = ""


def _joint_sigma(text: str) -> float:
    """argparse type: a joint reading's σ with its unit (rad, mrad, deg, rev; m, mm, um), in SI (rad or m), read by
    the flags' own angle and length parsers."""
    for parse, kind in ((observe.angle, "angle"), (observe.length, "length")):
        try:
            sigma = JointSigma(parse(text))
        except argparse.ArgumentTypeError:
            continue
        sigma.kind, sigma.written = kind, text.strip()
        return sigma
    raise argparse.ArgumentTypeError(f"'{text}': give the joints' reading noise, > 0, with its unit: 0.001rev, "
                                     f"0.05deg, 1e-4rad, 0.01mm")


def joint_std_for(robot, sigma: float | None) -> float | None:
    """``--std-joint`` in the units of ``robot``'s joint readings (rad or m): a length for legs read as motor turns
    through their leads (m per rad, within 25 % of each other) turned into the turn their mean lead gives; refused
    when its kind is not the joints' (a length for angles, an angle for lengths: taken as the other, it was 70x
    off on the Jugglebot's legs). Joints of both kinds take the number as given (rad or m)."""
    if not isinstance(sigma, JointSigma):
        return sigma
    value, revolute = float(sigma), np.asarray(robot.revolute, bool)
    leads = np.abs(np.asarray(robot.motor_leads, float))
    if revolute.all() and sigma.kind == "length":
        if np.all(np.isfinite(leads)) and leads.min() > 0 and leads.max() <= 1.25 * leads.min():
            return value / float(leads.mean())  # the motor turn that moves a leg by that length
        raise ValueError(f"--std-joint {sigma.written} is a length, but {robot.name}'s joints are read as angles: "
                         f"give their reading noise as an angle (rev, deg, mrad or rad)")
    if not revolute.any() and sigma.kind == "angle":
        raise ValueError(f"--std-joint {sigma.written} is an angle, but {robot.name}'s joints are read as lengths: "
                         f"give their reading noise as a length (mm, um or m)")
    return value


FORMS: dict[str, dict] = {"names": {"type": csv_list}, "count": {"type": positive_int},
                          "switch": {"action": "store_true"},
                          "joint sigma": {"type": _joint_sigma}}  # argparse forms of FitOptions fields
FLAGGED = [f for f in dataclasses.fields(kincal.FitOptions) if "flag" in f.metadata]  # the fields with a flag


def add_fit_flags(s) -> None:
    """The flags of :class:`kincal.FitOptions`' fields, declared once, in the record: flag, help, the
    form of the value, choices and default (the record's)."""
    for f in FLAGGED:
        m = f.metadata
        kw: dict = {"dest": f.name, "help": m["help"], **FORMS.get(m["form"], {})}
        if m["choices"]:
            kw["choices"] = list(m["choices"])
        if m["form"] not in ("switch", "names"):
            kw["default"] = f.default
        s.add_argument(m["flag"], **kw)


def fit_options(args, robot=None) -> kincal.FitOptions:
    """The calibrate command's options, for every kind, as the record the API takes (checked when
    built): the fields' own flags, the verdict's limits and the error model with its payload; ``robot``: the
    joints --std-joint is judged against (:func:`joint_std_for`)."""
    if args.payload and args.error_model is None:
        raise ValueError(f"--payload {args.payload:g}: only the gravity terms use it; give --error-model compliance, "
                         f"gravity-regressor or auto")
    error_model = None if args.error_model is None else kincal.ErrorModel(args.error_model, args.payload)
    (ls, lr), (a_s, a_r) = args.length_limits, args.angle_limits
    thresholds = kincal.Thresholds(length_suspect=ls / MM, length_refuse=lr / MM, angle_suspect=a_s / DEG,
                                   angle_refuse=a_r / DEG, tracker_noise=args.tracker_noise / MM)
    names = [f.name for f in FLAGGED]
    given: dict = {k: v for k, v in zip(names, operator.attrgetter(*names)(args)) if v is not None}  # None: a list
    sigma = given.get("joint_std")
    if isinstance(sigma, JointSigma) and args.residual != "joint":  # the flag as written (FitOptions has it in SI)
        raise ValueError(f"--std-joint {sigma.written}: the joints' reading noise σ of the joint-space residual; give "
                         f"--residual joint with it (got --residual {args.residual})")
    if "joint_std" in given and robot is not None:
        given["joint_std"] = joint_std_for(robot, given["joint_std"])
    return kincal.FitOptions(**given, thresholds=thresholds, error_model=error_model)  # flag not given


def _checked_kinds(args) -> list[str]:
    """The data's kinds (a flag that does not apply to them refused), after a session file given twice; then
    --same-frame or --refit-target where they change nothing, refused."""
    twice = [d for k, d in enumerate(args.data) if Path(d).resolve() in {Path(e).resolve() for e in args.data[:k]}]
    if twice:
        raise ValueError(f"{twice[0]} is given twice as a session: each pose would count twice (the σ too small, "
                         f"and a session held out against its own copy); give each session file once")
    kinds = observe.types_of(args)
    if args.same_frame and len(args.data) == 1 and not args.test:
        raise ValueError("--same-frame declares one measurement frame for several files (sessions or --test); "
                         "with one file and no --test it changes nothing: leave it out")
    if args.refit_target and not args.test:
        raise ValueError("--refit-target re-fits the target of held-out files (--test); there are none: leave it out "
                         "(the training files' target is fitted anyway)")
    return kinds


def cmd_calibrate(args) -> int:
    kinds = _checked_kinds(args)
    reports = [args.report, json_path_for(args.report)] if args.report else []
    if args.output:
        kincal.models.yaml_io.check_robot_output(args.output)  # before any work
    robot = covariates_of(args, load_robot(args, [*args.data, *args.test],
                                           [args.output, args.residuals, *reports, args.plot, store_file(args)]))
    options = fit_options(args, robot)
    res, tests = fit_files(args, robot, kinds, args.data, args.test, options)
    refused = res.verdict.status == "refused"
    written = bool(args.output) and (not refused or args.force)
    lines, held = held_out(res, tests, args.same_frame)  # before writing: a failure here leaves nothing half-written
    if written:
        kincal.save_robot(res.robot, args.output, calibration={**res.record(), "data": data_record(args, kinds)})
    if res.verdict.status != "good" and set(kinds) == {"point"}:  # a file of a robot with more joints?
        lines += [f"note: {path} also has the column(s) {', '.join(extra)}, which no joint of {robot.name} reads "
                  f"({robot.n_joints} joints): data of a robot with more joints?"
                  for path in args.data if (extra := unread_joints(path, robot, args.joint_cols))]
    text = "\n".join([str(res), *([res.dropped_text()] if res.identifiability.dropped else []), *lines])
    if args.residuals:  # per pose (position data: rows, joints in the file's units, errors, robust z) or per sample
        if res.data:
            meas = res.measurements
            kincal.io.write_residuals(args.residuals, meas, meas.xyz - res.residuals, res.pose_z, res.outlier_z,
                                      robot.joint_types, "mm", "deg")
        else:
            res.write_residuals(args.residuals)
        text += f"\nper-sample residuals written to {args.residuals}"
    if args.output:
        text += (f"\ncalibrated robot written to {args.output}" + (" (forced despite the verdict)" if refused else "")
                 if written else f"\nnothing written to {args.output}: the calibration is refused (--force writes it)")
    stored = store_record(args, robot, lambda identity, command: calibration_record(
        res, identity, [fingerprint(p) for p in [*args.data, *args.test]], heldout=held.get("held_out"),
        command=command, covariates=_covariate_ranges(res), output=fingerprint(args.output) if written else None))
    # before the report: it shows the history with it
    text += f"\n{stored}" if stored else ""
    text += "".join("\n" + line for line in write_outputs(args, res, tests, {
        "robot": args.robot, "units": f"{args.length_unit}, {angle_unit(args)}"}))
    emit(args, {**res.to_dict(), **held, "output": args.output if written else None, "residuals_file": args.residuals,
                "sessions": list(args.data) if len(args.data) > 1 else None}, text)
    # refused data are named, with the likely cause: more telling than the non-convergence they usually cause
    code = verdict_exit(res.verdict, res.converged)
    if code == EXIT_REFUSED:
        problems = [r.code for r in res.verdict.reasons if r.level == "refused" and r.code != "not-converged"
                    and not r.code.startswith("cause-")]
        cause = res.diagnosis.best if res.diagnosis else None
        err.print("kincal: calibration refused" + (f": {'; '.join(problems)}" if problems else "")
                  + (f"; likely cause: {cause.cause} (fix: {cause.fix})" if cause else ""))
    elif code == EXIT_NOT_CONVERGED:
        err.print(f"kincal: calibration did not converge: {res.message}")
    return code


def fit_files(args, robot, kinds: list[str], data: list[str], tests: list[str], options, use_q="held"):
    """The files read (``args``: how; held-out ``tests`` in the first file's kind) and fitted from ``robot`` with
    ``options``: (the result, the held-out sets); ``use_q``: the poses of use of position data (the prediction-σ
    guard of an "auto" error model), by default the held-out ones. Position files are fitted by :func:`kincal.calibrate`
    (one frame with --same-frame, else a frame per session), other kinds by :func:`kincal.identify.fit_observations`
    (each absolute file after the first in its own frame)."""
    if args.exclude and len(data) > 1:
        raise ValueError("--exclude names rows of one file; with several files leave the rows out of their files")
    _not_training(data, tests, bool(args.exclude))
    options.check(robot)
    points = set(kinds) == {"point"}

    def load(path: str, kind: str, held_out: bool = False):
        return read(args, robot, path) if points else observe.read_set(args, robot, path, kind, held_out)
    sets = [load(path, k) for path, k in zip(data, kinds)]
    sets = [sets[0].without_rows(args.exclude)] if args.exclude else sets
    held = [load(path, kinds[0], True) for path in tests]
    if points:
        _registrable(robot, held, options)
    if points and isinstance(use_q, str):
        use_q = np.concatenate([t.q for t in held]) if held else None
    with progress("calibrating", args.json) as say:
        if not points:
            return kincal.identify.fit_observations(robot, observe.sessions(sets, args.same_frame), options), held
        if len(sets) == 1 or args.same_frame:  # one frame: the files are one session
            return kincal.calibrate(robot, kincal.identify.joined(sets), options, use_q=use_q, progress=say), held
        say(f"calibrating {len(sets)} sessions, each in its own measurement frame")
        return kincal.identify.calibrate_sessions(robot, sets, options, use_q=use_q), held


def _registrable(robot, held: list, options) -> None:
    """Refuse, before the fit, a held-out position file of fewer than 3 distinct poses: its measurement frame is
    registered to it (re-fitted to judge it, or, with --same-frame, to tell whether the tracker moved), which
    needs 3; found only after the fit, the calibrated robot had been written with no figures printed."""
    tol = kincal.identify.verdict.repeat_tolerance(robot.joint_types, options.thresholds)
    for t in held:
        distinct = kincal.identify.verdict.distinct_count(t.q, tol, 3)
        if distinct < 3:
            raise ValueError(f"--test {t.source}: {distinct} distinct pose{'s' * (distinct != 1)} ({len(t.q)} rows); "
                             f"a held-out file's measurement frame is registered to it (to judge it, or with "
                             f"--same-frame to tell whether the tracker moved), which needs 3 at least: hold out a "
                             f"file of 3 or more poses spread over the workspace")


def _not_training(data: list[str], tests: list[str], excluded: bool = False) -> None:
    """Refuse a held-out file that is a training file (the same file, or the same bytes under another name): its
    "held-out" figures would be the training error, presented as what the model does on poses it never saw."""
    def digest(path: str) -> str:
        try:
            return fingerprint(path).sha256
        except OSError:  # the reader names what is wrong with it
            return path
    known = {digest(d): d for d in data}
    for path in tests:
        same = known.get(digest(path))
        if same is not None:
            raise ValueError(f"--test {path} holds the same data as the training file {same}: its figures would be "
                             + ("its left-out rows' mixed with the training rows'; write the rows left out (--exclude) "
                                "to a file of their own and hold that out" if excluded else
                                "the training error, not a held-out one; hold out a file of poses the fit does not see "
                                "(another session, or the rows left out of the training file, in a file of their own)"))


NOISE_MIN = 1e-3  # mm: a tracker noise below this (1 µm) given without a unit was written in metres


def _noise_mm(text: str) -> float:
    """argparse type: a tracker noise, mm: a number with a length unit (0.015mm, 15um, 1.5e-5m), or mm without one;
    a unitless value below NOISE_MIN is refused as metres."""
    s = text.strip()
    unit = next((u for u in sorted(LENGTH_UNITS, key=len, reverse=True) if s.endswith(u)), None)
    try:
        value = float(s[:-len(unit)] if unit else s) * (LENGTH_UNITS[unit] * MM if unit else 1.0)
    except ValueError:
        value = np.nan
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"'{text}': give a positive noise with its unit, e.g. 0.015mm or 15um")
    if unit is None and value < NOISE_MIN:
        raise argparse.ArgumentTypeError(f"'{text}' mm is {value * 1e6:g} nm, below any instrument's noise: metres? "
                                         f"give the unit ({text}m, or 0.015mm)")
    return value


def _training_twin(record: dict | None, path: str) -> str | None:
    """The calibration's training file (as its record names it) that holds the same bytes as ``path``, or None
    (no record, or no such file readable from here)."""
    files = ((record or {}).get("data") or {}).get("file") or []
    try:
        mine = fingerprint(path).sha256
    except OSError:
        return None
    for other in files:
        try:
            if fingerprint(str(other)).sha256 == mine:
                return str(other)
        except OSError:
            continue
    return None


def held_out(res, tests: list, same_frame: bool) -> tuple[list[str], dict]:
    """Held-out observation sets under the nominal ("before") and the calibrated model, and the
    placements of the training and held-out sets, as lines and as JSON (position data: :func:`_held_out_points`)."""
    if res.data:
        return _held_out_points(res, tests, same_frame)
    held = [(held_out_nominal(res, t, same_frame), held_out_stats(res, t, res.robot, same_frame))
            for t in tests]
    out = [f"  held out {h['type']} ({h['source']}): {stat_change(b, h)}" for b, h in held]
    envelopes = [kincal.analysis.envelope_warning(t.rows, t.q, res.robot, res.uncertainty())[1] for t in tests]
    out += [f"  warning: {w}" for w in envelopes if w]
    out += observe.group_lines(res.per_set, "training ") + observe.group_lines([h for _, h in held], "held out ")
    return out, {"held_out": [h for _, h in held], "held_out_nominal": [b for b, _ in held]}


def _held_out_points(res, tests: list, same_frame: bool) -> tuple[list[str], dict]:
    """Held-out position files judged as the report judges them: with ``same_frame`` both models as calibrated
    (the nominal one registered on the training data), else each file's frame re-fitted for both (its mean
    before → after in mm; the statistics in SI in the JSON)."""
    how = kincal.identify.AS_CALIBRATED if same_frame else kincal.identify.REGISTERED
    lines, after, before = [], [], []
    for t in tests:
        model = res.robot if same_frame else kincal.identify.refit_frame(res.robot, t)
        nominal = res.before if same_frame else kincal.identify.register_mounting(res.nominal, t.q, t.xyz)
        after.append(kincal.evaluate(model, t))
        before.append(kincal.evaluate(nominal, t))
        cause = kincal.identify.heldout_cause(model, t, res.stats_after.mean, not same_frame)  # as evaluate says
        lines.append(f"  held out {Path(t.source).name} ({how}): n={after[-1].n}  mean {before[-1].mean * MM:.4f} mm "
                     f"→ {after[-1].mean * MM:.4f} mm, max {after[-1].max * MM:.4f} mm"
                     + (f"\n  likely cause: {cause}" if cause else ""))
    return lines, ({"held_out": [{"file": t.source, "registration": how, **a.to_dict()} for t, a in zip(tests, after)],
                    "held_out_nominal": [b.to_dict() for b in before]} if tests else {})


def _covariate_ranges(res) -> dict:
    """Each covariate column's range in the training data (as read: °C, K, s), name -> (low, high)."""
    at = [res.robot.joint_names.index(n) for n in res.robot.covariate_names]
    q = np.concatenate([m.q for m in res.data]) if res.data and at else np.zeros((0, 0))
    return {n: (float(q[:, k].min()), float(q[:, k].max())) for n, k in zip(res.robot.covariate_names, at) if len(q)}


def cmd_evaluate(args) -> int:
    loaded = covariates_of(args, load_robot(args, args.data, [args.plot]))
    kinds = observe.types_of(args)
    if len(set(kinds)) > 1:
        raise ValueError("evaluate --type: one type for all files")
    record = kincal.models.load_calibration_record(args.robot) if robot_inputs(args.robot) else None
    r, unc, unread = covariates_read(loaded, kincal.analysis.load_uncertainty(args.robot) if record else None)
    judge = partial(_evaluate_points, uncertainty=unc) if kinds[0] == "point" else observe.evaluate_set
    with progress("evaluating", args.json):  # the figures of each file: STEM, or STEM-<k> for several
        judged = [judge(args, r, record, path, kinds[0],
                        args.plot and (args.plot if len(args.data) == 1 else f"{args.plot}-{k + 1}"))
                  for k, path in enumerate(args.data)]
    twins = [_training_twin(record, path) for path in args.data]
    left_out = bool(((record or {}).get("data") or {}).get("reading", {}).get("exclude"))
    judged = [({**payload, "training_file": twin}, lines + ([
        f"  note: {path} holds the same data as the calibration's training file {twin}: these figures are the "
        + ("training rows' and the rows the calibration left out (--exclude) together" if left_out else
           "training error, not a held-out one")] if twin else [])) for (payload, lines), path, twin in
        zip(judged, args.data, twins)]
    payloads = [payload for payload, _ in judged]
    stored = store_record(args, nominal_model(loaded, record, args.robot) or loaded, lambda identity, command:
                          evaluation_record(payloads, identity, [fingerprint(p) for p in args.data], command=command,
                                            robot=loaded, evaluated=fingerprint(args.robot) if record else None))
    return emit(args, {**payloads[0], "sessions": payloads} if len(payloads) == 1 else {"sessions": payloads},
                "\n".join([text for _, lines in judged for text in lines] + [t for t in (unread, stored) if t]))


def _few_bad(r, model, meas, mean: float, refit: bool) -> str:
    """The likely cause when a few poses of ``meas`` carry ``model``'s error (``mean``, m): calibrate's rule
    (:func:`kincal.identify.diagnosis.few_bad`), named with their rows when the rest (the frame of ``r`` re-fitted
    to it when ``refit``) leaves less than half that mean; "" otherwise."""
    from kincal.identify.diagnosis import EXPLAIN_RATIO, bad_rows, few_bad

    bad = few_bad(np.linalg.norm(meas.xyz - model.forward(meas.q), axis=1))
    if not len(bad) or len(meas) - len(bad) < 3:
        return ""
    rest = meas.subset(np.setdiff1d(np.arange(len(meas)), bad))
    left = kincal.evaluate(kincal.identify.refit_frame(r, rest) if refit else model, rest).mean
    if not left < EXPLAIN_RATIO * mean:
        return ""
    return (f"{bad_rows(meas, bad).cause}: without them the mean error is {left * MM:.4g} mm, not {mean * MM:.4g} mm; "
            f"check how they were measured and measure them again, or leave them out of the file")


def _evaluate_points(args, r, record: dict | None, path: str, kind: str, stem: str | None,
                     uncertainty=None) -> tuple[dict, list[str]]:
    """``r`` on one file of positions (its frame re-fitted unless --same-frame): the statistics (SI),
    the predicted σ and where the model extrapolates (``uncertainty``, from the calibration record), and the
    likely cause of an error far above the training error; the JSON payload and the lines to print."""
    meas = read(args, r, path)
    how = REFITTED if not args.same_frame else kincal.identify.AS_CALIBRATED if record else AS_GIVEN
    model = r if args.same_frame else kincal.identify.refit_frame(r, meas)
    if uncertainty is not None and not args.same_frame:  # the frame is the file's: its training σ does not count
        uncertainty = uncertainty.given(r.base_params(), r)
    stats = kincal.evaluate(model, meas, uncertainty=uncertainty)
    value = (record or {}).get("training_error")  # the mean error on the training data (m); 0 when unknown
    train_error = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0 else 0.0
    cause = _few_bad(r, model, meas, stats.mean, not args.same_frame)
    cause = cause or (kincal.identify.heldout_cause(model, meas, train_error, not args.same_frame) if train_error
                      else "")
    cause = cause or (_frame_not_given(r, meas, stats.mean) if args.same_frame and not record else "")
    texts = [f"{r.name} on {path} ({how}): {stats}" + (f"\n  likely cause: {cause}" if cause else "")]
    before, registered = _nominal_before(args, r, record, meas)
    if before is not None:
        mine = "" if args.same_frame else f" ({CALIBRATED_REGISTERED})"  # "before" refits the nominal's point too
        texts.append(f"  nominal, {registered}: mean {before * MM:.4f} mm → calibrated{mine} {stats.mean * MM:.4f} mm")
    if stem:
        from kincal.report import evaluation_figures

        texts += save_figures(evaluation_figures(model, meas), stem)
    return {"file": path, "registration": how, **stats.to_dict(), "nominal_mean": before,
            "nominal_registration": registered or None, "cause": cause or None}, texts


REFITTED = "frame re-registered to these data, kinematics fixed"  # the one model evaluate judges (the nominal: its own)
AS_GIVEN = "frame as the file gives it: it has no calibration record, its base frame is taken for the measurement frame"
CALIBRATED_REGISTERED = "its frame registered, its target point as calibrated"  # beside the nominal's "before"
FRAME_GAIN = 2.0  # --same-frame on a file without a record: a registration this many times better says why


def _frame_not_given(r, meas, mean: float) -> str:
    """Why a robot file without a calibration record may miss data measured, it is told, in its frame: its base
    frame (an export or a robot description keeps the robot's own) and its tool point were taken for where the
    instrument stood and what it measured, when registering both to the data does FRAME_GAIN times better; the
    data cannot tell which of the two is off, so both are named; '' otherwise."""
    registered = kincal.evaluate(kincal.identify.register_mounting(r, meas.q, meas.xyz), meas).mean
    if not mean > FRAME_GAIN * registered:
        return ""
    return (f"the file has no calibration record, so its base frame and tool point (the robot's own: an export or "
            f"a description keeps those) were taken for where the instrument stood and what it measured; with both "
            f"registered to these data the mean is {registered * MM:.4f} mm: if the instrument was not at the "
            f"robot's base, leave out --same-frame (or evaluate the calibrated file itself, which keeps the frame it "
            f"found); if the target is not the file's tool point, declare it (--tool)")


def _nominal_before(args, r, record: dict | None, meas) -> tuple[float | None, str]:
    """The nominal kinematics' mean error on ``meas`` (m), registered as the calibrated model is judged: with
    --same-frame its frame and target point as registered on the training data (the calibration record's, as
    the report does), else registered to these data; and how, in words. (None, '') without a record."""
    kept = nominal_model(r, record, args.robot, "before_mounting") if args.same_frame else None
    if kept is not None:
        return kincal.evaluate(kept, meas).mean, "its frame and target point as registered on the training data"
    nominal = nominal_model(r, record, args.robot)
    if nominal is None:
        return None, ""
    return (kincal.evaluate(kincal.identify.register_mounting(nominal, meas.q, meas.xyz), meas).mean,
            "its frame and target point registered to these data")


def add_covariate_flag(s) -> None:
    """--covariate-cols, of calibrate and evaluate: columns read after the joints as covariates."""
    s.add_argument("--covariate-cols", type=csv_list, default=None, metavar="COL[,COL...]",
                   help="covariate columns (a temperature, the time since power-on), read as written: the error model "
                        "thermal:COL grows the links with them and auto tries it; a model calibrated with them "
                        "reads them itself and refuses values outside the range it was fitted on")


def covariates_of(args, robot):
    """``robot`` reading the --covariate-cols after its joints (position data only: refused for the other kinds
    by :func:`kincal.identify.refuse_inapplicable`); with a named --error-model, each column must be one a term of
    it reads (thermal:COL; auto tries them all), or the flag changes nothing (ValueError)."""
    spec = vars(args).get("error_model")
    if args.covariate_cols and spec and spec != "auto":
        used = {t.split(":", 1)[1] for t in kincal.models.parse_model(spec) if t.startswith("thermal:")}
        unused = [c for c in args.covariate_cols if c not in used]
        if unused:
            raise ValueError(f"--covariate-cols {','.join(unused)}: no term of --error-model {spec} reads it (thermal:"
                             f"COL does, and auto tries it), so it would change nothing: give --error-model "
                             f"{'' if spec == 'geometric' else spec + '+'}thermal:{unused[0]} or auto, or leave the "
                             f"column out")
    return kincal.models.with_covariates(robot, args.covariate_cols)


def _pair(s: str) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in csv_list(s))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{s}': give two numbers, SUSPECT,REFUSE") from None
    if not 0 < a <= b:
        raise argparse.ArgumentTypeError(f"'{s}': need 0 < SUSPECT <= REFUSE")
    return a, b


def register(cmd) -> None:
    """Add the commands to the parser through ``cmd(name, func, help[, robot help or None])``."""
    s = cmd("calibrate", cmd_calibrate, "identify the robot's parameters from measurements")
    s.add_argument("data", nargs="+", help="measurement CSV, one per session (the tracker may move between sessions: "
                                           "each gets its own measurement frame, the kinematics are shared)")
    s.add_argument("-o", "--output", help="calibrated robot YAML to write")
    add_fit_flags(s)
    s.add_argument("--error-model", type=error_model_name,
                   help="error model: geometric, nobeta, compliance, gravity-regressor, harmonics:1..4, thermal:COL "
                        "(with --covariate-cols COL), terms joined by '+' (e.g. compliance+harmonics:2), or auto "
                        "(chosen by joint-space blocked cross-validation); default: the robot file's own")
    hidden_alias(s, "--model", "error_model", type=error_model_name)
    s.add_argument("--payload", type=nonneg_float, default=0.0,
                   help="payload at the tool in kg, for the gravity terms (default 0)")
    s.add_argument("--exclude", type=row_list, help="input rows to leave out, e.g. 12,40-42")
    s.add_argument("--residuals", help="CSV of per-pose residuals to write (mm, deg; robust z-scores, outliers); for "
                                       "the other kinds per sample: position and rotation error (mm, mrad), the "
                                       "residual against its stated σ, robust z, outlier")
    s.add_argument("--force", action="store_true", help="write the model even when the verdict is 'refused'")
    add_covariate_flag(s)
    add_session_flags(s)  # held-out sessions for the report and figures; with --error-model auto also the
    # poses where the model will be used (the prediction-σ guard)
    s.add_argument("--report", help="HTML report to write (self-contained; its JSON goes beside it)")
    s.add_argument("--plot", help="figures to write: STEM.png or STEM.svg gives STEM-<figure>.png/.svg")
    th = kincal.Thresholds()  # the defaults are the record's
    s.add_argument("--tracker-noise", type=judged(_noise_mm, lambda v: kincal.Thresholds(tracker_noise=v / MM)),
                   default=th.tracker_noise * MM,
                   help=f"expected tracker noise per axis, with its unit (0.015mm, 15um; mm without one; default "
                        f"{th.tracker_noise * MM:g}mm)")
    for kind, unit, lo, hi in (("length", "mm", th.length_suspect * MM, th.length_refuse * MM),
                               ("angle", "deg", th.angle_suspect * DEG, th.angle_refuse * DEG)):
        s.add_argument(f"--{kind}-limits", type=_pair, default=(lo, hi), metavar="SUSPECT,REFUSE",
                       help=f"largest plausible {kind} corrections, {unit} (default {lo:g},{hi:g})")
    observe.add_flags(s)
    add_store_flag(s)

    s = cmd("evaluate", cmd_evaluate, "position error statistics of a robot model on measurements")
    s.add_argument("data", nargs="+", help="measurement CSV, one per session")
    s.add_argument("--same-frame", action="store_true",
                   help="the data were measured in the model's measurement frame (the tracker did not move): use "
                        "the model as it is; by default each session's frame is re-fitted first (kinematics fixed)")
    s.add_argument("--rebase", action="store_true", help=argparse.SUPPRESS)  # the default now; accepted
    add_covariate_flag(s)
    s.add_argument("--plot", help="figures to write: STEM.png or STEM.svg gives STEM-<figure>.png/.svg")
    observe.add_refit_target(s)
    observe.add_flags(s)
    add_store_flag(s)
