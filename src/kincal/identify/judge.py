"""The one verdict of a calibration (:class:`~kincal.identify.CalibrationResult`, any kinds): the
fit's convergence and base frame, the corrections and the mounting against the user's limits
(:class:`~kincal.identify.verdict.Thresholds`), then per kind of data: position data fitted by
:func:`kincal.calibrate` by their residual σ against the tracker noise, per-pose outliers, repeated
poses and warm-up drift; other sets by the whitened residual per kind of component against its
stated σ, outlier samples and repeated poses per set (named by file and row), and what plane
contacts alone cannot confirm. A differential diagnosis, when run, comes first."""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from ..analysis.identifiability import jacobian_identifiability, stacked_jacobian
from ..errors import ModelError
from ..models.robot import TOOL_NAMES, Robot
from ..models.unit_checks import Framed
from ..observe.constraints import SamePointObs
from ..observe.files import DEFAULT_STD
from ..observe.observations import Wrapper
from ..units import MM, fine
from .noise import SIGNIFICANT
from .._csv import listed
from .pso import HALF_WIDTH
from .verdict import (FALSE_ALARM, Reason, Thresholds, Verdict, correction_reasons, drift_reasons, duplicate_groups,
                      duplicate_reasons, fitted_drift_reasons, jump_reasons, mounting_reasons, noise_level,
                      outlier_reasons, repeat_tolerance, residual_reasons, robust_z)

if TYPE_CHECKING:
    from .diagnosis import Diagnosis
    from .result import CalibrationResult

SIZE_SUSPECT = 1e-2  # a calibrated model this much larger or smaller than its drawings as a whole: no robot's error (one
# plate placement's 50 mm fixes the scale only to about 0.5 %)
SIZE_POSES = 100  # poses of the joint ranges the two models' sizes are compared over (seed 0)
IN_PLANE_RATIO = 1.0  # plane data: predicted points moved more along the planes (unseen) than across them
WHITENED_SUSPECT = 3.0  # a kind of observation whose whitened residual RMS is beyond this: suspect
MIN_SAMPLES = 10  # a set with fewer samples is not judged for outliers (no robust spread to judge by)
PLATE_Z = 6.0  # two files' samples of one shared socket point this many σ of their means apart: two plate positions.
# Above the 3.5 σ between the two halves of the Panda's front_center as measured (configurations grouped by row); the
# same rows moved by 0.5 mm are 14 σ apart
DISTANCE_Z = 4.0  # a known distance the fit leaves this many of its σ off (at least): not met. Above the 2.6 that
# noise alone passes once in a hundred: the Panda's true 50 mm are left up to 2.8 σ off where the model leaves its
# seats 3.5x their σ (all 8 placements); the same plate stated 49 or 50.5 mm is left 5.3 and 5.6 σ off


STATED = {"pose position": "--std-pos", "pose rotation": "--std-rot"}  # the flag that states each kind's σ
THROUGH = "with the measured positions' or poses' σ through the inverse kinematics"  # a joint residual's σ besides
ASSUMED = {"joint": f"the joints' reading noise taken as 1e-4 rad or m, {THROUGH}; --std-joint states it"}  # not stated


def component_kinds(sets) -> tuple[np.ndarray, tuple[str, ...]]:
    """Each stacked row's kind of component (M,), an index into the kinds' names (in order of first
    appearance): a pose's position and rotation rows apart (each has its own σ), other kinds whole."""
    names: dict[str, int] = {}  # name -> its index, in order of first appearance
    labels = []
    for obs in sets:
        m = obs.sigma().size
        parts = (("pose position", m // 2), ("pose rotation", m - m // 2)) if obs.kind == "pose" else ((obs.kind, m),)
        for name, count in parts:
            labels.append(np.full(count, names.setdefault(name, len(names))))
    return np.concatenate(labels) if labels else np.zeros(0, int), tuple(names)


def verdict_of(res: "CalibrationResult") -> Verdict:
    """Good, suspect or refused with reasons (limits: ``res.options.thresholds``)."""
    th = res.options.thresholds
    reasons = [] if res.converged else [Reason("refused", "not-converged", f"the fit did not converge "
                                                                             f"({res.message})")]
    reasons += _base_reasons(res) + _box_reasons(res)
    reasons += correction_reasons(res.nominal, {n: c for n, c in res.corrections.items() if np.isfinite(res.std[n])},
                                  th, res.correction_scales)
    if res.mounting and not res.mounting_gauge[0]:  # a tool point the data do not determine is judged by nothing
        reasons += mounting_reasons(res.nominal.tool_point(), res.robot.tool_point(), th)
    reasons += _position_reasons(res, th) if res.data else _set_reasons(res, th)
    reasons += overstated_reasons(res, {"joint"} if res.options.joint_std is not None else set())
    reasons += _size_reasons(res)
    verdict = Verdict.from_reasons(tuple(reasons))
    return verdict if res.diagnosis is None else _diagnosed(res, res.diagnosis, verdict)


def _size_reasons(res: "CalibrationResult") -> list[Reason]:
    """A calibrated model larger or smaller than the nominal one as a whole by more than SIZE_SUSPECT (1 %) and three
    of its σ: the length that sets the data's scale is off — a known distance between sockets or planes where the data
    have one, else the instrument's scale (or the robot file's lengths). The size is the scale of a similarity fit of
    the two models' flange positions at SIZE_POSES poses of the joint ranges (σ through the fit's covariance);
    judged only for a robot whose positions scale with its lengths (not a leg's or a screw's reading)."""
    if not _scales_with_lengths(res.nominal):
        return []
    flange = [m.with_tool_point(np.zeros(3)) if m.has_tool_point else m for m in (res.nominal, res.robot)]
    q = res.nominal.sample_joints(SIZE_POSES, seed=0)
    a = flange[0].forward_batch(q, flange[0].param_values(None)[None])[0]
    b = flange[1].forward_batch(q, flange[1].param_values(None)[None])[0]
    fine = np.all(np.isfinite(a) & np.isfinite(b), axis=1)
    scale = similarity_scale(a[fine], b[fine]) if fine.sum() >= 4 else 1.0
    if abs(scale - 1.0) <= SIZE_SUSPECT:  # the common case: no σ needed
        return []
    sigma = _size_sigma(res, flange[1], q[fine], a[fine], scale)
    if abs(scale - 1.0) <= 3 * sigma:
        return []
    known = any(o.kind in ("same-point", "plane") and o.reference for o in res.observations)
    why = ("the known distance that sets the scale (--distance, or the planes' known offsets) is likely off" if known
           else "the instrument's length scale or the robot file's lengths are likely off")
    return [Reason("suspect", "size", f"the calibrated model is {abs(scale - 1) * 100:.1f} % ± "
                                      f"{sigma * 100:.1f} % {'larger' if scale > 1 else 'smaller'} than the "
                                      f"nominal one as a whole (a similarity fit of their flange positions over the "
                                      f"joint ranges): no real robot is that far from its drawings; {why}")]


def _size_sigma(res: "CalibrationResult", robot: Robot, q: np.ndarray, a: np.ndarray, scale: float) -> float:
    """The σ of the similarity scale of ``robot``'s flange positions at q (N, n) against a (N, 3): forward differences
    in each fitted parameter (the tool point aside) through the fit's covariance."""
    values = robot.param_values(None)
    ok = [n for n in res.names if np.isfinite(res.std[n]) and n in robot.params.names and n not in TOOL_NAMES]
    idx = robot.params.indices(ok)
    step = np.where(np.array(robot.params.kinds)[idx] == "length", 1e-6, 1e-7)
    trial = np.repeat(values[None], len(idx), axis=0)
    trial[np.arange(len(idx)), idx] += step
    b = robot.forward_batch(q, trial)  # NaN where the robot does not reach
    grad = (np.array([similarity_scale(a, x) if np.all(np.isfinite(x)) else scale for x in b]) - scale) / step
    at = [res.free.index(n) for n in ok]
    return float(np.sqrt(max(grad @ res.covariance[np.ix_(at, at)] @ grad, 0.0)))


def _scales_with_lengths(robot: Robot) -> bool:
    """Whether the robot's positions grow with its lengths at the same joint readings: an arm of whole-turn joints,
    not a leg's or a screw's travel read as a motor turn (a prismatic joint, a transmission, a hexapod's legs)."""
    return bool(robot.periodic.all()) and not robot.reading_terms() and "transmission" not in robot.structure


def similarity_scale(a: np.ndarray, b: np.ndarray) -> float:
    """The scale s of the similarity b ≈ s R a + t that best maps points a (N, 3) onto b (N, 3) (Umeyama)."""
    a, b = a - a.mean(axis=0), b - b.mean(axis=0)
    U, S, Vt = np.linalg.svd(b.T @ a)
    S[-1] *= np.sign(np.linalg.det(U @ Vt))
    return float(S.sum() / max(np.sum(a**2), 1e-300))


def _box_reasons(res: "CalibrationResult") -> list[Reason]:
    """A particle swarm alone (``method="pso"``) whose estimates lie on the edge of its search box (the values it
    started from ± :data:`kincal.identify.pso.HALF_WIDTH` per kind, the 3-PUU paper of 2024's position limits):
    the swarm could go no further, and the best fit lies beyond the box."""
    if res.options.method != "pso":
        return []
    kinds = dict(zip(res.registered.params.names, res.registered.params.kinds))
    moved = {n: res.robot.params[n] - res.registered.params[n] for n in res.names}
    edge = [n for n, c in moved.items() if abs(c) >= HALF_WIDTH[kinds[n]] * (1.0 - EDGE)]
    if not edge:
        return []
    box = ", ".join(f"±{fine(HALF_WIDTH[k], k, 'g')} for {k}s" for k in dict.fromkeys(kinds[n] for n in edge))
    at = ", ".join(f"{n} {fine(moved[n], kinds[n], '+g')}" for n in edge)
    return [Reason("suspect", "search-box", f"the particle swarm stopped on the edge of its search box (the nominal "
                   f"values {box}) at {at}: the best "
                   f"fit lies beyond it; refit with --method pso+lm (Levenberg–Marquardt from the swarm's best, not "
                   f"bound by the box) or --method lm")]


EDGE = 1e-6  # an estimate within this share of the half-width from the box's edge is on it (the swarm clips to it)


def _base_reasons(res: "CalibrationResult") -> list[Reason]:
    """Position data that leave the base frame underdetermined (other kinds may leave it unseen:
    sockets and planes carry frames of their own): base parameters the poses cannot tell apart among themselves, by
    the identifiability rule on the base frame's own columns. A base parameter the fit dropped for acting like one
    the user keeps (``keep``: base.rz for j1.theta) is that choice, not the poses': the kept one carries it."""
    base = list(res.nominal.base_params())
    if not res.data or res.options.base != "estimate" or not set(base) & set(res.identifiability.dropped):
        return []
    J = stacked_jacobian(res.robot, res.measurements.q, base)
    loose = jacobian_identifiability(J, base, [], res.robot.name, len(res.measurements.q),
                                     res.options.rank_tol).dropped
    return [Reason("refused", "base-underdetermined", f"the poses leave the base frame underdetermined "
                   f"({', '.join(loose)}): measure poses spread over the workspace, or use --base fixed if the base "
                   f"is known")] if loose else []


def _position_reasons(res: "CalibrationResult", th: Thresholds) -> list[Reason]:
    """Position data as fitted: a frame that jumps inside a file (whatever the residual: a jump the fit has bent
    the model to can leave a σ the noise explains), residual σ (outliers left out) against the tracker noise,
    warm-up drift, per-pose outliers, repeated poses and a fitted drift (unless a step explains the data better)."""
    meas, z, err = res.measurements, res.pose_z, res.residuals
    pos_sigma, left_out = _position_sigma(res, th)
    noise = noise_level(meas.std, th)
    norms = np.linalg.norm(err, axis=1)
    files = meas.session if meas.session is not None and len(set(meas.session)) > 1 else None  # rows are per file
    parts = [(None, np.ones(len(z), bool))] if files is None else [(str(f), files == f) for f in dict.fromkeys(files)]
    model, base = res.robot.forward(meas.q), set(res.nominal.base_params())
    fitted = len([n for n in res.names if n not in base]) / len(z)  # the kinematics' parameters per pose
    jumps = [r for f, m in parts for r in jump_reasons(meas.rows[m], Framed.of(meas.xyz[m], model[m]),
                                                        round(fitted * m.sum()), res.drift is not None, f)]
    reasons = [*jumps, *(r for f, m in parts for r in drift_reasons(meas.rows[m], norms[m], f))]
    reasons += residual_reasons(pos_sigma, noise, th, left_out)
    reasons += [r for f, m in parts for r in outlier_reasons(meas.rows[m], z[m], th, res.options.loss, f)]
    groups = duplicate_groups(meas.q, repeat_tolerance(res.robot.joint_types, th))
    return [*reasons, *duplicate_reasons(meas.rows, groups, files=meas.session, xyz=meas.xyz),
            *([] if jumps else fitted_drift_reasons(res.drift, noise[0], meas.xyz))]  # a step, not a drift


def _position_sigma(res: "CalibrationResult", th: Thresholds) -> tuple[float, int]:
    """The residual σ per axis (m) the verdict judges position data by, the outlier poses left out (they are named
    on their own, not smeared into σ), and how many it left out."""
    inside = res.pose_z <= th.outlier_limit(len(res.pose_z))
    inliers = res.residuals[inside]
    return float(np.sqrt(np.sum(inliers**2) / max(inliers.size - len(res.names), 1))), int(np.sum(~inside))


def residual_words(res: "CalibrationResult") -> str:
    """The residuals against the limit the verdict judges them by, in words, for a verdict with no reason to
    give: position data by their σ per axis against the tracker noise (``residual_suspect``, 10x), observation sets
    by their whitened RMS per kind against its stated σ (``WHITENED_SUSPECT``, 3x).

    Parameters
    ----------
    res : CalibrationResult
        The calibration.

    Returns
    -------
    str
        E.g. "whitened RMS 2.11 (1 when the stated σ are right): residuals 2.1x their stated σ, within the limit
        of 3x".
    """
    th = res.options.thresholds
    if res.data:
        sigma, _ = _position_sigma(res, th)
        noise = noise_level(res.measurements.std, th)[0]
        return (f"residual σ per axis {sigma * MM:.4g} mm, {sigma / noise:.1f}x the tracker noise "
                f"({noise * MM:.3g} mm), within the limit of {th.residual_suspect:.0f}x")
    kinds = dict(res.whitened)
    each = (f"residuals {next(iter(kinds.values())):.1f}x their stated σ, within" if len(kinds) == 1 else
            ", ".join(f"{k} residuals {v:.1f}x" for k, v in kinds.items()) + " their stated σ, each within")
    return (f"whitened RMS {res.whitened_rms:.2f} (1 when the stated σ are right): {each} the limit of "
            f"{WHITENED_SUSPECT:.0f}x")


def _set_reasons(res: "CalibrationResult", th: Thresholds) -> list[Reason]:
    """Observation sets: the whitened residual per kind against its stated σ, outlier samples and
    repeated poses per set, and what plane contacts alone cannot confirm."""
    stated = {"joint"} if res.options.joint_std is not None else set()  # --std-joint: the joints' σ the user's word
    clean = _without_outliers(res.observations, res.whitened_residual, res.outliers)
    samples = _sample_reasons(res.observations, res.outliers, res.registered, th)
    residual = [_whitened_reason(kind, rms, res.whitened, th, stated) for kind, rms in res.whitened.items()
                if rms > WHITENED_SUSPECT and clean > WHITENED_SUSPECT]  # a few outlier samples alone: they are the reason, named below
    if np.isfinite(clean) and residual:  # outliers first: a least-squares fit follows them, and they may be all
        residual = [Reason(r.level, r.code, f"{r.message}; or the outlier samples above, which a least-squares fit "
                                             f"follows: see it with --reject-outliers") for r in residual]
    moved, pooled = _moved_plate_reasons(res.observations, res.robot)
    if moved:  # a point pooled from two plate positions: no σ and no distance describes it
        residual = [Reason(r.level, r.code, f"{r.message}; or the plate moved between files, as named above")
                    for r in residual]
    reasons = [*samples, *residual] if np.isfinite(clean) else [*residual, *samples]
    reasons = [*_jump_reasons(res), *moved, *reasons, *_distance_reasons(res.observations, res.whitened_residual,
                                                                         pooled)]
    if all(o.kind == "plane" for o in res.observations):
        reasons += _plane_reasons(res.registered, res.robot, res.observations)
    return reasons


def _jump_reasons(res: "CalibrationResult") -> list[Reason]:
    """A measurement frame that jumps inside a file, in every set whose kind measures in a frame
    (:meth:`kincal.observe.Observation.framed`: points, 6-D poses with their rotations, markers), as for position
    data (:func:`kincal.identify.verdict.jump_reasons`), against the calibrated model and the set's fitted set-up
    parameters. The parameters fitted to the set: the robot's beside its base frame, by the set's share of the
    residual rows, and the set's own."""
    robot, sets = res.robot, res.observations
    rows = np.array([o.sigma().size for o in sets], float)
    base = set(robot.base_params())
    kinematic = len([n for n in res.names if n in robot.params.names and n not in base])
    out = []
    for obs, share in zip(sets, rows / max(rows.sum(), 1.0)):
        names, start, _ = obs.nuisance(robot)
        framed = obs.framed(robot, robot.params.values, np.array([res.nuisance.get(n, v) for n, v in zip(names, start)]))
        if framed is not None:
            out += jump_reasons(obs.rows, framed, round(kinematic * share) + len(names), res.options.drift, obs.source)
    return out


def _moved_plate_reasons(sets, robot: Robot) -> tuple[list[Reason], set[str]]:
    """Socket points that two files share by name (one set-up parameter) whose samples in the two files lie more
    than :data:`PLATE_Z` σ of their means apart under the calibrated ``robot``: a plate moved between sessions kept its
    placement's name, and the fit took two places for one point. One reason per placement and pair of files (the
    offset of its point that lies farthest in σ), and the labels of those placements' points."""
    means = [(o, o.point_means(robot, robot.params.values)) for o in sets if isinstance(o, SamePointObs)]
    found: dict[tuple[str, str, str], tuple[float, float, str]] = {}  # (placement, file, file) -> z, offset, label
    for k, (a, at_a) in enumerate(means):
        for b, at_b in means[k + 1:]:
            for lab in [lab for lab in at_a if lab in at_b]:
                (ma, sa), (mb, sb) = at_a[lab], at_b[lab]
                z = float(np.linalg.norm((ma - mb) / np.sqrt(sa**2 + sb**2)))
                key = (_placement(a, lab), a.source, b.source)
                if z > PLATE_Z and z > found.get(key, (0.0,))[0]:
                    found[key] = (z, float(np.linalg.norm(ma - mb)), lab)
    what = "placement" if any(o.group is not None for o, _ in means) else "point"
    moved = {place for place, _, _ in found}
    return [Reason("suspect", "moved-plate", f"{what} {place}: its samples in {one} and in {two} share its name, so the "
                   f"fit took them for one point, but they put it {fine(offset, 'length', '.2f')} apart ({z:.0f}x the σ "
                   f"of their means; point {lab}): the plate moved between the files; if it did, give each session's "
                   f"placement a name of its own (e.g. {place}_1, {place}_2)")
            for (place, one, two), (z, offset, lab) in found.items()], \
        {lab for o, _ in means for lab in o.points() if _placement(o, lab) in moved}


def _placement(obs: SamePointObs, label: str) -> str:
    """The placement (group) of a socket point ``label`` of ``obs``, or the label itself when none are given."""
    return label if obs.group is None else str(obs.group[obs.labels == label][0])


def _distance_reasons(sets, r: np.ndarray | None, pooled: set[str] | frozenset[str] = frozenset()) -> list[Reason]:
    """Each known distance between sockets that the fit leaves more than :func:`distance_limit` of its σ off (``r``:
    the residual whitened by the stated σ, stacked as ``sets``): the stated distance or the plate is wrong. A learned
    prior holds the links' lengths, so a distance 1-2 % off is not honoured rather than scaling the model (which
    :func:`_size_reasons` would name): its own residual is what shows it. A distance stated again by another file
    (the same points) is named once; one to a point ``pooled`` from two plate positions is not judged."""
    if r is None:
        return []
    ends = np.cumsum([0, *[o.sigma().size for o in sets]])
    found: dict[tuple[str, str, float], tuple[SamePointObs, float]] = {}  # distance -> the first file stating it, z
    for obs, start, end in zip(sets, ends[:-1], ends[1:]):
        if isinstance(obs, SamePointObs) and obs.distances:
            z = r[start:end][obs.sample_rows() < 0]  # the distances' rows, in their order
            for d, zk in zip(obs.fitted_distances(), z):  # one stated before is fitted, and named, there
                if d[0] not in pooled and d[1] not in pooled:
                    found.setdefault(d, (obs, float(zk)))
    limit = distance_limit(len(found))
    return [Reason("suspect", "distance", f"{obs.source}: the distance {a}–{b} stated as {fine(d, 'length', 'g')} is "
                                          f"not met: the fit leaves it {fine(abs(z) * obs.std_distance, 'length', '.3f')}"
                                          f" {'longer' if z > 0 else 'shorter'} than stated, {abs(z):.1f}x its σ "
                                          f"({fine(obs.std_distance, 'length', 'g')}); the stated distance or the plate "
                                          f"is wrong: measure the plate and state its distance (--distance)")
            for (a, b, d), (obs, z) in found.items() if abs(z) > limit]


def distance_limit(n: int) -> float:
    """The |z| beyond which one of ``n`` known distances' whitened residuals is not met: :data:`DISTANCE_Z`, raised
    where Gaussian noise alone would pass it in more than one calibration in a hundred (``FALSE_ALARM``).

    >>> from kincal.identify.judge import distance_limit
    >>> distance_limit(8), round(distance_limit(10_000), 2)
    (4.0, 4.89)
    """
    low, high = DISTANCE_Z, 40.0
    if max(n, 1) * math.erfc(low / math.sqrt(2.0)) <= FALSE_ALARM:
        return low
    for _ in range(60):  # bisection on n · P(|z| > limit) = FALSE_ALARM
        mid = 0.5 * (low + high)
        low, high = (mid, high) if n * math.erfc(mid / math.sqrt(2.0)) > FALSE_ALARM else (low, mid)
    return high


OVERSTATED = 1.0 / 3.0  # a kind's whitened RMS below this: its stated σ many-fold too large (with the χ² bound)


def overstated_reasons(res: "CalibrationResult", stated: frozenset | set = frozenset()) -> list[Reason]:
    """Kinds whose whitened RMS is below OVERSTATED (1/3) and below 1 by more than SIGNIFICANT standard errors of
    χ²/dof (dof: the kind's rows less their share of the fitted parameters), for a σ the user stated (``stated``:
    the kinds whose σ a fit option gave; a set's σ other than kincal's default): that σ is many-fold too large.
    Suspect: the weak-parameter rule judges "determined worse than a real robot's error" by those σ, so it keeps
    parameters at nominal that the data determine, while the residuals look fine. A σ kincal assumed (a kind's
    default) is not judged so: data more precise than the default (a simulation's) are no fault."""
    labels, kinds = component_kinds(res.observations)
    share = 1.0 - len(res.free) / max(labels.size, 1)
    out = []
    for k, kind in enumerate(kinds):
        rms, rows = res.whitened.get(kind, np.nan), int(np.count_nonzero(labels == k))
        dof = share * rows
        if not (dof > 0 and rms < OVERSTATED and rms**2 * rows / dof < 1.0 - SIGNIFICANT * np.sqrt(2.0 / dof)):
            continue
        flag = _overstated_flag(res, kind, stated)
        if flag is None:
            continue
        factor = float(f"{1.0 / max(rms, 1e-300):.2g}")  # two significant figures: 180, not 1.8e+02
        held = (f"; by that σ {len(res.weak)} parameter(s) were kept at nominal as determined worse than a real "
                f"robot's error (listed above)" if res.weak else "")
        out.append(Reason("suspect", "sigma-overstated", (
            f"the {kind} residuals are {rms:.3g}x their stated σ, far below 1 ({rows} rows): {flag} looks about "
            f"{factor:g}x too large{held}; state the instrument's real noise and refit")))
    return out


SIGMA_FIELD = {"pose position": ("std_pos", 0), "pose rotation": ("std_rot", 1)}  # a kind's σ: its field, and its
# place in the file reader's defaults (observe.files.DEFAULT_STD); other kinds: "std", the position's


def _overstated_flag(res: "CalibrationResult", kind: str, stated: frozenset | set) -> str | None:
    """The σ a kind's residual is whitened by, named by its flag; None when it is kincal's assumption. A joint-space
    residual's is the joints' reading noise and the measured positions' or poses' through the inverse kinematics,
    named by the larger share of the samples' variance (:meth:`~kincal.observe.Observation.covariance` at the fit)."""
    sets = [o for o in res.observations if o.kind == ("pose" if kind.startswith("pose ") else kind)]
    if kind != "joint":
        field, at = SIGMA_FIELD.get(kind, ("std", 0))
        return None if all(_assumed(o, field, at) for o in sets) else STATED.get(kind, "--std-pos")
    reading = through = 0.0
    for obs in sets:
        names, start, _ = obs.nuisance(res.registered)
        nuis = np.array([res.nuisance.get(n, v) for n, v in zip(names, start)], float)
        try:
            C = obs.covariance(res.registered, res.robot.param_values(None), nuis)
        except ModelError:  # a measured pose out of the fitted model's reach: its share is not known
            C = None
        own = float(np.sum(obs.sigma() ** 2))
        reading += own
        through += 0.0 if C is None or not np.all(np.isfinite(C)) else float(np.trace(C, axis1=1, axis2=2).sum()) - own
    if reading >= through:
        return "--std-joint" if "joint" in stated else None
    if all(_assumed(o, "std_pos", 0) and _assumed(o, "std_rot", 1) for o in sets):
        return None
    return "the measured positions' or poses' σ through the inverse kinematics (--std-pos, --std-rot)"


def _assumed(obs, field: str, at: int) -> bool:
    """Whether the σ ``field`` of the set ``obs`` (its innermost set's, under a session's or a drift's wrapper) is
    kincal's default for it: its type's own, the file reader's for its kind (``at``: position 0, rotation 1), or
    for a position the verdict's default tracker noise (position data that state none are fitted with it); True
    for a set without that field."""
    while isinstance(obs, Wrapper):
        obs = obs.inner
    value = vars(obs).get(field)
    if value is None:
        return True
    defaults = [f.default for f in dataclasses.fields(obs) if f.name == field]
    defaults += [DEFAULT_STD.get(obs.kind, (None, None))[at], Thresholds().tracker_noise if at == 0 else None]
    return bool(np.all(np.isin(np.asarray(value, float), [d for d in defaults if isinstance(d, float)])))


def _without_outliers(sets, r: np.ndarray | None, outliers) -> float:
    """The whitened RMS of the residual ``r`` (stacked as ``sets``) without the rows of the outlier samples."""
    if r is None or not any(len(found) for found in outliers):
        return np.inf
    owner, _ = owners(sets)
    first = np.cumsum([0, *[len(obs) for obs in sets]])[:-1]
    bad = np.isin(owner, np.concatenate([found + start for found, start in zip(outliers, first)]))
    return float(np.sqrt(np.mean(r[~bad] ** 2))) if (~bad).any() else np.inf


def _whitened_reason(kind: str, rms: float, whitened: dict, th: Thresholds,
                     stated: frozenset | set = frozenset()) -> Reason:
    """A kind whose residuals are ``rms`` (> 3) times their stated σ: suspect; refused beyond ``th.residual_refuse``
    (the ratio that refuses position data against the tracker noise) when a flag states that σ (an assumed σ is
    not the user's word: suspect only)."""
    assumed = kind in ASSUMED and kind not in stated
    flag = STATED.get(kind, f"--std-joint, {THROUGH}" if kind in stated else ASSUMED.get(kind, "--std-pos"))
    if rms > th.residual_refuse and not assumed:
        return Reason("refused", "residual", f"the {kind} residuals are {rms:.0f}x their stated σ ({flag}): data and "
                                             f"model do not belong together (another robot's or another session's "
                                             f"data in one frame, a moved camera, wrong columns or units), unless "
                                             f"that σ is stated {rms:.0f} times too small")
    fine = [k for k, v in whitened.items() if k != kind and v <= WHITENED_SUSPECT]
    return Reason("suspect", "residual", (
        f"the {kind} residuals are {rms:.1f}x their stated σ ({flag}): the model leaves errors it cannot describe "
        f"there, or that σ is too small" + ("; state it with --std-joint" if assumed else
                                            "; restate it if the instrument is noisier")
        + (f" (the {', '.join(fine)} residuals are within 3x their stated σ)" if fine else "")))


def _diagnosed(res: "CalibrationResult", found: "Diagnosis", verdict: Verdict) -> Verdict:
    """The verdict with the differential diagnosis ``found`` first; a diagnosis that found no cause last, as a note
    (level "note") after the reasons for doubt. Bad poses in a least-squares fit steer the whole model: refused, not
    doubtful, where the diagnosis judged the fit itself (position data, or the whitened residual of other kinds:
    :func:`kincal.identify.diagnosis.diagnose_samples`)."""
    best, itself = found.best, res.data or found.whitened
    status = "refused" if best and best.code == "outliers" and itself and res.options.loss == "linear" \
        else verdict.status
    said = found.message() + ("" if itself else " (screened on the measured positions)")
    if best is None and verdict.reasons:  # no cause found: a note after the reasons for doubt, not one of them
        return Verdict(status, (*verdict.reasons, Reason("note", "cause-unknown", said)))
    reason = Reason(status, f"cause-{best.code}" if best else "cause-unknown", said)
    named = best is not None and best.code == "frame-jump"  # the jump the cause names with its refit: not twice
    framed = best is not None and best.code in FRAME_CAUSES  # the tool point a misplaced frame bent: no advice
    return Verdict(status, (reason, *(r for r in verdict.reasons if not (named and r.code == "frame-jump")
                                      and not (framed and r.code == "tool-point"))))


FRAME_CAUSES = ("frame", "frame-jump", "same-frame")  # diagnosed causes that misplace the frame the tool point is
# fitted in: the tool point they give says nothing of the target (a UR5 session moved 1.2 m fitted in the other's
# frame put it 887 mm from the flange, and advised --tool there)


def sample_norms(sets, r: np.ndarray) -> list[np.ndarray]:
    """Per set, the norm of each sample's whitened residual block (a pose's 6 rows, a marker sample's
    seen markers, a socket seat's 3); rows of no one sample (a known distance) left out."""
    owner, n = owners(sets)
    keep = owner >= 0
    norms = np.sqrt(np.bincount(owner[keep], r[keep] ** 2, minlength=n))
    return np.split(norms, np.cumsum([len(obs) for obs in sets])[:-1])


def owners(sets) -> tuple[np.ndarray, int]:
    """Each stacked row's sample, numbered over all sets (−1: a row of no one sample), and the count."""
    out, n = [], 0
    for obs in sets:
        rows = obs.sample_rows()
        out.append(np.where(rows >= 0, rows + n, -1))
        n += len(obs)
    return np.concatenate(out), n


def block_size(obs) -> int:
    """The residual rows of the set's smallest sample: a plane contact's 1, a point's or a seat's 3, a pose's 6, a
    marker sample's 3 per seen marker, a joint-space sample's one per joint. Its outlier limit is taken at that
    dimension (:meth:`Thresholds.outlier_limit`), the highest of its samples' when they differ."""
    rows = obs.sample_rows()
    counts = np.bincount(rows[rows >= 0], minlength=len(obs))
    return int(max(counts.min(), 1)) if len(obs) else 3


def outlier_samples(sets, r: np.ndarray, th: Thresholds) -> tuple[np.ndarray, ...]:
    """Per set, the indices of its samples whose whitened norm (of ``r``, stacked in the order of
    ``sets``) is more than ``th.outlier_limit`` robust σ off (at its :func:`block_size`); none in a set of fewer
    than MIN_SAMPLES."""
    zs = [robust_z(norms) if len(obs) >= MIN_SAMPLES else np.zeros(len(obs))
          for obs, norms in zip(sets, sample_norms(sets, r))]
    return tuple(np.flatnonzero(z > th.outlier_limit(len(z), block_size(obs))) for obs, z in zip(sets, zs))


def _sample_reasons(sets, outliers, robot: Robot, th: Thresholds) -> list[Reason]:
    """Outlier samples (per set, indices beyond ``th.outlier_limit`` robust σ: :func:`outlier_samples`)
    and repeated poses, per set."""
    out = []
    tol = repeat_tolerance(robot.joint_types, th)
    for obs, found in zip(sets, outliers):
        limit, bad = th.outlier_limit(len(obs), block_size(obs)), obs.rows[found]
        if bad.size:
            out.append(Reason("suspect", "outliers", f"{obs.source}: outlier sample(s) more than {limit:.3g} "
                                                     f"robust σ off: row(s) {listed(bad)}; check them (a blocked line "
                                                     f"of sight, a wrong seat); --reject-outliers leaves them out, "
                                                     f"--loss huber down-weights them"))
        out += duplicate_reasons(obs.rows, duplicate_groups(obs.q, tol), obs.source)
    return out


def _plane_reasons(nominal: Robot, calibrated: Robot, sets) -> list[Reason]:
    """Plane contacts alone never make a fit "good": they see only distances to the planes. When the
    fit moves the predicted points along the planes much more than across them, say so."""
    along, across = [], []
    for obs in sets:
        moved = calibrated.forward(obs.q) - nominal.forward(obs.q)
        # the normals the fit started from (no tilt, the start offsets): changes across them are what moved
        planes = obs.planes(np.array([v for lab in obs.unknown() for v in (0.0, 0.0, obs.start[lab][1])]))
        normal = np.array([planes[lab][0] for lab in obs.labels])
        n_part = np.sum(moved * normal, axis=1)
        across.append(n_part)
        along.append(np.linalg.norm(moved - n_part[:, None] * normal, axis=1))
    a, c = np.concatenate(along), np.concatenate(across)
    rms_a, rms_c = float(np.sqrt(np.mean(a**2))), float(np.sqrt(np.mean(c**2)))
    out = [Reason("suspect", "plane-only",
                  "plane contacts alone: the fit can only make the points lie on the planes; it cannot tell whether the "
                  "robot became more accurate (positions along the planes and the base are not seen); validate with "
                  "absolute data (a tracker, or sockets with a known distance) before trusting it")]
    if rms_a > IN_PLANE_RATIO * max(rms_c, 1e-12):
        out.append(Reason("suspect", "plane-in-plane",
                          f"the fit moved the predicted contact points by {rms_a * MM:.3f} mm RMS along the planes, "
                          f"more than it changed their distances to the planes ({rms_c * MM:.3f} mm RMS): the planes "
                          f"cannot confirm that motion, so the absolute error may have grown while the plane residual "
                          f"fell; check with absolute data"))
    return out
