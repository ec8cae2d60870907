"""Commands that identify and judge a model: calibrate, evaluate."""
from __future__ import annotations

import kincal

from .common import EXIT_NOT_CONVERGED, add_data_flags, csv_list, emit, err, progress, read


def cmd_calibrate(args) -> int:
    r = kincal.load_robot(args.robot)
    meas = read(args, r, args.data)
    with progress("calibrating", args.json) as say:
        res = kincal.calibrate(r, meas, params=args.params or "auto", base=args.base, loss=args.loss,
                               keep=args.keep or (), max_iter=args.max_iter, progress=say, method=args.method,
                               residual=args.residual)
    if args.output:
        kincal.save_robot(res.robot, args.output)
    payload = res.to_dict()
    payload["output"] = args.output
    text = str(res) + (f"\ncalibrated robot written to {args.output}" if args.output else "")
    if not args.json and res.identifiability.dropped:
        text += "\nnot estimated (kept nominal): " + ", ".join(res.identifiability.dropped)
    emit(args, payload, text)
    if not res.converged:
        err.print(f"kincal: calibration did not converge: {res.message}")
        return EXIT_NOT_CONVERGED
    return 0


def cmd_evaluate(args) -> int:
    r = kincal.load_robot(args.robot)
    meas = read(args, r, args.data)
    stats = kincal.evaluate(r, meas, rebase=args.rebase)
    emit(args, stats.to_dict(), f"{r.name} on {args.data}{' (base re-fitted)' if args.rebase else ''}: {stats}")
    return 0


def register(cmd) -> None:
    """Add the commands to the parser through ``cmd(name, func, help)``."""
    s = cmd("calibrate", cmd_calibrate, "identify the robot's parameters from measurements")
    s.add_argument("robot")
    s.add_argument("data", help="measurement CSV")
    s.add_argument("-o", "--output", help="calibrated robot YAML to write")
    s.add_argument("--base", choices=list(kincal.BASE_MODES), default="estimate",
                   help="estimate the measurement (tracker) frame, or take the robot's base as known")
    s.add_argument("--loss", choices=list(kincal.LOSSES), default="linear")
    s.add_argument("--params", type=csv_list, help="parameters to estimate (default: identifiable set)")
    s.add_argument("--keep", type=csv_list, help="parameters to prefer among confounded ones")
    s.add_argument("--max-iter", type=int, default=100, help="Levenberg-Marquardt iteration limit (default 100)")
    s.add_argument("--method", choices=list(kincal.CALIBRATION_METHODS), default="lm")
    s.add_argument("--residual", choices=list(kincal.RESIDUALS), default="cartesian",
                   help="joint: commanded − inverse kinematics of the measured positions (parallel robots)")
    add_data_flags(s)

    s = cmd("evaluate", cmd_evaluate, "position error statistics of a robot model on measurements")
    s.add_argument("robot")
    s.add_argument("data")
    s.add_argument("--rebase", action="store_true", help="re-fit only the base frame first")
    add_data_flags(s)
