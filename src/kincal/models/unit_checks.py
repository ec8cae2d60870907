"""Whether measured data are in the units they were declared in: degrees read as radians, and the
measured spread of positions against the robot's own at the same joints (which names the unit the
numbers are really in). Used by every reader of joint values and by the measurement checks."""
from __future__ import annotations

from contextlib import suppress
import dataclasses
from dataclasses import dataclass

import numpy as np

from ..errors import MeasurementError, ModelError
from .plausible import MAX_TOOL
from .robot import Robot
from .transforms import kabsch, rotvec_matrix
from ..ties import first_best
from .._stats import f_sf, spread
from ..units import ANGLE_UNITS, LENGTH_UNITS, OTHER_LENGTHS, joint_units

MIN_SPREAD = 1e-3  # m: below this the poses barely move the tool, and noise decides the spread
SPREAD_RATIO = 2.0  # measured vs predicted spread at the same poses; model errors change it by < 1 %
JUMP_RATIO = 0.25  # two frames leave less than this share of one frame's RMS: the frame jumps inside the file
MIN_PART = 10  # poses on either side of a frame jump (fewer fit any frame)
JUMP_ALARM = 0.01  # chance that noise alone passes frame_jump_test's F test, over all its splits (Bonferroni)
JUMP_SHARE = 0.5  # ... and the share of one frame's squared error a frame per part must remove at least: a model's own
# errors, shared by neighbouring rows, pass the F test, but a frame of their own absorbs at most 28 % of them in the
# real UR5 and WAM files (windows of 60 to 1000 rows), at most 31 % of simulated noise (20 poses)
DRIFT_ROUNDS = 20  # alternations of the frame and the linear drift in frame_jump_test's drift fit


def check_spread(source: str, q: np.ndarray, xyz: np.ndarray, robot: Robot, length_unit: str | None,
                 angle_unit: str | None, what: str = "measured positions", rows: np.ndarray | None = None) -> None:
    """Refuse measured positions whose spread is not the robot's at the same joints: a unit mistake, named.

    The RMS distance of ``xyz`` from its centroid is compared with that of the robot's tool point at the
    joints ``q``; when they differ by more than ``SPREAD_RATIO`` (2x; model errors change it by < 1 %), the
    cause is named: the joint values read in the other angle unit first, then a frame that jumps inside the
    file (at its row of ``rows``), then the unit the positions are really in. Where the robot's own spread is
    below ``MIN_SPREAD`` (1 mm: noise decides the spread) only the first two are looked for; where the robot does
    not even assemble at the joints (a closed chain) the joint values are judged against their limits instead
    (:func:`check_limits`, which names the unit that puts them within).

    Parameters
    ----------
    source : str
        Where the data come from (a file's path), named in the message.
    q : ndarray, shape (N, n)
        Joint values as read, rad (m for a prismatic joint).
    xyz : ndarray, shape (N, 3)
        Measured positions as read, m.
    robot : Robot
        The robot the data belong to.
    length_unit : str or None
        The length unit the positions were read in (None: "m"), to name the one they are really in.
    angle_unit : str or None
        The angle unit the joint values were read in (None: unknown; the other angle units are then not tried).
    what : str, optional
        What the positions are, for the message (default "measured positions").
    rows : ndarray of int, shape (N,), optional
        The 1-based line numbers of the samples, header = line 1 (default None: 2, 3, …).

    Raises
    ------
    MeasurementError
        When the spreads differ: with the angle unit that makes them agree, the row where the measurement frame
        jumps, or the length unit that explains the factor (or that none does).

    See Also
    --------
    check_degrees : Degrees read as radians, from the joint values alone.

    Examples
    --------
    >>> import kincal
    >>> from kincal.io import check_spread
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(12, seed=1), seed=0)
    >>> check_spread("ur5.csv", meas.q, meas.xyz, robot, "m", "rad")  # as measured: nothing to say

    Millimetres read as metres:

    >>> check_spread("ur5.csv", meas.q, meas.xyz * 1e3, robot, "m", "rad")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: ur5.csv: measured positions spread 1e+03x more than the robot moves at the same
    joint values (read as 'm'): they look like mm; use length unit 'mm' (CLI: --length-unit mm)
    """
    assembles = True
    try:
        predicted = spread(robot.forward(q))
    except ModelError:  # a closed chain that does not assemble at these joints: another angle unit, or the joints'
        predicted, assembles = 0.0, False  # own checks name why
    ratio = spread(xyz) / max(predicted, 1e-300)
    if predicted > MIN_SPREAD and 1 / SPREAD_RATIO < ratio < SPREAD_RATIO:
        return
    tool = tool_explains(q, xyz, robot) if assembles and predicted > MIN_SPREAD else None
    if tool is not None:
        raise MeasurementError(
            f"{source}: {what} spread {ratio:.3g}x the robot's at the same joint values with the declared tool point "
            f"({_mm(robot.tool_point())} mm), but with the tool point fitted they agree to {tool[1] * 1e3:.3g} mm RMS: "
            f"not a unit, the tool point: declare it (--tool {_mm(tool[0], ',')}mm)")
    other = _other_reading(q, xyz, robot, length_unit, angle_unit)
    if other is not None:
        how = (f"do not even assemble the robot ({robot.name})" if not assembles else
               f"move the robot {max(ratio, 1 / ratio):.3g}x {'less' if ratio > 1 else 'more'} than the {what} spread")
        raise MeasurementError(f"{source}: read as {ANGLE_WORDS[str(angle_unit)]}, the joint values {how}, {other}")
    if not assembles:  # the joint values' own check: far outside the limits, in the unit that puts them within
        check_limits(source, q, robot, length_unit, angle_unit, tried=True)
        return
    jump = frame_jump(xyz, robot.forward(q))
    if jump is not None:
        k, one, two = jump
        row = int(rows[k]) if rows is not None else k + 2  # default: the data rows after a header line
        raise MeasurementError(f"{source}: the measurement frame jumps at row {row}: the rows before it and those from "
                               f"it on each fit the robot in a frame of their own (RMS {two * 1e3:.3g} mm against "
                               f"{one * 1e3:.3g} mm in one frame): two set-ups in one file, or the tracker was moved "
                               f"or bumped there; give one file per session (each gets its own frame)")
    if predicted > MIN_SPREAD:
        setups = frame_groups(xyz, robot.forward(q)) if not _unit_of(ratio, length_unit) else None
        if setups is not None:
            raise MeasurementError(f"{source}: {what} spread {_times(ratio)} than the robot moves at the same joint "
                                   f"values, but no length unit explains that and the rows fall into {len(setups[0])} "
                                   f"groups that each fit the robot in a frame of their own (RMS {setups[1] * 1e3:.3g} "
                                   f"mm; {_groups_text(setups[0], rows)}): measurements from {len(setups[0])} tracker "
                                   f"set-ups in one file; give one file per set-up (each gets its own frame)")
        lead = lead_factor(q, xyz, robot) if not _unit_of(ratio, length_unit) else None
        if lead is not None:
            raise MeasurementError(f"{source}: {what} spread {_times(ratio)} than the robot moves at the same joint "
                                   f"values, and as far with the travel per reading of every joint driven through a "
                                   f"lead {lead:.3g}x the robot file's ({_leads(robot, angle_unit, lead)}): the robot "
                                   f"file's leads look {lead:.3g}x too {'small' if lead > 1 else 'large'}; check them "
                                   f"(each joint's lead: travel per reading unit)")
        raise MeasurementError(f"{source}: {unit_hint(ratio, length_unit, what)}")


ANGLE_WORDS = {"rad": "radians", "deg": "degrees", "rev": "revolutions"}
GROUP_TOL = 0.02  # share of the robot's spread: a row this near a group's rigid frame belongs to that group
GROUP_TRIES = 200  # random 3-row frames tried per group (two equal groups: 3 rows of one group in 1 try of 4)
GROUP_MOST = 4  # set-ups looked for in one file at most
GROUP_COVER = 0.95  # ... and the share of the rows they must hold together


def frame_groups(xyz: np.ndarray, model: np.ndarray, min_part: int = MIN_PART) -> tuple[list, float] | None:
    """The rows of the positions ``xyz`` (N, 3) m that fall into 2 to GROUP_MOST groups, each fitting the model's
    positions ``model`` (N, 3) m in a rigid frame of its own within GROUP_TOL of the model's spread, together
    GROUP_COVER of the rows at least, MIN_PART rows each (several tracker set-ups in one file, in any order): the
    groups' indices (largest first) and the RMS (m) left with a frame per group; None otherwise. The largest group
    is found first (the most rows within reach of a frame through 3 random rows, seeded: the same answer each
    run; ties: the first), then the largest among the rows left, and so on."""
    n, tol, rng = len(xyz), GROUP_TOL * spread(model), np.random.default_rng(0)
    left, sse = np.arange(n), 0.0
    groups: list[np.ndarray] = []

    def near(R: np.ndarray, t: np.ndarray, at: np.ndarray) -> np.ndarray:
        return np.linalg.norm(model[at] @ R.T + t - xyz[at], axis=1)
    while len(left) >= min_part and len(groups) < GROUP_MOST:
        tries = [left[near(*kabsch(model[k], xyz[k]), left) < tol]
                 for k in (rng.choice(left, 3, replace=False) for _ in range(GROUP_TRIES))]
        best = tries[first_best(np.array([len(g) for g in tries]), maximize=True)]
        if len(best) < 3:
            break
        frame = kabsch(model[best], xyz[best])  # refitted on its rows, which it then gathers again
        best = left[near(*frame, left) < tol]
        if len(best) < min_part:
            break
        groups.append(best)
        sse += float(np.sum(near(*kabsch(model[best], xyz[best]), best) ** 2))
        left = np.setdiff1d(left, best)
    if len(groups) < 2 or n - len(left) < GROUP_COVER * n:
        return None
    return groups, float(np.sqrt(sse / (n - len(left))))


def _groups_text(groups: list, rows: np.ndarray | None) -> str:
    """'500 rows: 2-251, 752-1001; 500 rows: 252-751': each group's size and its first runs of rows (1-based line
    numbers of ``rows``, default 2, 3, ...)."""
    out = []
    for g in groups:
        at = np.asarray(rows)[g] if rows is not None else g + 2
        cut = np.flatnonzero(np.diff(at) != 1) + 1
        runs = [f"{r[0]}" if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in np.split(at, cut)]
        out.append(f"{len(g)} rows: {', '.join(runs[:3])}{', …' if len(runs) > 3 else ''}")
    return "; ".join(out)


TOOL_ROUNDS = 50  # Gauss-Newton steps at most of the frame and the tool point in tool_explains
TOOL_FITS = 0.01  # a fitted tool point that brings the RMS miss below this share of the spread explains it
TOOL_MAX = MAX_TOOL  # m: ... and lies this near the flange at most (a tool, not a lever; robot files' bound)
TOOL_SPREAD = 0.01  # m: ... and the robot moves it this far at least (not a point where its axes meet)


def _mm(p: np.ndarray, sep: str = ", ") -> str:
    return sep.join(f"{v * 1e3:.1f}" for v in p)


def tool_explains(q: np.ndarray, xyz: np.ndarray, robot: Robot) -> tuple[np.ndarray, float] | None:
    """The tool point (3,) m, flange frame, and the RMS miss, m, with which the robot fits the positions ``xyz`` (N, 3)
    at the joints ``q`` (N, n) rigidly (frame and tool point fitted, alternately: Kabsch for the frame, linear least
    squares for the point), when that miss is below TOOL_FITS of the positions' spread and the point within TOOL_MAX
    of the flange, moved TOOL_SPREAD at least: then a spread unlike the robot's is a tool point declared wrong, not a
    unit; else None (also for a robot without a tool point on a flange)."""
    if not robot.has_tool_point or len(q) < 4:
        return None
    try:
        p_f, R_f, _, _ = robot.with_tool_point(np.zeros(3)).pose_and_jacobian(q)
    except ModelError:
        return None
    t = robot.tool_point()
    R, b = kabsch(p_f + np.einsum("nij,j->ni", R_f, t), xyz)
    for _ in range(TOOL_ROUNDS):  # Gauss-Newton on the frame's turn, its origin and the point, from Kabsch's frame
        world = (p_f + np.einsum("nij,j->ni", R_f, t)) @ R.T
        r = (world + b - xyz).reshape(-1)
        J = np.concatenate([-skew_rows(world), np.tile(np.eye(3), (len(q), 1, 1)),
                            np.einsum("ij,njk->nik", R, R_f)], axis=2).reshape(-1, 9)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        R, b, t = rotvec_matrix(step[:3]) @ R, b + step[3:6], t + step[6:]
        if np.abs(step).max() < 1e-12:
            break
    moved = p_f + np.einsum("nij,j->ni", R_f, t)
    miss = float(np.sqrt(np.mean(np.sum((moved @ R.T + b - xyz) ** 2, axis=1))))
    fits = miss < TOOL_FITS * spread(xyz) and np.linalg.norm(t) < TOOL_MAX and spread(moved) > TOOL_SPREAD
    return (t, miss) if fits else None  # a point the robot hardly moves (where its axes meet) explains nothing


def skew_rows(v: np.ndarray) -> np.ndarray:
    """(N, 3, 3): the cross-product matrix [vᵢ]× of each row of v (N, 3)."""
    z = np.zeros(len(v))
    return np.stack([np.stack([z, -v[:, 2], v[:, 1]], 1), np.stack([v[:, 2], z, -v[:, 0]], 1),
                     np.stack([-v[:, 1], v[:, 0], z], 1)], 1)


def _other_reading(q: np.ndarray, xyz: np.ndarray, robot: Robot, length_unit: str | None,
                   angle_unit: str | None) -> str | None:
    """What to say ("read as … they match: …") of the first other reading of the joint values as written
    (:func:`_readings`) that makes the robot move as far as the measured positions xyz, when the declared
    ``angle_unit`` does not; None if none does."""
    for read, said in _readings(q, robot, length_unit, angle_unit):
        if not robot.within_limits(read).mean() > 0.5:  # most joints beyond their limits: not this reading
            continue
        with suppress(ModelError):  # joints no configuration of the robot has: not this reading
            moved = spread(robot.forward(read))
            if 1 / SPREAD_RATIO < spread(xyz) / max(moved, 1e-300) < SPREAD_RATIO:
                return said
    return None


def _readings(q: np.ndarray, robot: Robot, length_unit: str | None, angle_unit: str | None):
    """(joint values (N, n) rad or m, what to say where they fit) of each other reading of the revolute joints'
    numbers as written in ``angle_unit``: the other angle units (in ``ANGLE_UNITS``' order), then, for joints a motor
    drives through a lead (``robot.motor_leads``), lengths (the declared ``length_unit`` first) turned into motor
    angles by the lead: a leg's travel in mm given where its motor's revolutions are read."""
    rev = robot.revolute
    if angle_unit not in ANGLE_UNITS or not rev.any():
        return
    for unit, factor in ANGLE_UNITS.items():
        if unit != angle_unit:
            yield (np.where(rev, q * (factor / ANGLE_UNITS[angle_unit]), q),
                   f"read as {ANGLE_WORDS[unit]} they match: use angle unit '{unit}' (CLI: --angle-unit {unit})")
    lead = robot.motor_leads
    driven = rev & np.isfinite(lead) & (lead != 0)
    for unit in sorted(LENGTH_UNITS, key=lambda u: u != (length_unit or "m")) if driven.any() else ():
        yield (np.where(driven, q / ANGLE_UNITS[angle_unit] * LENGTH_UNITS[unit] / np.where(driven, lead, 1.0), q),
               f"read as {unit} of travel through each one's lead ({_leads(robot, angle_unit, 1.0, unit)}) they "
               f"match: {as_travel(unit, angle_unit)}")


def as_travel(length_unit: str, angle_unit: str) -> str:
    """The advice for the readings of motors driving screws given as the lengths they drive (in ``length_unit``)."""
    return (f"they look like lengths in {length_unit}: give them in {angle_unit} (the travel divided by the lead), "
            f"or describe the joints as read in lengths in the robot file (a hexapod's legs: no 'reading', no 'lead')")


def _leads(robot: Robot, angle_unit: str | None, factor: float = 1.0, length_unit: str = "mm") -> str:
    """Each lead joint's lead times ``factor``, in ``length_unit`` per ``angle_unit`` (rev when not an angle unit)."""
    per = angle_unit if angle_unit in ANGLE_UNITS else "rev"
    lead = robot.motor_leads * factor * ANGLE_UNITS[per] / LENGTH_UNITS[length_unit]
    shown = [f"{n} {v:.4g}" for n, v in zip(robot.joint_names, lead) if np.isfinite(v)]
    return f"{', '.join(shown)} {length_unit}/{per}"


LEAD_ROUNDS = 30  # fixed-point steps at most of lead_factor
LEAD_AGREES = 1e-3  # ... which ends where the spreads agree to this share


def lead_factor(q: np.ndarray, xyz: np.ndarray, robot: Robot) -> float | None:
    """The factor on the travel per reading of every joint a motor drives through a lead (``robot.motor_leads``)
    with which the robot moves as far as the measured positions spread: a lead in the robot file that is not the
    robot's (scaling the lead scales the travel the readings drive). Found by a fixed point on the spreads' ratio
    (the spread grows about as the travel does); None without such joints, or where no factor in 1e-3..1e3 makes
    the robot assemble and the spreads agree to ``LEAD_AGREES``.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values as read, rad (m for a prismatic joint).
    xyz : ndarray, shape (N, 3)
        Measured positions, m.
    robot : Robot
        The robot (its leads).

    Returns
    -------
    float or None
        The factor (the true leads are the file's times it).

    Examples
    --------
    The hexapod's legs read through leads 10 % shorter than its own:

    >>> import kincal
    >>> from kincal.models.unit_checks import lead_factor
    >>> robot = kincal.load_robot("hexapod")
    >>> q = robot.sample_joints(30, seed=1)
    >>> round(lead_factor(q * 0.9, robot.forward(q), robot), 2)  # 1 / 0.9
    1.11
    """
    driven = robot.revolute & np.isfinite(robot.motor_leads)
    if not driven.any():
        return None
    s, target = 1.0, spread(xyz)
    for _ in range(LEAD_ROUNDS):
        try:
            ratio = target / max(spread(robot.forward(np.where(driven, q * s, q))), 1e-300)
        except ModelError:  # the legs do not assemble so: no lead explains the spread
            return None
        if abs(ratio - 1.0) < LEAD_AGREES:
            return s
        s *= ratio
        if not 1e-3 < s < 1e3:
            return None
    return None


@dataclass(frozen=True)
class Framed:
    """What a rigid change of the measurement frame moves, sample by sample in row order: the measured points and the
    fitted model's at the same poses, which its shift and its turn move, and, where rotations were measured, each
    one's axes and the model's, which its turn alone moves. Build it with :meth:`of`.

    Parameters
    ----------
    xyz : ndarray, shape (N, m, 3)
        Measured points (m points per sample: a tool point, or markers), m; NaN where a point was not seen.
    model : ndarray, shape (N, m, 3)
        The model's points at the same poses, m.
    axes : ndarray, shape (N, d, 3)
        The measured rotations' axes (d = 3; d = 0 without rotations), each times the sample's ``lever``, m.
    model_axes : ndarray, shape (N, d, 3)
        The model's, as ``axes``, m.
    lever : ndarray, shape (N,)
        m per rad: σ_pos / (√2 σ_rot), so that a turn of the rotations' σ weighs as a move of the positions' σ
        (‖R₁ − R₂‖_F² = 4 (1 − cos θ) ≈ 2 θ² for two rotations θ apart).
    """

    xyz: np.ndarray
    model: np.ndarray
    axes: np.ndarray
    model_axes: np.ndarray
    lever: np.ndarray

    @classmethod
    def of(cls, xyz: np.ndarray, model: np.ndarray, R: np.ndarray | None = None, model_R: np.ndarray | None = None,
           lever: np.ndarray | float = 1.0) -> "Framed":
        """From points xyz and model (N, 3) or (N, m, 3) m and, where rotations were measured, the measured ones R
        (N, 3, 3) (columns: the axes) and the model's model_R (N, 3, 3), weighed by ``lever`` (N,) or one number, m."""
        n = len(xyz)
        xyz, model = (np.asarray(a, float).reshape(n, -1, 3) for a in (xyz, model))
        none = np.zeros((n, 0, 3))
        lev = np.broadcast_to(np.asarray(lever, float), (n,))
        axes = none if R is None else R.transpose(0, 2, 1) * lev[:, None, None]
        model_axes = none if model_R is None else model_R.transpose(0, 2, 1) * lev[:, None, None]
        return cls(xyz, model, axes, model_axes, lev)

    def __len__(self) -> int:
        return len(self.xyz)

    def subset(self, idx: np.ndarray | slice) -> "Framed":
        """The samples ``idx`` (an index array or a slice), in its order."""
        return Framed(self.xyz[idx], self.model[idx], self.axes[idx], self.model_axes[idx], self.lever[idx])

    @property
    def rotations(self) -> bool:
        """Whether rotations were measured."""
        return self.axes.shape[1] > 0

    def seen(self) -> np.ndarray:
        """(N, m) the points that were seen and that the model reaches."""
        return np.all(np.isfinite(self.xyz) & np.isfinite(self.model), axis=2)

    def components(self) -> int:
        """The measured components: 3 per seen point and 3 per rotation."""
        return 3 * int(self.seen().sum()) + 3 * len(self) * self.rotations

    def sums(self) -> tuple[np.ndarray, ...]:
        """Per sample, what one rigid fit needs (:func:`_rigid_sse`): the seen points' count (N,), their sums Σx and
        Σp (N, 3), Σ(|x|² + |p|²) (N,) and Σ x pᵀ (N, 3, 3), the axes added to the last two (a turn moves them, a
        shift does not)."""
        w = self.seen().astype(float)
        x, p = (np.where(w[:, :, None] > 0, a, 0.0) for a in (self.xyz, self.model))
        a, b = self.axes, self.model_axes
        sq = np.einsum("nm,nmi->n", w, x**2 + p**2) + np.sum(a**2 + b**2, axis=(1, 2))
        return (w.sum(1), np.einsum("nm,nmi->ni", w, x), np.einsum("nm,nmi->ni", w, p), sq,
                np.einsum("nm,nmi,nmj->nij", w, x, p) + np.einsum("nki,nkj->nij", a, b))

    def misses(self, R: np.ndarray, t: np.ndarray,
               shift: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per sample (N,), with the points moved by (R, t) after ``shift`` (N, 3) m and the axes turned by R: the
        squared distances of the seen points from the model's, summed, m²; the same of the axes, m² (the two sum to
        the fit's squared error); the squared angle between the rotations so turned and the model's, rad²."""
        x = self.xyz if shift is None else self.xyz + shift[:, None, :]
        d = np.sum(np.where(self.seen()[:, :, None], x @ R.T + t - self.model, 0.0) ** 2, axis=(1, 2))
        chord = np.sum((self.axes @ R.T - self.model_axes) ** 2, axis=(1, 2))
        with np.errstate(invalid="ignore", divide="ignore"):  # no rotations: no lever, no angle
            cos = np.where(chord > 0, 1.0 - chord / (4 * self.lever**2), 1.0)
        return d, chord, np.arccos(np.clip(cos, -1.0, 1.0)) ** 2


def frame_jump(xyz: np.ndarray, model: np.ndarray, min_part: int = MIN_PART,
               ratio: float = JUMP_RATIO) -> tuple[int, float, float] | None:
    """Where the measurement frame jumps inside one file: the first index k of the second part and
    the RMS (m) of the positions xyz (N, 3) against the model's model (N, 3) with one rigid frame for
    all and with one for each part (rows before k and from k on), for the k that fits best; None
    unless two frames leave less than ``ratio`` (default JUMP_RATIO) of one frame's RMS (two set-ups, a bumped
    tracker); ``ratio`` 1: the best split whatever it leaves (a candidate to try)."""
    found = _best_split(Framed.of(xyz, model), min_part)
    if found is None:
        return None
    k, one, two = found[0], float(np.sqrt(found[1] / len(xyz))), float(np.sqrt(found[2] / len(xyz)))
    return (k, one, two) if two < ratio * one else None


def _best_split(framed: Framed, min_part: int) -> tuple[int, float, float] | None:
    """The first index k of the second part where one rigid frame per part (before k, from k on) fits ``framed``
    best (every split at once, from prefix sums; ties: the earliest), the squared error (m²) left by one frame for
    all and by one per part; None for fewer than 2 ``min_part`` samples."""
    n = len(framed)
    if n < 2 * min_part:
        return None
    cum = [np.cumsum(a, axis=0) for a in framed.sums()]
    total = [c[-1] for c in cum]
    k = np.arange(min_part, n - min_part + 1)  # the second part's first index
    head = [c[k - 1] for c in cum]
    tail = [t - h for t, h in zip(total, head)]
    two = _rigid_sse(*head) + _rigid_sse(*tail)
    one = float(_rigid_sse(*[t[None] for t in total])[0])
    best = first_best(two, maximize=False)  # splits that fit as well: the earliest
    return int(k[best]), max(one, 0.0), max(float(two[best]), 0.0)  # round-off: ≥ 0


@dataclass(frozen=True)
class Jump:
    """A frame jump inside one file (:func:`frame_jump_test`): the first index of the second part, the RMS distance
    (m) of the measured points from the model's with one rigid frame for all, with one frame per part, and with one
    frame and a linear drift over the rows, and the F test's p-value (Bonferroni over the splits); where rotations
    were measured, their RMS angle (rad) from the model's in the same three fits (``turns``; else None)."""

    index: int
    one: float
    two: float
    drift: float
    p: float
    turns: tuple[float, float, float] | None = None


def frame_jump_test(xyz: np.ndarray | Framed, model: np.ndarray | None = None, n_params: int = 0,
                    min_part: int = MIN_PART) -> Jump | None:
    """A significant, material frame jump inside one file, found cheaply (prefix sums) on a fitted model.

    The split of :func:`frame_jump` (the one that fits best, whatever it leaves) is judged by the F test of a
    second rigid frame (6 parameters) from that row on, with the noise estimated by what the two frames leave
    (Andrews 1993, "Tests for parameter instability and structural change with unknown change point"; its p-value
    times the number of splits tried, Bonferroni): significant below ``JUMP_ALARM`` (1 %); the split must also
    remove ``JUMP_SHARE`` (half) of the squared error one frame leaves, since a model's own errors, which
    neighbouring rows share, pass the F test alone (the real UR5 grid's best split removes 4.6 % of it at F = 24),
    and fit better than one frame with a linear drift over the rows (a warm-up, not a step). Whatever an observation
    kind measures in its frame is judged so (:meth:`kincal.observe.Observation.framed`): points, markers, and 6-D
    poses, whose rotations a frame's turn moves with their positions (weighed by their σ, :class:`Framed`).

    Parameters
    ----------
    xyz : ndarray, shape (N, 3), or Framed
        Measured positions in acquisition (row) order, m; or what a frame moves (:class:`Framed`), in that order.
    model : ndarray, shape (N, 3), optional
        The fitted model's positions at the same poses, m (for positions ``xyz``; default None).
    n_params : int, optional
        The parameters fitted to these data besides one rigid frame (default 0), for the F test's degrees
        of freedom.
    min_part : int, optional
        Poses on either side of a split at least (default ``MIN_PART``, 10).

    Returns
    -------
    Jump or None
        The jump when it is significant, material and a better fit than a drift; else None.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.models.unit_checks import frame_jump_test
    >>> rng = np.random.default_rng(0)
    >>> model = rng.uniform(-0.5, 0.5, (200, 3))
    >>> xyz = model + rng.normal(0.0, 20e-6, (200, 3))
    >>> frame_jump_test(xyz, model) is None  # noise alone
    True
    >>> xyz[120:] += [0.2e-3, 0.0, 0.0]  # the tracker bumped by 0.2 mm at index 120
    >>> jump = frame_jump_test(xyz, model)
    >>> jump.index, round(jump.one * 1e3, 3), round(jump.two * 1e3, 3), jump.p < 1e-100
    (120, 0.105, 0.033, True)
    """
    framed = xyz if isinstance(xyz, Framed) else Framed.of(xyz, np.asarray(model, float))
    found = _best_split(framed, min_part)
    dof = framed.components() - n_params - 12  # each part's frame fitted
    if found is None or dof < 1:
        return None
    k, sse_one, sse_two = found
    if not sse_two <= (1.0 - JUMP_SHARE) * sse_one:
        return None
    f = (sse_one - sse_two) / 6.0 / max(sse_two / dof, 1e-300)
    p = min(1.0, (len(framed) - 2 * min_part + 1) * f_sf(f, 6.0, float(dof)))
    drift = _drift_fit(framed)
    if not (p < JUMP_ALARM and sse_two < float(np.sum(drift[0] + drift[1]))):
        return None
    parts = [part.misses(*_frame(part)) for part in (framed.subset(slice(None, k)), framed.subset(slice(k, None)))]
    fits = [framed.misses(*_frame(framed)), tuple(np.concatenate(m) for m in zip(*parts)), drift]
    points = max(int(framed.seen().sum()), 1)
    one, two, drifted = (float(np.sqrt(np.sum(d) / points)) for d, _, _ in fits)
    one_turn, two_turn, drift_turn = (float(np.sqrt(np.mean(a))) for _, _, a in fits)
    return Jump(k, one, two, drifted, p, (one_turn, two_turn, drift_turn) if framed.rotations else None)


def _frame(framed: Framed, shift: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The rigid frame (R (3, 3), t (3,)) that moves ``framed``'s points (after ``shift`` (N, 3) m) and axes onto
    the model's best (Kabsch, the axes in the cross-covariance only)."""
    moved = framed if shift is None else dataclasses.replace(framed, xyz=framed.xyz + shift[:, None, :])
    n, sx, sp, _, sxp = (s.sum(axis=0) for s in moved.sums())
    H = sxp - np.outer(sx, sp) / max(n, 1.0)
    U, _, Vt = np.linalg.svd(H)
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0]) @ U.T  # a reflection is not a frame
    return R, (sp - R @ sx) / max(n, 1.0)


def _drift_fit(framed: Framed) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`Framed.misses` with one rigid frame and a linear drift of the points over the rows (from −½ to +½ of
    it from the first to the last), the two fitted alternately (Kabsch, then least squares)."""
    s = np.linspace(-0.5, 0.5, len(framed))
    w = framed.seen()
    d = np.zeros(3)
    for _ in range(DRIFT_ROUNDS):
        R, t = _frame(framed, -s[:, None] * d)
        r = np.where(w[:, :, None], framed.xyz @ R.T + t - framed.model, 0.0)  # the drift not taken out
        d = R.T @ np.einsum("n,nmi->i", s, r) / max(float(np.sum(w.sum(1) * s**2)), 1e-300)
    R, t = _frame(framed, -s[:, None] * d)
    return framed.misses(R, t, -s[:, None] * d)


def _rigid_sse(n, sx, sp, sq, sxp) -> np.ndarray:
    """Sum of squared distances left by the best rigid motion of the points x onto p, from their
    sums: count n (K,), Σx and Σp (K, 3), Σ(|x|² + |p|²) (K,), Σ x pᵀ (K, 3, 3) (Kabsch; axes, which a turn moves
    and a shift does not, are in the last two only: :meth:`Framed.sums`)."""
    n = np.maximum(n, 1.0)  # a part that saw no point: its sums are 0
    H = sxp - sx[:, :, None] * sp[:, None, :] / n[:, None, None]
    s = np.linalg.svd(H, compute_uv=False)
    s[:, -1] *= np.sign(np.linalg.det(H))  # a reflection is not a frame
    return sq - (np.sum(sx**2, 1) + np.sum(sp**2, 1)) / n - 2 * s.sum(axis=1)


def check_degrees(source: str, q: np.ndarray, robot: Robot, angle_unit: str | None, default: bool = False) -> None:
    """Refuse revolute joint values that look like degrees read as radians.

    They do when some go beyond their joint's reach, the larger of two turns and 1.5 times the joint's
    largest limit, and all would lie within it read as degrees.

    Parameters
    ----------
    source : str
        Where the values come from (a file's path), named in the message.
    q : ndarray, shape (N, n)
        Joint values as read, rad (m for a prismatic joint; not checked).
    robot : Robot
        The robot (its joint types and limits).
    angle_unit : str or None
        The angle unit the values were read in, named in the message (None: not named).
    default : bool, optional
        ``angle_unit`` is a reader's default, not given: the message says so (default False: it was given).

    Raises
    ------
    MeasurementError
        When the values look like degrees, naming the largest and the unit to use.

    See Also
    --------
    check_radians : The other mistake: radians read as degrees.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import check_degrees
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(5, seed=1)
    >>> check_degrees("poses.csv", q, robot, "rad")  # within the limits: nothing to say
    >>> check_degrees("poses.csv", np.degrees(q), robot, "rad")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: poses.csv: revolute joint values reach ... rad ('rad' was given), far beyond
    the joint limits: they look like degrees; use angle unit 'deg' (CLI: --angle-unit deg)
    >>> check_degrees("poses.csv", np.degrees(q), robot, "rad", default=True)
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: poses.csv: revolute joint values reach ... rad (the default 'rad': no unit was
    given), far beyond the joint limits: they look like degrees; use angle unit 'deg' (CLI: --angle-unit deg)
    """
    rev = robot.revolute
    if not rev.any() or angle_unit not in (None, "rad", "deg"):  # revolutions: no degrees-for-radians mistake
        return
    reach = _reach(robot)
    if _degrees_as_radians(q, robot):  # read as degrees, they would fit
        qmax = float(np.max(np.abs(q[:, rev])))
        given = (f" (the default '{angle_unit}': no unit was given)" if default else
                 f" ('{angle_unit}' was given)" if angle_unit else "")
        j = np.flatnonzero(rev)[int(np.argmax(np.max(np.abs(q[:, rev]), axis=0)))]
        written = q[:, j] * (180.0 / np.pi if angle_unit == "deg" else 1.0)
        alone = int(np.sum(np.any(np.abs(q[:, rev]) > reach, axis=0))) == 1  # the other joints fit as given
        if alone and _counter(written):
            raise MeasurementError(f"{source}: the column read as joint {robot.joint_names[j]} holds the whole numbers "
                                   f"{written.min():.0f} to {written.max():.0f}, counting up by 1 from row to row: a row "
                                   f"or sample number, not a joint angle; check the joint columns (CLI: --joint-cols)")
        if angle_unit == "deg":  # already read as degrees: not an angle at all
            raise MeasurementError(f"{source}: the column read as joint {robot.joint_names[j]} reaches "
                                   f"{np.degrees(qmax):.4g} deg as written ('deg' was given), far beyond its limits: "
                                   f"not a joint angle (a pose number or another quantity?); check the joint columns "
                                   f"(CLI: --joint-cols)")
        raise MeasurementError(f"{source}: revolute joint values reach {qmax:.4g} rad{given}, far beyond the joint "
                               f"limits: they look like degrees; use angle unit 'deg' (CLI: --angle-unit deg)")


def _reach(robot: Robot) -> np.ndarray:
    """Each revolute joint's reach (rad): the larger of two turns and 1.5 times its largest limit."""
    lim = np.maximum(np.abs(robot.lower), np.abs(robot.upper))
    return np.maximum(4 * np.pi, 1.5 * np.where(np.isfinite(lim), lim, 0.0))[robot.revolute]


def _degrees_as_radians(q: np.ndarray, robot: Robot) -> bool:
    """Whether revolute joint values (N, n) go beyond their reach while all would lie within it as degrees."""
    a = np.abs(q[:, robot.revolute])
    return bool(a.size and np.any(a > _reach(robot)) and np.all(a * np.pi / 180.0 <= _reach(robot)))


def joints_in_radians(what: str, q: np.ndarray, robot: Robot) -> None:
    """Refuse joint values of a Python call (``what`` names them) that look like degrees: a library call takes
    radians, and degrees read as radians go far beyond the joint limits.

    Parameters
    ----------
    what : str
        What the values are (an argument of the call), named in the message.
    q : ndarray, shape (N, n)
        The joint values given, meant in rad (m for a prismatic joint).
    robot : Robot
        The robot (its joint types and limits).

    Raises
    ------
    MeasurementError
        When they look like degrees, naming the largest and what to give.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import joints_in_radians
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(5, seed=1)
    >>> joints_in_radians("candidates", q, robot)  # radians: nothing to say
    >>> joints_in_radians("candidates", np.degrees(q), robot)
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: candidates: revolute joint values reach ... rad, far beyond the joint limits: they
    look like degrees; a Python call takes radians (np.radians(q))
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.ndim == 2 and q.shape[1] == robot.n_joints and _degrees_as_radians(q, robot):
        qmax = float(np.max(np.abs(q[:, robot.revolute])))
        raise MeasurementError(f"{what}: revolute joint values reach {qmax:.4g} rad, far beyond the joint limits: they "
                               f"look like degrees; a Python call takes radians (np.radians(q))")


def check_limits(source: str, q: np.ndarray, robot: Robot, length_unit: str | None, angle_unit: str | None,
                 suggest: bool = True, tried: bool = False) -> None:
    """Refuse a joint column whose values lie, in most rows, further outside the robot's limits than the limits are
    wide: another unit, or another quantity in that column (run after the degree and radian checks); with
    ``suggest``, a unit in which every value lies within the limits is named (without it, when measured positions
    were already checked for the unit that moves the robot as far as they spread, none is): for a motor driving a
    screw (``robot.motor_leads``) also lengths in ``length_unit``, turned into its angle by the lead (a leg's travel
    in mm given where its motor's revolutions are read).

    Parameters
    ----------
    source : str
        Where the values come from (a file's path), named in the message.
    q : ndarray, shape (N, n)
        Joint values as read, rad or m.
    robot : Robot
        The robot (its limits and joint types).
    length_unit, angle_unit : str or None
        The units the values were read in (None: SI), to show them as written.
    suggest : bool, optional
        Name a unit that puts every value within the limits (default True).
    tried : bool, optional
        The revolute joints' other readings were already tried against measured positions (:func:`check_spread`):
        none is named for them (default False).

    Raises
    ------
    MeasurementError
        Naming the column, its values and the limits as written.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import check_limits
    >>> robot = kincal.load_robot("hexapod")
    >>> q = robot.sample_joints(10, seed=1)
    >>> check_limits("legs.csv", q, robot, "mm", "rev")  # within the legs' ranges: nothing to say
    >>> check_limits("legs.csv", q * 40.0, robot, "mm", "rev", suggest=False)
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: legs.csv: the column read as joint leg... holds ... rev as written, while
    its range is 0 to 4.2 rev: far outside it in most rows: another unit, another lead in the robot file, or another
    quantity in that column? ...

    The legs' travel in mm where their motors' revolutions are read: the lead that turns it into them is named:

    >>> travel = q * robot.motor_leads * 1e3 * 2 * np.pi  # mm, as numbers read as rev
    >>> check_limits("legs.csv", travel, robot, "mm", "rev")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: legs.csv: the column read as joint leg1 holds ... rev as written, while its range
    is 0 to 4.2 rev: far outside it in most rows: read as mm of travel through its lead (75.69 mm/rev)... they lie
    within it: they look like lengths in mm: give them in rev (the travel divided by the lead), or describe the joints
    as read in lengths in the robot file (a hexapod's legs: no 'reading', no 'lead')...

    A 3-PUU's slides in mm read as metres: the unit that puts them all within their range is named:

    >>> puu = kincal.load_robot("puu3")
    >>> check_limits("pool.csv", puu.sample_joints(10, seed=1) * 1e3, puu, "m", "rad")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: pool.csv: the column read as joint h1 holds ... m as written, while its range
    is 0.38 to 0.835 m: far outside it in most rows: read as mm they lie within it; use length unit 'mm' (CLI:
    --length-unit mm)
    """
    width = robot.upper - robot.lower
    med = np.median(q, axis=0)
    far = np.isfinite(width) & (width > 0) & ((med > robot.upper + width) | (med < robot.lower - width))
    if not far.any():
        return
    j = int(np.flatnonzero(far)[0])
    unit = joint_units(robot.joint_types, length_unit or "m", angle_unit or "rad")[j] or ""
    units = ANGLE_UNITS if robot.joint_types[j] == "revolute" else LENGTH_UNITS
    f, flag = {**LENGTH_UNITS, **ANGLE_UNITS}.get(unit, 1.0), "angle" if units is ANGLE_UNITS else "length"
    written = q[:, j] / f
    inside = lambda g: bool(np.all((written * g >= robot.lower[j] - 1e-12)  # noqa: E731
                                   & (written * g <= robot.upper[j] + 1e-12)))
    fits = [u for u, g in units.items() if u != unit and inside(g)]
    lead = float(robot.motor_leads[j]) if robot.revolute[j] else np.nan  # a motor driving a screw: lengths of travel
    travel = [u for u in (length_unit or "m",) if np.isfinite(lead) and lead != 0 and inside(LENGTH_UNITS[u] / lead)]
    suggest = suggest and not (tried and robot.revolute[j])
    hint = (f": another unit, {'another lead in the robot file, ' if np.isfinite(lead) else ''}or another quantity "
            f"in that column? check the joint columns and their unit (joint_cols, {flag}_unit; "
            f"CLI: --joint-cols, --{flag}-unit)")
    if suggest and travel:
        per = f"{lead * f / LENGTH_UNITS[travel[0]]:.4g} {travel[0]}/{unit}"
        hint = (f": read as {travel[0]} of travel through its lead ({per}){f', or as {fits[0]},' if fits else ''} they "
                f"lie within it: {as_travel(travel[0], unit)}" + (f"; or use {flag} unit '{fits[0]}' (CLI: "
                                                                  f"--{flag}-unit {fits[0]})" if fits else ""))
    elif suggest and fits:
        hint = f": read as {fits[0]} they lie within it; use {flag} unit '{fits[0]}' (CLI: --{flag}-unit {fits[0]})"
    raise MeasurementError(f"{source}: the column read as joint {robot.joint_names[j]} holds {written.min():.4g} "
                           f"to {written.max():.4g} {unit} as written, while its range is {robot.lower[j] / f:.4g} "
                           f"to {robot.upper[j] / f:.4g} {unit}: far outside it in most rows{hint}")


def check_joints(source: str, q: np.ndarray, robot: Robot, length_unit: str | None, angle_unit: str | None,
                 suggest: bool = True, angle_default: bool = False) -> None:
    """The joint values' unit and column checks, in order: :func:`check_degrees`, :func:`check_radians`,
    :func:`check_limits`.

    Parameters
    ----------
    source : str
        Where the values come from (a file's path), named in the message.
    q : ndarray, shape (N, n)
        Joint values as read, rad or m.
    robot : Robot
        The robot.
    length_unit, angle_unit : str or None
        The units the values were read in.
    suggest : bool, optional
        Passed to :func:`check_limits` (default True).
    angle_default : bool, optional
        ``angle_unit`` is a reader's default, not given (:func:`check_degrees`; default False: it was given).

    Raises
    ------
    MeasurementError
        From the first check that finds a mistake.

    Examples
    --------
    >>> import kincal
    >>> from kincal.io import check_joints
    >>> robot = kincal.load_robot("ur5")
    >>> check_joints("poses.csv", robot.sample_joints(5, seed=1), robot, "mm", "rad")  # nothing to say
    """
    check_degrees(source, q, robot, angle_unit, angle_default)
    check_radians(source, q, robot, angle_unit)
    check_limits(source, q, robot, length_unit, angle_unit, suggest)


def _counter(values: np.ndarray) -> bool:
    """Whether values (N,) as written, N ≥ 5, are a counter: whole numbers that go up by 1 from row to row, but for
    restarts (a sample number within each placement)."""
    v = np.round(values, 9)
    steps = np.diff(v)
    return bool(len(v) >= 5 and np.all(v == np.round(v)) and np.all((steps == 1) | (steps < 0))
                and np.mean(steps == 1) >= 0.8)


def check_radians(source: str, q: np.ndarray, robot: Robot, angle_unit: str | None) -> None:
    """Refuse joint values declared in degrees that look like radians read as degrees.

    They do when, over poses meant to span the workspace (at least 10), the numbers as written never leave
    ±2π while some joint moves by more than 0.5 of them: radians read as degrees, which barely move the
    robot. Values declared in another unit are not checked.

    Parameters
    ----------
    source : str
        Where the values come from (a file's path), named in the message.
    q : ndarray, shape (N, n)
        Joint values as read, rad (m for a prismatic joint; not checked).
    robot : Robot
        The robot (its joint types).
    angle_unit : str or None
        The angle unit the values were read in; only "deg" is checked.

    Raises
    ------
    MeasurementError
        When the values look like radians, naming the unit to use.

    See Also
    --------
    check_degrees : The other mistake: degrees read as radians.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.io import check_radians
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(12, seed=1)
    >>> check_radians("poses.csv", q, robot, "deg")  # degrees read as degrees: nothing to say

    A file of radians read as degrees gives joint values 57.3 times too small:

    >>> check_radians("poses.csv", np.radians(q), robot, "deg")
    Traceback (most recent call last):
    ...
    kincal.errors.MeasurementError: poses.csv: read as degrees, no revolute joint moves more than ... deg over 12
    samples: the values look like radians; use angle unit 'rad' (CLI: --angle-unit rad)
    """
    rev = robot.revolute
    if angle_unit != "deg" or not rev.any() or len(q) < 10:
        return
    as_read = np.abs(q[:, rev]) * 180.0 / np.pi
    if radians_as_degrees(as_read) and float(np.ptp(as_read, axis=0).max()) > 0.5:
        raise MeasurementError(f"{source}: read as degrees, no revolute joint moves more than {as_read.max():.3g} "
                               f"deg over {len(q)} samples: the values look like radians; use angle unit 'rad' "
                               f"(CLI: --angle-unit rad)")


def radians_as_degrees(written: np.ndarray) -> bool:
    """Whether revolute joint values written in degrees look like radians: every one within ±2π as written (a robot's
    poses in degrees leave ±6.3° on some joint) and not all 0.

    Parameters
    ----------
    written : ndarray
        The values as written (any shape), meant in degrees.

    Returns
    -------
    bool
        True when they look like radians.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.models.unit_checks import radians_as_degrees
    >>> radians_as_degrees(np.array([[0.29, -1.08, 2.51, 0.0, 0.15, 0.29]]))
    True
    >>> radians_as_degrees(np.degrees([[0.29, -1.08, 2.51, 0.0, 0.15, 0.29]]))
    False
    """
    a = np.abs(np.asarray(written, dtype=float))
    return bool(a.size and a.max() <= 2 * np.pi and a.max() > 0)


def unit_hint(ratio: float, length_unit: str | None, what: str = "measured positions") -> str:
    """Why the measured spread is off by ``ratio`` (read in ``length_unit``, default m), and what to do:
    the unit the positions are really in when one explains the factor."""
    table = {**LENGTH_UNITS, **OTHER_LENGTHS}
    declared = length_unit if length_unit in table else "m"
    if not (np.isfinite(ratio) and ratio > 0):  # no spread at all, or one beyond floating point
        return (f"{what} spread {'not at all' if ratio == 0 else 'beyond any robot'} while the robot moves at the "
                f"same joint values (read as '{declared}'): check the position columns and their values")
    name = _unit_of(ratio, length_unit)
    head = f"{what} spread {_times(ratio)} than the robot moves at the same joint values (read as '{declared}')"
    if not name:
        return (f"{head}; no length unit explains that factor: check the joint columns and the robot file, or "
                f"whether the file holds measurements from several tracker set-ups (then give one file per set-up)")
    if name in LENGTH_UNITS:
        return f"{head}: they look like {name}; use length unit '{name}' (CLI: --length-unit {name})"
    return (f"{head}: they look like {name}; convert them to mm (x{table[name] / 1e-3:g}) and use length unit 'mm' "
            f"(CLI: --length-unit mm)")


def _times(ratio: float) -> str:
    """'6.08x more' or '2x less': a spread's ratio in words."""
    return f"{ratio:.3g}x more" if ratio > 1 else f"{1 / ratio:.3g}x less"


def _unit_of(ratio: float, length_unit: str | None) -> str:
    """The length unit (of ``LENGTH_UNITS`` and ``OTHER_LENGTHS``) measured positions read in ``length_unit`` (default
    m) are really in when they spread ``ratio`` times the robot's (within 30 %); '' when none is."""
    table = {**LENGTH_UNITS, **OTHER_LENGTHS}
    if not (np.isfinite(ratio) and ratio > 0):
        return ""
    true = table[length_unit if length_unit in table else "m"] / ratio  # the SI value of the unit they are in
    name = min(table, key=lambda k: abs(np.log(table[k] / true)))
    return name if abs(np.log(table[name] / true)) <= np.log(1.3) else ""
