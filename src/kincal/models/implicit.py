"""Closed-loop robots defined by constraints f(p, q, s) = 0 (one per leg; the 3-PUU error-model verification
paper, eq. 1).

p is the end-effector position in the robot frame, q the joint inputs, s the structural parameters.
A subclass supplies the constraints and their derivatives (and, where it exists, a closed-form
inverse); everything else is generic and batched:

* ``forward(q)``: Newton's method on f(p) = 0 from the model's start point; configurations where it
  does not converge, or where ∂f/∂p is singular, raise a ModelError that names them;
* ``param_jacobian``: implicit-function theorem, dp = −(∂f/∂p)⁻¹ (∂f/∂s) ds (eq. 3, 9);
* ``joint_jacobian``: dp = −(∂f/∂p)⁻¹ (∂f/∂q) dq;
* a 6-parameter base frame places the robot frame in the measurement frame, as for serial robots,
  so tracker data can be registered: world = R_b p + t_b, R_b = Rz(rz) Ry(ry) Rx(rx);
* ``forward_batch`` / ``inverse_batch``: many parameter vectors at once (a particle swarm) in one
  batched pass, every configuration carrying its own parameter row. Subclasses therefore write the
  constraint methods so ``values`` may be (P,) or one row per configuration, (N, P).
"""
from __future__ import annotations

from abc import abstractmethod

import numpy as np

from ..errors import ModelError
from .robot import Robot
from .serial import BASE_NAMES
from .transforms import rot_zyx

NEWTON_TOL = 1e-13  # m², constraint residual
NEWTON_ITER = 50
SINGULAR_COND = 1e10


class ImplicitRobot(Robot):
    """Base class: subclasses are frozen dataclasses that set ``name``, ``description``,
    ``joint_space``, ``params`` (the first six being the base frame) and implement the constraint
    methods below (robot frame, SI units). A subclass with a closed-form inverse implements
    ``inverse_local`` and sets ``has_inverse = True``."""

    # ---- to implement -------------------------------------------------------------------------
    @abstractmethod
    def constraints(self, p: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """f (N, c) for positions p (N, 3) in the robot frame."""

    @abstractmethod
    def constraint_derivatives(self, p: np.ndarray, q: np.ndarray, values: np.ndarray):
        """(∂f/∂p (N,c,3), ∂f/∂q (N,c,n), ∂f/∂s (N,c,P)); ∂f/∂s may leave the base columns 0."""

    @abstractmethod
    def start_point(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """A starting position (N, 3) for Newton's method, in the desired assembly mode."""

    def assembly_mode(self, p: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Map converged solutions (N, 3) onto the model's nominal assembly mode; identity by default."""
        return p

    def inverse_local(self, p: np.ndarray, values: np.ndarray, strict: bool = True) -> np.ndarray:
        """Closed-form inverse kinematics in the robot frame, (N, n); optional (``has_inverse``).
        Unreachable positions raise a ModelError, or give NaN rows when not ``strict``. Batched
        callers pass p (S, N, 3) with values (S, 1, P) and get (S, N, n)."""
        raise self._no_inverse()

    # ---- base frame ---------------------------------------------------------------------------
    def base_params(self) -> tuple[str, ...]:
        return BASE_NAMES

    def preferred_params(self) -> tuple[str, ...]:
        return BASE_NAMES

    def _base(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Base frame of a parameter vector (P,), R (3, 3) and t (3,), or of parameter rows (M, P),
        R (M, 3, 3) and t (M, 3)."""
        b = values[..., self.params.indices(BASE_NAMES)]
        return np.moveaxis(rot_zyx(b[..., 5], b[..., 4], b[..., 3]), (0, 1), (-2, -1)), b[..., :3]

    def _batch(self, values: np.ndarray) -> np.ndarray:
        """``values`` as an (S, P) array; ModelError for another shape."""
        values = np.asarray(values, dtype=float)
        if values.ndim != 2 or values.shape[1] != self.n_params:
            raise ModelError(f"{self.name}: expected (S, {self.n_params}) parameter vectors, got {values.shape}")
        return values

    def forward_batch(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Positions (S, N, 3) for S parameter vectors (S, P) in one Newton solve; NaN where a
        configuration does not assemble."""
        q = self.check_q(q)
        values = self._batch(values)
        rows = np.repeat(values, q.shape[0], axis=0)  # one parameter row per configuration
        p_local, ok = self._solve_local(np.tile(q, (len(values), 1)), rows, strict=False)
        R, t = self._base(rows)
        p = np.einsum("mij,mj->mi", R, p_local) + t
        return np.where(ok[:, None], p, np.nan).reshape(len(values), q.shape[0], 3)

    def inverse_batch(self, p: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Joint values (S, N, n) that reach world positions p (N, 3) for S parameter vectors (S, P);
        NaN where a position is out of reach. The geometry is built once per vector and broadcast
        over the positions (``values`` reach ``inverse_local`` as (S, 1, P))."""
        p = np.atleast_2d(np.asarray(p, float))
        values = self._batch(values)
        R, t = self._base(values)
        p_local = np.einsum("sni,sij->snj", p[None] - t[:, None], R)
        return self.inverse_local(p_local, values[:, None, :], strict=False)

    def _base_jacobian(self, values: np.ndarray, p: np.ndarray) -> np.ndarray:
        """d world position / d base x y z rx ry rz (N, 3, 6) at world positions p (N, 3): unit steps,
        then turns about the world axes of rx, ry, rz through t (R = Rz Ry Rx: each turns about its
        axis as already moved by the rotations before it in the product)."""
        b = values[self.params.indices(BASE_NAMES)]
        axes = [rot_zyx(b[5], b[4], 0.0) @ [1.0, 0, 0], rot_zyx(b[5], 0.0, 0.0) @ [0, 1.0, 0], np.array([0, 0, 1.0])]
        J = np.zeros((len(p), 3, 6))
        J[:, :, :3] = np.eye(3)
        J[:, :, 3:] = np.stack([np.cross(axis, p - b[:3]) for axis in axes], axis=2)
        return J

    # ---- generic kinematics -------------------------------------------------------------------
    def _solve_local(self, q: np.ndarray, values: np.ndarray, strict: bool = True):
        """Newton on f(p) = 0; returns p (N,3) and a converged mask (raises if ``strict``)."""
        p = self.start_point(q, values)
        ok = np.zeros(q.shape[0], bool)
        for _ in range(NEWTON_ITER):
            f = self.constraints(p, q, values)
            ok = np.all(np.abs(f) < NEWTON_TOL, axis=1)
            if ok.all():
                break
            fp = self.constraint_derivatives(p, q, values)[0]
            with np.errstate(all="ignore"):
                try:
                    step = np.linalg.solve(fp, f[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    step = np.einsum("nij,nj->ni", np.linalg.pinv(fp), f)
            step = np.where(np.isfinite(step), step, 0.0)
            p = p - np.where(ok[:, None], 0.0, step)
        ok &= np.all(np.isfinite(p), axis=1)
        p = self.assembly_mode(p, q, values)
        if strict and not ok.all():
            bad = np.flatnonzero(~ok)
            raise ModelError(f"{self.name}: forward kinematics did not converge for {bad.size} configuration(s) "
                             f"(first at index {bad[0]}, q = {np.array2string(q[bad[0]], precision=6)}): outside "
                             f"the workspace or at a singularity; check the joint values and their units")
        return p, ok

    def _forward_and_jacobian(self, q, values, jacobian):
        p_local, _ = self._solve_local(q, values)
        R, t = self._base(values)
        p = p_local @ R.T + t
        if not jacobian:
            return p, None
        fp, _, fs = self.constraint_derivatives(p_local, q, values)
        J = -np.einsum("ij,njc,nck->nik", R, self._checked_inverse(fp, q), fs)  # IFT in the robot frame, then rotated
        J[:, :, self.params.indices(BASE_NAMES)] = self._base_jacobian(values, p)
        return p, J

    def _checked_inverse(self, fp: np.ndarray, q: np.ndarray) -> np.ndarray:
        cond = np.linalg.cond(fp)
        bad = ~(cond < SINGULAR_COND)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise ModelError(f"{self.name}: {int(bad.sum())} configuration(s) are singular (∂f/∂p has condition "
                             f"number {cond[k]:.3g} at index {k}, q = {np.array2string(q[k], precision=6)}); "
                             f"leave them out")
        return np.linalg.inv(fp)

    def _joint_jacobian(self, q, values):
        p_local, _ = self._solve_local(q, values)
        fp, fq, _ = self.constraint_derivatives(p_local, q, values)
        R, _ = self._base(values)
        return -np.einsum("ij,njc,nck->nik", R, self._checked_inverse(fp, q), fq)

    def inverse(self, p: np.ndarray, values: np.ndarray | None = None, strict: bool = True) -> np.ndarray:
        """Joint values (N, n) that place the end effector at world positions p (N, 3); unreachable
        positions raise a ModelError (or give NaN rows when not ``strict``)."""
        values = self.param_values(values)
        R, t = self._base(values)
        return self.inverse_local((np.atleast_2d(np.asarray(p, float)) - t) @ R, values, strict)

    def in_working_mode(self, p: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(N,) bool: the solution is in the working mode the closed-form inverse returns."""
        return np.ones(p.shape[0], bool)

    def inverse_and_jacobian(self, p: np.ndarray, values: np.ndarray | None = None):
        """Joint values (N, n) for world positions p (N, 3) and their derivatives with respect to the
        parameters at fixed p, (N, n, P): dq = −(∂f/∂q)⁻¹ (∂f/∂p · ∂p_local/∂s + ∂f/∂s) ds."""
        values = self.param_values(values)
        p = np.atleast_2d(np.asarray(p, float))
        R, t = self._base(values)
        p_local = (p - t) @ R
        q = self.inverse_local(p_local, values)
        fp, fq, fs = self.constraint_derivatives(p_local, q, values)
        dpl = np.zeros((p.shape[0], 3, self.n_params))  # ∂p_local/∂(base parameters)
        dpl[:, :, self.params.indices(BASE_NAMES)] = -R.T @ self._base_jacobian(values, p)
        rhs = fs + np.einsum("nci,nik->nck", fp, dpl)
        return q, -np.linalg.solve(fq, rhs)

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """Within the limits, assembles, and in the nominal working mode."""
        q = self.check_q(q)
        p, ok = self._solve_local(q, self.params.values, strict=False)
        return self.within_limits(q) & ok & self.in_working_mode(p, q, self.params.values)
