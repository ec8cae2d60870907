"""The `Robot` interface every model (serial, hybrid, parallel) implements."""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .parameters import Parameters

JOINT_TYPES = ("revolute", "prismatic")


class Robot(ABC):
    """A robot with named joints, joint limits and a named parameter vector.

    Subclasses are immutable values. All kinematics are batched: the first axis of ``q`` is the
    configuration. Units are SI (m, rad).
    """

    name: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    lower: np.ndarray  # (n,) joint lower limits, rad or m
    upper: np.ndarray  # (n,)
    params: Parameters

    @property
    def kind(self) -> str:
        """A short description of the model type (e.g. 'dh', 'mdh', 'puu3 (implicit)')."""
        return type(self).__name__

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def n_params(self) -> int:
        return len(self.params)

    @abstractmethod
    def with_params(self, values: Mapping[str, float] | Sequence[float] | np.ndarray | Parameters) -> "Robot":
        """A new robot with changed parameter values (by name, or a full (P,) vector)."""

    @abstractmethod
    def forward_and_jacobian(
        self, q: np.ndarray, params: np.ndarray | None = None, jacobian: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Tool positions (N,3) m and parameter Jacobian (N,3,P) (None if not ``jacobian``) in one pass."""

    @abstractmethod
    def joint_jacobian(self, q: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """d position / d joint values, (N,3,n)."""

    def forward_jacobians(self, q: np.ndarray, params: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (N,3), parameter Jacobian (N,3,P) and joint Jacobian (N,3,n); chains give all
        three from one pass."""
        p, J = self.forward_and_jacobian(q, params)
        return p, J, self.joint_jacobian(q, params)

    def preferred_params(self) -> tuple[str, ...]:
        """Names to keep first when parameters are confounded (after any the user lists)."""
        return ()

    def structure_notes(self) -> list[str]:
        """Warnings about the model's structure (e.g. parallel axes without β); none by default."""
        return []

    def base_params(self) -> tuple[str, ...]:
        """Names of the 6 base-frame parameters (x y z rx ry rz), or () if the model has no base frame."""
        return ()

    def base_transform(self) -> tuple[np.ndarray, np.ndarray]:
        """Base frame as (R (3,3), t (3,)): world = R @ robot + t."""
        raise ModelError(f"robot '{self.name}' has no base frame")

    def with_base_transform(self, R: np.ndarray, t: np.ndarray) -> "Robot":
        """A copy whose base frame is (R, t)."""
        raise ModelError(f"robot '{self.name}' has no base frame")

    # ---- shared conveniences -------------------------------------------------------------------
    def check_q(self, q: np.ndarray) -> np.ndarray:
        """q as a float (N, n) array; ModelError if the joint count is wrong."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise ModelError(
                f"{self.name}: joint array has shape {q.shape}, expected (N, {self.n_joints}) "
                f"for joints {', '.join(self.joint_names)}"
            )
        return q

    def param_values(self, params: np.ndarray | None) -> np.ndarray:
        if params is None:
            return self.params.values
        v = np.asarray(params, dtype=float).reshape(-1)
        if v.size != self.n_params:
            raise ModelError(f"{self.name}: expected {self.n_params} parameter values, got {v.size}")
        return v

    def forward(self, q: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """Tool point position (N,3) in m for joint values q (N,n)."""
        squeeze = np.ndim(q) == 1
        p = self.forward_and_jacobian(q, params, jacobian=False)[0]
        return p[0] if squeeze else p

    def param_jacobian(self, q: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """d position / d parameters, (N,3,P); columns in the order of ``params.names``."""
        squeeze = np.ndim(q) == 1
        J = self.forward_and_jacobian(q, params)[1]
        return J[0] if squeeze else J

    def forward_batch(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Positions (S, N, 3) m for S parameter vectors ``values`` (S, P) at the same joints q (N, n),
        as a particle swarm needs; rows that cannot be computed are NaN. This default calls
        ``forward`` once per vector; models with a batched path override it."""
        q = self.check_q(q)
        out = np.full((len(values), q.shape[0], 3), np.nan)
        for k, v in enumerate(np.asarray(values, dtype=float)):
            try:
                out[k] = self.forward(q, v)
            except ModelError:
                pass
        return out

    def sampling_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits for drawing random poses: the limits, with ±π for unlimited (continuous) joints."""
        lo, hi = np.asarray(self.lower, float), np.asarray(self.upper, float)
        return np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)

    def sample_joints(self, n: int, seed: int | None = 0, margin: float = 0.0) -> np.ndarray:
        """n joint vectors drawn uniformly inside the limits (shrunk by ``margin`` of each range), (n, n_joints)."""
        rng = np.random.default_rng(seed)
        lo, hi = self.sampling_limits()
        span = hi - lo
        return rng.uniform(lo + margin * span, hi - margin * span, size=(int(n), self.n_joints))

    def sample_feasible(self, n: int, seed: int | None = 0, max_tries: int = 50) -> np.ndarray:
        """n joint vectors drawn uniformly within the limits where ``feasible`` holds, (n, n_joints)."""
        rng = np.random.default_rng(seed)
        kept, have = [], 0
        lo, hi = self.sampling_limits()
        for _ in range(max_tries):
            q = rng.uniform(lo, hi, size=(max(2 * (n - have), 16), self.n_joints))
            q = q[self.feasible(q)]
            kept.append(q)
            have += q.shape[0]
            if have >= n:
                return np.concatenate(kept)[:n]
        raise ModelError(f"{self.name}: only {have} of {n} random joint vectors satisfy the robot's constraints; "
                         f"check the joint limits and coupled constraints")

    def within_limits(self, q: np.ndarray, tol: float = 1e-12) -> np.ndarray:
        """(N,) bool: every joint inside its limits."""
        q = self.check_q(q)
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=1)

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: joint limits and any coupled constraints of the model hold."""
        return self.within_limits(q)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, joints={self.n_joints}, params={self.n_params})"


class Wrapped(Robot):
    """A robot built on another one (``inner``): the structure, the base frame and the preferences
    among confounded parameters are the inner robot's."""

    @property
    def inner(self) -> Robot:
        raise NotImplementedError

    def preferred_params(self) -> tuple[str, ...]:
        return self.inner.preferred_params()

    def structure_notes(self) -> list[str]:
        return self.inner.structure_notes()

    def base_params(self) -> tuple[str, ...]:
        return self.inner.base_params()

    def base_transform(self):
        return self.inner.base_transform()

    def with_base_transform(self, R: np.ndarray, t: np.ndarray) -> "Robot":
        return self.with_params(self.inner.with_base_transform(R, t).params.as_dict())
