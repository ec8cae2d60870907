"""Robot programs compensated in place: every literal move target replaced by the one that makes the
real robot (the calibrated model) land where the program meant, for a controller that moves with its
own (nominal) model; every other byte of the program kept.

* a joint target: the pose the nominal model reaches there is the intended one, at the calibrated model's TCP
  less what of the calibration's move of it is carried over (``carry``, :func:`kincal.compensate.tool_carry`: a
  move beyond a link's error is the target's mounting, where the nominal model has it too), as for the other
  languages (:mod:`kincal.compensate.branch`); it becomes the corrected joints;
* a pose target: the joints the controller would use (:func:`controller_inverse`: its inverse
  kinematics of the nominal model on the branch nearest the previous target's joints) are corrected
  on the calibrated model, and the pose is replaced by the filtered pose, the one the controller
  turns into the corrected joints.
The TCP is the program's own where it sets one (``set_tcp``, by the program's flow: a target where its paths
leave different TCPs is refused, naming their lines), else the given one. Each corrected
target is checked (converged, on the nominal branch, within the joint limits); a target that fails
keeps its text and is named by line.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._frozen import freeze_arrays
from ..io.branches import BITS
from ..io.program_ur import write as write_ur
from ..io.programs import Program, Target
from ..models.robot import Robot
from ..models.transforms import rotation_log, rotvec_matrix
from ..models.ur import nearest_turns, ur_inverse, ur_lengths
from ..ties import first_best
from .commands import branch_tolerance, past_limits
from .poses import solve_poses

STARTS = 24  # spread starts of the numeric inverse when Newton from the previous joints fails
TCP_MAX = 2.0  # m: no tool puts its TCP this far from the flange (a set_tcp written in mm, not m)
POSE_MAX = 20.0  # m: no arm's pose target lies this far from its base (a pose written in mm, not m)
SEARCH = (200, 20.0)  # iterations and travel (m) of the numeric inverse: from afar, not a small correction
FOREIGN = 0.5  # a program more than this fraction of whose literal targets its robot cannot reach is another robot's
ALIEN = ("the program looks written for another robot (more than half of its literal targets are out of this robot's "
         "reach as written): none of its targets is compensated")  # the mark beside a target it reached
SINGULAR = 1e3  # condition number of the pose Jacobian (m, rad) beyond which a failed correction is named as such
SINGULAR_EXACT = 1e8  # ... beyond which a joint target is at the singularity itself (a UR5's wrist 6e-8 rad from it; a
# literal 0): its correction, where one converges, is a split of a turn between joints in line that round-off decides
Models = Callable[[np.ndarray], tuple[Robot, Robot]]  # a TCP point (3,) m -> (calibrated, nominal) models for it


class Unreached(str):
    """Why a target is refused when the robot's nominal model cannot reach it as written: beyond its reach or joint
    limits, on none of its branches with the target's bits, or joints of another count (the refusals
    :func:`foreign` counts)."""


@dataclass(frozen=True)
class ProgramCompensation:
    """A robot program's literal targets compensated: their replacement texts and what was left as it is.

    Parameters
    ----------
    texts : dict of int to str
        Replacement texts by target index (into ``Program.targets``), for
        :meth:`kincal.io.Program.with_targets`.
    q : ndarray, shape (K, n)
        The corrected joints of each of the program's K targets, rad (m for a prismatic joint); NaN where
        refused.
    problems : tuple of str
        One message per refused target, naming the file and line.
    not_literal : tuple of tuple of (int, str, str)
        The moves left as they are (line, the move as written, why): their targets are not literals.
    kept : tuple of tuple of (int, str, str)
        The joint targets kept as they are (line, the move as written, why): at a singularity of the arm no
        joints near theirs put the calibrated TCP at their nominal pose; the robot goes where it went before.
    refused : dict of int to str
        Why each refused target was left, by target index: the mark written beside it (:class:`Unreached` where
        the nominal model cannot reach it as written).
    tcp : ndarray, shape (K, 3), optional
        Each target's TCP on the calibrated model, m in the flange frame (a tool's origin, the calibration's move
        carried over; a KRL, RAPID, FANUC or INFORM joint target's: the point the calibration measured); NaN where
        refused; None where not recorded (default). With ``q``, where the predicted σ is taken.
    foreign : str, optional
        Why the program looks written for another robot, '' when it does not (default): more than half of its
        literal targets are beyond the robot's reach or limits (:func:`foreign`); then every target is refused.

    See Also
    --------
    compensate_program, compensate_branches : Make it.

    Examples
    --------
    A URScript program that sets its TCP: the move after ``set_tcp`` needs models for that TCP, so without
    them it is refused and marked, while the move before it is compensated:

    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate_program
    >>> from kincal.io import read_program
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> text = ("movej([0.3, -1.2, 1.5, -1.9, 1.2, 0.4])\\n"
    ...         "set_tcp(p[0, 0, 0.1, 0, 0, 0])\\n"
    ...         "movej([0.5, -1.0, 1.3, -1.6, 1.0, 0.2])\\n")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "tcp.script")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path, "ur")
    >>> res = compensate_program(real, nominal, program)
    >>> sorted(res.texts), res.q.shape, bool(np.isnan(res.q[1]).all())
    ([0], (2, 6), True)
    >>> res.refused
    {1: 'the program sets its TCP (set_tcp) and no models were given for it'}
    >>> print(res.problems[0])
    /.../tcp.script: line 3 (movej): the program sets its TCP (set_tcp) and no models were given for it; left as is
    >>> print(program.with_targets(res.texts, res.refused))
    movej([0.29794..., -1.19963..., 1.50174..., -1.90109..., 1.20108..., 0.40139...])
    set_tcp(p[0, 0, 0.1, 0, 0, 0])
    movej([0.5, -1.0, 1.3, -1.6, 1.0, 0.2])  # kincal: not compensated: the program sets its TCP (set_tcp) and no
    models were given for it
    """

    texts: dict
    q: np.ndarray
    problems: tuple[str, ...]
    not_literal: tuple[tuple[int, str, str], ...]
    refused: dict
    kept: tuple[tuple[int, str, str], ...] = ()
    tcp: np.ndarray | None = None
    foreign: str = ""

    def __post_init__(self) -> None:
        freeze_arrays(self)  # the arrays it hands out: what it prints cannot drift from what it computed


def compensate_program(model: Robot, nominal: Robot, program: Program, q_start: np.ndarray | None = None,
                       models: Models | None = None, orientation: Robot | None = None,
                       measured: np.ndarray | None = None, carry: np.ndarray | None = None) -> ProgramCompensation:
    """Compensate every literal target of a robot program for a controller that moves with its nominal model.

    A joint target means the pose the nominal model reaches there (at the calibrated model's TCP less ``carry``),
    and becomes the joints at which the calibrated model reaches it; a pose target's controller joints (:func:`controller_inverse`) are corrected
    the same way, and the pose is replaced by the filtered pose (module docstring). Each corrected target is
    checked (converged, on the nominal branch, within the joint limits); a target that fails keeps its text
    and is named by line. Every other byte of the program is kept.

    Parameters
    ----------
    model : Robot
        The calibrated model (where the robot really goes), with the program's TCP, in its base frame.
    nominal : Robot
        The controller's (nominal) model, same TCP and frame.
    program : Program
        The program read (:func:`kincal.io.read_program`).
    q_start : ndarray, shape (n,), optional
        The joints the robot stands at before the first move, rad (default: the first joint target's).
    models : callable, optional
        ``models(tcp) -> (calibrated, nominal)``: the models for a TCP (3,) m the program sets with
        ``set_tcp`` (default: the targets after a ``set_tcp`` are refused).
    orientation : Robot, optional
        The model whose flange the corrected joints turn to each target's rotation (default: the calibrated
        model). Give the nominal model when the calibration measured no orientation (points, sockets, planes):
        the turns of the flange its parameters imply were never seen (:func:`compensate_poses`).
    measured : ndarray, shape (3,), optional
        With ``orientation``: the point the calibration measured, m in the flange frame (the calibrated file's
        tool point; default: each TCP itself). The calibrated model's position is trusted there, and a TCP beyond
        it is carried on by ``orientation``'s turn (:func:`kincal.compensate.poses.tcp_positions`).
    carry : ndarray, shape (3,), optional
        What of the calibration's move of the declared target point is carried over to the TCP, m, flange frame
        (:func:`kincal.compensate.tool_carry`, as :func:`kincal.compensate.command_models` adds it to a ``tcp``): a
        joint target's pose is the nominal model's at the calibrated model's TCP less it, for the TCP each
        target's models have (default: the nominal model's own TCP, the two TCPs' difference carried whole).

    Returns
    -------
    ProgramCompensation
        The replacement texts by target index, the corrected joints (K, n), and the refused targets.

    Examples
    --------
    A URScript program with a joint target, a pose target and a relative move (listed, never touched),
    written into a temporary folder, read, compensated for a perturbed UR5 and written again:

    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate_program
    >>> from kincal.io import read_program, write_program
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> text = ("def demo():\\n"
    ...         "  movej([0.3, -1.2, 1.5, -1.9, 1.2, 0.4], a=1.4, v=1.05)\\n"
    ...         "  movel(p[-0.551, -0.4952, 0.3974, 0.5627, 0.3079, -0.7644], a=1.2, v=0.25)\\n"
    ...         "  movel(pose_trans(get_actual_tcp_pose(), p[0, 0, 0.01, 0, 0, 0]))\\n"
    ...         "end\\n")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "demo.script")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path, "ur")
    ...     res = compensate_program(real, nominal, program)
    ...     write_program(os.path.join(folder, "out.script"), program, res.texts)
    ...     with open(os.path.join(folder, "out.script")) as f:
    ...         print(f.read(), end="")
    def demo():
      movej([0.29794..., -1.19963..., 1.50174..., -1.90109..., 1.20108..., 0.40139...], a=1.4, v=1.05)
      movel(p[-0.55178..., -0.49415..., 0.39652..., 0.56346..., 0.30603..., -0.76474...], a=1.2, v=0.25)
      movel(pose_trans(get_actual_tcp_pose(), p[0, 0, 0.01, 0, 0, 0]))
    end
    >>> res.problems, [line for line, _, _ in res.not_literal]
    ((), [4])
    >>> np.round(res.q, 3)
    array([[ 0.298, -1.2  ,  1.502, -1.901,  1.201,  0.401],
           [ 0.498, -1.   ,  1.302, -1.601,  1.001,  0.201]])
    """
    q_prev = (next((t.values for t in program.targets if t.kind == "joints" and t.values.size == model.n_joints
                    and not outside_limits(nominal, t.values)), None) if q_start is None
              else np.asarray(q_start, dtype=float))  # a refused joint target is no start
    values, refused, qs = {}, {}, np.full((len(program.targets), model.n_joints), np.nan)
    kept, tcps = [], np.full((len(program.targets), 3), np.nan)
    for k, t in enumerate(program.targets):
        tcp = program.in_force_of(t)
        pair = (model, nominal) if isinstance(tcp, tuple) else _for_tcp(models, tcp)
        found = _target(t, tcp, pair, q_prev, (orientation, measured), carry)
        if isinstance(found, str):
            refused[k] = found
            continue
        qs[k], q_prev, values[k] = found[:3]
        if not isinstance(pair, str):  # a pair that is why it is refused refuses its target (above)
            tcps[k] = pair[0].tool_point() if pair[0].has_tool_point else 0.0
        if len(found) > 3:  # a joint target kept as it is: nothing rewritten
            kept.append((t.line, t.move, found[3]))
            del values[k]
    alien = foreign(nominal, program, refused)
    if alien:  # nothing corrected for the wrong robot: the targets it reached are refused too
        refused.update({k: ALIEN for k in values})
        qs[list(values)] = tcps[list(values)] = np.nan
        values = {}
    texts = dict(zip(values, write_ur(program.text, [program.targets[k] for k in values], list(values.values()))))
    problems = tuple(f"{program.source}: line {program.targets[k].line} ({program.targets[k].move}"
                     f"{' ' + program.targets[k].variable if program.targets[k].variable else ''}): {why}; left as is"
                     for k, why in sorted(refused.items()))
    return ProgramCompensation(texts, qs, problems, program.not_literal, refused, tuple(kept), tcps, alien)


def foreign(robot: Robot, program: Program, refused: dict) -> str:
    """Why a program looks written for another robot, or '' when it does not: more than ``FOREIGN`` (half) of its
    literal targets are refused as :class:`Unreached` (beyond ``robot``'s reach or joint limits as written; in a
    language whose targets carry branch bits (:data:`kincal.io.branches.BITS`), on none of the branches they name).

    Parameters
    ----------
    robot : Robot
        The controller's (nominal) model the targets were tried on.
    program : Program
        The program read (:func:`kincal.io.read_program`).
    refused : dict of int to str
        Why each refused target was refused, by target index.

    Returns
    -------
    str
        The sentence, naming how many targets of how many and what to do; '' for half of them or fewer.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate.program import Unreached, foreign
    >>> from kincal.io.programs import Program
    >>> prog = Program("cell.mod", "", targets=(None, None, None), dialect="rapid")  # three targets (not read here)
    >>> foreign(kincal.load_robot("abb_irb120"), prog, {0: Unreached("out of reach"), 1: "no tool frame"})
    ''
    >>> print(foreign(kincal.load_robot("abb_irb120"), prog, {0: Unreached("a"), 1: Unreached("b")}))
    the program looks written for another robot: 2 of its 3 literal targets are out of abb_irb120's reach as
    written (beyond its reach or joint limits, or on none of its branches with the target's bits: more than
    half), so none is compensated (--skip-unreachable writes it as it was, each target marked): compensate it
    with the calibration of the robot it is written for (if it is this robot's, check the frames and units of its
    targets)
    """
    n, out = len(program.targets), sum(isinstance(why, Unreached) for why in refused.values())
    if not n or out <= FOREIGN * n:
        return ""
    bits = ", or on none of its branches with the target's bits" if program.dialect in BITS else ""  # URScript: none
    return (f"the program looks written for another robot: {out} of its {n} literal targets are out of "
            f"{robot.name}'s reach as written (beyond its reach or joint limits{bits}: more than half), so none is "
            f"compensated (--skip-unreachable writes it as it was, "
            f"each target marked): compensate it with the calibration of the robot it is written for (if it is "
            f"this robot's, check the frames and units of its targets)")


def _for_tcp(models: Models | None, tcp) -> tuple[Robot, Robot] | str:
    if isinstance(tcp, str):  # no one TCP is known there: why
        return tcp
    if tcp is None:
        return "the TCP is set from a variable (set_tcp of a non-literal); set it with a literal p[…]"
    if np.linalg.norm(tcp[:3]) > TCP_MAX:
        return (f"the TCP set_tcp sets is {np.linalg.norm(tcp[:3]):g} m from the flange: URScript's poses are in "
                f"metres (p[0, 0, 0.109, …] is 109 mm)")
    if models is None:
        return "the program sets its TCP (set_tcp) and no models were given for it"
    return models(tcp[:3])


def _target(t: Target, tcp, models, q_prev: np.ndarray | None, follow: tuple, carry: np.ndarray | None = None):
    """(corrected joints, nominal joints, the values to write: the joints, or the TCP pose as p[…] holds it) of one
    target, or why it is refused; ``follow``: the model whose flange turn is followed and the point the calibration
    measured (:func:`corrected`); ``carry``: what of the calibrated TCP's move is carried over (a joint target's pose
    is the nominal model's at the calibrated TCP less it: :func:`joint_goal_model`)."""
    if isinstance(models, str):
        return models
    model, nominal = models
    turn = np.eye(3) if isinstance(tcp, tuple) else rotvec_matrix(tcp[3:])  # the TCP's rotation on the flange
    if t.kind == "joints":
        if t.values.size != model.n_joints:
            return Unreached(f"{t.values.size} joint values for a {model.n_joints}-joint robot")
        outside = outside_limits(nominal, t.values)
        if outside:
            degrees = np.sum(np.abs(t.values) > 2 * np.pi) >= 2 and not outside_limits(nominal, np.radians(t.values))
            return Unreached(outside + (" (URScript's joints are in radians; these look like degrees)" if degrees
                                        else ""))
        q_nom = t.values
        nominal = joint_goal_model(model, nominal, carry)
        p, R, _, _ = nominal.pose_and_jacobian(q_nom[None])
    else:
        if q_prev is None:
            return ("a pose target with no joints to start the inverse kinematics from (no joint target before it "
                    "and no start joints given)")
        if np.linalg.norm(t.values[:3]) > POSE_MAX:
            return Unreached(f"the pose is {np.linalg.norm(t.values[:3]):g} m from the base: URScript's poses are "
                             f"in metres and radians")
        p, R = t.values[None, :3], (rotvec_matrix(t.values[3:]) @ turn.T)[None]
        found = controller_inverse(nominal, p, R, q_prev)
        if found is None:
            return Unreached("the nominal model does not reach this pose on any branch within the joint limits")
        q_nom = found
    q, why = corrected(model, p, R, q_nom, *follow)
    keep = kept_joints(model, nominal, q_nom, why) if t.kind == "joints" else ""
    if keep:
        return q_nom, q_nom, q_nom, keep
    if why:
        return why + singular(nominal, q_nom)
    if t.kind == "joints":
        return q, q_nom, q
    pf, Rf, _, _ = nominal.pose_and_jacobian(q[None])
    return q, q_nom, np.concatenate([pf[0], rotation_log(Rf @ turn)[0]])


def joint_goal_model(model: Robot, nominal: Robot, carry: np.ndarray | None) -> Robot:
    """The nominal model whose pose at a joint target is the intended one: its TCP the calibrated model's less
    ``carry`` (3,) m, what of the calibration's move of the point is the last link's error (a larger move is the
    target's mounting, on the nominal model too); ``nominal`` itself for ``carry`` None or a model without a TCP."""
    if carry is None or not model.has_tool_point:
        return nominal
    return nominal.with_tool_point(model.tool_point() - np.asarray(carry, dtype=float))


def outside_limits(robot: Robot, q: np.ndarray) -> str:
    """Why a joint target (n,) rad or m is refused before any correction: the first joint outside the robot's limits,
    with its value and the limits (deg or mm); '' when all are inside."""
    off = np.flatnonzero((q < robot.lower - 1e-12) | (q > robot.upper + 1e-12))
    if not off.size:
        return ""
    j = int(off[0])
    f, unit = (np.degrees(1.0), "°") if robot.joint_types[j] == "revolute" else (1e3, " mm")
    return (f"the target's own joints are outside the robot's limits: {robot.joint_names[j]} {q[j] * f:.3f}{unit} "
            f"(limits {robot.lower[j] * f:.3f}…{robot.upper[j] * f:.3f}{unit}): written for another robot, or in other "
            f"units")


def condition(robot: Robot, q: np.ndarray) -> float:
    """The condition number of ``robot``'s pose Jacobian (position rows in m, rotation rows in rad) at q (n,)."""
    _, _, Jp, Jw = robot.pose_and_jacobian(q[None])
    s = np.linalg.svd(np.concatenate([Jp[0], Jw[0]]), compute_uv=False)
    return float(s[0] / max(s[-1], 1e-300))


def singular(robot: Robot, q: np.ndarray) -> str:
    """A note when the arm is near a singularity at q (its pose Jacobian's condition number above SINGULAR):
    there the pose does not fix every joint, the usual cause of a correction that fails; else ''."""
    cond = condition(robot, q)
    return f" (the arm is at or near a singularity here: condition number {cond:.1e}; move the target off it)" \
        if cond > SINGULAR else ""


def kept_joints(model: Robot, nominal: Robot, q: np.ndarray, why: str) -> str:
    """Why a joint target q (n,) is kept as it is, or '' when it is not: its correction failed (``why``) at or near
    a singularity of the arm (a home pose with the wrist's axes in line), where no joints near q put ``model``'s
    TCP at ``nominal``'s pose; or q is at the singularity itself (SINGULAR_EXACT), where a correction that
    converges splits a turn between joints in line as round-off decides. The program's joints are what the
    robot should go to; the note says how far the calibrated TCP lands from the nominal one there."""
    cond = condition(nominal, q)
    if cond <= SINGULAR or (not why and cond <= SINGULAR_EXACT):
        return ""
    why = why or "at the singularity itself the pose does not fix how joints in line share a turn"
    miss = float(np.linalg.norm(model.forward(q[None])[0] - nominal.forward(q[None])[0]))
    return (f"a joint target at a singularity of the arm (condition number {cond:.1e}; {why}): its joints are kept, "
            f"and the TCP lands {miss * 1e3:.3f} mm from the nominal model's point there, as before calibration")


def corrected(model: Robot, p: np.ndarray, R: np.ndarray, q_nom: np.ndarray, orientation: Robot | None = None,
              measured: np.ndarray | None = None) -> tuple[np.ndarray, str]:
    """The joints (n,) at which ``model`` puts its tool point at p (1, 3) m with the flange (``orientation``'s, default
    ``model``'s) at R (1, 3, 3), by Newton from the nominal joints q_nom (n,), and why they are refused ('' when they
    are not): the correction did not converge, leaves the nominal branch (a joint moves more than its
    :func:`branch_tolerance`) or breaks a joint limit. With ``orientation``, the tool point is carried from the
    ``measured`` point (3,) m by its turn (:func:`solve_poses`)."""
    sol = solve_poses(model, p, R, q_nom[None], turned_as=orientation, measured=measured)
    q = sol.q[0]
    tol = branch_tolerance(model)
    return q, ("the correction did not converge" if not sol.converged[0] else
               "the corrected joints leave the nominal branch" if (np.abs(q - q_nom) > tol).any() else
               f"the corrected joints break the joint limits: {past_limits(model, q)}"
               if not model.within_limits(q[None])[0] else "")


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
