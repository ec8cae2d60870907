"""Robots built on another one: :class:`Wrapped` (its ``inner`` robot's parameters first, then its own)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .parameters import Parameters
from .robot import Robot


@dataclass(frozen=True, eq=False, repr=False)
class Wrapped(Robot):
    """A robot built on another one: its parameters are the inner robot's followed by its own.

    Its name, description, base frame, named frames, structure notes, mounting parameters, frame freedoms and
    preferences among confounded parameters are those of ``inner``. Subclasses (an error model on the joints,
    a transmission) are frozen dataclasses that add their fields and kinematics.

    Parameters
    ----------
    inner : Robot
        The robot it is built on.
    params : Parameters
        All its parameters: ``inner``'s (same names, in order) followed by its own, SI units.

    Attributes
    ----------
    name : str
        ``inner``'s name.
    description : str
        ``inner``'s description.

    Raises
    ------
    ModelError
        When ``params`` does not start with ``inner``'s parameter names.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models import Wrapped
    >>> robot = kincal.extend(kincal.load_robot("ur5"), "harmonics:1")
    >>> isinstance(robot, Wrapped), robot.inner.n_params, robot.n_params
    (True, 35, 45)
    >>> robot.params.names[:35] == robot.inner.params.names
    True
    """

    inner: Robot
    params: Parameters
    name: str = field(init=False)
    description: str = field(init=False)

    def __post_init__(self) -> None:
        n = self.inner.n_params
        if self.params.names[:n] != self.inner.params.names:
            raise ModelError(f"robot '{self.inner.name}': parameters must start with the inner robot's")
        object.__setattr__(self, "name", self.inner.name)
        object.__setattr__(self, "description", self.inner.description)

    def _rebuild(self, params: Parameters):
        inner = self.inner.with_params(params.values[:self.inner.n_params])
        return dataclasses.replace(self, inner=inner, params=params)

    def _split(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(inner's values, own values) of a (P,) vector."""
        return values[:self.inner.n_params], values[self.inner.n_params:]

    def preferred_params(self) -> tuple[str, ...]:
        return self.inner.preferred_params()

    def structure_notes(self) -> list[str]:
        return self.inner.structure_notes()

    def mounting_params(self) -> tuple[str, ...]:
        return self.inner.mounting_params()

    def frame_freedoms(self) -> tuple[tuple[str, tuple[str, ...], int], ...]:
        return self.inner.frame_freedoms()

    def base_params(self) -> tuple[str, ...]:
        return self.inner.base_params()

    def named_frames(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        return self.inner.named_frames()

    def program_language(self) -> str:
        return self.inner.program_language()
