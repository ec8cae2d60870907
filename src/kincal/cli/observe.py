"""calibrate --type pose|markers|same-point|plane: measurements other than one 3-D point per pose,
read by kincal.observe and fitted by the stacked, σ-weighted problem."""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

import kincal
from kincal.identify import (ABSOLUTE, MOUNTED, fit_observations, refuse_inapplicable, set_cause, stat_line,
                             trained_setup, unseen_note)
from kincal.observe import InSession, ObservationFormat, PointObs, read_observations
from kincal.simulate import (plane_plan, simulate_markers, simulate_planes, simulate_poses, simulate_same_point,
                             socket_plan)
from kincal._csv import listed
from kincal.units import ANGLE_UNITS, LENGTH_UNITS, MM, MRAD, in_display

from .common import TYPES, add_data_flags, csv_list, judged
from .report import nominal_model, save_figures

def types_of(args) -> list[str]:
    """One measurement type per data file (one given for all, or one per file), after the check that
    the flags given apply to them (:func:`kincal.identify.refuse_inapplicable`)."""
    kinds = args.type or ["point"]
    if len(kinds) not in (1, len(args.data)):
        raise ValueError(f"--type: give one type for all {len(args.data)} files or one per file, got {len(kinds)}")
    bad = [k for k in kinds if k not in TYPES]
    if bad:
        raise ValueError(f"--type {bad[0]}: use one of {', '.join(TYPES)}")
    kinds = kinds * len(args.data) if len(kinds) == 1 else list(kinds)
    refuse_inapplicable(kinds, args.given)
    return kinds


def _quantity(table: dict, kind: str, example: str):
    """argparse type: a number > 0 with a ``kind`` unit of ``table`` after it (e.g. ``example``), in SI."""
    def parse(s: str) -> float:
        text = s.strip()
        unit = next((u for u in sorted(table, key=len, reverse=True) if text.endswith(u)), None)
        if unit is None:
            raise argparse.ArgumentTypeError(f"'{s}': give a number and {'an' if kind[0] in 'aeiou' else 'a'} {kind} "
                                             f"unit ({', '.join(table)}), e.g. {example}")
        try:
            v = float(text[:-len(unit)]) * table[unit]
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{s}': give a number and a unit, e.g. {example}") from None
        if not (np.isfinite(v) and v > 0):
            raise argparse.ArgumentTypeError(f"'{s}': give a number > 0")
        return v
    return parse


length = _quantity(LENGTH_UNITS, "length", "0.1mm")  # '0.1mm', in m
angle = _quantity({**ANGLE_UNITS, "mrad": 1.0 / MRAD}, "angle", "1mrad")  # '1mrad', '0.05deg', in rad


def _flag_number(text: str) -> float | None:
    """A finite number as a data file writes it (no '0_5', no NaN or inf), or None."""
    text = text.strip()
    try:
        v = float(text) if text.isascii() and "_" not in text else None
    except ValueError:
        return None
    return v if v is not None and np.isfinite(v) else None


def distance(s: str) -> tuple[str, str, float]:
    """argparse type: 'A,B,D' (two different labels and their distance > 0 in the file's length unit)."""
    parts = [p.strip() for p in s.split(",")]
    if len(parts) != 3 or not all(parts):
        raise argparse.ArgumentTypeError(f"'{s}': give LABEL_A,LABEL_B,DISTANCE (three fields), e.g. 0,1,50 (the "
                                         f"length unit of the file)")
    d = _flag_number(parts[2])
    if d is None or d <= 0:
        raise argparse.ArgumentTypeError(f"'{s}': the distance '{parts[2]}' must be a number > 0, e.g. 0,1,50 (the "
                                         f"length unit of the file)")
    if parts[0] == parts[1]:
        raise argparse.ArgumentTypeError(f"'{s}': a distance is between two different labels, e.g. 0,1,50")
    return parts[0], parts[1], d


def plane(s: str) -> tuple[str, tuple[tuple[float, float, float], float]]:
    """argparse type: 'LABEL:NX,NY,NZ,C' (n·p = c in the robot's base frame; c in the file's length unit)."""
    label, colon, rest = s.partition(":")
    values = [_flag_number(x) for x in rest.split(",")]
    if not colon or not label.strip() or len(values) != 4 or None in values:
        raise argparse.ArgumentTypeError(f"'{s}': give LABEL:NX,NY,NZ,C (a label and four numbers), e.g. "
                                         f"table:0,0,1,0")
    nx, ny, nz, c = (v for v in values if v is not None)
    norm = float(np.linalg.norm([nx, ny, nz]))
    if norm == 0:
        raise argparse.ArgumentTypeError(f"'{s}': the normal is zero; give the plane's normal, e.g. table:0,0,1,0")
    return label.strip(), ((nx / norm, ny / norm, nz / norm), c)


class Once(argparse.Action):
    """A repeatable flag (--distance, --plane) each of whose values names one thing: the same pair of
    labels (in either order) or plane label again with another value is refused, naming both; an
    exact repeat is dropped."""

    def __call__(self, parser, namespace, value, option_string=None) -> None:
        given = list(vars(namespace).get(self.dest) or [])
        key = frozenset(value[:2]) if len(value) == 3 else value[0]
        other = next((v for v in given if (frozenset(v[:2]) if len(v) == 3 else v[0]) == key), None)
        if other is not None and other[-1] != value[-1]:
            what = f"the distance {value[0]}–{value[1]}" if len(value) == 3 else f"plane '{value[0]}'"
            raise argparse.ArgumentError(self, f"'{_flag_text(value)}': {what} is already given as "
                                               f"'{_flag_text(other)}'; give each once, with its one value")
        setattr(namespace, self.dest, given if other is not None else given + [value])


def _flag_text(value) -> str:
    """A --distance or --plane value as it is written on the command line."""
    if len(value) == 3:
        return f"{value[0]},{value[1]},{value[2]:g}"
    label, (n, c) = value
    return f"{label}:{n[0]:g},{n[1]:g},{n[2]:g},{c:g}"


def add_flags(p: argparse.ArgumentParser, std: bool = True) -> None:
    """The data flags (:func:`add_data_flags`, ``std``: with --std-cols) and those of the measurement types."""
    add_data_flags(p, std)
    g = p.add_argument_group("measurement types (see docs/howto/measurements.md)")
    g.add_argument("--type", type=csv_list, metavar="TYPE[,TYPE...]",
                   help="point (default: one 3-D point per pose), pose (position + orientation), markers (NAME.x/.y/.z "
                        "columns), same-point (sockets: a label column, known distances), plane (plane contacts); "
                        "one for all files or one per file")
    g.add_argument("--orientation", default="quat-wxyz",
                   help="pose: quat-wxyz, quat-xyzw, matrix, rotvec, rotvec-deg, or euler-<axes>-<intrinsic|"
                        "extrinsic>-<deg|rad> such as euler-zyx-intrinsic-deg (default quat-wxyz)")
    g.add_argument("--rot-cols", type=csv_list, help="pose: the orientation columns, in the convention's order")
    g.add_argument("--markers", type=csv_list, help="markers: their names (default: every NAME with NAME.x/.y/.z)")
    g.add_argument("--label-col", help="same-point / plane: the label column (default 'point' / 'plane')")
    g.add_argument("--group-col", help="same-point: a group column, e.g. the plate placement; labels and distances "
                                       "apply inside each group")
    g.add_argument("--distance", type=distance, action=Once, default=[], metavar="A,B,D",
                   help="same-point: a known distance between labels A and B (length unit of the file); repeatable")
    g.add_argument("--plane", type=plane, action=Once, default=[], metavar="LABEL:NX,NY,NZ,C",
                   help="plane: a known plane n·p = c in the robot's base frame (c in the file's length unit); "
                        "simulate, design and identifiability touch these planes (default: kincal's own table and "
                        "a step 50 mm above it)")
    g.add_argument("--std-pos", type=judged(length, lambda v: ObservationFormat(std_pos=v)),
                   help="position σ with its unit, e.g. 0.1mm (defaults: point 0.015mm, pose 0.1mm, "
                        "markers/sockets/planes 0.05mm)")
    g.add_argument("--std-rot", type=judged(angle, lambda v: ObservationFormat("pose", std_rot=v)),
                   help="pose: orientation σ with its unit, e.g. 1mrad (default 1mrad)")


AS_RECORDED = " (default: as the calibration was made; --no-... turns it off)"


def switch(recorded: bool) -> dict:
    """argparse keywords of an on/off flag: off by default, or, for a command that refits a calibration
    (``recorded``), None by default (the calibration record's value) with a --no- form."""
    return {"action": argparse.BooleanOptionalAction, "default": None} if recorded else {"action": "store_true"}


def add_refit_target(p: argparse.ArgumentParser, recorded: bool = False) -> None:
    """--refit-target, of the commands that judge held-out files (calibrate, report, evaluate)."""
    p.add_argument("--refit-target", **switch(recorded),
                   help="pose, held-out files: re-fit the target's frame on the flange too, its point and rotation "
                        "(a rigid body defined anew between sessions), not kept as calibrated; with --same-frame "
                        "only the target, the measurement frame kept"
                        + AS_RECORDED * recorded)


def format_of(args, kind: str, own_target: bool = False):
    return ObservationFormat(kind, tuple(args.joint_cols) if args.joint_cols else None, args.length_unit,
                             args.angle_unit, tuple(args.xyz_cols), args.orientation,
                             tuple(args.rot_cols) if args.rot_cols else None,
                             tuple(args.markers) if args.markers else None, args.label_col, args.group_col,
                             tuple(args.distance), dict(args.plane), args.std_pos, args.std_rot, own_target)


def read_set(args, robot, path: str, kind: str, held_out: bool = False):
    """One observation file of ``kind`` read as ``args`` say, its joints and positions checked
    against the declared units before any fit (a wrong unit is fitted by a shrunk or blown-up robot)."""
    return read_observations(path, robot, format_of(args, kind, held_out and args.refit_target))


def sessions(sets: list, same_frame: bool) -> list:
    """Each absolute file after the first in its own frame (the tracker or camera may have moved),
    named by its file; with ``same_frame`` all in the robot's base frame."""
    absolute = [] if same_frame else [k for k, o in enumerate(sets) if o.kind in ABSOLUTE]
    names = {k: f"{n}:{Path(sets[k].source).name}" for n, k in enumerate(absolute[1:], start=2)}
    return [InSession.of(o, names[k]) if k in names else o for k, o in enumerate(sets)]


PLAN_MARKERS = ((0.04, 0.0, 0.0), (0.0, 0.04, 0.0), (-0.03, -0.03, 0.02))  # m around the tool point: a small nest
SOCKETS_PER_POINT = 15  # samples per socket when planning
CONTACTS_PER_PLANE = 30  # contacts per plane when planning


def planned(args, robot, true, kind: str, q, std: float, seed: int, per: int | None = None):
    """Observations of ``true`` of the type ``kind``: at the joints q (point, pose, markers), or at a
    planned plate (sockets) or at the planes of --plane, else a planned table with a step (planes), ``per``
    samples per socket or plane (default 15 and 30). With ``std`` = 0 they are exact."""
    pos, rot = format_of(args, kind).std()
    if kind == "point":
        m = kincal.simulate(true, q, std, seed=seed)
        return PointObs(m.q, m.rows, m.source, xyz=m.xyz, std=pos)
    if kind == "pose":
        noise_rot = rot if std else 0.0
        return dataclasses.replace(simulate_poses(true, q, np.eye(3), std, noise_rot, seed), std_pos=pos, std_rot=rot)
    if kind == "markers":
        tool = true.tool_point()
        return dataclasses.replace(simulate_markers(true, q, tool + np.array(PLAN_MARKERS), std, 0.0, seed), std=pos)
    if kind == "same-point":
        points, distances = socket_plan(robot, spacing=_spacing(args), seed=seed)
        obs = simulate_same_point(true, points, per or SOCKETS_PER_POINT, distances, std, seed=seed)
        return dataclasses.replace(obs, std=pos, group=np.array([lab.split("/")[0] for lab in obs.labels]))
    planes = _planes(args, robot, seed)
    contacts = simulate_planes(true, planes, per or CONTACTS_PER_PLANE, known=tuple(planes), std=std, seed=seed)
    return dataclasses.replace(contacts, std=pos)


def _planes(args, robot, seed: int) -> dict:
    """The planes touched, label -> (unit normal, offset m): those of --plane (offsets in the file's length unit),
    else kincal's own table and step (:func:`kincal.simulate.plane_plan`)."""
    given = dict(vars(args).get("plane") or [])
    if not given:
        return plane_plan(robot, seed=seed)
    f = LENGTH_UNITS[args.length_unit]
    return {lab: (np.asarray(n, float), float(c) * f) for lab, (n, c) in given.items()}


SPACING = 0.05  # m: the sockets of kincal's own plate plan, 0 and 1, this far apart unless --distance says


def _spacing(args) -> float:
    """The distance of the planned plate's sockets 0 and 1, m: --distance 0,1,D (the file's length unit), else
    SPACING; any other --distance is refused (the plan has those two sockets only)."""
    given = list(args.distance or [])
    if not given:
        return SPACING
    if len(given) != 1 or {given[0][0], given[0][1]} != {"0", "1"}:
        raise ValueError(f"--distance {' '.join(','.join(map(str, d)) for d in given)}: kincal's own plate plan has "
                         f"sockets 0 and 1; give one --distance 0,1,D (their spacing) or leave it out ("
                         f"{SPACING * 1e3:g} mm)")
    return float(given[0][2]) * LENGTH_UNITS[args.length_unit]


def flags_to_use(args, kind: str, obs=None) -> str:
    """The calibrate flags that read back the file of ``kind`` written as ``args`` say (:func:`format_of`; a point
    file by :func:`kincal.write_measurements` with the same columns and units): its type, every column and unit the
    format names other than calibrate's defaults, the tool point it was simulated with, and a written plan's
    (``obs``) placements, known distances and planes. One rule for every kind, so the hint is the command that reads
    the file: a pose file's --xyz-cols and --rot-cols, a plane file's --label-col were left out."""
    fmt, default = format_of(args, kind), ObservationFormat(kind)
    parts = [] if kind == "point" else [f"--type {kind}"]
    parts += [f"--joint-cols {','.join(fmt.joint_cols)}"] if fmt.joint_cols else []
    if kind in ("point", "pose"):
        parts += [f"--xyz-cols {','.join(fmt.xyz_cols)}"] if fmt.xyz_cols != default.xyz_cols else []
    if kind == "pose":
        parts += [f"--orientation {fmt.orientation}"] if fmt.orientation != default.orientation else []
        parts += [f"--rot-cols {','.join(fmt.rot_cols)}"] if fmt.rot_cols else []
    f = 1.0 / LENGTH_UNITS[fmt.length_unit]
    if kind == "same-point":  # the label and placement columns simulate and design write
        parts += [f"--label-col {fmt.label} --group-col {fmt.group_col or 'placement'}"]
        parts += [f"--distance 0,1,{obs.distances[0][2] * f:g}"] if obs is not None else []
    if kind == "plane":
        parts += [f"--label-col {fmt.label}"] if fmt.label != default.label else []
        parts += [f"--plane {lab}:{n[0]:g},{n[1]:g},{n[2]:g},{c * f:.6g}" for lab, (n, c) in
                  (obs.known.items() if obs is not None else ())]
    parts += [f"--{flag}-unit {unit}" for flag, unit, default_unit in (("length", fmt.length_unit, "m"),
                                                                        ("angle", fmt.angle_unit, "rad"))
              if unit != default_unit]
    tool = vars(args).get("tool")
    parts += [] if tool is None else ["--tool " + ",".join(f"{v * 1e3:.10g}" for v in tool) + "mm"]
    return " ".join(parts)


def evaluate_set(args, robot, record: dict | None, path: str, kind: str, stem: str | None) -> tuple[dict, list[str]]:
    """``robot`` on one observation file, its kinematics fixed; only the set-up parameters (unless --same-frame,
    the file's measurement frame; with --refit-target, the target's point and rotation) are fitted, the probe's
    rotation and the markers otherwise held as calibrated (``record``), and the nominal model the same way beside
    it: the JSON payload and the lines to print, with the likely cause of an error far above the training error."""
    held, anchors = trained_setup(record, args.robot)
    obs = read_set(args, robot, path, kind, held_out=True).with_anchors(anchors)
    own = obs.refitted(robot)  # --refit-target: the target's point and rotation are the file's own
    held = {n: v for n, v in held.items() if n not in own}
    frame = (() if args.same_frame or kind not in ABSOLUTE else robot.base_params()) + tuple(
        n for n in own if n in robot.params)
    fit = _fixed_kinematics(robot, obs, frame, held)
    s, (before, fitted) = fit.per_set[0], _nominal_beside(args, robot, record, obs, held, own)
    kept = sorted({"probe rotation" if n.startswith("target.") else "marker points" for n in held if n in fit.nuisance})
    texts: list[str] = []
    if stem:  # the figures of the set with positions: stem-<figure>.png/.svg
        from kincal.report import observation_figures

        texts = save_figures(observation_figures(fit, "held-out"), stem)
    texts.append(f"{robot.name} on {path} ({kind}; kinematics fixed, {_fitted_here(robot, frame, own, fit, held)}"
                 f"{', the ' + ' and '.join(kept) + ' as calibrated' if kept else ''}): "
                 f"{stat_line(s)}{unseen_note(s)}"
                 + ("" if before is None else f"  (nominal, {fitted}: {stat_line(before)})"))
    texts += group_lines([s], "")
    train = [t.get("mean") for t in (record or {}).get("observations", []) if isinstance(t, dict)
             and t.get("type") in (obs.kind, "joint")]  # the training error of this kind (m; a joint-space
    # residual's statistics are its measured positions' or poses')
    cause = _few_bad_samples(robot, obs, fit, frame, held)
    if not cause and train and isinstance(train[0], (int, float)) and train[0] > 0:
        # the position path's likely cause of an error far above the training error (the tracker moved, another
        # tool point, a scale, the file's columns), in the frame the set was judged in
        cause = set_cause(fit.robot, obs, fit.nuisance, float(train[0]), bool(set(frame) & set(robot.base_params())),
                          tuple(n for n in frame if n not in robot.base_params()))
    texts += [f"  likely cause: {cause}"] if cause else []
    unc = kincal.analysis.load_uncertainty(args.robot) if record else None
    envelope = None if unc is None else kincal.analysis.envelope_warning(obs.rows, obs.q, robot, unc)[1]
    texts += [f"  warning: {envelope}"] if envelope else []
    return {"file": path, "frame_fitted": bool(set(frame) & set(robot.base_params())), "setup_as_trained": kept, **s, "nominal": before,
            "cause": cause or None, "warnings": [envelope] if envelope else []}, texts


def _few_bad_samples(robot, obs, fit, frame: tuple, held: dict) -> str:
    """The likely cause when a few samples of ``obs`` carry ``fit``'s error: calibrate's rule on their whitened norms
    (:func:`kincal.identify.diagnosis.few_bad` at the set's block size), named with their rows when the rest, fitted
    again alike (:func:`_fixed_kinematics`), leaves less than half the mean error; "" otherwise (or for a kind
    without a mean error)."""
    from kincal.identify.diagnosis import EXPLAIN_RATIO, few_bad
    from kincal.identify.judge import block_size, sample_norms

    sets, mean = fit.observations, fit.per_set[0].get("mean")
    bad = few_bad(sample_norms(sets, fit.whitened_residual)[0], dim=block_size(sets[0]))
    if not len(bad) or len(obs) - len(bad) < 3 or not isinstance(mean, float) or not mean > 0:
        return ""
    left = _fixed_kinematics(robot, obs.subset(np.setdiff1d(np.arange(len(obs)), bad)), frame, held).per_set[0]["mean"]
    if not left < EXPLAIN_RATIO * mean:
        return ""
    return (f"a few bad poses: row(s) {listed(obs.rows[bad])} lie far off the rest: without them the mean error is "
            f"{left * MM:.4g} mm, not {mean * MM:.4g} mm; check how they were measured and measure them again, or "
            f"leave them out of the file")


def group_lines(sets: list, which: str) -> list[str]:
    """A line per placement (group) of sockets in the sets' statistics: samples, mean distance to its point, error
    of the known distances; ``which`` before its name, and the file's name after it where several sets hold it."""
    names = [g["group"] for s in sets for g in s.get("groups", [])]
    return [f"  {which}{g['group']}" + (f" ({Path(s['source']).name})" if names.count(g["group"]) > 1 else "")
            + f": {g['samples']} samples, mean |p − point| {g['mean_abs_mm']:.4f} mm, distance error "
            + ("–" if g["distance_error_mm"] is None else f"{g['distance_error_mm']:.3f} mm")
            for s in sets for g in in_display(s).get("groups", [])]


def _fitted_here(robot, frame: tuple, own: tuple, fit, held: dict) -> str:
    """What a held-out set's fit moved, in words: its frame, the target --refit-target names, the set-up
    parameters not held as calibrated; or that nothing was fitted."""
    parts = ["frame"] if set(frame) & set(robot.base_params()) else []
    parts += ["the target (--refit-target)"] if own else []
    parts += ["set-up parameters"] if [n for n in fit.nuisance if n not in held and n not in own] else []
    return (" and ".join(parts) + " fitted") if parts else "nothing fitted"


def _nominal_beside(args, robot, record: dict | None, obs, held: dict, own: tuple = ()) -> tuple[dict | None, str]:
    """The nominal model's statistics on a held-out set, judged as calibrate judges it ("before"): with --same-frame
    its frame, target point and markers' points as registered on the training data (the record's, as the report
    does), a target the set defines anew (``own``: --refit-target) fitted as for the calibrated one; else its frame,
    target point and target rotation fitted to this set (the calibrated rotation belongs to the calibrated
    kinematics), kinematics fixed — the target point only for the kinds whose "before" registers it
    (:data:`kincal.identify.MOUNTED`: points and poses; sockets and planes keep the declared one, as calibrate --test
    and the report judge them: the Panda's held-out placements 7.78 mm, not 7.52 with a ball fitted to them), markers'
    points where the data fix a scale; and how, in words. (None, '') without a record."""
    kept = nominal_model(robot, record, args.robot, "before_mounting") if args.same_frame else None
    mounted = {str(k): float(v) for k, v in ((record or {}).get("before_setup") or {}).items()}  # markers' points
    if kept is not None:
        refit = tuple(n for n in own if n in kept.params)
        return _fixed_kinematics(kept, obs, refit, {**held, **mounted}).per_set[0], "its frame " + (
            "as registered on the training data, the target (--refit-target) fitted" if own else
            "and target point as registered on the training data")
    nominal = nominal_model(robot, record, args.robot)
    if nominal is None:
        return None, ""
    mounting = (*(robot.base_params() if obs.kind in ABSOLUTE else ()),
                *(n for n in robot.params.names if n.startswith("tool.") and obs.kind in MOUNTED))
    fit = _fixed_kinematics(nominal, obs, mounting, {n: v for n, v in held.items() if not n.startswith("target.")
                                                     and not (obs.reference and n in mounted)})
    parts = [w for w, p in (("frame", "base."), ("target point", "tool.")) if any(n.startswith(p) for n in mounting)]
    parts += ["target rotation"] if any(n.startswith("target.") for n in fit.nuisance) else []
    return fit.per_set[0], (f"its {', '.join(parts[:-1])}{' and ' * (len(parts) > 1)}{parts[-1]} fitted"
                            if parts else "its frame and target point as declared")


def _fixed_kinematics(robot, obs, frame: tuple, held: dict):
    """``robot`` fitted to one set with its kinematics fixed: only ``frame`` (the base frame's parameters, a target's
    own) and the set-up parameters not ``held``; the base frame kept unless ``frame`` names it."""
    base = "estimate" if set(frame) & set(robot.base_params()) else "fixed"
    return fit_observations(robot, [obs], names=frame, base=base, held=held)
