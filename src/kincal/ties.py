"""One rule for every "pick the best" step, so a result never depends on floating-point round-off.

Two values that differ by less than a relative tolerance are a tie: a different BLAS kernel, another
summation order or a hash-randomised iteration order may change them by a few ulps, and such noise
must not change a verdict. Ties are broken by the **canonical order** of the candidates: the order in
which the caller lists them. Callers list candidates as follows, so the rule is the same everywhere:

* parameters: the user's ``keep`` list first, then the model's preferred parameters (tool point,
  base frame), then ``robot.params.names`` order; the earliest is kept, the latest is dropped;
* sets of parameters: by size, then by the canonical positions of their members;
* a design frame's gauge freedoms (a hexapod's base and platform frames): held at the members that move most
  along them in the parameters' own units (m, rad: whatever unit the joints are read in), motions within
  5 % of the largest tied (a symmetric design's members move alike) and the earliest chosen
  (``kincal.analysis.identifiability.HOLD_RTOL``);
* poses: by position in the candidate pool (the earliest wins); exchange candidates likewise;
* an optimiser's incumbent beats any challenger it ties with (only a real improvement replaces it).

``TIE_RTOL`` (1e-9) is far above round-off (1e-16…1e-13 relative) and far below any difference that
means something in calibration.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

TIE_RTOL = 1e-9


def tie_tolerance(best: float, rtol: float = TIE_RTOL) -> float:
    """Width of the tie band around ``best``."""
    return rtol * abs(best)


def first_best(values: Sequence[float] | np.ndarray, maximize: bool = True, rtol: float = TIE_RTOL) -> int:
    """Index of the first value (canonical order) that ties with the best one; −inf/nan never win
    unless nothing else is there (then 0)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        raise ValueError("first_best of an empty sequence")
    s = np.where(np.isnan(v), -np.inf, v if maximize else -v)  # NaN never wins
    k = int(np.argmax(s))
    best = float(s[k])
    if not math.isfinite(best):
        return k if best == math.inf else 0
    return int(np.argmax(s >= best - tie_tolerance(best, rtol)))  # the first True


def improves(new: float, incumbent: float, maximize: bool = True, rtol: float = TIE_RTOL) -> bool:
    """True when ``new`` beats ``incumbent`` by more than the tie band (the incumbent wins ties)."""
    if np.isnan(new):
        return False
    if np.isnan(incumbent) or np.isinf(new) or np.isinf(incumbent):
        return bool(np.isnan(incumbent) or (new > incumbent if maximize else new < incumbent))
    gap = (new - incumbent) if maximize else (incumbent - new)
    return bool(gap > tie_tolerance(incumbent, rtol))


def order_with_ties(values: Sequence[float] | np.ndarray, descending: bool = True,
                    rtol: float = TIE_RTOL) -> list[int]:
    """Indices sorted by value; values tied with the head of their run keep canonical order."""
    v = np.asarray(values, dtype=float)
    ranked = np.argsort(-v if descending else v, kind="stable")
    s = v[ranked]
    if np.all(np.isfinite(s)) and np.all(np.abs(np.diff(s)) > rtol * np.abs(s[:-1])):
        return ranked.tolist()  # no two values tie: the plain order (the loop below gives the same)
    rest = list(range(v.size))
    out: list[int] = []
    while rest:
        k = rest[first_best(v[rest], maximize=descending, rtol=rtol)]
        band = tie_tolerance(float(v[k]), rtol)
        tied = [i for i in rest if i == k or v[i] == v[k] or abs(v[i] - v[k]) <= band]  # (inf - inf, NaN: nan)
        out += tied
        rest = [i for i in rest if i not in tied]
    return out
