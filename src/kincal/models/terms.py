"""Non-geometric error terms on top of any robot model: corrections of the joint values.

``ExtendedRobot(base, terms)`` reads joint i at qᵢ + Δqᵢ(q), Δq = Σ_terms B(q)·θ with a known
basis B (N, n, m) per term, linear in the term's parameters θ:

* ``harmonics:k``: Δqᵢ = Σₖ aᵢₖ sin(k qᵢ) + bᵢₖ cos(k qᵢ) (encoder eccentricity k = 1, gear
  transmission error k = 2); parameters ``<joint>.h<k>s`` / ``.h<k>c`` (rad).
* ``compliance``: Δqᵢ = cᵢ τᵢ(q), τ the gravity load of the robot file's link masses (and an
  optional payload at the tool; :mod:`kincal.models.gravity`). The parameter ``<joint>.compliance``
  is the deflection (rad) at ``TAU_REF`` = 100 N·m, so cᵢ = value / 100 in rad/(N·m). One per
  joint that carries at least ``TAU_MIN`` RMS load.
* ``gravity-regressor``: the same deflections with the masses unknown: Δqᵢ = Σ_links,k θᵢℓₖ Yᵢℓₖ(q),
  Y the regressor columns in m; ``<joint>.g_<link>_<m|x|y|z>`` (rad at a 1 m arm).

Terms go on revolute joints whose angle moves the tool point by at least ``MIN_LEVER`` per radian
(a joint turning the tool about itself cannot show its angle errors). All are bounded functions of
q: none is linear in q (a joint scale error, which real encoders do not have), and gravity loads are
bounded by the masses. The parameter Jacobian is analytic: ∂p/∂θ = (∂p/∂q) B at the corrected
values. ``joint_jacobian`` includes the slope of Δq (harmonics analytic; gravity loads by central
differences of the load, step ``SLOPE_STEP``: a correction of order c·∂τ/∂q ≈ 1e-4). Everything
else — identifiability, LM, covariance, compensation — sees an ordinary Robot.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .gravity import COMPONENTS, GravityModel
from .parameters import Parameters
from .robot import Robot, Wrapped
from .serial import ChainRobot, SerialRobot

MIN_LEVER = 0.01  # m per rad: RMS tool motion per joint rotation below which angle terms are not modelled
TAU_REF = 100.0  # N·m: a compliance parameter is the deflection at this load
TAU_MIN = 0.5  # N·m: RMS load below which a joint gets no compliance
REGRESSOR_MIN = 1e-6  # m: RMS of a regressor column below which it is left out (no load in any pose)
SLOPE_STEP = 1e-6  # rad
TERMS = ("compliance", "gravity-regressor", "harmonics")
MODELS = ("geometric", "nobeta", "compliance", "gravity-regressor", "harmonics:1", "harmonics:2", "harmonics:3",
          "harmonics:4")


def harmonic_names(joints: Sequence[str], order: int) -> list[str]:
    return [f"{j}.h{k}{sc}" for j in joints for k in range(1, order + 1) for sc in ("s", "c")]


def lever_joints(robot: Robot, q: np.ndarray) -> tuple[str, ...]:
    """Revolute joints whose rotation moves the tool by at least MIN_LEVER per rad (RMS over q)."""
    lever = np.sqrt(np.mean(np.sum(robot.joint_jacobian(robot.check_q(q)) ** 2, axis=1), axis=0))
    return tuple(j for j, t, arm in zip(robot.joint_names, robot.joint_types, lever)
                 if t == "revolute" and arm >= MIN_LEVER)


@dataclass(frozen=True, eq=False)
class Harmonics:
    """Joint-angle harmonics of ``order`` on joints ``index`` (positions in the robot's joints)."""

    order: int
    index: tuple[int, ...]
    joints: tuple[str, ...]

    token = property(lambda self: f"harmonics:{self.order}")
    names = property(lambda self: tuple(harmonic_names(self.joints, self.order)))

    def basis(self, q: np.ndarray) -> np.ndarray:
        kq = q[:, list(self.index), None] * np.arange(1, self.order + 1)
        sc = np.stack([np.sin(kq), np.cos(kq)], axis=-1).reshape(len(q), len(self.index), -1)  # (N, r, 2k)
        B = np.zeros((len(q), q.shape[1], sc.shape[1] * sc.shape[2]))
        for r, i in enumerate(self.index):
            B[:, i, r * sc.shape[2]:(r + 1) * sc.shape[2]] = sc[:, r]
        return B

    def slope(self, q: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(N, n, n): ∂Δq/∂q (diagonal)."""
        k = np.arange(1, self.order + 1)
        ab = theta.reshape(len(self.index), self.order, 2)
        out = np.zeros((len(q), q.shape[1], q.shape[1]))
        for r, i in enumerate(self.index):
            kq = q[:, i, None] * k
            out[:, i, i] = (k * (np.cos(kq) * ab[r, :, 0] - np.sin(kq) * ab[r, :, 1])).sum(axis=1)
        return out

    def to_dict(self) -> dict:
        return {"type": "harmonics", "order": self.order, "joints": list(self.joints)}


@dataclass(frozen=True, eq=False)
class GravityTerm:
    """``compliance`` (one column per loaded joint: its load / TAU_REF) or ``gravity-regressor``
    (the regressor ``columns``: (joint index, link index, component))."""

    kind: str
    gravity: GravityModel
    columns: tuple[tuple[int, int, int], ...]

    token = property(lambda self: self.kind)

    @property
    def names(self) -> tuple[str, ...]:
        joints, links = self.gravity.robot.joint_names, [ln[0] for ln in self.gravity.links()]
        if self.kind == "compliance":
            return tuple(f"{joints[i]}.compliance" for i, _, _ in self.columns)
        return tuple(f"{joints[i]}.g_{links[ell]}_{COMPONENTS[c]}" for i, ell, c in self.columns)

    def basis(self, q: np.ndarray) -> np.ndarray:
        return self.gravity._cached(f"basis:{self.columns}", q, self._basis)

    def _basis(self, q: np.ndarray) -> np.ndarray:
        B = np.zeros((len(q), q.shape[1], len(self.columns)))
        if self.kind == "compliance":
            tau = self.gravity.torques(q) / TAU_REF
            for col, (i, _, _) in enumerate(self.columns):
                B[:, i, col] = tau[:, i]
        else:
            Y = self.gravity.regressor(q)
            for col, (i, ell, c) in enumerate(self.columns):
                B[:, i, col] = Y[:, i, ell, c]
        return B

    def slope(self, q: np.ndarray, theta: np.ndarray) -> np.ndarray:
        out = np.empty((len(q), q.shape[1], q.shape[1]))
        for k in range(q.shape[1]):
            step = np.zeros(q.shape[1])
            step[k] = SLOPE_STEP
            out[:, :, k] = (self.basis(q + step) - self.basis(q - step)) @ theta / (2 * SLOPE_STEP)
        return out

    def to_dict(self) -> dict:
        joints = self.gravity.robot.joint_names
        if self.kind == "compliance":
            return {"type": "compliance", "joints": [joints[i] for i, _, _ in self.columns],
                    "payload": self.gravity.payload}
        return {"type": "gravity-regressor", "payload": self.gravity.payload, "columns": list(self.names)}


@dataclass(frozen=True, eq=False, repr=False)
class ExtendedRobot(Wrapped):
    """``base`` with non-geometric ``terms``; ``params`` = base's, then each term's."""

    base: Robot
    terms: tuple
    params: Parameters
    _sizes: tuple[int, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if isinstance(self.base, ExtendedRobot) or not self.terms:
            raise ModelError(f"robot '{self.base.name}': terms go on a geometric model")
        names = list(self.base.params.names) + [n for t in self.terms for n in t.names]
        if self.params.names != tuple(names):
            raise ModelError(f"robot '{self.base.name}': parameters do not match the error model")
        object.__setattr__(self, "_sizes", tuple(len(t.names) for t in self.terms))

    @classmethod
    def build(cls, base: Robot, terms: Sequence, values: Mapping[str, float] | None = None) -> "ExtendedRobot":
        names = [n for t in terms for n in t.names]
        params = Parameters(list(base.params.names) + names, list(base.params.values) + [0.0] * len(names),
                            list(base.params.kinds) + ["angle"] * len(names))
        robot = cls(base, tuple(terms), params)
        return robot.with_params(dict(values)) if values else robot

    # ---- the Robot interface, delegated to the base at the corrected joint values -------------
    name = property(lambda self: self.base.name)  # type: ignore[assignment]
    description = property(lambda self: self.base.description)
    joint_names = property(lambda self: self.base.joint_names)  # type: ignore[assignment]
    joint_types = property(lambda self: self.base.joint_types)  # type: ignore[assignment]
    lower = property(lambda self: self.base.lower)  # type: ignore[assignment]
    upper = property(lambda self: self.base.upper)  # type: ignore[assignment]

    @property
    def model(self) -> str:
        return "+".join(t.token for t in self.terms)

    @property
    def kind(self) -> str:
        return f"{self.base.kind} + {self.model}"

    @property
    def term_names(self) -> tuple[str, ...]:
        return self.params.names[self.base.n_params:]

    def with_params(self, values) -> "ExtendedRobot":
        new = values if isinstance(values, Parameters) else self.params.replace(values)
        return ExtendedRobot(self.base.with_params(new.values[:self.base.n_params]), self.terms, new)

    def _split(self, params) -> tuple[np.ndarray, list[np.ndarray]]:
        v = self.param_values(params)
        cuts = np.cumsum((self.base.n_params,) + self._sizes)
        return v[:cuts[0]], [v[a:b] for a, b in zip(cuts[:-1], cuts[1:])]

    def corrected(self, q: np.ndarray, params=None) -> np.ndarray:
        """The joint values the model uses for commanded/read values q (N, n)."""
        q = self.check_q(q)
        _, thetas = self._split(params)
        return q + sum(t.basis(q) @ th for t, th in zip(self.terms, thetas))

    def forward_and_jacobian(self, q, params=None, jacobian=True):
        q = self.check_q(q)
        base_values, thetas = self._split(params)
        bases = [t.basis(q) for t in self.terms]
        qc = q + sum(B @ th for B, th in zip(bases, thetas))
        if not jacobian:
            return self.base.forward_and_jacobian(qc, base_values, jacobian=False)
        p, Jb, Jq = self.base.forward_jacobians(qc, base_values)  # Jq: (N, 3, n)
        return p, np.concatenate([Jb] + [Jq @ B for B in bases], axis=2)

    def joint_jacobian(self, q, params=None):
        squeeze = np.ndim(q) == 1
        q = self.check_q(q)
        base_values, thetas = self._split(params)
        J = self.base.joint_jacobian(self.corrected(q, params), base_values)
        J = J + sum(J @ t.slope(q, th) for t, th in zip(self.terms, thetas))
        return J[0] if squeeze else J

    inner = property(lambda self: self.base)

    def feasible(self, q: np.ndarray) -> np.ndarray:
        return self.base.feasible(q)

    def compliances(self) -> dict[str, float]:
        """Per joint with a compliance term: the compliance in rad/(N·m)."""
        return {n.split(".")[0]: self.params[n] / TAU_REF for n in self.term_names if n.endswith(".compliance")}


def drop_terms(robot: Robot, names: Sequence[str]) -> Robot:
    """``robot`` without the gravity-term parameters ``names`` (a term left without columns goes)."""
    if not isinstance(robot, ExtendedRobot):
        return robot
    terms = []
    for t in robot.terms:
        if isinstance(t, GravityTerm):
            t = dataclasses.replace(t, columns=tuple(c for c, n in zip(t.columns, t.names) if n not in names))
        if t.names:
            terms.append(t)
    values = {n: robot.params[n] for t in terms for n in t.names}
    return ExtendedRobot.build(robot.base, terms, values) if terms else robot.base


def parse_model(model: str) -> tuple[str, ...]:
    """The tokens of a model name such as "compliance+harmonics:2" (ValueError naming the choices)."""
    tokens = tuple(model.split("+")) if isinstance(model, str) else ()
    kinds = [t.split(":")[0] for t in tokens]
    ok = bool(tokens) and all(t in MODELS for t in tokens) and len(set(kinds)) == len(kinds)
    ok = ok and ("geometric" not in tokens or len(tokens) == 1)
    ok = ok and not {"compliance", "gravity-regressor"} <= set(tokens)
    if not ok:
        raise ValueError(f"model '{model}': use geometric, or one or more of nobeta, compliance or gravity-regressor, "
                         f"harmonics:1..4 joined by '+' (e.g. compliance+harmonics:2), or auto")
    return tokens


def without_beta(robot: Robot) -> Robot:
    """A DH/MDH robot without its β tilts (their values dropped)."""
    if not isinstance(robot, SerialRobot):
        raise ModelError(f"robot '{robot.name}' ({robot.kind}): 'nobeta' applies to DH/MDH chains")
    return robot.with_joints([dataclasses.replace(j, beta=False) for j in robot.joints])


def extend(robot: Robot, model: str, q: np.ndarray | None = None, payload: float = 0.0) -> Robot:
    """``robot`` with the error model ``model`` (see :func:`parse_model`): terms on the joints with a
    lever arm at the poses q (default: 200 random poses); gravity terms load the robot's link masses
    and ``payload`` kg at the tool point, with ``robot``'s geometry as reference."""
    tokens = parse_model(model)
    base = robot.base if isinstance(robot, ExtendedRobot) else robot
    if "nobeta" in tokens:
        base = without_beta(base)
    q = base.sample_joints(200, seed=0) if q is None else base.check_q(q)
    terms = [_term(base, tok, q, payload) for tok in tokens if tok not in ("geometric", "nobeta")]
    return ExtendedRobot.build(base, terms) if terms else base


def _term(base: Robot, token: str, q: np.ndarray, payload: float):
    joints = lever_joints(base, q)
    index = [base.joint_names.index(j) for j in joints]
    if not joints:
        raise ModelError(f"robot '{base.name}': no revolute joint moves the tool enough for joint-angle terms")
    if token.startswith("harmonics"):
        return Harmonics(int(token.split(":")[1]), tuple(index), joints)
    if not isinstance(base, ChainRobot):
        raise ModelError(f"robot '{base.name}' ({base.kind}): gravity terms need a serial chain")
    gravity = GravityModel(base, float(payload))
    if token == "compliance":
        if gravity.total_mass <= 0.0:
            raise ModelError(f"robot '{base.name}': 'compliance' needs link masses: give mass and com per joint in the "
                             f"robot file (URDF: <inertial>) or a payload, or use gravity-regressor")
        rms = np.sqrt(np.mean(gravity.torques(q) ** 2, axis=0))
        cols = tuple((i, 0, 0) for i in index if rms[i] >= TAU_MIN)
    else:
        rms = np.sqrt(np.mean(gravity.regressor(q) ** 2, axis=0))  # (n, L, 4)
        cols = tuple((i, ell, c) for i in index for ell in range(rms.shape[1]) for c in range(4)
                     if rms[i, ell, c] >= REGRESSOR_MIN)
    if not cols:
        raise ModelError(f"robot '{base.name}': no joint carries a gravity load at these poses for '{token}'")
    return GravityTerm(token, gravity, cols)


def term_from_dict(base: Robot, reference: Robot | None, data: dict, where: str):
    """A term saved by :meth:`to_dict` (``reference``: the geometry of its gravity loads)."""
    kind = data.get("type") if isinstance(data, dict) else None
    index = {j: i for i, j in enumerate(base.joint_names)}
    joints = data.get("joints", []) if isinstance(data, dict) else None
    if kind not in TERMS or not isinstance(joints, list) or any(j not in index for j in joints):
        raise ModelError(f"{where}: a term is {{type: harmonics|compliance|gravity-regressor, ...}} on joints of "
                         f"the robot ({', '.join(base.joint_names)})")
    if kind == "harmonics":
        order = data.get("order")
        if not isinstance(order, int) or isinstance(order, bool) or not 1 <= order <= 4:
            raise ModelError(f"{where}: harmonics 'order' must be a whole number from 1 to 4")
        return Harmonics(order, tuple(index[j] for j in joints), tuple(joints))
    payload = data.get("payload", 0.0)
    if not isinstance(reference, ChainRobot) or isinstance(payload, bool) or not isinstance(payload, (int, float)) \
            or not payload >= 0:
        raise ModelError(f"{where}: a gravity term needs a serial chain, its 'reference' geometry and a payload in kg "
                         f"(0 or more)")
    gravity = GravityModel(reference, float(payload))
    if kind == "compliance":
        return GravityTerm(kind, gravity, tuple((index[j], 0, 0) for j in joints))
    links = {ln[0]: k for k, ln in enumerate(gravity.links())}
    cols = []
    for name in data.get("columns", []) if isinstance(data.get("columns"), list) else [None]:
        joint, _, rest = str(name).partition(".g_")
        link, _, comp = rest.rpartition("_")
        if joint not in index or link not in links or comp not in COMPONENTS:
            raise ModelError(f"{where}: gravity-regressor column '{name}' is not <joint>.g_<link>_<m|x|y|z>")
        cols.append((index[joint], links[link], COMPONENTS.index(comp)))
    return GravityTerm(kind, gravity, tuple(cols))


def model_name(robot: Robot) -> str:
    return robot.model if isinstance(robot, ExtendedRobot) else "geometric"
