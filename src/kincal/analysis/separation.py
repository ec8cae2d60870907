"""Separation of ill-conditioned parameters by GCN and branch-and-bound (Guo et al. 2024, §3.1).

GCN (eq. 14) = cond(J)/m = ‖J‖₂·‖J⁺‖₂ / m for a stacked Jacobian of m poses. ‖J⁺‖₂ is taken from
every singular value the SVD returns, floored at ``GCN_FLOOR``·σ_max: an exact dependence, whose
singular value is rounding noise (1e-16…1e-13·σ_max, different on every BLAS kernel), gets the
reproducible, large but finite GCN 1/(GCN_FLOOR·m) (the paper's tables show 1e12–1e16 here).
Columns are scaled with :func:`~kincal.analysis.observability.column_scale` of the pose set first
(cond depends on units; a column with no effect stays zero, so it is never "well conditioned").
A subdomain's GCN is averaged over its first 1, 2, …, M poses, as the paper does with M = 100.

Procedure: (1) split the parameters into subdomains by type (θ, α, a, d, β); (2) a subdomain whose
GCN exceeds the threshold (1e2) is branched by backward elimination: each parameter is removed in
turn, and the removals that bring it under the threshold are its candidate ill-conditioned
parameters; when no single removal suffices the best one is taken and the branch goes one level
deeper; (3) the reconstructed models (eq. 27–28) that remove every candidate, or one per group of
equivalent candidates, are built; (4) a reconstructed model whose GCN still exceeds the threshold
(step 4 of the paper: not yet verified) loses, one at a time, the parameter whose removal lowers its
GCN most — this catches dependences across types that per-type subdomains cannot see; the verified
model with the lowest GCN is kept.

Ties (GCN values within :data:`kincal.ties.TIE_RTOL`) follow :mod:`kincal.ties`: the canonical order
of the parameters is ``keep`` first, then the robot's parameter order; among tied removals the one
latest in that order is removed, and among tied reconstructed models the smaller set, then the one
whose members come latest. No result depends on set or hash order.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot
from ..ties import first_best
from .identifiability import Identifiability, identifiability
from .observability import column_scale

TYPES = ("theta", "alpha", "a", "d", "beta")
SYMBOL = {"theta": "θ", "alpha": "α", "a": "a", "d": "d", "beta": "β"}
PAPER_TABLES = {"a": 2, "d": 3}  # subdomain -> the paper's table of it (Guo et al. 2024, Tables 2-3: J_a, J_d)
GCN_FLOOR = 1e-10  # singular values below this fraction of σ_max are an exact dependence


def gcn(J: np.ndarray, m: int) -> float:
    """cond(J)/m = σ_max / σ_min / m over the min(rows, cols) singular values, σ_min floored at
    GCN_FLOOR·σ_max (finite always)."""
    s = np.linalg.svd(J, compute_uv=False)
    return float("inf") if s.size == 0 or s[0] == 0 else float(s[0] / max(s[-1], GCN_FLOOR * s[0]) / m)


DEPENDENT = 1e6  # an averaged GCN this large comes from the floor: an exact dependence (a real one stays below 1e4)


def _shown(g: float) -> str:
    """A GCN as the tables print it (10 characters): 'dependent' where it comes from the floor."""
    return f"{'dependent':>10}" if g >= DEPENDENT else f"{g:10.4g}"


def averaged_gcn(J: np.ndarray) -> float:
    """Mean GCN of the first 1…M poses of J (M, 3, k); inf without columns (no model left to condition: a
    separation that would remove every parameter is never the best)."""
    M, _, k = J.shape
    if k == 0:
        return float("inf")
    return float(np.mean([gcn(J[:m].reshape(-1, k), m) for m in range(1, M + 1)]))


@dataclass(frozen=True)
class Separation:
    """Outcome of the branch-and-bound separation (GCN values averaged over 1…M poses).

    Built by :func:`separate_ill_conditioned`; :meth:`tables` prints kincal's tables S1, S2, …, the
    analogues of the paper's Tables 1–3 (Guo et al. 2024, "Ill-conditioned parameter separation based optimization
    of measurement configuration for robot kinematic calibration", §3.1), each naming its analogue.

    Parameters
    ----------
    names : tuple of str
        The error-model parameters examined.
    subdomains : dict of str to tuple of str
        Parameter type (``"theta"``, ``"alpha"``, ``"a"``, ``"d"``, ``"beta"``) to its parameters.
    subdomain_gcn : dict of str to float
        The GCN of each subdomain's columns (dimensionless, columns scaled).
    branches : dict of str to tuple of (str, float)
        Per offending subdomain (GCN above ``threshold``), each single removal and the subdomain's GCN
        after it.
    candidates : dict of str to tuple of str
        Per offending subdomain, its candidate ill-conditioned parameters.
    models : tuple of (tuple of str, float)
        The reconstructed models (eq. 27–28): the removed set and the GCN of what remains, before
        step 4.
    separated : tuple of str
        The parameters separated (kincal's choice: the verified model that keeps the most
        parameters, then the lowest GCN).
    gcn_full : float
        GCN of the full model.
    gcn_reduced : float
        GCN of the reduced model (``names`` without ``separated``).
    threshold : float
        The GCN threshold a subdomain or model must not exceed.
    qr_dropped : tuple of str
        What the QR identifiability of the same parameters drops (:func:`identifiability`), for
        comparison.
    paper_choice : tuple of str, optional
        The separated set by the paper's rule, the lowest GCN (default empty).
    notes : tuple of str, optional
        How the separation compares with QR, in words (default none).

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis import separate_ill_conditioned
    >>> robot = kincal.load_robot("ur5")
    >>> sep = separate_ill_conditioned(robot, robot.sample_joints(8, seed=2),
    ...                                names=["j2.a", "j3.a", "j2.d", "j3.d", "j4.d"])
    >>> sep.subdomains
    {'a': ('j2.a', 'j3.a'), 'd': ('j2.d', 'j3.d', 'j4.d')}
    >>> sep.candidates  # the parallel offsets along the joint axes
    {'d': ('j4.d', 'j2.d', 'j3.d')}
    >>> print(sep.tables().splitlines()[-5])
    separated (ill-conditioned): j3.d, j4.d
    """

    names: tuple[str, ...]
    subdomains: dict[str, tuple[str, ...]]
    subdomain_gcn: dict[str, float]
    branches: dict[str, tuple[tuple[str, float], ...]]  # offending subdomain -> (removed, GCN after)
    candidates: dict[str, tuple[str, ...]]
    models: tuple[tuple[tuple[str, ...], float], ...]  # (removed set, GCN of the reconstructed model)
    separated: tuple[str, ...]
    gcn_full: float
    gcn_reduced: float
    threshold: float
    qr_dropped: tuple[str, ...]
    paper_choice: tuple[str, ...] = ()  # the separated set by the paper's rule (lowest GCN)
    notes: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict:
        return {"subdomain_gcn": self.subdomain_gcn, "branches": {k: list(v) for k, v in self.branches.items()},
                "candidates": {k: list(v) for k, v in self.candidates.items()},
                "models": [[list(r), g] for r, g in self.models], "separated": list(self.separated),
                "gcn_full": self.gcn_full, "gcn_reduced": self.gcn_reduced, "threshold": self.threshold,
                "qr_dropped": list(self.qr_dropped), "paper_choice": list(self.paper_choice),
                "notes": list(self.notes)}

    def tables(self) -> str:
        """kincal's tables S1, S2, … (analogues of the paper's Tables 1–3, named so that none is read under the
        paper's numbers) and the model comparison, as text."""
        out = ["kincal table S1  GCN of each subdomain of the error model  [analogue: the paper's Table 1]",
               "  " + "  ".join(f"J_{SYMBOL[t]:<2} {_shown(self.subdomain_gcn[t])}" for t in self.subdomain_gcn)]
        for n, (t, rows) in enumerate(self.branches.items(), start=2):
            paper = PAPER_TABLES.get(t)
            where = f"the paper's Table {paper}" if paper else "none in the paper"
            out.append(f"kincal table S{n}  GCN of J_{SYMBOL[t]} with one parameter separated (threshold "
                       f"{self.threshold:g})  [analogue: {where}]")
            out.append("  " + "  ".join(f"-{name:<9} {_shown(g)}" for name, g in rows))
        out.append("Reconstructed models (eq. 27-28): GCN with the candidates removed (before step 4)")
        for removed, g in self.models:
            out.append(f"  without {', '.join(removed):<40} GCN {_shown(g)}")
        out.append(f"  full model GCN {_shown(self.gcn_full).strip()}  ->  reduced model GCN "
                   f"{_shown(self.gcn_reduced).strip()} "
                   f"({len(self.names) - len(self.separated)} of {len(self.names)} parameters kept)")
        out.append(f"separated (ill-conditioned): {', '.join(self.separated) or 'none'}")
        if set(self.paper_choice) != set(self.separated):
            out.append(f"by the paper's rule (the lowest GCN once step 4 has verified each model) the separated set "
                       f"is: {', '.join(self.paper_choice)} ({len(self.names) - len(self.paper_choice)} of "
                       f"{len(self.names)} kept; kincal's reproduction of the paper's separated-parameter design "
                       f"leaves these out)")
        out += [f"note: {n}" for n in self.notes]
        if any(g >= DEPENDENT for g in (*self.subdomain_gcn.values(), *(g for _, g in self.models))):
            out.append("note: 'dependent': an exact dependence among the columns, its smallest singular value rounding "
                       "noise; its GCN is the floor's (GCN_FLOOR), the same for every such set, so those sets are not "
                       "ranked by it (the paper prints round-off there: 1e12-1e16)")
        return "\n".join(out)


def param_type(name: str) -> str:
    """'j2.a' -> 'a' (the stable name's field after the joint)."""
    return name.rsplit(".", 1)[-1]


def separate_ill_conditioned(robot: Robot, q: np.ndarray, names: Sequence[str] | None = None,
                             threshold: float = 1e2, keep: Sequence[str] = ()) -> Separation:
    """Separate the ill-conditioned parameters at poses ``q`` by GCN and branch-and-bound.

    The procedure of Guo et al. 2024, "Ill-conditioned parameter separation based optimization of
    measurement configuration for robot kinematic calibration", §3.1 (see the module description):
    subdomains by parameter type, backward elimination in each whose GCN exceeds ``threshold``, the
    reconstructed models, and their verification.

    Parameters
    ----------
    robot : Robot
        A robot with DH parameters (θ, α, a, d, β).
    q : ndarray, shape (M, n)
        Joint values of the M poses, rad (m for a prismatic joint); a subdomain's GCN is averaged over
        the first 1, 2, …, M of them.
    names : sequence of str, optional
        The error-model parameters (default: every θ, α, a, d, β of the robot, as the paper).
    threshold : float, optional
        The GCN above which a subdomain or model is ill-conditioned, > 0 (default 1e2).
    keep : sequence of str, optional
        Parameters to remove last when removals tie (canonical order: ``keep``, then model order;
        default none).

    Returns
    -------
    Separation
        The tables of the procedure, the separated parameters and the GCN before and after, with the
        QR identifiability of the same parameters for comparison.

    Raises
    ------
    ValueError
        When ``threshold`` is not a positive number, or the poses give no more rows than parameters.
    ModelError
        When the robot has no DH parameters to separate (a URDF or a parallel robot), or for an
        unknown name.

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis import separate_ill_conditioned
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(8, seed=2)
    >>> sep = separate_ill_conditioned(robot, q, names=["j2.a", "j3.a", "j2.d", "j3.d", "j4.d"])
    >>> sep.separated, sep.qr_dropped
    (('j3.d', 'j4.d'), ('j3.d', 'j4.d'))
    >>> sep.gcn_full > sep.threshold, round(sep.gcn_reduced, 3)
    (True, 0.473)
    >>> hexapod = kincal.load_robot("hexapod")
    >>> separate_ill_conditioned(hexapod, hexapod.sample_joints(3, seed=0))
    Traceback (most recent call last):
    ...
    kincal.errors.ModelError: robot 'hexapod' has no DH parameters (θ, d, a, α, β) to separate: ...
    """
    q = robot.check_q(q)
    if not threshold > 0:
        raise ValueError(f"threshold={threshold}: the GCN threshold must be a positive number")
    names = tuple(names) if names is not None else tuple(
        n for n in robot.params.names if param_type(n) in TYPES)
    if not names:
        raise ModelError(f"robot '{robot.name}' has no DH parameters (θ, d, a, α, β) to separate: the GCN separation "
                         f"of Guo et al. 2024 works on a DH model (a URDF or a parallel robot has other parameters); "
                         f"use 'kincal identifiability' for this robot")
    J = robot.param_jacobian(q)[:, :, robot.params.indices(names)]
    if J.shape[0] * J.shape[1] <= len(names):  # the whole model rank-deficient: no GCN judges it
        raise ValueError(f"{len(q)} poses give {J.shape[0] * J.shape[1]} rows for {len(names)} parameters: the "
                         f"model's GCN over them leaves the missing directions out; give at least "
                         f"{len(names) // J.shape[1] + 1} poses")
    J = J * column_scale(J.reshape(-1, len(names)))
    canon = [n for n in dict.fromkeys(keep) if n in names] + [n for n in names if n not in set(keep)]
    rank = {n: k for k, n in enumerate(canon)}

    def sub_gcn(members: Sequence[str]) -> float:
        return averaged_gcn(J[:, :, [i for i, n in enumerate(names) if n in set(members)]])

    def model_gcn(removed: Sequence[str]) -> float:
        return sub_gcn([n for n in names if n not in set(removed)])

    subdomains = {t: v for t in TYPES if (v := tuple(n for n in names if param_type(n) == t))}
    sub_values = {t: sub_gcn(v) for t, v in subdomains.items()}
    branches, candidates = {}, {}
    for t, members in subdomains.items():
        if sub_values[t] > threshold and len(members) > 1:
            branches[t], candidates[t] = _branch(members, sub_gcn, threshold, rank)
    models = tuple((removed, model_gcn(removed)) for removed in _reconstructions(list(candidates.values()), rank))
    completed = [_verify(list(removed), g, names, model_gcn, threshold, rank) for removed, g in models]
    verified = [c for c in completed if c[1] <= threshold] or completed  # never empty: one model at least
    separated, reduced = _choose(verified, by_size=True)
    qr = identifiability(robot, q, names=names, keep=keep)
    return Separation(names, subdomains, sub_values, branches, candidates, models, tuple(separated), averaged_gcn(J),
                      reduced, threshold, qr.dropped, tuple(_choose(verified, by_size=False)[0]),
                      tuple(_qr_notes(robot, q, names, separated, qr)))


def _branch(members, sub_gcn, threshold: float, rank: dict[str, int]):
    """Backward elimination in one subdomain: (table of single removals, candidate parameters)."""
    removed: list[tuple[str, ...]] = []
    current = list(members)
    rows: list[tuple[str, float]] = []
    while len(current) > 1:
        trial = [(n, sub_gcn([x for x in current if x != n])) for n in current]  # model order
        rows = rows or trial
        fixes = tuple(n for n, g in trial if g <= threshold)
        if fixes:
            removed.append(fixes)
            break
        ordered = sorted(trial, key=lambda x: -rank[x[0]])
        best = ordered[first_best([g for _, g in ordered], maximize=False)][0]
        removed.append((best,))
        current.remove(best)
    return tuple(rows), tuple(n for grp in removed for n in grp)


def _reconstructions(groups: list[tuple[str, ...]], rank: dict[str, int]) -> list[tuple[str, ...]]:
    """Removed sets of the reconstructed models (eq. 27–28): every candidate, or one of each group,
    in canonical order, members of each set in canonical order."""
    canon = lambda names: tuple(sorted(dict.fromkeys(names), key=rank.__getitem__))  # noqa: E731
    options = {canon(n for g in groups for n in g)}
    options.update(canon(pick) for pick in itertools.product(*groups))
    # canonical order of removed sets: smaller first, then the one whose members come latest
    return sorted(options, key=lambda s: (len(s), tuple(-r for r in sorted((rank[n] for n in s), reverse=True))))


def _verify(removed: list[str], g: float, names, model_gcn, threshold: float, rank: dict[str, int]):
    """Step 4: while the model's GCN exceeds the threshold, remove the parameter whose removal lowers
    it most. Returns (removed set in canonical order, GCN)."""
    while g > threshold and len(removed) < len(names) - 1:
        # candidates for removal, the one to remove first on a tie first (latest in canonical order)
        trial = sorted((n for n in names if n not in set(removed)), key=lambda n: -rank[n])
        values = [model_gcn(removed + [n]) for n in trial]
        k = first_best(values, maximize=False)
        removed.append(trial[k])
        g = values[k]
    return tuple(sorted(removed, key=rank.__getitem__)), g


def _choose(models: list[tuple[tuple[str, ...], float]], by_size: bool) -> tuple[tuple[str, ...], float]:
    """kincal's verdict (``by_size``): the verified model keeping the most parameters (QR's rank),
    then the lowest GCN; the paper's rule: the lowest GCN, which may drop whole groups of equivalent
    parameters. ``models`` are in canonical order, which breaks ties."""
    pool = [m for m in models if len(m[0]) == min(len(x[0]) for x in models)] if by_size else models
    return pool[first_best([g for _, g in pool], maximize=False)]


def _qr_notes(robot: Robot, q: np.ndarray, names, separated, qr: Identifiability) -> list[str]:
    """How the separation compares with ``qr``, the QR identifiability of the same parameters."""
    kept = [n for n in names if n not in set(separated)]
    qr_kept = identifiability(robot, q, names=kept)
    notes = [f"the reduced model keeps {len(kept)} parameters; QR rank of it {qr_kept.rank}, of the full model "
             f"{qr.rank} ({'full rank' if qr_kept.rank == len(kept) else 'still rank-deficient'})",
             f"QR identifiability of the same {len(names)} parameters drops {len(qr.dropped)}: "
             f"{', '.join(qr.dropped) or 'none'}"]
    both = [n for n in names if n in separated and n in qr.dropped]
    only_bb = [n for n in names if n in separated and n not in qr.dropped]
    only_qr = [n for n in names if n in qr.dropped and n not in separated]
    if not only_bb and not only_qr:
        notes.append("branch-and-bound and QR separate the same parameters")
    else:
        notes.append(f"both separate {', '.join(both) or 'nothing in common'}; of equivalent parameters "
                     f"branch-and-bound removes {', '.join(only_bb) or 'none'} where QR removes "
                     f"{', '.join(only_qr) or 'none'}")
    return notes
