"""The design problem: per-candidate Jacobian blocks of the parameters to identify, column-scaled."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .._frozen import freeze_arrays
from ..analysis.identifiability import (RANK_TOL, frame_members, free_parameters, identifiability,
                                        jacobian_identifiability)
from ..analysis.observability import column_scale, live_columns
from ..errors import IdentifiabilityError
from ..models.robot import Robot
from ..ties import first_best
from .criteria import score


@dataclass(frozen=True, eq=False)
class DesignProblem:
    """The design problem: candidate poses and their scaled Jacobian blocks for the parameters ``names``.

    Each candidate has a block of r rows: r = 3 position rows per pose for a tracker; other measurement
    types give other blocks (6 for a full pose, whitened by its σ). The columns are the raw Jacobian's
    times ``scale``, fixed by the pool, so every design of this problem is measured in the same units.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Candidate joint values, rad (m for a prismatic joint).
    J : ndarray, shape (N, r, k)
        Scaled Jacobian blocks of the candidates: the raw position Jacobian (m per m, m per rad; whitened
        by σ for other measurement types) times ``scale``.
    names : tuple of str
        The k parameters designed for, in column order.
    scale : ndarray, shape (k,)
        Factors applied to the raw columns (see :func:`kincal.analysis.observability.column_scale`; 1 for
        lengths and 1000 for angles in "paper" units).
    note : str, optional
        Parameters the pool cannot identify that spread poses would, and what they act like ('' when
        none; default '').

    Attributes
    ----------
    N : int
        Number of candidates.
    k : int
        Number of parameters (columns).
    r : int
        Rows per candidate.
    rows : ndarray, shape (rN, k)
        The stacked blocks.

    See Also
    --------
    design_problem : builds it for position measurements.
    observation_problem : builds it for a planned observation set.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.design import DesignProblem
    >>> J = np.arange(24.0).reshape(4, 3, 2)  # 4 candidates, 3 rows each, 2 parameters
    >>> P = DesignProblem(np.zeros((4, 1)), J, ("a", "b"), np.ones(2))
    >>> P.N, P.r, P.k, P.rows.shape
    (4, 3, 2, (12, 2))
    >>> bool(np.allclose(P.information([0, 2]), J[0].T @ J[0] + J[2].T @ J[2]))
    True
    """

    q: np.ndarray
    J: np.ndarray
    names: tuple[str, ...]
    scale: np.ndarray
    note: str = ""  # parameters the pool cannot identify that spread poses would, and what they act like

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @property
    def N(self) -> int:
        """Number of candidates."""
        return self.J.shape[0]

    @property
    def k(self) -> int:
        """Number of parameters (columns)."""
        return self.J.shape[2]

    @property
    def r(self) -> int:
        """Rows per candidate."""
        return self.J.shape[1]

    @property
    def rows(self) -> np.ndarray:
        """(rN, k) stacked blocks."""
        return self.J.reshape(-1, self.k)

    def information(self, idx: Sequence[int] | np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
        """The information matrix M = Σ wᵢ JᵢᵀJᵢ (k, k) over the candidates ``idx`` (all wᵢ = 1 without
        ``weights``, one per index)."""
        Js = self.J[np.asarray(idx)].reshape(-1, self.k)
        return Js.T @ Js if weights is None else (Js * np.repeat(np.asarray(weights, float), self.r)[:, None]).T @ Js

    def logdet(self, idx: Sequence[int] | np.ndarray) -> float:
        """log det M of a design (−inf if singular)."""
        return float(score(self.information(idx), len(idx), "D"))


UNITS = ("scaled", "paper")


def design_problem(robot: Robot, pool_q: np.ndarray, names: Sequence[str] | None = None,
                   base: str = "estimate", units: str = "scaled") -> DesignProblem:
    """Build the design problem of position measurements for ``robot`` on a candidate pool.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    pool_q : ndarray, shape (N, n)
        Candidate joint values, rad (m for a prismatic joint); at least 2 distinct poses.
    names : sequence of str, optional
        Parameters to design for, exactly these (each must be identifiable at the pool). Default: the
        identifiable set at the pool by the base-mode rule of :func:`kincal.analysis.free_parameters`, as
        :func:`kincal.calibrate` would fit; when spread poses would identify more, the problem's ``note``
        names those the pool cannot (a pool that loses half of them or more is refused).
    base : str, optional
        "estimate" (default) or "fixed": whether the base frame is fitted (used for the default
        ``names``).
    units : str, optional
        "scaled" (default): every column at unit RMS over the pool, so indices do not depend on the units
        of lengths and angles; "paper": the raw Jacobian in mm and rad (position in mm per mm of length,
        per rad of angle), as Guo et al. 2024 compute their indices.

    Returns
    -------
    DesignProblem
        The pool, its scaled Jacobian blocks (N, 3, k), the names and the column scale.

    Raises
    ------
    ValueError
        When ``units`` is not one of :data:`UNITS`.
    IdentifiabilityError
        When the pool holds fewer than 2 distinct poses, cannot identify all the given ``names``, or its
        candidates are too alike to design from.

    Examples
    --------
    >>> import kincal
    >>> from kincal.design import candidate_pool, design_problem
    >>> robot = kincal.load_robot("ur5")
    >>> pool = candidate_pool(robot, 60, seed=1)
    >>> P = design_problem(robot, pool, names=["j2.theta", "j3.theta", "j4.theta", "j2.a", "j3.a"])
    >>> P.J.shape, P.names[:2]
    ((60, 3, 5), ('j2.theta', 'j3.theta'))
    >>> P.scale[3:].round(6).tolist()  # a link length moves the point one to one (m per m): scale 1
    [1.0, 1.0]
    """
    if units not in UNITS:
        raise ValueError(f"units='{units}' is not one of {UNITS}")
    pool_q = robot.check_q(pool_q)
    distinct = len(np.unique(np.round(pool_q, 9), axis=0))
    if distinct < 2:
        raise IdentifiabilityError(f"the candidate pool holds {distinct} distinct pose(s) in {len(pool_q)} rows: "
                                   f"give candidates spread over the workspace")
    note = ""
    if names is None:
        names, note = _pool_parameters(robot, pool_q, base, distinct)
    else:
        names = tuple(names)
        ident = identifiability(robot, pool_q, names=names)
        if ident.dropped:
            raise IdentifiabilityError(f"the candidate pool cannot identify all the given parameters:\n{ident}")
    J = robot.param_jacobian(pool_q)[:, :, robot.params.indices(names)]
    if units == "paper":  # mm of position per mm of length (1), per rad of angle (1000 mm per m)
        scale = np.array([1.0 if robot.params.kinds[robot.params.index(n)] == "length" else 1e3 for n in names])
    else:
        scale = column_scale(J.reshape(-1, len(names)))
    return DesignProblem(pool_q, np.ascontiguousarray(J * scale), tuple(names), scale, note)


def _pool_parameters(robot: Robot, pool_q: np.ndarray, base: str, distinct: int) -> tuple[tuple[str, ...], str]:
    """The parameters the pool identifies, and a note naming those that poses spread over the
    workspace would identify but no subset of the pool can (with what they act like there). A pool
    that loses half of them or more is refused: its candidates are too alike to design from."""
    ident = free_parameters(robot, pool_q, base)
    generic = free_parameters(robot, robot.sample_joints(200, seed=0), base)
    if ident.rank >= generic.rank:
        return ident.identifiable, ""
    if 2 * ident.rank <= generic.rank:
        raise IdentifiabilityError(
            f"the candidate pool identifies only {ident.rank} parameters where poses spread over the workspace "
            f"identify {generic.rank}: its {distinct} distinct candidates are too alike (nearly identical poses?); "
            f"give candidates spread over the workspace, or name the parameters to design for")
    lost = [n for n in ident.dropped if n not in generic.dropped] or list(ident.dropped)
    like = "; ".join(f"{n} ~ {ident.acts_like(n, most=2)}" for n in lost)
    return ident.identifiable, (f"the candidates identify {ident.rank} of the {generic.rank} parameters that poses "
                                f"spread over the workspace identify; no design from them can separate {like}: a "
                                f"calibration on it keeps these nominal, as one on every candidate would")


def observation_problem(robot: Robot, planned, names: Sequence[str] | None = None) -> DesignProblem:
    """The design problem of a planned observation set (one sample per candidate pose).

    The samples' values are as the nominal robot predicts them. Each candidate's block holds its
    whitened residual rows (6 for a full pose, 3 per marker); the columns are the robot's and the set-up
    parameters the pool identifies (set-up parameters first, as the fit chooses them), or ``names``.
    Known distances between socket points are exact constraints on the set-up parameters, eliminated
    before the blocks are formed.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    planned : Observation
        The planned observation set (:mod:`kincal.observe`: poses, markers, sockets, planes), one sample
        per candidate pose.
    names : sequence of str, optional
        Parameters to design for (robot and set-up parameters); default: those the pool identifies.

    Returns
    -------
    DesignProblem
        The candidates' joint values, their whitened, scaled blocks (N, r, k), the names and the scale.

    Raises
    ------
    IdentifiabilityError
        When the data are not one block of the same size per pose (markers not seen in some), or a
        constraint involves robot parameters.
    """
    obs = planned.prepare(robot)
    nuis_names, start, _ = obs.nuisance(robot)
    _, Jr, Jn = obs.evaluate(robot, robot.params.values, start)
    rows = obs.sample_rows()
    raw, all_names = _constrained(np.hstack([Jr, Jn]), rows, list(robot.params.names) + list(nuis_names),
                                  robot.n_params)
    raw, sigma, rows = raw[rows >= 0], obs.sigma()[rows >= 0], rows[rows >= 0]
    J = raw / sigma[:, None]
    counts = np.bincount(rows, minlength=len(obs))
    if len(set(counts.tolist())) != 1:
        raise IdentifiabilityError(f"{obs.kind} data are not one block per pose (markers not seen in some): design "
                                   f"poses for tracker, pose, marker, socket or plane data")
    blocks = J[np.argsort(rows, kind="stable")].reshape(len(obs), counts[0], -1)
    if names is None:
        ident = jacobian_identifiability(J, all_names, [list(nuis_names), list(robot.base_params()),
                                                        list(robot.preferred_params())], robot.name, len(obs),
                                         RANK_TOL, live_columns(raw), frame_members(robot))
        names = ident.identifiable
    cols = [all_names.index(n) for n in names]
    Jb = blocks[:, :, cols]
    scale = column_scale(Jb.reshape(-1, len(cols)))
    return DesignProblem(obs.q, np.ascontiguousarray(Jb * scale), tuple(names), scale)


def _constrained(raw: np.ndarray, rows: np.ndarray, names: list[str], n_robot: int) -> tuple[np.ndarray, list[str]]:
    """Rows that belong to no sample (known distances between socket points) as exact constraints on
    the set-up parameters: per constraint, the set-up parameter it moves most (the first among ties)
    is eliminated, linearised, so every remaining row belongs to one candidate. Returns the raw
    Jacobian over the remaining columns and their names."""
    C = raw[rows < 0].copy()
    keep = np.ones(len(names), bool)
    if not C.size:
        return raw, names
    if np.any(C[:, :n_robot]):
        raise IdentifiabilityError("a constraint row involves robot parameters: design cannot eliminate it")
    A, size = raw.copy(), np.abs(C).max(axis=1)
    for k in range(C.shape[0]):
        free = np.flatnonzero(keep & (np.arange(len(names)) >= n_robot))
        j = int(free[first_best(np.abs(C[k, free]))])
        if abs(C[k, j]) <= 1e-9 * size[k]:
            continue  # a constraint the others already imply (what is left of it is round-off)
        coef = C[k] / C[k, j]  # x_j = −Σ_{i≠j} coef_i x_i on the constraint
        A -= np.outer(A[:, j], coef)
        C -= np.outer(C[:, j], coef)
        keep[j] = False
    return A[:, keep], [n for n, kp in zip(names, keep) if kp]
