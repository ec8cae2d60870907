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
    """``inner`` (an absolute set) measured in the frame of ``session``; ``frame0``: the frame's start
    values in the order and units of ``robot.base_params()`` (set by the fit from a registration)."""

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

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        return {**self.inner.stats(robot, *self._split(robot, values, nuis)), "session": self.session}
