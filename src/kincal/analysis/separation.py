"""Separation of ill-conditioned parameters by GCN and branch-and-bound (seed 1, §3.1).

GCN (eq. 14) = cond(J)/m = ‖J‖₂·‖J⁺‖₂ / m for a stacked Jacobian of m poses. ‖J⁺‖₂ is taken from
every singular value the SVD returns, without a cut-off: an exact dependence, whose singular value
is rounding noise (~1e-16·σ_max), gives a large but finite GCN (1e12–1e16, as in the paper's tables);
an exactly zero singular value is replaced by eps·σ_max for the same reason. Columns are scaled with
:func:`~kincal.analysis.observability.column_scale` of the pose set first (cond depends on units).
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
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..models.robot import Robot
from .identifiability import identifiability
from .observability import column_scale

TYPES = ("theta", "alpha", "a", "d", "beta")
SYMBOL = {"theta": "θ", "alpha": "α", "a": "a", "d": "d", "beta": "β"}


def gcn(J: np.ndarray, m: int) -> float:
    """cond(J)/m = σ_max / σ_min / m over the min(rows, cols) singular values (finite always)."""
    s = np.linalg.svd(J, compute_uv=False)
    if s.size == 0 or s[0] == 0:
        return float("inf")
    return float(s[0] / max(s[-1], np.finfo(float).eps * s[0]) / m)


def averaged_gcn(J: np.ndarray) -> float:
    """Mean GCN of the first 1…M poses of J (M, 3, k)."""
    M, _, k = J.shape
    return float(np.mean([gcn(J[:m].reshape(-1, k), m) for m in range(1, M + 1)]))


@dataclass(frozen=True)
class Separation:
    """Outcome of the branch-and-bound separation (GCN values averaged over 1…M poses)."""

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
        """The paper's Tables 1–3 and the model comparison, as text."""
        out = ["Table 1  GCN of each subdomain of the error model"]
        out.append("  " + "  ".join(f"J_{SYMBOL[t]:<2} {self.subdomain_gcn[t]:10.4g}" for t in self.subdomain_gcn))
        for n, (t, rows) in enumerate(self.branches.items(), start=2):
            out.append(f"Table {n}  GCN of J_{SYMBOL[t]} with one parameter separated (threshold {self.threshold:g})")
            out.append("  " + "  ".join(f"-{name:<9} {g:10.4g}" for name, g in rows))
        out.append("Reconstructed models (eq. 27-28): GCN with the candidates removed (before step 4)")
        for removed, g in self.models:
            out.append(f"  without {', '.join(removed):<40} GCN {g:10.4g}")
        out.append(f"  full model GCN {self.gcn_full:.4g}  ->  reduced model GCN {self.gcn_reduced:.4g} "
                   f"({len(self.names) - len(self.separated)} of {len(self.names)} parameters kept)")
        out.append(f"separated (ill-conditioned): {', '.join(self.separated) or 'none'}")
        if set(self.paper_choice) != set(self.separated):
            out.append(f"by the paper's rule (lowest GCN) the separated set would be: {', '.join(self.paper_choice)}")
        out += [f"note: {n}" for n in self.notes]
        return "\n".join(out)


def param_type(name: str) -> str:
    """'j2.a' -> 'a' (the stable name's field after the joint)."""
    return name.rsplit(".", 1)[-1]


def separate_ill_conditioned(robot: Robot, q: np.ndarray, params: Sequence[str] | None = None,
                             threshold: float = 1e2) -> Separation:
    """Branch-and-bound separation of ill-conditioned parameters at poses q (M, n).

    params -- the error-model parameters (default: every θ, α, a, d, β of the robot, as the seed).
    """
    q = robot.check_q(q)
    names = tuple(params) if params is not None else tuple(
        n for n in robot.params.names if param_type(n) in TYPES)
    J = robot.param_jacobian(q)[:, :, robot.params.indices(names)]
    J = J * column_scale(J.reshape(-1, len(names)))
    col = {n: i for i, n in enumerate(names)}

    def sub_gcn(members: Sequence[str]) -> float:
        return averaged_gcn(J[:, :, [col[n] for n in members]])

    subdomains = {t: tuple(n for n in names if param_type(n) == t) for t in TYPES}
    subdomains = {t: v for t, v in subdomains.items() if v}
    sub_values = {t: sub_gcn(v) for t, v in subdomains.items()}
    branches, candidates = {}, {}
    for t, members in subdomains.items():
        if sub_values[t] <= threshold or len(members) < 2:
            continue
        removed: list[str] = []
        current = list(members)
        rows: list[tuple[str, float]] = []
        while len(current) > 1:
            trial = [(n, sub_gcn([x for x in current if x != n])) for n in current]
            if not rows:
                rows = trial
            fixes = [n for n, g in trial if g <= threshold]
            if fixes:
                removed.append(tuple(fixes))
                break
            best = min(trial, key=lambda x: x[1])[0]
            removed.append((best,))
            current.remove(best)
        branches[t] = tuple(rows)
        candidates[t] = tuple(n for grp in removed for n in grp)

    # reconstructed models: remove every candidate, or one of each group of equivalent candidates
    groups = [c for c in candidates.values()]
    options = {tuple(sorted({n for g in groups for n in g}))}
    for pick in itertools.product(*groups):
        options.add(tuple(sorted(set(pick))))
    full = averaged_gcn(J)

    def model_gcn(removed: Sequence[str]) -> float:
        return averaged_gcn(J[:, :, [col[n] for n in names if n not in set(removed)]])

    models, completed = [], []
    for removed in sorted(options, key=len):
        g = model_gcn(removed)
        models.append((removed, g))
        extra = list(removed)
        while g > threshold and len(extra) < len(names) - 1:  # step 4: not verified, separate further
            trial = [(n, model_gcn(extra + [n])) for n in names if n not in extra]
            n_best, g = min(trial, key=lambda x: x[1])
            extra.append(n_best)
        completed.append((tuple(sorted(extra)), g))
    models.sort(key=lambda x: x[1])
    # kincal's verdict: among verified models, the one keeping the most parameters (QR's rank), then
    # the lowest GCN; the paper's rule, the lowest GCN, may drop whole groups of equivalent parameters
    verified = [c for c in completed if c[1] <= threshold] or completed
    separated, reduced = min(verified, key=lambda x: (len(x[0]), x[1])) if verified else ((), full)
    paper_choice = min(verified, key=lambda x: x[1])[0] if verified else ()

    qr = identifiability(robot, q, params=names)
    kept = [n for n in names if n not in set(separated)]
    qr_kept = identifiability(robot, q, params=kept)
    notes = [f"the reduced model keeps {len(kept)} parameters; QR rank of it {qr_kept.rank}, of the full model "
             f"{qr.rank} ({'full rank' if qr_kept.rank == len(kept) else 'still rank-deficient'})"]
    notes.append(f"QR identifiability of the same {len(names)} parameters drops {len(qr.dropped)}: "
                 f"{', '.join(qr.dropped) or 'none'}")
    only_bb, only_qr = set(separated) - set(qr.dropped), set(qr.dropped) - set(separated)
    if not only_bb and not only_qr:
        notes.append("branch-and-bound and QR separate the same parameters")
    else:
        notes.append(f"both separate {', '.join(sorted(set(separated) & set(qr.dropped))) or 'nothing in common'}; "
                     f"of equivalent parameters branch-and-bound removes {', '.join(sorted(only_bb)) or 'none'} "
                     f"where QR removes {', '.join(sorted(only_qr)) or 'none'}")
    return Separation(names, subdomains, sub_values, branches, candidates, tuple(models), tuple(separated),
                      full, reduced, threshold, qr.dropped, tuple(paper_choice), tuple(notes))
