"""Closed-loop robots defined by constraints f(x, q, s) = 0 (the 3-PUU paper of 2024,
"Error analysis model of parallel robot based on parameters identification", eq. 1),
with the platform's position or its whole pose as the unknown x.

x is the platform's position (``UNKNOWN = "position"``, 3 coordinates) or its pose (``"pose"``: a rotation
R and a translation t, 6 coordinates: a small change is a twist (dt, δ) with R ← exp(δ×) R) in the
robot frame; q are the joint inputs, s the structural parameters. A subclass supplies the constraints
and their derivatives by the twist (and, where it exists, a closed-form inverse); everything else is
generic and batched:

* ``forward(q)``: Newton's method on f(x) = 0 from the model's start; configurations where it does not
  converge, or where ∂f/∂x is singular, raise a ModelError that names them;
* ``param_jacobian``: implicit-function theorem, dx = −(∂f/∂x)⁻¹ (∂f/∂s) ds (eq. 3, 9);
* ``joint_jacobian``: dx = −(∂f/∂x)⁻¹ (∂f/∂q) dq;
* the measured point is the platform position, or for a pose the tool point ``tool.x/y/z`` on the
  platform (m, in its frame), whose frame is the flange frame of a 6-D measurement;
* a 6-parameter base frame places the robot frame in the measurement frame, as for serial robots,
  so tracker data can be registered: world = R_b x + t_b, R_b = Rz(rz) Ry(ry) Rx(rx);
* ``forward_batch`` / ``inverse_batch``: many parameter vectors at once (a particle swarm) in one
  batched pass, every configuration carrying its own parameter row. Subclasses therefore write the
  constraint methods so ``values`` may be (P,) or one row per configuration, (N, P).
"""
from __future__ import annotations

from abc import abstractmethod
from typing import ClassVar

import numpy as np

from ..errors import ModelError
from .robot import TOOL_NAMES, Robot
from .serial import BASE_NAMES
from .transforms import rot_zyx, skew

NEWTON_TOL = 1e-13  # constraint residual (the constraints' own unit: m or m²)
NEWTON_ITER = 50
SINGULAR_COND = 1e10
UNKNOWNS = {"position": 3, "pose": 6}  # coordinates of each kind of unknown


def twist_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors w (N, 3) rad (Rodrigues, series near 0)."""
    th2 = np.einsum("ni,ni->n", w, w)[:, None, None]
    small = th2 < 1e-12
    th = np.sqrt(np.where(small, 1.0, th2))
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(th) / th)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(th)) / np.where(small, 1.0, th2))
    K = skew(w)
    return np.eye(3) + a * K + b * (K @ K)


class ImplicitRobot(Robot):
    """A closed-loop robot defined by constraints f(x, q, s) = 0: the base class of parallel robots.

    Forward kinematics solves the constraints for the platform's position (or pose) x by Newton's method; the
    Jacobians follow from the implicit-function theorem (see the module docstring). Subclasses are frozen
    dataclasses that set ``name``, ``description``, ``joint_space``, ``params`` (the first six being the base
    frame; with a pose as the unknown also ``tool.x/y/z``), ``UNKNOWN`` ("position" or "pose") and implement the
    constraint methods below (robot frame, SI units). A subclass with a closed-form inverse of its unknown
    implements ``inverse_local`` and sets ``has_inverse = True`` (a position) or ``has_pose_inverse = True``
    (a pose).

    Attributes
    ----------
    UNKNOWN : str
        "position" (3 coordinates, the default) or "pose" (6: a rotation and a translation).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.load_robot("puu3")
    >>> isinstance(robot, kincal.ImplicitRobot), robot.UNKNOWN, robot.has_inverse
    (True, 'position', True)
    >>> q = robot.sample_joints(4, seed=1)
    >>> p, J = robot.forward_and_jacobian(q)
    >>> p.shape, J.shape
    ((4, 3), (4, 3, 11))
    >>> bool(np.allclose(robot.inverse(p), q, atol=1e-9))
    True
    """

    UNKNOWN: ClassVar[str] = "position"

    # ---- to implement -------------------------------------------------------------------------
    @abstractmethod
    def constraints(self, x: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """f (N, c) for the unknown x: positions (N, 3), or poses (N, 3, 4) = [R | t], in the robot frame."""

    @abstractmethod
    def constraint_derivatives(self, x: np.ndarray, q: np.ndarray, values: np.ndarray):
        """(∂f/∂x (N, c, d), ∂f/∂q (N, c, n), ∂f/∂s (N, c, P)); ∂f/∂s may leave the base columns 0.
        For a pose, ∂f/∂x is by the twist (dt, δ): t ← t + dt, R ← exp(δ×) R."""

    def constraint_jacobian(self, x: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """∂f/∂x (N, c, d) alone, what Newton's method needs (models with a cheaper way override it)."""
        return self.constraint_derivatives(x, q, values)[0]

    @abstractmethod
    def start_point(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """A start for Newton's method (a position (N, 3) or a pose (N, 3, 4)), in the desired assembly mode."""

    def assembly_mode(self, x: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Map converged solutions onto the model's nominal assembly mode; identity by default."""
        return x

    def inverse_local(self, p: np.ndarray, values: np.ndarray, strict: bool = True) -> np.ndarray:
        """Closed-form inverse kinematics in the robot frame, (N, n); optional (``has_inverse``).
        Unreachable positions raise a ModelError, or give NaN rows when not ``strict``. Batched
        callers pass p (S, N, 3) with values (S, 1, P) and get (S, N, n)."""
        raise self._no_inverse()

    # ---- the unknown ----------------------------------------------------------------------------
    def _retract(self, x: np.ndarray, step: np.ndarray) -> np.ndarray:
        """x moved by ``step`` (N, d): a position by the step, a pose by the twist (dt, δ)."""
        if self.UNKNOWN == "position":
            return x + step
        return np.concatenate([twist_exp(step[:, 3:]) @ x[:, :, :3], (x[:, :, 3] + step[:, :3])[:, :, None]], axis=2)

    def _end(self, x: np.ndarray, values: np.ndarray):
        """The measured point (N, 3) in the robot frame, its derivatives by the unknown's coordinates
        (N, 3, d) and by the parameters (N, 3, P), and the platform's rotation (N, 3, 3; None for a position)."""
        n = x.shape[0]
        Es = np.zeros((n, 3, self.n_params))
        if self.UNKNOWN == "position":
            return x, np.broadcast_to(np.eye(3), (n, 3, 3)), Es, None
        R, tool = x[:, :, :3], np.asarray(values)[..., self.params.indices(TOOL_NAMES)]
        a = np.einsum("nij,nj->ni", R, np.broadcast_to(tool, (n, 3)))
        Es[:, :, self.params.indices(TOOL_NAMES)] = R
        return a + x[:, :, 3], np.concatenate([np.broadcast_to(np.eye(3), (n, 3, 3)), -skew(a)], axis=2), Es, R

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
        x, ok = self._solve_local(np.tile(q, (len(values), 1)), rows, strict=False)
        R, t = self._base(rows)
        p = np.einsum("mij,mj->mi", R, self._end(x, rows)[0]) + t
        return np.where(ok[:, None], p, np.nan).reshape(len(values), q.shape[0], 3)

    def inverse_batch(self, p: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Joint values (S, N, n) that reach world positions p (N, 3) for S parameter vectors (S, P);
        NaN where a position is out of reach. The geometry is built once per vector and broadcast
        over the positions (``values`` reach ``inverse_local`` as (S, 1, P))."""
        if not self.has_inverse:  # (a pose unknown: its joints need the whole pose, inverse_pose)
            raise self._no_inverse()
        p = np.atleast_2d(np.asarray(p, float))
        values = self._batch(values)
        R, t = self._base(values)
        p_local = np.einsum("sni,sij->snj", p[None] - t[:, None], R)
        return self.inverse_local(p_local, values[:, None, :], strict=False)

    def _base_axes(self, values: np.ndarray) -> np.ndarray:
        """The world axes (3, 3) the base rotations rx, ry, rz turn about, as columns."""
        b = values[self.params.indices(BASE_NAMES)]
        return np.column_stack([rot_zyx(b[5], b[4], 0.0) @ [1.0, 0, 0], rot_zyx(b[5], 0.0, 0.0) @ [0, 1.0, 0],
                                [0, 0, 1.0]])

    def _base_jacobian(self, values: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d world position / d base x y z rx ry rz (N, 3, 6) at world positions p (N, 3), and the world
        axes (3, 3) the rotations rx, ry, rz turn about (columns): unit steps, then turns about the
        axes through t (R = Rz Ry Rx: each turns about its axis as already moved by the rotations
        before it in the product)."""
        b, axes = values[self.params.indices(BASE_NAMES)], self._base_axes(values)
        J = np.zeros((len(p), 3, 6))
        J[:, :, :3] = np.eye(3)
        J[:, :, 3:] = np.cross(axes.T[None], (p - b[:3])[:, None], axis=2).transpose(0, 2, 1)
        return J, axes

    # ---- generic kinematics -------------------------------------------------------------------
    def _solve_local(self, q: np.ndarray, values: np.ndarray, strict: bool = True):
        """Newton on f(x) = 0; returns x and a converged mask (N,) (raises if ``strict``)."""
        x = self.start_point(q, values)
        ok = np.zeros(q.shape[0], bool)
        for _ in range(NEWTON_ITER):
            f = self.constraints(x, q, values)
            self._check_count(f.shape[1])
            ok = np.all(np.abs(f) < NEWTON_TOL, axis=1)
            if ok.all():
                break
            fx = self.constraint_jacobian(x, q, values)
            with np.errstate(all="ignore"):
                try:
                    step = np.linalg.solve(fx, f[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    step = np.einsum("nij,nj->ni", np.linalg.pinv(fx), f)
            step = np.where(np.isfinite(step) & ~ok[:, None], step, 0.0)
            x = self._retract(x, -step)
        ok &= np.all(np.isfinite(x.reshape(x.shape[0], -1)), axis=1)
        x = self.assembly_mode(x, q, values)
        if strict and not ok.all():
            bad = np.flatnonzero(~ok)
            raise ModelError(f"{self.name}: forward kinematics did not converge for {bad.size} configuration(s) "
                             f"(first at index {bad[0]}, q = {np.array2string(q[bad[0]], precision=6)}): outside "
                             f"the workspace or at a singularity; check the joint values and their units")
        return x, ok

    def _check_count(self, c: int) -> None:
        """ModelError unless the constraints are as many as the unknown's coordinates."""
        d = UNKNOWNS[self.UNKNOWN]
        if c != d:
            raise ModelError(f"{self.name}: {c} constraint(s) for a {self.UNKNOWN} unknown of {d} coordinates: the "
                             f"model needs exactly {d} (one per actuated leg); "
                             f"{'a pose unknown' if d == 3 else 'a position unknown'} needs "
                             f"{6 if d == 3 else 3}")

    def _rates(self, q: np.ndarray, values: np.ndarray, joints: bool, x: np.ndarray | None = None):
        """The measured point p (N, 3) in the world at the solved unknown (or at ``x``), its Jacobian by
        the parameters (N, 3, P) or, with ``joints``, by the joints (N, 3, n), the world rotation of the
        platform (N, 3, 3; None for a position) and its rotation rate (N, 3, P or n; None for a position)."""
        x = self._solve_local(q, values)[0] if x is None else x
        e, Ex, Es, Rl = self._end(x, values)
        Rb, tb = self._base(values)
        p = e @ Rb.T + tb
        fx, fq, fs = self.constraint_derivatives(x, q, values)
        dx = -self._checked_inverse(fx, q) @ (fq if joints else fs)  # implicit-function theorem
        J = np.einsum("ij,njk->nik", Rb, Ex @ dx + (0.0 if joints else Es))
        W = None if Rl is None else np.einsum("ij,njk->nik", Rb, dx[:, 3:])
        if not joints:  # the base frame moves the point rigidly (and through constraints that depend on it)
            base, axes = self._base_jacobian(values, p)
            J[:, :, self.params.indices(BASE_NAMES)] += base
            if W is not None:
                W[:, :, self.params.indices(BASE_NAMES)] += np.concatenate([np.zeros((3, 3)), axes], axis=1)
        return p, J, None if Rl is None else Rb @ Rl, W

    def _pose_local(self, R: np.ndarray, p: np.ndarray, values: np.ndarray) -> np.ndarray:
        """The platform pose (N, 3, 4) in the robot frame whose frame is at world rotations R (N, 3, 3)
        with its tool point at world positions p (N, 3)."""
        Rb, tb = self._base(values)
        Rl = np.einsum("ji,njk->nik", Rb, R)
        t = (p - tb) @ Rb - np.einsum("nij,j->ni", Rl, values[self.params.indices(TOOL_NAMES)])
        return np.concatenate([Rl, t[:, :, None]], axis=2)

    def inverse_pose(self, R: np.ndarray, p: np.ndarray, values: np.ndarray | None = None,
                     strict: bool = True) -> np.ndarray:
        """Joint values (N, n) that put the platform frame at world rotations R (N, 3, 3) with the tool
        point at world positions p (N, 3): the closed-form inverse (``has_inverse``) of a pose unknown."""
        v = self.param_values(values)
        if self.UNKNOWN != "pose":
            raise ModelError(f"{self.name}: its platform only translates; give positions (inverse)")
        return self.inverse_local(self._pose_local(np.asarray(R, float), np.atleast_2d(np.asarray(p, float)), v), v,
                                  strict)

    def inverse_pose_and_jacobian(self, R: np.ndarray, p: np.ndarray, values: np.ndarray | None = None):
        """Joint values (N, n) for platform poses (world rotations R (N, 3, 3), tool points p (N, 3)),
        their derivatives by the parameters at the fixed pose (N, n, P), and by a turn of the pose about
        world axes through the tool point (N, n, 3): dq = −(∂f/∂q)⁻¹ (∂f/∂x · dx + ∂f/∂s ds), where the
        platform's pose in the robot frame, x, moves with the base frame and the tool point only."""
        v = self.param_values(values)
        x = self._pose_local(np.asarray(R, float), np.atleast_2d(np.asarray(p, float)), v)
        q = self.inverse_local(x, v)
        fx, fq, fs = self.constraint_derivatives(x, q, v)
        Rb, _ = self._base(v)
        n, Rl, t = len(q), x[:, :, :3], x[:, :, 3]
        dx = np.zeros((n, 6, self.n_params))  # the platform's twist (dt, δ) per parameter
        dx[:, :3, self.params.indices(TOOL_NAMES)] = -Rl
        base = self.params.indices(BASE_NAMES)
        dx[:, :3, base[:3]] = -Rb.T
        delta = -Rb.T @ self._base_axes(v)  # (3, 3): δ per base rotation
        dx[:, 3:, base[3:]] = delta
        dx[:, :3, base[3:]] = np.cross(delta.T[None], t[:, None], axis=2).transpose(0, 2, 1)
        solve = lambda rhs: -np.linalg.solve(fq, rhs)  # noqa: E731
        return q, solve(fx @ dx + fs), solve(fx @ self._world_moves(Rl, v)[:, :, 3:])

    def _world_moves(self, Rl: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(N, 6, 6) the platform's twist in the robot frame (dt, δ) per world translation of the tool point (3),
        then per turn about world axes through it (3), for platform rotations Rl (N, 3, 3) in the robot frame."""
        Rb, _ = self._base(values)
        n, tool = len(Rl), values[self.params.indices(TOOL_NAMES)]
        out = np.zeros((n, 6, 6))
        out[:, :3, :3] = Rb.T
        out[:, :3, 3:] = np.cross((Rl @ tool)[:, None], Rb[None], axis=2).transpose(0, 2, 1)
        out[:, 3:, 3:] = Rb.T
        return out

    def inverse_rates(self, p: np.ndarray, values: np.ndarray | None = None,
                      R: np.ndarray | None = None) -> np.ndarray:
        """The joints' derivatives by the measured tool point p (N, 3) (a world translation), (N, n, 3), or with
        the platform's world rotations R (N, 3, 3) by the pose (a translation, then a turn about world axes through
        the tool point), (N, n, 6): dq = −(∂f/∂q)⁻¹ ∂f/∂x · dx, the implicit-function theorem at the inverse."""
        v = self.param_values(values)
        p = np.atleast_2d(np.asarray(p, float))
        if (R is None) != (self.UNKNOWN == "position"):
            raise ModelError(f"{self.name}: its inverse starts from a {'position' if R is None else 'pose'}; give "
                             f"{'positions only' if self.UNKNOWN == 'position' else 'the rotations too'}")
        if R is None:
            Rb, t = self._base(v)
            x = (p - t) @ Rb
            moves = np.broadcast_to(Rb.T, (len(p), 3, 3))  # the local point per world translation
        else:
            x = self._pose_local(np.asarray(R, float), p, v)
            moves = self._world_moves(x[:, :, :3], v)
        fx, fq, _ = self.constraint_derivatives(x, self.inverse_local(x, v), v)
        return -np.linalg.solve(fq, fx @ moves)

    def _forward_and_jacobian(self, q, values, jacobian):
        if not jacobian:
            x, _ = self._solve_local(q, values)
            Rb, tb = self._base(values)
            return self._end(x, values)[0] @ Rb.T + tb, None
        return self._rates(q, values, False)[:2]

    def _frame_and_rates(self, q, values):
        if self.UNKNOWN == "position":
            return super()._frame_and_rates(q, values)
        return self._rates(q, values, False)

    def _pose_and_jacobian(self, q, values):
        if self.UNKNOWN == "position":
            return super()._pose_and_jacobian(q, values)
        p, Jp, R, Jw = self._rates(q, values, True)
        return p, R, Jp, Jw

    def _checked_inverse(self, fx: np.ndarray, q: np.ndarray) -> np.ndarray:
        cond = np.linalg.cond(fx)
        bad = ~(cond < SINGULAR_COND)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise ModelError(f"{self.name}: {int(bad.sum())} configuration(s) are singular (∂f/∂x has condition "
                             f"number {cond[k]:.3g} at index {k}, q = {np.array2string(q[k], precision=6)}); "
                             f"leave them out")
        return np.linalg.inv(fx)

    def _joint_jacobian(self, q, values):
        return self._rates(q, values, True)[1]

    def inverse(self, p: np.ndarray, values: np.ndarray | None = None, strict: bool = True) -> np.ndarray:
        """Joint values (N, n) that place the end effector at world positions p (N, 3); unreachable
        positions raise a ModelError (or give NaN rows when not ``strict``)."""
        if not self.has_inverse:  # (a pose unknown: its joints need the whole pose, inverse_pose)
            raise self._no_inverse()
        values = self.param_values(values)
        R, t = self._base(values)
        return self.inverse_local((np.atleast_2d(np.asarray(p, float)) - t) @ R, values, strict)

    def in_working_mode(self, p: np.ndarray, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(N,) bool: the solution is in the working mode the closed-form inverse returns."""
        return np.ones(p.shape[0], bool)

    def inverse_and_jacobian(self, p: np.ndarray, values: np.ndarray | None = None):
        """Joint values (N, n) for world positions p (N, 3) and their derivatives with respect to the
        parameters at fixed p, (N, n, P): dq = −(∂f/∂q)⁻¹ (∂f/∂p · ∂p_local/∂s + ∂f/∂s) ds."""
        if not self.has_inverse:  # (a pose unknown: its joints need the whole pose, inverse_pose)
            raise self._no_inverse()
        values = self.param_values(values)
        p = np.atleast_2d(np.asarray(p, float))
        R, t = self._base(values)
        p_local = (p - t) @ R
        q = self.inverse_local(p_local, values)
        fp, fq, fs = self.constraint_derivatives(p_local, q, values)
        dpl = np.zeros((p.shape[0], 3, self.n_params))  # ∂p_local/∂(base parameters)
        dpl[:, :, self.params.indices(BASE_NAMES)] = -R.T @ self._base_jacobian(values, p)[0]
        rhs = fs + np.einsum("nci,nik->nck", fp, dpl)
        return q, -np.linalg.solve(fq, rhs)

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """Within the limits, assembles, and in the nominal working mode."""
        q = self.check_q(q)
        p, ok = self._solve_local(q, self.params.values, strict=False)
        return self.within_limits(q) & ok & self.in_working_mode(p, q, self.params.values)
