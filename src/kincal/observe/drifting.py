"""A measuring instrument that drifts during a set: a set-up parameter of the set, not of the robot.

A tracker or camera creeping while it measures (temperature, a settling tripod) moves every measured position by
s·d: s the sample's place in acquisition (row) order, centred (−½ … +½), d the drift over the whole set
(``drift[<file>].x/y/z``, m). :class:`Drifting` wraps any set of measured positions (points, 6-D poses, markers; in
a session's own frame too) and fits d with the rest. The identifiability rule chooses the robot's parameters first,
so when the row order follows the joints (a grid scanned joint by joint) the drift is named as confounded.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..models.robot import Robot
from .observations import Observation, Wrapper

DRIFT = "drift"  # the kind of a drift's set-up parameters (chosen after the robot's, see the module docstring)


def acquisition(rows: np.ndarray) -> np.ndarray:
    """(N,) place of each sample in row order, centred on 0 and spanning 1 (ties keep input order)."""
    rank = np.argsort(np.argsort(rows, kind="stable")).astype(float)
    return (rank - rank.mean()) / max(len(rows) - 1, 1)


@dataclass(frozen=True, eq=False)
class Drifting(Wrapper):
    """A set measured by an instrument that drifts linearly over the set's row order.

    Every measured position moves by s·d: s the sample's place in acquisition (row) order, centred (−½ … +½),
    d the drift over the whole set (the set-up parameters ``drift[<file>].x/y/z``, m), fitted with the rest.
    Build it with ``Drifting.of(inner)``.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint): the inner set's.
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source``: the inner set's (their order is the acquisition
        order).
    source : str
        Where the data come from: the inner set's (its file name names the drift).
    inner : Observation
        The set of measured positions (points, 6-D poses, markers; in a session's own frame too).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import Drifting, PointObs
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(6, seed=1), seed=0)
    >>> obs = Drifting.of(PointObs(meas.q, meas.rows, "data/run1.csv", xyz=meas.xyz))
    >>> names, start, kinds = obs.nuisance(robot)
    >>> names, start.tolist(), kinds
    (('drift[run1.csv].x', 'drift[run1.csv].y', 'drift[run1.csv].z'), [0.0, 0.0, 0.0], ('drift', 'drift', 'drift'))
    >>> r, Jr, Jn = obs.evaluate(robot, robot.params.values, start)
    >>> Jn.shape, np.round(Jn[:6, 0], 6).tolist()  # x rows: each sample's place in the row order
    ((18, 3), [-0.5, -0.3, -0.1, 0.1, 0.3, 0.5])
    """

    def names(self) -> tuple[str, ...]:
        return tuple(f"drift[{Path(self.source).name}].{a}" for a in "xyz")

    def _corrected(self, d: np.ndarray) -> Observation:
        """The inner set with the drift taken out of its measured positions."""
        return self.inner.shifted(-acquisition(self.rows)[:, None] * d)

    def nuisance(self, robot: Robot):
        names, start, kinds = self.inner.nuisance(robot)
        return tuple(names) + self.names(), np.concatenate([start, np.zeros(3)]), tuple(kinds) + (DRIFT,) * 3

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        r, Jr, Jn = self._corrected(nuis[-3:]).evaluate(robot, values, nuis[:-3])
        axes, owner = self.inner.position_axes(), self.inner.sample_rows()
        Jd = np.zeros((r.size, 3))
        rows = np.flatnonzero(axes >= 0)
        Jd[rows, axes[rows]] = acquisition(self.rows)[owner[rows]]  # r = p − (x − s·d)
        return r, Jr, np.hstack([Jn, Jd])

    def covariance(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> np.ndarray | None:
        return self._corrected(nuis[-3:]).covariance(robot, values, nuis[:-3])

    def sample_errors(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple | None:
        return self._corrected(nuis[-3:]).sample_errors(robot, values, nuis[:-3])

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        return self._corrected(nuis[-3:]).stats(robot, values, nuis[:-3]) | {"drift": [float(v) for v in nuis[-3:]]}
