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
* ``coupled``:            qa = φa,  qb = φb + k φa               (k: a fixed number, the map's ``factor``)
  a joint whose controller value is measured from the previous link's neighbour, not from its own
  link: a FANUC arm's J3 is the forearm's angle from the horizontal, so the chain's third angle is
  J3 + J2 (k = 1; ROS-Industrial's fanuc_driver ``J23_factor``). k is a convention of the
  controller, not a quantity of the robot: it is not a parameter and is never identified.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .parameters import Parameters
from .joint_space import JointSpace
from .wrapped import Wrapped
from .serial import SerialRobot

TWO_PI = 2.0 * np.pi
MAP_SHAPES = {"direct": (1, 1, 0), "screw": (1, 1, 1), "differential_screw": (2, 2, 2),
              "coupled": (2, 2, 0)}  # actuators, joints, params


@dataclass(frozen=True)
class Map:
    """One element of a transmission: which actuators drive which chain joints, and how.

    The types (see the module docstring for their formulas): ``direct`` (q = φ), ``screw`` (motor angle to
    travel), ``differential_screw`` (two screws: a carriage's travel and turn) and ``coupled`` (qb = φb + k φa).

    Parameters
    ----------
    type : str
        "direct", "screw", "differential_screw" or "coupled".
    actuators : tuple of int
        Indices of the actuators it reads (1 for direct and screw, 2 otherwise).
    chain_joints : tuple of int
        Indices of the chain joints it drives, as many as actuators.
    param_names : tuple of str, optional
        Names of its drive parameters: none for direct and coupled, the lead (m per turn) for a screw, the
        lead and the lever length L (m) for a differential screw (default none).
    factor : float, optional
        The fixed factor k of a coupled map, a convention of the controller that is never identified
        (default 1; other maps keep 1).

    Raises
    ------
    ModelError
        When the type is unknown, the counts of actuators, joints and parameters do not fit it, or a factor is
        given to a map that is not coupled (or is not finite).

    Examples
    --------
    >>> from kincal.models import Map
    >>> Map("screw", (0,), (0,), ("drive.lead",))
    Map(type='screw', actuators=(0,), chain_joints=(0,), param_names=('drive.lead',), factor=1.0)
    >>> Map("coupled", (1, 2), (1, 2)).factor  # a FANUC arm's J2/J3
    1.0
    """

    type: str
    actuators: tuple[int, ...]
    chain_joints: tuple[int, ...]
    param_names: tuple[str, ...] = ()
    factor: float = 1.0

    def __post_init__(self) -> None:
        if self.type not in MAP_SHAPES:
            raise ModelError(f"transmission: unknown map type '{self.type}'; use one of {', '.join(MAP_SHAPES)}")
        shape = MAP_SHAPES[self.type]
        if (len(self.actuators), len(self.chain_joints), len(self.param_names)) != shape:
            raise ModelError(f"transmission: a '{self.type}' map takes {shape[0]} actuator(s), {shape[1]} joint(s) "
                             f"and {shape[2]} parameter(s)")
        if not np.isfinite(self.factor) or (self.type != "coupled" and self.factor != 1.0):
            raise ModelError(f"transmission: a factor (here {self.factor!r}) is a finite number of a 'coupled' map")


@dataclass(frozen=True, eq=False, repr=False)
class TransmissionRobot(Wrapped):
    """A serial chain whose joint variables are driven by actuators through a transmission.

    Its joints (what a user commands and a data file lists) are the actuators; the chain's joint variables
    follow from them through the maps. Its parameters are the chain's followed by the transmission's own
    (``drive``), so the drive parameters are identified like any other.

    Parameters
    ----------
    inner : SerialRobot
        The DH/MDH chain.
    params : Parameters
        The chain's parameters, then the transmission's (SI units: a screw lead in m per turn).
    joint_space : JointSpace
        The actuators: revolute (motor angles, rad) with finite limits.
    maps : tuple of Map
        The transmission: together they read every actuator once and drive every chain joint once.

    Attributes
    ----------
    drive : Parameters
        The transmission's own parameters (the end of ``params``).

    Raises
    ------
    ModelError
        When ``inner`` is not a SerialRobot, the maps do not drive each chain joint and read each actuator
        exactly once, a map names an unknown drive parameter, or an actuator is not revolute with finite limits.

    Examples
    --------
    A FANUC arm's J3 is the forearm's angle from the horizontal: the chain's third angle is J2 + J3.

    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.load_robot("fanuc_lrmate200id")
    >>> robot.structure, robot.joint_names[:3], robot.inner.joint_names[:3]
    ('dh + transmission', ('J1', 'J2', 'J3'), ('j1', 'j2', 'j3'))
    >>> chain = robot.chain_q(np.radians([0.0, 10.0, 20.0, 0.0, 0.0, 0.0]))
    >>> np.degrees(chain).round(6).tolist()
    [[0.0, 10.0, 30.0, 0.0, 0.0, 0.0]]
    >>> np.degrees(robot.actuator_q(chain)).round(6).tolist()
    [[0.0, 10.0, 20.0, 0.0, 0.0, 0.0]]
    """

    inner: SerialRobot  # checked in __post_init__
    joint_space: JointSpace
    maps: tuple[Map, ...]
    drive: Parameters = field(init=False, repr=False)  # the transmission's own parameters

    def __post_init__(self) -> None:
        super().__post_init__()
        p, n = self.params, self.inner.n_params
        object.__setattr__(self, "drive", Parameters(p.names[n:], p.values[n:], p.kinds[n:]))
        chain = self.inner
        if not isinstance(chain, SerialRobot):
            raise ModelError(f"{self.name}: a transmission drives a DH/MDH chain")
        n_a, n_j = len(self.joint_space), chain.n_joints
        driven = sorted(j for mp in self.maps for j in mp.chain_joints)
        if driven != list(range(n_j)):
            raise ModelError(f"{chain.name}: the transmission must drive each of the {n_j} chain joints "
                             f"exactly once (drives {driven})")
        used = sorted(a for mp in self.maps for a in mp.actuators)
        if used != list(range(n_a)):
            raise ModelError(f"{chain.name}: every actuator must feed exactly one map (uses {used})")
        self.drive.indices([n for mp in self.maps for n in mp.param_names])
        if set(self.joint_space.types) != {"revolute"} or not np.all(np.isfinite(self.lower + self.upper)):
            raise ModelError(f"{chain.name}: actuators are revolute (motor angles) with finite limits")

    @property
    def structure(self) -> str:
        return f"{self.inner.structure} + transmission"

    @property
    def motor_leads(self) -> np.ndarray:
        """(n_a,) m per rad: a screw's motor drives its travel by lead/2π, each motor of a differential screw the
        carriage by lead/4π; NaN for a direct or coupled actuator (it turns its joint)."""
        out = np.full(self.n_joints, np.nan)
        for mp in self.maps:
            if mp.type in ("screw", "differential_screw"):  # the lead is the map's first parameter
                out[list(mp.actuators)] = self.drive[mp.param_names[0]] / (TWO_PI * len(mp.actuators))
        return out

    # ---- the transmission ----------------------------------------------------------------------
    def chain_q(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """Chain joint values (N, n_j) for actuator values q (N, n_a)."""
        return self._transmit(self.check_q(q), self.param_values(values))[0]

    def actuator_q(self, chain_q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """Actuator values (N, n_a) that give the chain joint values ``chain_q`` (N, n_j): the inverse of
        :meth:`chain_q`."""
        qc = np.atleast_2d(np.asarray(chain_q, dtype=float))
        _, dv = self._split(self.param_values(values))
        phi = np.empty((len(qc), self.n_joints))
        for mp in self.maps:
            p = dv[self.drive.indices(mp.param_names)]
            if mp.type == "direct":
                phi[:, mp.actuators[0]] = qc[:, mp.chain_joints[0]]
            elif mp.type == "screw":
                phi[:, mp.actuators[0]] = TWO_PI * qc[:, mp.chain_joints[0]] / p[0]
            elif mp.type == "coupled":
                (a, b), (ja, jb) = mp.actuators, mp.chain_joints
                phi[:, a], phi[:, b] = qc[:, ja], qc[:, jb] - mp.factor * qc[:, ja]
            else:
                (a, b), (jt, jr), (lead, arm) = mp.actuators, mp.chain_joints, p
                s, d = 2 * TWO_PI * qc[:, jt] / lead, TWO_PI * arm * np.tan(qc[:, jr]) / lead
                phi[:, a], phi[:, b] = (s + d) / 2, (s - d) / 2
        return phi

    def _transmit(self, phi: np.ndarray, values: np.ndarray):
        """q (N, n_j), ∂q/∂φ (N, n_j, n_a) and ∂q/∂drive (N, n_j, P_drive) for actuator values φ."""
        _, dv = self._split(values)
        n, n_j, drive = phi.shape[0], self.inner.n_joints, self.drive
        q, dq_dphi, dq_ds = np.empty((n, n_j)), np.zeros((n, n_j, self.n_joints)), np.zeros((n, n_j, len(drive)))
        for mp in self.maps:
            ix = drive.indices(mp.param_names)
            if mp.type == "direct":
                (a,), (j,) = mp.actuators, mp.chain_joints
                q[:, j] = phi[:, a]
                dq_dphi[:, j, a] = 1.0
            elif mp.type == "screw":
                (a,), (j,), (lead,), (il,) = mp.actuators, mp.chain_joints, dv[ix], ix
                q[:, j] = lead * phi[:, a] / TWO_PI
                dq_dphi[:, j, a] = lead / TWO_PI
                dq_ds[:, j, il] = phi[:, a] / TWO_PI
            elif mp.type == "coupled":
                (a, b), (ja, jb) = mp.actuators, mp.chain_joints
                q[:, ja], q[:, jb] = phi[:, a], phi[:, b] + mp.factor * phi[:, a]
                dq_dphi[:, ja, a] = dq_dphi[:, jb, b] = 1.0
                dq_dphi[:, jb, a] = mp.factor
            else:
                self._differential(mp, dv[ix], ix, phi, q, dq_dphi, dq_ds)
        return q, dq_dphi, dq_ds

    def _differential(self, mp: Map, p, ix, phi, q, dq_dphi, dq_ds) -> None:
        """A differential screw pair: carriage travel and lever turn (and their derivatives, in place)."""
        (a, b), (jt, jr), (lead, arm), (il, ia) = mp.actuators, mp.chain_joints, p, ix
        s, d = phi[:, a] + phi[:, b], phi[:, a] - phi[:, b]
        q[:, jt] = lead * s / (2 * TWO_PI)
        u = lead * d / (TWO_PI * arm)
        q[:, jr] = np.arctan(u)
        g = 1.0 / (1.0 + u * u)  # d atan(u)/du
        dq_dphi[:, jt, a] = dq_dphi[:, jt, b] = lead / (2 * TWO_PI)
        dq_dphi[:, jr, a] = g * lead / (TWO_PI * arm)
        dq_dphi[:, jr, b] = -dq_dphi[:, jr, a]
        dq_ds[:, jt, il] = s / (2 * TWO_PI)
        dq_ds[:, jr, il] = g * d / (TWO_PI * arm)
        dq_ds[:, jr, ia] = -g * u / arm

    # ---- Robot interface -----------------------------------------------------------------------
    def _forward_and_jacobian(self, q, values, jacobian):
        cv, _ = self._split(values)
        qj, _, dq_ds = self._transmit(q, values)
        if not jacobian:
            return self.inner.forward(qj, cv), None
        p, Jc, Jq = self.inner.forward_jacobians(qj, cv)
        return p, np.concatenate([Jc, Jq @ dq_ds], axis=2)

    def _joint_jacobian(self, q, values):
        qj, dq_dphi, _ = self._transmit(q, values)
        return self.inner.joint_jacobian(qj, self._split(values)[0]) @ dq_dphi

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: the actuator limits and the chain's joint limits (e.g. ``abs(ψ) ≤ 45°``, the carriage's
        travel) hold at actuator values q (N, n_a)."""
        q = self.check_q(q)
        return self.within_limits(q) & self.inner.within_limits(self.chain_q(q))


def build_transmission_robot(chain: SerialRobot, actuators: Sequence[tuple[str, float, float]],
                             maps: Sequence[Map], drive: Mapping[str, tuple[float, str]]) -> TransmissionRobot:
    """A TransmissionRobot from (name, lower, upper) actuators (rad), maps and drive parameters
    {name: (value SI, kind)}."""
    names = tuple(a[0] for a in actuators)
    if len(set(names)) != len(names):
        raise ModelError(f"{chain.name}: duplicate actuator names {names}")
    clash = sorted(set(chain.params.names) & set(drive))
    if clash:
        raise ModelError(f"{chain.name}: transmission parameter names clash with the chain: {clash}")
    p = chain.params
    params = Parameters(p.names + tuple(drive), list(p.values) + [v for v, _ in drive.values()],
                        p.kinds + tuple(k for _, k in drive.values()))
    space = JointSpace(names, ("revolute",) * len(names), [a[1] for a in actuators], [a[2] for a in actuators])
    return TransmissionRobot(chain, params, space, tuple(maps))
