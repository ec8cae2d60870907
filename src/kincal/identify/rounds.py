"""One fit of the stacked problem's free columns (:class:`Round`): Levenberg–Marquardt from a start
(robustly reweighted with a robust loss), parameters the data hardly determine kept nominal, the
model error per kind estimated and the fit repeated until it settles, then the learned prior; and
the particle swarm that can start it (:func:`swarm`). The stack itself is
:class:`kincal.identify.stacked._Stack`; this room only evaluates it."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from .._frozen import freeze_arrays
from ..errors import MeasurementError, ModelError

from .judge import STATED, owners
from .lm import LMResult, levenberg_marquardt
from .pso import HALF_WIDTH, V_MAX, pso
from .relevance import with_learned_prior
from .robust import MAX_IRLS, WEIGHT_TOL, block_weights
from .weak import weak_note, weakest

if TYPE_CHECKING:  # the stack evaluates itself; this room only calls it
    from .stacked import _Stack


def unassembled(sets) -> MeasurementError:
    """The error of a fit that moved the model where it no longer assembles at some of the measured joints of the
    observation sets ``sets`` (a closed chain): the data and the model do not belong together."""
    files = ", ".join(sorted({o.source for o in sets}))
    return MeasurementError(f"{files}: the fit moved the model where it no longer assembles at some of the measured "
                            f"joints: the data and the model do not belong together; check the position and rotation "
                            f"columns (their order and axes: --xyz-cols, --rot-cols), the joint columns and their units")


def undetermined(st: _Stack, weak: dict[str, float]) -> MeasurementError:
    """The error of a fit whose every parameter the data determine worse than a real robot's error at the stated σ
    (``weak``: name -> its σ, m or rad): nothing is left to fit. Those σ are likely far too large."""
    files = ", ".join(sorted({o.source for o in st.sets}))
    flags = ", ".join(dict.fromkeys("--std-joint" if k == "joint" else STATED.get(k, "--std-pos") for k in st.kinds))
    shown = weak_note(st.robot, dict(list(weak.items())[:MAX_SHOWN])).split(": ", 1)[1]
    more = f" and {len(weak) - MAX_SHOWN} more" if len(weak) > MAX_SHOWN else ""
    return MeasurementError(f"{files}: no parameter is determined by these data at the stated σ: each is known worse "
                            f"than a real robot's error (10 mm, 2 deg) ({shown}{more}), so none is left to fit; the "
                            f"stated σ ({flags}) are likely far too large: state the instrument's real noise, or "
                            f"measure more poses spread over the workspace")


MAX_SHOWN = 6  # parameters named in that error


@dataclass(frozen=True)
class Round:
    """One fit of a set of free columns (module docstring). The columns not fitted stay at ``x0`` (the
    nominal values, the set-up parameters' starts), which is also the prior's centre."""

    st: _Stack
    x0: np.ndarray
    max_iter: int
    prior: str
    loss: str = "linear"
    f_scale: float | None = None  # m: the robust loss's scale on a sample's position norm (None: 3 robust σ)
    spent: list = dataclasses.field(default_factory=lambda: [0, 0, 0])  # iterations, evaluations, solver runs so far

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def fit(self, free: list[str], start: np.ndarray, evaluated):
        """(full vector, fit, free names, weak, the stack with its weights, s per kind) from the full
        vector ``start`` (its evaluation ``evaluated`` (r, J) over all columns, or None), as the module
        docstring says."""
        st, candidates = self.st, list(free)
        error: dict[str, float] = {}
        checked = np.array_equal(start, self.x0)  # the model as given, where the data's own joints were checked
        for k in range(NOISE_ROUNDS):
            try:
                fcols, fit, free, weak, used = self._least_squares(st, list(candidates), start, evaluated)
            except ModelError:  # the first round from the model as given: the data's joints (checked) say why
                if k == 0 and checked:
                    raise
                raise unassembled(st.sets) from None
            start, evaluated = self.x0.copy(), None
            start[fcols] = fit.x
            again, found = used.with_model_error(fit.residual, len(free))
            ratio = again.inv_sigma / st.inv_sigma
            if float(np.max(ratio)) <= float(np.min(ratio)) * (1.0 + NOISE_SETTLED):  # the same relative weights:
                error = found if any(found.values()) else error  # the same fit (one kind, one σ: a scale only)
                break
            st, error = again, found
        if self.prior == "relevance":
            fit = self._count(with_learned_prior(lambda x: fun_at(used, self.x0, fcols, x), fit, self.x0[fcols], free,
                                                 self.st.robot, self.max_iter), fit)
        full = self.x0.copy()
        full[fcols] = fit.x
        return full, fit, free, weak, used, error

    def _least_squares(self, st: _Stack, free: list[str], start: np.ndarray, evaluated):
        """LM on ``free`` (then reweighted, with a robust loss: outliers must not decide what is weak);
        a parameter the data determine worse than a real robot's error kept nominal and the fit
        repeated: (columns, fit, free names, weak, the stack with the robust factors in its weights)."""
        weak: dict[str, float] = {}
        scales = self.st.robot.correction_scales(np.concatenate([o.q for o in self.st.sets]))  # a compliance's load
        while True:
            fcols = self.st.cols(free)
            at_start = evaluated if evaluated is not None and np.array_equal(start, self.x0) else None
            fun = partial(fun_at, st, self.x0, fcols, start=at_start)
            if self.loss == "linear":
                fit, used = self._lm(fun, start[fcols]), st
            else:  # reweighted from the start: a least-squares fit pulled by outliers is a poor place to begin
                used, fit = self._reweighted(st, fcols, start[fcols], fun(start[fcols])[0])
            worst = weakest(self.st.robot, free, fit.jacobian * used.weak_scale(fit.residual, len(free))[:, None], 1.0,
                            scales)
            if worst is None:
                return fcols, fit, free, weak, used
            weak[worst[0]] = worst[1]
            free.remove(worst[0])
            if not free:
                raise undetermined(st, weak)

    def _reweighted(self, st: _Stack, fcols: np.ndarray, x: np.ndarray, r: np.ndarray):
        """Iteratively reweighted least squares on each sample's whitened block from ``x`` (its
        whitened residual ``r``) until the weights settle: (the stack with the robust factors in its
        weights, the fit)."""
        owner, n = owners(st.sets)
        base, factor = st, np.full(owner.size, np.nan)  # (nan: at least one fit)
        scale = None if self.f_scale is None else self.f_scale * float(np.median(st.inv_sigma))
        for _ in range(MAX_IRLS):
            new = block_weights(r / np.nan_to_num(factor, nan=1.0), owner, n, self.loss, scale)
            if np.max(np.abs(new**2 - factor**2)) < WEIGHT_TOL:
                break
            factor = new
            st = dataclasses.replace(base, inv_sigma=base.inv_sigma * factor)
            fit = self._lm(partial(fun_at, st, self.x0, fcols), x)
            x, r = fit.x, fit.residual
        return st, fit

    def _lm(self, fun, x0: np.ndarray):
        return self._count(levenberg_marquardt(fun, x0, max_iter=self.max_iter))

    def _count(self, run, before=None):
        """``run``, a solver run of at most ``max_iter`` iterations, added to what was spent (none when it is
        ``before``, the fit a learned prior had nothing to add to)."""
        if run is not before:
            self.spent[0] += run.iterations
            self.spent[1] += run.evaluations
            self.spent[2] += 1
        return run


NOISE_ROUNDS = 4  # least-squares fits at most, the model error per kind re-estimated after each
NOISE_SETTLED = 0.02  # relative change of every weight that ends them


def fun_at(st: _Stack, x0: np.ndarray, fcols: np.ndarray, x: np.ndarray,
           start: tuple[np.ndarray, np.ndarray] | None = None):
    """The stack's whitened residual and Jacobian in the columns ``fcols`` at ``x`` (the others at ``x0``);
    ``start``, the evaluation (all columns) at ``x0``, is reused there."""
    if start is not None and np.array_equal(x, x0[fcols]):
        return start[0], start[1][:, fcols]
    full = x0.copy()
    full[fcols] = x
    P = st.robot.n_params
    return st.evaluate(full[:P], full[P:], fcols)


def swarm(st: _Stack, x0: np.ndarray, cols: np.ndarray, settings) -> tuple[np.ndarray, LMResult, tuple[float, ...]]:
    """Particle swarm (:mod:`kincal.identify.pso`) over the robot parameters ``cols`` on the sets'
    batched mean squared residual, around ``x0``; sets with set-up parameters cannot take part. Returns
    the full vector, the fit evaluated there (no iterations of its own: it carries the swarm's iterations
    and evaluations) and the best mean squared residual per iteration."""
    P = st.robot.n_params
    if st.nuis_names or np.any(cols >= P):
        raise ValueError("a particle swarm fits the robot's parameters to points or joint-space residuals only: "
                         "these data bring set-up parameters (a frame, a target); use method 'lm'")

    def cost(X: np.ndarray) -> np.ndarray:
        V = np.tile(x0[:P], (X.shape[0], 1))
        V[:, cols] = X
        return sum((o.batch_cost(st.robot, V) for o in st.sets), np.zeros(X.shape[0]))
    kinds = [st.robot.params.kinds[i] for i in cols]
    found = pso(cost, x0[cols], np.array([HALF_WIDTH[k] for k in kinds]), np.array([V_MAX[k] for k in kinds]),
                **settings.to_dict())
    full = x0.copy()
    full[cols] = found.x
    r, J = fun_at(st, x0, cols, found.x)
    fit = LMResult(found.x, 0.5 * float(r @ r), r, J, found.iterations, found.evaluations, True,
                   "the particle swarm ran all its iterations; a swarm has no test of convergence")
    return full, fit, tuple(map(float, found.history))
