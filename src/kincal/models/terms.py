"""Non-geometric error terms on top of any robot model: corrections of the joint values.

``ExtendedRobot(inner, terms)`` reads joint i at qᵢ + Δqᵢ(q), Δq = Σ_terms B(q)·θ with a known
basis B (N, n, m) per term, linear in the term's parameters θ:

* ``harmonics:k``: Δqᵢ = Σₖ aᵢₖ sin(k qᵢ) + bᵢₖ cos(k qᵢ) (encoder eccentricity k = 1, gear
  transmission error k = 2); parameters ``<joint>.h<k>s`` / ``.h<k>c`` (rad).
* ``compliance``: Δqᵢ = cᵢ τᵢ(q), τ the gravity load of the robot file's link masses (and an
  optional payload at the tool; :mod:`kincal.models.gravity`). The parameter ``<joint>.compliance``
  is the deflection (rad) at ``TAU_REF`` = 100 N·m, so cᵢ = value / 100 in rad/(N·m). One per
  joint that carries at least ``TAU_MIN`` RMS load.
* ``gravity-regressor``: the same deflections with the masses unknown: Δqᵢ = Σ_links,k θᵢℓₖ Yᵢℓₖ(q),
  Y the regressor columns in m; ``<joint>.g_<link>_<m|x|y|z>`` (rad at a 1 m arm).
* ``thermal:<covariate>``: the links' thermal growth with a covariate input (a temperature column),
  a term on the tool point itself (``acts_on`` "position"): :mod:`kincal.models.covariates`.

Covariates are inputs after the joints (``ExtendedRobot.covariates``, type "covariate"): every q of
such a robot carries them; a term reading one refuses values beyond its fitted range
(:meth:`ExtendedRobot.inputs_outside`). A robot may carry covariates and no term ("geometric").

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
from typing import ClassVar, Mapping, Sequence

import numpy as np

from ..checks import number
from ..errors import ModelError
from .covariates import Covariate, thermal_term
from .gravity import COMPONENTS, GravityModel
from .parameters import Parameters
from .joint_space import JointSpace
from .robot import Robot
from .wrapped import Wrapped

MIN_LEVER = 0.01  # m per rad: RMS tool motion per joint rotation below which angle terms are not modelled
TAU_REF = 100.0  # N·m: a compliance parameter is the deflection at this load
TAU_MIN = 0.5  # N·m: RMS load below which a joint gets no compliance
REGRESSOR_MIN = 1e-6  # m: RMS of a regressor column below which it is left out (no load in any pose)
SLOPE_STEP = 1e-6  # rad
TERMS = ("compliance", "gravity-regressor", "harmonics", "thermal")
THERMAL = "thermal:"  # the token of a thermal term is THERMAL + the covariate's name
MAX_PAYLOAD = 3000.0  # kg: the heaviest industrial robots carry about 2300 kg
MODELS = ("geometric", "nobeta", "compliance", "gravity-regressor", "harmonics:1", "harmonics:2", "harmonics:3",
          "harmonics:4")


def lever_joints(robot: Robot, q: np.ndarray) -> tuple[str, ...]:
    """Revolute joints whose rotation moves the tool by at least MIN_LEVER per rad (RMS over q)."""
    lever = np.sqrt(np.mean(np.sum(robot.joint_jacobian(robot.check_q(q)) ** 2, axis=1), axis=0))
    return tuple(j for j, t, arm in zip(robot.joint_names, robot.joint_types, lever)
                 if t == "revolute" and arm >= MIN_LEVER)


@dataclass(frozen=True, eq=False)
class Harmonics:
    """Joint-angle harmonics of ``order`` on the joints ``joint_names`` (at positions ``index`` among
    the robot's joints)."""

    acts_on: ClassVar[str] = "joints"  # Δq (N, n, m) on the joint values
    kind: ClassVar[str] = "angle"
    order: int
    index: tuple[int, ...]
    joint_names: tuple[str, ...]
    reference: None = None  # no geometry of its own (gravity terms keep theirs)

    @property
    def token(self) -> str:
        return f"harmonics:{self.order}"

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{j}.h{k}{sc}" for j in self.joint_names for k in range(1, self.order + 1) for sc in "sc")

    def basis(self, q: np.ndarray) -> np.ndarray:
        kq = q[:, list(self.index), None] * np.arange(1, self.order + 1)
        sc = np.stack([np.sin(kq), np.cos(kq)], axis=-1).reshape(len(q), len(self.index), -1)  # (N, r, 2k)
        B = np.zeros((len(q), q.shape[1]) + sc.shape[1:])  # (N, n, r, 2k): joint index[r] gets block r
        B[:, list(self.index), np.arange(len(self.index))] = sc
        return B.reshape(len(q), q.shape[1], -1)

    def slope(self, q: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(N, n, n): ∂Δq/∂q (diagonal)."""
        k = np.arange(1, self.order + 1)
        ab = theta.reshape(len(self.index), self.order, 2)
        out, index = np.zeros((len(q), q.shape[1], q.shape[1])), list(self.index)
        kq = q[:, index, None] * k  # (N, r, order)
        out[:, index, index] = (k * (np.cos(kq) * ab[:, :, 0] - np.sin(kq) * ab[:, :, 1])).sum(axis=2)
        return out

    def to_dict(self) -> dict:
        return {"type": "harmonics", "order": self.order, "joints": list(self.joint_names)}


@dataclass(frozen=True, eq=False)
class GravityTerm:
    """``compliance`` (one column per loaded joint: its load / TAU_REF) or ``gravity-regressor``
    (the regressor ``columns``: (joint index, link index, component))."""

    acts_on: ClassVar[str] = "joints"
    kind: ClassVar[str] = "angle"
    token: str
    gravity: GravityModel
    columns: tuple[tuple[int, int, int], ...]

    @property
    def reference(self) -> Robot:
        """The geometry whose link frames carry the masses (held fixed: the basis is known)."""
        return self.gravity.robot

    @property
    def names(self) -> tuple[str, ...]:
        joints, links = self.gravity.robot.joint_names, [ln[0] for ln in self.gravity.links()]
        if self.token == "compliance":
            return tuple(f"{joints[i]}.compliance" for i, _, _ in self.columns)
        return tuple(f"{joints[i]}.g_{links[ell]}_{COMPONENTS[c]}" for i, ell, c in self.columns)

    def basis(self, q: np.ndarray) -> np.ndarray:
        return self.gravity._cached(f"basis:{self.columns}", q, self._basis)

    def _basis(self, q: np.ndarray) -> np.ndarray:
        i, ell, c = np.array(self.columns, dtype=int).reshape(-1, 3).T
        B = np.zeros((len(q), q.shape[1], len(self.columns)))
        if self.token == "compliance":
            B[:, i, np.arange(len(i))] = self.gravity.torques(q)[:, i] / TAU_REF
        else:
            B[:, i, np.arange(len(i))] = self.gravity.regressor(q)[:, i, ell, c]
        return B

    def slope(self, q: np.ndarray, theta: np.ndarray) -> np.ndarray:
        out = np.empty((len(q), q.shape[1], q.shape[1]))
        for k, step in enumerate(SLOPE_STEP * np.eye(q.shape[1])):
            out[:, :, k] = (self.basis(q + step) - self.basis(q - step)) @ theta / (2 * SLOPE_STEP)
        return out

    def to_dict(self) -> dict:
        joints = self.gravity.robot.joint_names
        if self.token == "compliance":
            return {"type": "compliance", "joints": [joints[i] for i, _, _ in self.columns],
                    "payload": self.gravity.payload}
        return {"type": "gravity-regressor", "payload": self.gravity.payload, "columns": list(self.names)}


@dataclass(frozen=True, eq=False, repr=False)
class ExtendedRobot(Wrapped):
    """A geometric robot (``inner``) with non-geometric ``terms`` and the ``covariates`` it reads after
    its joints; ``params`` = inner's, then each term's. q has inner's n joints, then one column per
    covariate."""

    terms: tuple
    covariates: tuple[Covariate, ...] = ()
    joint_space: JointSpace = field(init=False, repr=False)
    _sizes: tuple[int, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        if isinstance(self.inner, ExtendedRobot) or not (self.terms or self.covariates):
            raise ModelError(f"robot '{self.inner.name}': terms go on a geometric model")
        names = list(self.inner.params.names) + [n for t in self.terms for n in t.names]
        if self.params.names != tuple(names):
            raise ModelError(f"robot '{self.inner.name}': parameters do not match the error model")
        js, limits = self.inner.joint_space, [c.limits() for c in self.covariates]
        space = js if not self.covariates else JointSpace(
            js.names + tuple(c.name for c in self.covariates), js.types + ("covariate",) * len(self.covariates),
            [*js.lower, *(lo for lo, _ in limits)], [*js.upper, *(hi for _, hi in limits)])
        object.__setattr__(self, "joint_space", space)
        object.__setattr__(self, "_sizes", tuple(len(t.names) for t in self.terms))

    @classmethod
    def build(cls, inner: Robot, terms: Sequence, values: Mapping[str, float] | None = None,
              covariates: Sequence[Covariate] = ()) -> "ExtendedRobot":
        names = [n for t in terms for n in t.names]
        params = Parameters(list(inner.params.names) + names, list(inner.params.values) + [0.0] * len(names),
                            list(inner.params.kinds) + [t.kind for t in terms for _ in t.names])
        robot = cls(inner, params, tuple(terms), tuple(covariates))
        return robot.with_params(dict(values)) if values else robot

    # ---- the Robot interface, delegated to the geometry at the corrected joint values -----------
    @property
    def error_model(self) -> str:
        return "+".join(t.token for t in self.terms) or "geometric"

    @property
    def structure(self) -> str:
        return self.inner.structure + ("" if not self.terms else f" + {self.error_model}")

    @property
    def term_names(self) -> tuple[str, ...]:
        return self.params.names[self.inner.n_params:]

    def inputs_outside(self, q: np.ndarray) -> tuple[np.ndarray, str]:
        """(N,) bool: the rows whose covariates a term reads lie beyond the range it was fitted on, and
        why, naming each such covariate and its range ('' when none)."""
        bad, why = np.zeros(len(q), bool), []
        for t in self.terms:
            if t.acts_on == "position":
                out = t.covariate.outside(q[:, t.index])
                if out.any():
                    bad |= out
                    got = ", ".join(f"{v:g}" for v in q[out, t.index][:3])
                    why.append(f"covariate {t.covariate.describe()}, got {got}")
        return bad, ("; ".join(why) + ": the model does not extrapolate its covariate terms; measure inside the "
                     "range or calibrate over a wider one") if why else ""

    def _refuse_outside(self, q: np.ndarray) -> None:
        bad, why = self.inputs_outside(q)
        if bad.any():
            raise ModelError(f"robot '{self.name}': {int(bad.sum())} of {len(q)} sample(s): {why}")

    def _thetas(self, values: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """(the geometry's values, each term's parameters) of a (P,) vector."""
        cuts = np.cumsum((self.inner.n_params,) + self._sizes)
        return values[:cuts[0]], [values[a:b] for a, b in zip(cuts[:-1], cuts[1:])]

    def _joint_terms(self, thetas) -> list:
        return [(t, th) for t, th in zip(self.terms, thetas) if t.acts_on == "joints"]

    def corrected(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """The joint values (N, n) the geometry uses (inner's joints: covariates are not joints)."""
        q = self.check_q(q)
        _, thetas = self._thetas(self.param_values(values))
        qj = q[:, :self.inner.n_joints]
        return qj + sum(t.basis(qj) @ th for t, th in self._joint_terms(thetas))

    def _forward_and_jacobian(self, q, values, jacobian):
        self._refuse_outside(q)
        inner_values, thetas = self._thetas(values)
        qj = q[:, :self.inner.n_joints]
        bases = [t.basis(qj if t.acts_on == "joints" else q) for t in self.terms]
        on_joints = [t.acts_on == "joints" for t in self.terms]
        qc = qj + sum(B @ th for B, th, j in zip(bases, thetas, on_joints) if j)
        moved = sum(B @ th for B, th, j in zip(bases, thetas, on_joints) if not j)
        if not jacobian:
            return self.inner.forward_and_jacobian(qc, inner_values, jacobian=False)[0] + moved, None
        p, Jb, Jq = self.inner.forward_jacobians(qc, inner_values)  # Jq: (N, 3, n)
        return p + moved, np.concatenate([Jb] + [Jq @ B if j else B for B, j in zip(bases, on_joints)], axis=2)

    def _joint_jacobian(self, q, values):
        self._refuse_outside(q)
        inner_values, thetas = self._thetas(values)
        qj = q[:, :self.inner.n_joints]
        J = self.inner.joint_jacobian(self.corrected(q, values), inner_values)
        J = J + sum(J @ t.slope(qj, th) for t, th in self._joint_terms(thetas))
        out = np.concatenate([J, np.zeros((len(q), 3, len(self.covariates)))], axis=2)
        return out + sum(t.slope(q, th) for t, th in zip(self.terms, thetas) if t.acts_on == "position")

    def feasible(self, q: np.ndarray) -> np.ndarray:
        q = self.check_q(q)
        return self.inner.feasible(q[:, :self.inner.n_joints]) & self.within_limits(q)

    def compliances(self) -> dict[str, float]:
        """Per joint with a compliance term: the compliance in rad/(N·m)."""
        return {n.split(".")[0]: self.params[n] / TAU_REF for n in self.term_names if n.endswith(".compliance")}


def with_covariates(robot: Robot, names: Sequence[str] | None) -> Robot:
    """``robot`` reading the covariate columns ``names`` after its joints (not yet fitted: any value),
    with no term on them yet (the error model ``thermal:<name>`` adds one); ``robot`` itself for none, or
    when it reads exactly these already (a calibrated file). ValueError when it reads others."""
    names = tuple(names or ())
    have = robot.covariates if isinstance(robot, ExtendedRobot) else ()
    if not names or tuple(c.name for c in have) == names:
        return robot
    if have:
        raise ValueError(f"--covariate-cols {','.join(names)}: the model reads the covariate(s) "
                         f"{', '.join(c.name for c in have)}; give those columns, or leave the flag out")
    if len(set(names)) != len(names):
        raise ValueError(f"--covariate-cols {','.join(names)}: a column is named twice")
    covs = tuple(Covariate(n) for n in names)  # ModelError for a name no column can have
    if isinstance(robot, ExtendedRobot):  # terms on the joints already (a robot file's harmonics)
        return dataclasses.replace(robot, covariates=covs)
    return ExtendedRobot.build(robot, (), covariates=covs)


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
    return ExtendedRobot.build(robot.inner, terms, values, robot.covariates) if terms or robot.covariates \
        else robot.inner


def parse_model(name: str) -> tuple[str, ...]:
    """The tokens of an error-model name such as "compliance+harmonics:2" (ValueError naming the choices)."""
    tokens = tuple(name.split("+")) if isinstance(name, str) else ()
    families = [t if t.startswith(THERMAL) else t.split(":")[0] for t in tokens]
    ok = bool(tokens) and all(t in MODELS or _thermal_token(t) for t in tokens) and len(set(families)) == len(families)
    ok = ok and ("geometric" not in tokens or len(tokens) == 1)
    ok = ok and not {"compliance", "gravity-regressor"} <= set(tokens)
    if not ok:
        raise ValueError(f"error model '{name}': use geometric, or one or more of nobeta, compliance or "
                         f"gravity-regressor, harmonics:1..4, thermal:<covariate column> joined by '+' (e.g. "
                         f"compliance+harmonics:2), or auto")
    return tokens


def _thermal_token(token: str) -> bool:
    name = token[len(THERMAL):]
    return token.startswith(THERMAL) and bool(name) and not any(c in name for c in ".,: ")


@dataclass(frozen=True)
class ErrorModel:
    """What to model beyond the geometry, validated when built: ``name`` is "geometric", terms joined
    by '+' ("compliance+harmonics:2"; see :func:`parse_model`) or "auto" (chosen by joint-space
    blocked cross-validation in :func:`kincal.calibrate`); ``payload`` (kg) at the tool point loads
    the gravity terms."""

    name: str = "geometric"
    payload: float = 0.0

    def __post_init__(self) -> None:
        tokens = parse_model(self.name) if self.name != "auto" else ()
        object.__setattr__(self, "payload", number("payload", self.payload, positive=False, unit="kg at the tool"))
        if self.payload > MAX_PAYLOAD:
            raise ValueError(f"payload={self.payload:g} kg: more than any robot carries ({MAX_PAYLOAD:g} kg); give the "
                             f"payload at the tool in kg")
        if self.payload > 0 and self.name != "auto" and not {"compliance", "gravity-regressor"} & set(tokens):
            raise ValueError(f"payload={self.payload:g} kg: only the gravity terms (compliance, gravity-regressor) use "
                             f"it, and error model '{self.name}' has none")

    @classmethod
    def of(cls, value: "ErrorModel | str | Mapping") -> "ErrorModel":
        """An ErrorModel from itself, a name, or its :meth:`to_dict`."""
        if isinstance(value, ErrorModel):
            return value
        if isinstance(value, str):
            return cls(value)
        if isinstance(value, Mapping) and set(value) <= {"name", "payload"}:
            return cls(**value)
        raise ValueError(f"error model {value!r}: give a name such as 'compliance+harmonics:2' or 'auto'")

    def to_dict(self) -> dict:
        return {"name": self.name, "payload": self.payload}


def extend(robot: Robot, error_model: ErrorModel | str, q: np.ndarray | None = None) -> Robot:
    """``robot`` with the error model (see :class:`ErrorModel`; not "auto"): terms on the joints with
    a lever arm at the poses q (default: 200 random poses); gravity terms load the robot's link
    masses and the payload at the tool point, with ``robot``'s geometry as reference; the covariates
    ``robot`` reads are fitted on q (median and range: :class:`~kincal.models.covariates.Covariate`),
    and a thermal term grows the links of that geometry with one of them."""
    spec = ErrorModel.of(error_model)
    if spec.name == "auto":
        raise ValueError("error model 'auto' is chosen by calibrate(); extend() takes a named model")
    tokens = parse_model(spec.name)
    inner, covs = (robot.inner, robot.covariates) if isinstance(robot, ExtendedRobot) else (robot, ())
    n = inner.n_joints
    if q is None:
        q = robot.sample_joints(200, seed=0)
    else:
        q = robot.check_q(q)
        covs = tuple(Covariate.of_data(c.name, q[:, n + i]) for i, c in enumerate(covs))
    if "nobeta" in tokens:
        inner = inner.without_beta()
    if "compliance" in tokens and inner.has_load_compliance:  # the model's own (a hexapod's legs), not a term
        inner, tokens = inner.with_load_compliance(), tuple(t for t in tokens if t != "compliance")
    terms = [thermal_term(inner, tok[len(THERMAL):], covs) if tok.startswith(THERMAL) else
             _term(inner, tok, q[:, :n], spec.payload) for tok in tokens if tok not in ("geometric", "nobeta")]
    return ExtendedRobot.build(inner, terms, covariates=covs) if terms or covs else inner


def _term(geometry: Robot, token: str, q: np.ndarray, payload: float):
    joints = lever_joints(geometry, q)
    index = [geometry.joint_names.index(j) for j in joints]
    if not joints:
        raise ModelError(f"robot '{geometry.name}': no revolute joint moves the tool enough for joint-angle terms")
    if token.startswith("harmonics"):
        return Harmonics(int(token.split(":")[1]), tuple(index), joints)
    gravity = geometry.gravity(payload)
    if token == "compliance":
        if gravity.total_mass <= 0.0:
            raise ModelError(f"robot '{geometry.name}': 'compliance' needs link masses: give mass and com per joint in "
                             f"the robot file (URDF: <inertial>) or a payload, or use gravity-regressor")
        rms = np.sqrt(np.mean(gravity.torques(q) ** 2, axis=0))
        cols = tuple((i, 0, 0) for i in index if rms[i] >= TAU_MIN)
    else:
        rms = np.sqrt(np.mean(gravity.regressor(q) ** 2, axis=0))  # (n, L, 4)
        cols = tuple((i, ell, c) for i in index for ell in range(rms.shape[1]) for c in range(4)
                     if rms[i, ell, c] >= REGRESSOR_MIN)
    if not cols:
        raise ModelError(f"robot '{geometry.name}': no joint carries a gravity load at these poses for '{token}'")
    return GravityTerm(token, gravity, cols)
