"""Designs for accuracy where the robot works: the mean squared prediction error over the region of
use (IMSE), counting the bias of error terms the geometric fit leaves out, searched one pose per
joint-space stratum (coverage).

A geometric calibration on m poses predicts the tool at a pose u with the error

    J_u (θ̂ − θ) = J_u M⁻¹ Jᵀ (ε + K δ) − K_u δ,

ε the measurement noise (σ per row), δ the effect of terms the model does not have (compliance,
gravity loads, transmission harmonics: the terms of :func:`kincal.models.terms.extend`), K their
Jacobian. Averaged over the region of use, with δ drawn with variance ``weight``·σ² per term (each
term scaled to unit RMS effect over the region):

    IMSE / σ² = tr(M⁻¹B) + weight·‖J_u A − K_u‖²/n_u,    A = M⁻¹ JᵀK,  B = J_uᵀJ_u / n_u.

The first part is I-optimality; the second is the alias bias of Box and Draper's model-robust design
(JASA 1959): a design whose poses all sit at the workspace edges, where these terms are largest,
bends the geometric fit towards them. The search keeps one pose per stratum of the pool (k-means in
standardised joint space), so the design also covers the workspace as a random subset would.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._frozen import freeze_arrays
from ..errors import ModelError
from ..models.robot import Robot
from ..models.terms import extend
from ..ties import first_best, tie_tolerance
from .criteria import SINGULAR, score
from .problem import DesignProblem

UNMODELLED = "gravity-regressor+harmonics:1"  # what geometry cannot describe, to first order
KMEANS_ITERATIONS = 100
WOODBURY_COND = 1e-9  # M0's eigenvalue ratio below this: solve directly (the update would lose digits)


@dataclass(frozen=True, eq=False)
class RobustTerms:
    """Left-out terms on the pool and the region's moments (scaled like the problem's columns).

    K (N, r, p) -- pool blocks of the terms, each at RMS √weight over the region
    B (k, k), C (k, p), D -- J_uᵀJ_u/n_u, J_uᵀK_u/n_u, ‖K_u‖²/n_u over the region of use
    names      -- the terms (empty when the robot has none: IMSE is then I-optimality)
    """

    K: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: float
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def imse(self, M: np.ndarray, Q: np.ndarray) -> np.ndarray:
        """IMSE/σ² of designs with information M (c, k, k) and cross terms Q = JᵀK (c, k, p); inf if singular."""
        rhs = np.concatenate([np.broadcast_to(self.B, M.shape), Q], axis=-1)
        with np.errstate(all="ignore"):
            try:
                X = np.linalg.solve(M, rhs)
            except np.linalg.LinAlgError:
                return np.full(M.shape[0], np.inf)
        ok = np.linalg.eigvalsh(M)[..., 0] > SINGULAR * np.trace(M, axis1=-2, axis2=-1) / M.shape[-1]
        return np.where(ok, self._from_solution(X), np.inf)

    def imse_added(self, M0: np.ndarray, Q0: np.ndarray, Jc: np.ndarray, Kc: np.ndarray) -> np.ndarray:
        """IMSE/σ² of a design (M0, Q0) plus each candidate block Jc (c, r, k), Kc (c, r, p):
        M⁻¹ by the Woodbury identity from M0⁻¹ (M0 well conditioned), else directly."""
        lam = np.linalg.eigvalsh(M0)
        if lam[0] <= WOODBURY_COND * lam[-1]:
            return self.imse(M0 + np.swapaxes(Jc, 1, 2) @ Jc, Q0 + np.swapaxes(Jc, 1, 2) @ Kc)
        G = np.linalg.inv(M0)
        R = np.concatenate([np.broadcast_to(self.B, (len(Jc),) + M0.shape), Q0 + np.swapaxes(Jc, 1, 2) @ Kc], axis=-1)
        U = G @ np.swapaxes(Jc, 1, 2)  # (c, k, r)
        S = np.eye(Jc.shape[1]) + Jc @ U
        X = G @ R - U @ np.linalg.solve(S, np.swapaxes(U, 1, 2) @ R)
        return self._from_solution(X)

    def of_design(self, P: DesignProblem, design) -> float:
        """IMSE/σ² of a design of the pool of ``P`` (indices)."""
        Jd, Kd = P.J[design].reshape(1, -1, P.k), self.K[design].reshape(1, len(design) * P.r, -1)
        return float(self.imse(np.swapaxes(Jd, 1, 2) @ Jd, np.swapaxes(Jd, 1, 2) @ Kd)[0])

    def _from_solution(self, X: np.ndarray) -> np.ndarray:
        """IMSE/σ² from X = M⁻¹[B | Q] (c, k, k + p)."""
        k = self.B.shape[0]
        A = X[..., k:]
        var = np.trace(X[..., :k], axis1=-2, axis2=-1)
        bias = np.sum(A * (self.B @ A), axis=(1, 2)) - 2 * np.sum(A * self.C, axis=(1, 2)) + self.D
        out = var + bias
        return np.where(np.isfinite(out), out, np.inf)


def robust_terms(robot: Robot, P: DesignProblem, region_q: np.ndarray | None, weight: float) -> tuple[RobustTerms, str]:
    """The left-out terms of ``robot`` on the pool of ``P`` and the region (default: the pool), and a
    note when there are none (a robot without such terms, or blocks other than tool positions).
    The region's scaled Jacobian blocks Ju (n_u, r, k) give its mean information B; another region
    than the pool only for tool positions."""
    point = P.r == 3 and set(P.names) <= set(robot.params.names)
    if region_q is None:
        Ju = P.J
    elif point:
        Ju = robot.param_jacobian(region_q)[:, :, robot.params.indices(P.names)] * P.scale
    else:
        raise ValueError("a region of use other than the pool is supported for tool-position (point) designs only")
    B = np.einsum("nak,nal->kl", Ju, Ju) / len(Ju)
    none = RobustTerms(np.zeros(P.J.shape[:2] + (0,)), B, np.zeros((P.k, 0)), 0.0, ())
    if not point or weight == 0.0:
        why = "weight 0" if weight == 0.0 else "the measurement is not a tool position"
        return none, f"no left-out error terms counted ({why}): IMSE is I-optimality here"
    try:
        ext = extend(robot, UNMODELLED, P.q)
    except ModelError as e:
        return none, f"no left-out error terms counted ({e}): IMSE is I-optimality here"
    names = tuple(n for n in ext.params.names if n not in robot.params.names)
    idx = ext.params.indices(names)
    K = ext.param_jacobian(P.q)[:, :, idx]
    Ku = K if region_q is None else ext.param_jacobian(region_q)[:, :, idx]
    rms = np.sqrt(np.mean(Ku ** 2, axis=(0, 1)))
    keep = rms > 0
    s = np.sqrt(weight) / rms[keep]
    Ku, K = Ku[:, :, keep] * s, K[:, :, keep] * s
    n = len(Ju)
    terms = RobustTerms(np.ascontiguousarray(K), B, np.einsum("nak,nap->kp", Ju, Ku) / n,
                        float(np.sum(Ku ** 2)) / n, tuple(np.asarray(names)[keep]))
    return terms, f"{len(terms.names)} left-out error terms ({UNMODELLED}), weight {weight:g} σ² each"


def strata(q: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """Labels (N,) of m strata of the poses q (N, n): k-means in joint space, each joint scaled by its
    spread over the pool; every stratum holds at least one pose."""
    sd = q.std(axis=0)
    z = (q - q.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    centres = z[np.sort(rng.choice(len(z), m, replace=False))]
    for _ in range(KMEANS_ITERATIONS):
        d = ((z[:, None, :] - centres[None]) ** 2).sum(axis=2)
        lab = np.argmin(d, axis=1)
        counts = np.bincount(lab, minlength=m)
        for j in np.flatnonzero(counts == 0):  # an empty stratum takes the pose farthest from its centre
            far = int(np.argmax(d[np.arange(len(z)), lab]))
            lab[far], d[far] = j, 0.0
        new = np.array([z[lab == j].mean(axis=0) for j in range(m)])
        if np.array_equal(new, centres):
            break
        centres = new
    return lab


def medoids(q: np.ndarray, lab: np.ndarray) -> list[int]:
    """The pose nearest each stratum's mean (standardised joints), the earliest on a tie."""
    sd = q.std(axis=0)
    z = q / np.where(sd > 0, sd, 1.0)
    out = []
    for j in range(int(lab.max()) + 1):
        members = np.flatnonzero(lab == j)
        d = ((z[members] - z[members].mean(axis=0)) ** 2).sum(axis=1)
        out.append(int(members[first_best(d, maximize=False)]))
    return out


def exchange_in_strata(P: DesignProblem, lab: np.ndarray, start: list[int],
                       value: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray], K: np.ndarray,
                       max_sweeps: int = 20) -> list[int]:
    """Exchange each design pose for the best member of its stratum until a sweep changes nothing.

    value(M0 (k, k), Q0 (k, p), Jc (c, r, k), Kc (c, r, p)) -> (c,): the criterion, larger is better,
    of the design without the pose plus each candidate of its stratum; the incumbent wins ties.
    """
    design = list(start)
    for _ in range(max_sweeps):
        changed = False
        for j in range(len(design)):
            rest = design[:j] + design[j + 1:]
            M0 = np.einsum("nak,nal->kl", P.J[rest], P.J[rest])
            Q0 = np.einsum("nak,nap->kp", P.J[rest], K[rest])
            cand = np.flatnonzero(lab == lab[design[j]])
            v = value(M0, Q0, P.J[cand], K[cand])
            best = first_best(v)
            now = int(np.flatnonzero(cand == design[j])[0])
            better = v[best] > v[now] + tie_tolerance(v[now]) if np.isfinite(v[now]) else np.isfinite(v[best])
            if better and cand[best] != design[j]:
                design[j], changed = int(cand[best]), True
        if not changed:
            break
    return design


def stratified_design(P: DesignProblem, terms: RobustTerms, m: int, criterion: str,
                      rng: np.random.Generator) -> list[int]:
    """One pose per stratum, exchanged within its stratum for criterion IMSE, D or I over the region
    of ``terms`` (from :func:`robust_terms`); returns the pool indices, in stratum order."""
    if criterion == "IMSE":
        value = lambda M0, Q0, Jc, Kc: -terms.imse_added(M0, Q0, Jc, Kc)  # noqa: E731
    else:
        value = lambda M0, Q0, Jc, Kc: score(M0 + np.swapaxes(Jc, 1, 2) @ Jc, m, criterion, terms.B)  # noqa: E731
    lab = strata(P.q, m, rng)
    return exchange_in_strata(P, lab, medoids(P.q, lab), value, terms.K)


def design_imse(robot: Robot, P: DesignProblem, design, region_q: np.ndarray | None,
                weight: float) -> tuple[float, str]:
    """IMSE/σ² of any pool design (indices), and the note on the terms counted."""
    terms, note = robust_terms(robot, P, region_q, weight)
    return terms.of_design(P, list(design)), note
