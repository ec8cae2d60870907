"""Robot programs compensated in place: every literal move target replaced by the one that makes the
real robot (the calibrated model) land where the program meant, for a controller that moves with its
own (nominal) model; every other byte of the program kept.

* a joint target: the pose the nominal model reaches there is the intended one; it becomes the
  corrected joints;
* a pose target: the joints the controller would use (:func:`controller_inverse`: its inverse
  kinematics of the nominal model on the branch nearest the previous target's joints) are corrected
  on the calibrated model, and the pose is replaced by the filtered pose, the one the controller
  turns into the corrected joints.
The TCP is the program's own where it sets one (``set_tcp``), else the given one. Each corrected
target is checked (converged, on the nominal branch, within the joint limits); a target that fails
keeps its text and is named by line.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..io.program_ur import joints_literal, pose_literal
from ..io.programs import Program, Target
from ..models.robot import Robot
from ..models.transforms import rotation_log, rotvec_matrix
from ..models.ur import nearest_turns, ur_inverse, ur_lengths
from ..ties import first_best
from .commands import BRANCH_TOL
from .poses import solve_poses

STARTS = 24  # spread starts of the numeric inverse when Newton from the previous joints fails
SEARCH = (200, 20.0)  # iterations and travel (m) of the numeric inverse: from afar, not a small correction
Models = Callable[[np.ndarray], tuple[Robot, Robot]]  # a TCP point (3,) m -> (calibrated, nominal) models for it


@dataclass(frozen=True)
class ProgramCompensation:
    """Replacement texts by target index, the corrected joints per target (NaN where refused), the
    problems (by line), why each refused target was left (by index: the mark written beside it) and
    the moves left as they are (non-literal targets)."""

    texts: dict
    q: np.ndarray
    problems: tuple[str, ...]
    not_literal: tuple[tuple[int, str, str], ...]
    refused: dict


def compensate_program(model: Robot, nominal: Robot, program: Program, q_start: np.ndarray | None = None,
                       models: Models | None = None) -> ProgramCompensation:
    """Compensate every literal target of ``program`` (see the module docstring). ``q_start``: the
    joints the robot stands at before the first move (default: the first joint target's); ``models``:
    the models for a TCP the program sets (default: refuse the targets after a set_tcp)."""
    q_prev = (next((t.values for t in program.targets if t.kind == "joints"), None) if q_start is None
              else np.asarray(q_start, dtype=float))
    texts, refused, qs = {}, {}, np.full((len(program.targets), model.n_joints), np.nan)
    for k, t in enumerate(program.targets):
        tcp = program.tcp_at(t.at)
        found = _target(t, tcp, (model, nominal) if isinstance(tcp, tuple) else _for_tcp(models, tcp), q_prev)
        if isinstance(found, str):
            refused[k] = found
            continue
        qs[k], q_prev, texts[k] = found
    problems = tuple(f"{program.source}: line {program.targets[k].line} ({program.targets[k].move}"
                     f"{' ' + program.targets[k].variable if program.targets[k].variable else ''}): {why}; left as is"
                     for k, why in refused.items())
    return ProgramCompensation(texts, qs, problems, program.not_literal, refused)


def _for_tcp(models: Models | None, tcp) -> tuple[Robot, Robot] | str:
    if tcp is None:
        return "the TCP is set from a variable (set_tcp of a non-literal); set it with a literal p[…]"
    if models is None:
        return "the program sets its TCP (set_tcp) and no models were given for it"
    return models(tcp[:3])


def _target(t: Target, tcp, models, q_prev: np.ndarray | None):
    """(corrected joints, nominal joints, replacement text) of one target, or why it is refused."""
    if isinstance(models, str):
        return models
    model, nominal = models
    turn = np.eye(3) if isinstance(tcp, tuple) else rotvec_matrix(tcp[3:])  # the TCP's rotation on the flange
    if t.kind == "joints":
        if t.values.size != model.n_joints:
            return f"{t.values.size} joint values for a {model.n_joints}-joint robot"
        q_nom = t.values
        p, R, _, _ = nominal.pose_and_jacobian(q_nom[None])
    else:
        if q_prev is None:
            return ("a pose target with no joints to start the inverse kinematics from (no joint target before it "
                    "and no start joints given)")
        p, R = t.values[None, :3], (rotvec_matrix(t.values[3:]) @ turn.T)[None]
        found = controller_inverse(nominal, p, R, q_prev)
        if found is None:
            return "the nominal model does not reach this pose on any branch within the joint limits"
        q_nom = found
    q, why = corrected(model, p, R, q_nom)
    if why:
        return why
    if t.kind == "joints":
        return q, q_nom, joints_literal(q)
    pf, Rf, _, _ = nominal.pose_and_jacobian(q[None])
    return q, q_nom, pose_literal(np.concatenate([pf[0], rotation_log(Rf @ turn)[0]]))


def corrected(model: Robot, p: np.ndarray, R: np.ndarray, q_nom: np.ndarray) -> tuple[np.ndarray, str]:
    """The joints (n,) at which ``model`` puts its tool point at p (1, 3) m with the flange at R (1, 3, 3), by
    Newton from the nominal joints q_nom (n,), and why they are refused ('' when they are not): the correction
    did not converge, leaves the nominal branch (a joint moves more than BRANCH_TOL) or breaks a joint limit."""
    sol = solve_poses(model, p, R, q_nom[None])
    q = sol.q[0]
    tol = np.array([BRANCH_TOL[j] for j in model.joint_types])
    return q, ("the correction did not converge" if not sol.converged[0] else
               "the corrected joints leave the nominal branch" if (np.abs(q - q_nom) > tol).any() else
               "the corrected joints break the joint limits" if not model.within_limits(q[None])[0] else "")


def controller_inverse(robot: Robot, p: np.ndarray, R: np.ndarray, near: np.ndarray) -> np.ndarray | None:
    """The joints (n,) a controller moving with ``robot`` takes for the tool point at p (1, 3) m with
    the flange at R (1, 3, 3): of its inverse-kinematics solutions within the joint limits, the one
    nearest ``near`` (n,) (a UR arm: its eight closed-form branches, :func:`kincal.models.ur.ur_inverse`;
    any other: Newton from ``near``, else from spread starts); None when no solution reaches the pose."""
    if ur_lengths(robot) is not None:
        sols, ok = ur_inverse(robot, p, R, near[None])
        cand = sols[0][ok[0]]
    else:
        cand = _numeric_inverse(robot, p, R, near)
    if not len(cand):
        return None
    return cand[first_best(np.linalg.norm(cand - near, axis=1), maximize=False)]  # ties: the canonical branch order


def _numeric_inverse(robot: Robot, p: np.ndarray, R: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Solutions (K, n) within the limits: Newton from ``near``, else from STARTS spread starts
    (deterministic), revolute joints taken the whole turns nearest ``near``."""
    sol = solve_poses(robot, p, R, near[None], max_iter=SEARCH[0], max_travel=SEARCH[1])
    if not sol.converged[0]:
        starts = np.vstack([near, robot.sample_joints(STARTS, seed=0)])
        sol = solve_poses(robot, np.repeat(p, len(starts), 0), np.repeat(R, len(starts), 0), starts,
                          max_iter=SEARCH[0], max_travel=SEARCH[1])
    q = sol.q[sol.converged]
    turns = robot.periodic
    q = np.where(turns, nearest_turns(q, near, robot.lower, robot.upper), q)
    return q[robot.within_limits(q)] if len(q) else q
