"""Gravity loads on a serial chain: the joint torques a mass model causes, and their linear regressor.

Gravity acts along −z of the robot's own base frame (the base frame parameters, which place the
robot in the tracker's frame, are zeroed): a floor-mounted robot whose base z points up. A point
mass m at a point P of link j loads joint i (i ≤ j) with the generalised force

    τᵢ = (∂P/∂qᵢ) · m g⃗,   g⃗ = (0, 0, −9.80665) m/s²,

N·m for a revolute joint. ∂P/∂q is the joint Jacobian of the chain cut at link j's frame with P
added as constant translations, so one mechanism serves DH, MDH and URDF chains. The geometry is
that of the robot the model is built from (its reference), held fixed: the loads are known
functions of q, and terms built on them stay linear in their parameters.

With unknown masses, P = oⱼ + Rⱼc and ∂P/∂qᵢ is linear in c, so the load is linear in (m, m·c)
per link: the gravity regressor, four columns per (joint, link) pair, each ĝ·∂(oⱼ + Rⱼeₖ)/∂qᵢ in m.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .chain import AXES, TRANS, Chain, Op

if TYPE_CHECKING:
    from .serial import ChainRobot

G = 9.80665  # m/s²
COMPONENTS = ("m", "x", "y", "z")  # regressor columns per link: the mass, then its first moments


@dataclass(frozen=True, eq=False)
class GravityModel:
    """Loads of ``robot``'s link masses (and a ``payload`` kg at the tool point) at joint values q."""

    robot: "ChainRobot"
    payload: float = 0.0
    _values: np.ndarray = field(init=False, repr=False)
    _cache: dict = field(init=False, repr=False)

    def __post_init__(self) -> None:
        values = self.robot.chain_values().copy()
        values[self.robot.params.indices(self.robot.base_params())] = 0.0
        values.setflags(write=False)  # read-only: its own copy
        object.__setattr__(self, "_values", values)
        object.__setattr__(self, "_cache", {})

    def _jacobian(self, q: np.ndarray, end: int, joints: int, offset) -> np.ndarray:
        """The joint Jacobian (N, 3, joints) of the point ``offset`` in the frame after ``end`` ops."""
        key = ("chain", end, joints, tuple(float(c) for c in offset))
        if key not in self._cache:
            ops = self.robot.chain.ops[:end] + tuple(Op(TRANS, AXES[a], -1, offset=float(v))
                                                     for a, v in zip("xyz", offset) if v != 0.0)
            self._cache[key] = Chain(ops, len(self._values), joints)
        chain = self._cache[key]
        return chain.forward_and_jacobian(self._values, q[:, :joints])[1][:, :, chain.joint_param]

    def _cached(self, key: str, q: np.ndarray, compute) -> np.ndarray:
        """compute(q), kept for the last q seen per key (a fit evaluates the same poses many times)."""
        last_q, last = self._cache.get(key, (None, None))
        if last_q is None or last_q.shape != q.shape or not np.array_equal(last_q, q):
            last = compute(q)
            last.setflags(write=False)
            self._cache[key] = (q.copy(), last)
        return last

    def _mass_points(self) -> list[tuple[int, int, tuple, float]]:
        pts = [(end, k, com, m) for _, end, k, m, com in self.robot.link_frames() if m > 0.0 and k > 0]
        if self.payload > 0.0:
            pts.append((len(self.robot.chain.ops), self.robot.n_joints, (0.0, 0.0, 0.0), self.payload))
        return pts

    @property
    def total_mass(self) -> float:
        return float(sum(p[3] for p in self._mass_points()))

    def torques(self, q: np.ndarray) -> np.ndarray:
        """(N, n) gravity load per joint (N·m or N) at joint values q (N, n)."""
        return self._cached("torques", self.robot.check_q(q), self._torques)

    def _torques(self, q: np.ndarray) -> np.ndarray:
        out = np.zeros(q.shape)
        for end, k, com, m in self._mass_points():
            out[:, :k] -= G * m * self._jacobian(q, end, k, com)[:, 2, :]  # g⃗ = −G ẑ
        return out

    def links(self) -> list[tuple[str, int, int]]:
        """The links the regressor uses: the first frame after each moving joint (name, end, joints)."""
        first: dict[int, tuple[str, int, int]] = {}
        for name, end, k, _, _ in self.robot.link_frames():
            if k > 0:
                first.setdefault(k, (name, end, k))
        return list(first.values())

    def regressor(self, q: np.ndarray) -> np.ndarray:
        """(N, n, L, 4): for link ℓ and component (m, x, y, z) the load column on each joint, in m:
        −ẑ·∂oℓ/∂qᵢ and −ẑ·∂(Rℓeₖ)/∂qᵢ (zero for joints after the link)."""
        return self._cached("regressor", self.robot.check_q(q), self._regressor)

    def _regressor(self, q: np.ndarray) -> np.ndarray:
        links = self.links()
        out = np.zeros((len(q), self.robot.n_joints, len(links), 4))
        for ell, (_, end, k) in enumerate(links):
            J0 = self._jacobian(q, end, k, (0.0, 0.0, 0.0))[:, 2, :]
            out[:, :k, ell, 0] = -J0
            for c, axis in enumerate(np.eye(3)):
                out[:, :k, ell, c + 1] = J0 - self._jacobian(q, end, k, axis)[:, 2, :]
        return out
