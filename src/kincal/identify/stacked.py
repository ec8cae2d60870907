"""Calibration from any mix of observation types: the stacked, σ-whitened problem.

Every observation set (:mod:`kincal.observe`) gives its residual, its noise σ
and its nuisance parameters; this module stacks them (nuisance parameters with the same name are
one parameter: the same target, socket or plane seen by two sets), chooses the free parameters by
the one identifiability rule on the whitened Jacobian (nuisance parameters first, then the base
frame, then the model's preferred ones, so a confound is always resolved in favour of the set-up),
fits them by Levenberg–Marquardt, by default refits them with a prior learned from the data
(:mod:`kincal.identify.relevance`: corrections the data cannot confirm stay at nominal) and judges
the result.

Refused before any work: data with no length reference (only sockets without a distance, or only
unknown planes), because a robot shrunk towards a point explains them equally well.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial
from typing import Mapping, Sequence

import numpy as np

from .._threads import blas_threads
from ..analysis.identifiability import RANK_TOL, Identifiability, jacobian_identifiability
from ..analysis.observability import live_columns
from ..errors import MeasurementError
from ..models.robot import Robot
from ..models.terms import ErrorModel, drop_terms, extend
from ..observe.drifting import DRIFT, Drifting
from ..observe.sessions import InSession
from .compliance import negative_compliances
from .covariance import parameter_statistics
from .lm import levenberg_marquardt
from .noise import extra_variance
from .observed_diagnosis import diagnosed
from .observed_result import ObservationFit
from .observed_verdict import component_kinds, observation_verdict, outlier_samples, whitened_per_kind
from .registration import register_base
from .relevance import PRIORS, RelevanceFit, with_learned_prior
from .robust import LOSSES, MAX_IRLS, WEIGHT_TOL, block_weights
from .verdict import MAX_OUTLIER_SHARE, Thresholds
from .weak import weakest


@dataclass(frozen=True)
class _Stack:
    """The stacked problem: sets, robot candidates, nuisance names/start values, σ per component."""

    sets: tuple
    robot: Robot
    nuis_names: tuple[str, ...]
    nuis0: np.ndarray
    slots: tuple[np.ndarray, ...]  # per set: positions of its nuisance parameters in the stacked vector
    inv_sigma: np.ndarray  # (M,) the weights in use: 1/√(σ² + s²), s² the model error of the row's kind
    stated: np.ndarray  # (M,) 1/σ as stated (the instrument's noise)
    labels: np.ndarray  # (M,) each row's kind of component, an index into ``kinds``
    kinds: tuple[str, ...]  # "pose position", "pose rotation", "markers", ...
    late: tuple[str, ...] = ()  # set-up parameters chosen after the robot's when confounded (an instrument's drift)
    held: tuple[str, ...] = ()  # set-up parameters held at their start values (a held-out file's probe as trained)

    def with_model_error(self, r: np.ndarray, n_free: int) -> tuple["_Stack", dict]:
        """The stack weighted by 1/(σ² + s²) per kind of component, s² what the whitened residual
        ``r`` (at the weights in use) leaves beyond the stated σ (:mod:`kincal.identify.noise`);
        and s per kind (m or rad)."""
        phys2, var = (r / self.inv_sigma) ** 2, 1.0 / self.stated**2
        share = 1.0 - n_free / r.size
        s2 = np.array([extra_variance(phys2[self.labels == k], var[self.labels == k],
                                      share * np.count_nonzero(self.labels == k)) for k in range(len(self.kinds))])
        st = dataclasses.replace(self, inv_sigma=1.0 / np.sqrt(var + s2[self.labels]))
        return st, {k: float(np.sqrt(v)) for k, v in zip(self.kinds, s2)}

    def evaluate(self, values: np.ndarray, nuis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whitened residual (M,) and Jacobian (M, P + K) over all robot and nuisance parameters."""
        rs, Js = [], []
        for obs, slot in zip(self.sets, self.slots):
            r, Jr, Jn = obs.evaluate(self.robot, values, nuis[slot])
            J = np.zeros((r.size, values.size + nuis.size))
            J[:, :values.size] = Jr
            J[:, values.size + slot] = Jn
            rs.append(r)
            Js.append(J)
        r, J = np.concatenate(rs), np.concatenate(Js)
        return r * self.inv_sigma, J * self.inv_sigma[:, None]


def _stack(robot: Robot, observations: Sequence) -> _Stack:
    anchors: dict = {}
    prepared = []
    for o in (o.prepare(robot) for o in observations):  # sets sharing a target start from the first's
        o = o.with_anchors({k: v for k, v in anchors.items() if k in o.anchors()})
        anchors = {**o.anchors(), **anchors}
        prepared.append(o)
    sets = tuple(prepared)
    names: list[str] = []
    start: list[float] = []
    slots, late = [], []
    for obs in sets:
        n, v, k = obs.nuisance(robot)
        late += [name for name, kind in zip(n, k) if kind == DRIFT]
        for name, value in zip(n, v):
            if name not in names:
                names.append(name)
                start.append(float(value))
        slots.append(np.array([names.index(name) for name in n], dtype=int))
    sigma = np.concatenate([o.sigma() for o in sets])
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise MeasurementError("every measurement σ must be a positive number (m or rad)")
    labels, kinds = component_kinds(sets)
    return _Stack(sets, robot, tuple(names), np.array(start), tuple(slots), 1.0 / sigma, 1.0 / sigma, labels, kinds,
                  tuple(late))


def _gauge(robot: Robot, sets) -> tuple[str, ...]:
    """Robot parameters no set sees (the intersection of the sets' gauge freedoms)."""
    common = set(robot.params.names)
    for obs in sets:
        common &= set(obs.gauge_params(robot))
    return tuple(n for n in robot.params.names if n in common)


def fit_observations(robot: Robot, observations: Sequence, names: Sequence[str] | str = "auto",
                     keep: Sequence[str] = (), max_iter: int = 100, rank_tol: float = RANK_TOL,
                     prior: str = "relevance", thresholds: Thresholds | None = None, loss: str = "linear",
                     reject_outliers: bool = False, error_model: ErrorModel | str | None = None,
                     diagnose: bool = False, drift: bool = False, held: Mapping[str, float] | None = None
                     ) -> ObservationFit:
    """Calibrate ``robot`` from observation sets of any types (see the module docstring). ``names``:
    robot parameters to fit ("auto": every identifiable one); ``keep``: chosen first among confounded;
    ``prior``: "relevance" (a prior σ per joint origin and kind learned from the data,
    :mod:`kincal.identify.relevance`) or "none" (least squares); ``thresholds``: the verdict's limits
    of plausible corrections and of the mounting (default :class:`Thresholds`); ``loss``: "linear", or
    "huber" / "soft_l1" on each sample's whitened block (:func:`kincal.identify.robust.block_weights`);
    ``reject_outliers``: leave out the samples a robust (Huber) fit puts beyond the outlier limit, at
    most a tenth of a set's, and fit again (named in ``rejected`` by file and row); ``error_model``: a
    named :class:`~kincal.ErrorModel` (terms beyond geometry on the joints that move the tool at these
    samples; not "auto", which is chosen on position data); a compliance that comes out negative is
    dropped and the fit repeated (said in ``notes``); ``diagnose``: when the verdict doubts the data,
    screen the common input mistakes on the measured positions and name the one that explains them
    (:mod:`kincal.identify.observed_diagnosis`); ``drift``: each set of measured positions (points,
    poses, markers) gets its instrument's drift over its row order as set-up parameters
    (:class:`kincal.observe.Drifting`); ``held``: set-up parameters held at these values, not fitted
    (a held-out file judged with the probe's rotation and the markers as trained).

    Identifiability is judged at the start and again at the solution: where the fit moved the model
    (a tool point off a joint's axis) the data may identify other parameters. When the set changed,
    the fit is repeated from its solution with the new set, at most ``JUDGED`` times, and
    ``identifiability.notes`` says so."""
    if prior not in PRIORS:
        raise ValueError(f"prior {prior!r}: use one of {', '.join(PRIORS)}")
    if loss not in LOSSES or any(flag not in (True, False) for flag in (reject_outliers, diagnose, drift)):
        raise ValueError(f"loss {loss!r}: one of {', '.join(LOSSES)}; reject_outliers {reject_outliers!r}, diagnose "
                         f"{diagnose!r}, drift {drift!r}: True or False")
    th = thresholds or Thresholds()
    robot = _with_error_model(robot, observations, error_model)
    observations = [_drifting(o) for o in observations] if drift else observations

    def fit(sets: Sequence, lo: str) -> ObservationFit:
        return _fit_sets(robot, sets, names, keep, max_iter, rank_tol, prior, th, lo, held or {})
    res = fit(observations, loss)
    neg, notes = negative_compliances(res.names, res.robot.params.as_dict(), res.std)
    if neg:
        robot = drop_terms(robot, neg)
        res = dataclasses.replace(fit(observations, loss), notes=notes)
    if reject_outliers:
        res = _without_outliers(fit, observations, res, loss)
    return diagnosed(res, robot) if diagnose else res


def _without_outliers(fit, observations: Sequence, res: ObservationFit, loss: str) -> ObservationFit:
    """``res`` fitted again (``fit(sets, loss)``) without the samples a robust fit puts beyond the
    outlier limit, at most a tenth of a set's; ``res`` itself when there are none."""
    found = (res if loss != "linear" else fit(observations, "huber")).outliers
    bad = [b if len(b) <= max(1, int(MAX_OUTLIER_SHARE * len(o))) else b[:0] for o, b in zip(observations, found)]
    if not any(len(b) for b in bad):
        return res
    kept = [o.subset(np.setdiff1d(np.arange(len(o)), b)) if len(b) else o for o, b in zip(observations, bad)]
    rejected = {o.source: tuple(int(r) for r in o.rows[b]) for o, b in zip(observations, bad) if len(b)}
    return dataclasses.replace(fit(kept, loss), rejected=rejected, notes=res.notes)


def _drifting(obs):
    """``obs`` measured by a drifting instrument (in its session's frame, if it has one)."""
    if obs.kind not in ("point", "pose", "markers"):
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
        raise ValueError("error model 'auto' is chosen by blocked cross-validation of position data; for these "
                         "data name the model (e.g. compliance, harmonics:2) and compare on held-out data")
    return extend(robot, spec, np.concatenate([o.q for o in observations]))


def _fit_sets(robot: Robot, observations: Sequence, names, keep, max_iter: int, rank_tol: float, prior: str,
              th: Thresholds, loss: str, held: Mapping[str, float]) -> ObservationFit:
    """:func:`fit_observations` without leaving anything out."""
    with blas_threads(1):
        robot, st, gauge, ident, start = _problem(robot, observations, names, keep, rank_tol, held)
        if start[0].size <= len(ident.identifiable):
            raise MeasurementError(f"{start[0].size} residual components for {len(ident.identifiable)} parameters: "
                                   f"measure more samples")
        x0 = np.concatenate([robot.params.values, st.nuis0])
        wanted = robot.params.names if names == "auto" else tuple(names)
        rounds = _Round(robot, st, x0, max_iter, prior, loss)
        full, fit, free, weak, fitted, error = rounds.fit(list(ident.identifiable), x0, start)
        notes: tuple[str, ...] = ()
        for k in range(JUDGED + 1):
            # the fitted set first among confounded ones: only a real change of what the data see counts
            again = _identifiability(robot, st, gauge, wanted, (*keep, *ident.identifiable), rank_tol, full)
            change = again.change_from(ident)
            if not change:
                break
            if k == JUDGED:
                notes += (f"at the fitted model the identifiable set still changes ({change}) after {JUDGED} refits; "
                          f"the last fit is kept: measure poses that see these parameters clearly",)
                break
            notes += (f"at the fitted model the data identify a different set ({change}): refitted from that "
                      f"solution",)
            ident = again
            full, fit, free, weak, fitted, error = rounds.fit(list(ident.identifiable), full, None)
        ident = dataclasses.replace(_without_weak(ident, free, weak), notes=ident.notes + notes)
        return _result(robot, fitted, gauge, ident, free, rounds.cols(free), x0, fit, weak, th, error)


JUDGED = 3  # refits when the identifiable set at the solution differs from the start's


@dataclass(frozen=True)
class _Round:
    """One fit of a set of free columns: LM from a start, parameters the data hardly see kept nominal,
    then (by default) the learned prior. The columns not fitted stay at ``x0`` (the nominal values,
    the set-up parameters' starts), which is also the prior's centre."""

    robot: Robot
    st: _Stack
    x0: np.ndarray
    max_iter: int
    prior: str
    loss: str = "linear"

    def cols(self, free: Sequence[str]) -> np.ndarray:
        all_names = list(self.robot.params.names) + list(self.st.nuis_names)
        return np.array([all_names.index(n) for n in free], dtype=int)

    def fit(self, free: list[str], start: np.ndarray, evaluated):
        """(full vector, fit, free names, weak, the stack with its weights, s per kind) from the full
        vector ``start`` (its evaluation ``evaluated`` (r, J) over all columns, or None): least squares
        and the weak hold, the model error per kind estimated and the fit repeated until it settles,
        then the learned prior."""
        st, candidates = self.st, list(free)
        error: dict[str, float] = {}
        for _ in range(NOISE_ROUNDS):
            fcols, fit, free, weak = self._least_squares(st, list(candidates), start, evaluated)
            start, evaluated = self.x0.copy(), None
            start[fcols] = fit.x
            again, found = st.with_model_error(fit.residual, len(free))
            ratio = again.inv_sigma / st.inv_sigma
            if float(np.max(ratio)) <= float(np.min(ratio)) * (1.0 + NOISE_SETTLED):  # the same relative weights:
                error = found if any(found.values()) else error  # the same fit (one kind, one σ: a scale only)
                break
            st, error = again, found
        if self.loss != "linear":
            st, fit = self._reweighted(st, fcols, fit)
        if self.prior == "relevance":
            fit = with_learned_prior(lambda x: _fun(st, self.x0, fcols, x), fit, self.x0[fcols], free, self.robot)
        full = self.x0.copy()
        full[fcols] = fit.x
        return full, fit, free, weak, st, error

    def _least_squares(self, st: _Stack, free: list[str], start: np.ndarray, evaluated):
        """LM on ``free``; a parameter the data determine worse than a real robot's error kept nominal
        and the fit repeated: (columns, fit, free names, weak)."""
        weak: dict[str, float] = {}
        while True:
            fcols = self.cols(free)
            fun = (_fun_from(st, self.x0, fcols, evaluated) if evaluated is not None and
                   np.array_equal(start, self.x0) else lambda x, c=fcols: _fun(st, self.x0, c, x))
            fit = levenberg_marquardt(fun, start[fcols], max_iter=self.max_iter)
            worst = weakest(self.robot, free, fit.jacobian, fit.residual)
            if worst is None:
                return fcols, fit, free, weak
            weak[worst[0]] = worst[1]
            free.remove(worst[0])


    def _reweighted(self, st: _Stack, fcols: np.ndarray, fit):
        """Iteratively reweighted least squares on each sample's whitened block until the weights
        settle: (the stack with the robust factors in its weights, the fit)."""
        owner, n = _owners(st.sets)
        base, factor = st, np.ones(owner.size)
        for _ in range(MAX_IRLS):
            new = block_weights(fit.residual / factor, owner, n, self.loss)
            if np.max(np.abs(new**2 - factor**2)) < WEIGHT_TOL:
                break
            factor = new
            st = dataclasses.replace(base, inv_sigma=base.inv_sigma * factor)
            fit = levenberg_marquardt(partial(_fun, st, self.x0, fcols), fit.x, max_iter=self.max_iter)
        return st, fit


def _owners(sets) -> tuple[np.ndarray, int]:
    """Each stacked row's sample, numbered over all sets (−1: a row of no one sample), and the count."""
    out, n = [], 0
    for obs in sets:
        rows = obs.sample_rows()
        out.append(np.where(rows >= 0, rows + n, -1))
        n += len(obs)
    return np.concatenate(out), n


NOISE_ROUNDS = 4  # least-squares fits at most, the model error per kind re-estimated after each
NOISE_SETTLED = 0.02  # relative change of every weight that ends them


def observation_identifiability(robot: Robot, observations: Sequence, names: Sequence[str] | str = "auto",
                                keep: Sequence[str] = (), rank_tol: float = RANK_TOL
                                ) -> tuple[Identifiability, tuple[str, ...]]:
    """Which robot and set-up parameters the observation sets identify (the rule of
    :func:`fit_observations`, at ``robot``), and the gauge freedoms no set sees: for planned
    measurements (simulated at the nominal robot) before anyone measures."""
    with blas_threads(1):
        _, _, gauge, ident, _ = _problem(robot, observations, names, keep, rank_tol)
    return ident, gauge


def _problem(robot: Robot, observations: Sequence, names, keep, rank_tol, held: Mapping[str, float] | None = None):
    """The registered robot, the stacked problem (set-up parameters in ``held`` at those values, not
    fitted), the gauge, the identifiability (robot and set-up parameters; the gauge left out) and the
    whitened residual and Jacobian (all columns) at the start."""
    if not observations:
        raise MeasurementError("no observations given")
    wanted = robot.params.names if names == "auto" else tuple(names)
    if wanted and not any(o.reference for o in observations):  # (a model only evaluated needs no scale)
        raise MeasurementError(
            "these data do not fix the length scale: sockets without a known distance, or plane contacts without two "
            "known parallel planes at different heights, are explained as well by a robot shrunk towards a point, so "
            "the scale is unobservable; give a known distance between two labelled points, a known step between two "
            "parallel planes, or some absolute measurements (a tracker, a camera)")
    gauge = _gauge(robot, observations)
    if set(robot.base_params()) & set(wanted):  # a base that is not fitted stays where it is
        robot = _registered(robot, observations, gauge)
    st = _stack(robot, [_session_start(robot, o) for o in observations])
    if held:
        kept = tuple(n for n in st.nuis_names if n in held)
        st = dataclasses.replace(st, held=kept, nuis0=np.array([float(held[n]) if n in held else v
                                                                for n, v in zip(st.nuis_names, st.nuis0)]))
    x0 = np.concatenate([robot.params.values, st.nuis0])
    start = st.evaluate(robot.params.values, st.nuis0)
    ident = _identifiability(robot, st, gauge, wanted, keep, rank_tol, x0, start)
    return robot, st, gauge, ident, start


def _identifiability(robot: Robot, st: _Stack, gauge, wanted, keep, rank_tol, full: np.ndarray,
                     evaluated=None) -> Identifiability:
    """The one rule on the whitened Jacobian at the full vector ``full`` (robot and set-up
    parameters; its evaluation ``evaluated`` if known): robot and set-up parameters, the gauge left out."""
    # the gauge freedoms go before the robot's parameters: what acts like them (joint 1's origin next to
    # an unseen base) is dropped as confounded with them, not fitted to the residuals' curvature alone
    cand = list(gauge) + [n for n in wanted if n not in set(gauge)]
    P = robot.n_params
    J0 = (evaluated or st.evaluate(full[:P], full[P:]))[1]
    all_names = list(robot.params.names) + list(st.nuis_names)
    nuis = [n for n in st.nuis_names if n not in st.held]
    cols = np.array([all_names.index(n) for n in cand + nuis], dtype=int)
    live = live_columns(J0[:, cols] / st.inv_sigma[:, None])  # no effect: judged in m and rad, not whitened
    ident = jacobian_identifiability(J0[:, cols], cand + nuis,
                                     [list(keep), [n for n in nuis if n not in st.late], list(gauge),
                                      list(robot.base_params()),
                                      list(robot.preferred_params())], robot.name,
                                     sum(len(o) for o in st.sets), rank_tol, live)
    unseen = set(gauge)
    free = tuple(n for n in ident.identifiable if n not in unseen)
    notes = (f"not seen by these data (gauge freedoms, kept at their values): {', '.join(gauge)}",) if gauge else ()
    ident = dataclasses.replace(ident, measured=" + ".join(dict.fromkeys(o.kind for o in st.sets)), identifiable=free,
                                candidates=tuple(n for n in ident.candidates if n not in unseen), rank=len(free),
                                dropped=tuple(n for n in ident.dropped if n not in unseen),
                                confounds={k: v for k, v in ident.confounds.items() if k not in unseen},
                                notes=ident.notes + notes)
    return ident


def _without_weak(ident: Identifiability, free: list[str], weak: dict) -> Identifiability:
    if not weak:
        return ident
    note = (f"kept at nominal, determined worse than a real robot's error (10 mm, 2 deg): {', '.join(weak)}",)
    return dataclasses.replace(ident, identifiable=tuple(free), notes=ident.notes + note)


def _registered(robot: Robot, sets, gauge) -> Robot:
    """``robot`` with its measurement frame registered rigidly to the absolute positions in ``sets``
    (none, or a base the data do not see: unchanged)."""
    found = [p for p in (o.positions() for o in sets) if p is not None]
    if not found or not robot.base_params() or set(robot.base_params()) <= set(gauge):
        return robot
    q, xyz = np.concatenate([f[0] for f in found]), np.concatenate([f[1] for f in found])
    return register_base(robot, q, xyz) if len(q) >= 3 else robot


def _session_start(robot: Robot, obs):
    """A set in its own session frame, with the frame's start registered rigidly to its positions."""
    if not isinstance(obs, InSession) or obs.frame0 is not None:
        return obs
    found = obs.session_positions()
    if found is None or len(found[0]) < 3:
        raise MeasurementError(f"{obs.source}: a session in its own frame needs at least 3 absolute positions")
    moved = register_base(robot, *found)
    return dataclasses.replace(obs, frame0=moved.params.values[moved.params.indices(robot.base_params())])


def _fun_from(st: _Stack, x0: np.ndarray, fcols: np.ndarray, start: tuple[np.ndarray, np.ndarray]):
    """:func:`_fun` of the columns ``fcols``, the start's evaluation (all columns) reused at the start."""
    def fun(x):
        if np.array_equal(x, x0[fcols]):
            return start[0], start[1][:, fcols]
        return _fun(st, x0, fcols, x)
    return fun


def _fun(st: _Stack, x0: np.ndarray, fcols: np.ndarray, x: np.ndarray):
    full = x0.copy()
    full[fcols] = x
    P = st.robot.n_params
    r, J = st.evaluate(full[:P], full[P:])
    return r, J[:, fcols]


def _result(robot, st, gauge, ident, free, fcols, x0, fit, weak, th: Thresholds, error: dict) -> ObservationFit:
    full = x0.copy()
    full[fcols] = fit.x
    P = robot.n_params
    calibrated = robot.with_params(dict(zip(robot.params.names, full[:P])))
    if isinstance(fit, RelevanceFit):
        cov, learned = fit.covariance, fit.sigma
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    else:
        sd, _, _, cov = parameter_statistics(fit.jacobian, fit.residual, free, free)
        learned = {}
    nuis = dict(zip(st.nuis_names, full[P:]))
    std = {n: float(v) for n, v in zip(free, sd)}
    std.update({n: np.inf for n in st.nuis_names if n not in std})
    before = tuple(o.stats(robot, x0[:P], x0[P:][slot]) for o, slot in zip(st.sets, st.slots))
    after = tuple(o.stats(robot, full[:P], full[P:][slot]) for o, slot in zip(st.sets, st.slots))
    r = fit.residual * st.stated / st.inv_sigma  # whitened by the stated σ: what the user can restate
    rms = float(np.sqrt(np.mean(r**2)))
    per_kind = whitened_per_kind(st.sets, r)
    verdict = observation_verdict(robot, calibrated, st.sets, r, per_kind, fit.converged, th)
    return ObservationFit(calibrated, robot, tuple(n for n in free if n in robot.params.names), nuis, std, ident,
                          gauge, before, after, rms, cov, verdict, bool(fit.converged), fit.iterations, st.sets, weak,
                          learned, per_kind, {k: v for k, v in error.items() if v > 0},
                          outlier_samples(st.sets, r, th), whitened_residual=r)
