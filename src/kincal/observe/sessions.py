"""Sessions: an absolute set (points, poses, markers) measured in its own frame, because the tracker
or camera moved between sessions. One shared mechanism for every type: the set is evaluated with
the robot's base-frame parameters replaced by its own frame (``frame[<session>].<base parameter>``,
set-up parameters), so the kinematics are shared and each session keeps its frame."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..models.robot import Robot
from .observations import Wrapper


@dataclass(frozen=True, eq=False)
class InSession(Wrapper):
    """An absolute set (points, poses, markers) measured in a session's own frame.

    The set is evaluated with the robot's base-frame parameters replaced by the session's frame (set-up
    parameters ``frame[<session>].<base parameter>``), so the kinematics are shared and each session keeps
    its frame; the base frame is then a gauge freedom of the set. Build it with ``InSession.of(inner,
    session, frame0)``.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint): the inner set's.
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source``: the inner set's.
    source : str
        Where the data come from: the inner set's.
    inner : Observation
        The set measured in the session's frame.
    session : str, optional
        The session's name (default '').
    frame0 : ndarray, shape (B,), optional
        The frame's start values, in the order and units of ``robot.base_params()`` (m, rad) (default None:
        set by the fit from a registration).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import InSession, PointObs
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(6, seed=1), seed=0)
    >>> points = PointObs(meas.q, meas.rows, "tripod-2.csv", xyz=meas.xyz)
    >>> frame0 = robot.params.values[robot.params.indices(robot.base_params())]
    >>> obs = InSession.of(points, "tripod-2", frame0)
    >>> obs.kind, obs.positions() is None
    ('point', True)
    >>> names, start, kinds = obs.nuisance(robot)
    >>> names[:3]
    ('frame[tripod-2].base.x', 'frame[tripod-2].base.y', 'frame[tripod-2].base.z')

    At its start frame (the robot's base) the residual is the inner set's:

    >>> r, Jr, Jn = obs.evaluate(robot, robot.params.values, start)
    >>> bool(np.allclose(r, points.evaluate(robot, robot.params.values, np.zeros(0))[0])), Jn.shape
    (True, (18, 6))
    """

    session: str = ""
    frame0: np.ndarray | None = None

    def _base(self, robot: Robot) -> np.ndarray:
        if not robot.base_params():
            raise ModelError(f"robot '{robot.name}' has no base frame: its sessions cannot each have their own frame")
        return robot.params.indices(robot.base_params())

    def _start(self) -> np.ndarray:
        """``frame0``, which the fit sets before it prepares the set or asks for its parameters."""
        if self.frame0 is None:
            raise ValueError(f"session '{self.session}': its frame has no start values yet (the fit sets them "
                             f"from a registration)")
        return self.frame0

    def _at_frame(self, robot: Robot) -> Robot:
        """``robot`` with its base frame at this session's start frame."""
        return robot.with_params(dict(zip(robot.base_params(), self._start())))

    def _split(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The robot's ``values`` with their base frame at this session's (the end of ``nuis``), and the inner set's
        nuisance (the rest)."""
        v = np.array(values, float)
        v[self._base(robot)] = nuis[len(nuis) - len(robot.base_params()):]
        return v, nuis[:len(nuis) - len(robot.base_params())]

    def positions(self):
        return None  # its positions are in its own frame, not the robot's

    def flange_positions(self) -> dict:
        return {}  # (as its positions)

    def prepare(self, robot: Robot) -> "InSession":
        return dataclasses.replace(self, inner=self.inner.prepare(self._at_frame(robot)))

    def nuisance(self, robot: Robot):
        names, start, kinds = self.inner.nuisance(self._at_frame(robot))
        frame = tuple(f"frame[{self.session}].{n}" for n in robot.base_params())
        return (tuple(names) + frame, np.concatenate([start, self._start()]),
                tuple(kinds) + tuple(robot.params.kinds[i] for i in self._base(robot)))

    def gauge_params(self, robot: Robot) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.inner.gauge_params(robot) + robot.base_params()))

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        r, Jr, Jn = self.inner.evaluate(robot, *self._split(robot, values, nuis))
        idx = self._base(robot)
        Jr, Jf = Jr.copy(), Jr[:, idx]  # the frame's columns move to the set's own
        Jr[:, idx] = 0.0
        return r, Jr, np.hstack([Jn, Jf])

    def covariance(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> np.ndarray | None:
        return self.inner.covariance(robot, *self._split(robot, values, nuis))

    def sample_errors(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple | None:
        """The inner set's, at this session's frame: in the session's own measurement frame."""
        return self.inner.sample_errors(robot, *self._split(robot, values, nuis))

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        return {**self.inner.stats(robot, *self._split(robot, values, nuis)), "session": self.session}
