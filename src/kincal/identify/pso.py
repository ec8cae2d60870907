"""Particle swarm optimisation with the settings of the 3-PUU paper of 2024 as defaults
("Error analysis model of parallel robot based on parameters identification", Table 2).

The objective is evaluated for the whole swarm at once, ``objective(X (S, K)) -> (S,)``: with a
model's batched kinematics (``forward_batch`` / ``inverse_batch``) no Python loop runs over particles.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._frozen import freeze_arrays

HALF_WIDTH = {"length": 8e-3, "angle": 8e-3, "ratio": 8e-3}  # the paper's position limits ±8 (mm), per kind (m, rad,
# ratio): the search box around the nominal values; an estimate on its edge is named in the verdict (search-box)
V_MAX = {"length": 0.5e-3, "angle": 0.5e-3, "ratio": 0.5e-3}  # and velocity limits ±0.5 (mm per iteration)


@dataclass(frozen=True)
class PSOResult:
    x: np.ndarray
    value: float
    history: np.ndarray  # best value after each iteration
    evaluations: int
    iterations: int

    def __post_init__(self) -> None:
        freeze_arrays(self)


def pso(objective: Callable[[np.ndarray], np.ndarray], center: np.ndarray, half_width: np.ndarray, v_max: np.ndarray,
        particles: int = 500, iterations: int = 200, w: float = 0.8, c1: float = 0.5, c2: float = 1.2,
        seed: int | None = 0) -> PSOResult:
    """Minimise ``objective`` (batched over the swarm) for x in [center − half_width, center + half_width].

    Velocities are clipped to ±v_max and positions to the box (the paper's "position limits ±8 mm,
    velocity ±0.5"). Non-finite objective values count as +inf. Returns the best position found.
    """
    rng = np.random.default_rng(seed)
    lo, hi = center - half_width, center + half_width
    x = rng.uniform(lo, hi, size=(particles, center.size))
    v = rng.uniform(-v_max, v_max, size=x.shape)
    f = _finite(objective(x))
    p_best, f_best = x.copy(), f.copy()
    g = int(np.argmin(f))
    g_best, g_val = x[g].copy(), float(f[g])
    history = np.empty(iterations)
    for it in range(iterations):
        r1, r2 = rng.random(x.shape), rng.random(x.shape)
        v = np.clip(w * v + c1 * r1 * (p_best - x) + c2 * r2 * (g_best - x), -v_max, v_max)
        x = np.clip(x + v, lo, hi)
        f = _finite(objective(x))
        better = f < f_best
        p_best[better], f_best[better] = x[better], f[better]
        g = int(np.argmin(f_best))
        if f_best[g] < g_val:
            g_best, g_val = p_best[g].copy(), float(f_best[g])
        history[it] = g_val
    return PSOResult(g_best, g_val, history, particles * (iterations + 1), iterations)


def _finite(f: np.ndarray) -> np.ndarray:
    f = np.asarray(f, dtype=float)
    return np.where(np.isfinite(f), f, np.inf)
