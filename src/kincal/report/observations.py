"""The report's sections for a calibration from observation sets (poses, markers, sockets, planes, or
points in sessions of their own): the residuals per set and type (shown in mm, mrad), per-placement
statistics, the figures of sets with positions, and held-out sets under both models (m, rad in the
JSON)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..identify.calibrate import held_out_nominal, held_out_stats
from ..identify.result import CalibrationResult
from ..identify.sessions import set_cause
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
    figures = [{"name": n, "svg": F.svg(f)} for n, f in observation_figures(result).items()]
    warnings = [c for c in (_cause(result, t) for t in tests) if c] if same_frame else []
    part = {"residuals": residuals, "groups": groups, "figures": figures, "warnings": warnings,
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


def observation_figures(fit: CalibrationResult, label: str = "training") -> dict:
    """The report's figures of the observation sets with one measured position per sample.

    Points, 6-D poses and measured positions fitted in joint space count; sets in a session's own frame are left out. The figures show errors per
    sample, their distribution, per axis, against the joints and in the workspace, before (the
    registered nominal model) and after calibration, or of the model alone (``label`` "held-out").

    Parameters
    ----------
    fit : CalibrationResult
        A calibration from observation sets.
    label : str, optional
        "training" (default: before and after calibration) or "held-out" (the model alone, e.g.
        ``evaluate``).

    Returns
    -------
    dict
        name -> matplotlib Figure: "per_pose", "histogram", "per_axis", "vs_joints", "workspace"; {} when no
        set has such positions.
    """
    sets = []
    for obs, bad in zip(fit.observations, fit.outliers or ((),) * len(fit.observations)):
        found = obs.positions()
        if obs.kind not in ("point", "pose", "joint") or isinstance(obs, InSession) or found is None:
            continue
        q, xyz = found
        before = xyz - fit.before.forward(q) if label == "training" else None
        sets.append(F.PoseSet(label, obs.rows, q, xyz, before, xyz - fit.robot.forward(q),
                              np.isin(np.arange(len(q)), np.asarray(bad, int)), name=Path(obs.source).name))
    return F.pose_figures(sets, fit.robot) if sets else {}


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
