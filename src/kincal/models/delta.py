"""The Clavel delta robot: three revolute arms on a base, each joined to a translating platform by a
parallelogram forearm; the platform's position is the unknown of its forward kinematics.

Arm i (1..3) sits at azimuth φᵢ = (i − 1)·120° + ``arm<i>.phi`` with the radial unit vector eᵢ and the
vertical z. Its motor turns the upper arm (length ``arm<i>.L``) about the tangent through the base point
Rᵢ·eᵢ (``arm<i>.R``) by αᵢ = qᵢ + ``arm<i>.zero`` (α = 0: horizontal and outward, positive downwards): the
elbow is Eᵢ = Rᵢeᵢ + Lᵢ(cos αᵢ eᵢ − sin αᵢ z). The forearm parallelogram (length ``arm<i>.l``) keeps the
platform level and joins the elbow to the platform point p + rᵢeᵢ (``arm<i>.r``), so the constraint of arm i
is fᵢ = ‖p + rᵢeᵢ − Eᵢ‖² − lᵢ² = 0. The platform hangs below the three elbows (the working mode; the other
solution is its mirror image above them). Inverse kinematics is closed form (the elbow out).

Parameters: the base frame, then per arm ``R r L l zero phi`` (m, m, m, m, rad, rad).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import ModelError
from .implicit import ImplicitRobot
from .parameters import Parameters
from .joint_space import JointSpace
from .serial import BASE_NAMES

ARM_NAMES = ("R", "r", "L", "l", "zero", "phi")
ARM_KINDS = ("length",) * 4 + ("angle",) * 2
AZIMUTH = np.deg2rad([0.0, 120.0, 240.0])


def delta_names() -> tuple[list[str], list[str]]:
    """The parameter names and kinds of a delta robot."""
    names, kinds = list(BASE_NAMES), ["length"] * 3 + ["angle"] * 3
    for i in range(1, 4):
        names += [f"arm{i}.{p}" for p in ARM_NAMES]
        kinds += ARM_KINDS
    return names, kinds


@dataclass(frozen=True, eq=False, repr=False)
class DeltaRobot(ImplicitRobot):
    """A Clavel delta robot; joints are the three motor angles (rad)."""

    name: str
    params: Parameters
    q_lower: float
    q_upper: float
    description: str = ""
    joint_space: JointSpace = field(init=False, repr=False)
    has_inverse: ClassVar[bool] = True

    def __post_init__(self) -> None:
        names, kinds = delta_names()
        if self.params.names != tuple(names) or self.params.kinds != tuple(kinds):
            raise ModelError(f"{self.name}: parameters do not match the delta layout ({', '.join(names[6:12])}, …)")
        if not self.q_lower < self.q_upper:
            raise ModelError(f"{self.name}: arm limits must have lower < upper")
        object.__setattr__(self, "joint_space", JointSpace(("arm1", "arm2", "arm3"), ("revolute",) * 3,
                                                           [self.q_lower] * 3, [self.q_upper] * 3))

    @classmethod
    def build(cls, name: str = "delta", R: float = 0.2, r: float = 0.05, L: float = 0.35, l: float = 0.8,
              q_range: tuple[float, float] = (-0.6, 1.4), values: dict | None = None,
              description: str = "") -> "DeltaRobot":
        """A delta robot from its design (m, rad); ``values``: parameters by name (SI)."""
        names, kinds = delta_names()
        v = dict.fromkeys(names, 0.0)
        for i in range(1, 4):
            v.update({f"arm{i}.R": R, f"arm{i}.r": r, f"arm{i}.L": L, f"arm{i}.l": l})
        unknown = set(values or {}) - set(names)
        if unknown:
            raise ModelError(f"{name}: unknown parameter(s) {sorted(unknown)}; known: {', '.join(names)}")
        v.update(values or {})
        return cls(name, Parameters(names, [v[n] for n in names], kinds), q_range[0], q_range[1], description)

    @property
    def structure(self) -> str:
        return "delta (implicit)"

    # ---- geometry ---------------------------------------------------------------------------------
    def _arms(self, values: np.ndarray):
        """Per arm (…, 3): R, r, L, l, zero and the radial and tangential unit vectors (…, 3, 3)."""
        v = np.asarray(values, dtype=float)
        arm = v[..., 6:24].reshape(v.shape[:-1] + (3, 6))
        R, r, L, l, zero, phi = np.moveaxis(arm, -1, 0)
        a = AZIMUTH + phi
        zeros = np.zeros_like(a)
        e = np.stack([np.cos(a), np.sin(a), zeros], axis=-1)
        t = np.stack([-np.sin(a), np.cos(a), zeros], axis=-1)
        return R, r, L, l, zero, e, t

    def _d(self, p, q, values):
        """Forearm vectors d = p + r e − E (N, 3, 3), and the pieces of their derivatives."""
        R, r, L, l, zero, e, t = self._arms(values)
        alpha = q + zero
        c, s = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
        z = np.array([0.0, 0.0, 1.0])
        arm = c * e - s * z  # the upper arm's direction
        d = p[:, None, :] + (r - R)[..., None] * e - L[..., None] * arm
        return d, (R, r, L, l, e, t, c, s, arm, z)

    def constraints(self, x, q, values):
        d, (_, _, _, l, *_) = self._d(x, q, values)
        return np.einsum("nij,nij->ni", d, d) - l**2

    def constraint_derivatives(self, x, q, values):
        d, (R, r, L, l, e, t, c, s, arm, z) = self._d(x, q, values)
        n = x.shape[0]
        dot = lambda w: np.sum(d * w, axis=-1)  # noqa: E731  (N, 3)
        turn = L * dot(s * e + c * z)  # d f / d α, halved
        fq = np.zeros((n, 3, 3))
        arms = np.arange(3)
        fq[:, arms, arms] = 2.0 * turn
        fs = np.zeros((n, 3, self.n_params))
        cols = 6 + 6 * arms[:, None] + np.arange(6)
        de = dot(e)
        for k, value in enumerate((-de, de, -dot(arm), -np.broadcast_to(l, de.shape), turn,
                                   dot(t) * (r - R - L * c[..., 0]))):
            fs[:, arms, cols[:, k]] = 2.0 * value
        return 2.0 * d, fq, fs

    def _centres(self, q, values) -> tuple[np.ndarray, np.ndarray]:
        """The spheres the platform's centre lies on: centres Eᵢ − rᵢeᵢ (N, 3, 3) and radii lᵢ (…, 3)."""
        R, r, L, l, zero, e, _ = self._arms(values)
        alpha = (q + zero)[..., None]
        return (R - r)[..., None] * e + L[..., None] * (np.cos(alpha) * e - np.sin(alpha) * [0.0, 0.0, 1.0]), l

    def start_point(self, q, values):
        """On the axis, below the three elbows by the forearms' mean reach."""
        centre, l = self._centres(q, values)
        rho = np.linalg.norm(centre[..., :2], axis=-1)
        z = centre[..., 2].mean(axis=1) - np.sqrt(np.maximum(np.mean(l**2 - rho**2, axis=-1), 1e-12))
        return np.column_stack([np.zeros_like(z), np.zeros_like(z), z])

    def assembly_mode(self, x, q, values):
        """The platform hangs below the three sphere centres Eᵢ − rᵢeᵢ; a solution above them is reflected."""
        c = self._centres(q, values)[0]
        nrm = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm *= np.sign(nrm[:, 2:3])
        h = np.einsum("ni,ni->n", x - c[:, 0], nrm)
        return x - 2.0 * np.maximum(h, 0.0)[:, None] * nrm

    def inverse_local(self, p, values, strict=True):
        """Motor angles for platform positions p (N, 3): each arm's elbow out of the two that reach."""
        R, r, L, l, zero, e, t = self._arms(values)
        w = np.asarray(p, float)[..., None, :] + (r - R)[..., None] * e  # (…, N, 3, 3): elbow to reach
        a, b, c = np.sum(w * e, axis=-1), np.sum(w * t, axis=-1), w[..., 2]
        K = (a**2 + b**2 + c**2 + L**2 - l**2) / (2.0 * L)
        rho = np.hypot(a, c)
        with np.errstate(invalid="ignore", divide="ignore"):
            alpha = -np.arccos(K / rho) - np.arctan2(c, a)
        bad = ~np.isfinite(alpha)
        if strict and bad.any():
            k = int(np.flatnonzero(np.any(bad, axis=-1))[0])
            raise ModelError(f"{self.name}: position {np.array2string(np.asarray(p)[k], precision=6)} m is out of "
                             f"reach of the arms (row {k}); check the targets and their units")
        return alpha - zero
