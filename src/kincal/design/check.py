"""Poses for a short check of a calibrated robot (``kincal design CAL --check``): few poses whose measured positions
are most sensitive to the changes that happen to a robot — a joint zero (a motor or encoder replaced), a link, the
tool — after the measurement frame is re-fitted, which absorbs anything a frame change does.

Each candidate change c (:func:`kincal.analysis.changes.candidates`) moves the positions at a pose set S along g_c;
with the frame re-fitted only its part P g_c off the frame's directions is seen, and against the prediction miss σ per
axis its detectability is the non-centrality λ_c(S) = |P g_c|² (step_c / σ)², step_c the change that matters (0.01°,
0.1 mm; ``STEPS``). The design maximises Σ_c Φ(√λ_c − t) over the joint zeros, links and tool: the summed chance
that the check's directed test (threshold z = t) sees each change. A change near the threshold gains most; one no
pose shows well (a wrist's zero behind a short lever) gains little, so it cannot pull the poses away from the others
(Σ log(1 + λ) did that: its slope is largest at λ = 0, and the shoulder's zero lost two thirds of its
detectability to such changes on a simulated UR5). Greedy from the
empty set (the first three poses without the frame, which needs them), then exchange passes (modified Fedorov)
until no swap improves it by more than the tie tolerance (:mod:`kincal.ties`: the earliest pool pose wins ties).
"""
from __future__ import annotations

import numpy as np

from .._threads import blas_threads
from ..analysis.changes import ALPHA, MIN_CHECK_POSES, Repeat, candidates
from ..errors import ModelError
from ..models.robot import Robot
from ..ties import TIE_RTOL

KINDS = ("joint zero", "link", "tool")  # the changes a check is designed for
PASSES = 3  # exchange passes at most


def check_poses(robot: Robot, pool: np.ndarray, m: int, repeat: Repeat) -> np.ndarray:
    """Choose the poses of a short check of a calibrated robot (``kincal design CAL --check``).

    The miss's covariance over the poses whitens them: poses at near joint angles share their transmission
    errors, so they add less.

    Parameters
    ----------
    robot : Robot
        The calibrated robot.
    pool : ndarray, shape (P, n)
        Candidate joint values, rad (m for a prismatic joint).
    m : int
        How many poses to choose (``kincal design --check`` takes 10).
    repeat : Repeat
        The calibration's repeat record: how its predictions miss (:class:`kincal.analysis.changes.Repeat`).

    Returns
    -------
    ndarray of int, shape (m,)
        Indices into ``pool`` of the chosen poses, in the order they were chosen.

    Raises
    ------
    ValueError
        When m is fewer than a check needs (4: its re-fitted frame takes 6 of the 3 rows per pose).
    ModelError
        When the pool has fewer than m poses, or the calibration had no absolute positions.
    """
    if m < MIN_CHECK_POSES:
        raise ValueError(f"{m} check poses: a check needs at least {MIN_CHECK_POSES} (its re-fitted frame takes 6 of "
                         f"the 3 rows per pose); kincal design --check takes 10")
    pool = robot.check_q(pool)
    if len(pool) < m:
        raise ModelError(f"the pool has {len(pool)} poses; a check of {m} needs at least as many")
    cands = candidates(robot, pool, None)
    mine = [k for k, kind in enumerate(cands.kinds) if kind in KINDS]
    G = cands.G[:, mine].reshape(len(pool), 3, len(mine)) * cands.steps()[mine]
    names = list(robot.base_params())
    F = robot.param_jacobian(pool)[..., robot.params.indices(names)] if names else np.zeros((len(pool), 3, 0))
    with blas_threads(1):  # OpenBLAS threads spinning on a busy machine make this small dense work 100x slower
        A = repeat.conditioned(robot, pool)[1]  # what is left of the miss where the calibration's samples show it
    from scipy.special import ndtri  # noqa: PLC0415  (0.4 s to import: not at kincal's start)

    seen = sum(kind != "frame" for kind in cands.kinds)  # the directed test's family, Bonferroni at half of α
    t = float(ndtri(1.0 - ALPHA / (4.0 * max(seen, 1))))
    chosen: list[int] = []
    for _ in range(m):
        chosen.append(_best_addition(G, F, A, chosen, t))
    for _ in range(PASSES):
        if not _exchange_pass(G, F, A, chosen, t):
            break
    return np.array(chosen)


def sensitivities(G: np.ndarray, F: np.ndarray, A: np.ndarray, chosen: list[int],
                  threshold: float = 3.2) -> np.ndarray:
    """(P,) Σ_c Φ(√λ_c − t), the changes' summed chance of detection, of the poses ``chosen`` with each pool pose
    added (−inf for those chosen already): G (P, 3, C) the change directions (m per step), F (P, 3, 6) the frame's,
    A (P, P) the miss's covariance per axis; both whitened by it, the frame re-fitted from 3 poses on; t the
    directed test's threshold z."""
    P, s = len(G), len(chosen)
    B = np.empty((P, s + 1, s + 1))
    B[:, :s, :s] = A[np.ix_(chosen, chosen)]
    B[:, :s, s] = B[:, s, :s] = A[chosen].T
    B[:, s, s] = np.diag(A)
    B[chosen] = np.eye(s + 1)  # a pose twice: its value is −inf below
    L = np.linalg.cholesky(B)

    def whitened(X: np.ndarray) -> np.ndarray:  # (P, 3, K) with the chosen poses' rows first
        rows = np.concatenate([np.broadcast_to(X[chosen], (P, s, *X.shape[1:])), X[:, None]], axis=1)
        return np.linalg.solve(L, rows.reshape(P, s + 1, -1)).reshape(P, 3 * (s + 1), X.shape[-1])

    g = whitened(G)
    if s + 1 >= 3 and F.shape[-1]:
        Q = np.linalg.qr(whitened(F))[0]
        g = g - Q @ (np.swapaxes(Q, 1, 2) @ g)
    from scipy.special import ndtr  # noqa: PLC0415

    out = np.sum(ndtr(np.sqrt(np.sum(g**2, axis=1)) - threshold), axis=1)
    out[chosen] = -np.inf
    return out


def _best_addition(G: np.ndarray, F: np.ndarray, A: np.ndarray, chosen: list[int], t: float) -> int:
    values = sensitivities(G, F, A, chosen, t)
    return int(np.flatnonzero(values >= values.max() - TIE_RTOL * abs(values.max()))[0])


def _exchange_pass(G: np.ndarray, F: np.ndarray, A: np.ndarray, chosen: list[int], t: float) -> bool:
    """One pass of exchanges: each chosen pose replaced by the pool pose that improves the sensitivity most (in
    place); whether any swap was made."""
    swapped = False
    for slot in range(len(chosen)):
        rest = chosen[:slot] + chosen[slot + 1:]
        values = sensitivities(G, F, A, rest, t)
        best = float(values[chosen[slot]])
        k = _best_addition(G, F, A, rest, t)
        if values[k] > best + TIE_RTOL * abs(best):
            chosen[slot] = k
            swapped = True
    return swapped
