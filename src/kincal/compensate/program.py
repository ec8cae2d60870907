"""Robot programs compensated in place: every literal move target replaced by the one that makes the
real robot (the calibrated model) land where the program meant, for a controller that moves with its
own (nominal) model; every other byte of the program kept.

* a joint target: the pose the nominal model reaches there is the intended one; it becomes the
  corrected joints;
* a pose target: the controller's inverse kinematics (the nominal model, from the previous target's
  joints) give the joints it would use; the corrected joints are found from those, and the pose is
  replaced by the filtered pose, the one the controller turns into the corrected joints.
Each corrected target is checked (converged, on the nominal branch, within the joint limits); a
target that fails keeps its text and is named by line.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..io.program_ur import joints_literal, pose_literal
from ..io.programs import Program
from ..models.robot import Robot
from .commands import BRANCH_TOL
from .poses import rotation_log, solve_poses


@dataclass(frozen=True)
class ProgramCompensation:
    """Replacement texts by target index, the corrected joints per target (NaN where refused), the
    problems (by line) and the moves left as they are (non-literal targets)."""

    texts: dict
    q: np.ndarray
    problems: tuple[str, ...]
    not_literal: tuple[tuple[int, str, str], ...]


def compensate_program(model: Robot, nominal: Robot, program: Program, q_start: np.ndarray | None = None
                       ) -> ProgramCompensation:
    """Compensate every literal target of ``program`` (see the module docstring). ``q_start``: the
    joints the robot stands at before the first move (default: the first joint target's)."""
    from scipy.spatial.transform import Rotation

    first = next((t.values for t in program.targets if t.kind == "joints"), None)
    q_prev = q_start if q_start is not None else first
    q_prev = None if q_prev is None else np.asarray(q_prev, dtype=float)
    texts, problems, qs = {}, [], np.full((len(program.targets), model.n_joints), np.nan)
    tol = np.array([BRANCH_TOL[t] for t in model.joint_types])
    for k, t in enumerate(program.targets):
        where = f"{program.source}: line {t.line} ({t.move})"
        if t.kind == "joints":
            if t.values.size != model.n_joints:
                problems.append(f"{where}: {t.values.size} joint values for a {model.n_joints}-joint robot; left as is")
                continue
            q_nom = t.values
            p, R, _, _ = nominal.pose_and_jacobian(q_nom[None])
        else:
            if q_prev is None:
                problems.append(f"{where}: a pose target with no joints to start the inverse kinematics from (no joint "
                                f"target before it and no start joints given); left as is")
                continue
            p, R = t.values[None, :3], Rotation.from_rotvec(t.values[None, 3:]).as_matrix()
            ik = solve_poses(nominal, p, R, q_prev[None])
            if not ik.converged[0]:
                problems.append(f"{where}: the nominal model does not reach this pose from the previous joints; left "
                                f"as is")
                continue
            q_nom = ik.q[0]
        sol = solve_poses(model, p, R, q_nom[None])
        q = sol.q[0]
        why = ("the correction did not converge" if not sol.converged[0] else
               "the corrected joints leave the nominal branch" if (np.abs(q - q_nom) > tol).any() else
               "the corrected joints break the joint limits" if not model.within_limits(q[None])[0] else "")
        if why:
            problems.append(f"{where}: {why}; left as is")
            continue
        qs[k], q_prev = q, q_nom
        if t.kind == "joints":
            texts[k] = joints_literal(q)
        else:
            pf, Rf, _, _ = nominal.pose_and_jacobian(q[None])
            texts[k] = pose_literal(np.concatenate([pf[0], rotation_log(Rf)[0]]))
    return ProgramCompensation(texts, qs, tuple(problems), program.not_literal)
