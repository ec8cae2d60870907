"""The one fit and the procedures that wrap it: any observation sets (3-D points, joint-space
residuals, 6-D poses, markers, sockets, planes, sessions in their own frames) with one options
record (:class:`~kincal.identify.FitOptions`).

:func:`fit_stack` extends the robot by a named error model, wraps each set of measured positions in
its instrument's drift when asked, runs the stacked fit (:func:`kincal.identify.stacked.fit_sets`),
drops a compliance that comes out negative and fits again (until none is: a compliance's load then
falls to the others, which may turn negative in turn), and leaves out outlier samples by a
Huber refit. Each procedure calls the fit as a function: nothing recurses through ``calibrate``.
"""
from __future__ import annotations

import dataclasses
from typing import Callable, Mapping, Sequence

import numpy as np

from ..models.robot import Robot
from ..models.terms import TAU_REF, ErrorModel, drop_terms, extend
from ..observe.drifting import Drifting
from ..observe.joint import in_joint_space
from ..observe.sessions import InSession
from .result import CalibrationResult
from .options import FitOptions
from .stacked import fit_sets
from .verdict import MAX_OUTLIER_SHARE

POSITION_KINDS = ("point", "joint")  # kinds whose default prior is none (held-out: docs/howto/measurements.md)
ABSOLUTE = ("point", "pose", "markers")  # kinds measured in an instrument's frame (which may move between files)


def resolved_prior(prior: str, observations: Sequence) -> str:
    """"auto": no prior for position data alone (3-D points, joint-space residuals: a least-squares
    fit did as well on held-out sessions), the learned prior otherwise (poses, markers, sockets,
    planes: it stops corrections the data cannot confirm, 4.17 → 3.14 mm held out on one marker)."""
    if prior != "auto":
        return prior
    return "none" if all(o.kind in POSITION_KINDS for o in observations) else "relevance"


def negative_compliances(names: Sequence[str], estimates: Mapping[str, float], std: Mapping[str, float],
                         dropped: Sequence[str] = ()) -> tuple[list[str], tuple[str, ...]]:
    """The fitted compliance parameters that came out negative, and a note for each (rad/(N·m)): a
    joint that bends against its load is not a spring, so such a term describes something else; it
    is dropped and the fit repeated without it. ``dropped``: the compliances an earlier round dropped,
    named in the note (their load then falls to the others, which may turn negative in turn)."""
    neg = [n for n in names if n.endswith(".compliance") and estimates[n] < 0.0]
    after = f" once {', '.join(n.split('.')[0] for n in dropped)}'s was dropped" if dropped else ""
    notes = tuple(f"{n.split('.')[0]}: compliance came out negative{after} ({estimates[n] / TAU_REF:+.3g} rad/(N·m), "
                  f"σ {std[n] / TAU_REF:.2g}) and was dropped; the fit was repeated without it" for n in neg)
    return neg, notes


def fit_stack(robot: Robot, observations: Sequence, options: FitOptions, held: Mapping[str, float] | None = None,
              say: Callable[[str], None] = lambda msg: None) -> CalibrationResult:
    """Calibrate ``robot`` from ``observations`` with ``options`` (checked): the error model (a name;
    "auto" is chosen by :func:`kincal.calibrate` on position data), drift, the fit, the negative-
    compliance refit and outlier rejection; ``held``: set-up parameters held at these values (a held-
    out file judged with the probe as trained). No diagnosis: the callers add theirs."""
    extended = _with_error_model(robot, observations, options.error_model)
    if extended is not robot and not isinstance(options.names, str):  # --params: the model's terms fitted too
        options = options.replace(names=(*options.names, *[n for n in extended.params.names
                                                            if n not in robot.params.names]))
    robot = extended
    sets = [in_joint_space(o, options.joint_std) for o in observations] if options.residual == "joint" \
        else list(observations)
    sets = [_drifting(o) for o in sets] if options.drift else sets
    prior = resolved_prior(options.prior, sets)
    kinds = " + ".join(dict.fromkeys(o.kind for o in sets))
    say(f"fitting {kinds} data ({sum(len(o) for o in sets)} samples)")

    dropped: list[str] = []
    notes: tuple[str, ...] = ()

    def fit(chosen: Sequence, loss: str, drop: bool = True) -> CalibrationResult:
        """The fit of ``chosen``; with ``drop``, again without each compliance that comes out negative until none
        does: at most one round per compliance (each drops one or more), so none is negative at the end."""
        nonlocal robot, options, dropped, notes
        res = fit_sets(robot, chosen, options, prior, loss, held or {})
        for _ in range(sum(n.endswith(".compliance") for n in robot.params.names) if drop else 0):
            neg, more = negative_compliances(res.names, res.robot.params.as_dict(), res.std, dropped)
            if not neg:
                break
            say("dropping negative compliance: " + ", ".join(neg))
            robot, dropped, notes = drop_terms(robot, neg), dropped + neg, notes + more
            if not isinstance(options.names, str):  # --params with the error model's terms: the dropped ones go
                options = options.replace(names=tuple(n for n in options.names if n not in neg))
            res = fit_sets(robot, chosen, options, prior, loss, held or {})
        return res
    res = fit(sets, options.loss)
    if options.reject_outliers:
        res = _without_outliers(fit, sets, res, options.loss, say)
    return dataclasses.replace(res, notes=notes) if notes else res


def _without_outliers(fit, observations: Sequence, res: CalibrationResult, loss: str, say) -> CalibrationResult:
    """``res`` fitted again (``fit(sets, loss)``) without the samples a robust fit (which drops no term) puts beyond
    the outlier limit, at most a tenth of a set's; ``res`` itself when there are none."""
    found = (res if loss != "linear" else fit(observations, "huber", drop=False)).outliers
    bad = [b if len(b) <= max(1, int(MAX_OUTLIER_SHARE * len(o))) else b[:0] for o, b in zip(observations, found)]
    if not any(len(b) for b in bad):
        return res
    kept = [o.subset(np.setdiff1d(np.arange(len(o)), b)) if len(b) else o for o, b in zip(observations, bad)]
    rejected = {o.source: tuple(int(r) for r in o.rows[b]) for o, b in zip(observations, bad) if len(b)}
    say(f"leaving out {sum(len(b) for b in bad)} outlier sample(s) and fitting again")
    return dataclasses.replace(fit(kept, loss), rejected=rejected, notes=res.notes)


def _drifting(obs):
    """``obs`` measured by a drifting instrument (in its session's frame, if it has one)."""
    if obs.kind not in ABSOLUTE:
        raise ValueError(f"drift: {obs.kind} data ({obs.source}) have no measuring instrument that could drift; the "
                         f"drift term is for points, poses and markers")
    return dataclasses.replace(obs, inner=Drifting.of(obs.inner)) if isinstance(obs, InSession) else Drifting.of(obs)


def _with_error_model(robot: Robot, observations: Sequence, error_model) -> Robot:
    """``robot`` extended by the named error model, its terms on the joints that move the tool at
    the samples (``robot`` itself for None)."""
    if error_model is None:
        return robot
    spec = ErrorModel.of(error_model)
    if spec.name == "auto":
        raise ValueError("error model 'auto' is chosen by blocked cross-validation of position data (kincal.calibrate"
                         "); for these data name the model (e.g. compliance, harmonics:2) and compare on held-out data")
    return extend(robot, spec, np.concatenate([o.q for o in observations]))
