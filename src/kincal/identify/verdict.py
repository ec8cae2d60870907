"""Whether to believe a calibration: per-pose residuals, outliers by input row, and a verdict.

Every calibration gets a verdict, ``good``, ``suspect`` (warnings; the model is written) or
``refused`` (the model is not written unless forced), with reasons a user can act on. The thresholds
are a frozen :class:`Thresholds` value, documented here and overridable (``calibrate(thresholds=…)``,
CLI flags):

* implausible corrections (every estimated parameter except the base frame, which only says where
  the tracker stands, and the tool point, which says where the target is mounted): a length moving more than ``length_suspect`` (10 mm) is suspect, more than
  ``length_refuse`` (50 mm) is refused; an angle more than ``angle_suspect`` (2°) / ``angle_refuse``
  (10°). Real arms are off by fractions of a mm and a degree; corrections of tens of mm mean an input
  mistake, which the diagnosis names (:mod:`kincal.identify.diagnosis`);
* mounting: the tool point is where the user mounted the target, not a robot error; the fitted
  point is always reported against the declared one, a distance over ``tool_suspect`` (50 mm) is
  suspect (declare the real point) and over ``tool_refuse`` (1 m: no probe is that long) refused;
  never with unit advice;
* residual after the fit, σ per axis over the poses that are not outliers, against the tracker noise
  (``tracker_noise``, 0.05 mm): more than ``residual_suspect`` (10×) is suspect (errors the model
  cannot describe), more than ``residual_refuse`` (100×) is refused (data and model do not belong
  together);
* outliers: poses whose error norm lies more than ``outlier_z`` (5) robust σ above the median
  (σ = 1.4826·MAD) are named by input row, with the advice to use a robust loss or leave them out; the limit
  is raised where noise alone would pass it in more than one calibration in a hundred (:func:`noise_limit`: few
  or very many samples, residual blocks of fewer dimensions than a point's 3, such as a plane contact's 1);
* repeated poses (commanded joints within ``repeat_angle`` 1e-4 rad / ``repeat_length`` 0.01 mm: a
  robot's joint readings jitter around the same command) are named: they shrink the stated σ as if
  independent;
* drift: when the first tenth of the poses in acquisition (row) order carry errors 1.5× and 3
  standard errors above the rest, the tracker or the robot was still warming up;
* a measurement frame that jumps inside a file, whatever the residual (:func:`jump_reasons`: a rigid frame
  of its own from some row on, significant by the F test at 1 % over all rows, removing half the squared error
  and fitting better than a linear drift): named by row; with a fitted drift, instead of the drift; in every file
  of a kind that measures in a frame (points, 6-D poses with their rotations, markers);
* a fit that did not converge is refused.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from operator import le, sub
from typing import Mapping

import numpy as np

from .._csv import MAX_LISTED, listed
from ..models.parameters import SUSPECT
from ..models.robot import TOOL_NAMES, Robot
from ..models.unit_checks import Framed, frame_jump_test
from ..ties import first_best
from ..units import DEG, MM, MRAD, SHOWN, display, number
from .noise import decreasing_root

STATUSES = ("good", "suspect", "refused")
FALSE_ALARM = 0.01  # chance that pure noise names an outlier in one calibration (any number of samples)
SIMULATED_BELOW = 200  # samples below which the outlier limit is simulated; from here the asymptotic spread serves
DRAWS = 500_000  # error norms drawn to simulate one outlier limit (DRAWS // n sets of n)
_NODES, _WEIGHTS = np.polynomial.hermite_e.hermegauss(64)  # expectations over a standard normal
_WEIGHTS = _WEIGHTS / _WEIGHTS.sum()


def _chi_sf(x: float, dim: int) -> float:
    """P(‖e‖ > x) for e a ``dim``-D standard Gaussian (the χ distribution with ``dim`` degrees of freedom): the
    regularised upper incomplete gamma function Q(dim/2, x²/2), a finite sum for a whole ``dim``.

    >>> round(_chi_sf(1.0, 1), 6), round(_chi_sf(2.0, 2), 6), round(_chi_sf(1.5, 3), 6)  # erfc(1/√2), e⁻², χ₃
    (0.317311, 0.135335, 0.522167)
    """
    if x <= 0.0:
        return 1.0
    y, half = 0.5 * x * x, 0.5 * (dim % 2)
    head = math.erfc(math.sqrt(y)) if dim % 2 else 0.0
    return head + sum(math.exp(-y + (j + half) * math.log(y) - math.lgamma(j + half + 1.0)) for j in range(dim // 2))


def _chi_pdf(x: float, dim: int) -> float:
    """The density of ‖e‖ at x > 0 for e a ``dim``-D standard Gaussian."""
    return math.exp((dim - 1) * math.log(x) - 0.5 * x * x - (0.5 * dim - 1.0) * math.log(2.0) - math.lgamma(0.5 * dim))


@functools.lru_cache(maxsize=64)
def _chi_tables(dim: int) -> tuple[float, float, np.ndarray, np.ndarray]:
    """The median and the MAD of the χ distribution with ``dim`` degrees of freedom, and its log survival function
    on a grid (x, log P(‖e‖ > x)), which :func:`numpy.interp` reads at many points (its curvature is about 1: the
    grid's step of 0.005 keeps it to 3e-6)."""
    top = math.sqrt(dim) + 20.0
    med = decreasing_root(lambda x: _chi_sf(x, dim) - 0.5, 0.0, top)
    mad = decreasing_root(lambda d: 0.5 - (_chi_sf(max(med - d, 0.0), dim) - _chi_sf(med + d, dim)), 0.0, top)
    x = np.linspace(0.0, top, int(top / 0.005) + 1)
    return med, mad, x, np.log([max(_chi_sf(float(v), dim), 1e-300) for v in x])


def _simulated_limit(n: int, dim: int) -> float:
    """The limit of :func:`noise_limit` by simulation (seeded: the same in every run): ``DRAWS // n`` sets of n
    norms. Given a set's other norms its largest is χ-distributed above the second largest, and the median and the
    MAD scarcely depend on it, so each set adds the chance that it passes the limit (no count of rare events)."""
    sets = max(DRAWS // n, 1000)
    e = np.sqrt(np.random.default_rng(20240601).chisquare(dim, (sets, n)))
    med = np.median(e, axis=1)
    spread = 1.4826 * np.median(np.abs(e - med[:, None]), axis=1)
    second = np.partition(e, n - 2, axis=1)[:, n - 2]
    _, _, x, log_sf = _chi_tables(dim)
    below = np.interp(second, x, log_sf)

    def excess(limit: float) -> float:
        passed = np.interp(np.maximum(med + limit * spread, second), x, log_sf) - below
        return float(np.mean(np.exp(passed))) - FALSE_ALARM
    return decreasing_root(excess, 0.0, 1000.0, 1e-5)


def _asymptotic_limit(n: int, dim: int) -> float:
    """The limit of :func:`noise_limit` for many samples: the median and the MAD of n norms are normal about the
    distribution's (their Bahadur representations by the empirical distribution at median − MAD, median, median +
    MAD), and the chance that the largest norm passes ``median + limit·1.4826·MAD`` is averaged over that spread."""
    med, mad, x, log_sf = _chi_tables(dim)
    at = (med - mad, med, med + mad)
    p = np.array([1.0 - _chi_sf(v, dim) for v in at])
    f = [_chi_pdf(v, dim) for v in at]
    cov = (np.minimum.outer(p, p) - np.outer(p, p)) / n
    of_med = np.array([0.0, -1.0 / f[1], 0.0])  # δmedian and δMAD by δF at the three points
    of_mad = np.array([1.0, (f[2] - f[0]) / f[1], -1.0]) / (f[0] + f[2])

    def excess(limit: float) -> float:
        a = of_med + 1.4826 * limit * of_mad
        top = med + 1.4826 * limit * mad + math.sqrt(float(a @ cov @ a)) * _NODES
        sf = np.minimum(np.exp(np.interp(top, x, log_sf)), 1.0 - 1e-16)
        return float(_WEIGHTS @ -np.expm1(n * np.log1p(-sf))) - FALSE_ALARM
    return decreasing_root(excess, 0.0, 1000.0, 1e-5)


@functools.lru_cache(maxsize=256)
def noise_limit(n: int, dim: int = 3) -> float:
    """The robust z that noise alone passes in one calibration in a hundred (``FALSE_ALARM``).

    The largest of n error norms of pure Gaussian noise (each the norm of a ``dim``-D residual block of unit σ
    per row: a plane contact's 1, a point's 3, a pose's 6) lies ``limit`` robust σ ((e − median) / (1.4826·MAD),
    :func:`robust_z`, over the n norms themselves) above their median with probability ``FALSE_ALARM``. The
    median and the MAD of a few norms scatter, which raises the limit for few samples; the χ tail rises for many.
    Simulated (:func:`_simulated_limit`) below ``SIMULATED_BELOW`` samples, from the asymptotic spread of the
    median and the MAD above (:func:`_asymptotic_limit`; the two agree to 0.03 there).

    Parameters
    ----------
    n : int
        The number of samples judged together (a set's); 0 below 3 (no spread to judge by).
    dim : int, optional
        The dimension of each sample's residual block (default 3: a point).

    Returns
    -------
    float
        The limit, robust σ.

    Examples
    --------
    >>> from kincal.identify.verdict import noise_limit
    >>> [round(noise_limit(60, d), 1) for d in (1, 3, 6)]  # a plane contact's, a point's, a pose's
    [6.1, 5.0, 4.7]
    >>> round(noise_limit(10), 1), round(noise_limit(1000), 2), round(noise_limit(100_000), 2)
    (7.0, 5.27, 6.47)
    """
    n, dim = int(n), max(int(dim), 1)
    if n < 3:
        return 0.0
    return _simulated_limit(n, dim) if n < SIMULATED_BELOW else _asymptotic_limit(n, dim)


MAX_OUTLIER_SHARE = 0.1  # "a few bad poses": outliers are left out only up to this share of the poses

MIN_NOISE = 1e-9  # m: no instrument measures positions with less noise (an interferometer's ~1 nm)


@dataclass(frozen=True)
class Thresholds:
    """Verdict thresholds (SI units: m, rad; the residual ratios are to ``tracker_noise``).

    Every field must be a positive number and no ``*_suspect`` may exceed its ``*_refuse`` (ValueError).
    Corrections of the base frame (where the tracker stands) and of the tool point (where the target is
    mounted) are not judged by the length and angle limits.

    Parameters
    ----------
    length_suspect : float, optional
        A length correction beyond which a calibration is suspect, m (default 10e-3).
    length_refuse : float, optional
        A length correction beyond which it is refused, m (default 50e-3).
    angle_suspect : float, optional
        An angle correction beyond which it is suspect, rad (default 2°).
    angle_refuse : float, optional
        An angle correction beyond which it is refused, rad (default 10°).
    tracker_noise : float, optional
        The instrument's σ per axis when the data state none, m (default 0.05e-3).
    residual_suspect : float, optional
        Residual σ per axis over ``tracker_noise`` beyond which the fit is suspect: errors the model
        cannot describe (default 10).
    residual_refuse : float, optional
        The same ratio beyond which it is refused: data and model do not belong together (default 100).
    outlier_z : float, optional
        Robust σ (1.4826·MAD) above the median error norm beyond which a pose is an outlier, raised by
        :meth:`outlier_limit` where noise alone would pass it in more than one calibration in a hundred
        (default 5).
    tool_suspect : float, optional
        Distance of the fitted tool point from the declared one beyond which it is suspect, m (default
        50e-3).
    tool_refuse : float, optional
        The same beyond which it is refused, m (default 1.0: no probe is that long).
    repeat_angle : float, optional
        Commanded joint angles this close are the same pose (a repeat), rad (default 1e-4).
    repeat_length : float, optional
        The same for prismatic joints, m (default 1e-5).
    ratio_suspect : float, optional
        An actuator's scale this far off its nominal travel is suspect (default 0.02: 2 %).
    ratio_refuse : float, optional
        The same beyond which it is refused (default 0.2).
    mounting_suspect : float, optional
        A correction of a closed chain's design point beyond which it is suspect, m (default 50e-3).
    mounting_refuse : float, optional
        The same beyond which it is refused, m (default 0.5).

    Raises
    ------
    ValueError
        For a field that is not a positive number, or a suspect limit above its refuse limit.

    Examples
    --------
    >>> from kincal.identify import Thresholds
    >>> th = Thresholds(tracker_noise=20e-6)
    >>> th.tracker_noise, th.length_suspect, th.refuse("length")
    (2e-05, 0.01, 0.05)
    >>> th.outlier_limit(100), round(th.outlier_limit(100_000), 2)  # raised for many poses
    (5.0, 6.47)
    >>> round(th.outlier_limit(60, dim=1), 2)  # and for residuals of fewer dimensions (a plane contact's)
    6.13
    >>> Thresholds.of({"outlier_z": 4.0}).outlier_z
    4.0
    >>> Thresholds(length_suspect=0.1)
    Traceback (most recent call last):
    ...
    ValueError: thresholds: length_suspect must not exceed length_refuse
    """

    length_suspect: float = SUSPECT["length"]
    length_refuse: float = 50e-3
    angle_suspect: float = SUSPECT["angle"]
    angle_refuse: float = float(np.deg2rad(10.0))
    tracker_noise: float = 0.05e-3
    residual_suspect: float = 10.0
    residual_refuse: float = 100.0
    outlier_z: float = 5.0
    tool_suspect: float = 50e-3
    tool_refuse: float = 1.0
    repeat_angle: float = 1e-4  # rad: commanded joint angles this close are the same pose (a repeat)
    repeat_length: float = 1e-5  # m: the same for prismatic joints
    ratio_suspect: float = SUSPECT["ratio"]  # an actuator's scale this far off its nominal travel (2 %)
    ratio_refuse: float = 0.2
    mounting_suspect: float = SUSPECT["mounting"]  # m: a closed chain's design points, whose design frames are not
    # the measured ones
    mounting_refuse: float = 0.5

    def __post_init__(self) -> None:
        bad = [k for k, v in self.__dict__.items()
               if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not (np.isfinite(v) and v > 0)]
        if bad:
            raise ValueError(f"thresholds: {', '.join(bad)} must be positive numbers")
        if self.tracker_noise < MIN_NOISE:  # 1e-320 m passed as positive, and its whitened residuals overflowed
            raise ValueError(f"tracker_noise {self.tracker_noise:g} m: below any instrument's noise (an "
                             f"interferometer's is about {MIN_NOISE * 1e9:g} nm); give the tracker's with its unit, "
                             f"e.g. 0.015mm")
        for a, b in (("length_suspect", "length_refuse"), ("angle_suspect", "angle_refuse"),
                     ("residual_suspect", "residual_refuse"), ("tool_suspect", "tool_refuse"),
                     ("ratio_suspect", "ratio_refuse"), ("mounting_suspect", "mounting_refuse")):
            if self.__dict__[a] > self.__dict__[b]:
                raise ValueError(f"thresholds: {a} must not exceed {b}")

    def suspect(self, kind: str, mounting: bool = False) -> float:
        """The correction of a parameter of ``kind`` beyond which a calibration is suspect (m, rad or a
        ratio); ``mounting``: a closed chain's design point (:meth:`kincal.Robot.mounting_params`)."""
        return self.mounting_suspect if mounting else self.__dict__[f"{kind}_suspect"]

    def refuse(self, kind: str, mounting: bool = False) -> float:
        """The same beyond which it is refused."""
        return self.mounting_refuse if mounting else self.__dict__[f"{kind}_refuse"]

    def outlier_limit(self, n: int, dim: int = 3) -> float:
        """The robust z beyond which one of ``n`` error norms of ``dim``-D residual blocks (a plane contact's 1, a
        point's 3, a pose's 6) is an outlier: ``outlier_z``, raised where noise alone would pass it in more than
        one calibration in a hundred (:func:`noise_limit`): for points below about 60 and above about 250 (7.0 for
        10, 5.3 for 1000, 6.5 for 10⁵), for plane contacts always (6.1 for 60)."""
        return max(self.outlier_z, noise_limit(n, dim))

    @classmethod
    def of(cls, value) -> "Thresholds":
        """Thresholds from itself or a mapping of its fields (ValueError naming an unknown one)."""
        if isinstance(value, Thresholds):
            return value
        known = [f.name for f in dataclasses.fields(cls)]
        if not isinstance(value, Mapping) or set(value) - set(known):
            raise ValueError(f"thresholds {value!r}: a mapping of {', '.join(known)}")
        return cls(**value)

    def to_dict(self) -> dict:
        return {k: float(v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class Reason:
    """One finding of a verdict: its level, a short code and a message with what to do.

    Parameters
    ----------
    level : str
        ``"suspect"`` or ``"refused"``; ``"note"`` for what is said beside the reasons and sets no level (none of
        the common input mistakes explains the data better).
    code : str
        A short, stable code, e.g. ``"large-correction"``, ``"outliers"``, ``"drift"``.
    message : str
        What was found and what to do, in words.

    Examples
    --------
    >>> from kincal.identify import Reason
    >>> Reason("suspect", "drift", "the first 5 poses average 0.1 mm of error: warm-up?").level
    'suspect'
    """

    level: str
    code: str
    message: str


@dataclass(frozen=True)
class Verdict:
    """Whether to believe a calibration: good, suspect or refused, with the reasons.

    ``CalibrationResult.verdict``; :meth:`from_reasons` takes the worst level of its reasons.

    Parameters
    ----------
    status : str
        ``"good"``, ``"suspect"`` (warnings; the model is written) or ``"refused"`` (the model is not
        written unless forced).
    reasons : tuple of Reason, optional
        The findings, each with what to do (default none).

    Examples
    --------
    >>> from kincal.identify import Reason, Verdict
    >>> verdict = Verdict.from_reasons([Reason("suspect", "drift", "the first 5 poses average 0.1 mm of error")])
    >>> verdict.status
    'suspect'
    >>> print(verdict)
    verdict: SUSPECT
      suspect: the first 5 poses average 0.1 mm of error
    >>> Verdict.from_reasons([]).status
    'good'
    """

    status: str
    reasons: tuple[Reason, ...] = field(default=())

    @classmethod
    def from_reasons(cls, reasons) -> "Verdict":
        levels = {r.level for r in reasons}
        status = "refused" if "refused" in levels else "suspect" if reasons else "good"
        return cls(status, tuple(reasons))

    def to_dict(self) -> dict:
        return {"status": self.status, "reasons": [dataclasses.asdict(r) for r in self.reasons]}

    def __str__(self) -> str:
        return "\n".join([f"verdict: {self.status.upper()}", *(f"  {r.level}: {r.message}" for r in self.reasons)])


def robust_z(norms: np.ndarray) -> np.ndarray:
    """(N,) (e − median) / (1.4826·MAD) of error norms; 0 when the spread is nil."""
    med = float(np.median(norms))
    mad = 1.4826 * float(np.median(np.abs(norms - med)))
    return (norms - med) / mad if mad > 0 else np.zeros_like(norms)


def duplicate_groups(q: np.ndarray, tol: np.ndarray | float = 1e-9) -> list[np.ndarray]:
    """Indices of poses whose commanded joints agree within ``tol`` (per joint: rad or m, or one value
    for all), groups of ≥ 2 in row order. Each pose joins the first earlier group whose first pose it
    matches (every joint within tol), so the grouping never depends on rounding to a grid.

    ``q`` is (N, n) commanded joints (rad or m), ``tol`` (n,) or a scalar (the same units); returns the
    groups as int arrays of row indices, sorted by their first index. A NaN or infinite joint matches
    nothing (tol finite). O(N log N): a grid only says which poses to compare
    (:func:`_neighbour_cells`); the comparison itself is exact, in float64 as NumPy does it."""
    q = np.asarray(q, dtype=float)
    if len(q) < 2:
        return []
    tol = np.broadcast_to(np.asarray(tol, dtype=float), q.shape[1:])
    own, pose, cell = _neighbour_cells(q, tol)
    near = np.unique(pose)  # the other poses are alone: they lead groups of one
    rows, tols, cells = q[near].tolist(), tol.tolist(), cell.tolist()
    start = np.searchsorted(pose, near).tolist() + [len(pose)]
    leaders: dict[int, list[int]] = {}  # cell → the group leaders in it (positions in ``near``)
    first = []  # in row order: the earliest leader within tol in a cell it reaches, else itself
    for p, c_own in enumerate(own[near].tolist()):
        best = p
        for c in cells[start[p]:start[p + 1]]:
            for j in leaders.get(c, ()):
                if j < best and all(map(le, map(abs, map(sub, rows[j], rows[p])), tols)):  # |Δ| ≤ tol
                    best = j
        if best == p:
            leaders.setdefault(c_own, []).append(p)
        first.append(best)
    label = np.arange(len(q))
    label[near] = near[np.array(first, dtype=int)]
    grouped = np.flatnonzero(np.bincount(label, minlength=len(q))[label] > 1)
    order = grouped[np.argsort(label[grouped], kind="stable")]  # by first index, then row order
    return np.split(order, np.flatnonzero(np.diff(label[order])) + 1) if len(order) else []


def _neighbour_cells(q: np.ndarray, tol: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cells of a grid 8·tol wide per joint (hashed to uint64): each pose's own (N,), and as pairs
    (pose, cell) sorted by pose the occupied cells, its own included if shared, where a pose within
    tol of it can lie; a pose with no pair is within tol of no other.

    In units of the cell width a pose within tol is 1/8 away per joint (plus round-off below 2^-10
    where values are under 2^40; beyond, they are clipped together), so per joint at most one next
    cell, the one within 1/8 + 2^-10, can hold it. The hash is linear (neighbours by addition);
    a collision only merges cells, which adds poses to compare and never loses one."""
    n_pose, n = q.shape
    with np.errstate(all="ignore"):
        u = np.nan_to_num(np.clip(q / np.where(tol > 0, 8.0 * tol, 1.0) + 0.5, -2.0 ** 40, 2.0 ** 40))
    k, reach = np.floor(u), 0.125 + 2.0 ** -10
    step = ((np.floor(u + reach) - k) + (np.floor(u - reach) - k)).astype(np.int64)  # per joint -1, 0, +1
    mix = np.array(_odd_mixers(n), dtype=np.uint64)
    own = k.astype(np.int64).astype(np.uint64) @ mix
    pose, cell = np.arange(n_pose), own
    for j in np.flatnonzero(step.any(axis=0)):  # each cell so far, and its next one along joint j
        along = step[:, j][pose]
        s = np.flatnonzero(along)
        shift = along[s].astype(np.uint64) * mix[j]  # −mix[j] (mod 2^64) for a step of −1
        pose, cell = np.concatenate([pose, pose[s]]), np.concatenate([cell, cell[s] + shift])
    found, key = np.unique(np.concatenate([own, cell]), return_inverse=True)  # own cells first
    keep = np.bincount(key[:n_pose], minlength=len(found))[key[n_pose:]] > (cell == own[pose])  # others there
    order = np.argsort(pose[keep], kind="stable")
    return own, pose[keep][order], cell[keep][order]


def _odd_mixers(n: int) -> list[int]:
    """n fixed odd 64-bit multipliers (SplitMix64 outputs), for hashing integer cells."""
    out, x, m = [], 0, 2 ** 64 - 1
    for _ in range(n):
        x = (x + 0x9E3779B97F4A7C15) & m
        z = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & m
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & m
        out.append(z ^ (z >> 31) | 1)
    return out


def distinct_count(q: np.ndarray, tol: np.ndarray | float, most: int) -> int:
    """How many poses of ``q`` differ pairwise by more than ``tol`` in some joint, counted up to
    ``most``: the number of groups :func:`duplicate_groups` forms (singletons included), capped, in
    O(N·most) (each new pose is the first that matches none found so far, so it starts a group)."""
    found: list[int] = []
    apart = np.ones(len(q), bool)
    while len(found) < most and apart.any():
        k = int(np.argmax(apart))
        found.append(k)
        apart &= np.any(np.abs(q - q[k]) > tol, axis=1)
    return len(found)


def repeat_tolerance(joint_types, th: "Thresholds") -> np.ndarray:
    """Per joint, how close two commanded values count as the same pose (a repeated pose, ISO 9283)."""
    return np.array([th.repeat_angle if t == "revolute" else th.repeat_length for t in joint_types])


def _scale_hint(big: list[tuple[str, float]], kinds) -> str:
    """What a large correction of an actuator's scale says: its travel per unit in the robot file is off."""
    scales = [n.rsplit(".", 1)[0] for n, _ in big if kinds[n] == "ratio"]
    return (f"; {', '.join(scales)}: the travel per reading unit (a leg's lead) in the robot file is off by that "
            f"much, or the readings are in another unit" if scales else "")


LIMIT_KIND = {"mounting": "length"}  # a design point's limit is a length


def correction_reasons(robot: Robot, corrections: dict[str, float], th: Thresholds,
                       scales: Mapping[str, tuple[float, str]] | None = None) -> list[Reason]:
    """Implausibly large corrections (the base frame and the tool point, mounting results, excluded); a parameter
    with a scale in ``scales`` (:meth:`kincal.Robot.correction_scales` at the data's poses: a compliance, whose value
    is the deflection at 100 N·m) by the correction it makes there, correction × scale, shown with where."""
    base = set(robot.base_params()) | set(TOOL_NAMES)
    kinds = dict(zip(robot.params.names, robot.params.kinds))
    mounting, scales = set(robot.mounting_params()), scales or {}
    made = {n: c * scales.get(n, (1.0, ""))[0] for n, c in corrections.items()}  # the correction each makes
    for level, limit in (("refused", th.refuse), ("suspect", th.suspect)):
        lim = {n: limit(kinds[n], n in mounting) for n in corrections if n not in base}
        big = [(n, made[n]) for n in corrections if n in lim and abs(made[n]) > lim[n]]
        cause = robot.correction_hint(robot.with_params({n: robot.params[n] + c for n, c in corrections.items()})) \
            if big else ""
        level = "refused" if cause else level
        if big:
            shown = ", ".join(f"{n} {display(c, kinds[n], digits=(1, 2))}" + (f" {scales[n][1]}" if n in scales else "")
                              for n, c in sorted(big, key=lambda x: -abs(x[1] / lim[x[0]]))[:MAX_LISTED])
            used = {("mounting" if n in mounting else kinds[n]) for n in lim}
            limits = ", ".join(f"{limit(k, k == 'mounting') * SHOWN[LIMIT_KIND.get(k, k)][1]:g} "
                               f"{SHOWN[LIMIT_KIND.get(k, k)][0]}{' (design points)' if k == 'mounting' else ''}"
                               for k in ("length", "angle", "ratio", "mounting") if k in used)
            what = "implausible" if level == "refused" else "large"
            return [Reason(level, f"{what}-correction",
                           f"{what} corrections ({shown}; limits {limits}): the data and the robot file disagree by "
                           f"far more than a real robot's errors" + (cause or _scale_hint(big, kinds)))]
    return []


def mounting_line(declared: np.ndarray, fitted: np.ndarray) -> str:
    """Where the data put the target in the flange frame, against the declared tool point (m)."""
    mm = lambda v: "(" + ", ".join(number(x * MM, ".2f") for x in v) + ") mm"  # noqa: E731
    return (f"the data put the target at {mm(fitted)} in the flange frame (declared {mm(declared)}, "
            f"{np.linalg.norm(fitted - declared) * MM:.2f} mm apart)")


def undetermined_mounting_line(frame: str, held: tuple[str, ...]) -> str:
    """That the data do not determine the target's place in the flange frame: the tool point stands in a design
    frame (``frame``, in words) whose gauge freedom the fit holds at the parameters ``held``.

    Examples
    --------
    >>> line = undetermined_mounting_line("where the platform frame stands among the platform points", ("leg1.pz",))
    >>> line[:line.index(":")]
    "the target's place in the flange frame is not determined by these data"
    >>> line[line.index("held"):]
    'held here at leg1.pz: another choice moves the tool point, not a prediction)'
    """
    return (f"the target's place in the flange frame is not determined by these data: the tool point "
            f"({', '.join(TOOL_NAMES)}) trades with the design points it stands among ({frame} is a gauge freedom, "
            f"held here at {', '.join(held)}: another choice moves the tool point, not a prediction)")


def mounting_reasons(declared: np.ndarray, fitted: np.ndarray, th: Thresholds) -> list[Reason]:
    """The fitted tool point against the declared one: a mounting result, with its own limits."""
    gap, line = float(np.linalg.norm(fitted - declared)), mounting_line(declared, fitted)
    tool = ",".join(f"{x * MM:.2f}" for x in fitted)
    turned = _turned(declared, fitted)
    if turned and gap <= th.tool_suspect:  # as far out, another way: the frame the tool was declared in
        return [Reason("suspect", "tool-point", f"{line}: as far from the flange as declared but turned {turned:.0f}° "
                                                f"from it: the tip link's frame is turned from the one the tool was "
                                                f"declared in; check --tip-link, or declare the tool in that link's "
                                                f"axes (--tool {tool}mm)")]
    return _graded("tool-point", gap, (th.tool_refuse, th.tool_suspect), (
        f"{line}: no probe or reflector is mounted {gap:.2f} m from its declared place; check that the data belong "
        f"to this robot (joint columns, robot file)",
        f"{line}: if the target is mounted there, declare it (--tool {tool}mm) so that the tool point is known and "
        f"the commands use it; otherwise check the probe and its adapter"))


TURNED_LENGTH = 0.1  # the fitted tool point's distance from the flange within this share of the declared one ...
TURNED_ANGLE = 30.0  # deg ... but its direction turned more than this: declared in another link's axes
TURNED_MIN = 10e-3  # m: a point this close to the flange has no direction to speak of


def _turned(declared: np.ndarray, fitted: np.ndarray) -> float:
    """The angle (deg) between the declared and fitted tool points when they are as far from the flange within
    TURNED_LENGTH but point more than TURNED_ANGLE apart (a tool declared in another frame's axes); else 0."""
    a, b = float(np.linalg.norm(declared)), float(np.linalg.norm(fitted))
    if min(a, b) < TURNED_MIN or abs(a - b) > TURNED_LENGTH * a:
        return 0.0
    angle = float(np.degrees(np.arccos(np.clip(declared @ fitted / (a * b), -1.0, 1.0))))
    return angle if angle > TURNED_ANGLE else 0.0


def _graded(code: str, value: float, limits: tuple[float, float], messages: tuple[str, str]) -> list[Reason]:
    """A refused reason (messages[0]) when ``value`` exceeds limits[0], else a suspect one beyond limits[1]."""
    return [Reason(level, code, m) for level, limit, m in zip(("refused", "suspect"), limits, messages)
            if value > limit][:1]


def noise_level(std: np.ndarray | None, th: Thresholds) -> tuple[float, str]:
    """The instrument noise a residual is judged against (m), and where it comes from: the median of
    the data's per-sample σ (N, 3) when given, else the thresholds' tracker_noise."""
    if std is not None:
        return float(np.median(std)), "median of the data's measurement σ columns"
    if th.tracker_noise != Thresholds().tracker_noise:
        return th.tracker_noise, "as stated (--tracker-noise)"
    return th.tracker_noise, "the default; give --tracker-noise or measurement_std_x/y/z columns"


def residual_reasons(sigma: float, noise: tuple[float, str], th: Thresholds, left_out: int = 0) -> list[Reason]:
    """The fit's σ per axis against the instrument noise (value in m, and where it comes from); ``left_out``: the
    outlier poses the σ leaves out, which the message names (a σ of all poses elsewhere differs from it)."""
    ratio = sigma / noise[0]
    without = f" (without the {left_out} outlier pose{'s' if left_out > 1 else ''})" if left_out else ""
    msg = (f"residual σ per axis {sigma * MM:.3f} mm{without} is {ratio:.0f}x the tracker noise "
           f"({noise[0] * MM:.3g} mm: {noise[1]})")
    return _graded("residual", ratio, (th.residual_refuse, th.residual_suspect), (
        msg + ": data and model do not belong together",
        msg + ": the model leaves errors it cannot describe (non-geometric errors, a moved tracker, bad poses); look "
              "at the per-pose residuals"))


def outlier_reasons(rows: np.ndarray, z: np.ndarray, th: Thresholds, loss: str = "linear",
                    source: str | None = None) -> list[Reason]:
    """Poses more than ``outlier_z`` robust σ off, named by row (of the file ``source``, one of several), with what
    to do (given the loss used)."""
    limit = th.outlier_limit(len(z))
    bad = rows[z > limit]
    if bad.size == 0:
        return []
    exclude = f"--exclude {','.join(map(str, bad[:MAX_LISTED]))}" if source is None else "leave them out of their file"
    todo = (f"the {loss} loss already down-weights them; --reject-outliers leaves them out (or {exclude})"
            if loss != "linear" else f"use --reject-outliers (or {exclude}), or --loss huber")
    head = "" if source is None else f"{source}: "
    return [Reason("suspect", "outliers", f"{head}outlier pose(s) more than {limit:.3g} robust σ off: row(s) "
                                          f"{listed(bad)}; {todo}")]


def fitted_drift_reasons(drift: dict | None, noise: float, xyz: np.ndarray | None = None) -> list[Reason]:
    """A drift term (``{axis: {value, std}}``, m) that found a real drift: larger than 2× the instrument
    noise and 3 standard errors. The fit absorbs it in these data only; the set-up was not settled. When the
    measured positions ``xyz`` (N, 3) m, in acquisition order, follow that order along an axis (correlation
    at least ``ORDER_CORRELATION``), a drift cannot be told from an error that grows along that axis: said."""
    if not drift:
        return []
    d = np.array([drift[a]["value"] for a in drift])
    sd = np.array([drift[a]["std"] for a in drift])
    if not (np.linalg.norm(d) > DRIFT_NOISE * noise and np.any(np.abs(d) > DRIFT_Z * sd)):
        return []
    shown = ", ".join(f"{a} {drift[a]['value'] * MM:+.3f} mm" for a in drift)
    text = (f"the measurement frame drifted by {np.linalg.norm(d) * MM:.3f} mm over the session ({shown}): the drift "
            f"term absorbs it in these data only; let the tracker and robot warm up, check the tracker's stand, and "
            f"measure again (or repeat a reference pose to track the drift)")
    order = _order_axis(xyz)
    if order:
        axis, r = order
        text += (f"; but the rows were measured in an order that follows the position along {axis} (correlation "
                 f"{r:+.2f}), so a drift cannot be told from an error that grows along {axis} (one the model lacks): "
                 f"measure in a shuffled order, or repeat a reference pose, to tell them apart")
    return [Reason("suspect", "drift-fitted", text)]


def jump_reasons(rows: np.ndarray, framed: Framed, n_params: int = 0, drift: bool = False,
                 source: str | None = None) -> list[Reason]:
    """A measurement frame that jumps inside one file (of the file ``source``, one of several): what a change of the
    frame moves (:class:`kincal.models.unit_checks.Framed`: the positions, and a 6-D pose's rotations, against the
    fitted model's), in row order (``rows``, their line numbers), judged by
    :func:`kincal.models.unit_checks.frame_jump_test` (``n_params`` kinematic and set-up parameters fitted to them),
    named by the row where the second frame starts with the RMS before and after a frame per part and the linear
    drift's; with ``drift`` (a drift term fitted) the step is named instead of the drift."""
    order = np.argsort(rows, kind="stable")
    jump = frame_jump_test(framed.subset(order), n_params=n_params)
    if jump is None:
        return []
    row, turns = int(rows[order][jump.index]), jump.turns or (None, None, None)
    head = "" if source is None else f"{source}: "
    versus = (f"a step, not a drift: the fitted linear drift leaves {_misses(jump.drift, turns[2])}" if drift else
              f"a linear drift over the rows would leave {_misses(jump.drift, turns[2])}")
    return [Reason("suspect", "frame-jump", f"{head}the measurement frame jumps at row {row}: the "
                                            f"{'poses' if jump.turns else 'positions'} fit the calibrated model to "
                                            f"{_misses(jump.one, turns[0])} RMS in one frame, to "
                                            f"{_misses(jump.two, turns[1])} with one frame for the rows before it and "
                                            f"one from it on ({versus}): two set-ups in one file, or the tracker or "
                                            f"camera was moved or bumped there; split the file at row {row}: one file "
                                            f"per session (each gets its own frame)")]


def _misses(distance: float, angle: float | None) -> str:
    """An RMS distance (m) in mm, and an RMS angle (rad) in mrad where rotations were measured."""
    return f"{distance * MM:.3g} mm" + ("" if angle is None else f", {angle * MRAD:.3g} mrad")


ORDER_CORRELATION = 0.9  # |r| of row order against a position axis beyond which a drift is a position effect too


def _order_axis(xyz: np.ndarray | None) -> tuple[str, float] | None:
    """The position axis (x, y or z) the acquisition order follows most, with the correlation, when it reaches
    ``ORDER_CORRELATION``; None otherwise (or without positions)."""
    if xyz is None or len(xyz) < 3:
        return None
    t = np.arange(len(xyz), dtype=float)
    spread = xyz.std(axis=0)
    r = np.array([np.corrcoef(t, xyz[:, k])[0, 1] if spread[k] > 0 else 0.0 for k in range(3)])
    k = first_best(np.abs(r))  # a tie: the first axis (x before y before z)
    return ("xyz"[k], float(r[k])) if abs(r[k]) >= ORDER_CORRELATION else None


def duplicate_reasons(rows: np.ndarray, groups, source: str | None = None, files: np.ndarray | None = None,
                      xyz: np.ndarray | None = None) -> list[Reason]:
    """Repeated poses (groups of indices, see :func:`duplicate_groups`), named by input row (of the
    observation set from ``source``, when given); poses from several files (``files``: each pose's file, (N,))
    named by file and row, led by the files that repeat another's poses one for one (:func:`_copied_files`;
    ``xyz`` (N, 3) m: with the same positions too, the same rows)."""
    if not groups:
        return []
    labels = files if files is not None and len(set(files)) > 1 else None
    shown = "; ".join(", ".join(f"{f} row{'s' * (k.size > 1)} {listed(rows[k])}" for f in dict.fromkeys(labels[g])
                                if (k := np.asarray(g)[labels[g] == f]).size) if labels is not None
                      else f"rows {listed(rows[g])}" for g in groups[:5])
    head, what, look = ("", "rows", "") if source is None else (f"{source}: ", "samples", " look")
    copies = _copied_files(groups, labels, xyz) if labels is not None else ""
    return [Reason("suspect", "repeated-poses",
                   f"{head}{copies}{sum(len(g) for g in groups)} {what} repeat the same joint values ({shown}): "
                   f"repeated poses count as independent and make the stated σ{look} too small; average them or "
                   f"leave the copies out" + ("; give each file once" if copies else ""))]


def _copied_files(groups, files: np.ndarray, xyz: np.ndarray | None) -> str:
    """'B.csv holds the same rows as A.csv: ' for each file whose poses pair one for one with an earlier file's in
    the repeat groups (the same joint values; with ``xyz``, the same positions to 1 µm too: else 'repeats the poses
    of'); '' when none does."""
    order = list(dict.fromkeys(files))
    pairs: dict[tuple, list] = {}  # (earlier file, later file) -> their paired indices
    for g in groups:
        g = np.asarray(g)
        if len(g) == 2 and files[g[0]] != files[g[1]]:
            a, b = sorted(g, key=lambda k: order.index(files[k]))
            pairs.setdefault((files[a], files[b]), []).append((a, b))
    said = []
    for (a, b), paired in pairs.items():
        if len(paired) == int(np.sum(files == a)) == int(np.sum(files == b)):
            i, j = np.array(paired).T
            same = xyz is not None and float(np.abs(xyz[i] - xyz[j]).max()) < 1e-6
            said.append(f"{b} {'holds the same rows as' if same else 'repeats the poses of'} {a}")
    return "; ".join(said) + ": " if said else ""


DRIFT_RATIO, DRIFT_Z, DRIFT_MIN_POSES, DRIFT_NOISE = 1.5, 3.0, 50, 2.0


def drift_reasons(rows: np.ndarray, norms: np.ndarray, source: str | None = None) -> list[Reason]:
    """Warm-up drift: the first tenth of the poses by input row (of the file ``source``, one of several) against
    the rest."""
    if len(rows) < DRIFT_MIN_POSES:
        return []
    order = np.argsort(rows, kind="stable")
    k = max(5, len(rows) // 10)
    first, rest = norms[order[:k]], norms[order[k:]]
    if first.mean() > DRIFT_RATIO * rest.mean() and first.mean() > rest.mean() + DRIFT_Z * rest.std(ddof=1) / np.sqrt(k):
        a, b = rows[order[0]], rows[order[k - 1]]
        head, out = ("", f"--exclude {a}-{b}") if source is None else (f"{source}: ", "of their file")
        return [Reason("suspect", "drift", f"{head}the first {k} poses (rows {a}-{b}) average {first.mean() * MM:.3f} "
                                           f"mm of error against {rest.mean() * MM:.3f} mm for the rest: tracker or "
                                           f"robot warm-up? leave them out ({out}) and check the set-up")]
    return []
