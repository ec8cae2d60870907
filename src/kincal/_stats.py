"""Tail probabilities without SciPy's special-function module (its import alone costs 0.4 s, more than a whole
``kincal check``): the F distribution's survival function through the regularized incomplete beta function,
evaluated by its continued fraction (modified Lentz), accurate to ~1e-14 relative; and the spread of points about
their centroid."""
from __future__ import annotations

import math

import numpy as np

TINY = 1e-300
EPS = 1e-15
MAX_TERMS = 10_000


def betainc(a: float, b: float, x: float) -> float:
    """The regularized incomplete beta function I_x(a, b) for a, b > 0 and 0 ≤ x ≤ 1."""
    if not (a > 0 and b > 0 and 0.0 <= x <= 1.0):
        raise ValueError(f"betainc({a}, {b}, {x}): needs a, b > 0 and 0 <= x <= 1")
    if x in (0.0, 1.0):
        return x
    front = math.exp(a * math.log(x) + b * math.log1p(-x) - math.lgamma(a) - math.lgamma(b) + math.lgamma(a + b))
    if x < (a + 1.0) / (a + b + 2.0):  # the fraction converges fast on this side; the other by symmetry
        return front * _fraction(a, b, x) / a
    return 1.0 - front * _fraction(b, a, 1.0 - x) / b


def _fraction(a: float, b: float, x: float) -> float:
    """The continued fraction of I_x(a, b) (its even and odd steps), by the modified Lentz method."""
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > TINY else TINY)
    out = d
    for m in range(1, MAX_TERMS):
        for num in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                    -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > TINY else TINY)
            c = 1.0 + num / c
            c = c if abs(c) > TINY else TINY
            out *= c * d
        if abs(c * d - 1.0) < EPS:
            return out
    raise ArithmeticError(f"the incomplete beta fraction did not converge for a={a}, b={b}, x={x}")


def f_sf(x: float, d1: float, d2: float) -> float:
    """P(F > x) for an F distribution with d1, d2 > 0 degrees of freedom (1 for x ≤ 0)."""
    if x <= 0:
        return 1.0
    return betainc(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * x))


def spread(x: np.ndarray) -> float:
    """RMS distance (m) of the points x (N, 3) from their centroid (inf for values whose squares overflow:
    the readers refuse such values, data built in memory may hold them)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return float(np.sqrt(np.mean(np.sum((x - x.mean(axis=0)) ** 2, axis=1))))
