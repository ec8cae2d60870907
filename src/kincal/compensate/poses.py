"""Full-pose compensation: joint commands that put the calibrated model's TCP at target poses, and the
"filtered" poses to send to a controller that moves with its own (nominal or factory) model.

The solver is batched Newton on the 6-D pose error (damped least squares), iterating only the
targets not yet converged. Six joints solve all six components; a redundant arm takes the smallest
step from its start (the nominal command), so it stays near it in the null space; a robot with fewer
joints reaches the position first and the rotation components it controls, and the rest of the
rotation error is reported, per target, as not controlled.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._frozen import freeze_arrays
from ..errors import ModelError
from ..models.robot import Robot
from ..models.transforms import rotation_log

POS_TOL = 1e-12  # m: converged (commands then agree to ~1e-10 rad)
ROT_TOL = 1e-12  # rad
MAX_ITER = 50
CHUNK = 16384  # targets solved together
FIRST_PASS = 8  # iterations per chunk; the targets left then iterate together (near singularities)
DAMPING = 1e-12  # relative: keeps a step finite at an exact singularity
ROT_WEIGHT = {True: 0.1, False: 1e-4}  # m per rad: full pose (≥ 6 joints) / position first (fewer joints)
STALL = 1e-13  # m: a step moving the tool this little ends a least-squares solve (fewer than 6 joints)
MAX_MOVE = 0.02  # m: no joint may move the tool point more than this in one step (a full step near a
#                   singularity would leave the branch); joints are scaled by their lever (m per rad or m)
ROT_LEVER = 0.1  # m per rad: a wrist joint turning the tool counts as moving a point this far out
FINAL = 1e-9  # m and rad: an error below this is gone after one more Newton step (it leaves ~1e-18 at
#               the model's curvature of about 1 per m), so that step ends the solve without another evaluation
MAX_TRAVEL = 0.1  # m: a correction that has moved the tool this far is another arm configuration; given up
TURN_ROUNDS = 8  # rounds at most that put another model's flange at the target rotations (each leaves 1e-3 to 1e-2
# of the last: a 10 mrad turn is within ROT_TOL after 4 to 6; a rotation left at 1e-10 rad shows as 1e-8° in a program)


@dataclass(frozen=True)
class PoseSolution:
    """Commands that put a model's tool point at target poses, with the errors they leave.

    For a target whose last step started below ``FINAL`` (1e-9 m and rad), the errors are those before that
    step: a bound (the step leaves about their square).

    Parameters
    ----------
    q : ndarray, shape (N, n)
        The commands, rad (m for a prismatic joint).
    position_error : ndarray, shape (N,)
        The tool point's distance from its target at ``q``, m.
    rotation_error : ndarray, shape (N,)
        The flange's rotation from its target at ``q``, rad; for a robot with fewer than six joints, what
        it cannot control.
    converged : ndarray of bool, shape (N,)
        Which targets converged (the others stopped: too far from their start, or out of iterations).
    iterations : int
        The most Newton iterations any target took.

    See Also
    --------
    solve_poses : Makes it.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import solve_poses
    >>> robot = kincal.load_robot("ur5")
    >>> q0 = robot.sample_joints(2, seed=2)
    >>> p, R, _, _ = robot.pose_and_jacobian(q0)
    >>> sol = solve_poses(robot, p, R, q0 + 0.01)  # from 10 mrad off on every joint
    >>> sol.converged.tolist(), bool(abs(sol.q - q0).max() < 1e-9)
    ([True, True], True)
    >>> bool(sol.position_error.max() < 1e-9 and sol.rotation_error.max() < 1e-9)
    True
    """

    q: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray
    converged: np.ndarray
    iterations: int

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place


def pose_errors(model: Robot, q: np.ndarray, p_t: np.ndarray, R_t: np.ndarray):
    """Position errors (N, 3) m and world-frame rotation errors (N, 3) rad of the model at q against
    the targets, with the model's pose Jacobians (N, 3, n) each."""
    p, R, Jp, Jw = model.pose_and_jacobian(q)
    return p_t - p, rotation_log(R_t @ np.swapaxes(R, 1, 2)), Jp, Jw


def solve_poses(model: Robot, p_t: np.ndarray, R_t: np.ndarray, q0: np.ndarray, max_iter: int = MAX_ITER,
                fixed: tuple[int, ...] = (), chunk: int = CHUNK, give_up: np.ndarray | None = None,
                max_travel: float = MAX_TRAVEL, turned_as: Robot | None = None,
                measured: np.ndarray | None = None) -> PoseSolution:
    """Solve for the commands that put ``model``'s tool point and flange at target poses.

    Damped Newton steps on the 6-D pose error from ``q0`` (module docstring); only unconverged targets
    iterate, ``chunk`` targets at a time (bounded memory, arrays that stay in cache) for the first
    ``FIRST_PASS`` iterations, then the few left of every chunk together (a target near a singularity then
    costs no pass per chunk). No step moves the tool point more than ``MAX_MOVE`` (0.02 m).

    Parameters
    ----------
    model : Robot
        The model to solve on, with a tool point and flange frame.
    p_t : ndarray, shape (N, 3)
        Target positions of the tool point, m.
    R_t : ndarray, shape (N, 3, 3)
        Target rotations of the flange.
    q0 : ndarray, shape (N, n)
        Start joints, rad (m for a prismatic joint).
    max_iter : int, optional
        Newton iterations at most (default ``MAX_ITER``, 50).
    fixed : tuple of int, optional
        Joints (indices) that keep their start values (a redundant arm's controller takes one as its
        redundancy parameter).
    chunk : int, optional
        Targets solved together (default ``CHUNK``, 16384).
    give_up : ndarray, shape (n,), optional
        Per joint, rad or m: a target whose next command would leave its start by more than this on a
        joint stops there, unconverged (a caller that refuses such commands saves their iterations).
    max_travel : float, optional
        A target whose steps have moved its tool point this far in all stops unconverged, m (default
        ``MAX_TRAVEL``, 0.1: a correction that far is another configuration; an inverse from afar gives a
        larger one).
    turned_as : Robot, optional
        The model whose flange must reach the target rotations (default: ``model``); the tool point is still
        ``model``'s. Give the nominal model when ``model`` was calibrated from positions alone: the turns of
        the flange its parameters imply were never measured. Solved as rounds of ``model`` on the rotations it
        must reach for ``turned_as`` to reach R_t (:func:`turn_goal`), until ``turned_as``'s flange is within
        ``ROT_TOL`` of R_t wherever the solve converged (``TURN_ROUNDS`` at most); the rotation error reported is
        ``turned_as``'s.
    measured : ndarray, shape (3,), optional
        With ``turned_as``: the point the calibration measured, in the flange frame, m (default: ``model``'s tool
        point). ``model``'s position is trusted there, not at its tool point (the TCP): the TCP stands where
        ``model`` puts that point, carried on by ``turned_as``'s flange turn (:func:`tcp_positions`). Solved as
        that point on the goal less R_t times the lever (:func:`at_measured`); the position error reported is
        the TCP's.

    Returns
    -------
    PoseSolution
        The commands (N, n), the position (m) and rotation (rad) errors left (N,), which converged and the
        iterations.

    Raises
    ------
    ModelError
        When ``model`` has no tool point and flange frame.

    Examples
    --------
    The commands at which a perturbed UR5 reaches the poses its nominal model reaches at ``q0``:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import solve_poses
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q0 = nominal.sample_joints(4, seed=2)
    >>> p, R, _, _ = nominal.pose_and_jacobian(q0)
    >>> sol = solve_poses(real, p, R, q0)
    >>> sol.converged.tolist()
    [True, True, True, True]
    >>> round(float(np.abs(sol.q - q0).max()) * 1e3, 2)  # the largest correction, mrad
    4.37
    >>> p_real, R_real, _, _ = real.pose_and_jacobian(sol.q)
    >>> bool(np.abs(p_real - p).max() < 1e-9 and np.abs(R_real - R).max() < 1e-9)
    True
    """
    if not model.has_tool_point:
        raise ModelError(f"robot '{model.name}' has no tool point and flange frame: give position targets")
    if turned_as is None:
        return _solve(model, p_t, R_t, q0, max_iter, fixed, chunk, give_up, max_travel)
    point, p_point = at_measured(model, p_t, R_t, measured)
    sol = _solve(point, p_point, R_t, q0, max_iter, fixed, chunk, give_up, max_travel)
    for _ in range(TURN_ROUNDS):
        start = np.where(np.all(np.isfinite(sol.q), axis=1)[:, None], sol.q, q0)
        sol = _solve(point, p_point, turn_goal(turned_as, point, sol.q, R_t), start, max_iter, fixed, chunk,
                     give_up, max_travel)
        left = model_turn(turned_as, sol.q, R_t)
        if not np.any(sol.converged & (left > ROT_TOL)):
            break
    ok = np.all(np.isfinite(sol.q), axis=1)
    miss = sol.position_error.copy()
    miss[ok] = np.linalg.norm(tcp_positions(model, sol.q[ok], turned_as, measured) - p_t[ok], axis=1)
    return dataclasses.replace(sol, rotation_error=left, position_error=miss)


def at_measured(model: Robot, p_t: np.ndarray, R_t: np.ndarray,
                measured: np.ndarray | None) -> tuple[Robot, np.ndarray]:
    """The model and goals on which a pose solve puts the TCP at p_t (N, 3) m, the flange at R_t (N, 3, 3) turned as
    another model's, where ``model``'s position is trusted at ``measured`` (3,) m in the flange frame: ``model``
    with that point as its tool point, and p_t − R_t·(TCP − measured), where it stands when the TCP is on p_t
    (:func:`tcp_positions`); ``model`` and p_t as they are for ``measured`` None.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate.poses import at_measured
    >>> robot = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.15])
    >>> point, p = at_measured(robot, np.array([[0.4, 0.1, 0.3]]), np.eye(3)[None], np.array([0.0, 0.0, 0.03]))
    >>> point.tool_point().tolist(), np.round(p, 3).tolist()  # m
    ([0.0, 0.0, 0.03], [[0.4, 0.1, 0.18]])
    """
    if measured is None:
        return model, p_t
    measured = np.asarray(measured, dtype=float)
    return model.with_tool_point(measured), p_t - R_t @ (model.tool_point() - measured)


def tcp_positions(model: Robot, q: np.ndarray, turned_as: Robot | None = None,
                  measured: np.ndarray | None = None) -> np.ndarray:
    """Where the TCP (``model``'s tool point) stands at q (N, n), m (N, 3).

    ``model`` puts it there itself unless its flange turn is not followed (``turned_as``, the model whose flange
    turn is) and its position is trusted at another point, the one the calibration ``measured`` ((3,) m, flange
    frame): then ``model``'s position of that point plus ``turned_as``'s flange rotation times the lever from it
    to the TCP. The position data determine ``model``'s point where they were measured; its turn of the flange
    they do not, and the lever would carry that turn's error to the TCP.

    Parameters
    ----------
    model : Robot
        The calibrated model, with the TCP as its tool point.
    q : ndarray, shape (N, n)
        Joints, rad (m for a prismatic joint).
    turned_as : Robot, optional
        The model whose flange turn the commands follow (default: ``model``'s own).
    measured : ndarray, shape (3,), optional
        The point the calibration measured, m, flange frame (default: the TCP itself).

    Returns
    -------
    ndarray, shape (N, 3)
        The TCP positions, m.

    Examples
    --------
    A TCP 120 mm beyond the point measured, on a model whose flange turn differs from the nominal one: the two
    stand apart by the turn times that lever.

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate.poses import tcp_positions
    >>> nominal = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.15])
    >>> model = kincal.perturb(nominal, seed=1)
    >>> q = nominal.sample_joints(2, seed=2)
    >>> own, kept = tcp_positions(model, q), tcp_positions(model, q, nominal, np.array([0.0, 0.0, 0.03]))
    >>> np.round(np.linalg.norm(own - kept, axis=1) * 1e3, 3)  # mm
    array([0.236, 0.144])
    """
    if turned_as is None or measured is None:
        return model.forward(q)
    measured = np.asarray(measured, dtype=float)
    return model.with_tool_point(measured).forward(q) + turned_as.flange_rotation(q) @ (model.tool_point() - measured)


def assembled_rows(f: Callable[[np.ndarray], np.ndarray], q: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``f`` of the rows of q (N, n) where the models it uses assemble: (those rows' indices (K,), ``f`` of them,
    stacked; None when K is 0).

    ``f`` takes an index array and computes through models whose forward kinematics may fail at some rows (a closed
    chain's legs out of reach: a ModelError for the whole call). All finite rows are tried at once; where that fails,
    each half on its own, down to the rows that fail alone, which are left out: they are refused by row, not the file.

    Parameters
    ----------
    f : callable
        ``f(idx)`` -> ndarray (len(idx), ...), for an index array of rows of q.
    q : ndarray, shape (N, n)
        The commands, rad (m for a prismatic joint).

    Returns
    -------
    tuple of ndarray and (ndarray or None)
        The indices of the rows computed (finite and assembled, in order) and ``f`` of them.

    Examples
    --------
    A hexapod's legs of two poses, with leg 1 of the second made 2 m long, where no platform pose exists:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate.poses import assembled_rows
    >>> robot = kincal.load_robot("hexapod")
    >>> q = robot.sample_joints(3, seed=1)
    >>> q[1, 0] = 2.0 / robot.motor_leads[0]
    >>> rows, p = assembled_rows(lambda i: robot.forward(q[i]), q)
    >>> rows.tolist(), p.shape
    ([0, 2], (2, 3))
    """
    def tried(idx: np.ndarray) -> tuple[np.ndarray, list]:
        try:
            return idx, [f(idx)]
        except ModelError:
            if len(idx) == 1:
                return idx[:0], []
            (a, fa), (b, fb) = tried(idx[:len(idx) // 2]), tried(idx[len(idx) // 2:])
            return np.concatenate([a, b]), fa + fb

    finite = np.flatnonzero(np.all(np.isfinite(q), axis=1))
    if not finite.size:
        return finite, None
    rows, values = tried(finite)
    return rows, (np.concatenate(values) if values else None)


def turn_goal(model: Robot, robot: Robot, q: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the rotations ``robot``'s flange must reach for ``model``'s to reach ``rotations`` at about q
    (N, n): R_robot(q) R_model(q)ᵀ R* (rows with no finite q, or where a model does not assemble, keep R*)."""
    goal = np.array(rotations, dtype=float)
    ok, turn = assembled_rows(lambda i: robot.flange_rotation(q[i]) @ np.swapaxes(model.flange_rotation(q[i]), 1, 2),
                              q)
    if ok.size:
        goal[ok] = turn @ goal[ok]
    return goal


def model_turn(model: Robot, q: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """(N,) rad: how far ``model``'s flange at q (N, n) stands from ``rotations`` (inf where q is not finite or
    the model does not assemble)."""
    left = np.full(len(q), np.inf)
    ok, R = assembled_rows(lambda i: model.flange_rotation(q[i]), q)
    if ok.size:
        left[ok] = np.linalg.norm(rotation_log(R @ np.swapaxes(rotations[ok], 1, 2)), axis=1)
    return left


def _solve(model: Robot, p_t: np.ndarray, R_t: np.ndarray, q0: np.ndarray, max_iter: int, fixed: tuple[int, ...],
           chunk: int, give_up: np.ndarray | None, max_travel: float) -> PoseSolution:
    """:func:`solve_poses` on ``model``'s own flange."""
    q = np.array(q0, dtype=float)
    moving = np.ones(q.shape[1], bool)
    moving[list(fixed)] = False
    s = _State(q, np.empty(len(q)), np.empty(len(q)), np.zeros(len(q), bool), np.zeros(len(q)), np.array(q0, float),
               None if give_up is None else np.asarray(give_up, float), max_travel)
    first = min(FIRST_PASS, max_iter)
    left = [_iterate(model, p_t, R_t, s, np.arange(a, min(a + chunk, len(q))), moving, 1, first)
            for a in range(0, len(q), chunk)]
    rest = np.concatenate([a for a, _ in left]) if left else np.zeros(0, int)
    iterations = max((it for _, it in left), default=0)
    for a in range(0, rest.size, chunk):
        stopped, it = _iterate(model, p_t, R_t, s, rest[a:a + chunk], moving, first + 1, max_iter)
        iterations = max(iterations, it)
        if stopped.size:  # the errors at their last commands
            ep, er, _, _ = pose_errors(model, q[stopped], p_t[stopped], R_t[stopped])
            s.dp[stopped], s.dr[stopped] = np.linalg.norm(ep, axis=1), np.linalg.norm(er, axis=1)
    return PoseSolution(q, s.dp, s.dr, s.converged, iterations)


@dataclass(frozen=True)
class _State:
    """The solve's arrays, written in place: commands, errors left (m, rad), converged, and how far
    the steps have moved each tool point (m, summed)."""

    q: np.ndarray
    dp: np.ndarray
    dr: np.ndarray
    converged: np.ndarray
    travel: np.ndarray
    start: np.ndarray
    give_up: np.ndarray | None
    max_travel: float = MAX_TRAVEL


def _norms(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.sqrt(np.einsum("nij,nij->nj", x, x)) if axis == 1 else np.sqrt(np.einsum("ni,ni->n", x, x))


def _iterate(model: Robot, p_t, R_t, s: _State, active: np.ndarray, moving, start: int, stop: int
             ) -> tuple[np.ndarray, int]:
    """Newton iterations start..stop on the targets ``active`` (indices), in place; returns the targets
    still iterating after ``stop`` (empty when the last one is done) and the last iteration made.
    The errors of a target that stops unconverged are those at its last command."""
    n_j = int(moving.sum())
    w = ROT_WEIGHT[n_j >= 6]
    it = start - 1
    for it in range(start, stop + 1):
        q = s.q[active]
        ep, er, Jp, Jw = pose_errors(model, q, p_t[active], R_t[active])
        dp, dr = _norms(ep), _norms(er)
        s.dp[active], s.dr[active] = dp, dr
        keep = (dp >= POS_TOL) | (dr >= ROT_TOL)
        s.converged[active[~keep]] = True
        if not keep.all():
            active, q, dp, dr, Jp, Jw, ep, er = (x[keep] for x in (active, q, dp, dr, Jp, Jw, ep, er))
        if not active.size:
            return active, it
        J = np.concatenate([Jp, w * Jw], axis=1)
        dq = _step(J if moving.all() else J * moving, np.concatenate([ep, w * er], axis=1))
        lever = _norms(Jp, 1) + ROT_LEVER * _norms(Jw, 1)  # (N, n): how far a unit of each joint moves the tool
        move = (np.abs(dq) * lever).max(axis=1)
        dq *= np.minimum(1.0, MAX_MOVE / np.maximum(move, 1e-300))[:, None]
        s.travel[active] += np.minimum(move, MAX_MOVE)
        stalled = move < STALL if n_j < 6 else np.zeros(len(move), bool)  # least squares: steps stopped moving
        s.converged[active[stalled]] = True
        go = ~stalled & (s.travel[active] < s.max_travel)  # beyond max_travel: left unconverged, refused by the checks
        if s.give_up is not None:  # a command this far from its start is refused anyway (another branch)
            go &= ~(np.abs(q + dq - s.start[active]) > s.give_up).any(axis=1)
        s.q[active[go]] = q[go] + dq[go]
        if n_j >= 6:  # a full Newton step from an error this small leaves about its square: done
            last = go & (dp < FINAL) & (dr < FINAL) & (move < MAX_MOVE)
            s.converged[active[last]] = True
            go &= ~last
        active = active[go]
        if not active.size:
            return active, it
    return active, it


def _step(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Damped least-squares steps (N, n) for Jacobians J (N, 6, n) and errors e (N, 6): the smallest
    step that removes the error when the robot has six joints or more, the least-squares one else."""
    n = J.shape[2]
    if n == 6:  # square: one LU per target; the damped normal equations for the singular ones
        try:
            return np.linalg.solve(J, e[..., None])[..., 0]
        except np.linalg.LinAlgError:  # target by target, so that no target's step depends on the others
            out = np.empty(e.shape)
            for k in range(len(J)):
                try:
                    out[k] = np.linalg.solve(J[k], e[k, :, None])[:, 0]
                except np.linalg.LinAlgError:
                    out[k] = _damped_step(J[k:k + 1], e[k:k + 1])[0]
            return out
    return _damped_step(J, e)


def _damped_step(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Damped least-squares steps: minimum norm (n ≥ 6 joints) or least squares (fewer)."""
    n = J.shape[2]
    Jt = np.swapaxes(J, 1, 2)
    if n >= 6:
        return np.einsum("nij,nj->ni", Jt, np.linalg.solve(_damped(J @ Jt), e[..., None])[..., 0])
    return np.linalg.solve(_damped(Jt @ J), np.einsum("nij,nj->ni", Jt, e)[..., None])[..., 0]


def _damped(A: np.ndarray) -> np.ndarray:
    """A (N, k, k) plus DAMPING times its mean diagonal: finite steps at an exact singularity, and no
    measurable effect elsewhere whatever the units of the rows."""
    k = A.shape[1]
    return A + (DAMPING * np.trace(A, axis1=1, axis2=2) / k)[:, None, None] * np.eye(k)


def filtered_poses(controller: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the poses to send a controller so that its inverse kinematics produce given commands.

    The controller moves with ``controller``'s kinematics: the poses are its own forward kinematics at ``q``.

    Parameters
    ----------
    controller : Robot
        The model the controller moves with (its nominal model), with a tool point.
    q : ndarray, shape (N, n)
        The commands the robot should take, rad (m for a prismatic joint).

    Returns
    -------
    positions : ndarray, shape (N, 3)
        Positions of the tool point, m.
    rotations : ndarray, shape (N, 3, 3)
        Rotations of the flange.

    Examples
    --------
    The filtered poses of corrected commands differ from the intended poses by about the robot's errors:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import filtered_poses, solve_poses
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q0 = nominal.sample_joints(2, seed=2)
    >>> p, R, _, _ = nominal.pose_and_jacobian(q0)
    >>> q = solve_poses(real, p, R, q0).q
    >>> p_send, R_send = filtered_poses(nominal, q)
    >>> np.round(np.linalg.norm(p_send - p, axis=1) * 1e3, 2)  # mm
    array([1.41, 1.26])
    """
    return controller.pose_and_jacobian(q)[:2]
