"""``select_poses``: choose m measurement poses from a candidate pool, and report how good they are."""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .._frozen import freeze_arrays
from .._threads import blas_threads
from ..errors import IdentifiabilityError
from ..models.unit_checks import joints_in_radians
from ..models.robot import Robot
from ..papers import GUO2024
from ..ties import first_best
from .bound import Bound, relaxed_bound
from .cell import Cell
from .criteria import score
from .exchange import _State, det_blocks, fedorov, greedy
from .ide import ide
from .npose import minimum_poses
from .options import DesignOptions
from .problem import DesignProblem, design_problem
from .robust import robust_terms, stratified_design


@dataclass(frozen=True, eq=False)
class Design:
    """m chosen measurement poses of a pool, and how good they are.

    Parameters
    ----------
    indices : ndarray of int, shape (m,), or None
        Positions of the poses in the pool; None for methods "ide" and "detmax-ide", whose poses leave
        the pool.
    q : ndarray, shape (m, n)
        The poses' joint values, rad (m for a prismatic joint).
    method : str
        The method that chose them (one of :data:`METHODS`).
    criterion : str
        The criterion designed for (one of :data:`DESIGN_CRITERIA`).
    value : float
        The criterion of the design (IMSE: the mean squared prediction error in units of the noise
        variance, smaller is better; the others: larger is better).
    logdet : float
        log det of the design's scaled information matrix (−inf when singular).
    names : tuple of str
        The k parameters designed for.
    bound : Bound or None
        Certified upper bound on ``logdet`` over all m-pose designs of the pool, or None (not certified).
    time_s : float
        Time the design took, s (the certificate left out).
    seed : int or None
        The random seed used (None: a fresh one was drawn).
    history : tuple of float, optional
        Methods "ide" and "detmax-ide": the best criterion at generation 0 and after each generation
        (Guo et al. 2024, Fig. 6); () otherwise.
    note : str, optional
        What the criterion counted (IMSE: the left-out error terms) and the pool's note, or ''.

    Attributes
    ----------
    efficiency : float or None
        D-efficiency (det M / exp(bound.upper))^(1/k): how far from the best possible design of the pool
        (≤ 1 for pool designs; None for IDE's, whose poses leave the pool the bound covers); None without a bound or
        for a singular design.

    See Also
    --------
    select_poses : makes it.
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
    note: str = ""

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @property
    def efficiency(self) -> float | None:
        """D-efficiency against the certified bound, in (0, 1] for pool designs; None without a bound."""
        if self.bound is None or not np.isfinite(self.logdet):
            return None
        return float(np.exp((self.logdet - self.bound.upper) / len(self.names)))

    def to_dict(self) -> dict:
        """The design as JSON-ready values (SI: joint values in rad or m)."""
        return {"method": self.method, "criterion": self.criterion, "m": int(self.q.shape[0]),
                "indices": None if self.indices is None else self.indices.tolist(), "q": self.q.tolist(), "value": self.value,
                "logdet": self.logdet, "bound": None if self.bound is None else self.bound.to_dict(),
                "efficiency": self.efficiency, "parameters": list(self.names), "time_s": self.time_s,
                "seed": self.seed, "history": list(self.history), "note": self.note}

    def __str__(self) -> str:
        eff = "n/a" if self.efficiency is None else f"{self.efficiency:.4f}"
        what = "IMSE/σ² (smaller is better)" if self.criterion == "IMSE" else self.criterion
        return (f"{self.method} design of {self.q.shape[0]} poses for {len(self.names)} parameters: "
                f"{what} = {self.value:.6g}, D-efficiency {eff}, {self.time_s:.2f} s" +
                (f"\n  {self.note}" if self.note else ""))


def _score_blocks(J: np.ndarray, criterion: str, B) -> float:
    """Criterion of the design whose scaled Jacobian blocks are J (m, r, k)."""
    return float(score(np.einsum("nak,nal->kl", J, J), J.shape[0], criterion, B))


def detmax(P: DesignProblem, m: int, criterion: str, rng: np.random.Generator, B=None) -> list[int]:
    """DETMAX (Guo et al. 2024, §3.2 steps 1–3): from a random m-subset, add the candidate that most
    improves the criterion, then remove the design point whose removal leaves the best criterion;
    stop when the removed point is the one just added."""
    design = [int(i) for i in rng.choice(P.N, m, replace=False)]
    st = _State(P, P.information(design)) if criterion == "D" else None
    for _ in range(20 * m):
        free = np.setdiff1d(np.arange(P.N), design)
        # an addition: det M'/det M = det(I + V)
        gain = st.A_det[free] if st is not None else \
            score(P.information(design) + np.einsum("nak,nal->nkl", P.J[free], P.J[free]), m + 1, criterion, B)
        a = int(free[first_best(gain)])
        design.append(a)
        idx = np.asarray(design)
        if st is not None:
            st.update(P.J[a], np.ones(P.r), st.cross(a))
            loss = det_blocks(np.eye(P.r)[:, :, None] - st.V[:, :, idx])  # a removal: det M'/det M = det(I − Vⱼ)
        else:
            loss = score(P.information(design) - np.einsum("nak,nal->nkl", P.J[idx], P.J[idx]), m, criterion, B)
        r = design.pop(first_best(loss))
        if st is not None:
            st.update(P.J[r], -np.ones(P.r), st.cross(r))
        if r == a:
            break
    return design


def select_poses(robot: Robot, pool_q: np.ndarray, options: DesignOptions | None = None, *,
                 problem: DesignProblem | None = None, bound: Bound | None = None,
                 validation_q: np.ndarray | None = None, progress=None, cell: Cell | None = None,
                 **changes) -> Design:
    """Choose measurement poses from a candidate pool.

    Every option is checked before any work (a ValueError naming it). The design is searched on the
    problem's scaled information (see :class:`DesignProblem`); with ``certify`` its D-efficiency against a
    certified relaxation bound is reported.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    pool_q : ndarray, shape (N, n)
        Candidate joint values, rad (m for a prismatic joint); at least m distinct poses.
    options : DesignOptions, optional
        How to choose (default: ``DesignOptions()``).
    problem : DesignProblem, optional
        A prebuilt problem of this pool to reuse (its parameters win over ``options.names``).
    bound : Bound, optional
        A certified bound of this problem and m to reuse.
    validation_q : ndarray, shape (V, n), optional
        The region of use: poses where the IMSE and I criteria lower the prediction error, rad (default:
        the pool). Only with those two criteria.
    progress : callable, optional
        Called as ``progress(generation, best)`` by IDE.
    cell : Cell, optional
        The cell's constraints: every candidate must meet them, and IDE keeps to them.
    **changes
        Fields of ``options`` to change, e.g. ``select_poses(robot, pool, m=30, method="detmax")``.

    Returns
    -------
    Design
        The chosen poses, their criterion, log det, certificate and timing.

    Raises
    ------
    ValueError
        When an option is not valid, the pool holds fewer than m distinct poses, a candidate breaks the
        cell's constraints, or ``validation_q`` is given for a criterion other than IMSE or I.
    IdentifiabilityError
        When m poses give fewer equations than parameters, or the pool cannot identify the parameters.

    Examples
    --------
    >>> import kincal
    >>> from kincal.design import candidate_pool, select_poses
    >>> robot = kincal.load_robot("ur5")
    >>> pool = candidate_pool(robot, 60, seed=1)
    >>> names = ["j2.theta", "j3.theta", "j4.theta", "j2.a", "j3.a"]
    >>> d = select_poses(robot, pool, m=10, criterion="D", names=names)
    >>> d.q.shape, d.method, len(set(d.indices.tolist()))
    ((10, 6), 'fedorov', 10)
    >>> round(d.value, 3), bool(0.9 < d.efficiency <= 1.0)
    (10.829, True)
    >>> select_poses(robot, pool, m=100, criterion="D", names=names)
    Traceback (most recent call last):
        ...
    ValueError: m = 100 poses, but the candidate pool holds 60 distinct pose(s) in 60 rows: ...
    """
    with blas_threads(1):  # small dense work: OpenBLAS threads spinning on a busy machine cost 20-70x
        o = (options or DesignOptions()).replace(**changes)
        pool_q = _checked_pool(robot, pool_q, o, problem, validation_q)
        if cell is not None:
            _check_cell(robot, pool_q, cell)
        t0 = time.perf_counter()
        P = problem or design_problem(robot, pool_q, o.names, o.base, o.units)
        if P.r * o.m <= P.k:  # as the fit: more equations than unknowns, or nothing is left to judge the fit by
            raise IdentifiabilityError(f"{o.m} poses give {P.r * o.m} equations for {P.k} parameters, and a fit "
                                       f"needs more equations than parameters; choose m ≥ {P.k // P.r + 1}")
        # the left-out terms count for IMSE only; B, the region's mean information, steers criterion I
        terms, note = robust_terms(robot, P, validation_q, o.weight if o.criterion == "IMSE" else 0.0)
        rng = np.random.default_rng(o.seed)
        idx = None
        history: Sequence[float] = ()
        if o.method in ("ide", "detmax-ide"):
            q, J, history = _continuous_design(robot, P, o, terms.B, rng, progress, cell)
        else:
            idx = np.asarray(stratified_design(P, terms, o.m, o.criterion, rng) if o.stratified else
                             _pool_design(P, o, terms.B, rng), dtype=int)
            q, J = P.q[idx], P.J[idx]
        if o.criterion == "IMSE":  # stratified, or (method random) a random design, scored
            value = terms.of_design(P, idx)
        else:
            value = _score_blocks(J, o.criterion, terms.B)
            note = f"{o.criterion}-optimal within the strata" if o.stratified else ""
        elapsed = time.perf_counter() - t0
        beyond = o.method in ("ide", "detmax-ide")  # poses off the pool: its bound does not bound them
        if beyond:
            bound = None
        elif bound is None and o.certify:
            bound = relaxed_bound(P, o.m)
        note = "\n  ".join(n for n in (P.note, note, _below_minimum(robot, P, o.m), "no D-efficiency: the certified bound holds for designs from the "
                                                      "candidate pool, and IDE moves poses off it" if beyond and
                                                      o.certify else "") if n)
        return Design(idx, q, o.method, o.criterion, value, _score_blocks(J, "D", None), P.names, bound, elapsed,
                      o.seed, tuple(float(h) for h in history), note)


def _below_minimum(robot: Robot, P: DesignProblem, m: int) -> str:
    """A note when m poses are fewer than Guo et al. 2024's eq. 18 minimum for P's parameters, else ''."""
    low = minimum_poses(robot.n_joints, P.k)
    return (f"{m} poses are fewer than {GUO2024}'s eq. 18 minimum for {P.k} parameters on {robot.n_joints} joints "
            f"({low}): they give {P.r * m} equations, more than the parameters, but the paper measures at least {low}; "
            f"`kincal npose` shows how the criterion grows with m") if m < low else ""


def _checked_pool(robot: Robot, pool_q: np.ndarray, o: DesignOptions, problem: DesignProblem | None,
                  validation_q: np.ndarray | None) -> np.ndarray:
    """The pool as (N, n) after the checks that need the robot and the pool (cheap: before any work)."""
    pool_q = robot.check_q(pool_q)
    joints_in_radians("the candidate poses", pool_q, robot)
    if o.names is not None:
        robot.params.indices(o.names)
    if validation_q is not None:
        joints_in_radians("validation_q", robot.check_q(validation_q), robot)
        if o.criterion not in ("IMSE", "I"):
            raise ValueError(f"a region of use (validation_q, --use) steers the IMSE and I criteria only; criterion "
                             f"'{o.criterion}' does not look at it: choose IMSE or I, or leave it out")
    distinct = len(np.unique(np.round(problem.q if problem is not None else pool_q, 9), axis=0))
    if o.m > distinct:
        raise ValueError(f"m = {o.m} poses, but the candidate pool holds {distinct} distinct pose(s) in {len(pool_q)} "
                         f"rows: give at least m distinct candidates spread over the workspace, or a smaller m")
    return pool_q


def _check_cell(robot: Robot, pool_q: np.ndarray, cell: Cell) -> None:
    """Every candidate meets the cell's constraints, else the count, the first row and the constraint."""
    broken = cell.violations(robot, pool_q)
    bad = np.any(list(broken.values()), axis=0) | ~robot.feasible(pool_q)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        why = ", ".join(n for n, v in broken.items() if v[k]) or "the joint limits"
        raise ValueError(f"{int(bad.sum())} of {len(pool_q)} candidate poses break the cell's constraints (first: "
                         f"candidate {k + 1}, {why}); leave them out or loosen the cell")


def _pool_design(P: DesignProblem, o: DesignOptions, B, rng: np.random.Generator) -> list[int]:
    """Indices of a design of pool candidates by ``o.method`` (random, detmax, fedorov)."""
    if o.method == "random":
        return [int(i) for i in rng.choice(P.N, o.m, replace=False)]
    if o.method == "detmax":
        return detmax(P, o.m, o.criterion, rng, B)
    starts = [greedy(P, o.m)] + [[int(i) for i in rng.choice(P.N, o.m, replace=False)] for _ in range(o.restarts)]
    runs = [fedorov(P, start, o.criterion, B)[0] for start in starts]
    return runs[first_best([_score_blocks(P.J[np.asarray(d)], o.criterion, B) for d in runs])]


def _continuous_design(robot: Robot, P: DesignProblem, o: DesignOptions, B, rng, progress, cell: Cell | None):
    """IDE from a random (ide) or DETMAX (detmax-ide) pool design: poses (m, n), their scaled
    Jacobian blocks and the best criterion per generation."""
    cols = robot.params.indices(P.names)

    def blocks(q: np.ndarray) -> np.ndarray:
        """Scaled Jacobian blocks (N, 3, k) of poses off the pool."""
        return robot.param_jacobian(q)[:, :, cols] * P.scale

    idx0 = detmax(P, o.m, o.criterion, rng, B) if o.method == "detmax-ide" else rng.choice(P.N, o.m, replace=False)
    q, _, history = ide(robot, P.q[np.asarray(idx0)], lambda x: _score_blocks(blocks(x), o.criterion, B), rng,
                        generations=o.generations, population=o.population, F0=o.f0, cr=o.cr, progress=progress,
                        feasible=None if cell is None else (lambda x: cell.allows(robot, x)))
    return q, blocks(q), history
