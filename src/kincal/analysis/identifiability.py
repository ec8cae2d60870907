"""Which parameters can be known from position measurements at given poses.

Method: stack the position Jacobian over the poses (3N x P), scale every column to unit norm (so
lengths in m and angles in rad compare fairly), take the numerical rank from the singular values
(relative tolerance ``rank_tol``, :data:`RANK_TOL` by default, the one rule shared by calibration
and pose design; the gap to the next singular value is reported), and choose which
columns to keep by QR with column pivoting (parameters listed in ``keep`` are chosen first; columns
whose residual norms tie within :data:`kincal.ties.TIE_RTOL` go in canonical order, so exactly
equivalent parameters are resolved the same way on every machine: the earliest is kept). Each
dropped parameter is written as a combination of kept ones from the R factor,
``J_dropped ≈ J_kept @ C``: a change δ of the dropped parameter acts like changes ``C δ`` of the
kept ones, which is what "confounded with" means here.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence, cast

import numpy as np

from .._frozen import freeze_arrays
from ..models.robot import Robot
from ..models.unit_checks import joints_in_radians
from ..ties import first_best, order_with_ties
from .observability import column_norms, live_columns

# Singular values below RANK_TOL * s_max of the column-scaled Jacobian count as zero. The same rule
# decides what a calibration fits and what a design designs for: directions weaker than this are
# not determined by the poses and would drift to absurd values along a flat valley of the cost.
# (On every bundled robot and pool no singular value lies between 1e-8 and this, so exact
# dependences and practical ones are the same sets there.)
RANK_TOL = 3e-5


@dataclass(frozen=True)
class Identifiability:
    """Identifiability of a parameter set at a set of poses (all quantities for scaled columns unless raw).

    Built by :func:`identifiability` (and :func:`free_parameters`) from the stacked position Jacobian, its
    columns scaled to unit norm; the other observation types of a fit use the same rule on their whitened
    Jacobian.

    Parameters
    ----------
    robot : str
        The robot's name (the label of the summary line).
    candidates : tuple of str
        The parameter names asked about, in the order given (model order by default).
    identifiable : tuple of str
        The parameters the poses determine (the chosen columns), in the order of ``candidates``.
    dropped : tuple of str
        The other candidates, kept at their values: confounded ones in pivot order, then those with no
        effect on the measurements at all.
    confounds : dict of str to tuple of (str, float)
        Per dropped parameter, the kept parameters it acts like, largest first: a change δ of the
        dropped parameter acts like a change ``c·δ`` of each kept one, ``c`` in physical units (m/m,
        rad/rad, m/rad or rad/m); an empty tuple for a parameter with no effect.
    rank : int
        The numerical rank: singular values above ``rank_tol`` times the largest.
    n_poses : int
        The number of poses (or samples) the Jacobian was stacked over.
    singular_values : ndarray, shape (K,)
        Singular values of the column-scaled stacked Jacobian, descending (K: the candidates with an
        effect).
    gap : float
        ``s[rank - 1] / s[rank]``, the gap at the rank; inf when full rank.
    cond_raw : float
        Condition number of the raw (unscaled) Jacobian of the identifiable columns; inf when none.
    cond_scaled : float
        The same after unit-norm column scaling.
    rank_tol : float
        The relative singular-value tolerance used (:data:`RANK_TOL` by default).
    notes : tuple of str, optional
        Remarks in words: the robot's structure notes, pairs that act only through their sum or
        difference, a rank that is not clear-cut (default none).
    measured : str, optional
        What the data observe, for the summary line (default ``"position only"``).
    kinds : dict, optional
        Parameter name to its kind (``"length"``, ``"angle"``, or the robot's own, e.g. ``"ratio"``):
        the units of the confound coefficients (default empty: shown without units).
    frames : tuple of str, optional
        Parameters held as gauge freedoms of a closed chain's design frames (default none).
    frames_note : str, optional
        Which frames, in words (default ``""``).
    unseen : tuple of str, optional
        Parameters the data do not see at all (an observation's gauge freedoms, such as the base frame of
        socket data), left out of the other fields but the confounds (:meth:`without_unseen`) (default none).

    See Also
    --------
    identifiability : Build this record for position data.
    free_parameters : The same with the base-frame rule of a calibration.

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis import identifiability
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(30, seed=2)
    >>> ident = identifiability(robot, q)
    >>> ident.rank, len(ident.candidates), ident.full_rank
    (27, 35, False)
    >>> ident.dropped
    ('j1.theta', 'j1.d', 'j3.d', 'j4.d', 'j6.theta', 'j6.d', 'j6.a', 'j6.alpha')
    >>> [(name, round(c, 6)) for name, c in ident.confounds["j1.d"]]
    [('base.z', 1.0)]
    >>> without_tool = identifiability(robot, q, exclude=["tool.x", "tool.y", "tool.z"])
    >>> print(ident.change_from(without_tool))
    now also tool.x, tool.y, tool.z; no longer j6.theta, j6.d, j6.alpha
    """

    robot: str
    candidates: tuple[str, ...]
    identifiable: tuple[str, ...]
    dropped: tuple[str, ...]
    confounds: dict[str, tuple[tuple[str, float], ...]]  # dropped -> ((kept name, coefficient), ...)
    rank: int
    n_poses: int
    singular_values: np.ndarray  # of the scaled stacked Jacobian, descending
    gap: float  # s[rank-1] / s[rank]; inf when full rank
    cond_raw: float  # condition number of the raw Jacobian of the identifiable columns
    cond_scaled: float  # same after unit-norm column scaling
    rank_tol: float
    notes: tuple[str, ...] = field(default=())
    measured: str = "position only"  # what the data observe, for the summary line
    kinds: dict = field(default_factory=dict)  # name -> "length" or "angle": the confounds' units
    frames: tuple[str, ...] = ()  # held as gauge freedoms of a closed chain's design frames (Robot.frame_freedoms)
    frames_note: str = ""  # which frames, in words
    unseen: tuple[str, ...] = ()  # what the data do not see at all (gauge freedoms): left out, see without_unseen

    def __post_init__(self) -> None:
        freeze_arrays(self)  # the arrays it hands out: what it prints cannot drift from what it computed

    @property
    def full_rank(self) -> bool:
        return not self.dropped

    def change_from(self, before: "Identifiability") -> str:
        """How the identifiable set differs from ``before``'s, in words ('now also a, b; no longer c');
        '' when it is the same set."""
        gained = [n for n in self.identifiable if n not in before.identifiable]
        lost = [n for n in before.identifiable if n not in self.identifiable]
        return "; ".join(p for p in (f"now also {', '.join(gained)}" if gained else "",
                                      f"no longer {', '.join(lost)}" if lost else "") if p)

    def to_dict(self) -> dict:
        return {"robot": self.robot, "n_poses": self.n_poses, "n_candidates": len(self.candidates), "rank": self.rank,
                "identifiable": list(self.identifiable), "dropped": list(self.dropped),
                "confounds": {k: [[n, c] for n, c in v] for k, v in self.confounds.items()},
                "singular_values": [float(s) for s in self.singular_values], "gap": _finite_or_none(self.gap),
                "cond_raw": _finite_or_none(self.cond_raw), "cond_scaled": _finite_or_none(self.cond_scaled),
                "rank_tol": self.rank_tol, "notes": list(self.notes), "frames": list(self.frames),
                "frames_note": self.frames_note}

    def without_unseen(self, unseen: Sequence[str]) -> "Identifiability":
        """This record with the parameters the data do not see at all (``unseen``: an observation's gauge freedoms)
        left out of the candidates, the identifiable and the dropped ones and of the notes on pairs; a dropped
        parameter keeps them among its confounds (the record's data), and its line says they are not seen."""
        out = set(unseen)
        with_unseen = {d: c for d, c in self.confounds.items() if d in out or any(k in out for k, _ in c)}
        pairs = set(_pair_notes(self.dropped, with_unseen))
        free = tuple(n for n in self.identifiable if n not in out)
        return dataclasses.replace(self, candidates=tuple(n for n in self.candidates if n not in out), identifiable=free,
                                   rank=len(free), dropped=tuple(n for n in self.dropped if n not in out),
                                   confounds={k: v for k, v in self.confounds.items() if k not in out},
                                   notes=tuple(n for n in self.notes if n not in pairs), unseen=tuple(unseen))

    def confound_lines(self, indent: str = "    ") -> list[str]:
        """One line per dropped parameter: the kept parameters it acts like (physical units), and those of them
        the data do not see (:attr:`unseen`) said so."""
        return [f"{indent}{d}  ~  {self._acts(d)}" for d in self.dropped]

    def _acts(self, dropped: str) -> str:
        """What a dropped parameter acts like, in words: the seen kept parameters (:meth:`acts_like`), then the
        unseen ones as not seen."""
        seen = self.acts_like(dropped)
        hidden = [n for n, _ in self.confounds.get(dropped, ()) if n in set(self.unseen)]
        if not hidden:
            return seen or "no effect on the position"
        if seen:
            return f"{seen} (and {', '.join(hidden)}, not seen by these data)"
        return f"not seen by these data: it acts only like {', '.join(hidden)}, a gauge freedom{'s' * (len(hidden) > 1)}"

    def acts_like(self, dropped: str, most: int | None = None) -> str:
        """The kept parameters a dropped one acts like, each with its coefficient in physical units.

        Parameters
        ----------
        dropped : str
            A dropped parameter's name.
        most : int, optional
            How many of the kept parameters to give, in the order of :attr:`confounds` (default all).

        Returns
        -------
        str
            '+0.113 mm/mrad·j5.d -0.02·tool.z': each coefficient with its unit (:meth:`_unit`: mm/mrad for an
            angle acting like a length, mrad/mm for the reverse, none for the same kind), those the data do not
            see (:attr:`unseen`) left out; '' when none.
        """
        seen = [(n, c) for n, c in self.confounds.get(dropped, ()) if n not in set(self.unseen)]
        return " ".join(f"{c:+.3g}{self._unit(dropped, n)}·{n}" for n, c in seen[:most])

    def _unit(self, dropped: str, kept: str) -> str:
        """The unit of a confound coefficient, the kept parameter's per the dropped one's: ' mm/mrad' for an angle
        acting like a length (1 mrad of it moves the points like c mm of the length; m/rad is mm/mrad), ' mrad/mm'
        for a length acting like an angle, '' for the same kind or kinds not known."""
        a, b = self.kinds.get(dropped), self.kinds.get(kept)
        return "" if a is None or b is None or a == b else " mm/mrad" if b == "length" else " mrad/mm"

    def __str__(self) -> str:
        lines = [f"{self.robot}: {self.rank} of {len(self.candidates)} parameters identifiable from {self.n_poses} "
                 f"poses ({self.measured})",
                 f"  condition number: raw {self.cond_raw:.3g}, column-scaled {self.cond_scaled:.3g}; "
                 f"rank gap {self.gap:.3g} (rank tolerance {self.rank_tol:g})",
                 f"  identifiable: {', '.join(self.identifiable)}"]
        if self.dropped:
            lines.append(f"  not identifiable ({len(self.dropped)}), kept at their nominal values:")
            lines += self.confound_lines()
        return "\n".join(lines + [f"  note: {note}" for note in self.notes])


def _finite_or_none(x: float):
    return float(x) if np.isfinite(x) else None


def stacked_jacobian(robot: Robot, q: np.ndarray, names: Sequence[str] | None = None,
                     values: np.ndarray | None = None) -> np.ndarray:
    """Stack the position Jacobian over the poses for the named parameters.

    Parameters
    ----------
    robot : Robot
        The robot model.
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    names : sequence of str, optional
        The parameters whose columns to keep, in this order (default: all of ``robot.params``).
    values : ndarray, shape (P,), optional
        Parameter values to evaluate at, SI (default: the robot's own).

    Returns
    -------
    ndarray, shape (3N, K)
        Derivatives of the tool positions by the parameters, m/m for lengths and m/rad for angles;
        rows 3i, 3i + 1, 3i + 2 are pose i's x, y, z.

    Raises
    ------
    ModelError
        For an unknown parameter name or joint values of the wrong shape.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.analysis import stacked_jacobian
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(4, seed=0)
    >>> stacked_jacobian(robot, q).shape
    (12, 35)
    >>> J = stacked_jacobian(robot, q, ["j1.d", "base.z"])
    >>> J.shape
    (12, 2)
    >>> bool(np.allclose(J[2::3], 1.0))  # every pose's z moves 1:1 with either offset
    True
    """
    J = robot.param_jacobian(robot.check_q(q), values)
    if names is not None:
        J = J[:, :, robot.params.indices(names)]
    return J.reshape(J.shape[0] * J.shape[1], J.shape[2])


def identifiability(robot: Robot, q: np.ndarray, names: Sequence[str] | None = None, keep: Sequence[str] = (),
                    exclude: Sequence[str] = (), rank_tol: float = RANK_TOL,
                    jacobian: np.ndarray | None = None) -> Identifiability:
    """Identifiable and dropped parameters of ``robot`` from position data at joint values ``q``.

    The stacked position Jacobian's columns are scaled to unit norm, its numerical rank taken from the
    singular values, and the columns to keep chosen by QR with column pivoting (see the module
    description); each dropped parameter is written as a combination of kept ones.

    Parameters
    ----------
    robot : Robot
        The robot model, at the values the Jacobian is taken at.
    q : ndarray, shape (N, n)
        Joint values of the poses, rad (m for a prismatic joint).
    names : sequence of str, optional
        Candidate parameter names (default: all of the robot's).
    keep : sequence of str, optional
        Names to choose first when parameters are confounded; after them come the model's own
        ``robot.preferred_params()`` (for serial robots the tool point, then the base frame), so a
        dropped tool offset is never replaced by a huge joint-angle change (default none).
    exclude : sequence of str, optional
        Names removed from the candidates (default none).
    rank_tol : float, optional
        Relative singular-value tolerance on the column-scaled Jacobian, in (0, 1) (default
        :data:`RANK_TOL`, 3e-5).
    jacobian : ndarray, shape (3N, P), optional
        The stacked position Jacobian at ``q`` over every parameter, rows in any order, if already
        computed (a fit's first evaluation); default: computed here.

    Returns
    -------
    Identifiability
        The identifiable and dropped parameters, the confounds, singular values and condition numbers,
        with the robot's structure notes.

    Raises
    ------
    ValueError
        When ``rank_tol`` is not in (0, 1).
    ModelError
        For an unknown name in ``names`` or ``exclude``, or ``q`` of the wrong shape.
    MeasurementError
        When ``q`` looks like degrees (a call takes radians).

    See Also
    --------
    free_parameters : The parameters a calibration fits (the base-frame rule).

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis import identifiability
    >>> robot = kincal.load_robot("ur5")
    >>> ident = identifiability(robot, robot.sample_joints(30, seed=2))
    >>> print(str(ident).splitlines()[0])
    ur5: 27 of 35 parameters identifiable from 30 poses (position only)
    >>> "j1.d" in ident.dropped, "j1.d" in ident.identifiable
    (True, False)
    >>> preferred = identifiability(robot, robot.sample_joints(30, seed=2), keep=["j1.d"])
    >>> "j1.d" in preferred.identifiable, "base.z" in preferred.dropped
    (True, True)
    """
    if not 0 < rank_tol < 1:
        raise ValueError(f"rank_tol={rank_tol}: the relative singular-value tolerance must lie in (0, 1)")
    q = robot.check_q(q)
    joints_in_radians("q", q, robot)
    excluded = set(exclude)
    robot.params.indices(sorted(excluded))  # unknown names raise
    robot.params.indices(list(keep))  # and so do names to prefer that the robot does not have
    cand = [n for n in (names if names is not None else robot.params.names) if n not in excluded]
    robot.params.indices(cand)
    # a given Jacobian's columns are taken as rows of its transpose: column-major stays column-major
    J = stacked_jacobian(robot, q, cand) if jacobian is None else jacobian.T[robot.params.indices(cand)].T
    ident = jacobian_identifiability(J, cand, [list(keep), list(robot.preferred_params())], robot.name, q.shape[0],
                                     rank_tol, frames=frame_members(robot))
    return dataclasses.replace(ident, notes=tuple(robot.structure_notes()) + ident.notes, kinds=kinds_of(robot, cand))


def frame_members(robot: Robot) -> tuple[str, ...]:
    """The parameters among which a design frame of ``robot`` stands (:meth:`Robot.frame_freedoms`: a hexapod's
    base points with the base frame, its platform points with the tool point and the target's rotation); none for
    a serial arm. :func:`jacobian_identifiability` holds the frames' gauge freedoms at those of them that move
    most along the freedoms, in the parameters' own units (whatever unit the joints are read in).

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis.identifiability import frame_members
    >>> members = frame_members(kincal.load_robot("hexapod"))
    >>> len(members), members[-6:]
    (48, ('leg6.px', 'leg6.py', 'leg6.pz', 'target.rx', 'target.ry', 'target.rz'))
    >>> frame_members(kincal.load_robot("ur5"))
    ()
    """
    return tuple(n for _, members, _ in robot.frame_freedoms() for n in members)


ANGLE_SUFFIXES = (".rx", ".ry", ".rz", ".theta", ".alpha", ".beta", ".roll", ".pitch", ".yaw")


def kinds_of(robot: Robot, names: Sequence[str]) -> dict[str, str]:
    """"length" or "angle" per name: the robot's own parameters by their kind, set-up parameters by
    their name (rotations and plane tilts are angles; points, offsets and drifts lengths)."""
    own = dict(zip(robot.params.names, robot.params.kinds))
    tilt = lambda n: n.startswith("plane[") and n.endswith((".a", ".b"))  # noqa: E731
    return {n: own[n] if n in own else "angle" if tilt(n) or n.endswith(ANGLE_SUFFIXES) else "length" for n in names}


def jacobian_identifiability(J: np.ndarray, cand: Sequence[str], stages: Sequence[Sequence[str]], label: str,
                             n_poses: int, rank_tol: float = RANK_TOL, live: np.ndarray | None = None,
                             frames: Sequence[str] = ()) -> Identifiability:
    """Identifiability of the columns ``cand`` of any stacked (whitened) Jacobian J (M, K): the one
    rule for position data and for every other observation type. ``stages``: names chosen first, in
    order, when columns are confounded (e.g. nuisance parameters, then the base frame). ``live``:
    which columns have any effect, judged in physical units (default: from J itself, unwhitened).
    ``frames``: the members of design frames (:func:`frame_members`); those of no stage that hold the frames'
    gauge freedoms (:func:`_holders`: chosen on the null space in the parameters' own units, so the rows'
    weights, the unit the joints are read in, change nothing) are tried last, one at a time."""
    norms = column_norms(J)
    live = live_columns(J) if live is None else np.asarray(live, bool)
    live_names = [n for n, ok in zip(cand, live) if ok]
    # Everything below depends on the column space only, so it works on the small triangular
    # factor R0 of the scaled Jacobian (Js = Q0 R0): same singular values, same linear relations.
    # (J D⁻¹ = Q (R D⁻¹): the factor of the unscaled columns, scaled, saves a copy of J)
    Jl = J if live.all() else J[:, live]
    R0 = r_factor(Jl) / norms[live] if live.any() else np.zeros((0, 0))

    s = np.linalg.svd(R0, compute_uv=False) if R0.size else np.zeros(0)
    rank = int(np.sum(s > rank_tol * s[0])) if s.size else 0
    gap = float(s[rank - 1] / s[rank]) if 0 < rank < s.size and s[rank] > 0 else float("inf")

    staged = {n for st in stages for n in st}
    members = [n for n in live_names if n in set(frames) and n not in staged]
    held = _holders(R0, norms[live], live_names, rank, members)
    order = _pivot_order(R0, live_names, [list(st) for st in stages], rank, rank_tol * s[0] if s.size else 0.0,
                         [[n] for n in reversed(held)])
    ident = [live_names[k] for k in order[:rank]]
    confounds = _confounds(R0, norms[live], order, rank, live_names)
    dead = [n for n, ok in zip(cand, live) if not ok]
    confounds.update(dict.fromkeys(dead, ()))
    dropped = tuple(live_names[k] for k in order[rank:]) + tuple(dead)
    kept, inf = sorted(order[:rank]), float("inf")  # condition numbers (raw, column-scaled) of the kept columns
    cond_raw, cond_scaled = (float(np.linalg.cond(R0[:, kept] * norms[live][kept])),
                             float(np.linalg.cond(R0[:, kept]))) if kept else (inf, inf)
    notes = _pair_notes(dropped, confounds)
    if rank and gap < 1e3:
        notes.append(f"the rank is not clear-cut (gap {gap:.3g} < 1e3): the poses hardly excite some "
                     f"parameters; add poses or check the model")
    return Identifiability(label, tuple(cand), tuple(n for n in cand if n in set(ident)), dropped, confounds,
                           rank, n_poses, s, gap, cond_raw, cond_scaled, rank_tol, tuple(notes))


HOLD_TOL = 1e-6  # a member's motion along the freedoms left, against the first holder's: below it, none are left
HOLD_RTOL = 0.05  # motions this near the largest tie: a symmetric design's members move alike, up to its tolerances


def _holders(R0: np.ndarray, norms: np.ndarray, names: list[str], rank: int, members: list[str]) -> list[str]:
    """The ``members`` (of design frames, in canonical order) that hold the freedoms the columns of R0 leave
    undetermined, the first holder first: the null space of R0 in the parameters' own units (m, rad: the rows'
    weights do not change it), orthonormalised; the member that moves most along it holds one freedom, what is
    left is made orthogonal to its motion, and so on while a member still moves (:data:`HOLD_TOL`). Motions within
    :data:`HOLD_RTOL` (5 %) of the largest tie and go to the earliest member (:func:`kincal.ties.first_best`): the
    members of a symmetric design move alike but for its tolerances, which must not choose. The holders are far
    apart (a frame turned about a point moves the points far from it most), so the parameters left are well
    determined."""
    if rank >= R0.shape[1] or not members:
        return []
    null = np.linalg.svd(R0)[2][rank:].T / norms[:, None]  # (K, d): the undetermined directions, per SI unit
    A = np.linalg.qr(null)[0][[names.index(n) for n in members]]
    held: list[str] = []
    first = 0.0
    while len(held) < A.shape[1]:
        size = np.sqrt(np.einsum("ij,ij->i", A, A))
        i = first_best(size, rtol=HOLD_RTOL)
        if size[i] <= HOLD_TOL * (first or 1.0):
            break
        first = first or float(size[i])
        held.append(members[i])
        u = A[i] / size[i]
        A = A - np.outer(A @ u, u)
    return held


QR_ROWS = 2048  # rows per block of a tall QR: a block of a Jacobian stays in the cache


def r_factor(J: np.ndarray) -> np.ndarray:
    """The triangular factor R (k, k) of J (M, k) = Q R (M ≥ k), as a tall-skinny QR when M is large:
    the R factors of blocks of ``QR_ROWS`` rows, stacked, factored again. The same column space and
    singular values as one Householder QR (up to round-off and the signs of R's rows), five times
    faster for 10⁵ poses (0.10 s against 0.51 s: the blocks stay in the cache)."""
    # (NumPy's stubs type every qr result as a QRResult; mode="r" returns R alone)
    if J.shape[0] > 2 * QR_ROWS:
        J = np.concatenate([np.linalg.qr(J[i:i + QR_ROWS], mode="r") for i in range(0, J.shape[0], QR_ROWS)])
    return cast(np.ndarray, np.linalg.qr(J, mode="r"))


def _confounds(R0: np.ndarray, norms: np.ndarray, order: list[int], rank: int,
               names: list[str]) -> dict[str, tuple[tuple[str, float], ...]]:
    """Each dropped column as a combination of the kept ones, read off the R factor, in physical
    units (1 of the dropped parameter acts like ``c`` of each kept one), largest first."""
    out: dict[str, tuple[tuple[str, float], ...]] = {}
    if rank == 0 or rank == len(order):
        return out
    A, B = R0[:, order[:rank]], R0[:, order[rank:]]
    C = np.linalg.lstsq(A, B, rcond=None)[0]  # B ≈ A C  (scaled units)
    kept = [names[k] for k in order[:rank]]
    n_kept, n_drop = norms[order[:rank]], norms[order[rank:]]
    for j, k in enumerate(order[rank:]):
        col = C[:, j] * n_drop[j] / n_kept
        idx = np.flatnonzero(np.abs(C[:, j]) > max(1e-6, 1e-3 * np.abs(C[:, j]).max()))
        idx = idx[order_with_ties(np.abs(C[idx, j]))]
        out[names[k]] = tuple((kept[i], float(col[i])) for i in idx)
    return out


def _pair_notes(dropped, confounds) -> list[str]:
    """Pairs that act only through their sum or difference, said in words."""
    notes = []
    for name in dropped:
        conf = confounds.get(name, ())
        if len(conf) == 1 and abs(abs(conf[0][1]) - 1.0) < 1e-6:
            other, c = conf[0]
            how = f"their difference {name} − {other}" if c < 0 else f"their sum {name} + {other}"
            notes.append(f"{name} and {other} act only through {how}: only that combination can be identified")
    return notes


BASE_MODES = ("fixed", "estimate")


def free_parameters(robot: Robot, q: np.ndarray, base: str = "estimate", names: Sequence[str] | None = None,
                    keep: Sequence[str] = (), rank_tol: float = RANK_TOL,
                    jacobian: np.ndarray | None = None) -> Identifiability:
    """Identifiability of the parameters a calibration or a design would fit.

    The one home of the base-mode rule. ``base="fixed"``: the base frame is known, so its parameters
    are left out; ``"estimate"``: the base frame is fitted too and its parameters are chosen first
    among confounded ones (after ``keep``), so a base offset, not a joint term, absorbs where the
    tracker stands. The fit's free parameters are ``.identifiable``; ``.candidates`` is the list asked
    for.

    Parameters
    ----------
    robot : Robot
        The robot model.
    q : ndarray, shape (N, n)
        Joint values of the poses, rad (m for a prismatic joint).
    base : {"estimate", "fixed"}, optional
        Whether the base frame is fitted (default ``"estimate"``; :data:`BASE_MODES`).
    names : sequence of str, optional
        The candidates: None (default) for every parameter, otherwise exactly those (plus the base
        frame when estimated).
    keep : sequence of str, optional
        Names to choose first among confounded parameters (default none).
    rank_tol : float, optional
        Relative singular-value tolerance, in (0, 1) (default :data:`RANK_TOL`).
    jacobian : ndarray, shape (3N, P), optional
        The stacked position Jacobian at ``q`` if already computed (see :func:`identifiability`).

    Returns
    -------
    Identifiability
        The identifiable set (the fit's free parameters) and what the poses do not determine.

    Raises
    ------
    ValueError
        When ``base`` is not one of :data:`BASE_MODES`, when ``names`` lists a base-frame parameter
        with ``base="fixed"``, or when ``rank_tol`` is not in (0, 1).

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis import free_parameters
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(30, seed=2)
    >>> free_parameters(robot, q).rank
    27
    >>> fixed = free_parameters(robot, q, base="fixed")
    >>> fixed.rank, "base.x" in fixed.candidates
    (23, False)
    >>> free_parameters(robot, q, base="fixed", names=["base.x", "j2.a"])
    Traceback (most recent call last):
    ...
    ValueError: base.x listed with base='fixed'; use base='estimate' to fit the base
    """
    if base not in BASE_MODES:
        raise ValueError(f"base='{base}' is not one of {BASE_MODES}")
    bn = list(robot.base_params())
    chosen = None if names is None else list(dict.fromkeys(names))
    if chosen is not None and base == "fixed" and (clash := [n for n in chosen if n in bn]):
        raise ValueError(f"{', '.join(clash)} listed with base='fixed'; use base='estimate' to fit the base")
    if chosen is not None and base == "estimate":
        chosen = bn + [n for n in chosen if n not in bn]
    # base="fixed" with names: excluding the base frame changes nothing (none of it is listed)
    return identifiability(robot, q, names=chosen, keep=list(keep) + (bn if base == "estimate" else []),
                           exclude=bn if base == "fixed" else (), rank_tol=rank_tol, jacobian=jacobian)


def _pivot_order(Js: np.ndarray, names: list[str], stages: list[list[str]], rank: int, cutoff: float,
                 after: Sequence[Sequence[str]] = ()) -> list[int]:
    """Column order: pivoted Gram–Schmidt stage by stage (each stage's columns in the stage's own
    order, the rest in model order), a column counting when its residual exceeds ``cutoff``; the
    columns of no stage come next, then the stages ``after`` (one column each: tried in their order); the
    columns of no stage and of ``after`` complete the rank. Residual norms that tie go to the earliest
    column. The first ``rank`` entries are the chosen columns."""
    pos = {n: k for k, n in enumerate(names)}
    groups, seen = [], set()
    for stage in [*stages, *after]:
        g = [pos[n] for n in dict.fromkeys(stage) if n in pos and pos[n] not in seen]
        seen.update(g)
        groups.append(g)
    free = [k for k in range(len(names)) if k not in seen]
    groups.insert(len(stages), free)
    groups.append(free + [k for g in groups[len(stages) + 1:] for k in g])  # what completes the rank
    A = np.array(Js, dtype=float)  # columns made orthogonal to the chosen ones as we go
    chosen: list[int] = []
    for at, group in enumerate(groups):
        last = at == len(groups) - 1  # the last stage completes the rank whatever its residuals
        rest = [k for k in group if k not in set(chosen)]
        while rest and len(chosen) < rank:
            norms = np.sqrt(np.einsum("ij,ij->j", A, A)[rest])
            i = first_best(norms)
            if not last and norms[i] <= cutoff:
                break
            k = rest.pop(i)
            chosen.append(k)
            u = A[:, k] / norms[i]
            for _ in range(2):  # twice is enough (Kahan–Parlett)
                A -= u[:, None] * (u @ A)
    return chosen + [k for k in range(len(names)) if k not in set(chosen)]
