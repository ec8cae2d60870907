"""The calibration report: ``kincal report`` and the ``--report`` / ``--plot`` outputs of calibrate."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

import kincal
import kincal.identify
import kincal.models
from kincal.units import ANGLE_UNITS, LENGTH_UNITS

from .common import add_robot, check_paths, csv_list, emit, err, load_robot, progress, robot_inputs


def json_path(html: str) -> Path:
    """Where the report's JSON goes: beside the HTML, same name, .json (kincal.report.json_path_for;
    the same rule without loading the plotting room before any work)."""
    path = Path(html)
    return path.with_suffix(".json") if path.suffix.lower() in (".html", ".htm") else Path(f"{path}.json")


def data_record(args, path, exclude) -> dict:
    """How the training data were read, kept with the calibrated robot so a report can reread them."""
    files = [str(p) for p in path] if isinstance(path, (list, tuple)) else [str(path)]
    return {"file": files[0] if len(files) == 1 else files, "length_unit": args.length_unit, "angle_unit": args.angle_unit,
            "joint_cols": args.joint_cols, "xyz_cols": args.xyz_cols, "exclude": list(exclude or [])}


def write_outputs(args, res, test, info: dict) -> list[str]:
    """The report (``args.report``) and figures (``args.plot``) of a calibration; lines to print."""
    lines = []
    if args.report:
        with progress("writing the report", args.json):
            rep = kincal.build_report(res, test, info, Path(args.report).name, same_frame=args.same_frame)
            json_path = rep.write(args.report)
        lines.append(f"report written to {args.report} (numbers in {json_path})")
    if args.plot:
        from kincal.report import figure_set

        lines += save_figures(figure_set(res, test, args.same_frame), args.plot)
    return lines


def save_figures(figures: dict, stem: str) -> list[str]:
    """Each figure as ``<stem>-<name>.<ext>`` (ext from ``stem``, default png)."""
    path = Path(stem)
    ext = path.suffix if path.suffix.lower() in (".png", ".svg") else ".png"
    base = path.with_suffix("") if path.suffix.lower() in (".png", ".svg") else path
    from kincal.report import save_figure

    written = []
    for name, fig in figures.items():
        target = base.parent / f"{base.name}-{name}{ext}"
        save_figure(fig, target)
        written.append(str(target))
    return [f"figures written: {', '.join(written)}"]


def report_columns(args) -> dict:
    """The report command's flags of how the data files are read (None: as recorded)."""
    return {"joint_cols": args.joint_cols, "xyz_cols": args.xyz_cols, "length_unit": args.length_unit,
            "angle_unit": args.angle_unit}


def cmd_report(args) -> int:
    record = kincal.models.load_calibration_record(args.robot)
    if record and "observation_options" in record:  # calibrated from observation files (--type)
        from . import observe

        return observe.cmd_report(args, record)
    if not record or "nominal" not in record or "options" not in record:
        raise ValueError(f"{args.robot}: not a calibrated robot file (no calibration record: the nominal values and "
                         f"options the report refits); calibrate first, e.g. 'kincal calibrate {args.robot} DATA.csv "
                         f"-o calibrated.yaml --report report.html', or give the calibrated file")
    data = _mapping(record.get("data", {}), args.robot, "data")
    train_paths = args.train or data.get("file")
    train_paths = [train_paths] if isinstance(train_paths, str) else train_paths
    if not isinstance(train_paths, list) or not train_paths or not all(isinstance(p, str) for p in train_paths):
        raise ValueError("give the training data with --train (the record names no data file)")
    check_paths([*robot_inputs(args.robot), *train_paths, *args.test], [args.output, json_path(args.output)])
    options = kincal.FitOptions.from_dict(record["options"], f"{args.robot}: calibration options")
    cal = load_robot(args)
    nominal = cal.with_params(_nominal(record["nominal"], args.robot))
    use_q = _use_q(record.get("use_q"), nominal, args.robot)
    given = report_columns(args)
    units: dict[str, Any] = {k: given[k] if given[k] is not None else data.get(k, default)
             for k, default in (("length_unit", "m"), ("angle_unit", "rad"), ("joint_cols", None),
                                ("xyz_cols", ["x", "y", "z"]))}
    train = [kincal.read_measurements(path, nominal, **units) for path in train_paths]
    if data.get("exclude"):
        train = [train[0].without_rows(data["exclude"])]
    tests = [kincal.read_measurements(t, nominal, **units) for t in args.test]
    with progress("refitting the calibration", args.json):
        res = kincal.identify.calibrate_sessions(nominal, train, options, use_q=use_q)
    gap = float(np.max(np.abs(res.robot.params.values - cal.params.values)))
    info = {"robot": f"{args.robot} (nominal values from its calibration record)",
            "units": f"{units['length_unit']}, {units['angle_unit']}"}
    if gap > 1e-9:
        info["note"] = (f"a fit of these data differs from {args.robot} by up to {gap:.3g} (SI): the report shows "
                        f"the fit of these data, not the file")
        err.print(f"kincal: warning: {info['note']}", markup=False)
    rep = kincal.build_report(res, tests, info, Path(args.output).name, same_frame=args.same_frame)
    json_file = rep.write(args.output)
    emit(args, {**rep.data, "output": args.output, "json": str(json_file)},
         f"{rep.summary}\nreport written to {args.output} (numbers in {json_file})")
    return 0 if res.verdict.status != "refused" else 4


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


def _nominal(values, robot: str) -> dict[str, float]:
    """The record's nominal parameter values, checked to be numbers."""
    values = _mapping(values, robot, "nominal")
    bad = [k for k, v in values.items() if isinstance(v, bool) or not isinstance(v, (int, float))]
    if bad:
        raise ValueError(f"{robot}: the calibration record's nominal value of {bad[0]} is not a number; calibrate again")
    return {str(k): float(v) for k, v in values.items()}


def add_session_flags(p) -> None:
    """--test (repeatable: one file per session) and --same-frame."""
    p.add_argument("--test", action="append", default=[], metavar="FILE",
                   help="held-out measurements, one file per session (repeat --test for several sessions); each "
                        "session's measurement frame is re-fitted to it for the nominal and the calibrated model "
                        "alike, kinematics fixed")
    p.add_argument("--same-frame", action="store_true",
                   help="the held-out sessions were measured in the training data's frame (the tracker did not "
                        "move): use the models' frames as they are")
    p.add_argument("--rebase", action="store_true", help=argparse.SUPPRESS)  # the default now; accepted


def register(cmd) -> None:
    s = cmd("report", cmd_report, "the calibration report (HTML with plots, and JSON) of a calibrated robot")
    add_robot(s, "the calibrated robot file written by 'kincal calibrate -o'")
    s.add_argument("--train", nargs="+", help="the calibration data, one file per session (default: the files named "
                                              "in the robot's record)")
    add_session_flags(s)
    s.add_argument("-o", "--output", required=True, help="HTML file to write (the JSON goes beside it)")
    g = s.add_argument_group("data columns and units (default: as recorded by calibrate)")
    g.add_argument("--joint-cols", type=csv_list)
    g.add_argument("--xyz-cols", type=csv_list)
    g.add_argument("--length-unit", choices=list(LENGTH_UNITS))
    g.add_argument("--angle-unit", choices=list(ANGLE_UNITS))

