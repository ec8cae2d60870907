"""Markers: several points on the flange seen at once (motion capture, reflectors on a nest), each
an unknown point of the set-up, so the robot's own tool point is a gauge freedom."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..models.robot import TOOL_NAMES, Robot
from ..models.unit_checks import Framed
from .observations import Observation, error_stats, flange_point


@dataclass(frozen=True, eq=False)
class MarkersObs(Observation):
    """k markers per sample (motion capture, several reflectors on a nest), measured in the measurement frame.

    Each marker is an unknown point on the flange (the set-up parameters ``marker[<name>].x/y/z``, m), so
    the robot's own tool point is a gauge freedom here. The residual is each seen marker's predicted −
    measured position: marker by marker, its x rows, then y, then z.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    xyz : ndarray, shape (N, k, 3)
        The measured markers, m; NaN where a marker was not seen.
    names : tuple of str
        The markers' names, one per marker.
    start : ndarray, shape (k, 3), optional
        Start values of the marker points in the flange frame, m (default None: :meth:`prepare` sets them
        from the data; without it, the tool point).
    std : ndarray, shape (N,), or float, optional
        σ per axis, per sample or one number, m (default 15e-6).

    Examples
    --------
    Two markers on the flange of the nominal "ur5", seen without noise:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import simulate_markers
    >>> robot = kincal.load_robot("ur5")
    >>> obs = simulate_markers(robot, robot.sample_joints(5, seed=1), [[0.05, 0.0, 0.1], [0.0, 0.05, 0.1]],
    ...                        std=0.0)
    >>> type(obs).__name__, obs.xyz.shape, obs.names, obs.gauge_params(robot)
    ('MarkersObs', (5, 2, 3), ('m1', 'm2'), ('tool.x', 'tool.y', 'tool.z'))
    >>> obs.nuisance(robot)[0][:3]
    ('marker[m1].x', 'marker[m1].y', 'marker[m1].z')
    >>> bool(np.allclose(obs.prepare(robot).start, [[0.05, 0.0, 0.1], [0.0, 0.05, 0.1]]))
    True
    """

    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 1, 3)))
    names: tuple[str, ...] = ()
    start: np.ndarray | None = None  # (k, 3) m: start values of the marker points (default: the tool point)
    std: np.ndarray | float = 15e-6  # m, one number or per sample
    kind = "markers"

    def seen(self) -> np.ndarray:
        return np.all(np.isfinite(self.xyz), axis=2)  # (N, k)

    def _registering(self) -> tuple[np.ndarray, slice]:
        """The samples (N,) bool and the markers whose centroid :meth:`positions` gives: every marker where
        every marker was seen (at least 3 such samples), else the first marker where seen."""
        seen = self.seen()
        every = np.all(seen, axis=1)
        return (every, slice(None)) if np.count_nonzero(every) >= 3 else (seen[:, 0], slice(0, 1))

    def positions(self):
        """A point near the tool per sample, to register the measurement frame: the markers' centroid
        where every marker was seen (at least 3 such samples), else the first marker where seen."""
        rows, which = self._registering()
        return self.q[rows], self.xyz[rows][:, which].mean(axis=1)

    def position_rows(self) -> np.ndarray:
        return self.rows[self._registering()[0]]

    def flange_positions(self) -> dict:
        """Each marker's measured positions where it was seen: ``marker[<name>]`` -> (q (n, joints), xyz (n, 3) m)."""
        return {f"marker[{m}]": (self.q[seen], self.xyz[seen, k]) for k, (m, seen) in enumerate(zip(self.names,
                                                                                                  self.seen().T))}

    def positions_point(self, setup: dict) -> np.ndarray:
        """The point on the flange (3,) m :meth:`positions` measures: the centroid of the same markers' points
        ``marker[<name>].x/y/z`` in ``setup`` (m)."""
        points = np.array([[setup[f"marker[{m}].{a}"] for a in "xyz"] for m in self.names], float)
        return points[self._registering()[1]].mean(axis=0)

    def prepare(self, robot: Robot) -> "MarkersObs":
        """Without given starts, each marker starts where the (registered) robot's flange frames put
        its measurements on average: mean of Rᵢᵀ(xᵢ − tᵢ) over the samples that saw it."""
        if self.start is not None:
            return self
        origin, _, R = flange_point(robot, self.q, robot.params.values, np.zeros(3))
        start = np.array([np.einsum("nji,nj->ni", R[seen], self.xyz[seen, m] - origin[seen]).mean(0)
                          if seen.any() else robot.tool_point() for m, seen in enumerate(self.seen().T)])
        return dataclasses.replace(self, start=start)

    def nuisance(self, robot: Robot):
        k = self.xyz.shape[1]
        start = np.tile(robot.tool_point(), (k, 1)) if self.start is None else np.asarray(self.start, float)
        names = tuple(f"marker[{m}].{a}" for m in self.names for a in "xyz")
        return names, start.ravel(), ("length",) * (3 * k)

    def gauge_params(self, robot: Robot) -> tuple[str, ...]:
        return TOOL_NAMES

    def sigma(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.std, float), (len(self),))[self.sample_rows()]

    def sample_rows(self) -> np.ndarray:
        return np.concatenate([np.tile(np.flatnonzero(seen), 3) for seen in self.seen().T])

    def position_axes(self) -> np.ndarray:
        return np.concatenate([np.repeat(np.arange(3), np.count_nonzero(seen)) for seen in self.seen().T])

    def framed(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> Framed:
        """Every marker where it was seen (NaN where not), against its point ``marker[<name>].x/y/z`` in ``nuis``."""
        v = robot.param_values(values)
        model = [flange_point(robot, self.q, v, nuis[3 * m:3 * m + 3])[0] for m in range(self.xyz.shape[1])]
        return Framed.of(self.xyz, np.stack(model, axis=1))

    def shifted(self, offset: np.ndarray) -> "MarkersObs":
        return dataclasses.replace(self, xyz=self.xyz + offset[:, None, :])

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        k, r, Jr, Jn = self.xyz.shape[1], [], [], []
        for m, rows in enumerate(self.seen().T):
            p, J, R = flange_point(robot, self.q[rows], robot.param_values(values), nuis[3 * m:3 * m + 3])
            J = J.copy()
            J[:, :, robot.params.indices(TOOL_NAMES)] = 0.0
            Jm = np.zeros((rows.sum(), 3, 3 * k))
            Jm[:, :, 3 * m:3 * m + 3] = R
            r.append((p - self.xyz[rows, m]).T.ravel())
            Jr.append(J.transpose(1, 0, 2).reshape(-1, J.shape[2]))
            Jn.append(Jm.transpose(1, 0, 2).reshape(-1, 3 * k))
        return np.concatenate(r), np.concatenate(Jr), np.concatenate(Jn)

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        r = self.evaluate(robot, values, nuis)[0]  # per marker: its x rows, then y, then z
        ends = 3 * np.cumsum(np.count_nonzero(self.seen(), axis=0))[:-1]
        e = np.concatenate([np.linalg.norm(b.reshape(3, -1), axis=0) for b in np.split(r, ends)])
        unseen = int(np.count_nonzero(~self.seen().any(axis=1)))  # rows that saw no marker: no sample
        return {**error_stats(self, e, markers=len(self.names), observed=int(e.size)),
                "samples": len(self) - unseen, **({"unseen": unseen} if unseen else {})}
