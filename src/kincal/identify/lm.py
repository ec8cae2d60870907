"""Levenberg–Marquardt for small dense least-squares problems, with column scaling.

Minimises ½‖r(x)‖² where ``fun(x) -> (r (M,), J (M,K))`` (J may be a transposed view). Steps solve the
damped, column-scaled normal equations ``(AᵀA + μI) h = -Aᵀr`` with ``A = J D⁻¹`` (D: running maximum
of the column norms, Moré's scaling), and μ follows Nielsen's gain-ratio rule. Cheap for M ≫ K (a
K×K Cholesky per step).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..analysis.observability import column_norms
from .._frozen import freeze_arrays
from ..errors import ModelError

MU_LIMIT = 1e20  # damping beyond this (relative to the largest diagonal entry) means no step helps
STATIONARY = 1e-6  # when no step helps, a residual this close to orthogonal to every column is an optimum


@dataclass(frozen=True)
class LMResult:
    x: np.ndarray
    cost: float  # ½‖r‖² at x
    residual: np.ndarray
    jacobian: np.ndarray
    iterations: int
    evaluations: int
    converged: bool
    message: str

    def __post_init__(self) -> None:
        freeze_arrays(self)


@dataclass
class _Step:
    """Outcome of the damping loop of one iteration."""

    accepted: bool
    x: np.ndarray
    r: np.ndarray
    J: np.ndarray
    cost: float
    h: np.ndarray
    mu: float
    evaluations: int
    negligible: bool = False  # no step can lower the cost by more than the tolerance: not even tried


def _damped_step(fun, x, cost, H, g, D, mu: float, floor: float = 0.0) -> _Step:
    """Raise μ until a step lowers the cost (Nielsen's rule), or give up past MU_LIMIT; a step whose
    predicted decrease is at most ``floor`` is not evaluated (``negligible``): near an optimum the
    cost's round-off (10⁵ poses) would reject it, and each rejection costs an evaluation."""
    nu, evals, limit = 2.0, 0, MU_LIMIT * max(1.0, float(np.max(np.diag(H))))
    eye = np.eye(H.shape[0])
    while mu < limit:
        try:
            L = np.linalg.cholesky(H + mu * eye)  # numpy's: SciPy's linear algebra takes 0.3-0.7 s to import
            h = -np.linalg.solve(L.T, np.linalg.solve(L, g))
        except np.linalg.LinAlgError:
            mu, nu = mu * nu, nu * 2.0
            continue
        predicted = 0.5 * float(h @ (mu * h - g))
        if predicted <= floor:
            return _Step(False, x, np.empty(0), np.empty(0), cost, np.zeros_like(g), mu, evals, True)
        x_new = x + h / D
        evals += 1
        try:
            r_new, J_new = fun(x_new)
        except ModelError:  # a trial the model cannot take (a closed chain that no longer assembles): a shorter one
            mu, nu = mu * nu, nu * 2.0
            continue
        cost_new = 0.5 * float(r_new @ r_new)
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        if np.isfinite(cost_new) and rho > 0:
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            return _Step(True, x_new, r_new, J_new, cost_new, h, mu, evals)
        mu, nu = mu * nu, nu * 2.0
    return _Step(False, x, np.empty(0), np.empty(0), cost, np.zeros_like(g), mu, evals)


def levenberg_marquardt(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], x0: np.ndarray, max_iter: int = 100,
                        xtol: float = 1e-10, ftol: float = 1e-12, gtol: float = 1e-12) -> LMResult:
    """Minimise ½‖r(x)‖²; converged when the scaled step, the relative cost decrease or the scaled
    gradient falls below its tolerance, or when no step lowers the cost at a point where the residual
    is orthogonal to every scaled column within ``STATIONARY`` (the cosine; round-off level)."""
    x = np.array(x0, dtype=float)
    r, J = fun(x)
    n_eval, cost = 1, 0.5 * float(r @ r)
    if not (np.isfinite(cost) and np.all(np.isfinite(J))):
        raise ValueError("the residual or its Jacobian is not finite at the starting point")
    if x.size == 0:  # nothing free (a model judged with every parameter fixed): the start is the answer
        return LMResult(x, cost, r, J, 0, n_eval, True, "no free parameters")
    D = column_norms(J)
    D[D == 0] = 1.0
    mu = None
    for it in range(1, max_iter + 1):
        D = np.maximum(D, column_norms(J))
        H = (J.T @ J) / np.outer(D, D)  # normal matrix of the scaled problem A = J D⁻¹
        g = (J.T @ r) / D
        if np.max(np.abs(g)) <= gtol * max(1.0, np.sqrt(2 * cost)):
            return LMResult(x, cost, r, J, it, n_eval, True, "gradient below tolerance")
        if mu is None:
            mu = 1e-8 * float(np.max(np.diag(H)))  # near Gauss-Newton: calibration problems are mildly nonlinear
        step = _damped_step(fun, x, cost, H, g, D, mu, ftol * cost)
        n_eval += step.evaluations
        if step.negligible:
            return LMResult(x, cost, r, J, it, n_eval, True, "predicted decrease below tolerance")
        if not step.accepted:  # at an optimum, round-off can leave nothing to gain
            if np.max(np.abs(g)) <= STATIONARY * np.sqrt(2 * cost):
                return LMResult(x, cost, r, J, it, n_eval, True, "stationary point (no decrease left above round-off)")
            return LMResult(x, cost, r, J, it, n_eval, False,
                            "no step reduces the cost (damping exhausted); the problem may be ill-posed")
        small_step = np.linalg.norm(step.h) <= xtol * (np.linalg.norm(x * D) + xtol)
        small_drop = (cost - step.cost) <= ftol * cost
        x, r, J, cost, mu = step.x, step.r, step.J, step.cost, step.mu
        if small_step or small_drop:
            return LMResult(x, cost, r, J, it, n_eval, True,
                            "step below tolerance" if small_step else "cost decrease below tolerance")
    return LMResult(x, cost, r, J, max_iter, n_eval, False,
                    f"stopped after {max_iter} iterations without meeting the tolerances")
