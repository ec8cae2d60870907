"""A robot's joints: the immutable `JointSpace` (names, types, limits) and the `Joints` part of the
`Robot` interface that reads it (names, types, limits, checks, feasibility and sampling).

Units are SI: rad for revolute joints, m for prismatic ones; arrays are batched (first axis: configuration).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError

JOINT_TYPES = ("revolute", "prismatic", "covariate")  # a covariate: an input after the joints (models/covariates.py)

@dataclass(frozen=True, eq=False, init=False)
class JointSpace:
    """The joints a user commands, then any covariate inputs: names, types and limits, all immutable.

    A robot's inputs q (N, n) have one column per entry, in this order. The limits are stored as read-only
    arrays.

    Parameters
    ----------
    names : iterable of str
        Distinct, non-empty names without a dot.
    types : iterable of str
        Per entry "revolute" or "prismatic" (a joint), or "covariate" (an input after the joints: a
        temperature, a time).
    lower : array_like, shape (n,)
        Lower limits: rad (revolute), m (prismatic), the column's unit (covariate, limited to the range a
        term was fitted on); -inf for an unlimited joint.
    upper : array_like, shape (n,)
        Upper limits in the same units, each above its lower limit; +inf for an unlimited joint.

    Raises
    ------
    ModelError
        When the four do not have one entry per joint, a name is repeated, empty or has a dot, a type is
        unknown, or a lower limit is not below its upper limit.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.models import JointSpace
    >>> space = JointSpace(["j1", "slide"], ["revolute", "prismatic"], [-np.pi, 0.0], [np.pi, 0.2])
    >>> len(space), space.names, space.types
    (2, ('j1', 'slide'), ('revolute', 'prismatic'))
    >>> space.upper
    array([3.14159265, 0.2       ])
    >>> space.lower.flags.writeable
    False
    """

    names: tuple[str, ...]
    types: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def __init__(self, names: Iterable[str], types: Iterable[str], lower: ArrayLike, upper: ArrayLike) -> None:
        names, types = tuple(names), tuple(types)
        lo, hi = np.array(lower, dtype=float).reshape(-1), np.array(upper, dtype=float).reshape(-1)
        if not (len(names) == len(types) == lo.size == hi.size):
            raise ModelError(f"joints {list(names)}: names, types and limits must have one entry per joint")
        if len(set(names)) != len(names) or any(not n or "." in n for n in names):
            raise ModelError(f"joint names {list(names)} must be distinct, non-empty and contain no '.'")
        bad = [t for t in types if t not in JOINT_TYPES]
        if bad:
            raise ModelError(f"joint type(s) {sorted(set(bad))}: use one of {JOINT_TYPES}")
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or not np.all(lo < hi):
            raise ModelError(f"joints {list(names)}: every limit needs lower < upper")
        lo.setflags(write=False)  # read-only
        hi.setflags(write=False)
        for key, value in (("names", names), ("types", types), ("lower", lo), ("upper", hi)):
            object.__setattr__(self, key, value)

    def __len__(self) -> int:
        return len(self.names)


class Joints:
    """The joints of a robot (see `Robot`): what it reads from its ``joint_space``. ``feasible`` is where a
    model adds its coupled constraints; ``sample_joints`` draws only feasible poses."""

    name: str
    joint_space: JointSpace

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.joint_space.names

    @property
    def joint_types(self) -> tuple[str, ...]:
        return self.joint_space.types

    @property
    def covariate_names(self) -> tuple[str, ...]:
        """The names of the inputs after the joints that are not joints (a temperature column)."""
        return tuple(n for n, t in zip(self.joint_names, self.joint_types) if t == "covariate")

    def inputs_outside(self, q: np.ndarray) -> tuple[np.ndarray, str]:
        """(N,) bool: rows where the model may not predict — a covariate a term reads beyond the range
        it was fitted on — and why ('' when none); none by default."""
        return np.zeros(len(q), bool), ""

    @property
    def revolute(self) -> np.ndarray:
        """(n,) bool: the revolute joints (their values are angles)."""
        return np.array([t == "revolute" for t in self.joint_types], bool)

    @property
    def motor_leads(self) -> np.ndarray:
        """(n,) m per rad: the travel each joint drives where it is a motor turning a screw (a leg's, a
        carriage's), NaN for a joint that moves what its type says (an angle, a length); none by default."""
        return np.full(self.n_joints, np.nan)

    @property
    def periodic(self) -> np.ndarray:
        """(n,) bool: joints whose configuration repeats every whole turn (revolute joints; a motor
        that drives a travel through a screw, ``motor_leads``, does not: its turns add up)."""
        return self.revolute & np.isnan(self.motor_leads)

    @property
    def lower(self) -> np.ndarray:
        """(n,) joint lower limits, rad or m (read-only)."""
        return self.joint_space.lower

    @property
    def upper(self) -> np.ndarray:
        """(n,) joint upper limits, rad or m (read-only)."""
        return self.joint_space.upper

    @property
    def n_joints(self) -> int:
        return len(self.joint_space)

    def check_q(self, q: np.ndarray) -> np.ndarray:
        """q as a float (N, n) array; ModelError if the joint count is wrong."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise ModelError(f"{self.name}: joint array has shape {q.shape}, expected (N, {self.n_joints}) "
                             f"for joints {', '.join(self.joint_names)}")
        return q

    def link_points(self, q: np.ndarray) -> np.ndarray | None:
        """(N, K, 3) points along the arm at joints q (N, n), m in the world frame: the base, each
        joint's frame and the tool point, in chain order, for collision checks; None for a robot
        that does not declare them (a closed chain)."""
        return None

    @property
    def stack_names(self) -> tuple[str, ...]:
        """The joints' names in the robot stack (URDF, ROS: a robot file's ``names:``); default their own."""
        return self.joint_names

    def default_columns(self, header: Sequence[str]) -> list[str]:
        """The joint columns of a file with ``header`` when none are given: the joints' own names, or
        their robot-stack names (UR's shoulder_pan_joint …) when the file has those and not these."""
        own, stack = list(self.joint_names), list(self.stack_names)
        return stack if not set(own) <= set(header) and set(stack) <= set(header) else own

    def within_limits(self, q: np.ndarray, margin: float = 1e-12) -> np.ndarray:
        """(N,) bool: every joint inside its limits (widened by ``margin``, rad or m)."""
        q = self.check_q(q)
        return np.all((q >= self.lower - margin) & (q <= self.upper + margin), axis=1)

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: joint limits and any coupled constraints of the model hold."""
        return self.within_limits(q)

    def sampling_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits for drawing random poses: the limits, with ±π for unlimited (continuous) joints."""
        lo, hi = self.lower, self.upper
        return np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)

    def sample_joints(self, n: int, seed: int | None = 0, max_tries: int = 50) -> np.ndarray:
        """n joint vectors (n, n_joints) drawn uniformly inside the limits where ``feasible`` holds
        (coupled constraints, assembly), by rejection. Where every draw is feasible the result is the
        first n uniform draws of the generator."""
        rng = np.random.default_rng(seed)
        kept, have = [], 0
        lo, hi = self.sampling_limits()
        for _ in range(max_tries):
            q = rng.uniform(lo, hi, size=(max(2 * (int(n) - have), 16), self.n_joints))
            q = q[self.feasible(q)]
            kept.append(q)
            have += q.shape[0]
            if have >= n:
                return np.concatenate(kept)[:int(n)]
        raise ModelError(f"{self.name}: only {have} of {n} random joint vectors satisfy the robot's constraints; "
                         f"check the joint limits and coupled constraints")
