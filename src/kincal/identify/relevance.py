"""A prior on the robot's corrections, learned from the data: relevance per joint origin.

Data from a small region (60 seats of a ball in one socket plate) determine a full geometric model,
but with large, correlated corrections that the region cannot tell apart and that extrapolate badly
(the Panda trained on one plate placement: 0.37 mm at the other seven, 0.164 mm where it was
trained). A prior centred on the nominal values fixes that, if its width is right; no one knows
that width for a given robot. So it is learned from the same data, by maximising the evidence
(MacKay's automatic relevance determination): every joint origin's lengths share one prior σ and
its angles another (each part was made and assembled to its own tolerance), and the noise level is
estimated with them. A group whose corrections the data support gets a wide prior and is fitted
as by least squares; a group whose corrections the data cannot confirm gets a narrow one and stays
near nominal. The base (a set-up frame) and the set-up parameters get no prior.

The evidence is maximised on the linearised problem (MacKay's fixed-point updates, from 1 mm /
1 mrad: a machining tolerance), interleaved with Gauss–Newton steps from the least-squares fit.
The evidence can have several local optima. Grouping makes them few: on the Panda, starts from 1 mm
to 100 mm give the same prior, a start at 0.1 mm a neighbouring one (test error 0.338 mm against
0.333 mm); one σ per parameter found optima 0.325 mm and 0.349 mm apart by start. The posterior
covariance is reported: under the learned prior, a group held at nominal has σ ≈ 0.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .._frozen import freeze_arrays
from ..errors import ModelError
from ..units import fine
from .covariance import spd_inverse
from .lm import LMResult, levenberg_marquardt

PRIORS = ("relevance", "none")

START = {"length": 1e-3, "angle": 1e-3, "ratio": 1e-3}  # m, rad, 1: the first prior σ of every group
WIDEST = 1.0  # m or rad: a group's σ is at most this (a flat prior, in effect)
NARROWEST = 1e-10  # m or rad: and at least this (held at nominal, in effect)
RELINEARISE = 8  # Gauss–Newton steps at most, each after the evidence on the linearised problem
FIXED_POINT = 200  # evidence updates per linearisation at most
HELD = 1e-6  # m or rad: a group whose learned σ is below this is reported as held near nominal
LINEAR = 1e-6  # m or rad: a step this small is taken on the linearised model (its 2nd order: < 1e-12 m)
SETTLED = 1e-4  # relative change of every group's σ and of the noise level that ends the updates


@dataclass(frozen=True, eq=False)
class RelevanceFit:
    """The fit with the learned prior: the columns' values ``x``, the data's whitened residual and
    Jacobian there, the noise factor s² (1 when the stated σ are right), each group's prior σ (m or
    rad), the posterior covariance of the columns, whether the fit converged and its linearisations
    (each one evaluation of the data), its evaluations of the data and how it stopped."""

    x: np.ndarray
    residual: np.ndarray
    jacobian: np.ndarray
    noise2: float
    sigma: dict
    covariance: np.ndarray
    converged: bool
    iterations: int
    evaluations: int = 0
    message: str = "prior learned"

    def __post_init__(self) -> None:
        freeze_arrays(self)


def with_learned_prior(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], fit: LMResult,
                       nominal: np.ndarray, free: Sequence[str], robot, max_iter: int = 100) -> RelevanceFit | LMResult:
    """:func:`relevance_fit` of the columns ``free`` (robot parameters and set-up parameters) of a
    least-squares ``fit``, the base frame without a prior, in at most ``max_iter`` iterations; ``fit`` itself
    when no column has one (only a frame fitted)."""
    kinds = dict(zip(robot.params.names, robot.params.kinds))
    groups = prior_groups(free, kinds, robot.base_params())
    if not any(groups):
        return fit
    return relevance_fit(fun, fit, nominal, groups, [kinds.get(n, "") for n in free], max_iter)


def prior_lines(sigma: dict) -> list[str]:
    """What the learned prior did, in words: the groups held near nominal and the groups fitted."""
    if not sigma:
        return []
    held = [g for g, v in sigma.items() if v < HELD]
    lines = ["prior learned from the data (one σ per joint origin's lengths and angles, by the evidence): "
             f"{len(sigma) - len(held)} of {len(sigma)} groups fitted"]
    if held:
        lines.append(f"  held at nominal (the data do not confirm their corrections): {', '.join(held)}")
    fitted = [f"{g} ±{fine(v, g.rsplit(' ', 1)[1][:-1])}" for g, v in sigma.items() if v >= HELD]
    if fitted:
        lines.append(f"  prior σ of the others: {', '.join(fitted)}")
    return lines


def prior_groups(names: Sequence[str], kinds: dict, excluded: Sequence[str] = ()) -> list[str | None]:
    """Per parameter: its group ("panda_joint5 lengths", "j2 angles", "tool lengths"), or None for
    parameters without a prior (``excluded``: the base; names not in ``kinds``: set-up parameters)."""
    without = set(excluded)
    return [None if n not in kinds or n in without else f"{n.rsplit('.', 1)[0]} {kinds[n]}s" for n in names]


def relevance_fit(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], fit: LMResult,
                  nominal: np.ndarray, groups: Sequence[str | None], kinds: Sequence[str],
                  max_iter: int = 100) -> RelevanceFit:
    """Refit the columns of ``fun`` (whitened data residual and Jacobian), from their least-squares
    ``fit``, with a Gaussian prior around ``nominal`` whose σ per group is learned (module
    docstring); ``kinds`` per column ("length"/"angle"; others: no group) sets the first σ.
    Gauss–Newton steps interleaved with the evidence updates; Levenberg–Marquardt for the final
    prior if a step does not lower the cost or the steps have not settled; ``max_iter`` iterations at most,
    the two together (each step one)."""
    prec = np.array([0.0 if g is None else 1.0 / START.get(k, 1e-3) ** 2 for g, k in zip(groups, kinds)])
    x, r, J, s2 = fit.x, fit.residual, fit.jacobian, 1.0
    it = 0
    for it in range(1, min(RELINEARISE, max_iter) + 1):
        prec, s2, d, C = _evidence_updates(r, J, x - nominal, prec, s2, groups)
        step = nominal + d - x
        if np.all(np.abs(step) <= np.maximum(LINEAR, SETTLED * np.sqrt(np.diag(C)))):  # linear here
            return _relevance_result(x + step, r + J @ step, J, prec, s2, groups, True, it, it - 1)
        try:
            r_new, J_new = fun(x + step)
        except ModelError:  # a step the model cannot take (a closed chain that no longer assembles): not kept
            break
        if not _lower(r_new, x + step - nominal, r, x - nominal, prec, s2):
            break
        x, r, J = x + step, r_new, J_new
    lm = levenberg_marquardt(_augmented(fun, nominal, prec, s2), x, max_iter=max_iter - it)
    r, J = fun(lm.x)
    result = _relevance_result(lm.x, r, J, prec, s2, groups, lm.converged, it + lm.iterations,
                               it + lm.evaluations + 1)
    if lm.converged:
        return result
    why = (f"stopped after {max_iter} iterations without meeting the tolerances" if it + lm.iterations >= max_iter
           else lm.message)
    return dataclasses.replace(result, message=f"prior learned; {why}")


def _lower(r_new, d_new, r_old, d_old, prec, s2) -> bool:
    """A Gauss–Newton step is kept when it lowers the prior's cost, finitely."""
    def cost(r, d):
        return float(r @ r) / s2 + float(np.sum(prec * d * d))
    return bool(np.all(np.isfinite(r_new)) and cost(r_new, d_new) < cost(r_old, d_old))


def _relevance_result(x, r, J, prec, s2, groups, converged: bool, iterations: int, evaluations: int) -> RelevanceFit:
    cov = _posterior(J.T @ J / s2, prec)
    sigma = {g: float(1.0 / np.sqrt(prec[k])) for k, g in enumerate(groups) if g is not None}
    return RelevanceFit(x, r, J, float(s2), sigma, cov, bool(converged), iterations, evaluations)


def _posterior(A: np.ndarray, prec: np.ndarray) -> np.ndarray:
    """(A + diag(prec))⁻¹, computed on unit-diagonal scaling (columns in m, rad and whitened units)."""
    H = A + np.diag(prec)
    return spd_inverse(H, np.sqrt(np.diag(H)))


def _augmented(fun, nominal: np.ndarray, prec: np.ndarray, s2: float):
    """The data residual scaled by the noise factor, with one prior row per column with a prior."""
    keep = prec > 0
    w, root = 1.0 / np.sqrt(s2), np.sqrt(prec[keep])

    def aug(x):
        r, J = fun(x)
        return (np.concatenate([r * w, root * (x[keep] - nominal[keep])]),
                np.vstack([J * w, np.eye(x.size)[keep] * root[:, None]]))
    return aug


def _evidence_updates(r: np.ndarray, J: np.ndarray, d0: np.ndarray, prec: np.ndarray, s2: float,
                      groups: Sequence[str | None]) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """MacKay's fixed point for the group precisions and the noise factor on the linearised problem
    r(d) = J·d − b (d: correction from nominal), from ``prec``, ``s2``; also the corrections d and
    their posterior covariance under the settled values."""
    b = J @ d0 - r
    A, c = J.T @ J, J.T @ b
    names = sorted({g for g in groups if g is not None})
    members = [np.array([g == name for g in groups]) for name in names]
    with_prior = np.array([g is not None for g in groups])
    for _ in range(FIXED_POINT):
        C = _posterior(A / s2, prec)
        d = C @ c / s2
        gamma = np.where(with_prior, np.clip(1.0 - prec * np.diag(C), 0.0, 1.0), 1.0)
        res = J @ d - b
        s2_new = float(res @ res) / max(r.size - float(np.sum(gamma)), 1.0)
        new = prec.copy()
        for m in members:
            sigma2 = float(d[m] @ d[m]) / max(float(np.sum(gamma[m])), 1e-12)
            new[m] = 1.0 / np.clip(sigma2, NARROWEST**2, WIDEST**2)
        settled = (np.all(np.abs(np.log(new[with_prior] / prec[with_prior])) < 2 * SETTLED)
                   and abs(s2_new / s2 - 1.0) < SETTLED)
        prec, s2 = new, s2_new
        if settled:
            break
    C = _posterior(A / s2, prec)
    return prec, s2, C @ c / s2, C
