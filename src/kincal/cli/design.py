"""Commands that choose measurement poses and study the error model: design, npose, separate."""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

import kincal
import kincal.io
import kincal.analysis
import kincal.design
import kincal.identify
import kincal.models
from kincal.design import Cell
from kincal._atomic import write_text_atomic
from kincal.compensate import command_models
from kincal.identify import SCOPES, refuse_inapplicable
from kincal.identify.applies import Scope, joint_unit_scopes
from kincal.io.program_ur import measurement_program
from kincal.observe import read_observations, write_observations

from . import observe
from .common import (angle_unit, cell_lengths, csv_list, emit, err, judged, lengths, load_robot, nonneg_float,
                     nonneg_int, one_type, positive_float, positive_int, progress, check_paths)


CELL_FLAGS = {"floor", "keep_out", "tracker", "tracker_range", "cone", "reflector_axis", "joint_margin", "link_radius"}
CHECK_FLAGS = {"m", "output", "pool", "candidates", "joint_cols", "length_unit", "angle_unit", "seed", "check",
               "json"} | CELL_FLAGS
IDE = ("ide", "detmax-ide")
# a flag that sets how another works, and what it is for: given without that, it would change nothing
MODIFIERS = {**{k: (lambda a, o: o.method in IDE, "is for --method ide or detmax-ide, not {method}")
                for k in ("generations", "f0", "cr", "population")},
             "restarts": (lambda a, o: o.method == "fedorov" and not o.stratified,
                          "is for --method fedorov without coverage (criterion D or I): {method} with {criterion}"
                          "{stratified} makes no random start"),
             "weight": (lambda a, o: o.criterion == "IMSE", "is for --criterion IMSE, not {criterion}"),
             "settle": (lambda a, o: bool(a.program), "is for --program (the wait at each of its poses)"),
             **{k: (lambda a, o: a.tracker is not None, "is for --tracker (its range and line of sight)")
                for k in ("tracker_range", "cone", "reflector_axis")},
             "link_radius": (lambda a, o: bool(a.floor or a.keep_out),
                             "thickens the arm's links for --floor and --keep-out (give one of them)")}


def _unused_modifiers(args, options) -> None:
    """Refuse a flag given without what it modifies (:data:`MODIFIERS`: they were ignored), all of them named."""
    unused = [k for k, (used, _) in MODIFIERS.items() if k in args.given and not used(args, options)]
    if unused:
        said = "; ".join(f"{args.given[k]} " + MODIFIERS[k][1].format(
            method=options.method, criterion=options.criterion,
            stratified=" (one pose per stratum)" if options.stratified else "") for k in unused)
        raise ValueError(f"{said}: leave {'them' if len(unused) > 1 else 'it'} out")


AT_POSES = ("point", "pose", "markers")  # designed as poses of a pool; sockets and planes: samples of a plan
WRITES = "design writes the joint values of the poses to measure (sockets and planes: with their labels), not the "


def design_scopes(args, robot) -> dict[str, Scope]:
    """design's own table of what applies to which kind (:func:`kincal.identify.refuse_inapplicable`): the
    measured values' columns are not written, sockets and planes are samples of a plan (no pool, cell or program),
    the point design's own settings, and the units of its files of joint values alone."""
    kind = (args.type or ["point"])[0]
    plan = (f"a {kind} design chooses samples of a plan "
            f"(kincal's own, {PLAN_PER_LABEL} per socket or plane, or --candidates)")
    observed = "the other kinds are designed for the robot's and set-up parameters their samples identify"
    return {**{k: SCOPES[k] for k in ("label_col", "group_col", "distance", "plane", "std_rot", "std_pos")},
            **{k: Scope((), f"{WRITES}measured values' columns; give it to calibrate") for k in
               ("xyz_cols", "orientation", "rot_cols")},
            "markers": Scope((), f"{WRITES}markers' columns; the design is for kincal's own nest of three markers"),
            **{k: Scope(AT_POSES, f"the cell filters the poses of a tracker, pose or markers design; a {kind} plan "
                                  f"already says where the robot goes (plan it inside the cell)") for k in CELL_FLAGS},
            **{k: Scope(AT_POSES, f"{plan}, touched by hand or by a guided move at each sample, so no program is "
                                  f"written") for k in ("program", "settle")},
            "pool": Scope(AT_POSES, f"{plan}, not from a random pool"),
            "use": Scope(("point",), "a region of use other than the candidates is supported for tool-position "
                                     "(point) designs only"),
            "weight": Scope(("point",), "IMSE counts the left-out error terms of a tool position; for the other "
                                        "kinds it is I-optimality"),
            "params": Scope(("point",), observed),
            "base": Scope(("point",), f"{observed}, the measurement frame among them as the fit chooses"),
            "units": Scope(("point",), f"{observed}, scaled by their σ (--std-pos, --std-rot)"),
            **joint_unit_scopes(robot.name, robot.joint_types, "the poses CSV", CONSTRAINTS)}


def cmd_design(args) -> int:
    if args.check:
        return _design_check(args)
    r = load_robot(args, [args.candidates, args.use], [args.output, _program_path(args)])
    kind = one_type(args, f"design --type {','.join(args.type or ['point'])}")
    refuse_inapplicable([kind], args.given, design_scopes(args, r))
    imse = args.method in ("fedorov", "random")  # the default criterion: IMSE for these, D for the others
    options = kincal.DesignOptions(m=args.m, method=args.method, criterion=args.criterion or ("IMSE" if imse else "D"),
                                   seed=args.seed, names=args.params, base=args.base, certify=not args.no_bound,
                                   restarts=args.restarts, generations=args.generations, units=args.units, f0=args.f0,
                                   cr=args.cr, population=args.population, coverage=args.coverage, weight=args.weight)
    _unused_modifiers(args, options)
    if args.params:
        r.params.indices(args.params)
    if args.program and r.n_joints != 6:
        raise ValueError(f"--program ur writes URScript for a six-joint UR arm; {r.name} has {r.n_joints} joints")
    cell = cell_of(args)
    if kind in CONSTRAINTS:  # no cell: refused above
        return _design_constraints(args, r, options)
    if args.candidates:
        pool = kincal.read_joints(args.candidates, r, args.joint_cols, args.length_unit, args.angle_unit)
        kincal.io.check_joints(args.candidates, pool, r, args.length_unit, angle_unit(args),  # a unit, named
                               angle_default=args.angle_unit is None)
        bad = ~r.feasible(pool)
        if bad.any():
            raise kincal.MeasurementError(f"{args.candidates}: {int(bad.sum())} candidate pose(s) break the joint "
                                          f"limits or coupled constraints (first: row {int(np.flatnonzero(bad)[0]) + 2})"
                                          + _other_angle_unit(r, pool, args.angle_unit))
    elif cell is not None:
        pool = cell.pool(r, args.pool, seed=args.seed)
    else:
        pool = kincal.candidate_pool(r, args.pool, seed=args.seed)
    problem = _observation_problem(args, r, pool)
    use = None if args.use is None else kincal.read_joints(args.use, r, args.joint_cols, args.length_unit,
                                                           args.angle_unit)
    with progress("designing poses", args.json) as say:
        say(f"{args.method} on {len(pool)} candidates")
        d = kincal.select_poses(r, pool, options, problem=problem, cell=cell, validation_q=use)
        d, route = _route(args, r, d, pool, cell)
    if args.candidates and d.indices is not None:  # the user's own rows: IDs and every column kept
        kincal.io.write_selected_rows(args.output, args.candidates, d.indices)
        where = f"poses written to {args.output} (the chosen rows of {args.candidates}, every column kept)"
    else:
        kincal.io.write_joints(args.output, d.q, r, args.joint_cols, args.length_unit, angle_unit(args))
        where = f"poses written to {args.output}" + (f" ({args.method} leaves the candidates: new poses, no input "
                                                     f"rows)" if args.candidates else "")
    return emit(args, {**d.to_dict(), "output": args.output, **_program(args, r, route)}, f"{d}\n{where}" + (
        _program_said(args, route) if route is not None else ""))


def _design_check(args) -> int:
    """design CAL --check: the poses of a short check of a calibrated robot (kincal.design.check_poses), from the
    user's candidate rows or from random poses in the joint ranges the calibration was fitted in, inside the cell
    the cell flags give (in the robot's base frame)."""
    wrong = sorted(flag for dest, flag in args.given.items() if dest not in CHECK_FLAGS)
    if wrong:
        raise ValueError(f"design --check chooses the poses of a check of a calibrated robot; {', '.join(wrong)} "
                         f"{'does' if len(wrong) == 1 else 'do'} not apply to it (it takes -m, --pool or "
                         f"--candidates, the data columns, --seed and the cell flags)")
    _unused_modifiers(args, kincal.DesignOptions())
    check_paths([args.robot, args.candidates], [args.output])
    record = kincal.models.load_calibration_record(args.robot)
    cal = kincal.identify.Calibrated.of(kincal.load_robot(args.robot), record, args.robot)
    refuse_inapplicable(["point"], args.given, joint_unit_scopes(cal.robot.name, cal.robot.joint_types,
                                                                 "the check's poses CSV"))
    m = args.m if "m" in args.given else 10
    pool = _check_pool(args, cal, record, cell_of(args))
    with progress("designing the check", args.json):
        chosen = kincal.design.check_poses(cal.robot, pool, m, cal.repeat)
    if args.candidates:
        kincal.io.write_selected_rows(args.output, args.candidates, chosen)
    else:
        kincal.io.write_joints(args.output, pool[chosen], cal.robot, args.joint_cols, args.length_unit,
                               angle_unit(args))
    return emit(args, {"poses": len(chosen), "rows": (chosen + 2).tolist() if args.candidates else None,
                       "output": args.output},
                f"{len(chosen)} check poses of {len(pool)} candidates written to {args.output}"
                f"{_joint_units(args, cal)}: "
                f"measure them, then kincal check {args.robot} <measurements.csv> (with the joints' and positions' "
                f"units)")


def _joint_units(args, cal) -> str:
    """' (joints in deg)' and the like: the units design --check wrote the joints in ('' for the user's own rows)."""
    if args.candidates:
        return ""
    types = set(cal.robot.joint_types)
    units = [u for t, u in (("revolute", angle_unit(args)), ("prismatic", args.length_unit)) if t in types]
    return f" (joints in {' and '.join(units)})" if units else ""


def _check_pool(args, cal, record, cell) -> np.ndarray:
    """The candidates of design --check: the user's rows (each inside the cell, if one is given), else random
    poses in the joint ranges the calibration was fitted in (inside the cell)."""
    if args.candidates:
        pool = kincal.read_joints(args.candidates, cal.robot, args.joint_cols, args.length_unit, args.angle_unit)
        if cell is not None:
            model = _base_frame_model(cal.robot, record)
            bad = ~cell.allows(model, pool)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                broken = [cell.said(n) for n, v in cell.violations(model, pool[k:k + 1]).items() if v[0]]
                raise kincal.MeasurementError(f"{args.candidates}: {int(bad.sum())} candidate pose(s) leave the cell "
                                              f"(first: row {k + 2}: {', '.join(broken) or 'joint limits'}); give "
                                              f"poses inside it, or leave the cell flags out")
        return pool
    n = min(args.pool, 2000)
    if cell is not None:
        return cell.pool(_base_frame_model(cal.robot, record), n, seed=args.seed, within=(cal.lower, cal.upper))
    rng = np.random.default_rng(args.seed)
    pool = rng.uniform(cal.lower, cal.upper, size=(4 * n, len(cal.lower)))
    return pool[cal.robot.feasible(pool)][:n]


def _base_frame_model(calibrated, record):
    """The calibrated model in the robot's own base frame (the cell's), not the measurement frame its file
    keeps."""
    values = record.get("nominal") if isinstance(record, dict) and isinstance(record.get("nominal"), dict) else None
    return command_models(calibrated, values)[0]


def _program_path(args) -> str | None:
    """Where design --program writes the measurement program: beside the poses, .script."""
    return str(Path(args.output).with_suffix(".script")) if args.program else None


def _route(args, r, d, pool: np.ndarray, cell):
    """design --program: the design with its poses in the program's order and turns (kincal.design.plan_route: a
    short travel, no joint turning more than it must, every move checked against the cell with via poses where
    needed), and the route; the design as it is and None without --program. A user's candidate rows keep their
    values (the CSV holds them as given)."""
    if not args.program:
        return d, None
    rows = args.candidates is not None and d.indices is not None
    route = kincal.design.plan_route(r, d.q, cell, vias=pool, turn=not rows)
    return dataclasses.replace(d, q=route.q, indices=None if d.indices is None else d.indices[route.order]), route


def _program(args, r, route) -> dict:
    """design --program ur: the measurement program through the route written (atomically); its path, the tool
    positions (m, the robot's base frame), the vias and the travel for the JSON ({} without --program)."""
    if route is None:
        return {}
    tool, path = r.forward(route.q), str(_program_path(args))
    checked = ("every move checked against the cell (floor, keep-out boxes) at 1 deg steps; start it with the "
               "arm at pose 1: the move there is not checked" if route.checked else
               "the moves were NOT checked against any cell (no --floor or --keep-out): watch the first run")
    write_text_atomic(path, measurement_program(route.q, tool, args.settle, f"kincal design: {r.name}", route.vias,
                                                (checked,)))
    if not route.checked:
        err.print("kincal: warning: the program's moves were not checked against any cell: a movej between two "
                  "poses may put the arm into the table or a fixture; give --floor (e.g. 0mm) and --keep-out boxes "
                  "to check them", markup=False)
    vias = [{"before_pose": k + 2, "q": v.tolist()} for k, v in enumerate(route.vias) if v is not None]
    return {"program": path, "tool_positions": tool.tolist(), "moves_checked": route.checked, "vias": vias,
            "travel": route.travel, "travel_given": route.travel_given}


def _program_said(args, route) -> str:
    """The line about the program that design --program wrote."""
    moves = len(route.q) - 1
    vias = (f"; every move checked against the cell: {route.n_vias} of {moves} needed a via pose to stay inside it"
            if route.checked else "; its moves were not checked against any cell")
    return (f"\nmeasurement program written to {_program_path(args)} (movej through the poses in the CSV's order, "
            f"chosen for a short travel: the largest joint moves sum to {np.rad2deg(route.travel):.0f} deg, "
            f"{np.rad2deg(route.travel_given):.0f} in the design's order{vias}; {args.settle:g} s to settle at each; "
            f"the predicted tool positions in its comments and the JSON)")


def _criterion_flags(s) -> None:
    s.add_argument("--method", default="fedorov", choices=list(kincal.design.METHODS))
    s.add_argument("--criterion", choices=list(kincal.design.DESIGN_CRITERIA),
                   help="IMSE (default for fedorov and random): the smallest mean squared prediction error where the "
                        "robot is used, counting error terms geometry cannot describe (it won on the real UR5 and WAM, "
                        "see docs/explanation/validation.md); D for detmax and the IDE")
    s.add_argument("--use", help="CSV of joint values where the robot will work (the region of use of IMSE and I; "
                                 "default: the candidates)")
    s.add_argument("--coverage", action=argparse.BooleanOptionalAction, default=None,
                   help="one pose per joint-space stratum of the candidates (default: on for IMSE)")
    s.add_argument("--weight", type=nonneg_float, default=0.3,
                   help="IMSE: variance of each left-out error term, in units of the noise variance (default 0.3)")


def _other_angle_unit(r, q: np.ndarray, unit: str | None) -> str:
    """The hint when the joint values (N, n) as read break the limits but every pose is within them read in the
    other angle unit (degrees read as radians, or the reverse); '' otherwise."""
    declared = unit or "rad"
    other = "deg" if declared == "rad" else "rad"
    factor = np.where(r.revolute, np.deg2rad(1.0) if other == "deg" else np.rad2deg(1.0), 1.0)
    if declared not in ("rad", "deg") or not r.feasible(q * factor).all():
        return ""
    return f"; read as {other}, every pose is within them: give --angle-unit {other}"


def add_cell_flags(s, obeys: str) -> None:
    """The cell's flags (:func:`cell_of`), of the commands that choose where the robot goes (design, verify)."""
    c = s.add_argument_group(f"the cell (robot base frame; {obeys})")
    c.add_argument("--floor", type=cell_lengths(1, "0mm"),
                   help="the target stays above this height, e.g. 0mm (the mounting plane)")
    c.add_argument("--keep-out", type=judged(cell_lengths(6, "200,-300,0,600,300,400mm"),
                                             lambda t: Cell(keep_out=((np.array(t[:3]), np.array(t[3:])),))),
                   action="append", help="X0,Y0,Z0,X1,Y1,Z1[UNIT]: a box the target may not enter (repeatable)")
    c.add_argument("--tracker", type=cell_lengths(3, "3000,0,500mm"),
                   help="the tracker's position: poses it cannot see are left out")
    c.add_argument("--tracker-range", type=judged(cell_lengths(2, "500,20000mm"), lambda t: Cell(tracker_range=t)),
                   help="MIN,MAX[UNIT] distance to the tracker")
    c.add_argument("--cone", type=judged(positive_float, lambda v: Cell(cone=np.deg2rad(v))), default=30.0,
                   help="half-angle (deg) of the reflector's acceptance around its axis (default 30)")
    c.add_argument("--reflector-axis", type=judged(lengths(3, "0,0,1"), lambda t: Cell(reflector_axis=t)),
                   default=(0.0, 0.0, 1.0), help="the reflector's opening direction in the flange frame (default 0,0,1)")
    c.add_argument("--joint-margin", type=nonneg_float, default=0.0, help="degrees kept from every revolute joint's limits")
    c.add_argument("--link-radius", type=judged(cell_lengths(1, "50mm"), lambda t: Cell(link_radius=t[0])),
                   default=(0.05,), help="the arm's links as segments this thick (between its joint frames), kept "
                                         "above --floor and out of --keep-out boxes too (default 50mm)")


def cell_of(args):
    """The cell's constraints from the flags (SI, the robot's base frame), or None when none is given."""
    half = [((0.0, 0.0, 1.0), args.floor[0])] if args.floor else []
    boxes = [(np.array(b[:3]), np.array(b[3:])) for b in args.keep_out or []]
    labels = (("half-space 1", "--floor"),) + tuple((f"keep-out {k}", f"--keep-out box {k}")
                                                    for k in range(1, len(boxes) + 1))
    cell = kincal.design.Cell(tuple(half), tuple(boxes), None if args.tracker is None else np.array(args.tracker),
                              tuple(args.tracker_range) if args.tracker_range else (0.0, np.inf),
                              np.deg2rad(args.cone), tuple(args.reflector_axis),
                              np.deg2rad(args.joint_margin), args.link_radius[0], labels)
    return None if cell.empty else cell


CONSTRAINTS = ("same-point", "plane")  # plans of where the robot goes (sockets, planes): samples chosen from them
PLAN_PER_LABEL = 40  # candidate samples per socket or plane in kincal's own plan


def _observation_problem(args, robot, pool):
    """With --type pose or markers: the design problem of that measurement (whitened blocks with the
    set-up parameters), else None (tracker points, the default)."""
    if (args.type or ["point"]) == ["point"]:
        return None
    _check_observation_design(args)
    return kincal.design.observation_problem(robot, observe.planned(args, robot, robot, args.type[0], pool, 0.0,
                                                                    args.seed))


def _check_observation_design(args) -> None:
    if args.method in IDE:
        raise ValueError(f"design --type {args.type[0]}: use --method detmax or fedorov (the IDE leaves the pool)")


def _design_constraints(args, robot, options) -> int:
    """design --type same-point|plane: choose samples of a plan (a plate's sockets, a table and a step:
    the candidates file, e.g. from 'simulate --type', or kincal's own plan) by the stacked, whitened
    problem; known distances count as exact constraints on the socket points."""
    kind = args.type[0]
    _check_observation_design(args)
    plan = (read_observations(args.candidates, robot, observe.format_of(args, kind)) if args.candidates
            else observe.planned(args, robot, robot, kind, None, 0.0, args.seed, per=PLAN_PER_LABEL))
    problem = kincal.design.observation_problem(robot, plan)
    with progress("designing samples", args.json) as say:
        say(f"{args.method} on {len(plan)} candidates")
        d = kincal.select_poses(robot, plan.q, options, problem=problem)
    assert d.indices is not None  # detmax and fedorov choose among the plan's samples (checked above)
    flags = observe.flags_to_use(args, kind, plan)
    if args.candidates:
        kincal.io.write_selected_rows(args.output, args.candidates, d.indices)
        where = f"samples written to {args.output} (the chosen rows of {args.candidates}, every column kept)"
    else:
        write_observations(args.output, plan.subset(d.indices), robot, observe.format_of(args, kind))
        where = f"samples written to {args.output}; measure them and calibrate with: {flags}"
    return emit(args, {**d.to_dict(), "output": args.output, "type": kind, "flags": flags}, f"{d}\n{where}")


def cmd_npose(args) -> int:
    r = load_robot(args)
    P = kincal.design.design_problem(r, kincal.candidate_pool(r, max(args.max, 200), seed=args.seed),
                                     names=args.params, units=args.units)
    curve = kincal.design.pose_count_curve(P, args.criterion, m_max=args.max, seed=args.seed)
    low = kincal.design.minimum_poses(r.n_joints, P.k)
    payload = {"parameters": len(P.names), "minimum_eq18": low, **curve.to_dict()}
    step = max(1, args.max // 10)
    rows = "\n".join(f"  m = {m:4d}   {args.criterion} = {v:.5g}" for m, v in
                     zip(curve.m_values[step - 1::step], curve.values[step - 1::step]))
    return emit(args, payload, f"{r.name}: {P.k} parameters, {r.n_joints} joints\n"
                f"minimum number of poses (eq. 18): {low}\n{rows}\n"
                + (f"the curve flattens (< 1 % gain over 10 more poses) at m = {curve.chosen}" if curve.flattened
                   else f"the curve does not flatten within m <= {args.max} (< 1 % gain over 10 more poses): try a "
                        f"larger --max"))


def cmd_separate(args) -> int:
    r = load_robot(args)
    sep = kincal.analysis.separate_ill_conditioned(r, kincal.candidate_pool(r, args.poses, seed=args.seed),
                                                   threshold=args.threshold, keep=args.keep or ())
    return emit(args, sep.to_dict(), sep.tables())


def register(cmd) -> None:
    s = cmd("design", cmd_design, "choose measurement poses (writes a poses CSV)")
    s.add_argument("--check", action="store_true", help="ROBOT is a calibrated file: choose the poses of a short "
                                                        "check of it (default -m 10; kincal check judges them)")
    s.add_argument("-m", type=positive_int, default=60, help="number of poses (default 60)")
    s.add_argument("-o", "--output", required=True, help="poses CSV to write")
    s.add_argument("--program", choices=("ur",), help="also write the measurement program (ur: URScript, beside "
                                                     "the poses as .script): movej through the poses with a wait")
    s.add_argument("--settle", type=positive_float, default=2.0, help="--program: seconds to wait at each pose "
                                                                      "before measuring (default 2)")
    src = s.add_mutually_exclusive_group()
    src.add_argument("--pool", type=positive_int, default=5000, help="random feasible candidates (default 5000)")
    src.add_argument("--candidates", help="CSV of candidate poses (e.g. the poses you can reach)")
    add_cell_flags(s, "every pose of the pool and the design obeys it")
    _criterion_flags(s)
    s.add_argument("--params", type=csv_list, help="parameters to design for (default: identifiable set)")
    s.add_argument("--base", choices=list(kincal.analysis.BASE_MODES), default="estimate")
    s.add_argument("--restarts", type=nonneg_int, default=0, help="extra random starts for fedorov")
    s.add_argument("--generations", type=positive_int, default=200, help="generations for ide / detmax-ide")
    s.add_argument("--f0", type=positive_float, default=0.2, help="IDE F0, eq. 21 (default 0.2)")
    s.add_argument("--cr", type=positive_float, default=0.2, help="IDE crossover probability, eq. 25 (default 0.2)")
    s.add_argument("--population", type=positive_int, default=30, help="IDE's population size")
    s.add_argument("--no-bound", action="store_true", help="skip the certified bound (and D-efficiency)")
    s.add_argument("--units", choices=list(kincal.design.UNITS), default="scaled",
                   help="index units: scaled (unit-invariant, default) or paper (raw Jacobian in mm and rad)")
    s.add_argument("--seed", type=int, default=0)
    observe.add_flags(s, std=False)  # --type: design for that measurement (sockets, planes: samples of a plan)

    s = cmd("npose", cmd_npose, "how many poses: Guo et al. 2024's eq. 18 minimum and where the criterion curve "
                                "flattens")
    s.add_argument("--criterion", default="comprehensive", choices=list(kincal.design.CRITERIA))
    s.add_argument("--max", type=positive_int, default=100, help="largest number of poses on the curve (default 100)")
    s.add_argument("--units", choices=list(kincal.design.UNITS), default="scaled",
                   help="index units: scaled (unit-invariant, default) or paper (raw Jacobian in mm and rad)")
    s.add_argument("--params", type=csv_list, help="parameters (default: identifiable set)")
    s.add_argument("--seed", type=int, default=0)

    s = cmd("separate", cmd_separate, "GCN branch-and-bound separation of ill-conditioned parameters")
    s.add_argument("--poses", type=positive_int, default=100, help="random poses (default 100)")
    s.add_argument("--threshold", type=positive_float, default=1e2, help="GCN threshold (default 1e2)")
    s.add_argument("--keep", type=csv_list, help="parameters to remove last when removals tie")
    s.add_argument("--seed", type=int, default=0)
