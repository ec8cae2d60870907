"""Whose flange orientation pose commands follow: the calibrated model's where its data determine it.

Position data see the flange's orientation only through the lever from the flange to the measured point. With
a long lever (a reflector 150 mm out) the calibrated model's turn of the flange is measured to a few hundredths
of a mrad and is worth following; with the point on the flange's axis near the flange (a UR5's 31 mm) the
parameters that turn the flange are fitted in combinations the positions cannot tell apart, and the turn they
imply is noise several mrad wide. 6-D poses and several markers see the turn directly. :func:`flange_turn`
weighs the calibrated model's turn from the nominal model against its standard deviation from the calibration's
covariance, over poses of the calibration's joint ranges, both relative to each model's base (where the tracker
stood is not a turn of the robot).
"""
from __future__ import annotations

from dataclasses import dataclass

from typing import Mapping

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot
from ..models.transforms import rotation_log

TURN_Z = 3.0  # the calibrated turn is followed when it is at least this many standard deviations
TURN_POSES = 200  # poses the turn and its σ are taken over (uniform in the calibration's joint ranges, seed 0)
TURN_TRIES = 20  # rounds of TURN_POSES draws at most, for a parallel robot whose legs' ranges do not all assemble
FD_STEP = 1e-6  # rad or m: the parameter step of the rotation's finite differences


@dataclass(frozen=True)
class FlangeTurn:
    """How far a calibrated model turns the flange from the nominal model, and how well its data determine it.

    Parameters
    ----------
    change : float
        The RMS over the poses of the calibrated flange's rotation from the nominal one, rad.
    sigma : float
        The RMS over the poses of that rotation's standard deviation (the calibration's covariance), rad; inf
        when the calibration recorded no covariance.
    determined : bool
        ``change`` is at least ``TURN_Z`` (3) times ``sigma``: pose commands follow the calibrated flange.
    rotations_seen : bool, optional
        The calibration's data saw rotations (6-D poses, several markers): the note's advice is then not to
        measure them (default False).

    See Also
    --------
    flange_turn : Makes it.
    """

    change: float
    sigma: float
    determined: bool
    rotations_seen: bool = False

    def to_dict(self) -> dict:
        """The fields, rad, with ``sigma`` None where it is not known (JSON has no inf)."""
        return {"change": self.change, "sigma": self.sigma if np.isfinite(self.sigma) else None,
                "determined": self.determined}

    def note(self) -> str:
        """One line for the user: whose orientation the commands follow and why (mrad)."""
        sigma = f"{self.sigma * 1e3:.3f} mrad" if np.isfinite(self.sigma) else "unknown: no covariance recorded"
        if self.determined:
            return (f"orientation: from the calibrated model, whose data determine its turn of the flange "
                    f"({self.change * 1e3:.3f} mrad from the nominal model, σ {sigma})")
        what = ("the data saw rotations, yet in the robot's own frame they leave it open: poses spread over more of "
                "the joints' ranges, or targets in the measurement frame" if self.rotations_seen else
                "6-D poses or several markers, or a measured point further from the flange's axis, at poses spread "
                "over more of the joints' ranges")
        return (f"orientation: as the nominal model turns the flange; the calibrated model's turn of it "
                f"({self.change * 1e3:.3f} mrad from the nominal model, σ {sigma}) is within {TURN_Z:g}σ, not told "
                f"apart from noise, so the commands correct the positions with the calibrated model only (what "
                f"determines it: {what})")


def flange_turn(calibrated: Robot, nominal: Robot, covariance: np.ndarray | None, names, lower: np.ndarray,
                upper: np.ndarray, held: Mapping[str, float] | None = None) -> FlangeTurn:
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
        The K parameters of ``covariance``; the base frame's are left out (a turn of the base is not the flange's).
    lower, upper : ndarray, shape (n,)
        The joint ranges the poses are drawn from (the calibration's), rad (m for a prismatic joint).
    held : mapping of str to float, optional
        Parameters the calibration kept at nominal because its data determine them too weakly, with the σ the data
        gave them (m or rad: the record's ``weakly_determined``): their turn of the flange is as unknown as that σ
        says, so it counts in the turn's σ (default none).

    Returns
    -------
    FlangeTurn
        The RMS turn and its σ, rad, and whether the turn is determined.

    Examples
    --------
    A UR5 calibrated from a point 31 mm out on the flange's axis, and with the point 120 mm out and off the
    axis: the first leaves the turn undetermined, the second determines it.

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
    ...     print(turn.determined, round(turn.change / turn.sigma, 1))
    False 0.5
    True 22.2
    """
    q = poses_in(calibrated, lower, upper, nominal)
    turn = _relative(calibrated, q, None, nominal)
    change = float(np.sqrt(np.mean(np.sum(turn**2, axis=1))))
    if covariance is None:
        return FlangeTurn(change, np.inf, False)
    names, covariance = _with_held(calibrated, tuple(names), np.asarray(covariance, float), held or {})
    sigma = _sigma(calibrated, q, covariance, names)
    return FlangeTurn(change, sigma, bool(change >= TURN_Z * sigma))


def _with_held(robot: Robot, names: tuple[str, ...], covariance: np.ndarray, held: Mapping[str, float]):
    """``names`` and ``covariance`` with the held parameters' σ² on the diagonal beside them (each independent)."""
    extra = [n for n, v in held.items() if n not in names and n in robot.params.names and np.isfinite(v)]
    if not extra:
        return names, covariance
    k = len(names)
    out = np.zeros((k + len(extra), k + len(extra)))
    out[:k, :k] = covariance
    out[k:, k:] = np.diag([float(held[n]) ** 2 for n in extra])
    return (*names, *extra), out


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


def _sigma(robot: Robot, q: np.ndarray, covariance: np.ndarray, names: tuple[str, ...]) -> float:
    """The RMS over q of the turn's standard deviation (rad): forward differences of the flange's rotation
    relative to the base in each parameter but the base frame's, through the covariance."""
    keep = [k for k, n in enumerate(names) if n not in set(robot.base_params())]
    v0 = robot.param_values(None)
    idx = robot.params.indices([names[k] for k in keep])
    B, back = _base_rotation(robot), np.swapaxes(robot.flange_rotation(q), 1, 2)  # the base frame's parameters held
    J = np.empty((len(q), 3, len(keep)))
    for j, i in enumerate(idx):
        v = v0.copy()
        v[i] += FD_STEP
        J[:, :, j] = rotation_log(B.T @ robot.flange_rotation(q, v) @ back @ B) / FD_STEP  # as _relative, relative to
        # the base
    C = covariance[np.ix_(keep, keep)]
    return float(np.sqrt(np.mean(np.einsum("nik,kl,nil->n", J, C, J))))
