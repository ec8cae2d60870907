"""A base drift over acquisition order: the tracker (or the robot's base) creeping during a session.

With ``calibrate(drift=True)`` the measured positions are modelled as p(q) + s·d, s the pose's
place in acquisition order (input row order, centred: −½ … +½) and d = ``drift.x/y/z`` (m) the
drift over the whole session. Inside the fit the robot carries s as an extra joint value, so the
identifiability analysis, LM and covariance treat d like any parameter: when the poses were taken
in an order that follows the joints (a grid scanned joint by joint), d is confounded with the
geometry and is named as such instead of being fitted. The calibrated robot is returned without
the drift (it belongs to that session, not to the robot); ``result.drift`` reports it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..io.measurements import Measurements
from ..models.parameters import Parameters
from ..models.robot import JointSpace, Robot
from ..models.wrapped import Wrapped

NAMES = ("drift.x", "drift.y", "drift.z")
ORDER = "acquisition"


def acquisition(rows: np.ndarray) -> np.ndarray:
    """(N,) place of each pose in row order, centred on 0 and spanning 1 (ties keep input order)."""
    rank = np.empty(len(rows))
    rank[np.argsort(rows, kind="stable")] = np.arange(len(rows))
    return (rank - rank.mean()) / max(len(rows) - 1, 1)


@dataclass(frozen=True, eq=False, repr=False)
class DriftRobot(Wrapped):
    """``inner`` plus a drift d·s, s the last joint value (see the module docstring)."""

    joint_space: JointSpace = field(init=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        js = self.inner.joint_space
        object.__setattr__(self, "joint_space", JointSpace((*js.names, ORDER), (*js.types, "prismatic"),
                                                           np.append(js.lower, -1.0), np.append(js.upper, 1.0)))

    @classmethod
    def build(cls, inner: Robot) -> "DriftRobot":
        p = inner.params
        return cls(inner, Parameters(list(p.names) + list(NAMES), list(p.values) + [0.0] * 3,
                                     list(p.kinds) + ["length"] * 3))

    @property
    def structure(self) -> str:
        return f"{self.inner.structure} + drift"

    def _forward_and_jacobian(self, q, values, jacobian):
        inner_values, d = self._split(values)
        p, J = self.inner.forward_and_jacobian(q[:, :-1], inner_values, jacobian)
        p = p + q[:, -1:] * d
        if not jacobian:
            return p, None
        return p, np.concatenate([J, q[:, -1, None, None] * np.eye(3)], axis=2)

    def _joint_jacobian(self, q, values):
        inner_values, d = self._split(values)
        J = self.inner.joint_jacobian(q[:, :-1], inner_values)
        return np.concatenate([J, np.broadcast_to(d[:, None], (len(q), 3, 1))], axis=2)


def with_drift(robot: Robot, meas: Measurements) -> tuple[DriftRobot, Measurements]:
    """The robot with the drift term, and the measurements with their acquisition place as a joint."""
    q = np.column_stack([meas.q, acquisition(meas.rows)])
    return DriftRobot.build(robot), Measurements(q, meas.xyz, (*meas.joint_names, ORDER), meas.source, meas.rows,
                                                 meas.std, meas.units)


def without_drift(res, robot: Robot, meas: Measurements):
    """A result fitted with the drift term, as a result for ``robot`` itself (drift in ``res.drift``)."""
    keep = [k for k, n in enumerate(res.names) if n not in NAMES]
    drift = {n.split(".")[1]: {"value": res.estimates[n], "std": res.std[n]} for n in NAMES if n in res.names}
    drop = lambda d: {k: v for k, v in d.items() if k not in NAMES}  # noqa: E731
    sub = np.ix_(keep, keep)
    return dataclasses.replace(
        res, robot=res.robot.inner, nominal=robot, names=tuple(res.names[k] for k in keep),
        estimates=drop(res.estimates), corrections=drop(res.corrections), std=drop(res.std),
        correlation=res.correlation[sub], covariance=None if res.covariance is None else res.covariance[sub],
        measurements=meas, drift=drift or None)
