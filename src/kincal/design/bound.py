"""Continuous relaxation of D-optimal design with a certified upper bound.

    maximise f(w) = log det Σ wᵢ JᵢᵀJᵢ   subject to Σ wᵢ = m, 0 ≤ wᵢ ≤ 1.

Every exact design of m distinct candidates is a feasible w, so the relaxed optimum bounds the best
exact design from above. f is concave with ∂f/∂wᵢ = dᵢ = tr(M⁻¹JᵢᵀJᵢ) and Σ wᵢdᵢ = k, so for any
feasible w (Frank–Wolfe duality)

    f* ≤ f(w) + max_{v feasible} ∇f(w)·(v − w) = f(w) + (sum of the m largest dᵢ) − k,

which is the certificate reported, whatever the solver's progress. The solver is accelerated projected
gradient ascent with backtracking (projection onto the capped simplex by bisection on the shift).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import DesignProblem
from .._frozen import freeze_arrays


@dataclass(frozen=True)
class Bound:
    """A certified upper bound on log det M over the m-pose designs of a pool.

    M is the information matrix in the problem's scaled units (:class:`DesignProblem`). Every exact design
    of m distinct candidates is a feasible weighting of the relaxation, so none exceeds ``upper``; the bound
    holds whatever the solver's progress (Frank–Wolfe duality).

    Parameters
    ----------
    upper : float
        Certified upper bound on log det M of any m-pose design of the pool (scaled units).
    relaxed : float
        log det M at the relaxed solution found (scaled units).
    weights : ndarray, shape (N,)
        The relaxed solution: one weight in [0, 1] per candidate, summing to m.
    iterations : int
        Iterations of the solver.

    Attributes
    ----------
    gap : float
        ``upper - relaxed``, the room left between the relaxed solution and the bound.

    See Also
    --------
    relaxed_bound : computes it.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.design import Bound
    >>> b = Bound(upper=10.5, relaxed=10.4, weights=np.full(4, 0.5), iterations=12)
    >>> round(b.gap, 6)
    0.1
    >>> sorted(b.to_dict())
    ['gap', 'iterations', 'relaxed', 'upper']
    """

    upper: float
    relaxed: float
    weights: np.ndarray
    iterations: int

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @property
    def gap(self) -> float:
        """``upper - relaxed`` (scaled units of log det M)."""
        return self.upper - self.relaxed

    def to_dict(self) -> dict:
        """The bound as JSON-ready values: upper, relaxed, gap and iterations (the weights left out)."""
        return {"upper": self.upper, "relaxed": self.relaxed, "gap": self.gap, "iterations": self.iterations}


def _project(v: np.ndarray, m: float) -> np.ndarray:
    """Euclidean projection onto {0 ≤ w ≤ 1, Σw = m}: w = clip(v − τ, 0, 1) with τ by bisection."""
    lo, hi = v.min() - 1.0, v.max()
    for _ in range(60):
        tau = 0.5 * (lo + hi)
        if np.clip(v - tau, 0.0, 1.0).sum() > m:
            lo = tau
        else:
            hi = tau
    return np.clip(v - 0.5 * (lo + hi), 0.0, 1.0)


def _eval(P: DesignProblem, w: np.ndarray):
    M = P.information(np.arange(P.N), w)
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        return -np.inf, None
    Y = np.linalg.solve(L, P.rows.T)  # (k, rN): L⁻¹Jᵀ
    d = np.sum((Y * Y).reshape(P.k, P.N, P.r), axis=(0, 2))
    return 2.0 * float(np.sum(np.log(np.diag(L)))), d


def relaxed_bound(P: DesignProblem, m: int, gap_tol: float = 2e-3, max_iter: int = 300) -> Bound:
    """Certified upper bound on log det M over m-point designs of the problem's candidates.

    Maximises the continuous relaxation f(w) = log det Σ wᵢ JᵢᵀJᵢ subject to Σ wᵢ = m, 0 ≤ wᵢ ≤ 1 by
    accelerated projected-gradient ascent (FISTA with restarts) from uniform weights; it stops when the
    certified gap is below ``gap_tol`` (an efficiency uncertainty of about gap_tol/k) or after ``max_iter``
    iterations. The bound f(w) + (sum of the m largest dᵢ) − k, dᵢ = tr(M⁻¹JᵢᵀJᵢ), holds at any feasible w.

    Parameters
    ----------
    P : DesignProblem
        The candidates and their scaled Jacobian blocks (N, r, k).
    m : int
        Number of poses of the designs bounded.
    gap_tol : float, optional
        Stop when the certified gap (upper − relaxed, in log det units) is at most this (default 2e-3).
    max_iter : int, optional
        Most iterations of the solver (default 300).

    Returns
    -------
    Bound
        The certified upper bound, the log det of the relaxed solution, its weights (N,) and the iterations.

    Examples
    --------
    >>> import kincal
    >>> from kincal.design import candidate_pool, design_problem, relaxed_bound
    >>> robot = kincal.load_robot("ur5")
    >>> pool = candidate_pool(robot, 60, seed=1)
    >>> P = design_problem(robot, pool, names=["j2.theta", "j3.theta", "j4.theta", "j2.a", "j3.a"])
    >>> b = relaxed_bound(P, 10)
    >>> bool(b.gap <= 2e-3), b.weights.shape, round(float(b.weights.sum()), 6)
    (True, (60,), 10.0)
    """
    N, k = P.N, P.k
    w = np.full(N, m / N)
    f, d = _eval(P, w)
    best_upper = np.inf
    step = m / max(k, 1)
    y, fy, dy, t = w, f, d, 1.0  # extrapolated point (FISTA)
    it = 0
    for it in range(1, max_iter + 1):
        best_upper = min(best_upper, f + np.sort(d)[-m:].sum() - k)
        if best_upper - f <= gap_tol:
            break
        while True:  # backtracking from the extrapolated point
            w_new = _project(y + step * dy, m)
            f_new, d_new = _eval(P, w_new)
            diff = w_new - y
            if f_new >= fy + dy @ diff - diff @ diff / (2 * step) or (step := step * 0.5) < 1e-14:
                break
        if step < 1e-14:
            break
        if f_new < f:  # restart the momentum when it overshoots
            y, fy, dy, t = w, f, d, 1.0
            continue
        t_new = 0.5 * (1 + np.sqrt(1 + 4 * t * t))
        y = _project(w_new + (t - 1) / t_new * (w_new - w), m)
        fy, dy = _eval(P, y)
        if dy is None:
            y, fy, dy = w_new, f_new, d_new
        w, f, d, t = w_new, f_new, d_new, t_new
        step *= 1.5
    best_upper = min(best_upper, f + np.sort(d)[-m:].sum() - k)
    return Bound(float(best_upper), float(f), w, it)
