"""Particle swarm optimisation with the seed-2 paper's settings as defaults (Table 2)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class PSOResult:
    x: np.ndarray
    value: float
    history: np.ndarray  # best value after each iteration
    evaluations: int
    iterations: int


def pso(
    objective: Callable[[np.ndarray], float],
    center: np.ndarray,
    half_width: np.ndarray,
    v_max: np.ndarray,
    particles: int = 500,
    iterations: int = 200,
    w: float = 0.8,
    c1: float = 0.5,
    c2: float = 1.2,
    seed: int | None = 0,
    progress: Callable[[int, float], None] | None = None,
) -> PSOResult:
    """Minimise ``objective(x)`` for x in [center − half_width, center + half_width].

    Velocities are clipped to ±v_max and positions to the box (the paper's "position limits ±8 mm,
    velocity ±0.5"). Returns the best position found.
    """
    rng = np.random.default_rng(seed)
    lo, hi = center - half_width, center + half_width
    x = rng.uniform(lo, hi, size=(particles, center.size))
    v = rng.uniform(-v_max, v_max, size=x.shape)
    f = np.array([objective(xi) for xi in x])
    p_best, f_best = x.copy(), f.copy()
    g = int(np.argmin(f))
    g_best, g_val = x[g].copy(), float(f[g])
    history = []
    for it in range(iterations):
        r1, r2 = rng.random(x.shape), rng.random(x.shape)
        v = np.clip(w * v + c1 * r1 * (p_best - x) + c2 * r2 * (g_best - x), -v_max, v_max)
        x = np.clip(x + v, lo, hi)
        f = np.array([objective(xi) for xi in x])
        better = f < f_best
        p_best[better], f_best[better] = x[better], f[better]
        g = int(np.argmin(f_best))
        if f_best[g] < g_val:
            g_best, g_val = p_best[g].copy(), float(f_best[g])
        history.append(g_val)
        if progress is not None:
            progress(it + 1, g_val)
    return PSOResult(g_best, g_val, np.array(history), particles * (iterations + 1), iterations)
