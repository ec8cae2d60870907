"""Transmissions: actuator inputs → joint variables of a serial chain, with their own parameters.

A :class:`TransmissionRobot` is a serial chain driven through a transmission. Its "joints" (what a
user commands and a data file lists) are the actuators; the chain's joint variables follow from
them. Parameters are the chain's followed by the transmission's, and the position Jacobian of a
transmission parameter s is J_q · ∂q/∂s (chain rule), so identification, identifiability and pose
design work unchanged.

Maps (a transmission is a list of them, each driving its own joints):
* ``direct``:             q = φ
* ``screw``:              q = lead · φ / 2π                    (ball screw: motor angle → travel)
* ``differential_screw``: ξ = lead (φa + φb) / 4π,  ψ = atan(lead (φa − φb) / (2π L))
  two parallel screws driven together translate a carriage by ξ and, driven differentially, turn
  it by ψ about a lever of length L (the 3T2R robot's J1/J2).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .parameters import Parameters
from .robot import Robot, Wrapped
from .serial import SerialRobot

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class Map:
    """One transmission element: ``kind`` with actuator and joint indices and parameter names."""

    kind: str
    actuators: tuple[int, ...]
    joints: tuple[int, ...]
    params: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        shape = {"direct": (1, 1, 0), "screw": (1, 1, 1), "differential_screw": (2, 2, 2)}
        if self.kind not in shape:
            raise ModelError(f"transmission: unknown map type '{self.kind}'; use one of {', '.join(shape)}")
        if (len(self.actuators), len(self.joints), len(self.params)) != shape[self.kind]:
            raise ModelError(f"transmission: a '{self.kind}' map takes {shape[self.kind][0]} actuator(s), "
                             f"{shape[self.kind][1]} joint(s) and {shape[self.kind][2]} parameter(s)")


@dataclass(frozen=True, eq=False, repr=False)
class TransmissionRobot(Wrapped):
    """A serial chain whose joint variables are driven by actuators through a transmission."""

    chain: SerialRobot
    actuator_names: tuple[str, ...]
    actuator_lower: np.ndarray
    actuator_upper: np.ndarray
    maps: tuple[Map, ...]
    drive: Parameters  # the transmission's own parameters
    params: Parameters = field(init=False)

    def __post_init__(self) -> None:
        n_a, n_j = len(self.actuator_names), self.chain.n_joints
        driven = sorted(j for mp in self.maps for j in mp.joints)
        if driven != list(range(n_j)):
            raise ModelError(f"{self.chain.name}: the transmission must drive each of the {n_j} chain joints "
                             f"exactly once (drives {driven})")
        used = sorted(a for mp in self.maps for a in mp.actuators)
        if used != list(range(n_a)):
            raise ModelError(f"{self.chain.name}: every actuator must feed exactly one map (uses {used})")
        for mp in self.maps:
            self.drive.indices(mp.params)
        clash = set(self.chain.params.names) & set(self.drive.names)
        if clash:
            raise ModelError(f"{self.chain.name}: transmission parameter names clash with the chain: {sorted(clash)}")
        lo, hi = np.asarray(self.actuator_lower, float), np.asarray(self.actuator_upper, float)
        if lo.shape != (n_a,) or hi.shape != (n_a,) or not np.all(lo < hi):
            raise ModelError(f"{self.chain.name}: actuator limits must be finite with lower < upper")
        object.__setattr__(self, "actuator_lower", lo)
        object.__setattr__(self, "actuator_upper", hi)
        object.__setattr__(self, "params", Parameters(
            self.chain.params.names + self.drive.names,
            np.concatenate([self.chain.params.values, self.drive.values]),
            self.chain.params.kinds + self.drive.kinds))

    # ---- identity -----------------------------------------------------------------------------
    name = property(lambda self: self.chain.name)  # type: ignore[assignment]
    description = property(lambda self: self.chain.description)
    convention = property(lambda self: self.chain.convention)
    kind = property(lambda self: f"{self.chain.convention} + transmission")  # type: ignore[assignment]
    joint_names = property(lambda self: self.actuator_names)  # type: ignore[assignment]
    joint_types = property(lambda self: ("revolute",) * len(self.actuator_names))  # type: ignore[assignment]
    lower = property(lambda self: self.actuator_lower)  # type: ignore[assignment]
    upper = property(lambda self: self.actuator_upper)  # type: ignore[assignment]

    def _split(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pc = self.chain.n_params
        return values[:pc], values[pc:]

    def with_params(self, values) -> "TransmissionRobot":
        new = values if isinstance(values, Parameters) else self.params.replace(values)
        chain_v, drive_v = self._split(new.values)
        return TransmissionRobot(self.chain.with_params(chain_v), self.actuator_names, self.actuator_lower,
                                 self.actuator_upper, self.maps, self.drive.replace(drive_v))

    # ---- the transmission ----------------------------------------------------------------------
    def joints(self, phi: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """Chain joint variables (N, n_j) for actuator values φ (N, n_a)."""
        return self._transmit(self.check_q(phi), self.param_values(params), derivatives=False)[0]

    def actuators(self, q: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """Actuator values φ (N, n_a) that give chain joint variables q (N, n_j): the inverse of :meth:`joints`."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        _, dv = self._split(self.param_values(params))
        phi = np.empty((len(q), len(self.actuator_names)))
        for mp in self.maps:
            p = [dv[self.drive.index(name)] for name in mp.params]
            if mp.kind == "direct":
                phi[:, mp.actuators[0]] = q[:, mp.joints[0]]
            elif mp.kind == "screw":
                phi[:, mp.actuators[0]] = TWO_PI * q[:, mp.joints[0]] / p[0]
            else:
                (a, b), (jt, jr), (lead, arm) = mp.actuators, mp.joints, p
                s, d = 2 * TWO_PI * q[:, jt] / lead, TWO_PI * arm * np.tan(q[:, jr]) / lead
                phi[:, a], phi[:, b] = (s + d) / 2, (s - d) / 2
        return phi

    def _transmit(self, phi: np.ndarray, values: np.ndarray, derivatives: bool = True):
        """q (N, n_j), ∂q/∂φ (N, n_j, n_a) and ∂q/∂drive (N, n_j, P_drive)."""
        _, dv = self._split(values)
        n = phi.shape[0]
        q = np.empty((n, self.chain.n_joints))
        dq_dphi = np.zeros((n, self.chain.n_joints, len(self.actuator_names))) if derivatives else None
        dq_ds = np.zeros((n, self.chain.n_joints, len(self.drive))) if derivatives else None
        for mp in self.maps:
            p = [dv[self.drive.index(name)] for name in mp.params]
            if mp.kind == "direct":
                (a,), (j,) = mp.actuators, mp.joints
                q[:, j] = phi[:, a]
                if derivatives:
                    dq_dphi[:, j, a] = 1.0
            elif mp.kind == "screw":
                (a,), (j,), (lead,) = mp.actuators, mp.joints, p
                q[:, j] = lead * phi[:, a] / TWO_PI
                if derivatives:
                    dq_dphi[:, j, a] = lead / TWO_PI
                    dq_ds[:, j, self.drive.index(mp.params[0])] = phi[:, a] / TWO_PI
            else:
                (a, b), (jt, jr), (lead, arm) = mp.actuators, mp.joints, p
                il, ia = self.drive.index(mp.params[0]), self.drive.index(mp.params[1])
                s, d = phi[:, a] + phi[:, b], phi[:, a] - phi[:, b]
                q[:, jt] = lead * s / (2 * TWO_PI)
                u = lead * d / (TWO_PI * arm)
                q[:, jr] = np.arctan(u)
                if derivatives:
                    g = 1.0 / (1.0 + u * u)  # d atan(u)/du
                    dq_dphi[:, jt, a] = dq_dphi[:, jt, b] = lead / (2 * TWO_PI)
                    dq_dphi[:, jr, a] = g * lead / (TWO_PI * arm)
                    dq_dphi[:, jr, b] = -dq_dphi[:, jr, a]
                    dq_ds[:, jt, il] = s / (2 * TWO_PI)
                    dq_ds[:, jr, il] = g * d / (TWO_PI * arm)
                    dq_ds[:, jr, ia] = -g * u / arm
        return q, dq_dphi, dq_ds

    # ---- Robot interface -----------------------------------------------------------------------
    def forward_and_jacobian(self, q, params=None, jacobian=True):
        phi = self.check_q(q)
        values = self.param_values(params)
        cv, _ = self._split(values)
        qj, _, dq_ds = self._transmit(phi, values, derivatives=jacobian)
        if not jacobian:
            return self.chain.forward(qj, cv), None
        p, Jc = self.chain.forward_and_jacobian(qj, cv)
        Jq = Jc[:, :, self.chain.joint_columns]
        return p, np.concatenate([Jc, Jq @ dq_ds], axis=2)

    def joint_jacobian(self, q, params=None):
        squeeze = np.ndim(q) == 1
        phi = self.check_q(q)
        values = self.param_values(params)
        qj, dq_dphi, _ = self._transmit(phi, values)
        out = self.chain.joint_jacobian(qj, self._split(values)[0]) @ dq_dphi
        return out[0] if squeeze else out

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """Actuator limits and the chain's joint limits (e.g. |ψ| ≤ 45°, carriage travel) hold."""
        phi = self.check_q(q)
        return self.within_limits(phi) & self.chain.within_limits(self.joints(phi))

    inner = property(lambda self: self.chain)


def build_transmission_robot(chain: SerialRobot, actuators: Sequence[tuple[str, float, float]],
                             maps: Sequence[Map], drive: Mapping[str, tuple[float, str]]) -> TransmissionRobot:
    """A TransmissionRobot from (name, lower, upper) actuators (rad), maps and drive parameters
    {name: (value SI, kind)}."""
    names = tuple(a[0] for a in actuators)
    if len(set(names)) != len(names):
        raise ModelError(f"{chain.name}: duplicate actuator names {names}")
    drive_p = Parameters(tuple(drive), [v for v, _ in drive.values()], tuple(k for _, k in drive.values()))
    return TransmissionRobot(chain, names, np.array([a[1] for a in actuators]), np.array([a[2] for a in actuators]),
                             tuple(maps), drive_p)
