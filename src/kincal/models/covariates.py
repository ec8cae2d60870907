"""Covariates — per-sample inputs that are not joints (a temperature, the time since power-on) — and
the thermal term they drive.

How a covariate travels: as one more input column after the joints (type "covariate" in the robot's
:class:`~kincal.models.joint_space.JointSpace`, on an :class:`~kincal.models.terms.ExtendedRobot`).
So measurements, subsets, sessions, cross-validation folds, evaluation and the calibrated file carry it
with the joint values, with no plumbing of their own; a prediction needs it like it needs the joints
(a file without the column is refused naming it). Its value is used as the file gives it (°C or K:
only differences enter the term, but keep one scale from calibration to use; a time in s or min: the
parameter is per that unit).

The range: a covariate fitted on data keeps the training data's median (``reference``) and range
[min, max]; its input limits are that range widened by ``RANGE_TOL`` of its width at each end (a few
tenths of a kelvin past the warmest calibration pose is interpolation in practice, 10 K is not). A
term that reads the covariate refuses a value beyond those limits (ModelError naming the covariate,
its range and the values): a linear thermal model is only known where it was fitted, so a prediction
outside is never extrapolated silently.

The thermal term ``thermal:<covariate>`` is the published linear model of thermal growth: every
length of link ``g`` (its parameters of kind "length", the base frame and the tool point excepted,
grouped by name prefix: ``j2.a`` and ``j2.d`` are link ``j2``'s) grows by α_g·(c − c_ref), so the
tool point moves by Δp = Σ_g α_g (c − c_ref) Σ_{k∈g} L_k ∂p/∂L_k. A chain's tool point is linear in its
lengths at fixed angles, so this first-order form is the growth itself. The basis is evaluated on the
``reference`` geometry (the nominal one, held fixed like a gravity term's: the basis is known, the
term linear in α, its Jacobian exact); the calibrated lengths differ from it by a thousandth, which
changes a 0.3 mm growth by 0.3 µm. Parameters ``<link>.<covariate>`` (kind "ratio": 1/K for a
temperature, steel 12e-6, aluminium 23e-6; 1/s for a time). A link shorter than ``MIN_LINK`` in all
gets none (its growth is below any tracker). The arm's orientation does not change with its
lengths, so poses' rotations are untouched.

What an input column means elsewhere: a fit never moves q, so calibration, cross-validation and
evaluation are exact; design samples the covariate inside its limits like a joint (a pose is then a
pose at a temperature). Inverse kinematics and compensation solve for joints and must hold the
covariate at the target's value: not done yet, so a model whose term reads a covariate is not for
``compensate`` (refused before any work); one no term reads is no input of the model
(:func:`~kincal.models.terms.without_unread_covariates`): ``compensate`` and ``evaluate`` leave it out.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import ModelError
from .robot import Robot

RANGE_TOL = 0.1  # share of the fitted range accepted beyond each end
MIN_LINK = 0.01  # m: a link whose lengths add up to less gets no thermal parameter
SLOPE_STEP = 1e-6  # rad or m: central differences of the basis for the joint Jacobian


@dataclass(frozen=True)
class Covariate:
    """One covariate input: ``name`` (its column), the training data's median ``reference`` and range
    [``lower``, ``upper``] (±inf before it is fitted on data), in the column's unit."""

    name: str
    reference: float = 0.0
    lower: float = -np.inf
    upper: float = np.inf

    def __post_init__(self) -> None:
        if not self.name or any(c in self.name for c in ".,+:") or self.name != self.name.strip():
            raise ModelError(f"covariate '{self.name}': a column name without '.', ',', '+' or ':'")
        if not (np.isfinite(self.reference) and self.lower <= self.upper):
            raise ModelError(f"covariate '{self.name}': a finite reference and lower <= upper")

    @classmethod
    def of_data(cls, name: str, values: np.ndarray) -> "Covariate":
        """The covariate fitted on ``values`` (N,): their median and range."""
        v = np.asarray(values, dtype=float)
        return cls(name, float(np.median(v)), float(v.min()), float(v.max()))

    @property
    def fitted(self) -> bool:
        return bool(np.isfinite(self.lower) and np.isfinite(self.upper))

    def limits(self) -> tuple[float, float]:
        """The accepted input range: the fitted range widened by RANGE_TOL of its width (±inf unfitted)."""
        if not self.fitted:
            return -np.inf, np.inf
        pad = RANGE_TOL * (self.upper - self.lower) + 1e-9 * max(1.0, abs(self.upper), abs(self.lower))
        return self.lower - pad, self.upper + pad

    def outside(self, values: np.ndarray) -> np.ndarray:
        """(N,) bool: values beyond :meth:`limits` (NaN counts as outside)."""
        lo, hi = self.limits()
        return ~((values >= lo) & (values <= hi))

    def describe(self) -> str:
        lo, hi = self.limits()
        return (f"'{self.name}' was fitted on [{self.lower:g}, {self.upper:g}] (reference {self.reference:g}; "
                f"accepted {lo:.4g} to {hi:.4g})")

    def to_dict(self) -> dict:
        return {"name": self.name, "reference": self.reference, "range": [self.lower, self.upper]}


def covariate_from_dict(data, where: str) -> Covariate:
    """A covariate saved by :meth:`Covariate.to_dict`."""
    rng = data.get("range") if isinstance(data, dict) else None
    ok = isinstance(data, dict) and set(data) == {"name", "reference", "range"} and isinstance(rng, list) \
        and len(rng) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                  for x in [data.get("reference"), *rng])
    if not ok or not isinstance(data, dict) or not isinstance(rng, list):
        raise ModelError(f"{where}: a covariate is {{name: <column>, reference: <median>, range: [<min>, <max>]}}")
    return Covariate(str(data["name"]), float(data["reference"]), float(rng[0]), float(rng[1]))


def link_groups(geometry: Robot) -> tuple[tuple[str, tuple[int, ...]], ...]:
    """(link, indices of its length parameters) for every link whose lengths add up to MIN_LINK or
    more, in parameter order; the base frame and the tool point are not links."""
    skip = set(geometry.base_params()) | {n for n in geometry.params.names if n.startswith("tool.")}
    groups: dict[str, list[int]] = {}
    for k, (name, kind) in enumerate(zip(geometry.params.names, geometry.params.kinds)):
        if kind == "length" and name not in skip and "." in name:
            groups.setdefault(name.split(".")[0], []).append(k)
    values = geometry.params.values
    return tuple((g, tuple(ix)) for g, ix in groups.items() if np.sum(np.abs(values[ix])) >= MIN_LINK)


@dataclass(frozen=True, eq=False)
class ThermalTerm:
    """``thermal:<covariate>``: link growth α_g (c − c_ref) on ``geometry`` (the reference, held fixed);
    ``index``: the covariate's column among the robot's inputs, ``covariate`` it with its reference."""

    acts_on: ClassVar[str] = "position"  # a term on the tool point (N, 3, m), not on the joint values
    kind: ClassVar[str] = "ratio"
    geometry: Robot
    covariate: Covariate
    index: int
    groups: tuple[tuple[str, tuple[int, ...]], ...]
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def token(self) -> str:
        return f"thermal:{self.covariate.name}"

    @property
    def reference(self) -> Robot:
        return self.geometry

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{g}.{self.covariate.name}" for g, _ in self.groups)

    def growth(self, q: np.ndarray) -> np.ndarray:
        """(N, 3, m): the tool point's move per unit growth rate of each link at a unit covariate step."""
        qj = q[:, :self.geometry.n_joints]
        last_q, last = self._cache.get("growth", (None, None))
        if last_q is None or last_q.shape != qj.shape or not np.array_equal(last_q, qj):
            J = self.geometry.param_jacobian(qj)
            values = self.geometry.params.values
            last = np.stack([J[:, :, list(ix)] @ values[list(ix)] for _, ix in self.groups], axis=2)
            last.setflags(write=False)
            self._cache["growth"] = (qj.copy(), last)
        return last

    def basis(self, q: np.ndarray) -> np.ndarray:
        """(N, 3, m): ∂p/∂α, m per (1/unit)."""
        return self.growth(q) * (q[:, self.index] - self.covariate.reference)[:, None, None]

    def slope(self, q: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(N, 3, n): ∂(basis·θ)/∂q over all inputs: the joints by central differences (step
        SLOPE_STEP), the covariate exactly."""
        out = np.zeros((len(q), 3, q.shape[1]))
        n = self.geometry.n_joints
        for k in range(n):
            step = np.zeros(q.shape[1])
            step[k] = SLOPE_STEP
            out[:, :, k] = (self.basis(q + step) - self.basis(q - step)) @ theta / (2 * SLOPE_STEP)
        out[:, :, self.index] = self.growth(q) @ theta
        return out

    def to_dict(self) -> dict:
        return {"type": "thermal", "covariate": self.covariate.name, "links": [g for g, _ in self.groups]}


def thermal_term(geometry: Robot, name: str, covariates: tuple[Covariate, ...]) -> ThermalTerm:
    """The thermal term of covariate ``name`` (one of ``covariates``, the robot's, fitted on data) on
    ``geometry``'s links."""
    found = [i for i, c in enumerate(covariates) if c.name == name]
    if not found:
        have = ", ".join(c.name for c in covariates) or "none"
        raise ModelError(f"error model 'thermal:{name}' needs the covariate column '{name}' with the data (CLI: "
                         f"--covariate-cols {name}); the robot reads covariates: {have}")
    cov = covariates[found[0]]
    if cov.fitted and cov.upper <= cov.lower:
        raise ModelError(f"covariate '{name}' is {cov.lower:g} in every sample: a thermal term needs it to vary")
    groups = link_groups(geometry)
    if not groups:
        raise ModelError(f"robot '{geometry.name}': no link has lengths of {MIN_LINK * 1e3:g} mm or more to grow")
    return ThermalTerm(geometry, cov, geometry.n_joints + found[0], groups)


def thermal_from_dict(geometry: Robot, covariates: tuple[Covariate, ...], data: dict, where: str) -> ThermalTerm:
    """A thermal term saved by :meth:`ThermalTerm.to_dict` (``geometry``: its reference)."""
    term = thermal_term(geometry, str(data.get("covariate")), covariates)
    known = dict(term.groups)
    links = data.get("links")
    if not isinstance(links, list) or not links or any(str(g) not in known for g in links):
        raise ModelError(f"{where}: thermal 'links' must list links of the robot with lengths ({', '.join(known)})")
    return ThermalTerm(geometry, term.covariate, term.index, tuple((str(g), known[str(g)]) for g in links))
