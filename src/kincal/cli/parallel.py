"""Commands that turn a model into robot commands: compensation (targets -> corrected joint commands)
and the 3-PUU error-model verification paper's verification (commands to run, then the comparison)."""
from __future__ import annotations

import numpy as np

import kincal
import kincal.io
import kincal.analysis
from kincal.compensate import VerificationPlan, verification_plan
from kincal.units import MM

from .common import (EXIT_REFUSED, add_data_flags, add_robot, check_paths, csv_list, emit, load_robot, nonneg_float,
                     positive_float, positive_int, robot_inputs)


def cmd_compensate(args) -> int:
    check_paths([*robot_inputs(args.robot), args.targets], [args.output])
    r = load_robot(args)
    targets, rows = kincal.read_positions(args.targets, args.xyz_cols, args.length_unit, with_rows=True)
    start = None
    if not r.has_inverse:
        start = kincal.read_joints(args.targets, r, args.joint_cols, args.length_unit, args.angle_unit)
    comp = kincal.compensate(r, targets, start, rows=rows, uncertainty=kincal.analysis.load_uncertainty(args.robot))
    written = comp.all_ok or (args.skip_unreachable and comp.ok.any())
    if written:
        kincal.io.write_joints(args.output, comp.q[comp.ok], r, args.joint_cols, args.length_unit, args.angle_unit)
    payload = {**comp.to_dict(), "output": args.output if written else None}
    good = comp.residual[comp.ok]
    text = "\n".join(f"refused: {p}" for p in comp.problems)
    if written:
        text += (f"\n{int(comp.ok.sum())} of {len(targets)} targets: commands written to {args.output} ({comp.method}); "
                 f"largest model residual {good.max() * MM:.2e} mm")
    else:
        text += (f"\nnothing written to {args.output}: {len(comp.problems)} of {len(targets)} targets refused"
                 + ("" if args.skip_unreachable else " (--skip-unreachable writes the others)"))
    if comp.predicted_sigma is not None and comp.ok.any():
        s = comp.predicted_sigma[comp.ok]
        text += f"\nmodel's predicted σ at the commands: median {np.median(s) * MM:.4f} mm, max {s.max() * MM:.4f} mm"
    text += "".join(f"\nwarning: {w}" for w in comp.warnings)
    emit(args, payload, text.strip())
    return 0 if written else EXIT_REFUSED


PLAN_JOINT_TOL = 1e-5  # rad or m: measured joint values must repeat the plan's commands this closely


def cmd_verify(args) -> int:
    check_paths([*robot_inputs(args.robot), args.plan, args.measured, args.simulate], [args.output])
    r = load_robot(args)
    if args.measured and not args.plan:
        raise ValueError("--measured needs --plan FILE: the plan written with -o, whose commands were measured")
    if not (args.output or args.measured or args.simulate):
        raise ValueError("nothing to do: give -o FILE to write the commands to run; after measuring them, run "
                         "again with --plan FILE --measured MEASUREMENTS (or --simulate TRUE_ROBOT to try it)")
    plan = (VerificationPlan.read_csv(args.plan, r) if args.plan else
            verification_plan(r, r.sample_joints(args.samples, seed=args.seed), args.params))
    if args.output:
        plan.write_csv(args.output, r, args.joint_cols, args.length_unit, args.angle_unit)
    if not (args.measured or args.simulate):
        emit(args, {"cases": list(plan.cases), "commands": plan.commands.tolist(), "output": args.output},
             f"{len(plan.cases)} cases x {plan.commands.shape[1]} samples: commands written to {args.output} "
             f"({args.length_unit}, {args.angle_unit}); measure them in this order, then run with --plan "
             f"{args.output} --measured FILE")
        return 0
    result = plan.compare(_measured(args, r, plan), args.tolerance / MM)
    emit(args, result.to_dict(), result.table())
    return 0 if result.passed.all() else EXIT_REFUSED


def _measured(args, r, plan) -> np.ndarray:
    """Measured positions (C, N, 3) of the plan's commands, from a file or simulated."""
    if args.simulate:
        true = kincal.load_robot(args.simulate)
        return np.array([kincal.simulate(true, c, args.noise / MM, seed=k).xyz for k, c in enumerate(plan.commands)])
    meas = kincal.read_measurements(args.measured, r, args.joint_cols, args.xyz_cols, args.length_unit,
                                    args.angle_unit)
    cmds = plan.commands.reshape(-1, r.n_joints)
    if len(meas) != len(cmds):
        raise kincal.MeasurementError(f"{args.measured}: {len(meas)} rows, the plan {args.plan} has {len(cmds)} "
                                      f"(cases x samples, in its order)")
    off = np.abs(meas.q - cmds).max(axis=1) > PLAN_JOINT_TOL
    if off.any():
        raise kincal.MeasurementError(f"{args.measured}: the joint values in row(s) "
                                      f"{', '.join(map(str, meas.rows[off][:10]))} are not the plan's commands "
                                      f"({args.plan}); measure the plan's commands in its order")
    return meas.xyz.reshape(plan.predicted.shape)


def register(cmd) -> None:
    """Add the commands to the parser through ``cmd(name, func, help)``."""
    s = cmd("compensate", cmd_compensate, "joint commands that the calibrated model says reach target positions")
    add_robot(s, "the calibrated robot (YAML)")
    s.add_argument("targets", help="CSV of target positions (serial robots: with the nominal joint values too)")
    s.add_argument("-o", "--output", required=True, help="commands CSV to write")
    s.add_argument("--skip-unreachable", action="store_true",
                   help="write the commands that pass every check and list the refused targets")
    add_data_flags(s)

    s = cmd("verify", cmd_verify, "error-model verification (the 3-PUU paper): commands to run, then the comparison "
                                  "(its Table 5)")
    add_robot(s, "the identified (actual) robot model")
    s.add_argument("--samples", type=positive_int, default=10)
    s.add_argument("--params", type=csv_list)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("-o", "--output", help="CSV of the commands to run, case by case (in --length-unit/--angle-unit)")
    s.add_argument("--plan", help="the plan CSV written with -o (whose commands were measured)")
    s.add_argument("--measured", help="measurements of the plan's commands, in the same order")
    s.add_argument("--tolerance", type=positive_float, default=0.05, help="largest deviation per axis to pass, mm (default 0.05)")
    s.add_argument("--simulate", help="a 'true' robot YAML to simulate the measurements instead")
    s.add_argument("--noise", type=nonneg_float, default=0.015, help="simulated tracker noise, mm per axis")
    add_data_flags(s)
