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
from ..ties import order_with_ties
from .covariates import Covariate, ThermalTerm, thermal_term
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
GRAVITY_TERMS = frozenset({"compliance", "gravity-regressor"})  # the terms a payload loads
THERMAL = "thermal:"  # the token of a thermal term is THERMAL + the covariate's name
MAX_PAYLOAD = 3000.0  # kg: the heaviest industrial robots carry about 2300 kg
PAYLOAD_MARGIN = 2.0  # a payload loading a joint this many times beyond its effort limit is refused (grams as kg?)
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
    """A geometric robot with non-geometric error terms, and the covariates it reads after its joints.

    The geometry reads each joint at its corrected value q + Δq(q) (terms on the joints: harmonics, compliance,
    gravity regressor); a term on the position (thermal growth) adds to the tool point. Build one with
    :func:`extend` or :meth:`ExtendedRobot.build`. Its inputs q are ``inner``'s n joints, then one column per
    covariate.

    Parameters
    ----------
    inner : Robot
        The geometric robot (not itself an ExtendedRobot).
    params : Parameters
        ``inner``'s parameters, then each term's, in the order of ``terms`` (rad for joint terms).
    terms : tuple
        The error terms (each with its parameter names, basis and slope); may be empty when ``covariates``
        is not.
    covariates : tuple of Covariate, optional
        The inputs read after the joints (a temperature column), each limited to the range it was fitted on
        (default none).

    Attributes
    ----------
    joint_space : JointSpace
        ``inner``'s joints, then the covariates (type "covariate").

    Raises
    ------
    ModelError
        When ``inner`` is an ExtendedRobot, there is neither a term nor a covariate, or ``params`` does not
        match ``inner`` and the terms.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.extend(kincal.load_robot("ur5"), "harmonics:1")
    >>> type(robot).__name__, robot.structure, robot.n_params
    ('ExtendedRobot', 'dh + harmonics:1', 45)
    >>> robot.term_names[:4]
    ('j1.h1s', 'j1.h1c', 'j2.h1s', 'j2.h1c')
    >>> q = robot.sample_joints(3, seed=1)
    >>> bool(np.array_equal(robot.corrected(q), q))  # all terms 0: the joints read as they are
    True
    >>> tilted = robot.with_params({"j2.h1s": 1e-4})  # 0.1 mrad · sin(q2) on joint 2
    >>> bool(np.allclose(tilted.corrected(q)[:, 1] - q[:, 1], 1e-4 * np.sin(q[:, 1])))
    True
    """

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
        """Build the robot with its term parameters laid out after ``inner``'s, all 0 unless ``values`` (by
        name, SI units) gives them; ``covariates`` are the inputs read after the joints."""
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

    def value_units(self) -> dict[str, str]:
        """A compliance is the deflection at ``TAU_REF``, a gravity-regressor parameter the deflection at a 1 m load
        column, a thermal rate per unit of its covariate.

        >>> import kincal
        >>> from kincal.models import with_covariates
        >>> kincal.extend(kincal.load_robot("ur5"), "compliance").value_units()["j2.compliance"]
        'deflection at 100 N·m'
        >>> warm = kincal.extend(with_covariates(kincal.load_robot("ur5"), ["temperature"]), "thermal:temperature")
        >>> warm.value_units()["j2.temperature"]
        'per unit of temperature'
        """
        per = {"compliance": f"deflection at {TAU_REF:g} N·m", "gravity-regressor": "deflection at a 1 m load column"}
        return {n: per[t.token] if isinstance(t, GravityTerm) else f"per unit of {t.covariate.name}"
                for t in self.terms if isinstance(t, (GravityTerm, ThermalTerm)) for n in t.names}

    def correction_scales(self, q: np.ndarray) -> dict[str, tuple[float, str]]:
        """A compliance (the deflection at ``TAU_REF``) deflects its joint at the poses q (N, n) by at most its value
        × max|τ| / ``TAU_REF``, τ that joint's gravity load there (N·m): its scale, and that load in words."""
        qj, out = self.check_q(q)[:, :self.inner.n_joints], {}
        for t in self.terms:
            if isinstance(t, GravityTerm) and t.token == "compliance":
                peak = np.abs(t.basis(qj)).max(axis=(0, 1)) if len(qj) else np.zeros(len(t.names))
                out.update({n: (float(s), f"at {s * TAU_REF:.3g} N·m, the largest load of {n.split('.')[0]} in the "
                                          f"data") for n, s in zip(t.names, peak)})
        return out


def with_covariates(robot: Robot, names: Sequence[str] | None) -> Robot:
    """Make a robot read covariate columns (a temperature) after its joints.

    The covariates are not yet fitted (any value is accepted) and no term reads them yet: the error model
    ``thermal:<name>`` (:func:`extend`) adds one.

    Parameters
    ----------
    robot : Robot
        The robot.
    names : sequence of str or None
        The covariate columns, in order; None or empty for none.

    Returns
    -------
    Robot
        An ExtendedRobot whose inputs are ``robot``'s joints, then the covariates; ``robot`` itself for no
        names, or when it reads exactly these covariates already (a calibrated robot file).

    Raises
    ------
    ValueError
        When ``robot`` reads other covariates, or a name is given twice.
    ModelError
        When a name cannot be a column's.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models import with_covariates
    >>> robot = kincal.load_robot("ur5")
    >>> warm = with_covariates(robot, ["temperature"])
    >>> warm.joint_names, warm.covariate_names, warm.error_model
    (('j1', 'j2', 'j3', 'j4', 'j5', 'j6', 'temperature'), ('temperature',), 'geometric')
    >>> with_covariates(robot, None) is robot, with_covariates(warm, ["temperature"]) is warm
    (True, True)
    """
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


def without_unread_covariates(robot: Robot) -> Robot:
    """``robot`` without the covariates no term of it reads: they are no input of its predictions.

    A calibration given covariate columns keeps them with its model even when the model it chose has no term
    that reads them (``geometric``, or ``auto`` choosing no thermal term); such a model predicts the same for
    any value of them, so data and targets need not carry them.

    Parameters
    ----------
    robot : Robot
        The robot.

    Returns
    -------
    Robot
        ``robot`` itself when every covariate it reads is read by a term (or it reads none); else the same
        model without the others: its geometry alone when it has no term left.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models import with_covariates, without_unread_covariates
    >>> robot = kincal.load_robot("ur5")
    >>> warm = with_covariates(robot, ["temperature"])
    >>> without_unread_covariates(warm).joint_names
    ('j1', 'j2', 'j3', 'j4', 'j5', 'j6')
    >>> thermal = kincal.extend(warm, "thermal:temperature")
    >>> without_unread_covariates(thermal) is thermal
    True
    """
    if not isinstance(robot, ExtendedRobot):
        return robot
    read = {t.covariate.name for t in robot.terms if isinstance(t, ThermalTerm)}
    keep = tuple(c for c in robot.covariates if c.name in read)
    if len(keep) == len(robot.covariates):
        return robot
    if not robot.terms:
        return robot.inner
    at = {c.name: robot.inner.n_joints + k for k, c in enumerate(keep)}  # a kept covariate's new input column
    terms = tuple(dataclasses.replace(t, index=at[t.covariate.name]) if isinstance(t, ThermalTerm) else t
                  for t in robot.terms)
    return dataclasses.replace(robot, terms=terms, covariates=keep)


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
    """Split and check an error-model name such as "compliance+harmonics:2".

    A name is "geometric", or one or more of nobeta, compliance or gravity-regressor (not both),
    harmonics:1 to harmonics:4 and thermal:<covariate column>, joined by '+', each family at most once.
    ("auto" is not a model name here: :class:`ErrorModel` takes it.)

    Parameters
    ----------
    name : str
        The error-model name.

    Returns
    -------
    tuple of str
        Its tokens, in the order given.

    Raises
    ------
    ValueError
        When the name is not valid; the message names the choices.

    Examples
    --------
    >>> from kincal.models import parse_model
    >>> parse_model("compliance+harmonics:2")
    ('compliance', 'harmonics:2')
    >>> parse_model("nobeta+thermal:temperature")
    ('nobeta', 'thermal:temperature')
    >>> parse_model("harmonics:5")
    Traceback (most recent call last):
    ...
    ValueError: error model 'harmonics:5': use geometric, or one or more of nobeta, ...
    """
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
    """What to model beyond the geometry: an error-model name and the payload, validated when built.

    Parameters
    ----------
    name : str, optional
        "geometric" (default), terms joined by '+' such as "compliance+harmonics:2" (see :func:`parse_model`),
        or "auto" (chosen by joint-space blocked cross-validation in :func:`kincal.calibrate`).
    payload : float, optional
        Mass at the tool point, kg (default 0), at most ``MAX_PAYLOAD``; it loads the gravity terms
        (compliance, gravity-regressor), so only a model with one of them (or "auto") takes a payload.

    Raises
    ------
    ValueError
        When the name is not valid, or the payload is negative, not finite, heavier than any robot carries, or
        given to a model without gravity terms.

    Examples
    --------
    >>> from kincal.models import ErrorModel
    >>> ErrorModel("compliance", payload=2.0)
    ErrorModel(name='compliance', payload=2.0)
    >>> ErrorModel.of("compliance+harmonics:2").to_dict()
    {'name': 'compliance+harmonics:2', 'payload': 0.0}
    >>> ErrorModel("harmonics:2", payload=3.0)
    Traceback (most recent call last):
    ...
    ValueError: payload=3 kg: only the gravity terms (compliance, gravity-regressor) use it, ...
    """

    name: str = "geometric"
    payload: float = 0.0

    def __post_init__(self) -> None:
        tokens = parse_model(self.name) if self.name != "auto" else ()
        object.__setattr__(self, "payload", number("payload", self.payload, positive=False, unit="kg at the tool"))
        if self.payload > MAX_PAYLOAD:
            raise ValueError(f"payload={self.payload:g} kg: more than any robot carries ({MAX_PAYLOAD:g} kg); give the "
                             f"payload at the tool in kg")
        if self.payload > 0 and self.name != "auto" and not GRAVITY_TERMS & set(tokens):
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

    def named(self, name: str) -> "ErrorModel":
        """The error model ``name`` with this one's payload when its terms use it, else none: ``auto``'s
        candidates and its choice.

        >>> from kincal.models import ErrorModel
        >>> auto = ErrorModel("auto", payload=0.5)
        >>> auto.named("compliance+harmonics:1").payload, auto.named("geometric").payload
        (0.5, 0.0)
        """
        return ErrorModel(name, self.payload if GRAVITY_TERMS & set(parse_model(name)) else 0.0)

    def to_dict(self) -> dict:
        return {"name": self.name, "payload": self.payload}


def extend(robot: Robot, error_model: ErrorModel | str, q: np.ndarray | None = None) -> Robot:
    """Add an error model's terms to a robot, all terms starting at 0.

    Terms go on the revolute joints whose rotation moves the tool point by at least ``MIN_LEVER`` per rad at
    the poses q. Gravity terms load the robot's link masses and the payload at the tool point, with ``robot``'s
    geometry as reference; the covariates ``robot`` reads are fitted on q (median and range:
    :class:`~kincal.models.covariates.Covariate`), and a thermal term grows the links of that geometry with one
    of them. "nobeta" drops the β tilts; "compliance" on a model with its own load compliance (a hexapod's legs)
    is that model's, not a term.

    Parameters
    ----------
    robot : Robot
        The robot; if it carries terms already, they are replaced: its geometry (``inner``) gets the new ones.
    error_model : ErrorModel or str
        The error model, or its name (see :class:`ErrorModel`); not "auto".
    q : ndarray, shape (N, n), optional
        Poses that judge the lever arms and gravity loads and fit the covariates (default: 200 random poses,
        seed 0; the covariates then keep the ranges they have).

    Returns
    -------
    Robot
        An ExtendedRobot, or the geometry alone when the model adds no term and ``robot`` reads no covariate
        ("geometric", "nobeta").

    Raises
    ------
    ValueError
        When the error model is "auto" or its name is not valid.
    ModelError
        When no revolute joint moves the tool enough for joint-angle terms, compliance finds no link mass and
        no payload, no joint carries a gravity load, or a thermal term names a covariate the robot does not read.

    Examples
    --------
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> extended = kincal.extend(robot, "harmonics:1")
    >>> extended.error_model, extended.n_params - robot.n_params
    ('harmonics:1', 10)
    >>> kincal.extend(robot, kincal.ErrorModel("compliance", payload=2.0)).term_names
    ('j2.compliance', 'j3.compliance', 'j4.compliance', 'j5.compliance')
    >>> kincal.extend(robot, "geometric") is robot
    True
    """
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
        check_payload(robot, spec.payload, q)
    if "nobeta" in tokens:
        inner = inner.without_beta()
    if "compliance" in tokens and inner.has_load_compliance:  # the model's own (a hexapod's legs), not a term
        inner, tokens = inner.with_load_compliance(), tuple(t for t in tokens if t != "compliance")
    terms = [thermal_term(inner, tok[len(THERMAL):], covs) if tok.startswith(THERMAL) else
             _term(inner, tok, q[:, :n], spec.payload) for tok in tokens if tok not in ("geometric", "nobeta")]
    return ExtendedRobot.build(inner, terms, covariates=covs) if terms or covs else inner


def check_payload(robot: Robot, payload: float, q: np.ndarray) -> None:
    """Refuse a payload no joint of ``robot`` could hold at the poses ``q``: a payload in grams given as kg.

    The gravity load of the link masses and ``payload`` at the tool point, at every pose, is compared with each
    joint's effort limit from the robot file; a joint loaded beyond ``PAYLOAD_MARGIN`` (2) times its limit, where
    the links alone stay within that, is refused. A robot without effort limits or link masses is not judged.

    Parameters
    ----------
    robot : Robot
        The robot (its geometry, when it carries error terms).
    payload : float
        Mass at the tool point, kg.
    q : ndarray, shape (N, n)
        The data's poses, rad (m for a prismatic joint); covariates after the joints are ignored.

    Raises
    ------
    ValueError
        Naming each such joint, its largest load and its effort limit, the worst first, and the unit of the
        payload.

    Examples
    --------
    >>> import kincal
    >>> from kincal.models.terms import check_payload
    >>> ur5 = kincal.load_robot("ur5")  # j2's effort limit: 150 N·m
    >>> q = ur5.sample_joints(50, seed=0)
    >>> check_payload(ur5, 5.0, q)  # its rated payload: nothing to say
    >>> check_payload(ur5, 500.0, q)
    Traceback (most recent call last):
    ...
    ValueError: payload=500 kg: at the data's poses its gravity load exceeds the effort limits of the robot file: ...
    """
    geometry = robot.inner if isinstance(robot, ExtendedRobot) else robot
    if payload <= 0.0 or not geometry.has_gravity:
        return
    loaded = geometry.gravity(payload)
    limits = np.array([np.nan if not vars(j).get("effort") else float(vars(j)["effort"]) for j in loaded.robot.moving])
    if np.all(np.isnan(limits)):
        return
    qj = q[:, :geometry.n_joints]
    tau = np.abs(loaded.torques(qj)).max(axis=0)
    links = np.abs(geometry.gravity(0.0).torques(qj)).max(axis=0)
    with np.errstate(invalid="ignore"):
        over = np.flatnonzero((tau > PAYLOAD_MARGIN * limits) & (links <= PAYLOAD_MARGIN * limits))
    if over.size:
        units = ["N·m" if t == "revolute" else "N" for t in geometry.joint_types]
        each = [f"{geometry.joint_names[k]} up to {tau[k]:.0f} {units[k]} against {limits[k]:g} {units[k]} "
                f"({tau[k] / limits[k]:.0f}x; the links alone {links[k]:.0f} {units[k]})"
                for k in over[order_with_ties(tau[over] / limits[over])]]
        raise ValueError(f"payload={payload:g} kg: at the data's poses its gravity load exceeds the effort limits of "
                         f"the robot file: {', '.join(each)}; the payload is in kg: was it given in grams "
                         f"({payload:g} g is {payload / 1000:g} kg)?")


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
