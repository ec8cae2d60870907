"""Whose flange orientation pose commands follow: the calibrated model's where its data determine it.

Position data see the flange's orientation only through the lever from the flange to the measured point. With
a long lever (a reflector 150 mm out) the calibrated model's turn of the flange is measured to a few hundredths
of a mrad and is worth following; with the point on the flange's axis near the flange (a UR5's 31 mm) the
parameters that turn the flange are fitted in combinations the positions cannot tell apart, and the turn they
imply is noise several mrad wide. 6-D poses and several markers see the turn directly. :func:`flange_turn`
weighs the calibrated model's turn from the nominal model against its standard deviation, over poses of the
calibration's joint ranges, both relative to each model's base (where the tracker stood is not a turn of the
robot). That σ is the calibration's covariance and what the estimated parameters took up of the real errors of
those kept at nominal (weakly determined, or not identifiable), as large as a real robot's: a FANUC LR Mate
measured 30 mm out on the flange's axis fits j5.theta to a j5.a error it cannot see, and turns the flange by it.
A kept parameter's own turn is in both models alike and does not count; those of its turns the estimated
parameters do not take up are named: neither model corrects them. 6-D poses and several markers see the turn, so
after them the covariance alone is its σ. The decision is one for all commands, so it weighs the whole turn
against the whole σ (a test per direction would follow a turn mostly noise for a part well determined).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..models.parameters import SUSPECT
from ..models.robot import Robot
from ..models.transforms import rotation_log

TURN_Z = 3.0  # the calibrated turn is followed when it is at least this many standard deviations
TURN_POSES = 200  # poses the turn and its σ are taken over (uniform in the calibration's joint ranges, seed 0)
TURN_TRIES = 20  # rounds of TURN_POSES draws at most, for a parallel robot whose legs' ranges do not all assemble
FD_STEP = 1e-6  # rad or m: the parameter step of the rotation's finite differences
UNCORRECTED = 0.5  # rad/rad: a kept angle that turns the flange by this much of itself (RMS), not taken up by the
# estimated parameters, is named as a turn neither model corrects


@dataclass(frozen=True)
class FlangeTurn:
    """How far a calibrated model turns the flange from the nominal model, and how well its data determine it.

    Parameters
    ----------
    change : float
        The RMS over the poses of the calibrated flange's rotation from the nominal one, rad.
    sigma : float
        The RMS over the poses of that rotation's standard deviation, rad: the calibration's covariance with what
        the estimated parameters took up of the errors of those kept at nominal (:func:`flange_turn`); inf when
        the calibration recorded no covariance.
    determined : bool
        ``change`` is at least ``TURN_Z`` (3) times ``sigma``: pose commands follow the calibrated flange.
    rotations_seen : bool, optional
        The calibration's data saw rotations (6-D poses, several markers): the note's advice is then not to
        measure them (default False).
    uncorrected : tuple of str, optional
        Angles kept at nominal whose turn of the flange the estimated parameters do not take up: neither model
        corrects it, and ``sigma`` does not cover it (default none).

    See Also
    --------
    flange_turn : Makes it.
    """

    change: float
    sigma: float
    determined: bool
    rotations_seen: bool = False
    uncorrected: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The fields, rad, with ``sigma`` None where it is not known (JSON has no inf)."""
        return {"change": self.change, "sigma": self.sigma if np.isfinite(self.sigma) else None,
                "determined": self.determined, "uncorrected": list(self.uncorrected)}

    def note(self) -> str:
        """One line for the user: whose orientation the commands follow and why (mrad)."""
        sigma = f"{self.sigma * 1e3:.3f} mrad" if np.isfinite(self.sigma) else "unknown: no covariance recorded"
        unseen = "" if not self.uncorrected else (
            f"; neither model corrects the flange's turns by {', '.join(self.uncorrected)} (kept at nominal, not "
            f"determined by the data; not in σ)")
        if self.determined:
            return (f"orientation: from the calibrated model, whose data determine its turn of the flange "
                    f"({self.change * 1e3:.3f} mrad from the nominal model, σ {sigma}){unseen}")
        what = ("the data saw rotations, yet in the robot's own frame they leave it open: poses spread over more of "
                "the joints' ranges, or targets in the measurement frame" if self.rotations_seen else
                "6-D poses or several markers, or a measured point further from the flange's axis, at poses spread "
                "over more of the joints' ranges")
        return (f"orientation: as the nominal model turns the flange; the calibrated model's turn of it "
                f"({self.change * 1e3:.3f} mrad from the nominal model, σ {sigma}) is within {TURN_Z:g}σ, not told "
                f"apart from noise, so the commands correct the positions with the calibrated model only, where it "
                f"measured them: a TCP beyond the measured point is carried on from it by the nominal turn (what "
                f"determines it: {what}){unseen}")


def flange_turn(calibrated: Robot, nominal: Robot, covariance: np.ndarray | None, names, lower: np.ndarray,
                upper: np.ndarray, rotations_seen: bool = False) -> FlangeTurn:
    """Weigh the calibrated model's turn of the flange against what its data determine (module docstring).

    Parameters
    ----------
    calibrated : Robot
        The calibrated model.
    nominal : Robot
        The nominal model, the same structure.
    covariance : ndarray, shape (K, K) or None
        The calibration's covariance of the parameters ``names`` (m and rad); None: not recorded.
    names : sequence of str
        The K parameters of ``covariance``, the ones the calibration estimated; the others were kept at nominal
        (weakly determined, or not identifiable). The base frame's turn is left out (a turn of the base is not the
        flange's).
    lower, upper : ndarray, shape (n,)
        The joint ranges the poses are drawn from (the calibration's), rad (m for a prismatic joint).
    rotations_seen : bool, optional
        The calibration's data saw rotations (6-D poses, several markers): they see the turn itself, so the
        estimated parameters cannot take up those kept at nominal with a turn the data do not show, and the
        covariance alone is the turn's σ (default False: positions of one point).

    Returns
    -------
    FlangeTurn
        The RMS turn and its σ, rad, whether the turn is determined, and the parameters kept at nominal whose turn
        of the flange neither model corrects.

    Examples
    --------
    A UR5 calibrated from a point 31 mm out on the flange's axis, and with the point 120 mm out and off the
    axis: the first leaves the turn undetermined, the second determines it. Neither sees a turn about the flange's
    axis (j6.theta acts like a move of the measured point) nor j6.alpha's: neither model corrects them.

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import flange_turn
    >>> for tool in ([0, 0, 0.031], [0.03, -0.02, 0.12]):
    ...     nominal = kincal.load_robot("ur5").with_tool_point(tool)
    ...     q = nominal.sample_joints(200, seed=1)
    ...     data = kincal.simulate(kincal.perturb(nominal, seed=2), q, 15e-6, 1)
    ...     fit = kincal.calibrate(nominal, data, kincal.FitOptions(diagnose=False))
    ...     unc = fit.uncertainty()
    ...     turn = flange_turn(fit.robot, nominal, unc.covariance, unc.names, nominal.lower, nominal.upper)
    ...     print(turn.determined, round(turn.change / turn.sigma, 1), turn.uncorrected)
    False 0.5 ('j6.theta', 'j6.alpha')
    True 22.2 ('j6.theta', 'j6.alpha')
    """
    q = poses_in(calibrated, lower, upper, nominal)
    turn = _relative(calibrated, q, None, nominal)
    change = float(np.sqrt(np.mean(np.sum(turn**2, axis=1))))
    if covariance is None:
        return FlangeTurn(change, np.inf, False, rotations_seen)
    names = tuple(names)
    added, uncorrected = (0.0, ()) if rotations_seen else _kept(calibrated, q, names)
    sigma = float(np.sqrt(_sigma(calibrated, q, np.asarray(covariance, float), names) ** 2 + added))
    return FlangeTurn(change, sigma, bool(change >= TURN_Z * sigma), rotations_seen, uncorrected)


def _kept(robot: Robot, q: np.ndarray, names: tuple[str, ...]) -> tuple[float, tuple[str, ...]]:
    """What the parameters kept at nominal (weakly determined, or not identifiable) add to the turn's variance
    (rad²) when the commands follow the calibrated model, and those kept angles whose turn of the flange the estimated
    parameters ``names`` do not take up (in the robot's order).

    A kept parameter k keeps its real error e in the true robot, which turns the flange by J_k·e. The fit moves the
    estimated ones by A_k·e, A the least-squares regression of the kept ones' position columns on the estimated
    ones' at the measured point over ``q``, and so turns the calibrated flange by J·A_k·e. The commands that follow
    it miss by (J_k − J·A_k)·e, those that keep the nominal turn by J_k·e: following adds
    E|(J_k − J·A_k)·e|² − E|J_k·e|² (RMS over q) with e of the size of a real robot's largest error (the verdict's
    suspect limits, 10 mm and 2 deg; a compliance, the deflection at 100 N·m, as the verdict sizes it: 2 deg at the
    largest load at q, :meth:`~kincal.Robot.correction_scales`), or nothing where that is negative (the fit took up
    the kept one's turn with its position: following corrects it). A kept angle is named when at least half its
    turn (RMS) is left."""
    base = set(robot.base_params())
    kept = [n for n in robot.params.names if n not in names and n not in base]
    if not kept:
        return 0.0, ()
    est, out = robot.params.indices(list(names)), robot.params.indices(kept)
    P = robot.param_jacobian(q).reshape(-1, robot.n_params)
    scale = np.maximum(np.linalg.norm(P[:, est], axis=0), 1e-300)
    A = np.linalg.lstsq(P[:, est] / scale, P[:, out], rcond=None)[0] / scale[:, None]
    kinds, mounting = dict(zip(robot.params.names, robot.params.kinds)), set(robot.mounting_params())
    scales = robot.correction_scales(q)  # a compliance: its deflection per unit of its value at q's largest load
    limit = np.array([SUSPECT["mounting" if n in mounting else kinds[n]] / max(scales.get(n, (1.0, ""))[0], 1e-300)
                      for n in kept])
    J = _turn_jacobian(robot, q, [*names, *kept])
    own, moved = J[:, :, len(names):], np.einsum("nik,km->nim", J[:, :, :len(names)], A)  # the base's turn in it
    share = np.sqrt(np.mean(np.sum((own - moved) ** 2, axis=1), axis=0))
    moved = np.einsum("nik,km->nim", J[:, :, :len(names)] * [n not in base for n in names], A)  # relative to it
    added = np.mean(np.sum(moved**2 - 2 * moved * own, axis=1), axis=0) * limit**2
    return float(np.sum(np.maximum(added, 0.0))), tuple(
        n for n, s in zip(kept, share) if kinds[n] == "angle" and s >= UNCORRECTED)


def poses_in(robot: Robot, lower: np.ndarray, upper: np.ndarray, *others: Robot) -> np.ndarray:
    """TURN_POSES joint vectors (N, n), uniform in [lower, upper] within the robot's limits, seed 0, where the robot
    (and each of ``others``) assembles: a parallel robot's legs drawn each in its own range often do not (a serial
    arm's always do: its first TURN_POSES draws). Fewer when fewer than TURN_POSES of TURN_TRIES rounds assemble;
    ModelError when none does."""
    lo, hi = np.maximum(lower, robot.lower), np.minimum(upper, robot.upper)
    lo, hi = np.where(hi >= lo, lo, robot.lower), np.where(hi >= lo, hi, robot.upper)
    rng, kept = np.random.default_rng(0), []
    for _ in range(TURN_TRIES):
        q = lo + rng.random((TURN_POSES, robot.n_joints)) * (hi - lo)
        ok = robot.feasible(q)
        for other in others:
            ok &= other.feasible(q)
        kept.append(q[ok])
        if sum(len(k) for k in kept) >= TURN_POSES:
            break
    q = np.concatenate(kept)[:TURN_POSES]
    if not len(q):
        raise ModelError(f"{robot.name}: none of {TURN_TRIES * TURN_POSES} poses drawn in the calibration's joint "
                         f"ranges assembles; the calibrated file's joint ranges do not fit its model")
    return q


def _base_rotation(robot: Robot) -> np.ndarray:
    """The base frame's rotation (3, 3) (the identity for a robot without one)."""
    return robot.base_transform()[0] if robot.base_params() else np.eye(3)


def _relative(robot: Robot, q: np.ndarray, values: np.ndarray | None, other: Robot) -> np.ndarray:
    """(N, 3) rad: the rotation vectors from ``other``'s flange to ``robot``'s (at ``values``, its base frame's
    parameters as they are) at q, each relative to its own base."""
    Ra = _base_rotation(robot).T @ robot.flange_rotation(q, values)
    Rb = _base_rotation(other).T @ other.flange_rotation(q)
    return rotation_log(Ra @ np.swapaxes(Rb, 1, 2))


def _turn_jacobian(robot: Robot, q: np.ndarray, names) -> np.ndarray:
    """(N, 3, K) rad per unit: forward differences of the flange's rotation relative to the base in each parameter
    of ``names``, the base frame held where it is (a base parameter's column is then the turn of the base)."""
    v0 = robot.param_values(None)
    B, back = _base_rotation(robot), np.swapaxes(robot.flange_rotation(q), 1, 2)
    J = np.empty((len(q), 3, len(names)))
    for j, i in enumerate(robot.params.indices(list(names))):
        v = v0.copy()
        v[i] += FD_STEP
        J[:, :, j] = rotation_log(B.T @ robot.flange_rotation(q, v) @ back @ B) / FD_STEP  # as _relative
    return J


def _sigma(robot: Robot, q: np.ndarray, covariance: np.ndarray, names: tuple[str, ...]) -> float:
    """The RMS over q of the turn's standard deviation (rad): the turn's Jacobian in each parameter but the base
    frame's (:func:`_turn_jacobian`), through the covariance."""
    keep = [k for k, n in enumerate(names) if n not in set(robot.base_params())]
    J = _turn_jacobian(robot, q, [names[k] for k in keep])
    C = covariance[np.ix_(keep, keep)]
    return float(np.sqrt(np.mean(np.einsum("nik,kl,nil->n", J, C, J))))
