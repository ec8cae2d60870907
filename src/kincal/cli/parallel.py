"""Commands that turn a model into robot commands: compensation (targets -> corrected joint commands)
and the error-model verification of the 3-PUU paper of 2024 ("Error analysis model of parallel robot based on
parameters identification"): commands to run, then the comparison."""
from __future__ import annotations

import contextlib
import os

import numpy as np

import kincal
import kincal.analysis
import kincal.io
import kincal.models
from kincal.compensate import (LINK_ERROR_MAX, StreamJob, TargetsFormat, VerificationPlan, base_note, command_models,
                               commandable,
                               check_folder_output, compensate_branches, compensate_file, compensate_folder,
                               compensate_program, flange_turn,
                               resolve_taught, tool_carry, unseen_at_flange, unseen_in_base, verification_plan,
                               write_folder)
from kincal.analysis.uncertainty import extrapolation_warning
from kincal.compensate.turn import poses_in
from kincal.observe import check_convention
from kincal.io.frames_file import frames_read
from kincal.papers import PUU3_2024
from kincal.units import DEG, MM

from .design import add_cell_flags, cell_of
from .common import (EXIT_REFUSED, add_data_flags, angle_unit, checked, covariates_read, csv_list, emit, err, load_robot,
                     nonneg_float, point, positive_float, positive_int, progress_bar)


def _ranges(cal, unc) -> tuple:
    """The calibration's joint ranges (lower, upper) (the robot's limits where its file records none): where the
    flange's turn and what the base frame hides are judged."""
    return (cal.lower, cal.upper) if unc is None or unc.lower is None or unc.upper is None else (unc.lower, unc.upper)


def _orientation(args, record: dict, cal, values, nominal, unc):
    """The model whose flange pose targets (a targets file with --pose, or a program's targets) are turned to, and
    why: for a calibrated file (its ``record``; ``unc`` its uncertainty), the nominal model (``nominal``, the
    commands' frame and TCP) unless the calibration's data determine its turn of the flange
    (:func:`kincal.compensate.flange_turn`: points far enough from the flange's axis, 6-D poses, several markers);
    else (a bundled robot, a URDF) None, the model itself, with no reason."""
    if not (args.pose or args.program) or not record:
        return None, None
    kinds = (record.get("data") or {}).get("kinds") or []
    lo, hi = _ranges(cal, unc)
    turn = flange_turn(cal, cal.with_params(values) if values else cal, None if unc is None else unc.covariance,
                       () if unc is None else unc.names, lo, hi, any(k in ("pose", "markers") for k in kinds))
    return (None if turn.determined else nominal), turn


def _base_line(args, record: dict, cal, unc) -> str:
    """The note on the parameters a base frame fitted to the tracker leaves as the controller has them, for commands
    in the robot's base frame (a targets file's --target-frame other than measurement, or a program's world); ''
    when the calibration knew its base (--base fixed) or the targets are in the tracker's frame."""
    options, fitted = record.get("options"), record.get("parameters")
    estimated = isinstance(options, dict) and options.get("base") == "estimate" and isinstance(fitted, list) and \
        bool(set(cal.base_params()) & set(map(str, fitted)))
    if not estimated or (not args.program and args.target_frame == "measurement"):
        return ""
    return base_note(unseen_in_base(cal, poses_in(cal, *_ranges(cal, unc))), not args.program)


def _measured_point(cal) -> np.ndarray | None:
    """The point the calibration measured (3,) m in the flange frame, the calibrated file's tool point (None for a
    model without one): where its positions are trusted when the commands turn the flange as the nominal model."""
    return cal.tool_point() if cal.has_tool_point else None


def _orientation_from(turned, turn) -> dict:
    """The JSON fields that say which model turned the flange, and why."""
    return {"orientation_from": "nominal" if turned is not None else "calibrated",
            "flange_turn": None if turn is None else turn.to_dict()}


def cmd_compensate(args) -> int:
    if args.program and os.path.isdir(args.targets):
        return _compensate_folder(args)
    _not_a_program(args)
    cal = load_robot(args, _read_files(args), [args.output])
    record, values = _calibration(args)
    uncertainty = kincal.analysis.load_uncertainty(args.robot)  # a malformed record is refused before any work
    cal, uncertainty, unread = covariates_read(cal, uncertainty)
    _doubt(args, record, unread)
    _flange_doubt(args, record, cal, uncertainty)
    _tcp_length(args.tcp)
    if "link_error_max" in args.given and args.tcp is None and not args.program:  # a program may set its TCP
        raise ValueError("--link-error-max decides how much of the calibration's move of the measured target is "
                         "carried over to the controller's TCP; without --tcp the commands are for the measured "
                         "target itself: give --tcp, or leave --link-error-max out")

    def models(tcp):  # the models for a TCP: --tcp's, or one a program sets (set_tcp)
        return command_models(cal, values, tcp, args.target_frame, args.link_error_max / MM)
    r, nominal = models(args.tcp)
    shift, carry = _carried(args, cal, values)
    if args.program:
        _same_language(args.targets, args.program)
        _program_for(cal, args.program, args.robot)
    in_robot = None if uncertainty is None else uncertainty.without(cal.base_params(), cal)  # a program's frame
    if args.program and args.program != "ur":
        return _compensate_branches(args, (cal, values, in_robot), _orientation(args, record, cal, values, cal.with_params(
            values) if values else cal, uncertainty), _base_line(args, record, cal, uncertainty))
    if "frames" in args.given:
        raise ValueError("--frames gives the frames a KRL, RAPID, FANUC or INFORM program names; URScript sets its TCP "
                         "with set_tcp (or give --tcp)")
    if args.program:
        return _compensate_program(args, (r, nominal, _measured_point(cal), in_robot), (shift, carry), models,
                                   _orientation(args, record, cal, values, nominal, uncertainty),
                                   _base_line(args, record, cal, uncertainty))
    carry = carry if args.tcp is not None else ""
    fmt = TargetsFormat(args.pose, tuple(args.joint_cols) if args.joint_cols else None, tuple(args.xyz_cols),
                        args.orientation, tuple(args.rot_cols) if args.rot_cols else None, args.length_unit,
                        args.angle_unit)
    turned, turn = _orientation(args, record, cal, values, nominal, uncertainty)
    in_robot = uncertainty if uncertainty is None or args.target_frame == "measurement" else \
        uncertainty.without(cal.base_params(), cal)  # commands in a robot frame do not depend on the tracker's
    _frame_doubt(args, uncertainty, in_robot)
    body, body_note = _body(args, record)
    job = StreamJob(r, nominal, fmt, in_robot, args.output_kind, args.path, turned, body, _measured_point(cal))
    with progress_bar(args, "compensating") as bar:
        res = compensate_file(job, args.targets, args.output, skip_unreachable=args.skip_unreachable,
                              workers=args.workers, progress=bar)
    payload = {**res.to_dict(), "output": args.output if res.written else None, "target_frame": args.target_frame,
               "output_kind": args.output_kind, "tool_carry": carry or None,
               **(_orientation_from(turned, turn) if args.pose else {"orientation_from": None})}
    unseen = _base_line(args, record, cal, uncertainty)
    payload["base_note"] = unseen or None
    alone = "" if values else (f"note: {args.robot} has no calibration record: the commands are this model's own "
                               f"inverse kinematics, orientation included (no nominal model to correct, no σ)")
    text = _compensation_text(args, res, r) + (f"\n{body_note}" if body_note else "") + \
        (f"\nTCP: {carry}" if carry else "") + \
        (f"\n{turn.note()}" if turn is not None else "") + (f"\n{unseen}" if unseen else "") + \
        (f"\n{alone}" if alone else "")
    return emit(args, payload, text, 0 if res.written else EXIT_REFUSED)


SHOWN_PROBLEMS = 50  # refused rows listed on the terminal (all of them with --json)


def _compensation_text(args, res, r) -> str:
    """What compensate prints: refused rows, what was written, the largest joint move and orientation change."""
    shown = res.problems[:SHOWN_PROBLEMS]
    text = "\n".join(f"refused: {p}" for p in shown)
    if len(res.problems) > len(shown):
        text += f"\n… and {len(res.problems) - len(shown)} more refused rows (all of them with --json)"
    frame = f"targets in the '{args.target_frame}' frame"
    big = res.largest
    if res.written:
        text += (f"\n{res.accepted} of {res.targets} targets ({frame}): commands written to {args.output} "
                 f"({res.method}); largest model residual {big['residual'] * MM:.2e} mm")
        if "change" in big:
            text += "\nlargest change per joint: " + ", ".join(
                f"{j} {d * DEG:.4f} deg" if t == "revolute" else f"{j} {d * MM:.4f} mm"
                for j, t, d in zip(r.joint_names, r.joint_types, big["change"]))
        if "orientation_change" in big:
            text += (f"\npredicted change of the tool orientation: up to {big['orientation_change'] * 1e3:.3f} mrad "
                     f"(position-only compensation)")
        if "rotation_residual" in big:
            text += f"\nlargest orientation residual {big['rotation_residual'] * 1e3:.2e} mrad"
        if args.output_kind == "cartesian":
            text += (f"\nfiltered poses ({args.orientation}) written: send them to a controller moving with the "
                     f"nominal model; its inverse kinematics give the commands listed beside them")
    else:
        text += (f"\nnothing written to {args.output}: {len(res.problems)} problem(s) for {res.targets} targets "
                 f"({frame})" + ("" if args.skip_unreachable else " (--skip-unreachable writes the others)"))
    if res.sigma_median is not None:
        text += (f"\nmodel's predicted σ at the commands: median {res.sigma_median * MM:.4f} mm, "
                 f"max {res.sigma_max * MM:.4f} mm")
    return (text + "".join(f"\nwarning: {w}" for w in res.warnings)).strip()


def _same_language(path: str, program: str) -> None:
    """ValueError when the file's suffix names another language than --program (read as the wrong one, a program
    shows no targets at all)."""
    try:
        named = kincal.io.dialect_of(path)
    except ValueError:
        return  # a suffix no language claims: --program says what it is
    if named != program:
        raise ValueError(f"{path}: its suffix is a {named} program's, not {program}'s; give --program {named} (or "
                         f"rename the file if it really is {program})")


def _program_for(robot, program: str, source) -> None:
    """ValueError when the robot file says its controller runs programs of another language than --program (a
    calibration applied to another robot's program would be compensated on the wrong geometry, every check passing)."""
    own = robot.program_language()
    if own and own != program:
        raise ValueError(f"{source}: robot '{robot.name}' runs {own} programs (its robot file says language: {own}); "
                         f"this is a {program} program: give the calibration of the robot it was written for")


NOT_FOR_BRANCHES = ("tcp", "pose", "orientation", "rot_cols", "path", "output_kind", "workers",
                    "target_frame", "joint_cols", "xyz_cols", "length_unit", "angle_unit")


def _carried(args, cal, values) -> tuple[np.ndarray, str]:
    """What of the calibration's move of the declared target point is carried over to the controller's TCP (3,) m,
    and the sentence that says so (:func:`tool_carry`); zeros and '' for a model without a tool point."""
    if not cal.has_tool_point:
        if "link_error_max" in args.given:
            raise ValueError(f"--link-error-max: {args.robot} has no tool point, so the calibration moved no declared "
                             f"target point to carry over to a TCP: leave --link-error-max out")
        return np.zeros(3), ""
    return tool_carry(cal.tool_point(), (cal.with_params(values) if values else cal).tool_point(),
                      args.link_error_max / MM)


def _compensate_branches(args, calibrated, orientation, unseen: str) -> int:
    """compensate --program krl|rapid|fanuc|inform: the program compensated on the branch each target states
    (kincal.compensate.branch), written to -o only when every target passed or with --skip-unreachable.
    ``calibrated``: the calibrated model, its nominal values and its uncertainty in the robot's base frame."""
    cal, values, unc = calibrated
    flags = [args.given[k] for k in NOT_FOR_BRANCHES if k in args.given]
    if flags:
        raise ValueError(f"{', '.join(flags)}: not for a {args.program} program, whose targets carry their own frames "
                         f"(--frames), units and orientation")
    model, nominal = command_models(cal, values)  # both in the robot's base frame, the controller's world
    prog = _read_program(args)
    frames = kincal.io.read_frames(args.frames) if args.frames else {}
    turned, turn = orientation
    shift, carry = _carried(args, cal, values)  # the tool frames' TCPs move as --tcp's would (command_models)
    res = compensate_branches(model, nominal, prog, kincal.io.ROWS[args.program], frames, orientation=turned,
                              carry=shift)
    written = not res.problems or args.skip_unreachable  # no target at all: the program as it was
    if written:
        kincal.io.write_program(args.output, prog, res.texts, res.refused)
    lines = [f"{len(res.texts)} of {len(prog.targets)} literal targets compensated on their own branch, each "
             f"checked as written" + (f"; program written to {args.output} (every other byte as it was)" if written
                                      else f"; nothing written to {args.output}" + (
                                          " (--skip-unreachable writes the others)" if res.texts else ""))]
    lines += [f"refused: {res.foreign}"] if res.foreign else []
    declared = kincal.io.dialects()[args.program].frames(prog)
    known = sorted(k for k, v in declared.items() if not isinstance(v, str))
    lines += [f"frames the program declares or holds beside it: {', '.join(known)}"] if known else []
    lines += _taught_lines(model, nominal, frames, turned, shift)
    lines += [f"refused: {p}" for p in res.problems]
    lines += _left_lines(res)
    warned = _sigma_warnings(model, prog, res, unc)
    if prog.targets:  # how targets were corrected: nothing to say of a program without any
        lines += ([f"TCP: {carry}"] if carry else []) + ([turn.note()] if turn is not None else []) + (
            [unseen] if unseen else []) + [f"warning: {w}" for w in warned]
    return emit(args, {"compensated": len(res.texts), "targets": len(prog.targets), "problems": list(res.problems),
                       "declared_frames": known, **_left_dict(res), "tool_carry": carry or None,
                       "output": args.output if written else None, **_orientation_from(turned, turn),
                       "base_note": unseen or None, "warnings": warned},
                "\n".join(lines), 0 if written else EXIT_REFUSED)


def _sigma_warnings(model, prog, res, unc) -> list[str]:
    """The predicted σ at a program's compensated targets, each at its TCP on the calibrated model (``res.tcp``),
    warned of as for a targets file (:func:`kincal.analysis.uncertainty.extrapolation_warning`: where the model
    extrapolates, or a TCP far from the measured point whose flange turn the data leave open), naming the
    program's lines; one warning per TCP. None without the calibration's uncertainty (``unc``)."""
    if unc is None or res.tcp is None:
        return []
    done = np.all(np.isfinite(res.tcp), axis=1) & np.all(np.isfinite(res.q), axis=1)
    lines, out = np.array([t.line for t in prog.targets]), []
    for tcp in np.unique(res.tcp[done], axis=0):
        at = done & np.all(res.tcp == tcp, axis=1)
        robot = model.with_tool_point(tcp)
        out.append(extrapolation_warning(lines[at], unc.sigma(robot, res.q[at]), unc, res.q[at], robot, "line"))
    return [w for w in out if w]


def _read_files(args) -> list[str]:
    """Every file compensate reads for one targets file or program: it, the files its language's reader reads
    beside it (a KRL .dat's module .src, the controller's $config.dat and $machine.dat: Dialect.beside) and the
    frames file's (frames_read); an output must replace none of them."""
    beside = kincal.io.dialects()[args.program].beside(args.targets) if args.program else ()
    return [args.targets, *beside, *(frames_read(args.frames) if args.frames else ())]


def _not_a_program(args) -> None:
    """Refuse a targets file whose suffix is a robot program's, given without --program."""
    language = None
    if not args.program and not os.path.isdir(args.targets):
        with contextlib.suppress(ValueError):  # a suffix no language has: a targets file
            language = kincal.io.dialect_of(args.targets)
    if language:
        raise ValueError(f"{args.targets} looks like a {language} program (its suffix): give --program {language} "
                         f"(without it the file is read as a CSV of targets)")


def _doubt(args, record: dict, unread: str = "") -> None:
    """On stderr (the commands' output stays as it is): the calibration's verdict when it was not good; ``unread``,
    the note on covariates no term reads (:func:`covariates_read`)."""
    if unread:
        err.print(unread, markup=False)
    if record.get("verdict") in ("suspect", "refused"):
        err.print(f"warning: {args.robot} was calibrated with the verdict {str(record['verdict']).upper()} (its "
                  f"report says why): these commands carry that doubt", markup=False)


def _flange_doubt(args, record: dict, cal, unc) -> None:
    """On stderr: a calibration from markers alone (fitted where they sit on the flange) leaves the parameters that
    the nest's pose takes up (the last link's: :func:`kincal.compensate.unseen_at_flange`) as the controller has
    them; the flange and a TCP carry their real errors, which the predicted σ leaves out. With a point or pose set
    beside them the tool point is measured, and carried to the TCP as for point data: nothing to say."""
    setup, fitted, data = record.get("setup"), record.get("parameters"), record.get("data")
    kinds = data.get("kinds") if isinstance(data, dict) else None
    if not (isinstance(setup, dict) and setup.get("markers")) or not isinstance(fitted, list) or \
            not isinstance(kinds, list) or set(map(str, kinds)) != {"markers"}:  # a point on the TCP measured too
        return
    names = [n for n in unseen_at_flange(cal, poses_in(cal, *_ranges(cal, unc))) if n not in set(map(str, fitted))]
    if names:
        err.print(f"warning: flange: {', '.join(names)} not corrected: the calibration fitted where its markers sit on "
                  f"the flange, and the markers' positions took these up, so the flange and a TCP on it keep them as "
                  f"the controller has them (the predicted σ leaves them out); to correct them, calibrate with a "
                  f"point on the TCP measured too (--type point or pose)", markup=False)


TCP_MIN = 1e-3  # m: a TCP nearer the flange than this, and not on it, is a unit slip (0,0,0.109mm for 109 mm)


def _tcp_length(tcp) -> None:
    """Refuse a --tcp nearer the flange than TCP_MIN but not on it: no tool's point is there; a unit slip."""
    d = 0.0 if tcp is None else float(np.linalg.norm(tcp))
    if 0.0 < d < TCP_MIN:
        raise ValueError(f"--tcp is {d * MM:.3g} mm from the flange: no tool's TCP lies that close unless it is the "
                         f"flange itself (give 0,0,0); is it in another unit (0,0,0.109mm for 0,0,109mm)?")


FRAME_DOUBT = 3.0  # the model this many times less certain in the robot's frame than in the instrument's: said


def _frame_doubt(args, uncertainty, in_robot) -> None:
    """On stderr: when the calibrated model is FRAME_DOUBT times less certain in the robot's own base frame than in
    the instrument's (σ over the training region, the record's envelope), the data do not fix where that frame
    lies among the robot's geometry (a hexapod's base and platform points and legs' zeros), and commands for
    targets given in it carry that doubt. A serial arm's ratio is 0.9 to 1.5; the Jugglebot's 6 and 34."""
    if uncertainty is None or in_robot is uncertainty or not uncertainty.envelope_sigma or \
            not in_robot.envelope_sigma or in_robot.envelope_sigma <= FRAME_DOUBT * uncertainty.envelope_sigma:
        return
    err.print(f"warning: in the robot's base frame the calibrated model is "
              f"{in_robot.envelope_sigma / uncertainty.envelope_sigma:.1f}x less certain than in the instrument's "
              f"(σ over the training region {in_robot.envelope_sigma * MM:.3f} mm against "
              f"{uncertainty.envelope_sigma * MM:.3f} mm): the data do not fix where the robot's own frame lies among "
              f"its geometry, so targets given in it can miss by that much; give them in the measurement frame "
              f"(--target-frame measurement) or a frame taught with the robot, or calibrate with the robot's base "
              f"frame known (--base fixed)", markup=False)


def _read_program(args):
    """The program --program reads; a file in which that language finds nothing at all and whose suffix is none
    of the language's is refused (another language's file, or no program: 0 of 0 targets said nothing)."""
    prog = kincal.io.read_program(args.targets, args.program)
    suffixes = kincal.io.dialects()[args.program].suffixes
    if not prog.targets and not prog.not_literal and os.path.splitext(args.targets)[1].lower() not in suffixes:
        raise ValueError(f"{args.targets}: read as {args.program}, it holds no move and no position, and its suffix "
                         f"is none of {args.program}'s ({', '.join(suffixes)}): is it a {args.program} program? "
                         f"(--program names the language)")
    return prog


def _calibration(args) -> tuple[dict, dict | None]:
    """The robot file's calibration record ({} for a bundled robot or a URDF) and its nominal values (None without);
    refused for a program, whose targets are the controller's nominal model's: with one model nothing corrects."""
    record = kincal.models.load_calibration_record(args.robot) or {}
    values = record.get("nominal") if isinstance(record.get("nominal"), dict) else None
    if values is not None and "tool" in args.given:
        fitted = kincal.load_robot(args.robot).tool_point() * MM
        raise ValueError(f"--tool replaces the target point {args.robot} holds, the one its calibration fitted "
                         f"({', '.join(f'{v:.3f}' for v in fitted)} mm in the flange frame): the commands would be "
                         f"for a point the data did not determine; leave --tool out (the commands are for the "
                         f"measured point), or give the TCP to command with --tcp")
    if values is None and args.program:
        raise ValueError(f"{args.robot} holds one model and no calibration record: a program's targets are the "
                         f"controller's nominal model's, corrected with the calibrated one, so there is nothing to "
                         f"correct; give the file `kincal calibrate -o` wrote")
    return record, values


def _compensate_folder(args) -> int:
    """compensate FOLDER --program krl|rapid|fanuc|inform -o NEW_FOLDER: every program file of the language,
    with one report (kincal.compensate.folder); written only when nothing is refused or unreadable, or with
    --skip-unreachable."""
    if args.program == "ur":
        raise ValueError(f"{args.targets}: a folder of programs: --program krl, rapid, fanuc or inform (URScript "
                         f"programs are compensated one file at a time)")
    flags = [args.given[k] for k in NOT_FOR_BRANCHES if k in args.given]
    if flags:
        raise ValueError(f"{', '.join(flags)}: not for {args.program} programs, whose targets carry their own frames "
                         f"(--frames), units and orientation")
    check_folder_output(args.targets, args.output)
    cal, unc, unread = covariates_read(load_robot(args, [*([args.frames] if args.frames else [])], []),
                                       kincal.analysis.load_uncertainty(args.robot))
    _program_for(cal, args.program, args.robot)
    record, values = _calibration(args)
    _doubt(args, record, unread)
    _flange_doubt(args, record, cal, unc)
    model, nominal = command_models(cal, values)  # both in the robot's base frame, the controller's world
    frames = kincal.io.read_frames(args.frames) if args.frames else {}
    turned, turn = _orientation(args, record, cal, values, nominal, unc)
    shift, carry = _carried(args, cal, values)
    res = compensate_folder(model, nominal, args.targets, args.program, kincal.io.ROWS[args.program], frames, turned,
                            shift)
    others = _left_out_line(res)
    if not res.files:
        suffixes = ", ".join(kincal.io.dialects()[args.program].suffixes)
        raise ValueError(f"{args.targets}: no {args.program} program in this folder (suffixes {suffixes})"
                         + (f"; {others}" if others else ""))
    stuck = res.count("refused") + res.count("unreadable")
    written = not stuck or args.skip_unreachable
    if written:
        write_folder(res, args.output)
    refused = [f"refused: {f.path}: line {line} ({what}): {why}" for f in res.files for line, what, status, why in f.rows
               if status == "refused"]
    lines = [f"{f.path}: " + (f"unreadable: {f.rows[0][3]}" if f.count("unreadable") else
                              f"{f.count('compensated')} of {f.targets} targets compensated, {f.count('refused')} "
                              f"refused, {f.count('listed')} listed" + _kept_count(f.count("kept"))
                              + (f"; {f.foreign}" if f.foreign else ""))
             for f in res.files]
    lines.append(f"{len(res.files)} files: {res.count('compensated')} targets compensated, {res.count('refused')} "
                 f"refused{_kept_count(res.count('kept'))}, {res.count('listed')} listed, {res.count('unreadable')} "
                 f"files unreadable; " +
                 (f"written to {args.output} (every {args.program} file, compensated or as it was; report "
                  f"{args.output}/kincal_report.csv)" if written else
                  f"nothing written (--skip-unreachable writes the folder with those left as they are)"))
    lines += [others] if others else []
    unseen = _base_line(args, record, cal, unc)
    lines += refused[:SHOWN_PROBLEMS] + ([f"… and {len(refused) - SHOWN_PROBLEMS} more refused targets (all of them "
                                          f"with --json)"] if len(refused) > SHOWN_PROBLEMS else [])
    lines += ([f"TCP: {carry}"] if carry else []) + ([turn.note()] if turn is not None else []) + (
        [unseen] if unseen else [])
    return emit(args, {**res.to_dict(), "output": args.output if written else None, **_orientation_from(turned, turn),
                       "tool_carry": carry or None, "base_note": unseen or None},
                "\n".join(lines), 0 if written else EXIT_REFUSED)


def _left_out_line(res) -> str:
    """The programs of other languages under the folder, not read: how many, which (the first SHOWN_PROBLEMS) and what
    to do; '' for none."""
    if not res.left_out:
        return ""
    named = ", ".join(f"{p} ({lang})" for p, lang in res.left_out[:SHOWN_PROBLEMS])
    more = f", … and {len(res.left_out) - SHOWN_PROBLEMS} more" if len(res.left_out) > SHOWN_PROBLEMS else ""
    return (f"left out: {len(res.left_out)} program(s) of other languages than {res.dialect}, not read and not "
            f"written: {named}{more} (compensate each with its own --program)")


def _taught_lines(cal, nominal, frames, turned, shift: np.ndarray) -> list[str]:
    """How far each taught frame of the frames file really is from the controller's (as compensate used it: the
    flange turned as ``turned``'s, a given tool's TCP moved by ``shift``, :func:`tool_carry`)."""
    resolved = resolve_taught(frames, nominal.with_tool_point(np.zeros(3)), cal, turned, shift)
    out = []
    for name, f in frames.items():
        if isinstance(f, kincal.io.TaughtFrame):
            got = resolved[name]
            out.append(f"taught frame {name}: corrected as a measurement: its origin really is "
                       f"{np.linalg.norm(got[1][:3, 3] - got[0][:3, 3]) * MM:.3f} mm from the controller's"
                       if isinstance(got, tuple) else f"taught frame {name}: {got}")
    return out


def _compensate_program(args, robots, carried: tuple, models, orientation, unseen: str) -> int:
    """compensate --program ur: a robot program compensated in place, written to -o (never over it);
    with --skip-unreachable each target left as it is gets a comment saying why. ``robots``: the calibrated and the
    nominal model for --tcp, the point the calibration measured (:func:`_measured_point`) and the calibration's
    uncertainty in the robot's base frame; ``carried``: what of the calibration's move of the declared point is
    carried over to the TCP (m) and the sentence that says so (:func:`_carried`)."""
    r, nominal, measured, unc = robots
    shift, carry = carried
    prog = _read_program(args)
    if args.tcp is not None and prog.targets and not any(isinstance(prog.in_force_of(t), tuple) for t in prog.targets):
        raise ValueError(f"--tcp is the TCP of the moves before the program's first set_tcp, and {args.targets} sets "
                         f"its TCP before every move (or leaves it unknown there: such a move is refused, naming its "
                         f"set_tcp lines): leave --tcp out (the program's set_tcp is used)")
    turned, turn = orientation
    res = compensate_program(r, nominal, prog, models=models, orientation=turned, measured=measured, carry=shift)
    written = not res.problems or args.skip_unreachable  # never half a program silently; none at all: as it was
    if written:
        kincal.io.write_program(args.output, prog, res.texts, res.refused)
    lines = [f"{len(res.texts)} of {len(prog.targets)} literal targets compensated"
             + (f"; program written to {args.output} (everything else byte for byte"
                + (", a comment beside each target left as it is)" if res.refused else ")") if written else
                f"; nothing written to {args.output}" + (" (--skip-unreachable writes the program with the refused "
                                                         "targets left as they are, each marked)" if res.texts else ""))]
    lines += [f"refused: {res.foreign}"] if res.foreign else []
    carry = carry if prog.tcps or args.tcp is not None or any(t.kind == "joints" for t in prog.targets) else ""
    lines += [f"TCP set by the program (set_tcp) at {len(prog.tcps)} place(s): each move takes the one its flow "
              f"reaches it with (branches, loops and calls followed)"] \
        if prog.tcps else [] if args.tcp is not None else [
        "warning: the program sets no TCP (set_tcp) and no --tcp was given: its poses are taken as poses of the "
        "measured target (the calibration's tool point); give --tcp with the controller's TCP if it is another"]
    lines += [f"refused: {p}" for p in res.problems]
    lines += _left_lines(res)
    warned = _sigma_warnings(r, prog, res, unc)
    return emit(args, {"compensated": len(res.texts), "targets": len(prog.targets), "problems": list(res.problems),
                       **_left_dict(res),
                       "output": args.output if written else None, "tool_carry": carry or None,
                       **_orientation_from(turned, turn), "base_note": unseen or None, "warnings": warned},
                "\n".join(lines + ([f"TCP: {carry}"] if carry else []) + ([turn.note()] if turn is not None else [])
                          + ([unseen] if unseen else []) + [f"warning: {w}" for w in warned]),
                0 if written else EXIT_REFUSED)


def _body(args, record: dict) -> tuple[np.ndarray | None, str]:
    """For pose targets in the measurement frame (the instrument's poses of the measured body): the body's rotation
    on the flange the calibration found (its record's setup), and a line saying how the targets are turned; else
    (None, '')."""
    if not (args.pose and args.target_frame == "measurement") or not record:
        return None, ""
    found = record.get("setup")
    setup: dict = found if isinstance(found, dict) else {}
    if "target_rotation" not in setup:
        if "target.rx" in (record.get("nuisance") or {}):  # a fit in joint space before kincal recorded it
            raise ValueError(f"{args.robot}: its calibration fitted the measured body's rotation on the flange "
                             f"(target.rx, target.ry, target.rz) but does not record it (setup.target_rotation), so "
                             f"the measured body's poses (--target-frame measurement) cannot be turned to the "
                             f"flange's; calibrate again with this kincal, which records it")
        return None, ("target rotations: taken as the flange's (the calibration recorded no rotation of a measured "
                      "body on the flange)")
    R = kincal.identify.trained_setup({"setup": setup}, str(args.robot))[1]["target_rotation"]
    angle = float(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)))
    return R, (f"target rotations: the measured body's, as the instrument gives them; turned to the flange's by the "
               f"body's rotation on it that the calibration found ({angle * 1e3:.3f} mrad)")


def _kept_count(n: int) -> str:
    return f", {n} kept (joint targets at a singularity)" if n else ""


def _left_lines(res) -> list[str]:
    """The lines of a program's targets kept as they are and of its moves not rewritten (listed: a move to the Offs() of
    a compensated target goes with it at run time, and its reason says so)."""
    return ([f"kept as is: line {n}: {what}: {why}" for n, what, why in res.kept]
            + [f"not rewritten: line {n}: {what}: {why}" for n, what, why in res.not_literal])


def _left_dict(res) -> dict:
    return {"foreign": res.foreign or None, "kept": [{"line": n, "what": w, "why": y} for n, w, y in res.kept],
            "not_literal": [{"line": n, "what": w, "why": y} for n, w, y in res.not_literal]}


PLAN_JOINT_TOL = 1e-5  # rad or m: measured joint values must repeat the plan's commands this closely
PLAN_COPY_TOL = 1e-12  # relative: "measurements" this close to the predictions are a copy of them (no noise)


def cmd_verify(args) -> int:
    r = load_robot(args, [args.plan, args.measured, args.simulate], [args.output])
    if args.measured and not args.plan:
        raise ValueError("--measured needs --plan FILE: the plan written with -o, whose commands were measured")
    if not (args.output or args.measured or args.simulate):
        raise ValueError("nothing to do: give -o FILE to write the commands to run; after measuring them, run "
                         "again with --plan FILE --measured MEASUREMENTS (or --simulate TRUE_ROBOT to try it)")
    plan = _plan(args, r)
    if args.output:
        plan.write_csv(args.output, r, args.joint_cols, args.length_unit, angle_unit(args))
    if not (args.measured or args.simulate):
        return emit(args, {"cases": list(plan.cases), "commands": plan.commands.tolist(), "output": args.output},
                    f"{len(plan.cases)} cases x {plan.commands.shape[1]} samples: commands written to {args.output} "
                    f"({args.length_unit}, {angle_unit(args)}); measure them in this order, then run with --plan "
                    f"{args.output} --measured FILE")
    result = plan.compare(_measured(args, r, plan), args.tolerance / MM)
    return emit(args, result.to_dict(), result.table(), 0 if result.passed.all() else EXIT_REFUSED)


def _plan(args, r) -> VerificationPlan:
    """The plan to run: read (--plan), or drawn inside the cell the flags give, else within the joint limits (a
    warning on stderr when such samples put the tool point under the base plane while others are above it)."""
    cell = cell_of(args)
    if args.plan:
        if cell is not None:
            raise ValueError(f"the cell flags (--floor, --keep-out, --tracker, --joint-margin ...) choose where a new "
                             f"plan's samples go; --plan {args.plan} already says where the robot goes: give one or "
                             f"the other")
        return VerificationPlan.read_csv(args.plan, r)
    q = _samples(r, cell, args)
    plan = verification_plan(r, q, args.params)
    z = r.forward(plan.commands.reshape(-1, r.n_joints))[:, 2]
    if cell is None and (z < 0).any() and (z > 0).any():
        err.print(f"kincal: warning: {int((z < 0).sum())} of {z.size} commands put the tool point below the robot's "
                  f"base plane (z < 0 in its base frame, down to {z.min() * MM:.0f} mm): a robot on a table would "
                  f"hit it; the samples were drawn over the whole joint range: give --floor 0mm (and --keep-out "
                  f"boxes) to draw them inside the cell", markup=False)
    return plan


SAMPLE_DRAWS = 4  # candidate samples drawn per sample a plan needs: those with a refused command are passed over


def _samples(r, cell, args) -> np.ndarray:
    """A new plan's sample inputs (--samples): drawn in the cell (or within the joint limits), the first whose every
    case has a command the robot may be sent (kincal.compensate.commandable), in the order drawn."""
    n = args.samples * SAMPLE_DRAWS
    q = r.sample_joints(n, seed=args.seed) if cell is None else cell.pool(r, n, seed=args.seed)
    ok = commandable(r, q, args.params)
    if ok.sum() < args.samples:
        raise ValueError(f"only {int(ok.sum())} of {n} samples drawn have a command the robot may be sent for every "
                         f"case (the others reach a joint limit, leave the branch or are unreachable); give fewer "
                         f"--samples, or --params with fewer cases")
    return q[ok][:args.samples]


def _measured(args, r, plan) -> np.ndarray:
    """Measured positions (C, N, 3) of the plan's commands, from a file or simulated."""
    if args.simulate:
        true = kincal.load_robot(args.simulate)
        seeds = np.random.SeedSequence(args.seed).spawn(len(plan.commands))  # the noise differs with --seed
        return np.array([kincal.simulate(true, c, args.noise / MM, seed=int(s.generate_state(1)[0])).xyz
                         for s, c in zip(seeds, plan.commands)])
    meas = kincal.read_measurements(args.measured, r, args.joint_cols, args.xyz_cols, args.length_unit, args.angle_unit)
    cmds = plan.commands.reshape(-1, r.n_joints)
    if len(meas) != len(cmds):
        raise kincal.MeasurementError(f"{args.measured}: {len(meas)} rows, the plan {args.plan} has {len(cmds)} "
                                      f"(cases x samples, in its order)")
    off = np.abs(meas.q - cmds).max(axis=1) > PLAN_JOINT_TOL
    if off.any():
        raise kincal.MeasurementError(f"{args.measured}: the joint values in row(s) "
                                      f"{', '.join(map(str, meas.rows[off][:10]))} are not the plan's commands "
                                      f"({args.plan}); measure the plan's commands in its order")
    xyz = meas.xyz.reshape(plan.predicted.shape)
    if np.max(np.abs(xyz - plan.predicted)) < PLAN_COPY_TOL * max(1.0, float(np.max(np.abs(plan.predicted)))):
        raise kincal.MeasurementError(f"{args.measured}: the 'measured' positions ({', '.join(args.xyz_cols)}) equal "
                                      f"the plan's predictions to the last digits: they are the plan's predicted "
                                      f"columns, not measurements; give the columns the instrument measured")
    return xyz


def register(cmd) -> None:
    s = cmd("compensate", cmd_compensate, "joint commands that the calibrated model says reach target positions",
            "the calibrated robot (YAML)")
    s.add_argument("targets", help="CSV of target positions (serial robots: with the nominal joint values too); with "
                   "--program a robot program, or a folder of them (a controller's backup: every file of the language)")
    s.add_argument("-o", "--output", required=True, help="commands CSV to write (--program: the program, or the new "
                   "folder, which must not exist yet, with kincal_report.csv)")
    s.add_argument("--skip-unreachable", action="store_true",
                   help="write the commands that pass every check and list the refused targets (--program: write the "
                        "program or folder with the refused targets and unreadable files left as they are)")
    s.add_argument("--tcp", type=point, metavar="X,Y,Z[UNIT]",
                   help="the controller's TCP in the flange frame, e.g. 0,0,109mm: the point the targets are for "
                        "(default: the calibrated tool point)")
    s.add_argument("--link-error-max", type=nonneg_float, default=LINK_ERROR_MAX * MM,
                   help=f"with --tcp or a program's tool frames: the most the last link can be off, mm (default {LINK_ERROR_MAX * MM:g}); the "
                        f"calibration's move of the declared target point up to this is carried over to the TCP as "
                        f"the link's error, a larger one is the target's mounting and is not")
    s.add_argument("--pose", action="store_true",
                   help="the targets are full poses: position and the orientation columns of --orientation")
    s.add_argument("--orientation", default="quat-wxyz", type=checked(check_convention),
                   help="--pose: quat-wxyz (default), quat-xyzw, matrix, rotvec, rotvec-deg or "
                        "euler-<axes>-<intrinsic|extrinsic>-<deg|rad>")
    s.add_argument("--rot-cols", type=csv_list, help="--pose: the orientation columns, in the convention's order")
    s.add_argument("--program", choices=kincal.io.DIALECT_NAMES,
                   help="the targets file is a robot program (ur: URScript .script; krl: KUKA .src/.dat; rapid: ABB "
                        ".mod; fanuc: FANUC TP .ls; inform: Yaskawa .JBI): its literal move targets are compensated "
                        "in place, every other byte kept, on the branch each target states; the result goes to -o")
    s.add_argument("--frames", metavar="FILE",
                   help="--program krl|rapid|fanuc|inform: the tool and base frames the program names, YAML {name: "
                        "{x, y, z, rx, ry, rz}} in mm and deg ('default tool', 'default base': those in force where the "
                        "program names none), or a KUKA $config.dat; a RAPID module's own tooldata and wobjdata and "
                        "the $config.dat beside a KRL program (R1/System, with $ROBROOT_C from STEU/Mada/$machine.dat "
                        "for its bases) are read without it; a frame none of them gives is refused, never taken as "
                        "the identity; a frame taught on the robot (taught: {rule, joints, tool}) is corrected as the "
                        "measurement it is (docs/howto/compensate.md)")
    s.add_argument("--path", action="store_true",
                   help="the rows are consecutive targets of one path: a row whose corrected command jumps much "
                        "more from the previous one than the nominal commands do is refused and named")
    s.add_argument("--output-kind", choices=("joints", "cartesian"), default="joints",
                   help="joints: corrected joint commands (default); cartesian: the filtered poses to send a "
                        "controller that moves with the nominal model")
    s.add_argument("--workers", type=positive_int,
                   help="processes sharing a long targets file (default: one per core; the output is the same)")
    s.add_argument("--target-frame", default="base",
                   help="the frame of the targets: base (the robot's own, default), measurement (the calibration's "
                        "tracker frame), or a frame the robot file names (e.g. base_link for UR arms, as in ROS)")
    add_data_flags(s, std=False)
    _register_verify(cmd)


def _register_verify(cmd) -> None:
    """verify's flags: a new plan (its samples, in the cell), or a plan measured (or simulated) and judged."""
    s = cmd("verify", cmd_verify, f"error-model verification ({PUU3_2024}): commands to run, then the comparison "
                                  "(its Table 5)", "the identified (actual) robot model")
    s.add_argument("--samples", type=positive_int, default=10, help="sample inputs of a new plan (default 10)")
    s.add_argument("--params", type=csv_list, help="the parameters to test, one case each (default: all but the "
                                                   "base frame's and a transmission's own)")
    s.add_argument("--seed", type=int, default=0, help="random seed of a new plan's samples (default 0)")
    add_cell_flags(s, "a new plan's samples obey it")
    s.add_argument("-o", "--output", help="CSV of the commands to run, case by case (in --length-unit/--angle-unit)")
    s.add_argument("--plan", help="the plan CSV written with -o (whose commands were measured)")
    s.add_argument("--measured", help="measurements of the plan's commands, in the same order")
    s.add_argument("--tolerance", type=positive_float, default=0.05, help="largest deviation per axis to pass, mm (default 0.05)")
    s.add_argument("--simulate", help="a 'true' robot YAML to simulate the measurements instead")
    s.add_argument("--noise", type=nonneg_float, default=0.015, help="simulated tracker noise, mm per axis")
    add_data_flags(s, std=False)
