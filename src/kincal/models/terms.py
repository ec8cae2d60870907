"""Non-geometric error terms on top of any robot model: corrections of the joint angles.

``ExtendedRobot(base, harmonics=k)`` reads a revolute joint i at qᵢ + Δqᵢ(qᵢ) with

    Δqᵢ = Σₖ aᵢₖ sin(k qᵢ) + bᵢₖ cos(k qᵢ),   k = 1 … harmonics,

the usual form of encoder eccentricity (k = 1) and gear transmission error (k = 2), on the joints
whose angle moves the tool point by at least ``MIN_LEVER`` per radian (a joint turning the tool
about itself, as a UR5's last joint with the reflector on its axis, cannot show its angle errors).
The parameters are named ``<joint>.h<k>s`` / ``<joint>.h<k>c`` (rad); nominal 0. They are bounded and periodic, so
they cannot grow without limit away from the training poses, and no term is linear in q (that
would be a joint scale error, which real encoders do not have). The Jacobian is analytic:
∂p/∂aᵢₖ = ∂p/∂qᵢ · sin(k qᵢ) at the corrected angles. Everything else — identifiability, LM,
covariance, compensation — sees an ordinary Robot.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .parameters import Parameters
from .robot import Robot


MIN_LEVER = 0.01  # m per rad: RMS tool motion per joint rotation below which harmonics are not modelled


def harmonic_names(joints: Sequence[str], order: int) -> list[str]:
    return [f"{j}.h{k}{sc}" for j in joints for k in range(1, order + 1) for sc in ("s", "c")]


def lever_joints(robot: Robot, q: np.ndarray) -> tuple[str, ...]:
    """Revolute joints whose rotation moves the tool by at least MIN_LEVER per rad (RMS over q)."""
    lever = np.sqrt(np.mean(np.sum(robot.joint_jacobian(robot.check_q(q)) ** 2, axis=1), axis=0))
    return tuple(j for j, t, arm in zip(robot.joint_names, robot.joint_types, lever)
                 if t == "revolute" and arm >= MIN_LEVER)


@dataclass(frozen=True, eq=False, repr=False)
class ExtendedRobot(Robot):
    """``base`` with joint-angle harmonics of order ``harmonics`` on ``joints``; ``params`` = base's,
    then the terms."""

    base: Robot
    harmonics: int
    joints: tuple[str, ...]
    params: Parameters
    _revolute: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if isinstance(self.base, ExtendedRobot) or not 1 <= self.harmonics <= 4:
            raise ModelError(f"robot '{self.base.name}': harmonics of order 1 to 4 on a geometric model")
        types = dict(zip(self.base.joint_names, self.base.joint_types))
        bad = [j for j in self.joints if types.get(j) != "revolute"]
        if bad or not self.joints:
            raise ModelError(f"robot '{self.base.name}': harmonics need revolute joints, got {list(self.joints)}")
        names = list(self.base.params.names) + harmonic_names(self.joints, self.harmonics)
        if self.params.names != tuple(names):
            raise ModelError(f"robot '{self.base.name}': parameters do not match the error model")
        object.__setattr__(self, "_revolute", np.array([self.base.joint_names.index(j) for j in self.joints]))

    @classmethod
    def build(cls, base: Robot, harmonics: int, joints: Sequence[str],
              values: Mapping[str, float] | None = None) -> "ExtendedRobot":
        names = harmonic_names(joints, harmonics)
        params = Parameters(list(base.params.names) + names, list(base.params.values) + [0.0] * len(names),
                            list(base.params.kinds) + ["angle"] * len(names))
        robot = cls(base, harmonics, tuple(joints), params)
        return robot.with_params(dict(values)) if values else robot

    # ---- the Robot interface, delegated to the base at the corrected angles ---------------------
    name = property(lambda self: self.base.name)  # type: ignore[assignment]
    description = property(lambda self: self.base.description)
    joint_names = property(lambda self: self.base.joint_names)  # type: ignore[assignment]
    joint_types = property(lambda self: self.base.joint_types)  # type: ignore[assignment]
    lower = property(lambda self: self.base.lower)  # type: ignore[assignment]
    upper = property(lambda self: self.base.upper)  # type: ignore[assignment]

    @property
    def kind(self) -> str:
        return f"{self.base.kind} + harmonics:{self.harmonics}"

    @property
    def term_names(self) -> tuple[str, ...]:
        return self.params.names[self.base.n_params:]

    def with_params(self, values) -> "ExtendedRobot":
        new = values if isinstance(values, Parameters) else self.params.replace(values)
        return ExtendedRobot(self.base.with_params(new.values[:self.base.n_params]), self.harmonics, self.joints, new)

    def _split(self, params) -> tuple[np.ndarray, np.ndarray]:
        v = self.param_values(params)
        nb = self.base.n_params
        return v[:nb], v[nb:].reshape(len(self._revolute), self.harmonics, 2)

    def _basis(self, q: np.ndarray) -> np.ndarray:
        """(N, r, k, 2): sin(k qᵢ), cos(k qᵢ) for the revolute joints."""
        kq = q[:, self._revolute, None] * np.arange(1, self.harmonics + 1)
        return np.stack([np.sin(kq), np.cos(kq)], axis=-1)

    def corrected(self, q: np.ndarray, params=None) -> np.ndarray:
        """The joint angles the model uses for commanded/read angles q (N, n)."""
        q = self.check_q(q)
        _, terms = self._split(params)
        out = q.copy()
        out[:, self._revolute] += np.einsum("nrks,rks->nr", self._basis(q), terms)
        return out

    def forward_and_jacobian(self, q, params=None, jacobian=True):
        q = self.check_q(q)
        base_values, _ = self._split(params)
        qc = self.corrected(q, params)
        if not jacobian:
            return self.base.forward_and_jacobian(qc, base_values, jacobian=False)
        p, Jb = self.base.forward_and_jacobian(qc, base_values)
        Jq = self.base.joint_jacobian(qc, base_values)[:, :, self._revolute]  # (N, 3, r)
        Jt = Jq[:, :, :, None, None] * self._basis(q)[:, None]  # (N, 3, r, k, 2)
        return p, np.concatenate([Jb, Jt.reshape(len(q), 3, -1)], axis=2)

    def joint_jacobian(self, q, params=None):
        squeeze = np.ndim(q) == 1
        q = self.check_q(q)
        base_values, terms = self._split(params)
        J = self.base.joint_jacobian(self.corrected(q, params), base_values)
        k = np.arange(1, self.harmonics + 1)
        b = self._basis(q)  # d/dq of a sin(kq) + b cos(kq) = k (a cos(kq) − b sin(kq))
        slope = np.einsum("nrk,rk->nr", b[..., 1] * k, terms[..., 0]) - np.einsum("nrk,rk->nr", b[..., 0] * k,
                                                                                    terms[..., 1])
        J[:, :, self._revolute] *= 1.0 + slope[:, None, :]
        return J[0] if squeeze else J

    def preferred_params(self) -> tuple[str, ...]:
        return self.base.preferred_params()

    def structure_notes(self) -> list[str]:
        return self.base.structure_notes()

    def base_params(self) -> tuple[str, ...]:
        return self.base.base_params()

    def base_transform(self):
        return self.base.base_transform()

    def with_base_transform(self, R: np.ndarray, t: np.ndarray) -> "ExtendedRobot":
        moved = self.base.with_base_transform(R, t)
        return self.with_params(dict(zip(moved.params.names, moved.params.values)))

    def feasible(self, q: np.ndarray) -> np.ndarray:
        return self.base.feasible(q)


MODELS = ("geometric", "harmonics:1", "harmonics:2", "harmonics:3", "harmonics:4")


def extend(robot: Robot, model: str, q: np.ndarray | None = None) -> Robot:
    """``robot`` with the error model named ``model``: "geometric" (unchanged) or "harmonics:k" on the
    joints with a lever arm at the poses q (default: 200 random poses)."""
    if model not in MODELS:
        raise ValueError(f"model '{model}': use one of {', '.join(MODELS)} or auto")
    base = robot.base if isinstance(robot, ExtendedRobot) else robot
    if model == "geometric":
        return base
    joints = lever_joints(base, base.sample_joints(200, seed=0) if q is None else q)
    if not joints:
        raise ModelError(f"robot '{base.name}': no revolute joint moves the tool enough for angle harmonics")
    return ExtendedRobot.build(base, int(model.split(":")[1]), joints)


def model_name(robot: Robot) -> str:
    return f"harmonics:{robot.harmonics}" if isinstance(robot, ExtendedRobot) else "geometric"

