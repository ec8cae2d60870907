"""What a change of a calibrated robot looks like at given poses: the directions ``kincal compare``, ``kincal check``
and ``kincal design --check`` test and name, and the record of what a repeat calibration differs by (:class:`Repeat`,
computed by :mod:`kincal.identify.repeat`).

A change that happens to a robot is one of a few kinds, each a direction in the space of predicted positions at the
poses of use (3 rows per pose): a **joint zero** (a motor or encoder replaced, a crash: the joint's column of the joint
Jacobian, for any robot), a **link** (a length parameter: a bent or replaced part), a **joint axis** (an angle
parameter of the model other than a joint's zero), the **tool** point, and the **frame** (where the robot stands in the
instrument's frame: only when the instrument did not move, else it is re-fitted and no change of it can be seen).
Directions that coincide at the poses (a DH θ and the joint's zero; a joint 1 zero and the frame's turn) are one
candidate, named by the first in this order: joint zeros, then the model's parameters in their own order (the rule of
:mod:`kincal.ties`). ``STEPS`` are the sizes of change that matter, for a pose design: 0.01° and 0.1 mm.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .._frozen import freeze_arrays
from ..errors import ModelError
from ..models.robot import TOOL_NAMES, Robot

ALPHA = 0.05  # the default false-alarm probability of compare and check (and the threshold check poses aim at)
MIN_CHECK_POSES = 4  # a check's re-fitted frame takes 6 of its 3n rows
STEPS = {"joint zero": np.deg2rad(0.01), "link": 1e-4, "joint axis": np.deg2rad(0.01), "tool": 1e-4,
         "frame": 1e-4, "actuator": 1e-4}  # m, rad or ratio: changes a check should see (a frame's angles: 0.01°)
PARALLEL = 1e-5  # 1 − |cos| below which two directions are one candidate (within 4.5 mrad)
NEGLIGIBLE = 1e-9  # m per unit change (RMS over the rows) below which a direction is not seen at all
SAMPLES = 300  # calibration samples a Repeat keeps to predict the miss from (a check's cost is cubic in them)


@dataclass(frozen=True, eq=False)
class Repeat:
    """names      -- the robot and set-up parameters of the fit (the columns of ``covariance``)
    covariance -- (K, K) repeat (sandwich) covariance (m, rad)
    dof        -- samples − K: the degrees of freedom the covariance was estimated with
    sigma      -- m per axis a prediction at a new pose of the region misses by, beside the joints' part (None: the
                  data had no absolute positions)
    joints     -- σ per joint (rad or m): the miss that acts like joint errors (transmission, harmonics), so it grows
                  with the lever arm, as the changes a check looks for do
    dispersion -- ≥ 1, the whitened squared position misses' variance over a Gaussian's (1: Gaussian)
    length     -- rad: how far a revolute joint turns before its part of the miss is another (0: at every pose; a
                  transmission error is a smooth function of the joint's angle, so poses at near angles share it)
    poses      -- (S, n) joints of up to ``SAMPLES`` of the calibration's position samples (evenly by row) ...
    residuals  -- (S, 3) m: ... and what the calibrated model missed them by, in the robot's base frame (measured −
                  predicted): the miss at a new pose is predicted from them (:meth:`conditioned`)
    scale      -- ≥ 1, how much larger the kept samples' leave-one-out misses are than the conditioned covariance
                  says (:func:`loo_scale`): the covariance :meth:`conditioned` gives is multiplied by it"""

    names: tuple[str, ...]
    covariance: np.ndarray
    dof: int
    sigma: float | None
    joints: tuple[float, ...]
    dispersion: float
    length: float = 0.0
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    residuals: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    scale: float = 1.0

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def restricted(self, names) -> "Repeat":
        """The same record over the parameters ``names`` (a subset of :attr:`names`)."""
        at = [self.names.index(n) for n in names]
        return replace(self, names=tuple(names), covariance=self.covariance[np.ix_(at, at)])

    def miss(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """(M, M) the covariance per axis (m²) of what predictions at the poses q (M, n) miss by, the same for x, y
        and z (:func:`miss_covariance`); ModelError without a miss (no absolute positions in the calibration's data)."""
        return self._prior(robot, q)

    def _prior(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        if self.sigma is None or len(self.joints) != robot.n_joints:
            raise ModelError("the calibration left no miss of positions to judge measured positions against: its data "
                             "had no absolute positions, or it was fitted in joint space (--residual joint); for a "
                             "check, calibrate from positions or poses with their own residual (the default)")
        revolute = robot.revolute
        return miss_covariance(robot.joint_jacobian(q)[:, :3, :], q, revolute, self.sigma, self.joints, self.length)

    def conditioned(self, robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What predictions at the poses q (M, n) will miss by, given what the calibration missed its own samples by.

        The miss is a Gaussian field over the joints (:func:`miss_covariance`); the calibration's samples
        (:attr:`poses`, :attr:`residuals`) show it where they were taken, and a transmission error shared by poses at
        near joint angles is then predicted, not only allowed for (Gaussian-process regression, Rasmussen and
        Williams 2006, eq. 2.19). Without samples: a zero mean and :meth:`miss`.

        Parameters
        ----------
        robot : Robot
            The calibrated robot (its joint Jacobian gives the joints' lever arms).
        q : ndarray, shape (M, n)
            Joint values, rad (m for a prismatic joint).

        Returns
        -------
        mean : ndarray, shape (M, 3)
            The expected miss (measured − predicted) in the robot's base frame, m.
        covariance : ndarray, shape (M, M)
            Its covariance per axis around that mean, the same for x, y and z, m².

        Raises
        ------
        ModelError
            When the calibration's data had no absolute positions.
        """
        S = len(self.poses)
        if S == 0:
            return np.zeros((len(q), 3)), self._prior(robot, q)
        A = self._prior(robot, np.concatenate([self.poses, q]))
        L = np.linalg.cholesky(A[:S, :S])
        W = np.linalg.solve(L, A[:S, S:])
        mean = W.T @ np.linalg.solve(L, self.residuals)
        cov = (A[S:, S:] - W.T @ W) * self.scale
        return mean, 0.5 * (cov + cov.T)

    def to_dict(self) -> dict:
        return {"parameters": list(self.names), "covariance": self.covariance.tolist(), "dof": self.dof,
                "sigma": self.sigma, "joints": list(self.joints), "dispersion": self.dispersion, "length": self.length,
                "poses": self.poses.tolist(), "residuals": self.residuals.tolist(), "scale": self.scale}

    @classmethod
    def from_dict(cls, data, label: str) -> "Repeat":
        """The record of a calibrated file's ``calibration: repeat:`` section; ModelError naming ``label`` when it is
        missing (a file calibrated before kincal kept it) or malformed."""
        if not isinstance(data, dict):
            raise ModelError(f"{label}: the calibration keeps no repeat covariance (calibrated by an older kincal); "
                             f"calibrate again to compare or check it")
        try:
            names = tuple(str(n) for n in data["parameters"])
            cov = np.array(data["covariance"], dtype=float).reshape(len(names), len(names))
            sigma = None if data.get("sigma") is None else float(data["sigma"])
            joints = tuple(float(v) for v in data["joints"])
            poses = np.array(data.get("poses", []), dtype=float).reshape(-1, max(len(joints), 1))[:, :len(joints)]
            residuals = np.array(data.get("residuals", []), dtype=float).reshape(len(poses), 3)
            out = cls(names, cov, int(data["dof"]), sigma, joints, float(data["dispersion"]), float(data["length"]),
                      poses, residuals, float(data.get("scale", 1.0)))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"{label}: the calibration's 'repeat' section is malformed ({exc}); calibrate again") \
                from None
        if not (np.all(np.isfinite(cov)) and np.all(np.isfinite(out.poses)) and np.all(np.isfinite(out.residuals))
                and out.dof > 0
                and out.dispersion >= 1.0 and out.scale >= 1.0):
            raise ModelError(f"{label}: the calibration's 'repeat' section is malformed; calibrate again")
        return out


def miss_covariance(Jq: np.ndarray, q: np.ndarray, revolute: np.ndarray, sigma: float, joints, length: float):
    """(M, M) per-axis covariance (m²) of the miss at poses q (M, n) with joint Jacobian Jq (M, 3, n): σ² δ_ik plus,
    per joint j, σ_j² k_j(q_ij − q_kj) (∂p/∂q_j at i · ∂p/∂q_j at k) / 3, k_j = exp(−2 sin²(Δ/2) / length²) for a
    revolute joint (periodic, smooth; length 0: δ), δ for a prismatic one. Positive semi-definite: each term is a
    product of a kernel and a Gram matrix."""
    return miss_from_parts(miss_parts(Jq, q, revolute, joints), sigma, length, len(q))


def loo_scale(A: np.ndarray, residuals: np.ndarray) -> float:
    """≥ 1: the mean squared standardised leave-one-out miss of samples whose misses ``residuals`` (S, 3) have the
    per-axis covariance A (S, S), each predicted from the others by the Gaussian conditional (closed form:
    residual (A⁻¹ r)ᵢ / (A⁻¹)ᵢᵢ with variance 1 / (A⁻¹)ᵢᵢ; Rasmussen and Williams 2006, eq. 5.12). Above 1 when
    the field's σ or correlation length, estimated from the same samples, make the conditional too sure of itself.
    """
    if len(residuals) < 2:
        return 1.0
    inv = np.linalg.inv(A)
    d = np.diag(inv)
    z2 = np.sum((inv @ residuals) ** 2, axis=1) / d  # per sample: Σ over the axes of (miss / σ)², 3 on average
    return max(1.0, float(np.mean(z2)) / 3.0)


def miss_parts(Jq: np.ndarray, q: np.ndarray, revolute: np.ndarray,
               joints) -> list[tuple[np.ndarray | None, np.ndarray]]:
    """Per joint with a σ: (sin²(Δq/2) (M, M), or None for a kernel δ; σ_j² · Gram / 3 (M, M)), what
    :func:`miss_covariance` builds for any length (computed once when several lengths are tried)."""
    out = []
    for j, s in enumerate(joints):
        if s > 0:
            half = np.sin((q[:, j, None] - q[None, :, j]) / 2.0) ** 2 if revolute[j] else None
            out.append((half, s**2 * (Jq[:, :, j] @ Jq[:, :, j].T) / 3.0))
    return out


def miss_from_parts(parts, sigma: float, length: float, M: int) -> np.ndarray:
    """:func:`miss_covariance` of M poses from its :func:`miss_parts`."""
    A = sigma**2 * np.eye(M)
    for half, gram in parts:
        A += (np.exp(-2.0 * half / length**2) if length > 0 and half is not None else np.eye(M)) * gram
    return A


@dataclass(frozen=True, eq=False)
class Candidates:
    """names -- one per candidate change ("j2 zero", "j3.a", "tool.z", "base.rx")
    kinds -- "joint zero", "link", "joint axis", "actuator" (a scale), "tool" or "frame" per candidate
    units -- "length", "angle" or "ratio" per candidate (what its size is in)
    G     -- (3M, C) the predicted positions' change per unit change of each (m per m or m per rad), pose-major
    also  -- per candidate, the names of the changes that act the same at these poses (merged into it), "−" before
             one that acts the same with the opposite sign"""

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    units: tuple[str, ...]
    G: np.ndarray
    also: tuple[tuple[str, ...], ...] = ()

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def steps(self) -> np.ndarray:
        """(C,) the size of change of each candidate that matters (``STEPS``; a frame angle 0.01°)."""
        return np.array([np.deg2rad(0.01) if k == "frame" and u == "angle" else STEPS[k]
                         for k, u in zip(self.kinds, self.units)])


def candidates(robot: Robot, q: np.ndarray, basis: np.ndarray | None) -> Candidates:
    """The candidate changes of ``robot`` at the poses q (M, n): joint zeros, the tool point, then the model's other
    parameters; the base frame's too when ``basis`` is None (the instrument did not move), else every direction with
    its part along the re-fitted frame's ``basis`` (:func:`frame_basis`) removed, so what a frame absorbs is not seen.
    Directions that coincide (after that) are merged into the first."""
    q = robot.check_q(q)
    base, kinds = set(robot.base_params()), dict(zip(robot.params.names, robot.params.kinds))
    params = sorted(robot.params.names, key=lambda n: _kind(n, kinds[n], base) != "tool")  # stable: tool first
    names = [f"{j} zero" for j in robot.joint_names] + params
    units = ["angle" if t == "revolute" else "length" for t in robot.joint_types] + [kinds[n] for n in params]
    what = ["joint zero"] * robot.n_joints + [_kind(n, kinds[n], base) for n in params]
    G = np.concatenate([robot.joint_jacobian(q)[:, :3, :].reshape(3 * len(q), -1),
                        robot.param_jacobian(q)[..., robot.params.indices(params)].reshape(3 * len(q), -1)], axis=1)
    keep = [k for k, w in enumerate(what) if w != "frame" or basis is None]
    G = G[:, keep] if basis is None else without(basis, G[:, keep])
    kept, merged = _distinct(G)
    return Candidates(tuple(names[keep[k]] for k in kept), tuple(what[keep[k]] for k in kept),
                      tuple(units[keep[k]] for k in kept), G[:, kept],
                      tuple(tuple(("" if sign > 0 else "−") + names[keep[j]] for j, sign in merged.get(k, ()))
                            for k in kept))


def _kind(name: str, unit: str, base: set) -> str:
    if name in base:
        return "frame"
    if name in TOOL_NAMES or name.startswith("tool."):
        return "tool"
    return {"length": "link", "ratio": "actuator"}.get(unit, "joint axis")  # a ratio: a leg's or a joint's scale


def _distinct(G: np.ndarray) -> tuple[list[int], dict[int, list[tuple[int, float]]]]:
    """The columns of G (in order) that move the positions at all and are not parallel to an earlier kept one, and
    for each kept column the later ones merged into it (the same change under other names) with the sign of their
    direction against it."""
    norms = np.sqrt(np.mean(G**2, axis=0))
    unit = G / np.where(norms > 0, norms, 1.0) / np.sqrt(G.shape[0])
    kept: list[int] = []
    merged: dict[int, list[tuple[int, float]]] = {}
    for k in range(G.shape[1]):
        if norms[k] <= NEGLIGIBLE:
            continue
        same = [j for j in kept if abs(float(unit[:, k] @ unit[:, j])) >= 1 - PARALLEL]
        if same:
            merged.setdefault(same[0], []).append((k, float(np.sign(unit[:, k] @ unit[:, same[0]]))))
        else:
            kept.append(k)
    return kept, merged


def frame_basis(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(3M, r) orthonormal basis of what moving the instrument's frame does to the positions at q (M, n): the
    directions a re-fitted frame absorbs (r ≤ 6; empty when the model has no base frame)."""
    names = list(robot.base_params())
    if not names:
        return np.zeros((3 * len(q), 0))
    J = robot.param_jacobian(robot.check_q(q))[..., robot.params.indices(names)].reshape(-1, len(names))
    U, s, _ = np.linalg.svd(J, full_matrices=False)
    return U[:, s > s[0] * 1e-9] if s.size and s[0] > 0 else np.zeros((3 * len(q), 0))


def without(basis: np.ndarray, X: np.ndarray) -> np.ndarray:
    """X (3M, …) with its part along the orthonormal ``basis`` (3M, r) removed."""
    return X - basis @ (basis.T @ X)
