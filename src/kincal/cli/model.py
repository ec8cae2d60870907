"""Commands about robots and their kinematics: robots, show, identifiability, simulate, sensitivity."""
from __future__ import annotations

import argparse
import contextlib
import os
import re
import shlex

import numpy as np

import kincal
import kincal.analysis
import kincal.io
import kincal.models
from kincal.compensate import fit_frames_only
from kincal.identify import SCOPES, FitOptions, observation_identifiability, refuse_inapplicable
from kincal.identify.applies import OBSERVED, Scope, joint_unit_scopes
from kincal.identify.stacked import wanted_names
from kincal.models.export import controller_base
from kincal.observe import describe, read_observations, write_observations
from kincal.units import ANGLE_UNITS, DEG, LENGTH_UNITS, MM, SHOWN, display, joint_factors, joint_units

from . import observe
from .common import (angle_unit, csv_list, emit, finite_float, hidden_alias, joint_values, load_robot, nonneg_float,
                     one_type, positive_float, positive_int)


def cmd_robots(args) -> int:
    from rich.table import Table

    rows = [(n, kincal.load_robot(n)) for n in kincal.bundled_robots()]
    t = Table("robot", "joints", "parameters", "structure", "description")
    for n, r in rows:  # the description up to a colon or the end of its first sentence
        t.add_row(n, str(r.n_joints), str(r.n_params), r.structure, re.split(r"\. (?=[A-Z])|: ", r.description)[0])
    return emit(args, {"robots": [{"name": n, "joints": r.n_joints, "parameters": r.n_params,
                                   "structure": r.structure, "description": r.description} for n, r in rows]}, t)


FILE_FLAGS = ("joint_cols", "xyz_cols", "length_unit", "angle_unit", "orientation", "rot_cols", "markers", "label_col",
              "group_col", "distance", "plane", "std_pos", "std_rot")  # how a file is read: what show --type describes


def show_scopes(args, robot) -> dict[str, Scope]:
    """show's own table of what applies to which kind (:func:`kincal.identify.refuse_inapplicable`): with --type, the
    flags that change the description of a file of that type (its columns, units and σ, as calibrate reads them);
    without, none of the file flags (no file is described)."""
    if not args.type:
        return {k: Scope((), "without --type show describes no data file; give --type with it to see what a file of "
                             "that type holds, read so") for k in FILE_FLAGS}
    return {**{k: SCOPES[k] for k in ("xyz_cols", "orientation", "rot_cols", "markers", "label_col", "group_col",
                                      "std_pos", "std_rot")},
            **{k: Scope((), "show describes a file's columns, units and σ; known distances and planes are none of "
                            "them: give it to calibrate (or simulate, design, identifiability)")
               for k in ("distance", "plane")},
            **{k: v for k, v in joint_unit_scopes(robot.name, robot.joint_types, "a data file").items()
               if k == "angle_unit"}}  # the length unit is that of the positions, distances and planes too


def cmd_show(args) -> int:
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    r = load_robot(args)
    refuse_inapplicable([one_type(args)], args.given, show_scopes(args, r))
    covariates = r.covariate_names
    t = Table("parameter", "value", "unit", title=f"{r.name} ({r.structure}, {r.n_joints - len(covariates)} joints"
              + (f"; covariates {', '.join(covariates)}" if covariates else "") + ")")
    for n, k, v in zip(r.params.names, r.params.kinds, r.params.values):
        t.add_row(n, f"{v * SHOWN[k][1]:.6g}", SHOWN[k][0])
    lim = Table("joint", "type", "lower", "upper", "unit")
    for name, typ, lo, hi, f, u in zip(r.joint_names, r.joint_types, r.lower, r.upper,
                                       joint_factors(r.joint_types, "mm", "deg"), joint_units(r.joint_types, "mm", "deg")):
        lim.add_row(name, typ, f"{lo / f:.6g}", f"{hi / f:.6g}", u or "as written")
    notes = r.structure_notes()
    payload = {"name": r.name, "structure": r.structure, "description": r.description,
               "parameters": r.params.as_dict(), "kinds": dict(zip(r.params.names, r.params.kinds)),
               "joints": [{"name": n, "type": t, "limits": [float(v) if np.isfinite(v) else None for v in (lo, hi)]}
                          for n, t, lo, hi in zip(r.joint_names, r.joint_types, r.lower, r.upper)], "notes": notes}
    if args.type:
        payload["measurement"] = describe(r, observe.format_of(args, one_type(args)))
    lines = [Text(f"note: {n}" if n in notes else n) for n in notes + payload.get("measurement", [])]  # no markup
    return emit(args, payload, Group(t, lim, *lines))


def cmd_identifiability(args) -> int:
    kind = one_type(args)
    r = load_robot(args)
    refuse_inapplicable([kind], args.given, identifiability_scopes(args, r))
    args.poses = IDENTIFIABILITY_POSES if args.poses is None else args.poses
    args.seed = 0 if args.seed is None else args.seed
    if kind == "point":
        ident = kincal.analysis.free_parameters(r, joint_values(args, r, args.data), base=args.base,
                                                keep=args.keep or (), rank_tol=args.rank_tol)
        return emit(args, ident.to_dict(), str(ident))
    if kind in ("same-point", "plane"):  # the samples of a file or of kincal's own plan
        obs = (read_observations(args.data, r, observe.format_of(args, kind)) if args.data
               else observe.planned(args, r, r, kind, None, 0.0, args.seed))
    else:  # the type's observations at the poses of a file or at random ones
        obs = observe.planned(args, r, r, kind, joint_values(args, r, args.data), 0.0, args.seed)
    names = wanted_names(r, FitOptions(base=args.base))  # --base fixed: the base frame left out, as calibrate does
    ident, gauge = observation_identifiability(r, [obs], names, keep=args.keep or (), rank_tol=args.rank_tol)
    return emit(args, {**ident.to_dict(), "gauge": list(gauge), "type": kind}, str(ident))


AT_JOINTS = ("point", "pose", "markers")  # the kinds simulate measures at joints given or drawn at random
SIMULATE_POSES = 60  # random poses of a point, pose or markers simulation unless --poses says
# simulate's own table of what applies to which kind (kincal.identify.refuse_inapplicable): the file-layout flags
# as calibrate reads them, and those of simulate alone
SIMULATE_SCOPES = {**{k: SCOPES[k] for k in ("orientation", "rot_cols", "std_rot", "label_col", "group_col",
                                             "distance", "plane", "xyz_cols")},
                   "poses": Scope(AT_JOINTS, f"sockets and planes are touched where kincal's own plan puts them, so "
                                  f"their count is the plan's: {observe.SOCKETS_PER_POINT} seatings in each of the "
                                  f"2 sockets at 4 placements of the plate (120 samples), "
                                  f"{observe.CONTACTS_PER_PLANE} contacts per plane (60 on kincal's table and step; "
                                  f"{observe.CONTACTS_PER_PLANE} per --plane given)"),
                   "poses_file": Scope(AT_JOINTS, "sockets and planes are touched where kincal's own plan puts them, "
                                       "the true robot moved until it touches them, so joint values given in advance "
                                       "(a design's poses) have no place"),
                   "std_pos": Scope((), "simulated files carry no σ; the position noise is --noise (mm per axis)"),
                   "markers": Scope((), "simulate writes kincal's own nest of three markers, m1, m2 and m3")}


IDENTIFIABILITY_POSES = 100  # random poses of a point, pose or markers plan unless --poses says
READ_FROM_DATA = ("the measured values do not change what the samples identify: identifiability reads the joint "
                  "columns of a point, pose or markers file and the joints and labels of a socket or plane file")
PLANNED = ("without --data no file is read (kincal plans the samples: at random joint values for points, poses and "
           "markers, where its own plan puts them for sockets and planes), so a flag that says how a file is read "
           "has nothing to read")


def identifiability_scopes(args, robot) -> dict[str, Scope]:
    """identifiability's own table of what applies to which kind (:func:`kincal.identify.refuse_inapplicable`), with
    --data (the file's samples: no count, nothing drawn, only its joints and labels read, so a unit that reads none
    of ``robot``'s joints nor a value of --distance or --plane is refused) or without (kincal's plan: no file read;
    --length-unit is then the unit of --distance and --plane alone)."""
    std_pos = Scope(OBSERVED, "position data are judged by their Jacobian alone: one σ for every sample scales it "
                              "and changes nothing")
    own = {**{k: SCOPES[k] for k in ("base", "std_rot", "label_col", "group_col", "distance", "plane")},
           "std_pos": std_pos}
    valued = tuple(k for k, flag in (("same-point", "distance"), ("plane", "plane")) if flag in args.given)
    if args.data:
        beside = f"beside --data {args.data} its rows are the samples"
        return {**own, **joint_unit_scopes(robot.name, robot.joint_types, args.data, valued),
                "poses": Scope((), f"{beside}, as many as it holds"),
                "seed": Scope((), f"{beside}: nothing is drawn at random"),
                **{k: Scope((), READ_FROM_DATA) for k in ("xyz_cols", "orientation", "rot_cols", "markers")}}
    return {**own, "poses": SIMULATE_SCOPES["poses"],
            **{k: Scope((), PLANNED) for k in ("joint_cols", "xyz_cols", "orientation", "rot_cols", "markers",
                                               "label_col", "group_col", "angle_unit")},
            "length_unit": Scope(valued, f"{PLANNED}; it is the unit of the values of --distance (sockets) and "
                                         f"--plane (planes) alone")}


def cmd_simulate(args) -> int:
    r = load_robot(args, [args.poses_file], [args.output, args.save_true])
    true = (kincal.perturb(r, length=args.length_error / MM, angle=args.angle_error / DEG, seed=args.seed)
            if args.perturb else r)
    kind = one_type(args)
    refuse_inapplicable([kind], args.given, SIMULATE_SCOPES)
    if args.poses_file and args.poses is not None:
        raise ValueError(f"--poses {args.poses}: the poses are those of --poses-file {args.poses_file}; give one")
    args.poses = SIMULATE_POSES if args.poses is None else args.poses
    q = joint_values(args, r, args.poses_file)
    if args.save_true:
        kincal.save_robot(true, args.save_true)
    if kind != "point":  # observations of the type, written in its columns
        obs = observe.planned(args, r, true, kind, q, args.noise / MM, args.seed + 1)
        write_observations(args.output, obs, r, observe.format_of(args, kind))
        use, command = _read_back(args, kind, obs)
        return emit(args, {"output": args.output, "type": kind, "n": len(obs), "flags": use, "command": command},
                    f"wrote {len(obs)} simulated {kind} samples of {true.name} to {args.output}{_hint(args, command)}")
    meas = kincal.simulate(true, q, noise=args.noise / MM, seed=args.seed + 1)
    kincal.write_measurements(args.output, meas, r.joint_types, args.length_unit, angle_unit(args),
                              joint_cols=args.joint_cols, xyz_cols=args.xyz_cols)
    payload = {"output": args.output, "n": len(meas), "noise": args.noise / MM, "perturbed": bool(args.perturb),
               "true_robot": args.save_true, "true_parameters": true.params.as_dict()}
    use, command = _read_back(args, kind)
    return emit(args, {**payload, "flags": use, "command": command}, f"wrote {len(meas)} simulated measurements of "
                f"{true.name} to {args.output}" + (f" (true robot saved to {args.save_true})" if args.save_true else "")
                + _hint(args, command))


def _hint(args, command: str) -> str:
    """'; calibrate them with: COMMAND' where the output is a file to read back ('' for a stream: -o /dev/stdout)."""
    from kincal._atomic import data_on_stdout

    return f"; calibrate them with: {command}" if os.path.isfile(args.output) and not data_on_stdout() else ""


def _read_back(args, kind: str, obs=None) -> tuple[str, str]:
    """The flags that read a simulated file back (:func:`kincal.cli.observe.flags_to_use`) and the whole command:
    kincal calibrate, the robot with the URDF chain flags given, the file, those flags."""
    use = observe.flags_to_use(args, kind, obs)
    chain = [f"{args.given[k]} {shlex.quote(vars(args)[k])}" for k in ("base_link", "tip_link") if k in args.given]
    return use, " ".join(["kincal calibrate", shlex.quote(args.robot), shlex.quote(args.output), *chain, use]).strip()


def cmd_sensitivity(args) -> int:
    r = load_robot(args, [], [args.plot])
    s = kincal.analysis.sensitivity(r, r.sample_joints(args.samples, seed=args.seed), args.params)
    if args.plot:
        s.plot(args.plot)
    return emit(args, s.to_dict(), s.table() + (f"\nplot written to {args.plot}" if args.plot else ""))


def cmd_export(args) -> int:
    if "tool_load" in args.given and args.format != "frames-rapid":
        raise ValueError("--tool-load is the load a RAPID tooldata carries: for --format frames-rapid only")
    if args.format in kincal.io.FRAMES_FORMATS:
        return _export_frames(args)
    r = load_robot(args, [args.source], [args.output])
    values = (kincal.models.load_calibration_record(args.robot) or {}).get("nominal")
    base = {n: values[n] for n in r.base_params() if n in values} if isinstance(values, dict) else None
    info = kincal.export_robot(r, args.output, args.format, args.source, args.tool_link,
                               None if args.base_yaw is None else args.base_yaw / DEG,
                               args.length_unit, args.angle_unit, args.joint_names, base if base else None)
    lines = [f"{r.name}: {info['format']} written to {args.output} (checked: it reproduces the model, tool point "
             f"included, to 1e-9 m)"]
    if info.get("tool_link") and not args.tool_link:
        where = ", ".join(f"{v * MM:.3f}" for v in r.tool_point())
        lines.append(f"the tool point ({where}) mm on the flange is the fixed link '{info['tool_link']}' "
                     f"(--tool-link names it)")
    found = info["base_frame"]
    if found and any(abs(v - (base or {}).get(n, 0.0)) > 1e-12 for n, v in found.items()):  # not the nominal base
        kinds = dict(zip(r.params.names, r.params.kinds))
        kept = " (the file keeps the nominal model's base)" if info["format"] == "yaml" and base else ""
        lines.append(f"base frame found by the calibration (where the instrument saw {_base_frame_of(info)}; not "
                     f"part of the robot description{kept}): " + ", ".join(f"{k} {display(v, kinds[k], digits=(4, 4))}"
                                                               for k, v in info["base_frame"].items()))
    if info["format"] == "ur":
        tcp = np.array(info["tool_point"]) * MM
        lines.append(f"set the TCP on the controller to x {tcp[0]:+.4f}, y {tcp[1]:+.4f}, z {tcp[2]:+.4f} mm (the "
                     f"tool point in the UR flange frame); the driver will warn that the file's hash does not match "
                     f"the robot's factory calibration: expected for a tracker calibration (see docs/howto/export.md)")
    return emit(args, {**info, "output": args.output}, "\n".join(lines))


def _base_frame_of(info: dict) -> str:
    """What an export's base frame parameters place: the robot, or the URDF link they locate, named beside the
    written file's root when that is another link (a DH UR arm's base_link_inertia, 180° about z from base_link)."""
    link, root = info.get("base_frame_link"), info.get("root_link")
    if not link:
        return "the robot"
    return f"link '{link}'" + (f", not the URDF's root '{root}'" if root and root != link else "")


NOT_FOR_FRAMES = ("source", "tool_link", "joint_names", "base_yaw", "length_unit", "angle_unit")


def _export_frames(args) -> int:
    """export --format frames-krl|frames-rapid|frames-urscript: the base and tool that bring the nominal model
    nearest the calibrated one (kincal.compensate.fit_frames_only), as the controller's own data, read back
    before it is written, with what the frames leave of the calibration."""
    flags = [args.given[k] for k in NOT_FOR_FRAMES if k in args.given]
    if flags:
        raise ValueError(f"{', '.join(flags)}: not for frames data, which hold only a base and a tool")
    kincal.io.check_frames_output(args.output, args.format, tuple(args.tool_load) if args.tool_load else None)
    cal = load_robot(args, [], [args.output])
    language = args.format.removeprefix("frames-").replace("urscript", "ur")
    if cal.program_language() and cal.program_language() != language:
        own = f"frames-{cal.program_language()}".replace("frames-ur", "frames-urscript")
        raise ValueError(f"--format {args.format}: robot '{cal.name}' runs {cal.program_language()} programs (its "
                         f"robot file says language: {cal.program_language()}), and {language} data are for another "
                         f"controller: " + (f"give --format {own}" if own in kincal.io.FRAMES_FORMATS else
                                            f"kincal writes no {cal.program_language()} frames data; enter the base "
                                            f"and tool another format prints on the pendant"))
    values = (kincal.models.load_calibration_record(args.robot) or {}).get("nominal")
    if not isinstance(values, dict):
        raise ValueError(f"{args.robot}: frames data need the nominal model the controller moves with; export them "
                         f"from a calibration's robot file (kincal calibrate … -o cal.yaml), which records it")
    if not cal.has_tool_point:
        with contextlib.suppress(kincal.ModelError):  # a parallel robot has none: fit_frames_only says why no frames
            cal = cal.with_tool_point(np.zeros(3))
    unc = kincal.analysis.load_uncertainty(args.robot)
    region = None if unc is None or unc.lower is None or unc.upper is None else (unc.lower, unc.upper)
    fit = fit_frames_only(cal, cal.with_params(values), region=region)
    where = "the joint ranges of the calibration's data" if region else "the joint limits"
    base = np.linalg.inv(fit.base)  # the measurement frame (where targets are) in the robot's base
    ctrl = controller_base(cal)  # a URDF's link 'base': the controller's base frame, where its frames are
    base = base if ctrl is None else np.linalg.inv(ctrl) @ base
    note = [f"kincal frames-only correction of {cal.name}: base = the calibration's measurement frame in the "
            f"robot's base, tool = the TCP in the flange",
            f"left by the frames: RMS {fit.after_rms * 1e3:.3f} mm, max {fit.after_max * 1e3:.3f} mm over "
            f"{fit.samples} poses within {where} (compensated commands carry the rest)"]
    kincal.io.write_frames_data(args.output, args.format, base, fit.tool, note,
                                tuple(args.tool_load) if args.tool_load else None)
    lines = [f"{cal.name}: {args.format} written to {args.output} (read back by the language's reader: the frames "
             f"to 1e-9 m and 1e-9 rad)", _frame_line("base (the measurement frame in the " + (
                 "controller's base frame, the URDF's link 'base')" if ctrl is not None else "robot's base)"), base),
             _frame_line("tool (the TCP in the flange)", fit.tool),
             "angles ZYX: KUKA A, B, C; FANUC W, P, R and Yaskawa Rx, Ry, Rz are C, B, A (enter these on the pendant)",
             f"the frames alone leave RMS {fit.after_rms * 1e3:.3f} mm, max {fit.after_max * 1e3:.3f} mm, "
             f"{np.degrees(fit.rotation_after):.4f} deg of the calibrated model over {fit.samples} poses within "
             f"{where} (the nominal model with the calibration's base frame and tool point: RMS "
             f"{fit.before_rms * 1e3:.3f} mm, max {fit.before_max * 1e3:.3f} mm); compensated commands "
             f"(kincal compensate) carry the whole calibration"]
    return emit(args, {**fit.to_dict(), "format": args.format, "output": args.output, "written_base": base.tolist()},
                "\n".join(lines))


def _frame_line(what: str, T: np.ndarray) -> str:
    x, y, z, a, b, c = kincal.io.frame_numbers(T)
    return f"{what}: X {x:.4f}, Y {y:.4f}, Z {z:.4f} mm, A {a:.5f}, B {b:.5f}, C {c:.5f} deg"


def _tool_load(s: str) -> tuple[float, ...]:
    """argparse type: MASS,X,Y,Z: a mass > 0 (kg) and a centre of gravity (mm), finite."""
    try:
        v = tuple(float(x) for x in csv_list(s))
    except ValueError:
        v = ()
    if len(v) != 4 or not np.isfinite(v).all() or v[0] <= 0:
        raise argparse.ArgumentTypeError(f"'{s}': give the tool's mass (kg, > 0) and its centre of gravity x, y, z "
                                         f"(mm, tool frame), e.g. 2.5,0,0,80")
    return v


def register(cmd) -> None:
    cmd("robots", cmd_robots, "list the bundled robots", None)
    s = cmd("show", cmd_show, "show a robot's parameters (mm, deg), joints and structure notes")
    observe.add_flags(s, std=False)  # --type: also what a file of that measurement type holds for this robot

    s = cmd("identifiability", cmd_identifiability, "which parameters position data can identify")
    s.add_argument("--data", help="CSV of poses (joint columns) to analyse (default: random poses)")
    s.add_argument("--poses", type=positive_int, help=f"point, pose, markers without --data: random poses within "
                   f"the joint limits (default {IDENTIFIABILITY_POSES}; sockets and planes are as many as kincal's plan "
                   f"touches)")
    s.add_argument("--seed", type=int, help="without --data: the random poses or kincal's plan (default 0)")
    s.add_argument("--base", choices=list(kincal.analysis.BASE_MODES), default="estimate")
    s.add_argument("--keep", type=csv_list, help="parameters to prefer among confounded ones")
    s.add_argument("--rank-tol", type=positive_float, default=kincal.analysis.RANK_TOL,
                   help=f"relative singular-value tolerance, as calibrate and design use (default "
                        f"{kincal.analysis.RANK_TOL:g})")
    hidden_alias(s, "--tol", "rank_tol", type=positive_float)
    observe.add_flags(s, std=False)  # poses only: no σ columns read

    s = cmd("simulate", cmd_simulate, "simulate tracker measurements of a (perturbed) robot")
    s.add_argument("-o", "--output", required=True, help="CSV to write")
    s.add_argument("--poses", type=positive_int, help=f"point, pose, markers: random poses within the joint limits "
                   f"(default {SIMULATE_POSES}; sockets and planes are as many as kincal's plan touches)")
    s.add_argument("--poses-file", help="CSV of joint values to use instead of random poses (e.g. a design)")
    hidden_alias(s, "--joints", "poses_file")
    s.add_argument("--perturb", action="store_true", help="apply random geometric errors to the robot first")
    s.add_argument("--length-error", type=nonneg_float, default=0.5, help="mm, uniform ± (default 0.5)")
    s.add_argument("--angle-error", type=nonneg_float, default=0.05, help="deg, uniform ± (default 0.05)")
    s.add_argument("--noise", type=nonneg_float, default=0.015, help="tracker noise, mm per axis (default 0.015)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--save-true", help="write the simulated 'true' robot to this YAML")
    observe.add_flags(s, std=False)  # simulated files carry no σ columns

    s = cmd("export", cmd_export, "write a calibrated robot as URDF, UR calibration file or kincal YAML")
    s.add_argument("output", help="file to write (.urdf, .xacro or .xml: URDF; otherwise kincal YAML unless "
                                  "--format ur)")
    s.add_argument("--format", choices=[*kincal.models.FORMATS, *kincal.io.FRAMES_FORMATS], help="urdf, ur "
                   "(Universal Robots' kinematics file for the ROS driver), yaml (default: from the file name), or "
                   "frames-krl, frames-rapid, frames-urscript: a calibration as a base and a tool in the controller's "
                   "own data, for a controller that keeps its nominal kinematics (what the frames leave is printed)")
    s.add_argument("--tool-load", type=_tool_load, metavar="MASS,X,Y,Z", help="--format frames-rapid: the tool's "
                   "load its tooldata carries (kg; centre of gravity in mm in the tool frame), as your tool has it")
    s.add_argument("--from", dest="source", help="the URDF a URDF robot was read from (default: the file it names)")
    s.add_argument("--tool-link", help="add the tool point to the URDF as a fixed joint and link of this name")
    s.add_argument("--joint-names", type=csv_list, help="URDF of a DH robot: the joints' names in your robot stack, "
                   "e.g. shoulder_pan_joint,... (default: the robot file's 'names:')")
    s.add_argument("--base-yaw", type=finite_float, help="UR files: UR's Base frame is the model's base turned by "
                   "this about z, deg (default: the URDF's link 'base' where it has one, as ur_description's, turned "
                   "180 deg from base_link, through the fixed joints from the chain's base link, wherever a mounting "
                   "puts it; a URDF without it needs this; 0 for kincal's DH UR arms)")
    s.add_argument("--length-unit", default="m", choices=list(LENGTH_UNITS), help="kincal YAML: length unit")
    s.add_argument("--angle-unit", default="rad", choices=list(ANGLE_UNITS), help="kincal YAML: angle unit")

    s = cmd("sensitivity", cmd_sensitivity, "position error caused by a unit error of each parameter")
    s.add_argument("--samples", type=positive_int, default=10)
    s.add_argument("--params", type=csv_list)
    s.add_argument("--plot", help="PNG or SVG file for the plot")
    s.add_argument("--seed", type=int, default=0)
