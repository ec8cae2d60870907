"""Has the robot changed? ``kincal compare A B`` (two calibrations) and ``kincal check CAL data.csv`` (a short
check of a calibrated model on a few measured poses, those ``kincal design CAL --check`` chose), each recorded in
the calibration store when one is set."""
from __future__ import annotations

import argparse

import kincal
from kincal.identify import ALPHA, Calibrated, ChangeTest, check, compare
from kincal.identify.change import EXPLAINED_MIN

from .common import EXIT_REFUSED, add_data_flags, check_paths, emit, err, positive_float
from .history import add_store_flag, store_of, store_record


def calibrated(path: str) -> Calibrated:
    """The calibrated robot file ``path`` with its calibration record (a clear error for any other file: the record
    is read first, so a URDF is not given the URDF reader's advice, --tip-link, which compare and check refuse)."""
    check_paths([path], [])
    record = Calibrated.required(kincal.models.load_calibration_record(path), path)
    return Calibrated.of(kincal.load_robot(path), record, path)


def _alpha(s: str) -> float:
    value = positive_float(s)
    if not value < 0.5:
        raise argparse.ArgumentTypeError(f"'{s}': the false-alarm probability must be below 0.5 (e.g. 0.05)")
    return value


def lines_of(test: ChangeTest) -> list[str]:
    """The test in words: the verdict with its false-alarm probability, the figures, the suspects, the notes."""
    frame = "re-fitted" if test.frame_refitted else "kept (--same-frame)"
    out = [f"verdict: {test.verdict}  (false-alarm probability {test.alpha:.0%}; p = {test.p_value:.3g})",
           f"{test.poses} poses, frame {frame}: discrepancy {test.rms * kincal.units.MM:.4f} mm RMS per pose, "
           f"whitened {test.statistic:.1f} on {test.dof} degrees of freedom"]
    if test.misfit:  # its suspects are no robot's changes: the note says why, and what the data are
        return out + [f"note: {n}" for n in test.notes]
    if test.changed and test.explained < EXPLAINED_MIN:
        out.append("single changes, none explaining it alone (ranked; sizes with σ):")
    elif test.changed:
        out.append("most likely single change (ranked; sizes with σ):")
    else:
        out.append("largest candidate changes, none significant:")
    out += [f"  {s.line()}" for s in test.suspects[:3]]
    return out + [f"note: {n}" for n in test.notes]


def record(args, test: ChangeTest, path: str, robot, inputs: list[str]) -> str | None:
    """The test in the calibration store when one is set, for the robot whose calibrated file is ``path``."""
    if store_of(args) is None:
        return None
    from kincal.history import Record, fingerprint, utc_time

    from .report import nominal_model  # noqa: PLC0415  (the report's module imports the observation commands')

    nominal = nominal_model(robot, kincal.models.load_calibration_record(path), path) or robot
    evaluated = {"evaluated": fingerprint(path).to_dict()} if test.question == "check" else {}  # the store links it
    return store_record(args, nominal, lambda identity, command: Record(
        identity, "check" if test.question == "check" else "comparison", utc_time(), test.verdict,
        tuple(fingerprint(p) for p in inputs), figures={"heldout_rms": test.rms},
        payload={"command": command, "test": test.to_dict(), **evaluated}))


def _doubtful(path: str, test: ChangeTest) -> None:
    """On stderr: a calibration compared or checked against whose verdict was not good (its doubt carries over to
    a change ``test`` names; a test that names none is not said to)."""
    verdict = (kincal.models.load_calibration_record(path) or {}).get("verdict")
    if verdict in ("suspect", "refused"):
        named = test.changed and not test.misfit and test.explained >= EXPLAINED_MIN
        err.print(f"warning: {path} was calibrated with the verdict {str(verdict).upper()} (its report says why)"
                  + (": the change named here may be that calibration's trouble, not the robot's" if named else ""),
                  markup=False)


def cmd_compare(args) -> int:
    a, b = calibrated(args.first), calibrated(args.second)
    test = compare(a, b, same_frame=args.same_frame, alpha=args.alpha)
    for path in dict.fromkeys((args.first, args.second)):  # one file given twice: said once
        _doubtful(path, test)
    stored = record(args, test, args.second, b.robot, [args.first, args.second])
    emit(args, test.to_dict(), "\n".join(lines_of(test) + ([stored] if stored else [])))
    return EXIT_REFUSED if test.changed else 0  # as check: a change found (or no one robot) is no pass


def cmd_check(args) -> int:
    cal = calibrated(args.calibration)
    check_paths([args.data], [])
    meas = kincal.read_measurements(args.data, cal.robot, joint_cols=args.joint_cols, xyz_cols=args.xyz_cols,
                                    length_unit=args.length_unit, angle_unit=args.angle_unit)
    test = check(cal, meas.q, meas.xyz, same_frame=args.same_frame, alpha=args.alpha, units=meas.units,
                  rows=meas.rows)
    _doubtful(args.calibration, test)
    stored = record(args, test, args.calibration, cal.robot, [args.calibration, args.data])
    emit(args, test.to_dict(), "\n".join(lines_of(test) + ([stored] if stored else [])))
    return EXIT_REFUSED if test.changed else 0


def register(cmd) -> None:
    """Add compare and check through ``cmd(name, func, help, None)``."""
    s = cmd("compare", cmd_compare, "did the robot change between two calibrations? (the parameters that moved, "
                                    "with a stated false-alarm probability); exit 4 when it changed or the two "
                                    "do not describe one robot, as check", None)
    s.add_argument("first", metavar="A", help="the earlier calibrated robot file")
    s.add_argument("second", metavar="B", help="the later calibrated robot file (sizes are B − A)")
    _common(s)
    s = cmd("check", cmd_check, "is a calibrated model still good? a few measured poses (those `design --check` "
                                "chose) against it: 'still good' or 're-calibrate' with what moved; exit 4 when "
                                "re-calibration is advised or the data do not fit, as compare", None)
    s.add_argument("calibration", metavar="CAL", help="the calibrated robot file")
    s.add_argument("data", help="the check's measurements CSV (joints and measured positions, like calibrate's)")
    add_data_flags(s, std=False)
    _common(s)


def _common(s) -> None:
    s.add_argument("--same-frame", action="store_true",
                   help="the instrument kept its frame (a tracker not moved): a frame change counts as a change; "
                        "by default the frame is re-fitted and only the robot is judged")
    s.add_argument("--alpha", type=_alpha, default=ALPHA,
                   help=f"false-alarm probability of the test (default {ALPHA:g})")
    add_store_flag(s)
