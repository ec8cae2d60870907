"""Position data, the measured points of a calibration: their error statistics (evaluate, the
studies), the sessions of several files joined or expressed in another's frame, and a fit's points
as the fit kept them (outliers left out, in the first session's frame, drift taken out)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..io.measurements import Measurements
from ..models.robot import Robot
from ..observe.drifting import Drifting, acquisition
from ..observe.sessions import InSession
from ..units import MM


@dataclass(frozen=True)
class EvaluationStats:
    """3-D position error statistics over n poses (m).

    Returned by :func:`evaluate`; with a model's uncertainty also the predicted σ at every pose and
    warnings where the model extrapolates. Printed in mm.

    Parameters
    ----------
    mean : float
        Mean of the error norms, m.
    rms : float
        Root mean square of the error norms, m.
    max : float
        Largest error norm, m.
    std : float
        Standard deviation of the error norms, m.
    p95 : float
        95th percentile of the error norms, m.
    n : int
        Number of poses.
    predicted_sigma : tuple of float or None, optional
        The model's predicted 3-D σ at every pose, m; None (default): no uncertainty given.
    extrapolated_rows : tuple of int, optional
        Input rows of the poses where the model extrapolates (default none).
    warnings : tuple of str, optional
        Warnings naming those poses (default none).

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.identify import EvaluationStats
    >>> stats = EvaluationStats.from_errors(np.array([[3e-6, 4e-6, 0.0], [0.0, 0.0, 10e-6]]))  # (N, 3) m
    >>> print(stats)
    n=2  mean 0.0075 mm  rms 0.0079 mm  max 0.0100 mm  std 0.0025 mm  p95 0.0097 mm
    >>> sorted(stats.to_dict())
    ['max', 'mean', 'n', 'p95', 'rms', 'std', 'warnings']
    """

    mean: float
    rms: float
    max: float
    std: float
    p95: float
    n: int
    predicted_sigma: tuple[float, ...] | None = None
    extrapolated_rows: tuple[int, ...] = ()
    warnings: tuple[str, ...] = ()

    @classmethod
    def from_errors(cls, err: np.ndarray) -> "EvaluationStats":
        e = np.linalg.norm(np.asarray(err, dtype=float).reshape(-1, 3), axis=1)
        return cls(float(e.mean()), float(np.sqrt(np.mean(e**2))), float(e.max()), float(e.std()),
                   float(np.percentile(e, 95)), int(e.size))

    def to_dict(self) -> dict:
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}
        if self.predicted_sigma is None:
            del out["predicted_sigma"], out["extrapolated_rows"]
        return out

    def __str__(self) -> str:
        text = (f"n={self.n}  mean {self.mean * MM:.4f} mm  rms {self.rms * MM:.4f} mm  max {self.max * MM:.4f} mm"
                f"  std {self.std * MM:.4f} mm  p95 {self.p95 * MM:.4f} mm")
        if self.predicted_sigma is not None:
            s = np.asarray(self.predicted_sigma)
            text += f"\n  model's predicted σ at these poses: median {np.median(s) * MM:.4f} mm, max {s.max() * MM:.4f} mm"
        return text + "".join(f"\n  warning: {w}" for w in self.warnings)


def kept_positions(fit, sessions: list[Measurements]):
    """The poses ``fit`` (a :class:`~kincal.identify.CalibrationResult`) fitted (outliers left out) in the first session's frame, their position errors
    measured − predicted (N, 3) m (a fitted drift taken out), and the drift per axis (or None)."""
    parts, errs, drift = [], [], None
    for obs, s in zip(fit.observations, sessions):
        kept = s.subset(np.flatnonzero(np.isin(s.rows, obs.rows)))
        frame, inner, offset = session_frame(fit, obs), obs, np.zeros((len(kept), 3))
        if isinstance(inner, InSession):
            inner = inner.inner
        if isinstance(inner, Drifting):
            d = np.array([fit.nuisance[n] for n in inner.names()])
            offset = acquisition(inner.rows)[:, None] * d
            drift = drift or {a: {"value": float(v), "std": float(fit.std[n])}
                              for a, v, n in zip("xyz", d, inner.names())}
        parts.append(in_frame_of(fit.robot, frame, kept))
        errs.append(in_frame_of(fit.robot, frame, dataclasses.replace(kept, xyz=kept.xyz - offset)).xyz
                    - fit.robot.forward(kept.q))
    return joined(parts), np.concatenate(errs), drift


def session_frame(fit, obs) -> Robot:
    """The calibrated model of ``fit`` (a :class:`~kincal.identify.CalibrationResult`) as it sees the fitted set
    ``obs``: with the frame fitted for its session when the set is in a session's own frame, else ``fit.robot``."""
    if not isinstance(obs, InSession):
        return fit.robot
    return fit.robot.with_params({b: fit.nuisance[f"frame[{obs.session}].{b}"] for b in fit.robot.base_params()})


def in_frame_of(model: Robot, registered: Robot, meas: Measurements) -> Measurements:
    """``meas`` (taken in the frame where ``registered`` sees the robot) expressed in ``model``'s frame."""
    if registered is model:
        return meas
    R0, t0 = model.base_transform()
    Rs, ts = registered.base_transform()
    std = None if meas.std is None else np.sqrt(meas.std**2 @ (Rs @ R0.T) ** 2)  # per-axis variances, rotated
    return dataclasses.replace(meas, xyz=(meas.xyz - ts) @ Rs @ R0.T + t0, std=std)


def joined(sessions: list[Measurements]) -> Measurements:
    """Join several sessions into one set of measurements.

    Their rows keep their own files' line numbers; each pose is labelled with its session's source (a
    repeated source gets its position added, ``"a.csv (2)"``), so held-out sessions can be told apart.
    The positions are joined as given: use this for sessions measured in one frame
    (:func:`calibrate_sessions` fits each later session's frame).

    Parameters
    ----------
    sessions : list of Measurements
        The sessions, with the same joints.

    Returns
    -------
    Measurements
        All poses in order, ``source`` the sources joined by ``" + "``, ``session`` the labels; one
        session is returned as it is.

    Examples
    --------
    >>> import kincal
    >>> from kincal.identify import joined
    >>> robot = kincal.load_robot("ur5")
    >>> a = kincal.simulate(robot, robot.sample_joints(3, seed=1))
    >>> b = kincal.simulate(robot, robot.sample_joints(2, seed=2))
    >>> both = joined([a, b])
    >>> len(both), both.rows.tolist()
    (5, [2, 3, 4, 2, 3])
    >>> both.sessions()
    ('simulated ur5', 'simulated ur5 (2)')
    """
    if len(sessions) == 1:
        return sessions[0]
    std = None if any(s.std is None for s in sessions) else np.concatenate([s.std for s in sessions])
    labels = [s.source if s.source not in [t.source for t in sessions[:i]] else f"{s.source} ({i + 1})"
              for i, s in enumerate(sessions)]
    return Measurements(np.concatenate([s.q for s in sessions]), np.concatenate([s.xyz for s in sessions]),
                        sessions[0].joint_names, " + ".join(s.source for s in sessions),
                        np.concatenate([s.rows for s in sessions]), std, sessions[0].units,
                        np.concatenate([np.full(len(s), name) for s, name in zip(sessions, labels)]))


EXACT = 1e-9  # m: a validation error below this is round-off (no noise, an exact model)


def e_statistics(point_errors: dict) -> dict[str, tuple[float, float, float]]:
    """Per model the paper's Table 8 statistics of e (the signed average of the three axis errors)
    over the validation points: max |e|, mean |e|, std e (m)."""
    means = {k: np.asarray(err).mean(axis=1) for k, err in point_errors.items()}
    return {k: (float(np.max(np.abs(e))), float(np.mean(np.abs(e))), float(np.std(e, ddof=1)))
            for k, e in means.items()}
