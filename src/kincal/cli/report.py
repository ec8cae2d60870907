"""The calibration report: ``kincal report`` and the ``--report`` / ``--plot`` outputs of calibrate."""
from __future__ import annotations

from pathlib import Path

import numpy as np

import kincal

from .common import add_robot, check_paths, csv_list, emit, err, load_robot, progress, robot_inputs

OPTIONS = ("params", "base", "loss", "method", "f_scale", "keep", "tol", "max_iter", "residual", "pso_options")


def data_record(args, path, exclude) -> dict:
    """How the training data were read, kept with the calibrated robot so a report can reread them."""
    return {"file": str(path), "length_unit": args.length_unit, "angle_unit": args.angle_unit,
            "joint_cols": args.joint_cols, "xyz_cols": args.xyz_cols, "exclude": list(exclude or [])}


def write_outputs(args, res, test, info: dict) -> list[str]:
    """The report (``args.report``) and figures (``args.plot``) of a calibration; lines to print."""
    lines = []
    if args.report:
        with progress("writing the report", args.json):
            rep = kincal.build_report(res, test, info, Path(args.report).name)
            json_path = rep.write(args.report)
        lines.append(f"report written to {args.report} (numbers in {json_path})")
    if args.plot:
        lines += save_figures(kincal.figure_set(res, test), args.plot)
    return lines


def save_figures(figures: dict, stem: str) -> list[str]:
    """Each figure as ``<stem>-<name>.<ext>`` (ext from ``stem``, default png)."""
    path = Path(stem)
    ext = path.suffix if path.suffix.lower() in (".png", ".svg") else ".png"
    base = path.with_suffix("") if path.suffix.lower() in (".png", ".svg") else path
    written = []
    for name, fig in figures.items():
        target = base.parent / f"{base.name}-{name}{ext}"
        kincal.save_figure(fig, target)
        written.append(str(target))
    return [f"figures written: {', '.join(written)}"]


def cmd_report(args) -> int:
    record = kincal.load_calibration_record(args.robot)
    if not record or "nominal" not in record or "options" not in record:
        raise ValueError(f"{args.robot}: no calibration record in the file; write it with 'kincal calibrate ... -o "
                         f"{args.robot}' (the record keeps the nominal values and options the report refits)")
    data = record.get("data", {})
    train_path = args.train or data.get("file")
    if not train_path:
        raise ValueError("give the training data with --train")
    check_paths([*robot_inputs(args.robot), train_path, args.test], [args.output, kincal.json_path_for(args.output)])
    cal = load_robot(args)
    nominal = cal.with_params({k: float(v) for k, v in record["nominal"].items()})
    units = {k: getattr(args, k) if getattr(args, k) is not None else data.get(k, default)
             for k, default in (("length_unit", "m"), ("angle_unit", "rad"), ("joint_cols", None),
                                ("xyz_cols", ["x", "y", "z"]))}
    train = kincal.read_measurements(train_path, nominal, **units)
    if data.get("exclude"):
        train = train.without_rows(data["exclude"])
    test = kincal.read_measurements(args.test, nominal, **units) if args.test else None
    options = {k: record["options"][k] for k in OPTIONS if k in record["options"]}
    thresholds = kincal.Thresholds(**record["options"].get("thresholds", {}))
    with progress("refitting the calibration", args.json):
        res = kincal.calibrate(nominal, train, thresholds=thresholds, use_q=None if test is None else test.q, **options)
    gap = float(np.max(np.abs(res.robot.params.values - cal.params.values)))
    info = {"robot": f"{args.robot} (nominal values from its calibration record)",
            "units": f"{units['length_unit']}, {units['angle_unit']}"}
    if gap > 1e-9:
        info["note"] = (f"a fit of these data differs from {args.robot} by up to {gap:.3g} (SI): the report shows "
                        f"the fit of these data, not the file")
        err.print(f"kincal: warning: {info['note']}", markup=False)
    rep = kincal.build_report(res, test, info, Path(args.output).name)
    json_path = rep.write(args.output)
    emit(args, {**rep.data, "output": args.output, "json": str(json_path)},
         f"{rep.summary}\nreport written to {args.output} (numbers in {json_path})")
    return 0 if res.verdict.status != "refused" else 4


def register(cmd) -> None:
    s = cmd("report", cmd_report, "the calibration report (HTML with plots, and JSON) of a calibrated robot")
    add_robot(s, "the calibrated robot file written by 'kincal calibrate -o'")
    s.add_argument("--train", help="the calibration data (default: the file named in the robot's record)")
    s.add_argument("--test", help="held-out measurements to validate on")
    s.add_argument("-o", "--output", required=True, help="HTML file to write (the JSON goes beside it)")
    g = s.add_argument_group("data columns and units (default: as recorded by calibrate)")
    g.add_argument("--joint-cols", type=csv_list)
    g.add_argument("--xyz-cols", type=csv_list)
    g.add_argument("--length-unit", choices=["m", "mm", "um"])
    g.add_argument("--angle-unit", choices=["rad", "deg"])

