"""kincal command line: parses, calls the public API, prints (tables for people, --json for programs)."""
from __future__ import annotations

import argparse
import sys

import numpy as np
from rich.table import Table

import kincal
import kincal.design
from kincal.errors import KincalError

from kincal.cli_common import DEG, EXIT_ERROR, EXIT_NOT_CONVERGED, MM, err, out
from kincal.cli_common import add_data_flags as _add_data_flags
from kincal.cli_common import csv_list as _csv_list
from kincal.cli_common import emit as _emit
from kincal.cli_common import progress as _progress
from kincal.cli_common import read as _read


# ---- commands ------------------------------------------------------------------------------------
def cmd_robots(args) -> int:
    names = kincal.bundled_robots()
    rows = [(n, kincal.load_robot(n)) for n in names]
    t = Table("robot", "joints", "parameters", "model", "description")
    for n, r in rows:
        t.add_row(n, str(r.n_joints), str(r.n_params), r.kind, r.description.split(". ")[0].split(": ")[0])
    _emit(args, {"robots": [{"name": n, "joints": r.n_joints, "parameters": r.n_params,
                             "model": r.kind, "description": r.description} for n, r in rows]}, t)
    return 0


def cmd_show(args) -> int:
    r = kincal.load_robot(args.robot)
    t = Table("parameter", "value", "unit", title=f"{r.name} ({r.kind}, {r.n_joints} joints)")
    for n, k, v in zip(r.params.names, r.params.kinds, r.params.values):
        t.add_row(n, f"{v * MM:.6g}" if k == "length" else f"{v * DEG:.6g}", "mm" if k == "length" else "deg")
    lim = Table("joint", "type", "lower", "upper")
    for name, typ, lo, hi in zip(r.joint_names, r.joint_types, r.lower, r.upper):
        f = DEG if typ == "revolute" else MM
        lim.add_row(name, typ, f"{lo * f:.6g}", f"{hi * f:.6g}")
    notes = r.structure_notes()
    payload = {"name": r.name, "model": r.kind, "description": r.description,
               "parameters": r.params.as_dict(), "kinds": dict(zip(r.params.names, r.params.kinds)),
               "joints": [{"name": n, "type": t, "limits": [float(lo), float(hi)]}
                          for n, t, lo, hi in zip(r.joint_names, r.joint_types, r.lower, r.upper)], "notes": notes}
    if args.json:
        _emit(args, payload, None)
    else:
        out.print(t)
        out.print(lim)
        for n in notes:
            out.print(f"note: {n}")
    return 0


def cmd_identifiability(args) -> int:
    r = kincal.load_robot(args.robot)
    if args.data:
        q = kincal.read_joints(args.data, r, args.joint_cols, args.length_unit, args.angle_unit)
    else:
        q = r.sample_joints(args.poses, seed=args.seed)
    fixed = args.base == "fixed"
    ident = kincal.identifiability(r, q, exclude=r.base_params() if fixed else (),
                                   keep=list(args.keep or ()) + ([] if fixed else list(r.base_params())), tol=args.tol)
    _emit(args, ident.to_dict(), str(ident))
    return 0


def cmd_simulate(args) -> int:
    r = kincal.load_robot(args.robot)
    true = r
    if args.perturb:
        true = kincal.perturb(r, length=args.length_error / MM, angle=args.angle_error / DEG, seed=args.seed)
    if args.joints:
        q = kincal.read_joints(args.joints, r, args.joint_cols, args.length_unit, args.angle_unit)
    else:
        q = r.sample_joints(args.poses, seed=args.seed)
    meas = kincal.simulate(true, q, noise=args.noise / MM, seed=args.seed + 1)
    kincal.write_measurements(args.output, meas, r.joint_types, args.length_unit, args.angle_unit,
                              joint_cols=args.joint_cols)
    if args.save_true:
        kincal.save_robot(true, args.save_true)
    payload = {"output": args.output, "n": len(meas), "noise": args.noise / MM, "perturbed": bool(args.perturb),
               "true_robot": args.save_true, "true_parameters": true.params.as_dict()}
    _emit(args, payload, f"wrote {len(meas)} simulated measurements of {true.name} to {args.output}"
          + (f" (true robot saved to {args.save_true})" if args.save_true else ""))
    return 0


def cmd_calibrate(args) -> int:
    r = kincal.load_robot(args.robot)
    meas = _read(args, r, args.data)
    with _progress("calibrating", args.json) as say:
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
    _emit(args, payload, text)
    if not res.converged:
        err.print(f"kincal: calibration did not converge: {res.message}")
        return EXIT_NOT_CONVERGED
    return 0


def cmd_evaluate(args) -> int:
    r = kincal.load_robot(args.robot)
    meas = _read(args, r, args.data)
    stats = kincal.evaluate(r, meas, rebase=args.rebase)
    _emit(args, stats.to_dict(), f"{r.name} on {args.data}{' (base re-fitted)' if args.rebase else ''}: {stats}")
    return 0


def cmd_demo(args) -> int:
    """The seed-1 study on the 3T2R robot, in simulation."""
    from kincal.studies import seed1_study

    with _progress("seed-1 study", args.json) as say:
        study = seed1_study(seeds=args.seeds, m=args.poses, progress=say)
    _emit(args, study.to_dict(), str(study))
    return 0


def cmd_design(args) -> int:
    r = kincal.load_robot(args.robot)
    if args.candidates:
        pool = kincal.read_joints(args.candidates, r, args.joint_cols, args.length_unit, args.angle_unit)
        bad = ~r.feasible(pool)
        if bad.any():
            raise kincal.MeasurementError(f"{args.candidates}: {int(bad.sum())} candidate pose(s) break the joint "
                                          f"limits or coupled constraints (first: row {int(np.flatnonzero(bad)[0]) + 2})")
    else:
        pool = kincal.candidate_pool(r, args.pool, seed=args.seed)
    with _progress("designing poses", args.json) as say:
        say(f"{args.method} on {len(pool)} candidates")
        d = kincal.select_poses(r, pool, args.m, args.method, args.criterion, seed=args.seed, params=args.params,
                                base=args.base, bound=not args.no_bound, restarts=args.restarts,
                                generations=args.generations)
    kincal.write_joints(args.output, d.q, r, args.joint_cols, args.length_unit, args.angle_unit)
    payload = d.to_dict()
    payload["output"] = args.output
    _emit(args, payload, f"{d}\nposes written to {args.output}")
    return 0


def cmd_npose(args) -> int:
    from kincal.design import design_problem
    from kincal.design.npose import minimum_poses, pose_count_curve

    r = kincal.load_robot(args.robot)
    P = design_problem(r, kincal.candidate_pool(r, max(args.max, 200), seed=args.seed), params=args.params)
    curve = pose_count_curve(P, args.criterion, m_max=args.max, seed=args.seed)
    low = minimum_poses(r.n_joints, P.k)
    payload = {"parameters": len(P.names), "minimum_eq18": low, **curve.to_dict()}
    step = max(1, args.max // 10)
    rows = "\n".join(f"  m = {m:4d}   {args.criterion} = {v:.5g}" for m, v in
                      zip(curve.m_values[step - 1::step], curve.values[step - 1::step]))
    _emit(args, payload, f"{r.name}: {P.k} parameters, {r.n_joints} joints\n"
          f"minimum number of poses (eq. 18): {low}\n{rows}\n"
          f"the curve flattens (< 1 % gain over 10 more poses) at m = {curve.chosen}")
    return 0


def cmd_separate(args) -> int:
    r = kincal.load_robot(args.robot)
    sep = kincal.separate_ill_conditioned(r, kincal.candidate_pool(r, args.poses, seed=args.seed),
                                          threshold=args.threshold)
    _emit(args, sep.to_dict(), sep.tables())
    return 0


# ---- parser --------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kincal", description="Robot kinematic calibration.")
    p.add_argument("--version", action="version", version=f"kincal {kincal.__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def cmd(name, func, help_):
        s = sub.add_parser(name, help=help_, description=help_)
        s.add_argument("--json", action="store_true", help="machine-readable result on stdout (SI units)")
        s.set_defaults(func=func)
        return s

    cmd("robots", cmd_robots, "list the bundled robots")
    s = cmd("show", cmd_show, "show a robot's parameters (mm, deg), joints and structure notes")
    s.add_argument("robot", help="bundled name or robot YAML")

    s = cmd("identifiability", cmd_identifiability, "which parameters position data can identify")
    s.add_argument("robot")
    s.add_argument("--data", help="CSV of poses (joint columns) to analyse (default: random poses)")
    s.add_argument("--poses", type=int, default=100, help="number of random poses (default 100)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--base", choices=["estimate", "fixed"], default="estimate")
    s.add_argument("--keep", type=_csv_list, help="parameters to prefer among confounded ones")
    s.add_argument("--tol", type=float, default=1e-8, help="relative singular-value tolerance (default 1e-8)")
    _add_data_flags(s)

    s = cmd("simulate", cmd_simulate, "simulate tracker measurements of a (perturbed) robot")
    s.add_argument("robot")
    s.add_argument("-o", "--output", required=True, help="CSV to write")
    s.add_argument("--poses", type=int, default=60, help="random poses within the joint limits (default 60)")
    s.add_argument("--joints", help="CSV of joint values to use instead of random poses")
    s.add_argument("--perturb", action="store_true", help="apply random geometric errors to the robot first")
    s.add_argument("--length-error", type=float, default=0.5, help="mm, uniform ± (default 0.5)")
    s.add_argument("--angle-error", type=float, default=0.05, help="deg, uniform ± (default 0.05)")
    s.add_argument("--noise", type=float, default=0.015, help="tracker noise, mm per axis (default 0.015)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--save-true", help="write the simulated 'true' robot to this YAML")
    _add_data_flags(s)

    s = cmd("calibrate", cmd_calibrate, "identify the robot's parameters from measurements")
    s.add_argument("robot")
    s.add_argument("data", help="measurement CSV")
    s.add_argument("-o", "--output", help="calibrated robot YAML to write")
    s.add_argument("--base", choices=["estimate", "fixed"], default="estimate",
                   help="estimate the measurement (tracker) frame, or take the robot's base as known")
    s.add_argument("--loss", choices=["linear", "huber", "soft_l1"], default="linear")
    s.add_argument("--params", type=_csv_list, help="parameters to estimate (default: identifiable set)")
    s.add_argument("--keep", type=_csv_list, help="parameters to prefer among confounded ones")
    s.add_argument("--max-iter", type=int, default=100, help="Levenberg-Marquardt iteration limit (default 100)")
    s.add_argument("--method", choices=["lm", "pso", "pso+lm"], default="lm")
    s.add_argument("--residual", choices=["cartesian", "joint"], default="cartesian",
                   help="joint: commanded − inverse kinematics of the measured positions (parallel robots)")
    _add_data_flags(s)

    s = cmd("evaluate", cmd_evaluate, "position error statistics of a robot model on measurements")
    s.add_argument("robot")
    s.add_argument("data")
    s.add_argument("--rebase", action="store_true", help="re-fit only the base frame first")
    _add_data_flags(s)

    s = cmd("design", cmd_design, "choose measurement poses (writes a poses CSV)")
    s.add_argument("robot")
    s.add_argument("-m", type=int, default=60, help="number of poses (default 60)")
    s.add_argument("-o", "--output", required=True, help="poses CSV to write")
    src = s.add_mutually_exclusive_group()
    src.add_argument("--pool", type=int, default=5000, help="random feasible candidates (default 5000)")
    src.add_argument("--candidates", help="CSV of candidate poses (e.g. the poses you can reach)")
    s.add_argument("--method", default="fedorov", choices=list(kincal.design.METHODS))
    s.add_argument("--criterion", default="D", choices=list(kincal.design.CRITERIA))
    s.add_argument("--params", type=_csv_list, help="parameters to design for (default: identifiable set)")
    s.add_argument("--base", choices=["estimate", "fixed"], default="estimate")
    s.add_argument("--restarts", type=int, default=0, help="extra random starts for fedorov")
    s.add_argument("--generations", type=int, default=200, help="generations for ide / detmax-ide")
    s.add_argument("--no-bound", action="store_true", help="skip the certified bound (and D-efficiency)")
    s.add_argument("--seed", type=int, default=0)
    _add_data_flags(s)

    s = cmd("npose", cmd_npose, "how many poses: eq. 18 minimum and where the criterion curve flattens")
    s.add_argument("robot")
    s.add_argument("--criterion", default="comprehensive", choices=list(kincal.design.CRITERIA))
    s.add_argument("--max", type=int, default=100, help="largest number of poses on the curve (default 100)")
    s.add_argument("--params", type=_csv_list, help="parameters (default: identifiable set)")
    s.add_argument("--seed", type=int, default=0)

    s = cmd("separate", cmd_separate, "GCN branch-and-bound separation of ill-conditioned parameters")
    s.add_argument("robot")
    s.add_argument("--poses", type=int, default=100, help="random poses (default 100)")
    s.add_argument("--threshold", type=float, default=1e2, help="GCN threshold (default 1e2)")
    s.add_argument("--seed", type=int, default=0)

    from kincal.cli_parallel import register

    register(cmd)

    s = cmd("demo", cmd_demo, "the seed-1 study on the 3T2R robot (simulation)")
    s.add_argument("--poses", type=int, default=60, help="poses per design (default 60)")
    s.add_argument("--seeds", type=int, default=20, help="repetitions (default 20)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (KincalError, ValueError, OSError) as exc:
        msg = " ".join(str(exc).split()) if not isinstance(exc, kincal.IdentifiabilityError) else str(exc)
        err.print(f"kincal: error: {msg}", markup=False)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
