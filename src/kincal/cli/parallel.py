"""Seed-2 commands: compensation (targets -> corrected joint commands) and error-model verification."""
from __future__ import annotations

import numpy as np

import kincal

from .common import MM, add_data_flags, csv_list, emit


def cmd_compensate(args) -> int:
    r = kincal.load_robot(args.robot)
    targets = kincal.read_positions(args.targets, args.xyz_cols, args.length_unit)
    start = None
    if not hasattr(r, "inverse"):
        start = kincal.read_joints(args.targets, r, args.joint_cols, args.length_unit, args.angle_unit)
    comp = kincal.compensate(r, targets, start)
    kincal.write_joints(args.output, comp.q, r, args.joint_cols, args.length_unit, args.angle_unit)
    payload = {**comp.to_dict(), "output": args.output}
    emit(args, payload, f"{len(targets)} targets: commands written to {args.output} ({comp.method}); "
                        f"largest model residual {comp.residual.max() * MM:.2e} mm")
    return 0


def cmd_verify(args) -> int:
    r = kincal.load_robot(args.robot)
    plan = kincal.verification_plan(r, r.sample_joints(args.samples, seed=args.seed), args.params)
    if args.output:
        plan.write_csv(args.output, r.joint_names)
    if args.measured or args.simulate:
        if args.measured:
            meas = kincal.read_measurements(args.measured, r, args.joint_cols, args.xyz_cols, args.length_unit,
                                            args.angle_unit)
            if len(meas) != plan.commands.shape[0] * plan.commands.shape[1]:
                raise kincal.MeasurementError(f"{args.measured}: {len(meas)} rows, the plan has "
                                              f"{plan.commands.shape[0] * plan.commands.shape[1]} (cases x samples)")
            measured = meas.xyz.reshape(plan.predicted.shape)
        else:
            true = kincal.load_robot(args.simulate)
            measured = np.array([kincal.simulate(true, c, args.noise / MM, seed=k).xyz
                                 for k, c in enumerate(plan.commands)])
        result = plan.compare(measured)
        emit(args, result.to_dict(), result.table())
    else:
        emit(args, {"cases": list(plan.cases), "commands": plan.commands.tolist(), "output": args.output},
             f"{len(plan.cases)} cases x {plan.commands.shape[1]} samples: commands written to {args.output}; "
             f"measure them in this order, then run with --measured")
    return 0


def register(cmd) -> None:
    """Add the commands to the parser through ``cmd(name, func, help)``."""
    s = cmd("compensate", cmd_compensate, "joint commands that the calibrated model says reach target positions")
    s.add_argument("robot", help="the calibrated robot (YAML)")
    s.add_argument("targets", help="CSV of target positions (serial robots: with the nominal joint values too)")
    s.add_argument("-o", "--output", required=True, help="commands CSV to write")
    add_data_flags(s)

    s = cmd("verify", cmd_verify, "error-model verification: commands to run, then the comparison (Table 5)")
    s.add_argument("robot", help="the identified (actual) robot model")
    s.add_argument("--samples", type=int, default=10)
    s.add_argument("--params", type=csv_list)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("-o", "--output", help="CSV of the commands to run (SI units), case by case")
    s.add_argument("--measured", help="measurements of those commands, in the same order")
    s.add_argument("--simulate", help="a 'true' robot YAML to simulate the measurements instead")
    s.add_argument("--noise", type=float, default=0.015, help="simulated tracker noise, mm per axis")
    add_data_flags(s)
