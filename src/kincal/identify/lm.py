"""Levenberg–Marquardt for small dense least-squares problems, with column scaling.

Minimises ½‖r(x)‖² where ``fun(x) -> (r (M,), J (M,K))`` (J may be a transposed view). Steps solve the damped, column-scaled
normal equations ``(AᵀA + μI) h = -Aᵀr`` with ``A = J D⁻¹`` (D: running maximum of the column norms,
Moré's scaling), and μ follows Nielsen's gain-ratio rule. Cheap for M ≫ K (a K×K Cholesky per step).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg as sla


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


def levenberg_marquardt(
    fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    x0: np.ndarray,
    max_iter: int = 100,
    xtol: float = 1e-10,
    ftol: float = 1e-12,
    gtol: float = 1e-12,
) -> LMResult:
    """Minimise ½‖r(x)‖²; converged when the scaled step, the relative cost decrease or the scaled
    gradient falls below its tolerance."""
    x = np.array(x0, dtype=float)
    r, J = fun(x)
    n_eval = 1
    cost = 0.5 * float(r @ r)
    if not (np.isfinite(cost) and np.all(np.isfinite(J))):
        raise ValueError("the residual or its Jacobian is not finite at the starting point")
    D = np.linalg.norm(J, axis=0)
    D[D == 0] = 1.0
    mu, nu = None, 2.0
    message, converged = f"stopped after {max_iter} iterations without meeting the tolerances", False
    it = 0
    for it in range(1, max_iter + 1):
        D = np.maximum(D, np.linalg.norm(J, axis=0))
        H = (J.T @ J) / np.outer(D, D)  # normal matrix of the scaled problem A = J D⁻¹
        g = (J.T @ r) / D
        if np.max(np.abs(g)) <= gtol * max(1.0, np.sqrt(2 * cost)):
            converged, message = True, "gradient below tolerance"
            break
        if mu is None:
            mu = 1e-8 * float(np.max(np.diag(H)))  # near Gauss-Newton: calibration problems are mildly nonlinear
        for _attempt in range(100):
            try:
                c = sla.cho_factor(H + mu * np.eye(H.shape[0]), check_finite=False)
                h = -sla.cho_solve(c, g, check_finite=False)
            except np.linalg.LinAlgError:
                mu *= nu
                nu *= 2.0
                continue
            x_new = x + h / D
            r_new, J_new = fun(x_new)
            n_eval += 1
            cost_new = 0.5 * float(r_new @ r_new)
            predicted = 0.5 * float(h @ (mu * h - g))
            rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
            if np.isfinite(cost_new) and rho > 0:
                small_step = np.linalg.norm(h) <= xtol * (np.linalg.norm(x * D) + xtol)
                small_drop = (cost - cost_new) <= ftol * cost
                x, r, J, cost = x_new, r_new, J_new, cost_new
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                break
            mu *= nu
            nu *= 2.0
            if not mu < 1e20 * max(1.0, float(np.max(np.diag(H)))):
                break
        else:
            mu = np.inf
        if not np.isfinite(mu) or not mu < 1e20 * max(1.0, float(np.max(np.diag(H)))):
            return LMResult(x, cost, r, J, it, n_eval, False,
                            "no step reduces the cost (damping exhausted); the problem may be ill-posed")
        if small_step:
            converged, message = True, "step below tolerance"
            break
        if small_drop:
            converged, message = True, "cost decrease below tolerance"
            break
    return LMResult(x, cost, r, J, it, n_eval, converged, message)
