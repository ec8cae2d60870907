"""Prediction uncertainty of a calibrated model, and the guard against extrapolation.

With the parameter covariance C (K × K, from the fit) the model's predicted position at joint values
q has the covariance J C Jᵀ (J: the 3 × K position Jacobian of the fitted parameters), so its 3-D
standard deviation is σ(q) = sqrt(trace(J C Jᵀ)). Inside the region the calibration poses spanned,
σ(q) stays within what it is over that region: the reference is its 95th percentile over
ENVELOPE_POSES poses drawn evenly in the training joint ranges (a designed set of poses, or a grid
that spans a subspace, has a median σ 1–3× below that of the region it spans). A pose with σ(q)
above ``ENVELOPE_FACTOR`` (1.25) times that reference lies where the data did not constrain the
model: its prediction is an extrapolation (on the real UR5 grid 0.7 % of poses drawn in its own
joint ranges, 24 % of poses drawn in ranges twice as wide); the more flexible the error model, the
less it should be trusted there. A record without the reference (an older calibration) is judged by
``EXTRAPOLATION_RATIO`` (2.5) times the median σ at the training poses.

The training joint ranges (the envelope) are kept too. A model with joint-value terms (harmonics,
compliance, gravity regressor) learned those terms only inside them: a pose with a joint more than
``ENVELOPE_MARGIN`` (2 %) of its training range outside it is named as well. A revolute joint is
compared a whole number of turns away, nearest its training range: the terms are periodic in it, and
a controller's −360° is its 0° (joint 6 at −360° against a ±62° range is inside).
"""
from __future__ import annotations

import dataclasses
from contextlib import suppress
from dataclasses import dataclass

import numpy as np

from .._csv import listed
from .._frozen import freeze_arrays
from ..errors import ModelError
from ..models.robot import Robot
from ..models.yaml_io import load_calibration_record
from ..units import MM, joint_shown

EXTRAPOLATION_RATIO = 2.5
ENVELOPE_FACTOR = 1.25
ENVELOPE_POSES = 2000  # poses drawn in the training joint ranges for the reference σ (seed 0)
ENVELOPE_MARGIN = 0.02
SIGMA_CHUNK = 4096  # poses per parameter Jacobian when computing σ


@dataclass(frozen=True, eq=False)
class ModelUncertainty:
    """The parameter covariance of a calibrated model, and the references its predictions are judged by.

    With the covariance C the predicted position at joint values q has the 3-D standard deviation
    σ(q) = sqrt(trace(J C Jᵀ)) (:meth:`sigma`); a pose whose σ exceeds :meth:`limit` is an extrapolation,
    and with joint-value terms a pose outside the training joint ranges too (:meth:`outside`). Built by
    :meth:`from_fit` (``CalibrationResult.uncertainty()``) or read back with :func:`load_uncertainty`.

    Parameters
    ----------
    names : tuple of str
        The K fitted robot parameters the covariance is over.
    covariance : ndarray, shape (K, K)
        Their covariance, SI (m², rad², m·rad).
    training_median : float
        Median predicted σ at the training poses, m.
    lower : ndarray, shape (n,), optional
        The training joint ranges' lower ends, rad (m for a prismatic joint); None: not recorded
        (default).
    upper : ndarray, shape (n,), optional
        Their upper ends, the same units; None: not recorded (default).
    envelope_sigma : float, optional
        95th percentile of σ over the training joint ranges, m; None: not recorded (default), then
        the limit is :data:`EXTRAPOLATION_RATIO` times ``training_median``.
    measured_point : ndarray, shape (3,), optional
        The point the calibration measured, in the flange frame, m (the references are σ there); None: not
        recorded (default).

    Examples
    --------
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> meas = kincal.simulate(true, robot.sample_joints(30, seed=2), seed=3)
    >>> res = kincal.calibrate(robot, meas, diagnose=False)
    >>> unc = res.uncertainty()
    >>> len(unc.names), unc.covariance.shape
    (26, (26, 26))
    >>> sigma = unc.sigma(res.robot, robot.sample_joints(4, seed=9))  # (N,) m
    >>> sigma.shape, bool(sigma.max() < unc.limit())
    ((4,), True)
    >>> f"limit {unc.limit() * 1e3:.3f} mm", round(unc.limit() / unc.envelope_sigma, 6)  # ENVELOPE_FACTOR x
    ('limit 0.029 mm', 1.25)
    """

    names: tuple[str, ...]
    covariance: np.ndarray
    training_median: float
    lower: np.ndarray | None = None  # (n,) training joint ranges (rad or m); None: not recorded
    upper: np.ndarray | None = None
    envelope_sigma: float | None = None  # 95th percentile of σ over the training joint ranges (m); None: not recorded
    measured_point: np.ndarray | None = None  # (3,) m in the flange frame: where the references' σ are; None: unknown

    def __post_init__(self) -> None:
        freeze_arrays(self)  # the arrays it hands out: what it prints cannot drift from what it computed

    @classmethod
    def from_fit(cls, robot: Robot, names, covariance: np.ndarray, q_train: np.ndarray) -> "ModelUncertainty":
        """The training joint ranges, and the envelope's reference: the 95th percentile of σ at ENVELOPE_POSES
        feasible poses drawn evenly in them (None when fewer than a tenth of them are feasible: coupled joints)."""
        unc = cls(tuple(names), np.asarray(covariance, dtype=float), 0.0)
        lo, hi = q_train.min(axis=0), q_train.max(axis=0)
        median = float(np.median(unc.sigma(robot, q_train)))
        q = np.random.default_rng(0).uniform(lo, hi, size=(ENVELOPE_POSES, len(lo)))
        q = q[robot.feasible(q)]
        try:
            ref = float(np.percentile(unc.sigma(robot, q), 95)) if len(q) >= ENVELOPE_POSES // 10 else None
        except ModelError:  # a pose the model cannot compute (a closed chain outside its workspace)
            ref = None
        return cls(unc.names, unc.covariance, median, lo, hi, ref,
                   robot.tool_point() if robot.has_tool_point else None)

    def without(self, names, robot: Robot) -> "ModelUncertainty":
        """The same uncertainty with the parameters ``names`` left out (their covariance's marginal: the others'
        block), its envelope reference recomputed the same way over the training ranges; for predictions that do
        not depend on them (positions in the robot's base frame do not on the frame the instrument stood in).

        Parameters
        ----------
        names : iterable of str
            The parameters to leave out (those not in it are ignored).
        robot : Robot
            The calibrated robot, for the envelope reference.

        Returns
        -------
        ModelUncertainty
            ``self`` when none of ``names`` is in it.
        """
        keep = [k for k, n in enumerate(self.names) if n not in set(names)]
        return self if len(keep) == len(self.names) else self._over(keep, self.covariance[np.ix_(keep, keep)], robot)

    def given(self, names, robot: Robot) -> "ModelUncertainty":
        """The same uncertainty with the parameters ``names`` taken as known: the others' covariance conditioned on
        them, C_kk − C_kb C_bb⁻¹ C_bk (the Schur complement), its envelope reference recomputed the same way over
        the training ranges; for predictions in a measurement frame registered to the data anew (``names``: the
        base frame's), where the part of the kinematics' error a frame absorbs does not count, nor where the
        instrument stood (a rigid relabelling of the data changes no σ).

        Parameters
        ----------
        names : iterable of str
            The parameters taken as known (those not in it are ignored).
        robot : Robot
            The calibrated robot, for the envelope reference.

        Returns
        -------
        ModelUncertainty
            Over the other parameters; ``self`` when none of ``names`` is in it.

        Examples
        --------
        >>> import numpy as np
        >>> import kincal
        >>> from kincal.analysis import ModelUncertainty
        >>> unc = ModelUncertainty(("base.x", "j2.a"), np.array([[4.0, 2.0], [2.0, 3.0]]) * 1e-8, 1e-4)
        >>> unc.given(["base.x"], kincal.load_robot("ur5")).covariance / 1e-8  # 3 - 2 * 2 / 4
        array([[2.]])
        """
        gone = [k for k, n in enumerate(self.names) if n in set(names)]
        keep = [k for k in range(len(self.names)) if k not in gone]
        if not gone:
            return self
        c = self.covariance
        cross = c[np.ix_(keep, gone)]
        conditioned = c[np.ix_(keep, keep)] - cross @ np.linalg.pinv(c[np.ix_(gone, gone)], hermitian=True) @ cross.T
        return self._over(keep, 0.5 * (conditioned + conditioned.T), robot)

    def _over(self, keep: list[int], covariance: np.ndarray, robot: Robot) -> "ModelUncertainty":
        """The uncertainty over the parameters ``keep`` (indices) with ``covariance`` (K', K'), the envelope's
        reference recomputed with it as :meth:`from_fit` does (kept as it is without the training ranges)."""
        unc = dataclasses.replace(self, names=tuple(self.names[k] for k in keep), covariance=covariance)
        if self.lower is None or self.upper is None or self.envelope_sigma is None:
            return unc
        q = np.random.default_rng(0).uniform(self.lower, self.upper, size=(ENVELOPE_POSES, len(self.lower)))
        q = q[robot.feasible(q)]
        with suppress(ModelError):
            return dataclasses.replace(unc, envelope_sigma=float(np.percentile(unc.sigma(robot, q), 95)))
        return unc

    def on_inputs(self, keep) -> "ModelUncertainty":
        """The same uncertainty with the training ranges of the inputs ``keep`` only (indices into the robot's
        joints and covariates, in order): of a robot without covariates no term reads
        (:func:`kincal.models.without_unread_covariates`); ``self`` without recorded ranges (or fewer than
        ``keep`` reaches)."""
        keep = [int(k) for k in keep]
        if self.lower is None or self.upper is None or not keep or max(keep) >= len(self.lower):
            return self
        return dataclasses.replace(self, lower=self.lower[keep], upper=self.upper[keep])

    def outside(self, q: np.ndarray, revolute: np.ndarray | None = None) -> np.ndarray:
        """(N,) bool: a joint lies outside its training range by more than ENVELOPE_MARGIN of it (the
        ``revolute`` joints, a bool mask, taken the whole turns nearest the range)."""
        if self.lower is None or self.upper is None:
            return np.zeros(len(q), bool)
        q = self.turned(q, revolute)
        margin = ENVELOPE_MARGIN * (self.upper - self.lower)
        return np.any((q < self.lower - margin) | (q > self.upper + margin), axis=1)

    def turned(self, q: np.ndarray, revolute: np.ndarray | None) -> np.ndarray:
        """q (N, n) with each ``revolute`` joint moved by the whole turns that bring it nearest the
        middle of its training range (the same joint position for the robot and its terms)."""
        if revolute is None or self.lower is None or self.upper is None or not np.any(revolute):
            return q
        middle = 0.5 * (self.lower + self.upper)
        turns = np.where(revolute, np.round((q - middle) / (2 * np.pi)), 0.0)
        return q - 2 * np.pi * turns

    def sigma(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """(N,) 3-D standard deviation (m) of the predicted position at joint values q (N, n)."""
        q = robot.check_q(q)
        idx = robot.params.indices(self.names)
        var = np.empty(len(q))
        for a in range(0, len(q), SIGMA_CHUNK):  # Jacobians that stay in cache
            J = robot.param_jacobian(q[a:a + SIGMA_CHUNK])[:, :, idx].reshape(-1, len(idx))  # (3n, K)
            var[a:a + SIGMA_CHUNK] = np.einsum("ik,ik->i", J @ self.covariance, J).reshape(-1, 3).sum(axis=1)
        return np.sqrt(np.maximum(var, 0.0))

    def extrapolated(self, sigma: np.ndarray) -> np.ndarray:
        """(N,) bool: σ above the limit (:meth:`limit`)."""
        return sigma > self.limit()

    def limit(self) -> float:
        """The σ (m) above which a prediction is an extrapolation: ENVELOPE_FACTOR times the training
        region's 95th percentile, else EXTRAPOLATION_RATIO times the training median."""
        return EXTRAPOLATION_RATIO * self.training_median if self.envelope_sigma is None else \
            ENVELOPE_FACTOR * self.envelope_sigma

    def to_dict(self) -> dict:
        out = {"parameters": list(self.names), "covariance": self.covariance.tolist(),
               "training_median_sigma": self.training_median}
        if self.lower is not None and self.upper is not None:
            out["envelope"] = {"lower": self.lower.tolist(), "upper": self.upper.tolist()}
        if self.envelope_sigma is not None:
            out["envelope_sigma"] = self.envelope_sigma
        if self.measured_point is not None:
            out["measured_point"] = self.measured_point.tolist()
        return out

    @classmethod
    def from_dict(cls, data: dict, label: str = "calibration") -> "ModelUncertainty":
        key = "parameters"
        try:
            if not isinstance(data[key], (list, tuple)):  # not a string either
                raise TypeError("a list")
            names = tuple(str(n) for n in data[key])
            key = "covariance"
            cov = np.array(data[key], dtype=float)
            key = "training_median_sigma"
            med = float(data[key])
            key = "envelope"
            env = data.get(key)
            lo, hi = (None, None) if env is None else (np.array(env["lower"], float), np.array(env["upper"], float))
            key = "envelope_sigma"
            ref = None if data.get(key) is None else float(data[key])
            key = "measured_point"
            point = None if data.get(key) is None else np.array(data[key], float).reshape(3)
        except (KeyError, TypeError, ValueError) as exc:
            what = "is missing" if isinstance(exc, KeyError) and str(exc).strip("'") == key else "is malformed"
            raise ModelError(f"{label}: the 'calibration' section's '{key}' {what}; calibrate again or remove the "
                             f"section") from None
        if cov.shape != (len(names), len(names)) or not np.all(np.isfinite(cov)) or not np.isfinite(med) or \
                (ref is not None and not (np.isfinite(ref) and ref > 0)):
            raise ModelError(f"{label}: the 'calibration' covariance must be a finite {len(names)}x{len(names)} "
                             f"matrix; calibrate again or remove the section")
        if lo is not None and hi is not None and (lo.shape != hi.shape or lo.ndim != 1 or not np.all(lo <= hi)):
            raise ModelError(f"{label}: the 'calibration' envelope must give lower <= upper per joint")
        if point is not None and not np.all(np.isfinite(point)):
            raise ModelError(f"{label}: the 'calibration' measured_point must be three finite numbers")
        return cls(names, cov, med, lo, hi, ref, point)


def extrapolation_warning(rows: np.ndarray, sigma: np.ndarray, unc: ModelUncertainty, q: np.ndarray | None = None,
                          robot: Robot | None = None, what: str = "row") -> str | None:
    """A warning naming the poses whose predicted σ says the model extrapolates there — where they lie
    (the joint ranges beyond the training ones, given ``q`` and ``robot``) and their first rows (``what`` they
    are: a program's lines) — or None."""
    bad = unc.extrapolated(sigma)
    if not bad.any():
        return None
    lever = _lever(sigma, bad, unc, q, robot) if q is not None and robot is not None else ""
    if lever:
        return lever
    where = _beyond(q[bad], robot, unc) if q is not None and robot is not None else ""
    words = f": {ENVELOPE_FACTOR:g}x its 95th percentile over the region the calibration poses span" \
        if unc.envelope_sigma is not None else f": {EXTRAPOLATION_RATIO:g}x the median at the training poses"
    return (f"{int(bad.sum())} pose(s) lie where the calibration data did not constrain the model (predicted σ up to "
            f"{sigma[bad].max() * MM:.4f} mm, {sigma[bad].max() / unc.limit():.1f}x the limit {unc.limit() * MM:.4f} mm"
            f"{words}){where}: {what}(s) {listed(rows[bad])}; measure calibration poses there too")


LEVER = 1e-3  # m: a TCP this far from the measured point may owe its σ to the lever, not to the poses


def _lever(sigma: np.ndarray, bad: np.ndarray, unc: ModelUncertainty, q: np.ndarray, robot: Robot) -> str:
    """The warning when the poses' σ is beyond the limit at the TCP but within it at the point the calibration
    measured: the lever from that point to the TCP, through a flange turn the data determine poorly; ''
    otherwise."""
    if unc.measured_point is None or not robot.has_tool_point:
        return ""
    arm = float(np.linalg.norm(robot.tool_point() - unc.measured_point))
    if arm <= LEVER or unc.sigma(robot.with_tool_point(unc.measured_point), q[bad]).max() > unc.limit():
        return ""
    return (f"{int(bad.sum())} pose(s) have a predicted σ at the TCP up to {sigma[bad].max() * MM:.4f} mm "
            f"({sigma[bad].max() / unc.limit():.1f}x the limit {unc.limit() * MM:.4f} mm) where the point the "
            f"calibration measured is within it: the TCP is {arm * MM:.0f} mm from that point and the flange's turn "
            f"that carries it there is poorly determined; measure at the TCP, or at a point off the flange's axis "
            f"(or 6-D poses), rather than more poses")


def _beyond(q: np.ndarray, robot: Robot, unc: ModelUncertainty) -> str:
    """', with j2 at -175.0..-3.0 deg (calibrated on -90.0..-20.0 deg), …' for the joints whose values in
    ``q`` leave the training ranges; '' when none does or the ranges are not known."""
    if unc.lower is None or unc.upper is None or len(unc.lower) != q.shape[1]:
        return ""
    q = unc.turned(q, robot.periodic)
    parts = []
    for j in np.flatnonzero(np.any((q < unc.lower) | (q > unc.upper), axis=0)):
        u, k = joint_shown(robot.joint_types, robot.periodic)[j]  # a multi-turn motor in revolutions
        parts.append(f"{robot.joint_names[j]} at {q[:, j].min() * k:.1f}..{q[:, j].max() * k:.1f} {u} (calibrated on "
                     f"{unc.lower[j] * k:.1f}..{unc.upper[j] * k:.1f} {u})")
    return ", with " + "; ".join(parts) if parts else ", inside the training joint ranges"


def envelope_warning(rows: np.ndarray, q: np.ndarray, robot: Robot, unc: ModelUncertainty) -> tuple[np.ndarray, str | None]:
    """Name the poses outside the training joint ranges of a model with joint-value terms.

    Terms of the joint values (harmonics, compliance, a gravity regressor) were learned only inside the
    training joint ranges; a pose with a joint more than ``ENVELOPE_MARGIN`` (2 %) of its range outside
    (a revolute joint taken the whole turns nearest its range) is an extrapolation. A model without such
    terms, or an uncertainty without the ranges, flags nothing.

    Parameters
    ----------
    rows : ndarray, shape (N,)
        The poses' input rows, for the warning.
    q : ndarray, shape (N, n)
        Joint values of the poses, rad (m for a prismatic joint).
    robot : Robot
        The calibrated model (its joint-value terms, joint names and types).
    unc : ModelUncertainty
        Its uncertainty, with the training joint ranges.

    Returns
    -------
    outside : ndarray of bool, shape (N,)
        The poses outside the training joint ranges (all False without terms or ranges).
    warning : str or None
        A warning naming the joint ranges and the first rows; None when no pose is outside.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.analysis import ModelUncertainty, envelope_warning
    >>> robot = kincal.load_robot("ur5")
    >>> q = np.zeros((3, 6))
    >>> q[1, 2] = 1.5  # j3 at 1.5 rad in the second pose
    >>> model = kincal.extend(robot, "harmonics:1", q)  # terms of the joint values
    >>> # trained on joint ranges of ±1 rad (ModelUncertainty.from_fit records those of a fit's poses)
    >>> trained = ModelUncertainty((), np.zeros((0, 0)), 0.0, lower=np.full(6, -1.0), upper=np.full(6, 1.0))
    >>> outside, warning = envelope_warning(np.array([2, 3, 4]), q, model, trained)
    >>> outside
    array([False,  True, False])
    >>> print(warning)
    1 pose(s) lie outside the joint ranges the terms (harmonics:1) were fitted on, with j3 at 85.9..85.9 deg
    (calibrated on -57.3..57.3 deg): row(s) 3; they extrapolate there
    >>> envelope_warning(np.array([2, 3, 4]), q, robot, trained)  # no joint-value terms: nothing to flag
    (array([False, False, False]), None)
    """
    terms = robot.reading_terms()
    if not terms or unc.lower is None or len(unc.lower) != q.shape[1]:
        return np.zeros(len(q), bool), None
    bad = unc.outside(q, robot.periodic)
    if not bad.any():
        return bad, None
    return bad, (f"{int(bad.sum())} pose(s) lie outside the joint ranges {terms} were fitted on"
                 f"{_beyond(q[bad], robot, unc)}: row(s) {listed(rows[bad])}; they extrapolate there")


def load_uncertainty(name_or_path) -> ModelUncertainty | None:
    """Read the uncertainty saved with a calibrated robot file (its ``calibration:`` section).

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A robot file, or the name of a bundled robot (which has no such section).

    Returns
    -------
    ModelUncertainty or None
        The covariance, training median σ and (when recorded) the training joint ranges; None for a
        file without a ``calibration:`` section.

    Raises
    ------
    ModelError
        When the section is malformed (not a mapping, a missing key, a covariance of the wrong shape or
        not finite, an envelope with lower above upper).

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.analysis import ModelUncertainty, load_uncertainty
    >>> load_uncertainty("ur5") is None  # a bundled robot: no calibration section
    True
    >>> unc = ModelUncertainty(("j2.a", "j3.a"), np.diag([1e-10, 4e-10]), 2e-5)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "ur5_calibrated.yaml")
    ...     kincal.save_robot(kincal.load_robot("ur5"), path, calibration=unc.to_dict())
    ...     back = load_uncertainty(path)
    >>> back.names, back.training_median, back.limit()  # no envelope recorded: 2.5 x the median
    (('j2.a', 'j3.a'), 2e-05, 5e-05)
    """
    section = load_calibration_record(name_or_path)
    return None if section is None else ModelUncertainty.from_dict(section, str(name_or_path))
