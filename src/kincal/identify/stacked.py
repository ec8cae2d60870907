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
from typing import Mapping, Sequence

import numpy as np

from .._threads import blas_threads
from ..analysis.identifiability import RANK_TOL, Identifiability, frame_members, jacobian_identifiability, kinds_of
from ..analysis.observability import live_columns
from ..errors import IdentifiabilityError, MeasurementError, ModelError
from ..models.robot import TOOL_NAMES, Robot
from ..models.transforms import kabsch
from ..observe.constraints import SamePointObs
from ..observe.drifting import DRIFT
from ..observe.joint import in_cartesian, unassembled_rows
from ..observe.observations import PoseObs, Wrapper
from ..observe.sessions import InSession
from .covariance import parameter_statistics
from ..analysis.changes import Repeat
from .repeat import repeat_of
from .options import FitOptions, PSOOptions
from .pso import HALF_WIDTH
from .noise import extra_variance
from .result import CalibrationResult
from .judge import component_kinds, outlier_samples
from .registration import register_base, register_mounting, register_points
from .relevance import RelevanceFit
from .rounds import Round, swarm, unassembled
from .verdict import Thresholds


LEVERAGE_FLOOR = 1e-12  # a sample's residual variance below this share of its largest: the fit took that direction


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

    def cols(self, names: Sequence[str]) -> np.ndarray:
        """The positions of the robot and set-up parameters ``names`` in the full vector (robot's, then set-up's)."""
        all_names = list(self.robot.params.names) + list(self.nuis_names)
        return np.array([all_names.index(n) for n in names], dtype=int)

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

    def weak_scale(self, r: np.ndarray, n_free: int) -> np.ndarray:
        """(M,) factors that whiten the rows by √(σ² + s²) instead of the weights in use: what the
        weak-parameter rule judges σ by, the stated σ and what the model cannot describe (robustly
        estimated: a few outliers do not make the rest look weak). A kind whose s exceeds
        ``residual_refuse`` times its stated σ (the data do not belong to the model: swapped joints)
        is judged by its stated σ alone, so its implausible corrections stay in view."""
        st, s = self.with_model_error(r, n_free)
        refuse = Thresholds().residual_refuse
        for k, kind in enumerate(self.kinds):
            rows = self.labels == k
            if rows.any() and s[kind] > refuse / float(np.median(self.stated[rows])):
                st.inv_sigma[rows] = self.stated[rows]
        return st.inv_sigma / self.inv_sigma

    def judged(self, u: np.ndarray, G: np.ndarray, A: np.ndarray, values: np.ndarray, nuis: np.ndarray) -> np.ndarray:
        """(M,) the fit's residual ``u`` (M,), whitened by the weights in use, whitened by the stated noise instead:
        what the verdict judges by and the user can restate. A row of its own σ is r/σ. A sample whose components
        share noise (:meth:`~kincal.observe.Observation.covariance` C at ``values`` and ``nuis``) is whitened by its
        residual's covariance after the fit, V = [(I − H) C (I − H)ᵀ]ᵢᵢ, H = G A Gᵀ the fit's hat matrix (G (M, K)
        its whitened Jacobian, A (K, K) its parameters' covariance in those units), so rᵢᵀ V⁻¹ rᵢ is its squared
        norm: where C is far larger along some directions than others, the fit's own error leaks into the quiet
        ones and C alone would take those samples for outliers (26 of 100 clean simulated hexapod calibrations, their
        poses stated at 0.015 mm and 1 mrad as simulated; 1 of 100 so)."""
        out = u * self.stated / self.inv_sigma
        var = (self.inv_sigma / self.stated) ** 2  # each row's stated variance in the fit's units
        ends, blocks, own = np.cumsum([0, *[o.sigma().size for o in self.sets]]), [], np.ones(u.size, bool)
        for o, slot, start in zip(self.sets, self.slots, ends[:-1]):
            try:
                C = o.covariance(self.robot, values, nuis[slot])
            except ModelError:  # a sample out of reach where a swarm stopped: its residual is infinite anyway
                C = None
            if C is not None and np.all(np.isfinite(C)):  # its rows per sample (N, c), and C in the fit's units
                rows = start + np.argsort(o.sample_rows(), kind="stable").reshape(len(o), -1)
                w = self.inv_sigma[rows]
                blocks.append((rows, w[:, :, None] * C * w[:, None, :]))
                own[rows] = False
        if not blocks or not np.all(np.isfinite(G)):
            return out
        B = (G[own].T * var[own]) @ G[own] + sum(np.einsum("nik,nij,njl->kl", G[rows], Cw, G[rows])
                                                 for rows, Cw in blocks)  # the parameters' error, (K, K)
        for rows, Cw in blocks:
            GA = G[rows] @ A
            H = GA @ G[rows].transpose(0, 2, 1)
            lam, Q = np.linalg.eigh(Cw - H @ Cw - Cw @ H + GA @ B @ GA.transpose(0, 2, 1))
            lam = np.maximum(lam, np.maximum(lam[:, -1:], np.finfo(float).tiny) * LEVERAGE_FLOOR)
            out[rows] = np.einsum("nji,nj->ni", Q, u[rows]) / np.sqrt(lam)
        return out

    def evaluate(self, values: np.ndarray, nuis: np.ndarray,
                 cols: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Whitened residual (M,) and Jacobian (M, P + K) over all robot and nuisance parameters, or
        over the columns ``cols`` of them (one set without set-up parameters: its own column view, no
        copy of the columns not asked for)."""
        if len(self.sets) == 1 and not nuis.size:
            r, J = self.sets[0].evaluate_cols(self.robot, values, np.arange(values.size) if cols is None else cols)
        else:
            rs, Js = [], []
            for obs, slot in zip(self.sets, self.slots):
                r, Jr, Jn = obs.evaluate(self.robot, values, nuis[slot])
                Jo = np.zeros((r.size, values.size + nuis.size))
                Jo[:, :values.size] = Jr
                Jo[:, values.size + slot] = Jn
                rs.append(r)
                Js.append(Jo)
            r, J = np.concatenate(rs), np.concatenate(Js)
            J = J if cols is None else J[:, cols]
        J *= self.inv_sigma[:, None]  # (a fresh array either way)
        return r * self.inv_sigma, J


def _stack(robot: Robot, observations: Sequence) -> _Stack:
    anchors: dict = {}
    prepared = []
    for o in (o.prepare(robot) for o in observations):  # sets sharing a target start from the first's
        o = o.with_anchors({k: v for k, v in anchors.items() if k in o.anchors()})
        anchors = {**o.anchors(), **anchors}
        prepared.append(o)
    sets = tuple(o.after(prepared[:k]) if isinstance(o, SamePointObs) else o for k, o in enumerate(prepared))
    start: dict[str, float] = {}  # a name shared by several sets is one parameter, started from the first's value
    own, late = [], []
    for obs in sets:
        n, v, k = obs.nuisance(robot)
        late += [name for name, kind in zip(n, k) if kind == DRIFT]
        for name, value in zip(n, v):
            start.setdefault(name, float(value))
        own.append(n)
    names = list(start)
    slots = [np.array([names.index(name) for name in n], dtype=int) for n in own]
    sigma = np.concatenate([o.sigma() for o in sets])
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise MeasurementError("every measurement σ must be a positive number (m or rad)")
    labels, kinds = component_kinds(sets)
    return _Stack(sets, robot, tuple(names), np.array(list(start.values())), tuple(slots), 1.0 / sigma, 1.0 / sigma,
                  labels, kinds, tuple(late))


def fit_sets(robot: Robot, observations: Sequence, o: FitOptions, prior: str, loss: str,
             held: Mapping[str, float]) -> CalibrationResult:
    """The one fit of ``observations`` with the options ``o`` (the learned ``prior`` resolved, the
    ``loss`` in use), set-up parameters in ``held`` kept at those values: nothing left out, nothing
    diagnosed (:func:`kincal.identify.fitting.fit_stack` wraps it)."""
    with blas_threads(1):
        wanted, declared = wanted_names(robot, o), robot
        robot, st, gauge, ident, start = _problem(robot, observations, wanted, o.keep, o.rank_tol, held)
        models = (declared, robot, _before(robot, st, bool(set(robot.base_params()) & set(wanted)), wanted))
        _check_strict(ident, o, st)
        _check_equations(st, start[0].size, len(ident.identifiable if o.method == "lm" else ident.candidates))
        x0 = np.concatenate([robot.params.values, st.nuis0])
        rounds = Round(st, x0, o.max_iter, prior, loss, o.f_scale)
        begin = x0  # where Levenberg-Marquardt starts
        history: tuple[float, ...] = ()  # the particle swarm's best value per iteration, when it runs
        if o.method != "lm":
            begin, swarmed, history = swarm(st, x0, st.cols(ident.candidates), o.pso or PSOOptions())
            rounds.spent[:] = [swarmed.iterations, swarmed.evaluations, 1]  # every solver run counts
            if o.method == "pso":
                return _result(models, st, gauge, ident, list(ident.candidates), x0, swarmed, {}, o, {}, rounds.spent,
                               history, ident.dropped)
            start = None
        full, fit, free, weak, fitted, error = rounds.fit(list(ident.identifiable), begin, start)
        notes: tuple[str, ...] = ()
        for k in range(JUDGED + 1):
            # the fitted set first among confounded ones: only a real change of what the data see counts
            again = _identifiability(robot, st, gauge, wanted, (*o.keep, *ident.identifiable), o.rank_tol, full)
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
        ident = dataclasses.replace(ident, identifiable=tuple(free) if weak else ident.identifiable,
                                    notes=ident.notes + notes)
        return _result(models, fitted, gauge, ident, free, x0, fit, weak, o, error, rounds.spent, history)


JUDGED = 3  # refits when the identifiable set at the solution differs from the start's


def wanted_names(robot: Robot, o: FitOptions) -> tuple[str, ...]:
    """The robot parameters a fit with ``o`` may free: ``o.names`` ("auto": all), the base frame's
    added when it is estimated and left out when it is known (``o.base``: the one base-mode rule)."""
    base = robot.base_params()
    if o.names == "auto":
        return tuple(n for n in robot.params.names if o.base == "estimate" or n not in base)
    clash = [n for n in o.names if n in base]
    if o.base == "fixed" and clash:
        raise ValueError(f"{', '.join(clash)} listed with base='fixed': the base frame is known; use base='estimate' "
                         f"to fit it")
    return tuple(dict.fromkeys((*base, *o.names))) if o.base == "estimate" else tuple(o.names)


def _check_strict(ident: Identifiability, o: FitOptions, st: "_Stack") -> None:
    """An explicit list of names fitted by Levenberg–Marquardt must be identifiable (a particle swarm,
    a global search, keeps the undetermined ones free)."""
    if o.names == "auto" or o.method != "lm":
        return
    lost = [n for n in ident.dropped if n in set(o.names) and n not in st.robot.base_params()]
    if lost:
        raise IdentifiabilityError(f"these parameters cannot all be identified from the {_samples(st)}; leave out "
                                   f"the dropped ones or estimate names='auto':\n{ident}")


def _samples(st: "_Stack") -> str:
    n = sum(len(o) for o in st.sets)
    return f"{n} poses" if all(o.kind in ("point", "joint") for o in st.sets) else f"{n} samples"


def _check_equations(st: "_Stack", equations: int, unknowns: int) -> None:
    """More residual components than free parameters, or a MeasurementError saying how many samples."""
    if equations > unknowns:
        return
    per = equations // max(sum(len(o) for o in st.sets), 1)
    raise MeasurementError(f"{st.sets[0].source}: {_samples(st)} give {equations} equations for {unknowns} "
                           f"parameters; measure at least {unknowns // max(per, 1) + 1} (3-5 times as many is "
                           f"advisable)")


def observation_identifiability(robot: Robot, observations: Sequence, names: Sequence[str] | str = "auto",
                                keep: Sequence[str] = (), rank_tol: float = RANK_TOL
                                ) -> tuple[Identifiability, tuple[str, ...]]:
    """Which robot and set-up parameters the observation sets identify, and the gauge freedoms no set sees.

    The rule of :func:`~kincal.identify.fit_observations`, at ``robot``: for planned measurements
    (simulated at the nominal robot) before anyone measures.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    observations : sequence of Observation
        The planned observation sets (points, poses, markers, sockets, planes).
    names : "auto" or sequence of str, optional
        The robot parameters to consider (default ``"auto"``: all of them).
    keep : sequence of str, optional
        Names to prefer among confounded parameters (default none).
    rank_tol : float, optional
        Relative singular-value tolerance (default :data:`~kincal.analysis.RANK_TOL`, 3e-5).

    Returns
    -------
    identifiability : Identifiability
        What the sets determine among the robot and set-up parameters (the gauge left out).
    gauge : tuple of str
        The robot parameters no set sees (gauge freedoms: a base frame that sockets or planes do not
        see), kept at their values.

    Raises
    ------
    MeasurementError
        For no observations, or data that do not fix the length scale.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import observation_identifiability
    >>> from kincal.observe import PointObs
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(30, seed=2)
    >>> plan = PointObs(q, list(range(2, 32)), "plan.csv", xyz=robot.forward(q))
    >>> ident, gauge = observation_identifiability(robot, [plan])
    >>> ident.rank, len(ident.candidates), gauge
    (27, 35, ())
    >>> ident.dropped[:4]
    ('j1.theta', 'j1.d', 'j3.d', 'j4.d')
    """
    wanted = robot.params.names if names == "auto" else tuple(names)
    with blas_threads(1):
        _, _, gauge, ident, _ = _problem(robot, observations, wanted, keep, rank_tol)
    return ident, gauge


def _problem(robot: Robot, observations: Sequence, wanted: tuple[str, ...], keep, rank_tol,
             held: Mapping[str, float] | None = None):
    """The registered robot, the stacked problem (set-up parameters in ``held`` at those values, not
    fitted), the gauge, the identifiability (robot and set-up parameters; the gauge left out) and the
    whitened residual and Jacobian (all columns) at the start."""
    if not observations:
        raise MeasurementError("no observations given")
    if wanted and not any(o.reference for o in observations):  # (a model only evaluated needs no scale)
        for o in observations:  # a known step stated in another unit is named as such first
            o.check_known_lengths(robot)
        raise MeasurementError(
            "these data do not fix the length scale: sockets without a known distance, or plane contacts without two "
            "known parallel planes at different heights, are explained as well by a robot shrunk towards a point, so "
            "the scale is unobservable; give a known distance between two labelled points, a known step between two "
            "parallel planes, or some absolute measurements (a tracker, a camera)")
    for o in observations:  # joint values the robot does not assemble at (a closed chain): named by row
        found = o.positions()
        error = None if found is None else unassembled_rows(o.source, found[0], found[1], robot, o.rows)
        if error is not None:
            raise error[0]
    unseen = set(robot.params.names).intersection(*(obs.gauge_params(robot) for obs in observations))
    gauge = tuple(n for n in robot.params.names if n in unseen)  # robot parameters no set sees
    if set(robot.base_params()) & set(wanted):  # a base that is not fitted stays where it is
        robot = _registered(robot, observations, gauge)
    st = _stack(robot, [_session_start(robot, o) for o in observations])
    if held:
        kept = tuple(n for n in st.nuis_names if n in held)
        st = dataclasses.replace(st, held=kept, nuis0=np.array([float(held[n]) if n in held else v
                                                                for n, v in zip(st.nuis_names, st.nuis0)]))
    for o in st.sets:
        o.check(robot, robot.params.values)
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
    nuis = [n for n in st.nuis_names if n not in st.held]
    cols = st.cols(cand + nuis)
    J0 = evaluated[1][:, cols] if evaluated else st.evaluate(full[:P], full[P:], cols)[1]
    w = st.inv_sigma
    # no effect: judged in m and rad, not whitened (one σ for every row: a scale of the column norms)
    live = live_columns(J0, 1.0 / w[0]) if w.size and np.all(w == w[0]) else live_columns(J0 / w[:, None])
    ident = jacobian_identifiability(J0, cand + nuis,
                                     [list(keep), [n for n in nuis if n not in st.late], list(gauge),
                                      list(robot.base_params()),
                                      list(robot.preferred_params())], robot.name,
                                     sum(len(o) for o in st.sets), rank_tol, live, frame_members(robot))
    ident = _design_frames(robot, ident).without_unseen(gauge)
    notes = (f"not seen by these data (gauge freedoms, kept at their values): {', '.join(gauge)}",) if gauge else ()
    return dataclasses.replace(ident, measured=" + ".join(dict.fromkeys(o.kind for o in st.sets)),
                               notes=ident.notes + notes, kinds=kinds_of(robot, cand + nuis))


def _design_frames(robot: Robot, ident: Identifiability) -> Identifiability:
    """``ident`` with the parameters it drops among a design frame's (:meth:`Robot.frame_freedoms`) named as that
    frame's gauge freedoms (``frames``) instead of as confounded, when no more are dropped there than the frame
    has freedoms (more would be a weakness of the data, said as such)."""
    held: list[str] = []
    said = []
    for what, members, count in robot.frame_freedoms():
        inside = [n for n in ident.dropped if n in set(members)]
        if 0 < len(inside) <= count:
            held += inside
            said.append(f"{what} ({len(inside)}: {', '.join(inside)})")
    if not held:
        return ident
    return dataclasses.replace(ident, dropped=tuple(n for n in ident.dropped if n not in set(held)),
                               confounds={k: v for k, v in ident.confounds.items() if k not in set(held)},
                               frames=tuple(held), frames_note=f"{len(held)} gauge freedoms of the design frames, "
                               f"held at their values (no prediction depends on them): " + "; ".join(said))


MOUNTED = ("point", "pose")  # the kinds whose positions register the nominal model's target point "before" calibration
# (markers register their own points; sockets and planes keep the declared target point: the MUKCa sockets' 8.28 mm)
Before = tuple[Robot, dict, tuple[dict, ...] | None]  # the "before" model, its markers' points, its per-set figures


def _before(robot: Robot, st: _Stack, frame: bool, wanted) -> Before:
    """The nominal kinematics as judged "before" calibration, so the figure does not depend on where the target
    was declared, the markers' points registered with it (name -> m) and each set's figures under it (None:
    computed from the model with the sets' set-up values).

    With poses (whatever residual the fit uses): the measurement frame (when it is fitted, ``frame``), the target
    point and every set-up parameter (the target's rotation, a session's frame) fitted to the sets' position and
    rotation errors with the kinematics fixed, as ``kincal evaluate`` judges the nominal model and as a held-out
    file's nominal figure is (:func:`kincal.identify.held_out_nominal`); a fit of nothing but that mounting is
    that registration, its own "before" (``()``). Else points and markers: :func:`_registered_before`."""
    cartesian = [in_cartesian(o) for o in st.sets]
    mounting = (*(robot.base_params() if frame else ()), *(TOOL_NAMES if robot.has_tool_point else ()))
    if any(o.kind == "pose" for o in cartesian):
        if set(wanted) <= set(mounting):
            return robot, {}, ()  # the fit is that registration: its own "before"
        from .fitting import fit_stack  # (fitting fits stacks through this module)

        judged = fit_stack(robot, cartesian, FitOptions(diagnose=False).replace(
            names=mounting, base="estimate" if frame else "fixed").check(robot))
        return judged.robot, {}, tuple({**s, "type": o.kind} for s, o in zip(judged.per_set, st.sets))
    return (*_registered_before(robot, st, cartesian, frame), None)


def _registered_before(robot: Robot, st: _Stack, cartesian, frame: bool) -> tuple[Robot, dict]:
    """The nominal kinematics with the measurement frame (when it is fitted, ``frame``), the target point and the
    markers' points registered to the measured points and markers in the robot's frame (:func:`register_mounting`,
    :func:`register_points`), and the registered markers' points (name -> m). Markers judged by their start instead:
    5.50 mm for one marker of a simulated UR5 registered at 0.83."""
    found: dict = {}  # a point's name (tool, marker[m1]) -> its (q, xyz) per set
    for o in (o for o in cartesian if o.kind in (*MOUNTED, "markers")):
        for key, seen in o.flange_positions().items():
            found.setdefault(key, []).append(seen)
    keys = list(found)
    q, xyz = ([np.concatenate([f[i] for f in found[k]]) for k in keys] for i in (0, 1))
    if keys == ["tool"]:
        return register_mounting(robot, q[0], xyz[0], frame), {}
    if sum(map(len, q)) < 3:
        return robot, {}
    start = {**dict(zip(st.nuis_names, st.nuis0)), **robot.params.as_dict()}
    which = np.concatenate([np.full(len(a), k) for k, a in enumerate(q)])
    moved, points = register_points(robot, np.concatenate(q), np.concatenate(xyz), which,
                                    np.array([[start[f"{k}.{a}"] for a in "xyz"] for k in keys]), frame)
    setup = {f"{k}.{a}": float(v) for k, point in zip(keys, points) for a, v in zip("xyz", point)}
    moved = moved.with_params({n: v for n, v in setup.items() if n in moved.params.names})
    return moved, {n: v for n, v in setup.items() if n not in moved.params.names}


def session_before(model: Robot, obs, setup: Mapping[str, float] | None = None) -> Robot:
    """The "before" model ``model`` as the set ``obs`` is judged by it (its per-set "before" figures): a set in a
    session's own frame with that frame registered to the session's positions, any other set as it is; markers
    registered with their points in ``setup`` (name -> m), their centroid taken for the tool point would not be
    (2.28 mm on the second of two simulated UR5 sessions instead of 0.80)."""
    found = obs.inner.flange_positions() if isinstance(obs, InSession) else {}
    if not found or not model.base_params():
        return model
    if list(found) == ["tool"]:
        return register_base(model, *found["tool"])
    points = [model.with_params({f"tool.{a}": (setup or {}).get(f"{k}.{a}", model.params[f"tool.{a}"]) for a in "xyz"})
              for k in found]
    R, t = kabsch(np.concatenate([m.forward(q) for m, (q, _) in zip(points, found.values())]),
                  np.concatenate([xyz for _, xyz in found.values()]))
    Rb, tb = model.base_transform()
    return model.with_base_transform(R @ Rb, R @ tb + t)


def before_nuisance(model: Robot, obs, nuis: np.ndarray, names, setup: dict) -> np.ndarray:
    """A set's set-up values (``names``) for its "before" figures: as the fit started, but the markers' points as
    registered with the "before" model (``setup``, name -> m; :func:`_before`), a session's own frame registered
    to its positions with the "before" model (it kept the frame the fit started from, with the declared tool
    point: 2.86 mm on the second half of the UR5 grid, whose nominal registered alone gives 0.65 mm), and a 6-D
    target's turn registered to its rotations (its start came with the declared frame: the positioner's "before"
    rotation was 14.9 mrad against the nominal model's 0.85 registered)."""
    out = np.array([setup.get(n, v) for n, v in zip(names, nuis)], float)
    at = session_before(model, obs, dict(zip(names, out)))
    if at is not model:
        out[len(out) - len(model.base_params()):] = at.params.values[at.params.indices(model.base_params())]
    inner = obs
    while isinstance(inner, Wrapper):
        inner = inner.inner
    if isinstance(inner, PoseObs) and len(out) >= 3:  # the target's turn: the inner set's first set-up values
        out[:3] = inner.registered_turn(at)
    return out


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
    found = obs.inner.positions()  # in the session's own frame
    if found is None or len(found[0]) < 3:
        raise MeasurementError(f"{obs.source}: a session in its own frame needs at least 3 absolute positions")
    moved = register_base(robot, *found)
    return dataclasses.replace(obs, frame0=moved.params.values[moved.params.indices(robot.base_params())])


def _swarm_drift(robot: Robot, ident, moved) -> list[tuple[str, float, tuple]]:
    """For each parameter a particle swarm moved that the data do not determine: its name, the variance of a value
    anywhere in its search box (uniform, half-width :data:`HALF_WIDTH` of its kind, m or rad) and the determined
    parameters it acts like (its confound), whose values move with it."""
    kinds = dict(zip(robot.params.names, robot.params.kinds))
    return [(d, HALF_WIDTH[kinds[d]] ** 2 / 3.0, ident.confounds.get(d, ())) for d in moved if d in kinds]


def _result(models: tuple[Robot, Robot, Before], st, gauge, ident, free, x0, fit, weak, o: FitOptions, error: dict,
            spent: list, history: tuple[float, ...], undetermined=()) -> CalibrationResult:
    """The fit of the columns ``free`` as a :class:`CalibrationResult` with options ``o`` (``models``: the model as given,
    as registered, and as judged "before" with its markers' points and its per-set figures, :func:`_before`;
    ``undetermined``: moved by a particle swarm but not determined by the data, σ = inf; ``spent``: iterations and
    evaluations of every solver run, and how many runs)."""
    declared, robot, (before_model, before_setup, figures) = models
    full = x0.copy()
    full[st.cols(free)] = fit.x
    P = robot.n_params
    calibrated = robot.with_params(dict(zip(robot.params.names, full[:P])))
    if isinstance(fit, RelevanceFit):
        cov, learned = fit.covariance, fit.sigma
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    else:
        sd, cov = parameter_statistics(fit.jacobian, fit.residual, free, undetermined,
                                       _swarm_drift(robot, ident, undetermined))
        learned = {}
    std = {n: float(v) for n, v in zip(free, sd)}
    std.update({n: np.inf for n in st.nuis_names if n not in std})
    judged = [o.among(st.sets) if isinstance(o, SamePointObs) else o for o in st.sets]  # a shared point is one point
    try:
        after = tuple(o.stats(robot, full[:P], full[P:][slot]) for o, slot in zip(judged, st.slots))
    except ModelError:  # a fit on other residuals (the joints') whose model does not assemble at the data's joints
        raise unassembled(st.sets) from None
    before: tuple[dict, ...] | None = figures
    if before == ():  # a fit of the mounting alone: it is its own "before"
        before_model, before = calibrated, after
    before = before or tuple(o.stats(before_model, before_model.params.values, before_nuisance(
        before_model, o, x0[P:][slot], [st.nuis_names[k] for k in slot], before_setup))
        for o, slot in zip(judged, st.slots))
    r = st.judged(fit.residual, fit.jacobian, _hat_covariance(fit, cov), full[:P], full[P:])
    return CalibrationResult(
        robot=calibrated, nominal=declared, registered=robot, before=before_model, before_setup=before_setup,
        names=tuple(n for n in free if n in robot.params.names), nuisance=dict(zip(st.nuis_names, full[P:])),
        std=std, identifiability=ident, gauge=gauge, per_set_before=before, per_set=after,
        whitened_rms=float(np.sqrt(np.mean(r**2))), covariance=cov,
        converged=bool(fit.converged), iterations=spent[0], runs=spent[2], observations=st.sets, weak=weak, prior=learned,
        whitened={name: float(np.sqrt(np.mean(r[st.labels == k] ** 2))) for k, name in enumerate(st.kinds)},
        model_error={k: v for k, v in error.items() if v > 0},
        outliers=outlier_samples(st.sets, r, o.thresholds), whitened_residual=r, evaluations=spent[1],
        message=fit.message, history=tuple(history),
        free=tuple(free), options=o, repeat=_repeat(calibrated, st, fit, free, weak))


def _hat_covariance(fit, cov: np.ndarray) -> np.ndarray:
    """(K, K) the fitted columns' covariance in the fit's whitened units, as its hat matrix takes them: the posterior's
    with a learned prior, else (GᵀG)⁺ of the whitened Jacobian G; zeros where G is not finite (a stopped swarm)."""
    G = fit.jacobian
    if not np.all(np.isfinite(G)):
        return np.zeros((G.shape[1], G.shape[1]))
    return cov / fit.noise2 if isinstance(fit, RelevanceFit) and fit.noise2 > 0 else np.linalg.pinv(G.T @ G)


def _repeat(robot: Robot, st, fit, free, weak: dict) -> Repeat:
    """What a repeat calibration on other poses of the region would differ by (:mod:`kincal.identify.repeat`), the
    parameters kept nominal because the data determine them too weakly with the σ the data gave them."""
    posterior = fit.covariance / fit.noise2 if isinstance(fit, RelevanceFit) else None
    return repeat_of(robot, st.sets, free, fit.jacobian, fit.residual, posterior, fit.residual / st.inv_sigma,
                     weak)
