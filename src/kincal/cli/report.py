"""The calibration report: ``kincal report`` and the ``--report`` / ``--plot`` outputs of calibrate."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import kincal
import kincal.identify
import kincal.models
from kincal._atomic import json_path_for  # kincal.report.json_path_for, without loading the plotting room
from kincal.units import ANGLE_UNITS, LENGTH_UNITS

from . import observe
from .history import add_store_flag, history_for_report
from .common import TYPES, verdict_exit, csv_list, emit, err, load_robot, progress


READING = ("joint_cols", "length_unit", "angle_unit", "xyz_cols", "std_cols", "orientation", "rot_cols", "markers",
           "label_col", "group_col", "distance", "plane", "std_pos", "std_rot", "exclude",
           "refit_target")  # how files are read


def data_record(args, kinds: list[str]) -> dict:
    """How the training data were read, kept with the calibrated robot so a report can reread them:
    the files, their kinds, one frame or one per file, and every reading flag."""
    return {"file": list(args.data), "kinds": list(kinds), "same_frame": bool(args.same_frame),
            "reading": {k: _plain(vars(args)[k]) for k in READING}}


def _plain(value):
    """A flag's value as YAML keeps it (tuples as lists)."""
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


def write_outputs(args, res, tests: list, info: dict) -> list[str]:
    """The report (``args.report``) and figures (``args.plot``) of a calibration; lines to print."""
    lines = []
    if args.report:
        with progress("writing the report", args.json):
            rep = kincal.build_report(res, tests, info, Path(args.report).name, same_frame=args.same_frame,
                                      history=history_for_report(args, res.nominal))
            json_file = rep.write(args.report)
        lines.append(f"report written to {args.report} (numbers in {json_file})")
    if args.plot:
        from kincal.report import figure_set

        lines += save_figures(figure_set(res, tests, args.same_frame), args.plot)
    return lines


def save_figures(figures: dict, stem: str) -> list[str]:
    """Each figure as ``<stem>-<name>.<ext>`` (ext from ``stem``, default png); the line to print. No figures:
    no file has one position per sample in the fit's frame, and the line says so."""
    from kincal.report import save_figure

    if not figures:
        return ["no figures written: they show each sample's 3-D position error, and no file here has one in the "
                "robot's frame (sessions in their own frames); the report (--report) shows every file"]
    path = Path(stem)
    base, ext = (path.with_suffix(""), path.suffix) if path.suffix.lower() in (".png", ".svg") else (path, ".png")
    targets = [base.parent / f"{base.name}-{name}{ext}" for name in figures]
    for fig, target in zip(figures.values(), targets):
        save_figure(fig, target)
    return [f"figures written: {', '.join(map(str, targets))}"]


def cmd_report(args) -> int:
    from .identify import fit_files

    record = kincal.models.load_calibration_record(args.robot) or {}
    data, options = _record_parts(args.robot, record, args.train)
    given = {"joint_cols": args.joint_cols, "xyz_cols": args.xyz_cols, "length_unit": args.length_unit,
             "angle_unit": args.angle_unit,  # read as attributes: tests track which flags a command reads
             "refit_target": args.refit_target}
    default = {"xyz_cols": ["x", "y", "z"], "length_unit": "m", "angle_unit": "rad", "orientation": "quat-wxyz",
               "refit_target": False}
    reading = argparse.Namespace(**{k: given[k] if given.get(k) is not None else data["reading"].get(k, default.get(k))
                                    for k in READING}, json=args.json, data=data["file"],
                                 same_frame=bool(data.get("same_frame") if args.same_frame is None else args.same_frame))
    reading.distance = [tuple(d) for d in reading.distance or []]
    reading.exclude = None if args.train else reading.exclude  # recorded rows are rows of the recorded files
    reading.plane = [(lab, (tuple(n), c)) for lab, (n, c) in reading.plane or []]
    cal = load_robot(args, [*data["file"], *args.test], [args.output, json_path_for(args.output)])
    nominal = nominal_model(cal, record, args.robot)  # the record has one (checked by _record_parts)
    with progress("refitting the calibration", args.json):
        res, tests = fit_files(reading, nominal, data["kinds"], data["file"], args.test, options,
                               _use_q(record.get("use_q"), nominal, args.robot))
    gap = float(np.max(np.abs(res.robot.params.values - cal.params.values)))
    info = {"robot": f"{args.robot} (nominal values from its calibration record)",
            "units": f"{reading.length_unit}, {reading.angle_unit or 'rad'}"}
    if gap > 1e-9:
        info["note"] = (f"a fit of these data differs from {args.robot} by up to {gap:.3g} (SI): the report shows "
                        f"the fit of these data, not the file")
        err.print(f"kincal: warning: {info['note']}", markup=False)
    rep = kincal.build_report(res, tests, info, Path(args.output).name, same_frame=reading.same_frame,
                              history=history_for_report(args, nominal))
    json_file = rep.write(args.output)
    return emit(args, {**rep.data, "output": args.output, "json": str(json_file)},
                f"{rep.summary}\nreport written to {args.output} (numbers in {json_file})",
                verdict_exit(res.verdict, res.converged))


def _record_parts(path: str, record: dict, train: list[str] | None) -> tuple[dict, "kincal.FitOptions"]:
    """The record's options (checked) and data: the files (``train`` when given), their kinds, how they were read
    and whether in one frame; a record that does not say (written by hand) takes ``train`` as position files read
    as the report's flags say. A ValueError names the file and what is missing."""
    if not record or "nominal" not in record or "options" not in record:
        raise ValueError(f"{path}: not a calibrated robot file (no calibration record: the nominal values and "
                         f"options the report refits); calibrate first, e.g. 'kincal calibrate {path} DATA.csv "
                         f"-o calibrated.yaml --report report.html', or give the calibrated file")
    options = kincal.FitOptions.from_dict(record["options"], f"{path}: calibration options")
    data = _mapping(record.get("data", {}), path, "data")
    recorded = [data["file"]] if isinstance(data.get("file"), str) else data.get("file")
    files = train or recorded
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        raise ValueError(f"{path}: the calibration record names no data files; give the training data with --train")
    if "kinds" in data and not isinstance(data.get("reading"), dict):
        raise ValueError(f"{path}: the calibration record lacks data: reading (how the files were read; edited by "
                         f"hand, or written by another version); calibrate again to write it")
    kinds = data.get("kinds") if isinstance(data.get("reading"), dict) else ["point"] * len(files)
    if not isinstance(kinds, list) or not kinds or not all(k in TYPES for k in kinds):
        raise ValueError(f"{path}: the calibration record's data.kinds must name the kind of each file (one of "
                         f"{', '.join(TYPES)}); calibrate again")
    return {"file": files, "kinds": kinds if not train else [kinds[0]] * len(train),
            "reading": data.get("reading") or {}, "same_frame": bool(data.get("same_frame"))}, options


def _mapping(value, robot: str, key: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{robot}: the calibration record's '{key}' must be a mapping; calibrate again")
    return value


def _use_q(value, robot, path: str) -> np.ndarray | None:
    """The record's poses of use (N, n) in SI units, or None; checked to be finite numbers per joint."""
    if value is None:
        return None
    try:
        q = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        q = np.empty((0, 0))
    if q.ndim != 2 or q.shape[1] != robot.n_joints or len(q) == 0 or not np.all(np.isfinite(q)):
        raise ValueError(f"{path}: the calibration record's 'use_q' must be rows of {robot.n_joints} joint values "
                         f"(rad or m); calibrate again")
    return q


def nominal_model(cal, record: dict | None, path: str, key: str = "nominal"):
    """The nominal model a calibrated file was fitted from (its record's nominal values, checked to be
    numbers), or None for a file without a calibration record; ``key="before_mounting"``: that model with
    its frame and target point as registered on the training data ("before" calibration), or None for a record
    without them (a file written before they were kept)."""
    if not record or "nominal" not in record or key not in record:
        return None
    values = {str(k): v for k, v in _mapping(record["nominal"], path, "nominal").items()}
    if key != "nominal":
        values.update({str(k): v for k, v in _mapping(record[key], path, key).items()})
    bad = [k for k, v in values.items() if isinstance(v, bool) or not isinstance(v, (int, float)) or k not in
           cal.params.names]
    if bad:
        raise ValueError(f"{path}: the calibration record's {key.replace('_', ' ')} value of {bad[0]} is not a "
                         f"number of this model; calibrate again")
    return cal.with_params({k: float(v) for k, v in values.items()})


def add_session_flags(p, recorded: bool = False) -> None:
    """--test (repeatable: one file per session), --same-frame and --refit-target; with ``recorded`` (a command
    that refits a calibration) the last two default to the calibration's record and have a --no- form."""
    p.add_argument("--test", action="append", default=[], metavar="FILE",
                   help="held-out measurements, one file per session (repeat --test for several sessions); each "
                        "session's measurement frame is re-fitted to it for the nominal and the calibrated model "
                        "alike, kinematics fixed")
    p.add_argument("--same-frame", **observe.switch(recorded),
                   help=("the held-out sessions were measured in the training data's frame (the tracker did not "
                         "move): use the models' frames as they are" if recorded else
                         "all the files were measured in one frame (the tracker did not move): the training files "
                         "are fitted in one measurement frame (not one each), and the held-out sessions (--test) "
                         "are judged in it as calibrated (not re-registered)") + observe.AS_RECORDED * recorded)
    p.add_argument("--rebase", action="store_true", help=argparse.SUPPRESS)  # the default now; accepted
    observe.add_refit_target(p, recorded)


def register(cmd) -> None:
    s = cmd("report", cmd_report, "the calibration report (HTML with plots, and JSON) of a calibrated robot",
            "the calibrated robot file written by 'kincal calibrate -o'")
    s.add_argument("--train", nargs="+", help="the calibration data, one file per session (default: the files named "
                                              "in the robot's record)")
    add_session_flags(s, recorded=True)
    s.add_argument("-o", "--output", required=True, help="HTML file to write (the JSON goes beside it)")
    g = s.add_argument_group("data columns and units (default: as recorded by calibrate)")
    g.add_argument("--joint-cols", type=csv_list)
    g.add_argument("--xyz-cols", type=csv_list)
    g.add_argument("--length-unit", choices=list(LENGTH_UNITS))
    g.add_argument("--angle-unit", choices=list(ANGLE_UNITS))
    add_store_flag(s, recording=False)  # the robot's history beside the report, when a store holds it

