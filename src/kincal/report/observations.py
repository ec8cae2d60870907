"""The report's sections for a calibration from observation sets (poses, markers, sockets, planes, or
points in sessions of their own): the residuals per set and type (shown in mm, mrad), per-placement
statistics, the figures of sets with positions, and held-out sets under both models (m, rad in the
JSON)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..identify.calibrate import held_out_judged, held_out_nominal, held_out_stats
from ..identify.positions import session_frame
from ..identify.result import CalibrationResult, Judged
from ..identify.sessions import set_cause
from ..identify.stacked import before_nuisance
from ..identify.verdict import Thresholds, robust_z
from ..models.robot import Robot
from ..observe.sessions import InSession
from . import figures as F
from .._csv import listed
from ..units import in_display

COLUMNS = ("mean_mm", "rms_mm", "max_mm", "mean_mrad", "rms_mrad", "max_mrad")


def sets_part(result: CalibrationResult, tests: Sequence, same_frame: bool):
    """The sections, the numbers they add to the JSON (the held-out statistics under the calibrated
    and the nominal model) and the lines of the terminal summary; ``tests``: held-out sets."""
    held = [held_out_stats(result, t, result.robot, same_frame) for t in tests]
    nominal = [held_out_nominal(result, t, same_frame) for t in tests]
    residuals = [_row(s, f"training {k + 1}", "nominal", "before") for k, s in enumerate(result.per_set_before)]
    residuals += [_row(s, f"training {k + 1}", "calibrated", "after") for k, s in enumerate(result.per_set)]
    residuals += [_row(s, f"held out {k + 1}", "nominal", "held_out_before") for k, s in enumerate(nominal)]
    residuals += [_row(s, f"held out {k + 1}", "calibrated", "held_out") for k, s in enumerate(held)]
    groups = _groups(result.per_set_before, result.per_set, "training") + _groups(nominal, held, "held out")
    drawn, rest = drawable_sets(result, "training", tests, same_frame)
    figures = [{"name": n, "svg": F.svg(f)} for n, f in F.pose_figures(drawn, result.robot).items()] if drawn else []
    warnings = [c for c in (_cause(result, t) for t in tests) if c] if same_frame else []
    part = {"residuals": residuals, "groups": groups, "figures": figures, "warnings": warnings,
            "not_drawn": ", ".join(f"{Path(o.source).name} ({o.kind})" for o in rest) if drawn else "",
            "rejected": {k: listed(v) for k, v in result.rejected.items()}}
    summary = [f"  {r['data']} {r['type']} ({r['model']}): mean {r['mean_mm']:.4f} mm" for r in residuals
               if r["mean_mm"] is not None] + [f"  warning: {w}" for w in warnings]
    return part, {"held_out": held, "held_out_nominal": nominal, "residuals": residuals, "groups": groups,
                  "warnings": warnings}, summary


def _cause(result: CalibrationResult, obs) -> str:
    """The likely cause of a held-out set's error far above the training error of its kind, judged on its positions
    in the calibration's frame (``--same-frame``: the tracker moved, another tool point, a scale), as ``evaluate``
    names it; '' for a set without positions or within the limit."""
    train = [s["mean"] for s in result.per_set if s.get("type") == obs.kind and s.get("mean")]
    return set_cause(result.robot, obs, result.nuisance, float(train[0])) if train else ""


def observation_figures(fit: CalibrationResult, label: str = "training", tests: Sequence = (),
                        same_frame: bool = False) -> dict:
    """The report's figures of the observation sets with one measured position per sample, and held-out sets.

    Points, 6-D poses and measured positions fitted in joint space count, whatever frame they were measured in: a
    set in a session's own frame and a held-out set with its frame re-fitted are drawn in the training data's frame
    (the first's), their positions and error vectors turned into it. The figures show errors per sample, their
    distribution, per axis, against the joints and in the workspace, before (the registered nominal model) and after
    calibration, or of the model alone (``label`` "held-out"); 6-D data also their rotation error per sample.

    Parameters
    ----------
    fit : CalibrationResult
        A calibration from observation sets.
    label : str, optional
        "training" (default: before and after calibration) or "held-out" (the model alone, e.g.
        ``evaluate``).
    tests : sequence of Observation, optional
        Held-out sets, judged as the report's table judges them (:func:`kincal.identify.held_out_judged`; default
        none).
    same_frame : bool, optional
        The held-out sets were measured in the training data's frame (default False: each one's frame re-fitted).

    Returns
    -------
    dict
        name -> matplotlib Figure: "per_pose", "rotation" (6-D data only), "histogram", "per_axis", "vs_joints",
        "workspace"; {} when no set has such positions.
    """
    sets, _ = drawable_sets(fit, label, tests, same_frame)
    return F.pose_figures(sets, fit.robot) if sets else {}


def drawable_sets(fit: CalibrationResult, label: str = "training", tests: Sequence = (),
                  same_frame: bool = False) -> tuple[list[F.PoseSet], list]:
    """The figures' sets (:func:`observation_figures`) and the training and held-out sets they cannot draw (no
    measured position per sample: markers, sockets, planes)."""
    sets, rest = _training_sets(fit, label)
    th = fit.options.thresholds
    for k, t in enumerate(tests):
        after = held_out_judged(fit, t, fit.robot, same_frame)
        drawn = _pose_set(fit, t, after, held_out_nominal(fit, t, same_frame, held_out_judged), None, k, th)
        sets += [drawn] if drawn else []
        rest += [] if drawn else [t]
    return sets, rest


def _training_sets(fit: CalibrationResult, label: str) -> tuple[list[F.PoseSet], list]:
    """The drawable training sets, errors as the fit judged them (after: the calibrated model with the fitted set-up
    values; before: the "before" model as the table's "nominal" row, none for ``label`` "held-out"), and the rest."""
    out: list[F.PoseSet] = []
    rest: list = []
    for obs, bad in zip(fit.observations, fit.outliers or ((),) * len(fit.observations)):
        names = obs.nuisance(fit.robot)[0]
        nuis = np.array([fit.nuisance[n] for n in names])
        before = Judged(obs, fit.before, before_nuisance(fit.before, obs, nuis, names, fit.before_setup)) \
            if label == "training" else None
        drawn = _pose_set(fit, obs, Judged(obs, fit.robot, nuis), before, np.asarray(bad, int), len(out), label)
        out += [drawn] if drawn else []
        rest += [] if drawn else [obs]
    return out, rest


def _pose_set(fit: CalibrationResult, obs, after: Judged, before: Judged | None, bad, k: int, how) -> F.PoseSet | None:
    """One set's figure data in the training data's frame (None when it has no position per sample): ``after``
    and ``before`` judge it; outliers the samples ``bad`` (indices), or for a held-out set (``how``: the
    thresholds) by robust z of its errors; ``k``: its place among the sets of its label, for its colour."""
    errors = after.sample_errors()
    inner = obs.inner if isinstance(obs, InSession) else obs
    found = inner.positions()
    if errors is None or found is None or len(found[0]) != len(obs):
        return None
    model = session_frame(fit, obs) if isinstance(obs, InSession) else after.robot
    turn, xyz = _to_training(fit.robot, model, found[1])
    e, rot = errors
    label = "held-out" if isinstance(how, Thresholds) else how
    if bad is None:
        z = robust_z(np.linalg.norm(e, axis=1))
        bad = np.flatnonzero(z > how.outlier_limit(len(z)))
    ref = None if before is None else before.sample_errors()
    name = Path(obs.source).name if label != "training" or len(fit.observations) > 1 else ""
    return F.PoseSet(label, obs.rows, obs.q, xyz, None if ref is None else ref[0] @ turn, e @ turn,
                     np.isin(np.arange(len(obs)), bad), name=name, colour=F.colour(label, k),
                     rot_before=None if ref is None else ref[1], rot_after=rot)


def _to_training(training: Robot, model: Robot, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The turn (3, 3) that takes vectors from the frame where ``model`` sees the robot into ``training``'s (rows:
    ``v @ turn``), and the positions ``xyz`` (N, 3) m in ``training``'s frame."""
    if not training.base_params():
        return np.eye(3), xyz
    (R0, t0), (Rs, ts) = training.base_transform(), model.base_transform()
    return Rs @ R0.T, (xyz - ts) @ Rs @ R0.T + t0


def _row(stats: dict, data: str, model: str, key: str) -> dict:
    """One table row (mm, mrad) from a set's statistics (m, rad; a socket set's mean is its mean
    |p − point|), the file by its name (the data section gives its path)."""
    s = in_display(stats)
    s = {**s, "mean_mm": s["mean_abs_mm"]} if "mean_abs_mm" in s else s
    return {"data": f"{data}: {Path(s['source']).name}", "type": s["type"], "samples": s["samples"], "model": model,
            "key": f"{key}.{s['source']}", **{k: s.get(k) for k in COLUMNS}}


def _groups(before: Sequence[dict], after: Sequence[dict], data: str) -> list[dict]:
    out = []
    before, after = [in_display(s) for s in before], [in_display(s) for s in after]
    for k, s in enumerate(after):
        prior = {g["group"]: g for g in before[k].get("groups", [])} if k < len(before) else {}
        for g in s.get("groups", []):
            b = prior.get(g["group"], dict.fromkeys(("mean_abs_mm", "distance_error_mm")))  # None: no such group before
            out.append({"data": f"{data}: {Path(s['source']).name}", "group": g["group"], "samples": g["samples"],
                        "before": b["mean_abs_mm"], "after": g["mean_abs_mm"], "dist_before": b["distance_error_mm"],
                        "dist_after": g["distance_error_mm"], "key": f"{data}.{g['group']}"})
    return out
