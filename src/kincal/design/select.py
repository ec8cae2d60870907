"""``select_poses``: choose m measurement poses from a candidate pool, and report how good they are."""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import IdentifiabilityError
from ..models.robot import Robot
from ..ties import first_best
from .bound import Bound, relaxed_bound
from .criteria import check_criterion, score
from .exchange import _State, det3, fedorov, greedy
from .ide import ide
from .problem import DesignProblem, design_problem

METHODS = ("random", "detmax", "fedorov", "ide", "detmax-ide")


@dataclass(frozen=True, eq=False)
class Design:
    """m chosen poses of a pool.

    indices    -- positions in the pool (None for ide / detmax-ide, whose poses leave the pool);
                  q: the joint values (m, n)
    value      -- the criterion of the design; logdet: log det of its scaled information matrix
    bound      -- certified upper bound on logdet over all m-pose designs of the pool (or None)
    efficiency -- D-efficiency (det M / exp(bound))^(1/k): how far from the best possible design
                  of the pool (≤ 1 for pool designs; continuous designs may exceed the pool's bound)
    history    -- ide / detmax-ide: the best criterion after each generation (seed 1, Figs. 5–6)
    """

    indices: np.ndarray | None
    q: np.ndarray
    method: str
    criterion: str
    value: float
    logdet: float
    names: tuple[str, ...]
    bound: Bound | None
    time_s: float
    seed: int | None
    history: tuple[float, ...] = ()

    @property
    def efficiency(self) -> float | None:
        if self.bound is None or not np.isfinite(self.logdet):
            return None
        return float(np.exp((self.logdet - self.bound.upper) / len(self.names)))

    def to_dict(self) -> dict:
        return {"method": self.method, "criterion": self.criterion, "m": int(self.q.shape[0]),
                "indices": None if self.indices is None else self.indices.tolist(), "q": self.q.tolist(), "value": self.value,
                "logdet": self.logdet, "bound": None if self.bound is None else self.bound.to_dict(),
                "efficiency": self.efficiency, "parameters": list(self.names), "time_s": self.time_s,
                "seed": self.seed, "history": list(self.history)}

    def __str__(self) -> str:
        eff = "n/a" if self.efficiency is None else f"{self.efficiency:.4f}"
        return (f"{self.method} design of {self.q.shape[0]} poses for {len(self.names)} parameters: "
                f"{self.criterion} = {self.value:.6g}, D-efficiency {eff}, {self.time_s:.2f} s")


def _score_blocks(J: np.ndarray, criterion: str, B) -> float:
    """Criterion of the design whose scaled Jacobian blocks are J (m, 3, k)."""
    return float(score(np.einsum("nak,nal->kl", J, J), J.shape[0], criterion, B))


def detmax(P: DesignProblem, m: int, criterion: str, rng: np.random.Generator, B=None,
           max_iter: int | None = None) -> list[int]:
    """DETMAX (the seed's §3.2 steps 1–3): from a random m-subset, add the candidate that most
    improves the criterion, then remove the design point whose removal leaves the best criterion;
    stop when the removed point is the one just added."""
    design = [int(i) for i in rng.choice(P.N, m, replace=False)]
    in_design = np.zeros(P.N, bool)
    in_design[design] = True
    st = _State(P, P.information(design)) if criterion == "D" else None
    for _ in range(max_iter or 20 * m):
        free = np.flatnonzero(~in_design)
        if st is not None:  # det M' / det M = det(I + V) for an addition
            a = int(free[first_best(st.A_det[free])])
        else:
            M = P.information(design)
            Ja = P.J[free]
            vals = score(M + np.einsum("nak,nal->nkl", Ja, Ja), m + 1, criterion, B)
            a = int(free[first_best(vals)])
        design.append(a)
        in_design[a] = True
        if st is not None:
            st.update(P.J[a], np.ones(3), st.cross(a))
            idx = np.asarray(design)
            # removal: det M'/det M = det(I − Vⱼ)
            r_pos = first_best(det3(np.eye(3)[:, :, None] - st.V[:, :, idx]))
        else:
            M = P.information(design)
            Jd = P.J[np.asarray(design)]
            r_pos = first_best(score(M - np.einsum("nak,nal->nkl", Jd, Jd), m, criterion, B))
        r = design.pop(r_pos)
        in_design[r] = False
        if st is not None:
            st.update(P.J[r], -np.ones(3), st.cross(r))
        if r == a:
            break
    return design


def design_bound(robot: Robot, pool_q: np.ndarray, m: int, params: Sequence[str] | None = None,
                 base: str = "estimate", tol: float = 2e-3) -> Bound:
    """Certified upper bound on log det M (scaled) over every m-pose design from the pool."""
    return relaxed_bound(design_problem(robot, pool_q, params, base), m, tol=tol)


def select_poses(
    robot: Robot,
    pool_q: np.ndarray,
    m: int = 60,
    method: str = "fedorov",
    criterion: str = "D",
    seed: int | None = 0,
    params: Sequence[str] | None = None,
    base: str = "estimate",
    bound: bool | Bound = True,
    restarts: int = 0,
    validation_q: np.ndarray | None = None,
    problem: DesignProblem | None = None,
    generations: int = 200,
    progress=None,
    units: str = "scaled",
) -> Design:
    """Choose m poses from pool_q (N, n) for identifying ``params`` (default: the identifiable set).

    method    -- "random"; "detmax" (add–compare–remove–compare exchange); "fedorov" (greedy start,
                 then modified Fedorov exchange with low-rank updates; D and I criteria only), with
                 ``restarts`` extra random starts, keeping the best; "ide" (improved differential
                 evolution over continuous poses from a random pool design, ``generations``);
                 "detmax-ide" (the seed's two steps: DETMAX on the pool, then IDE from its design)
    criterion -- "D", "A", "E", "I" (average prediction variance over ``validation_q``, default the
                 pool), "O1"…"O6", "comprehensive" (the seed's entropy-weighted index)
    bound     -- True to compute the certified relaxation bound (D-efficiency), a precomputed Bound
                 to reuse, or False
    units     -- "scaled" (unit-invariant columns) or "paper" (raw Jacobian in mm and rad); see
                 :func:`~kincal.design.problem.design_problem`
    """
    if method not in METHODS:
        raise ValueError(f"method '{method}' is not one of {', '.join(METHODS)}")
    check_criterion(criterion)
    t0 = time.perf_counter()
    P = problem or design_problem(robot, pool_q, params, base, units)
    if 3 * m < P.k:
        raise IdentifiabilityError(f"{m} poses give {3 * m} equations for {P.k} parameters; choose m ≥ {-(-P.k // 3)}")
    distinct = len(np.unique(np.round(P.q, 9), axis=0))
    if m > distinct:
        raise ValueError(f"m = {m} poses but the pool has only {distinct} distinct candidates ({P.N} rows)")
    B = None
    if criterion == "I":
        Jv = P.J if validation_q is None else robot.param_jacobian(validation_q)[:, :, robot.params.indices(P.names)] * P.scale
        B = np.einsum("nak,nal->kl", Jv, Jv) / Jv.shape[0]
    rng = np.random.default_rng(seed)
    cols = robot.params.indices(P.names)

    def blocks(q: np.ndarray) -> np.ndarray:
        """Scaled Jacobian blocks (N, 3, k) of poses off the pool."""
        return robot.param_jacobian(q)[:, :, cols] * P.scale

    idx, history = None, ()
    if method in ("ide", "detmax-ide"):
        idx0 = detmax(P, m, criterion, rng, B) if method == "detmax-ide" else rng.choice(P.N, m, replace=False)
        q, _, history = ide(robot, P.q[np.asarray(idx0)], lambda x: _score_blocks(blocks(x), criterion, B), rng,
                      generations=generations, progress=progress)
        J = blocks(q)
    else:
        if method == "random":
            idx = [int(i) for i in rng.choice(P.N, m, replace=False)]
        elif method == "detmax":
            idx = detmax(P, m, criterion, rng, B)
        else:
            if criterion not in ("D", "I"):
                raise ValueError("method 'fedorov' supports the D and I criteria; use 'detmax' for the others")
            starts = [greedy(P, m)] + [[int(i) for i in rng.choice(P.N, m, replace=False)] for _ in range(restarts)]
            runs = [fedorov(P, s, criterion, B)[0] for s in starts]
            idx = runs[first_best([_score_blocks(P.J[np.asarray(d)], criterion, B) for d in runs])]
        idx = np.asarray(idx, dtype=int)
        q, J = P.q[idx], P.J[idx]
    elapsed = time.perf_counter() - t0
    if bound is True:
        bound = relaxed_bound(P, m)
    return Design(idx, q, method, criterion, _score_blocks(J, criterion, B), _score_blocks(J, "D", None), P.names,
                  bound if isinstance(bound, Bound) else None, elapsed, seed, tuple(float(h) for h in history))
