"""Observation types without a measuring device: a ball seated in sockets (the same unknown point reached in many
configurations, with known distances between points) and contacts with planes.

Neither sees where the robot stands: the base frame is a gauge freedom (left at its value and named). Sockets without
a known distance, and planes without two known parallel ones at different offsets, do not fix the length scale
either: a robot shrunk towards a point (on a plane, or on the line where two planes meet) satisfies them as well, so
such a fit is refused before it starts (MUKCa, Franzese et al. 2025, use the 50 mm between two sockets).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from ..errors import MeasurementError
from ..models.robot import Robot
from ..ties import tie_tolerance
from ..units import LENGTH_UNITS, MM, OTHER_LENGTHS, fine
from .observations import Observation, error_stats


SCALE_LIMIT = 3.0  # a stated distance this many times off the robot file's: a unit or label mistake
SPREAD_LIMIT = 50e-3  # m: one point's samples farther than this from their centre under the robot file: not one point
STEP_SLACK = 5e-3  # m: a step between known planes this far off the robot file's is a robot's error, never a unit's
UNIT_FACTORS = {"mm": 1 / LENGTH_UNITS["mm"], "cm": 1 / OTHER_LENGTHS["cm"], "inches": 1 / OTHER_LENGTHS["inch"]}


def _labels_in_order(labels: np.ndarray) -> list[str]:
    return list(dict.fromkeys(str(x) for x in labels.tolist()))  # in order of first appearance


def _unit_hint(stated: float, seen: float, what: str) -> str:
    """What a known length ``stated`` (m), which the robot file sees as ``seen`` (m), looks like ('' if nothing):
    metres written in a file read in mm (a thousandth), another unit (:data:`UNIT_FACTORS`: mm, cm, inches where m
    is read) or another power of ten; ``what`` names the lengths in the advice (e.g. "distances").

    >>> _unit_hint(0.05e-3, 0.05, "plane offsets")[:52]
    ': a thousandth of it, as if metres were stated in a '
    >>> _unit_hint(50.0, 0.05, "plane offsets"), _unit_hint(0.12, 0.05, "distances")
    (': it looks like mm; give plane offsets in m', '')
    >>> _unit_hint(0.5, 0.05, "distances")
    ": 10 times theirs, a power of ten: stated in another unit than the file's?"
    """
    ratio = max(stated, 1e-300) / max(seen, 1e-12)
    if abs(np.log(ratio * 1e3)) < 0.3:  # metres stated where the file's unit is mm
        return f": a thousandth of it, as if metres were stated in a file read in mm; state {what} in the file's " \
               f"length unit"
    unit = next((u for u, f in UNIT_FACTORS.items() if abs(np.log(ratio / f)) < 0.3), None)
    if unit:
        return f": it looks like {unit}; give {what} in m"
    tens = round(float(np.log10(ratio)))
    return (f": {10.0 ** tens:g} times theirs, a power of ten: stated in another unit than the file's?"
            if tens and abs(np.log(ratio / 10.0 ** tens)) < 0.3 else "")


def _tool_hint(robot: Robot, q: np.ndarray, labels: np.ndarray) -> str:
    """Where the samples say the ball is when a tool point puts each label's samples on one point (least squares: the
    flange poses, one tool point, one centre per label) within a robot's error, the robot file's being elsewhere:
    '' when none does."""
    if not robot.has_tool_point:
        return ""
    P, R, _, _ = robot.pose_and_jacobian(q)
    flange = P - R @ robot.tool_point()
    names = list(dict.fromkeys(labels))
    A = np.zeros((3 * len(q), 3 + 3 * len(names)))
    A[:, :3] = R.reshape(-1, 3)
    for k, lab in enumerate(labels):
        A[3 * k:3 * k + 3, 3 + 3 * names.index(lab):6 + 3 * names.index(lab)] = -np.eye(3)
    x = np.linalg.lstsq(A, -flange.reshape(-1), rcond=None)[0]
    spread = np.linalg.norm((A @ x + flange.reshape(-1)).reshape(-1, 3), axis=1).mean()
    if spread > 0.25 * SPREAD_LIMIT:  # a robot's error left (an uncalibrated arm: several mm), not places
        return ""
    where = ", ".join(f"{v * MM:.1f}" for v in x[:3])
    return (f"a tool point at ({where}) mm in the flange frame puts them within {spread * MM:.1f} mm of one point: the "
            f"ball is not where the robot file puts the tool (check --tip-link, or declare it with --tool)")


def two_places(p: np.ndarray) -> np.ndarray | None:
    """Whether points p (N, 3), m, are two tight clusters: the split along their principal axis that leaves the least
    squared spread (every cut, by prefix sums), when each side has two points or more within :data:`SPREAD_LIMIT` of
    its centre on average (a robot's error); its mask of the points on one side (N,) of bool, else None.

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> p = np.vstack([rng.normal(0, 5e-3, (6, 3)), rng.normal([0.48, 0, 0], 5e-3, (4, 3))])
    >>> two_places(p).astype(int).tolist(), two_places(rng.normal(0, 0.2, (10, 3))) is None
    ([1, 1, 1, 1, 1, 1, 0, 0, 0, 0], True)
    """
    if len(p) < 4:
        return None
    c = p - p.mean(axis=0)
    order = np.argsort(c @ np.linalg.svd(c, full_matrices=False)[2][0], kind="stable")
    s, s2, n = np.cumsum(c[order], axis=0), np.cumsum(np.sum(c[order] ** 2, axis=1)), np.arange(1, len(p) + 1)
    left = s2[:-1] - np.sum(s[:-1] ** 2, axis=1) / n[:-1]
    right = (s2[-1] - s2[:-1]) - np.sum((s[-1] - s[:-1]) ** 2, axis=1) / (len(p) - n[:-1])
    k = int(np.argmin(np.where((n[:-1] >= 2) & (n[:-1] <= len(p) - 2), left + right, np.inf))) + 1
    one = np.zeros(len(p), bool)
    one[order[:k]] = True
    tight = all(np.linalg.norm(p[m] - p[m].mean(axis=0), axis=1).mean() < SPREAD_LIMIT for m in (one, ~one))
    return one if tight else None


def _spans(rows: np.ndarray) -> str:
    """Row numbers as runs: '371-402, 410' (MAX_RUNS runs at most, then how many more rows)."""
    rows = np.sort(np.asarray(rows, int))
    breaks = np.flatnonzero(np.diff(rows) != 1) + 1
    runs = [f"{r[0]}-{r[-1]}" if len(r) > 1 else f"{r[0]}" for r in np.split(rows, breaks)]
    rest = int(sum(len(r) for r in np.split(rows, breaks)[MAX_RUNS:]))
    return ", ".join(runs[:MAX_RUNS]) + (f" and {rest} more" if rest else "")


MAX_RUNS = 4


@dataclass(frozen=True, eq=False)
class SamePointObs(Observation):
    """The tool point held at the same unknown point in every sample with that label (a ball in a socket).

    Each labelled point is a set-up parameter (``point[<label>].x/y/z``, m, in the robot's base frame); known
    distances between labelled points fix the length scale (without one the set is no reference and such a
    fit is refused). The base frame is a gauge freedom: the sockets do not see where the robot stands. The
    residual is each sample's tool point − its label's point (x rows, then y, then z), then each known
    distance's error, once in a fit: a distance between points another file holds too, stated there as well, is
    fitted by the first file stating it (:meth:`after`).

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    labels : ndarray of str, shape (N,)
        Each sample's point.
    distances : tuple of (str, str, float), optional
        Known distances between labelled points: (label a, label b, distance m), … (default ()).
    group : ndarray of str, shape (N,), optional
        Per sample, the placement whose statistics are reported (default None: one group).
    std : ndarray, shape (N,), or float, optional
        How well the ball seats, σ per axis, per sample or one number, m (default 0.05e-3).
    std_distance : float, optional
        How well the distances are known, σ, m (default 0.1e-3).
    elsewhere : tuple of (str, ndarray (M, n)), optional
        Per label, the joints of other files' samples of the same point (default (): :meth:`among` sets them), which
        :meth:`stats` judges this file's samples against with its own.
    stated_before : tuple of (str, str), optional
        The pairs of labels of ``distances`` that an earlier set of the same fit states too (default (): :meth:`after`
        sets them): they have no residual here, so that each distance weighs once; :meth:`stats` still reports them.

    Examples
    --------
    Two sockets 0.31 m apart, each reached in three configurations of a SCARA:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import simulate_same_point
    >>> robot = kincal.load_robot("scara")
    >>> a, b = robot.forward(np.array([[0.3, 0.5, 0.1, 0.0], [-0.4, 0.8, 0.05, 0.0]]))
    >>> d = float(np.linalg.norm(a - b))
    >>> obs = simulate_same_point(robot, {"a": a, "b": b}, per_point=3, distances=[("a", "b", d)])
    >>> type(obs).__name__, obs.labels.tolist(), obs.reference
    ('SamePointObs', ['a', 'a', 'a', 'b', 'b', 'b'], True)
    >>> obs.nuisance(robot)[0]
    ('point[a].x', 'point[a].y', 'point[a].z', 'point[b].x', 'point[b].y', 'point[b].z')
    >>> obs.gauge_params(robot)
    ('base.x', 'base.y', 'base.z', 'base.rx', 'base.ry', 'base.rz')
    >>> obs.sigma().shape  # 3 per sample, then the distance
    (19,)

    A distance stated in mm where metres are meant is refused before a fit starts:

    >>> import dataclasses
    >>> dataclasses.replace(obs, distances=(("a", "b", d * 1e3),)).prepare(robot)
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: simulated scara sockets: the distance a–b is stated as 313686 mm, but the
    robot file puts those points 313.7 mm apart: it looks like mm; give distances in m
    """

    labels: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    distances: tuple[tuple[str, str, float], ...] = ()
    group: np.ndarray | None = None
    std: np.ndarray | float = 0.05e-3  # m: how well the ball seats, per axis (one number or per sample)
    std_distance: float = 0.1e-3  # m: how well the distances are known
    elsewhere: tuple[tuple[str, np.ndarray], ...] = ()  # (label, joints (M, n)): its points' samples in other files
    stated_before: tuple[tuple[str, str], ...] = ()  # distances an earlier set of the fit states: fitted there, once
    kind = "same-point"

    @property
    def reference(self) -> bool:
        return bool(self.distances)

    def points(self) -> list[str]:
        return _labels_in_order(self.labels)

    def subset(self, idx: np.ndarray) -> "SamePointObs":
        """The samples ``idx``, with the known distances between points that still have samples (a placement left
        out whole, by --exclude or a cross-validation fold, takes its distances with it)."""
        out = cast(SamePointObs, super().subset(idx))  # every per-sample array indexed
        kept = set(out.labels.tolist())
        return dataclasses.replace(out, distances=tuple(d for d in self.distances if d[0] in kept and d[1] in kept))

    def fitted_distances(self) -> tuple[tuple[str, str, float], ...]:
        """The known distances this set adds residuals for (m): ``distances`` but those ``stated_before``."""
        before = {frozenset(pair) for pair in self.stated_before}
        return tuple(d for d in self.distances if frozenset(d[:2]) not in before)

    def after(self, earlier) -> "SamePointObs":
        """The set as it is fitted after the sets ``earlier``: a distance between two points that an earlier set
        states too (the same labels: the same points) is fitted there, once (stated in two files it weighed twice),
        and MeasurementError when the two lengths differ beyond a tie (:mod:`kincal.ties`)."""
        stated: dict[frozenset, tuple[float, str]] = {}
        for o in earlier:
            for a, b, d in o.distances if isinstance(o, SamePointObs) else ():
                stated.setdefault(frozenset((a, b)), (d, o.source))
        before = []
        for a, b, d in self.distances:
            if frozenset((a, b)) in stated:
                other, where = stated[frozenset((a, b))]
                if abs(d - other) > tie_tolerance(max(d, other)):
                    raise MeasurementError(
                        f"{self.source}: the distance {a}–{b} is stated as {fine(d, 'length', 'g')}, but {where} "
                        f"states it as {fine(other, 'length', 'g')} between the same points (their labels are "
                        f"shared); give each known distance once, or give the files' points labels of their own "
                        f"(another placement name) if they are different plates")
                before.append((a, b))
        return dataclasses.replace(self, stated_before=tuple(before))

    def among(self, sets) -> "SamePointObs":
        """The set as it is fitted among ``sets``: a label that another file's samples hold too is one point (one
        set-up parameter), so :meth:`stats` judges this file's samples of it against the mean of all of them, as if
        the files were one (each file's own mean hid a plate moved between them: 0.22 mm per file where the same rows
        in one file are 1.51 mm off their point)."""
        mine = set(self.points())
        found = tuple((lab, o.q[o.labels == lab]) for o in sets if o is not self and isinstance(o, SamePointObs)
                      for lab in o.points() if lab in mine)
        return dataclasses.replace(self, elsewhere=found)

    def point_means(self, robot: Robot, values: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per label, the mean of its samples' points under ``robot`` at ``values`` (3,), m, and that mean's standard
        error per axis (3,), m: their spread (the stated σ at least) over the square root of their count."""
        p = robot.forward(self.q, values)
        seat = np.broadcast_to(np.asarray(self.std, float), (len(self),))
        out = {}
        for lab in self.points():
            mine = self.labels == lab
            spread = np.std(p[mine], axis=0, ddof=1) if mine.sum() > 1 else np.zeros(3)
            out[lab] = (p[mine].mean(axis=0), np.maximum(spread, seat[mine].mean()) / np.sqrt(mine.sum()))
        return out

    def _spread_hint(self, p: np.ndarray, label: str) -> str:
        """What to check when the samples labelled ``label`` (their points p (N, 3) under the robot file, m) are not
        one point: two tight places (a plate moved within the label, or two placements under one name), the
        placements (when none are labelled), then the joint columns (their order, one given twice) and units."""
        mine = self.labels == label
        one = two_places(p[mine])
        if one is not None:
            gap = float(np.linalg.norm(p[mine][one].mean(axis=0) - p[mine][~one].mean(axis=0)))
            where = "; ".join(f"rows {_spans(self.rows[mine][m])} ({m.sum()} samples)" for m in (one, ~one))
            return (f"they fall into two places {gap * MM:.0f} mm apart, each within a robot's error ({where}): the "
                    f"plate moved within this label, or two placements share its name; give each plate position a "
                    f"placement name of its own" + (" (kincal calibrate: --group-col)" if self.group is None else
                                                     f" (in the --group-col column)"))
        columns = "check the joint columns (their order, and that each is the joint it names) and their units"
        if self.group is None:
            return (f"if the plate was moved between samples, label each placement (kincal calibrate: --group-col), "
                    f"else {columns}")
        return f"the placements are labelled (each label within its placement), so {columns}"

    def prepare(self, robot: Robot) -> "SamePointObs":
        """Checks that one label's samples are one point up to ``robot``'s error (samples of several places under one
        label, a moved plate without its placement, are refused with that cause), each known distance against where
        it puts the two points (a unit mistake makes them 10-1000x apart) and each label against the points named;
        returns the set unchanged."""
        p = robot.forward(self.q)
        at = {lab: p[self.labels == lab].mean(axis=0) for lab in self.points()}  # the points' starts (nuisance)
        for lab, centre in at.items():
            d = np.linalg.norm(p[self.labels == lab] - centre, axis=1)
            if d.mean() > SPREAD_LIMIT:
                raise MeasurementError(
                    f"{self.source}: the {d.size} samples labelled '{lab}' are not one point: the robot file puts them "
                    f"{d.mean() * MM:.0f} mm from their centre on average (up to {d.max() * MM:.0f} mm), far more "
                    f"than a robot's error; " + (_tool_hint(robot, self.q, self.labels) or self._spread_hint(p, lab)))
        for a, b, d in self.distances:
            missing = [lab for lab in (a, b) if lab not in at]
            if missing:
                raise MeasurementError(f"{self.source}: the distance {a}–{b} names {', '.join(missing)}, which no sample "
                                       f"has (labels: {', '.join(self.points()[:10])})")
            seen = float(np.linalg.norm(at[a] - at[b]))
            if not (d > 0 and SCALE_LIMIT ** -1 < d / max(seen, 1e-12) < SCALE_LIMIT):
                raise MeasurementError(f"{self.source}: the distance {a}–{b} is stated as {fine(d, 'length', 'g')}, "
                                       f"but the robot file puts those points {fine(seen, 'length', '.4g')} apart"
                                       f"{_unit_hint(d, seen, 'distances')}")
        return self

    def nuisance(self, robot: Robot):
        p = robot.forward(self.q)
        start = np.concatenate([p[self.labels == lab].mean(axis=0) for lab in self.points()])
        return tuple(f"point[{lab}].{a}" for lab in self.points() for a in "xyz"), start, ("length",) * start.size

    def gauge_params(self, robot: Robot) -> tuple[str, ...]:
        return robot.base_params()

    def sample_rows(self) -> np.ndarray:
        return np.concatenate([np.tile(np.arange(len(self)), 3), -np.ones(len(self.fitted_distances()), int)])

    def sigma(self) -> np.ndarray:
        per_sample = np.broadcast_to(np.asarray(self.std, float), (len(self),))  # one number or (N,)
        return np.concatenate([np.tile(per_sample, 3), np.full(len(self.fitted_distances()), self.std_distance)])

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        p, J = robot.forward_and_jacobian(self.q, values)
        pos = {lab: k for k, lab in enumerate(self.points())}
        at = np.array([pos[str(lab)] for lab in self.labels])  # each sample's point
        P, n, K = nuis.reshape(-1, 3), len(self), nuis.size
        Jn = np.zeros((3, n, K))
        Jn[np.arange(3)[:, None], np.arange(n), 3 * at + np.arange(3)[:, None]] = -1.0  # d (p − P[at]) / d P
        fitted = self.fitted_distances()
        rd, Jd = np.empty(len(fitted)), np.zeros((len(fitted), K))
        for k, (a_lab, b_lab, d) in enumerate(fitted):
            i, j = pos[a_lab], pos[b_lab]
            u = P[i] - P[j]
            length = float(np.linalg.norm(u))
            rd[k] = length - d
            Jd[k, 3 * i:3 * i + 3], Jd[k, 3 * j:3 * j + 3] = u / length, -u / length
        Jr = np.vstack([J.transpose(1, 0, 2).reshape(-1, J.shape[2]), np.zeros((len(rd), J.shape[2]))])
        return np.concatenate([(p - P[at]).T.ravel(), rd]), Jr, np.vstack([Jn.reshape(3 * n, K), Jd])

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        """Per group (placement), as the MUKCa paper defines them: the count-weighted mean over its points of
        ``|p − that point's mean of p|`` and, per known distance inside it, ``| ‖m_a − m_b‖ − d |`` (m: the mean
        points). A point other files hold too (:meth:`among`) is one point: its mean is over all their samples."""
        p = robot.forward(self.q, values)
        group = np.full(len(self), "all") if self.group is None else self.group
        others: dict[str, list[np.ndarray]] = {}
        for lab, q in self.elsewhere:
            others.setdefault(lab, []).append(robot.forward(q, values))
        out, devs = [], []
        for g in _labels_in_order(group):
            mine = group == g
            means = {lab: np.concatenate([p[self.labels == lab], *others.get(lab, [])]).mean(axis=0)
                     for lab in _labels_in_order(self.labels[mine])}
            dev = np.concatenate([np.linalg.norm(p[mine & (self.labels == lab)] - m, axis=1) for lab, m in means.items()])
            dist = [abs(float(np.linalg.norm(means[a] - means[b])) - d) for a, b, d in self.distances
                    if a in means and b in means]
            out.append({"group": g, "samples": int(mine.sum()), "mean_abs": float(dev.mean()),
                        "distance_error": float(np.mean(dist)) if dist else None})
            devs.append(dev)
        stats = error_stats(self, np.concatenate(devs))  # its mean: the paper's mean |p − mean of p|
        return {("mean_abs" if k == "mean" else k): v for k, v in stats.items()} | {"groups": out}


@dataclass(frozen=True, eq=False)
class PlaneObs(Observation):
    """The tool point touching a plane: per sample a plane label.

    A plane is known (unit normal n and offset c, n·x = c in the robot's base frame, m) or unknown (the
    set-up parameters ``plane[<label>].a/b/c``: the normal tilted by a, b (rad) from its start and the offset
    c, m). The residual is n·p − c (m) per sample. Only two known parallel planes at different offsets (a
    gauge block's step) fix the length scale; unknown planes alone leave the base frame a gauge freedom.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    labels : ndarray of str, shape (N,)
        Each sample's plane.
    known : dict, optional
        The known planes: label -> (normal (3,), offset c in m); the normal is normalised here (default {}).
    std : ndarray, shape (N,), or float, optional
        σ of the contacts across the plane, per sample or one number, m (default 0.05e-3).
    start : dict, optional
        The unknown planes' starts: label -> (unit normal (3,), offset c in m) (default {}; :meth:`prepare`
        sets them from the data).

    Examples
    --------
    A SCARA's tool point height depends on its third (prismatic) joint alone: touches of a table and of a
    gauge-block step 50 mm above it.

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import PlaneObs
    >>> robot = kincal.load_robot("scara")
    >>> q = np.array([[0.3, 0.5, 0.10, 0.0], [-0.4, 0.8, 0.10, 1.0], [0.9, -0.6, 0.10, 0.0],
    ...               [0.2, 1.2, 0.05, 0.3], [-0.7, 0.4, 0.05, 0.0]])
    >>> z = robot.forward(q)[:, 2]
    >>> labels = np.array(["table"] * 3 + ["step"] * 2)
    >>> known = {"table": ((0.0, 0.0, 1.0), float(z[0])), "step": ((0.0, 0.0, 1.0), float(z[3]))}
    >>> obs = PlaneObs(q, np.arange(2, 7), "touches.csv", labels=labels, known=known)
    >>> round(float(z[3] - z[0]), 9), obs.reference, obs.unknown()
    (0.05, True, [])
    >>> r, _, _ = obs.evaluate(robot, robot.params.values, np.zeros(0))
    >>> bool(np.abs(r).max() < 1e-12)
    True

    The same planes unknown: fitted, starting from the planes through the nominal points, and no length scale:

    >>> unknown = PlaneObs(q, np.arange(2, 7), "touches.csv", labels=labels).prepare(robot)
    >>> unknown.reference, unknown.nuisance(robot)[0]
    (False, ('plane[table].a', 'plane[table].b', 'plane[table].c', 'plane[step].a', 'plane[step].b', 'plane[step].c'))
    """

    labels: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    known: dict = field(default_factory=dict)  # label -> (n (3,), c)
    std: np.ndarray | float = 0.05e-3  # m, one number or per sample
    kind = "plane"

    @property
    def reference(self) -> bool:
        """Only two known parallel planes at different offsets (a gauge block's step) fix the length
        scale: points collapsed onto one plane, or onto the line where two planes meet, satisfy the rest."""
        known = [(np.asarray(n, float) / np.linalg.norm(n), float(c)) for n, c in self.known.values()]
        return any(abs(abs(a @ b) - 1.0) < 1e-6 and abs(ca - np.sign(a @ b) * cb) > 1e-3
                   for i, (a, ca) in enumerate(known) for b, cb in known[i + 1:])

    def unknown(self) -> list[str]:
        return [lab for lab in _labels_in_order(self.labels) if lab not in self.known]

    start: dict = field(default_factory=dict)  # unknown planes: label -> (n0, c0) the fit starts from (prepare)

    def prepare(self, robot: Robot) -> "PlaneObs":
        """A copy whose unknown planes start at the best-fitting planes through ``robot``'s points, after the check
        of each step between known parallel planes against the one ``robot`` puts between their contacts
        (:meth:`check_known_lengths`)."""
        self.check_known_lengths(robot)
        p = robot.forward(self.q)
        start = {}
        for lab in self.unknown():
            pts = p[self.labels == lab]
            n = np.linalg.svd(pts - pts.mean(axis=0))[2][2]
            n = n if n[np.argmax(np.abs(n))] > 0 else -n  # canonical sign
            start[lab] = (n, float(n @ pts.mean(axis=0)))
        return dataclasses.replace(self, start=start)

    def check_known_lengths(self, robot: Robot) -> None:
        """Refuses a step between two known parallel planes that ``robot`` puts more than ``STEP_SLACK`` and a factor
        ``SCALE_LIMIT`` away from the stated one (between the mean heights of their contacts), naming the unit it
        looks like (:func:`_unit_hint`): offsets in another unit make a step 10-1000x off, which a fit reads as a
        robot that many times its size, or, under 1 mm, as no step at all (no length scale)."""
        p = robot.forward(self.q)
        known = {lab: (np.asarray(n, float) / np.linalg.norm(n), float(c)) for lab, (n, c) in self.known.items()
                 if np.any(self.labels == lab)}
        labels = list(known)
        for i, a in enumerate(labels):
            for b in labels[i + 1:]:
                (na, ca), (nb, cb) = known[a], known[b]
                if abs(abs(na @ nb) - 1.0) >= 1e-6:
                    continue
                turn = float(np.sign(na @ nb))
                stated = abs(ca - turn * cb)
                seen = abs(float(np.mean(p[self.labels == a] @ na) - turn * np.mean(p[self.labels == b] @ nb)))
                if abs(stated - seen) > STEP_SLACK and not SCALE_LIMIT ** -1 < stated / max(seen, 1e-12) < SCALE_LIMIT:
                    raise MeasurementError(
                        f"{self.source}: the known planes {a} and {b} are stated {fine(stated, 'length', '.4g')} apart "
                        f"(offsets {ca * MM:g} and {fine(cb, 'length', 'g')}), but the robot file puts their contacts "
                        f"{fine(seen, 'length', '.4g')} apart"
                        f"{_unit_hint(stated, seen, 'plane offsets')}")

    def nuisance(self, robot: Robot):
        names = tuple(f"plane[{lab}].{a}" for lab in self.unknown() for a in "abc")
        vals = np.concatenate([[0.0, 0.0, self.start[lab][1]] for lab in self.unknown()]) if self.unknown() else np.zeros(0)
        return names, vals, ("angle", "angle", "length") * len(self.unknown())

    def sample_rows(self) -> np.ndarray:
        return np.arange(len(self))

    def gauge_params(self, robot: Robot) -> tuple[str, ...]:
        """Unknown planes only: a rigid motion of robot and planes together is unseen. A known plane
        sees the base's motion across it; what it does not see is dropped by the identifiability rule."""
        return () if self.known else robot.base_params()

    def sigma(self) -> np.ndarray:
        return np.array(np.broadcast_to(np.asarray(self.std, float), (len(self),)))

    def planes(self, nuis: np.ndarray) -> dict:
        """label -> (n, c, dn/da, dn/db) at the nuisance values (known planes: no derivatives)."""
        out = {lab: (np.asarray(n, float) / np.linalg.norm(n), float(c), None, None) for lab, (n, c) in self.known.items()}
        for k, lab in enumerate(self.unknown()):
            n0 = self.start[lab][0]
            u1 = np.cross(n0, np.eye(3)[np.argmin(np.abs(n0))])
            u1 /= np.linalg.norm(u1)
            u2 = np.cross(n0, u1)
            a, b, c = nuis[3 * k:3 * k + 3]
            m = n0 + a * u1 + b * u2
            nm = np.linalg.norm(m)
            n = m / nm
            proj = (np.eye(3) - np.outer(n, n)) / nm
            out[lab] = (n, float(c), proj @ u1, proj @ u2)
        return out

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        p, J = robot.forward_and_jacobian(self.q, values)
        planes, unknown = self.planes(nuis), {lab: k for k, lab in enumerate(self.unknown())}
        r, Jr, Jn = np.empty(len(self)), np.empty((len(self), J.shape[2])), np.zeros((len(self), nuis.size))
        for lab, (n, c, da, db) in planes.items():
            rows = self.labels == lab
            r[rows] = p[rows] @ n - c
            Jr[rows] = np.einsum("i,nip->np", n, J[rows])
            if lab in unknown:
                k = unknown[lab]
                Jn[rows, 3 * k], Jn[rows, 3 * k + 1], Jn[rows, 3 * k + 2] = p[rows] @ da, p[rows] @ db, -1.0
        return r, Jr, Jn

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        return error_stats(self, np.abs(self.evaluate(robot, values, nuis)[0]), planes=len(set(self.labels.tolist())))
