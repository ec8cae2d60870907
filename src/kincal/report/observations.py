"""The report of a calibration from observation sets (poses, markers, sockets, planes, points): the
residuals per set and type (mm, mrad), per-placement statistics, the robot and set-up parameters.
Self-contained HTML and the JSON of the same numbers, like the position report."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..identify.relevance import prior_lines
from ..identify.observed_result import ObservationFit
from ..observe.sessions import InSession
from . import figures as F
from .._csv import listed
from ..units import MM, MRAD, display
from .build import Report, json_path_for, report_date, template

COLUMNS = ("mean_mm", "rms_mm", "max_mm", "mean_mrad", "rms_mrad", "max_mrad")


def observation_report(fit: ObservationFit, held_out: Sequence[dict] = (), held_out_nominal: Sequence[dict] = (),
                       html_name: str = "report.html") -> Report:
    """The report of ``fit``; ``held_out`` / ``held_out_nominal``: statistics of held-out sets under
    the calibrated and the nominal robot (``fit.held_out(obs)``, ``fit.held_out(obs, fit.before)``)."""
    from .. import __version__

    residuals = [_row(s, f"training {k + 1}", "nominal", "before") for k, s in enumerate(fit.stats_before)]
    residuals += [_row(s, f"training {k + 1}", "calibrated", "after") for k, s in enumerate(fit.stats)]
    residuals += [_row(s, f"held out {k + 1}", "nominal", "held_out_before") for k, s in enumerate(held_out_nominal)]
    residuals += [_row(s, f"held out {k + 1}", "calibrated", "held_out") for k, s in enumerate(held_out)]
    groups = _groups(fit.stats_before, fit.stats, "training") + _groups(held_out_nominal, held_out, "held out")
    ctx = {"robot": fit.robot.name, "version": __version__, "date": report_date(),
           "types": sorted({s["type"] for s in fit.stats}), "n_estimated": len(fit.names), "n_setup": len(fit.nuisance),
           "n_samples": sum(s["samples"] for s in fit.stats), "whitened_rms": fit.whitened_rms,
           "verdict": fit.verdict.to_dict(), "residuals": residuals, "groups": groups,
           "parameters": _parameters(fit), "setup": _setup(fit), "weak": fit.weak_lines(), "gauge": list(fit.gauge),
           "prior": prior_lines(fit.prior), "rejected": {k: listed(v) for k, v in fit.rejected.items()},
           "not_estimated": [line for line in fit.identifiability.confound_lines("")
                             if line.split()[0] not in set(fit.gauge)], "json_name": json_path_for(html_name).name}
    figures = observation_figures(fit)
    ctx["figures"] = [{"name": n, "svg": F.svg(f)} for n, f in figures.items()]
    html = template("observations.html").render(**ctx)
    data = {**fit.to_dict(), "held_out": list(held_out), "held_out_nominal": list(held_out_nominal), "date": ctx["date"], "version": __version__}
    summary = "\n".join([f"verdict: {fit.verdict.status.upper()}"] + [
        f"  {r['data']} {r['type']} ({r['model']}): mean {r['mean_mm']:.4f} mm" for r in residuals
        if r["mean_mm"] is not None])
    return Report(html, data, summary)


def observation_figures(fit: ObservationFit, label: str = "training") -> dict:
    """The report's figures of the sets with one measured position per sample (points, 6-D poses;
    sets in a session's own frame left out): errors per sample, distribution, per axis, against the
    joints and in the workspace, before (the registered nominal model) and after calibration, or of
    the model alone (``label`` "held-out", e.g. ``evaluate``); {} when no set has such positions."""
    sets = []
    for obs, bad in zip(fit.observations, fit.outliers or ((),) * len(fit.observations)):
        found = obs.positions()
        if obs.kind not in ("point", "pose") or isinstance(obs, InSession) or found is None:
            continue
        q, xyz = found
        flags = np.zeros(len(q), bool)
        flags[np.asarray(bad, int)] = True
        before = xyz - fit.before.forward(q) if label == "training" else None
        sets.append(F.PoseSet(label, obs.rows, q, xyz, before, xyz - fit.robot.forward(q), flags, name=obs.source))
    if not sets:
        return {}
    names, types = fit.robot.joint_names, fit.robot.joint_types
    return {"per_pose": F.per_pose(sets), "histogram": F.histogram(sets), "per_axis": F.per_axis(sets),
            "vs_joints": F.vs_joints(sets, names, types), "workspace": F.workspace(sets)}


def _row(s: dict, data: str, model: str, key: str) -> dict:
    """One table row from a set's statistics (a socket set's mean is its mean |p − point|)."""
    row = {"data": f"{data}: {s['source']}", "type": s["type"], "samples": s["samples"], "model": model,
           "key": f"{key}.{s['source']}"}
    row.update({k: s.get(k) for k in COLUMNS})
    if "mean_abs_mm" in s:
        row["mean_mm"] = s["mean_abs_mm"]
    return row


def _groups(before: Sequence[dict], after: Sequence[dict], data: str) -> list[dict]:
    out = []
    for k, s in enumerate(after):
        prior = {g["group"]: g for g in before[k].get("groups", [])} if k < len(before) else {}
        for g in s.get("groups", []):
            b = prior.get(g["group"])
            out.append({"data": f"{data}: {s['source']}", "group": g["group"], "samples": g["samples"],
                        "before": None if b is None else b["mean_abs_mm"], "after": g["mean_abs_mm"],
                        "dist_before": None if b is None else b["distance_error_mm"],
                        "dist_after": g["distance_error_mm"], "key": f"{data}.{g['group']}"})
    return out


def _parameters(fit: ObservationFit) -> list[dict]:
    kinds = dict(zip(fit.robot.params.names, fit.robot.params.kinds))
    return [{"name": n, "nominal": display(fit.nominal.params[n], kinds[n], signed=False),
             "estimate": display(fit.robot.params[n], kinds[n], signed=False),
             "correction": display(fit.robot.params[n] - fit.nominal.params[n], kinds[n]),
             "std": display(fit.std[n], kinds[n], signed=False)} for n in fit.names]


def _setup(fit: ObservationFit) -> list[dict]:
    """Set-up parameters in mm (lengths) and mrad (angles: target rotations, plane tilts)."""
    out = []
    for n, v in fit.nuisance.items():
        angle = n.startswith("target.") or n.endswith((".a", ".b"))
        f, unit = (MRAD, "mrad") if angle else (MM, "mm")
        sd = fit.std.get(n, np.inf)
        out.append({"name": n, "value": f"{v * f:.4f} {unit}",
                    "std": f"{sd * f:.4f} {unit}" if np.isfinite(sd) else "–"})
    return out
