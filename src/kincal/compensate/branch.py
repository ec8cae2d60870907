"""Programs whose targets state their branch (KUKA S/T, ABB confdata, FANUC CONFIG, Yaskawa RCONF),
compensated on that branch.

A controller turns a Cartesian target into joints with its own (nominal) model, on the branch the
target's configuration bits name. For each literal target of such a program:

* a joint target q₀ means the pose the nominal model reaches there, at the measured point as the controller
  has it (the calibrated model's less what of the calibration's move of it is carried over to a TCP,
  ``carry``: the same (controller, physical) tool pair as a given tool's, :func:`tool_pair`); the corrected
  joints q reach that pose with the calibrated model's measured point (Newton from q₀) and are written as
  they are;
* a pose target T (the TCP in the program's base frame B, with the program's tool frame U) is turned
  into the controller's joints q₀: a nominal inverse-kinematics solution within the joint limits whose
  bits equal the target's (all targets together by Newton passes, each from the joints of the last
  target before it already solved; what they leave, one by one from spread starts with the whole turns
  the limits allow; a target without bits takes the branch nearest its predecessor's joints). The
  corrected joints q reach T on the calibrated model; the target is replaced by the filtered pose, the
  one the nominal model reaches at q, which the controller turns back into q.

The bits are derived again from q (the language's rule, :data:`kincal.io.branches.ROWS`): they must equal
the target's, else the target is refused with its line (as when the correction does not converge, leaves
the nominal branch or breaks a joint limit; at a singularity the refusal says so). A pose target of an
arm with more than six joints is refused (``REDUNDANT``: the controller's redundancy rule is not modelled);
its joint targets are compensated. Frames are the
program's own names (``Target.frames``): each must be given in ``frames`` (name -> 4x4 pose, m) unless the
language defines it as the identity (RAPID's tool0 and wobj0); a frame that is missing is refused, never
taken as the identity; where the program names none, the frames' ``default tool`` and ``default base``
are the ones in force. The written program is read again and every compensated target checked end to
end: the controller's joints of the text as written reach the intended pose on the calibrated model
(``CHECK_TOL``).
"""
from __future__ import annotations

import dataclasses
import itertools
from typing import Callable, Mapping, Sequence

import numpy as np

from .._collector import paused_collector
from ..io.programs import Program, dialects
from ..models.robot import Robot
from ..models.serial import SerialRobot
from ..models.wrapped import Wrapped
from ..models.transforms import rotation_log, rotvec_matrix
from ..ties import first_best
from .poses import solve_poses
from .commands import branch_tolerance, past_limits
from .taught import resolve_taught, tool_pair
from .program import (ALIEN, SEARCH, STARTS, ProgramCompensation, Unreached, foreign, kept_joints, outside_limits,
                      singular)

CHECK_TOL = 1e-9  # m and rad: a written target must reproduce its intended pose this closely
METRES_LOOK = 5.0  # mm: a pose target within this of its frame's origin in every coordinate looks written in metres
BIT_EDGE = np.radians(0.01)  # rad: a joint this near 0 sits on the edge of its sign bit (a pose's last decimals)
CHAIN = 512  # targets per Newton pass of the controller's joints (the next ones start from the joints found)
IDENTITY_FRAMES = {"rapid": (("tool0",), ("wobj0", "")), "krl": (("$nullframe",), ()),  # (tools, bases) a language
                   "inform": ((), ("robot",)), "fanuc": ((), ("uf 0",))}  # defines as the identity (RAPID: tool0 is
# the flange, wobj0 the world frame, and a move without \WObj is in wobj0; KRL: $TOOL = $NULLFRAME is the flange,
# while $BASE = $NULLFRAME is the world, given with $ROBROOT_C; INFORM: ROBOT coordinates, and BASE ones where no base
# axis moves the robot; FANUC: user frame 0 is the world frame)
REDUNDANT = ("a pose target of a redundant arm: the controller chooses the redundancy (the elbow's arm angle, "
             "KRL's E1 or RAPID's eax_a) by a rule kincal does not model, so the joints it would take are unknown; "
             "give joint targets (E6AXIS, jointtarget) to compensate")
PULSES_WHY = ("a PULSE position (encoder counts): turning it into joint angles needs each joint's pulses per degree "
              "(the controller's parameters): give pulses_per_degree on the robot file's joints")
Config = Callable[[Robot, np.ndarray], tuple]
Rows = Callable[[Robot, np.ndarray], list]


@paused_collector
def compensate_branches(model: Robot, nominal: Robot, program: Program, rows: Rows,
                        frames: Mapping[str, object] | None = None,
                        q_start: np.ndarray | None = None, orientation: Robot | None = None,
                        carry: np.ndarray | None = None) -> ProgramCompensation:
    """Compensate every literal target of a program on the branch it states (KUKA S/T, ABB confdata, ...).

    A joint target means the pose the nominal model reaches there (at the measured point less ``carry``, reached
    by the calibrated model's measured point: the tool pair of :func:`tool_pair`); a pose target means the TCP in the
    program's base and tool frames, reached by the controller on the branch its bits name (module
    docstring). Batched: the controller's joints of all targets are solved together, each from the start and
    then from its predecessor's joints, and only what that leaves is searched one by one. The replacement
    texts are read again and checked end to end (:func:`check_written`); a target that fails any check keeps
    its text and is named by line.

    Parameters
    ----------
    model : Robot
        The calibrated model (where the robot really goes), in the controller's world frame.
    nominal : Robot
        The controller's (nominal) model, same frame.
    program : Program
        The program read (:func:`kincal.io.read_program`), in a language whose targets state their branch.
    rows : callable
        ``rows(robot, q) -> bits per row`` for joints q (N, 6) rad, as the language writes them
        (:data:`kincal.io.ROWS`).
    frames : mapping of str to ndarray, str or TaughtFrame, optional
        The program's tool and base frames by name (4x4, m; a taught frame, :func:`resolve_taught`), beside
        those it declares itself (RAPID's tooldata and wobjdata; a given one wins). Where the program names
        none, ``"default tool"`` and ``"default base"`` are in force; a frame that is needed and missing
        refuses its targets (never taken as the identity).
    q_start : ndarray, shape (n,), optional
        The joints before the first move, rad (default: the first joint target's, else the zero pose: the
        bits choose the branch).
    orientation : Robot, optional
        The model whose flange the corrected joints turn to each target's rotation, in the end-to-end check too
        (default: the calibrated model). Give the nominal model when the calibration measured no orientation
        (points, sockets, planes): the turns of the flange its parameters imply were never seen.
    carry : ndarray, shape (3,), optional
        What of the calibration's move of the declared target point is carried over to the TCP, m, flange frame
        (:func:`kincal.compensate.tool_carry`; default zeros): added to the TCP (the origin) of each tool frame
        given by its values on the calibrated model only, as :func:`kincal.compensate.command_models` does for a
        ``tcp``, for the program's targets and a base taught with that tool alike (a taught tool's physical frame is
        the calibrated model's own: :func:`kincal.compensate.taught.tool_pair`); a joint target's TCP is the
        measured point, on the nominal model where the calibrated one has it less ``carry``.

    Returns
    -------
    ProgramCompensation
        The replacement texts by target index, the corrected joints (K, n), and the refused targets.

    Examples
    --------
    A KRL module with an axis target and a Cartesian target (mm, deg, its S and T), written into a temporary
    folder and read:

    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate_branches
    >>> from kincal.io import ROWS, read_program
    >>> nominal = kincal.load_robot("kuka_kr6r900sixx")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> text = ("DEF demo()\\n"
    ...         "PTP {A1 20, A2 -70, A3 80, A4 10, A5 40, A6 5}\\n"
    ...         "LIN {X 609.5, Y -231.3, Z 728.6, A -29.83, B 49.15, C -20.16, S 2, T 2}\\n"
    ...         "END\\n")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "demo.src")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path, "krl")
    >>> [(t.line, t.kind, t.config) for t in program.targets]
    [(2, 'joints', ()), (3, 'pose', (2, 2))]

    The module names no tool or base: its pose target is refused until the frames in force are given.

    >>> compensate_branches(real, nominal, program, ROWS["krl"]).refused
    {1: "the program names no tool frame here: give the one in force (frames: 'default tool')"}
    >>> frames = {"default tool": np.eye(4), "default base": np.eye(4)}
    >>> res = compensate_branches(real, nominal, program, ROWS["krl"], frames)
    >>> res.problems
    ()
    >>> print(program.with_targets(res.texts), end="")
    DEF demo()
    PTP {A1 19.8158..., A2 -70.0937..., A3 80.1103..., A4 10.2834..., A5 40.0511..., A6 4.6542...}
    LIN {X 609.4226..., Y -229.3217..., Z 728.7163..., A -29.9386..., B 49.1673..., C -20.2546..., S 2, T 2}
    END
    >>> np.round(np.degrees(res.q), 2)
    array([[ 19.82, -70.09,  80.11,  10.28,  40.05,   4.65],
           [ 19.81, -70.1 ,  80.11,  10.29,  40.05,   4.65]])
    """
    dialect = dialects()[program.dialect]
    measured = model.tool_point() if model.has_tool_point else np.zeros(3)  # the point the calibration measured
    model, nominal = model.with_tool_point(np.zeros(3)), nominal.with_tool_point(np.zeros(3))  # flange poses
    frames = resolve_taught({**dialect.spellings(dialect.frames(program)), **dialect.spellings(frames or {})}, nominal,
                            model.with_tool_point(measured), orientation, carry)  # the program's frames, unless given
    scale = pulse_scale(nominal)
    work = in_joints(program, scale)  # PULSE positions as joint targets (rad)
    q0 = (next((t.values for t in work.targets if t.kind == "joints"), np.clip(0.0, model.lower, model.upper))
          if q_start is None else np.asarray(q_start, dtype=float))
    carry = np.zeros(3) if carry is None else np.asarray(carry, dtype=float)
    point = tool_pair(_poses((measured - carry)[None], np.eye(3)[None])[0], carry)  # a joint target's TCP
    goals, tools, refused = _goals(nominal, work, frames, carry=carry, point=point)
    held, _, _ = _goals(nominal, work, frames, side=0, carry=carry, point=point)  # as the controller holds them
    q_nom = _controller_joints(nominal, work, held, rows, q0, refused)
    tcp_goals = _at_tcp(goals, tools)
    kept: dict[int, str] = {}
    qs = _corrected_all(model, nominal, work, (tcp_goals, tools), q_nom, rows, (refused, kept), (orientation, measured))
    values = _written(nominal, work.targets, qs, tools, [k for k in range(len(qs)) if k not in refused | kept])
    values = {k: np.round(v * scale) if program.targets[k].kind == "pulses" else v for k, v in values.items()}
    texts = dict(zip(values, dialect.write(program.text, [program.targets[k] for k in values], list(values.values()))))
    for k, why in check_written(model, nominal, program, texts, qs, rows, frames, tcp_goals, scale,
                                orientation, measured).items():
        texts.pop(k)
        refused[k] = why
        qs[k] = np.nan  # ProgramCompensation.q: NaN where refused, as the other refusals
    alien = foreign(nominal, program, refused)
    if alien:  # nothing corrected for the wrong robot: the targets it reached are refused too
        refused.update({k: ALIEN for k in texts})
        qs[list(texts)], texts = np.nan, {}
    problems = tuple(f"{program.source}: line {program.targets[k].line} ({program.targets[k].move}"
                     f"{' ' + program.targets[k].variable if program.targets[k].variable else ''}): {why}; left as is"
                     for k, why in sorted(refused.items()))
    tcp = np.where(np.isfinite(qs[:, :1]), tcp_goals[2], np.nan)
    tcp[sorted(refused)] = np.nan  # as for ProgramCompensation.q: where the robot goes
    return ProgramCompensation(texts, qs, problems, program.not_literal, refused, tuple(
        (program.targets[k].line, program.targets[k].move, why) for k, why in sorted(kept.items())), tcp, alien)


def _goals(nominal: Robot, program: Program, frames: Mapping[str, object], side: int = 1,
           carry: np.ndarray | None = None, point: tuple | None = None):
    """Each target's flange pose (p (N, 3), R (N, 3, 3); NaN where refused), its (tool, base) frames (each a
    (controller, physical) pair, a tool's physical TCP moved by ``carry`` (3,) m unless taught: :func:`tool_pair`)
    and the refusals so far (index -> why): a target's flange pose is B·T·U⁻¹ with the ``side`` of its frames (1:
    the physical ones, what the program means; 0: the controller's, what it turns a written target with), T a pose
    target's pose, or a joint target's TCP pose on the nominal model there (its tool ``point``, the measured point's
    (controller, physical) pair, default the flange; its base the identity); all at once."""
    n = len(program.targets)
    T = np.full((n, 4, 4), np.nan)
    tools: list = [None] * n
    refused: dict[int, str] = {}
    given = {k.lower(): v if isinstance(v, (str, tuple)) else np.asarray(v, dtype=float) for k, v in frames.items()}
    known: dict[tuple[str, str], tuple | str] = {}
    no_scale = any(t.kind == "pulses" for t in program.targets) and pulse_scale(nominal) is None
    for k, t in enumerate(program.targets):
        if t.kind == "pulses":  # what in_joints could not turn into joints
            refused[k] = (PULSES_WHY if no_scale else
                          Unreached(f"{t.values.size} pulse counts for a {nominal.n_joints}-joint robot"))
            continue
        if t.kind == "joints":
            if t.values.size != nominal.n_joints:
                refused[k] = Unreached(f"{t.values.size} joint values for a {nominal.n_joints}-joint robot")
            elif outside_limits(nominal, t.values):
                refused[k] = Unreached(outside_limits(nominal, t.values))
            continue
        if nominal.n_joints > 6:
            refused[k] = REDUNDANT
            continue
        if isinstance(program.in_force_of(t), str):  # the program's flow leaves no one tool or base here
            refused[k] = program.in_force_of(t)
            continue
        if t.frames not in known:
            known[t.frames] = _frames(program.dialect, t.frames, given, carry)
        found = known[t.frames]
        if isinstance(found, str):
            refused[k] = found
        else:
            tools[k] = found
    poses = [k for k in range(n) if tools[k] is not None]
    if poses:
        v = np.array([program.targets[k].values[:6] for k in poses])
        T[poses] = _poses(v[:, :3], rotvec_matrix(v[:, 3:6]))
    ok = [k for k, t in enumerate(program.targets) if t.kind == "joints" and k not in refused]
    if ok:
        pf, Rf, _, _ = nominal.pose_and_jacobian(np.array([program.targets[k].values for k in ok]))
        T[ok] = _poses(pf, Rf) @ (np.eye(4) if point is None else point[0])
        tools = [(point or (np.eye(4), np.eye(4)), (np.eye(4), np.eye(4))) if k in ok else t
                 for k, t in enumerate(tools)]
    have = [k for k in range(n) if tools[k] is not None]
    p, R = np.full((n, 3), np.nan), np.full((n, 3, 3), np.nan)
    if have:
        F = np.array([tools[k][1][side] for k in have]) @ T[have] \
            @ np.linalg.inv(np.array([tools[k][0][side] for k in have]))
        p[have], R[have] = F[:, :3, 3], F[:, :3, :3]
    return (p, R), tools, refused


def _controller_joints(nominal: Robot, program: Program, goals, rows: Rows, q0: np.ndarray,
                       refused: dict[int, str]) -> np.ndarray:
    """The controller's joints (N, n) of every target (NaN where refused; refusals added): joint targets as
    written; pose targets by batched Newton passes, each from the joints of the last target before it that is
    solved (q0 before any), kept when its bits are the target's (without bits: only from its predecessor's
    joints, the nearest branch); a pass takes the first ``CHAIN`` targets with a start not tried yet, in the
    program's order, so the next ones start from joints near theirs; where no target has a start left to try,
    the first target left is searched alone (:func:`controller_inverse`), and the passes go on from it."""
    p, R = goals
    targets = program.targets
    q_nom = np.full((len(targets), nominal.n_joints), np.nan)
    for k, t in enumerate(targets):
        if t.kind == "joints" and k not in refused:
            q_nom[k] = t.values
    pending = [k for k, t in enumerate(targets) if t.kind != "joints" and k not in refused]
    tried: dict[int, int] = {}  # target -> the target whose joints it last started from (-1: q0)
    while pending:
        starts = _starts(q_nom, pending, tried, targets)
        if starts:
            _pass(nominal, program, goals, rows, q_nom, starts, q0)
            tried.update(starts)
            pending = np.array(pending)[np.isnan(q_nom[pending, 0])].tolist()
        else:  # no start left to try: the first one left, alone
            k = pending.pop(0)
            near = _last_solved(q_nom, k)
            found = controller_inverse(nominal, p[k][None], R[k][None], q0 if near < 0 else q_nom[near],
                                       targets[k].config, _single(rows))
            if isinstance(found, str):
                refused[k] = (Unreached if isinstance(found, Unreached) else str)(found + _in_metres(targets[k]))
            else:
                q_nom[k] = found
    return q_nom


def _in_metres(target) -> str:
    """A hint when a pose target the nominal model does not reach is written as if in metres: every coordinate
    within ``METRES_LOOK`` of its frame's origin (a vendor's positions are in mm); else ''."""
    if target.kind != "pose" or np.abs(target.values[:3]).max() * 1e3 > METRES_LOOK:
        return ""
    return (f"; its coordinates are all within {METRES_LOOK:g} mm of its frame's origin "
            f"({', '.join(f'{v * 1e3:g}' for v in target.values[:3])} mm): written in metres? This language's "
            f"positions are in mm")


def _last_solved(q_nom: np.ndarray, k: int) -> int:
    """The last target before k whose controller joints are known (-1: none)."""
    known = np.flatnonzero(~np.isnan(q_nom[:k, 0]))
    return int(known[-1]) if known.size else -1


def _starts(q_nom: np.ndarray, pending: list[int], tried: dict[int, int], targets) -> dict[int, int]:
    """For the first CHAIN pending targets that have one, a start not tried yet: the last solved target before
    it; only the first pending one starts from q0 (-1) while none before it is solved (the others wait for its
    joints: a start nearer them); a target without bits starts only from its immediate predecessor (the
    nearest branch is the controller's)."""
    solved = np.where(~np.isnan(q_nom[:, 0]), np.arange(len(q_nom)), -1)
    last = np.concatenate([[-1], np.maximum.accumulate(solved)[:-1]])  # the last solved before each target
    out = {}
    for k in pending:
        j = int(last[k])
        if tried.get(k) != j and (j == k - 1 or (j < 0 and k == pending[0]) or (targets[k].config and j >= 0)):
            out[k] = j
            if len(out) == CHAIN:
                break
    return out


def _pass(nominal: Robot, program: Program, goals, rows: Rows, q_nom: np.ndarray, starts: dict[int, int],
          q0: np.ndarray) -> None:
    """One batched Newton pass of the controller's joints from the given starts; a solution within the joint
    limits is kept (in q_nom) when its bits are the target's (any, for a target without bits)."""
    ks = np.array(sorted(starts))
    q_start = np.array([q0 if starts[k] < 0 else q_nom[starts[k]] for k in ks])
    sol = solve_poses(nominal, goals[0][ks], goals[1][ks], q_start, max_iter=SEARCH[0], max_travel=SEARCH[1])
    fine = sol.converged & nominal.within_limits(sol.q)
    bits = rows(nominal, sol.q[fine]) if fine.any() else []
    for k, q, b in zip(ks[fine], sol.q[fine], bits):
        config = tuple(program.targets[k].config)
        if not config or tuple(b) == config:
            q_nom[k] = q


def _at_tcp(goals, tools: list):
    """The goals (flange poses p (N, 3), R (N, 3, 3)) with the TCP point of each target's physical tool: p (N, 3), R
    and the calibrated model's TCP in the flange frame (N, 3) m: the physical tool's origin (a given tool's moved by
    the carry, :func:`tool_pair`; a joint target's, the point the calibration measured). Where the flange is turned
    as another model's (``orientation``), the calibrated model's position is trusted at the measured point, not at
    the TCP nor the flange: the TCP is that point carried on by ``orientation``'s turn
    (:func:`kincal.compensate.poses.tcp_positions`), as the taught frames take it."""
    p, R = goals
    lever = np.array([np.zeros(3) if t is None else t[0][1][:3, 3] for t in tools]).reshape(-1, 3)
    return p + np.einsum("nij,nj->ni", R, lever), R, lever


def _corrected_all(model: Robot, nominal: Robot, program: Program, aims, q_nom: np.ndarray, rows: Rows,
                   out: tuple[dict[int, str], dict[int, str]], turn: tuple = (None, None)) -> np.ndarray:
    """The corrected joints (N, n) of every target not refused (NaN elsewhere; refusals added to ``out``'s first
    dict): Newton on the calibrated model from the controller's joints (``aims``: the goals of :func:`_at_tcp` for
    the TCP, and each target's (tool, base) pairs of :func:`_goals`; ``turn``: the model whose flange turn is
    followed and the point the calibration measured, :func:`_solve_levers`), together; refused where it did not converge, left the nominal branch,
    broke a joint limit or changed the target's bits (each named, with a singularity's condition), except a joint
    target at a singularity: kept as it is (its joints; why in ``out``'s second dict, :func:`kept_joints`)."""
    (goals, tools), (refused, kept) = aims, out
    qs = np.full_like(q_nom, np.nan)
    idx = np.array([k for k in range(len(q_nom)) if k not in refused], dtype=int)
    if not idx.size:
        return qs
    q, converged = _solve_levers(model, [g[idx] for g in goals], q_nom[idx], *turn)
    tol = branch_tolerance(model)
    off = (np.abs(q - q_nom[idx]) > tol).any(axis=1)
    outside = ~model.within_limits(q)
    bits = rows(model, np.where(np.isfinite(q), q, 0.0))
    for i, k in enumerate(idx):
        config = tuple(program.targets[k].config)
        why = ("the correction did not converge" if not converged[i] else
               "the corrected joints leave the nominal branch" if off[i] else
               f"the corrected joints break the joint limits: {past_limits(model, q[i])}" if outside[i] else
               f"the corrected joints' configuration bits {tuple(bits[i])} differ from the target's {config}"
               + _crossed(model, q_nom[k], q[i]) if config and tuple(bits[i]) != config else "")
        tcp = tools[k][0]  # a joint target's: the measured point, where each model has it (controller, physical)
        keep = kept_joints(model.with_tool_point(tcp[1][:3, 3]), nominal.with_tool_point(tcp[0][:3, 3]), q_nom[k],
                           why) if program.targets[k].kind == "joints" else ""
        if keep:
            kept[int(k)], qs[k] = keep, q_nom[k]
        elif why:
            refused[int(k)] = why + singular(nominal, q_nom[k])
        else:
            qs[k] = q[i]
    return qs


def _crossed(robot: Robot, q_nom: np.ndarray, q: np.ndarray) -> str:
    """The joints the correction moves across 0 (the edge of a sign bit), named with both angles; '' for none."""
    moved = [j for j in range(len(q)) if robot.joint_types[j] == "revolute" and np.sign(q[j]) != np.sign(q_nom[j])]
    return "".join(f" ({robot.joint_names[j]} moves from {np.degrees(q_nom[j]):+.3f}° to {np.degrees(q[j]):+.3f}°, "
                   f"across 0: a joint taught at 0 whose sign bit the correction changes; give the target as an axis "
                   f"position)" for j in moved[:1])


def _solve_levers(model: Robot, goals, q0: np.ndarray, orientation: Robot | None,
                  measured: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The commands (N, n) and which converged (N,) of :func:`solve_poses` on goals (TCP points p (N, 3) m, flange
    rotations R (N, 3, 3), TCPs in the flange frame (N, 3) m) from q0 (N, n): one solve per distinct TCP; the flange
    turned as ``orientation``'s, the calibrated position trusted at the ``measured`` point (3,) m, flange frame."""
    p, R, lever = goals
    q, converged = np.full_like(q0, np.nan), np.zeros(len(q0), bool)
    _, which = np.unique(lever, axis=0, return_inverse=True)
    for g in range(int(which.max()) + 1):
        at = np.flatnonzero(which.reshape(-1) == g)
        sol = solve_poses(model.with_tool_point(lever[at[0]]), p[at], R[at], q0[at], turned_as=orientation,
                          measured=measured)
        q[at], converged[at] = sol.q, sol.converged
    return q, converged


def _written(nominal: Robot, targets, qs: np.ndarray, tools: list, ks: list[int]) -> dict[int, np.ndarray]:
    """The new SI values of the targets ks: the corrected joints, or the pose the nominal model reaches there in
    the program's frames as the controller holds them (the filtered pose, which the controller turns back into
    them); all at once."""
    out = {k: qs[k] for k in ks if targets[k].kind == "joints"}
    poses = [k for k in ks if targets[k].kind != "joints"]
    if poses:
        pf, Rf, _, _ = nominal.pose_and_jacobian(qs[poses])
        T = np.linalg.inv(np.array([tools[k][1][0] for k in poses])) @ _poses(pf, Rf) \
            @ np.array([tools[k][0][0] for k in poses])  # the controller's frames
        rot = rotation_log(T[:, :3, :3])
        out.update({k: np.concatenate([x[:3, 3], r]) for k, x, r in zip(poses, T, rot)})
    return out


def _single(rows: Rows) -> Config:
    """The bits of one joint vector, from the rule for rows."""
    return lambda robot, q: tuple(rows(robot, np.asarray(q, dtype=float)[None])[0])


def _frames(dialect: str, names: tuple[str, str], given: Mapping[str, object],
            carry: np.ndarray | None = None) -> tuple[tuple, tuple] | str:
    """The tool and base frames of a target naming ``names`` (any case; ``given`` by lower-case name), each a
    (controller, physical) pair of 4x4 frames (a base: the same frame twice unless it was taught; a tool: its TCP
    moved by ``carry`` (3,) m on the calibrated model unless it was taught, :func:`tool_pair`), or why they are
    not known."""
    out = []
    for what, name, identity in zip(("tool", "base"), names, IDENTITY_FRAMES.get(dialect, ((), ()))):
        key = name.lower() or f"default {what}"  # the frame in force where the program names none
        found = np.eye(4) if name.lower() in identity else given.get(key)
        if isinstance(found, str):
            return f"its {what} frame {name!r} is not known: {found}"
        if found is None:
            return (f"its {what} frame {name!r} is not given (give it with the frames; it is not taken as the "
                    f"identity)" if name else f"the program names no {what} frame here: give the one in force "
                    f"(frames: 'default {what}')")
        out.append(tool_pair(found, carry) if what == "tool" else found if isinstance(found, tuple) else (found, found))
    return out[0], out[1]


def controller_inverse(robot: Robot, p: np.ndarray, R: np.ndarray, near: np.ndarray, config: tuple,
                       config_of: Config) -> np.ndarray | str:
    """The joints (n,) a controller moving with ``robot`` takes for the tool point at p (1, 3) m with the
    flange at R (1, 3, 3) on the branch ``config`` (all branches for ()): of the solutions within the joint
    limits whose bits equal it, the one nearest ``near`` (ties: the first in the order found); or why none (an
    :class:`Unreached` unless a joint of the pose sits on the edge of its sign bit: a rounding, not the reach)."""
    cand: list[np.ndarray] = []
    reached: list[np.ndarray] = []
    for starts in (near[None], robot.sample_joints(STARTS, seed=0)):  # the spread starts only when needed
        sol = solve_poses(robot, np.repeat(p, len(starts), 0), np.repeat(R, len(starts), 0), starts,
                          max_iter=SEARCH[0], max_travel=SEARCH[1])
        every = [c for q in sol.q[sol.converged] for c in _turns(robot, q)]
        reached += every
        cand += [c for c in every if not config or tuple(config_of(robot, c)) == tuple(config)]
        if cand:
            break
    if not cand:
        return (_at_bit_edge(robot, reached, tuple(config), config_of) or Unreached(  # a bit's edge: a rounding
                f"the nominal model reaches this pose, but on no branch with the target's bits {tuple(config)} "
                f"within the joint limits") if reached else Unreached("the nominal model does not reach this pose "
                                                                      "within the joint limits (out of reach, or the "
                                                                      "wrong robot or frames)"))
    c = np.array(cand)
    return c[first_best(np.linalg.norm(c - near, axis=1), maximize=False)]


def _at_bit_edge(robot: Robot, reached: list[np.ndarray], config: tuple, config_of: Config) -> str:
    """Why a reached pose has none of the target's bits when a joint sits within BIT_EDGE of 0, the edge of its sign
    bit, and the bits of its mirror (−q) are the target's: the pose was written to fewer decimals than the
    controller keeps, or taught at 0; '' otherwise."""
    for q in reached:
        for j in np.flatnonzero(np.abs(q) < BIT_EDGE):
            mirrored = q.copy()
            mirrored[j] = -q[j]
            if robot.within_limits(mirrored[None])[0] and tuple(config_of(robot, mirrored)) == config:
                return (f"the pose puts {robot.joint_names[j]} at {np.degrees(q[j]):+.2e}°, on the other side of 0 "
                        f"from what the target's bits {config} say (a joint at 0 taught, or a pose written to fewer "
                        f"decimals than the controller keeps): give it as an axis position, or with more decimals")
    return ""


def _turns(robot: Robot, q: np.ndarray) -> list[np.ndarray]:
    """q with every combination of whole turns of its revolute joints that stays within the limits."""
    options = [[q[j] + 2 * np.pi * k for k in (0, -1, 1) if robot.lower[j] <= q[j] + 2 * np.pi * k <= robot.upper[j]]
               if periodic else ([q[j]] if robot.lower[j] <= q[j] <= robot.upper[j] else [])
               for j, periodic in enumerate(robot.periodic)]
    return [np.array(c) for c in itertools.product(*options)]


def check_written(model: Robot, nominal: Robot, program: Program, texts: dict, qs: np.ndarray, rows: Rows,
                  frames: Mapping[str, object], intended, scale: np.ndarray | None = None,
                  orientation: Robot | None = None, measured: np.ndarray | None = None) -> dict[int, str]:
    """The compensated targets whose text, read again, does not bring the robot where the program meant, and
    why: a written pose target's controller joints (Newton on the nominal model from the corrected joints, on
    the target's bits) and a written joint target's joints must put the calibrated model's TCP (carried from the
    ``measured`` point (3,) m by ``orientation``'s turn, when given: :func:`_misses`) on the intended
    point and its flange (``orientation``'s, when given) on the intended rotation (``intended``: TCP points
    (N, 3) m, flange rotations (N, 3, 3) and TCPs in the flange (N, 3) m of every target, from :func:`_at_tcp`)
    to ``CHECK_TOL`` and what rounding to the controller's step moves them (:func:`_rounding`); a PULSE
    position's counts (``scale``: pulses per rad or m) must be the corrected joints' nearest, and then miss by no
    more than half a pulse on every joint moves the TCP. All together."""
    if not texts:
        return {}
    model, nominal = model.with_tool_point(np.zeros(3)), nominal.with_tool_point(np.zeros(3))  # flange poses
    again = in_joints(dialects()[program.dialect].parse(program.source, program.with_targets(texts)), scale)
    ks = sorted(texts)
    work = in_joints(program, scale).targets
    old = [work[k] for k in ks]
    goals = [g[ks] for g in intended]
    new = dataclasses.replace(program, targets=tuple(again.targets[k] for k in ks))
    written, _, _ = _goals(nominal, new, frames, side=0)  # the controller turns the written text with its frames
    poses = np.array([t.kind != "joints" for t in old])
    q = np.array([again.targets[k].values if t.kind == "joints" else qs[k] for k, t in zip(ks, old)])
    bad: dict[int, str] = {}
    if poses.any():
        sol = solve_poses(nominal, written[0][poses], written[1][poses], q[poses])
        q[poses] = sol.q
        bits = rows(nominal, np.where(np.isfinite(sol.q), sol.q, 0.0))
        for i, k in enumerate(np.array(ks)[poses]):
            config = tuple(program.targets[k].config)
            if not sol.converged[i] or (config and tuple(bits[i]) != config):
                bad[int(k)] = "the written target does not come back on its branch when read again"
    miss, turn, Jp, Jw = _misses(model, orientation or model, q, goals, measured)
    pulsed = np.array([program.targets[k].kind == "pulses" for k in ks])
    kinds = [program.targets[k].kind for k in ks]
    tol_p, tol_r = _rounding(nominal, kinds, Jp, Jw, goals[2], scale, dialects()[program.dialect].step)
    for i, (k, m, r) in enumerate(zip(ks, miss, turn)):
        if pulsed[i] and not np.array_equal(np.round(q[i] * scale), np.round(qs[k] * scale)):
            bad[k] = "the written pulse counts are not the corrected joints' nearest (checked as read again)"
        if k not in bad and not (m <= tol_p[i] and r <= tol_r[i]):
            bad[k] = (f"the written target misses by {m * 1e3:.2e} mm / {r:.2e} rad (checked as read again)"
                      + singular(nominal, q[i]))
    return bad


def _rounding(robot: Robot, kinds: Sequence[str], Jp: np.ndarray, Jw: np.ndarray, lever: np.ndarray,
              scale: np.ndarray | None, step: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """What a written target may miss by (m, rad; each (N,)) for the numbers' rounding, beyond ``CHECK_TOL``: half
    a pulse (``scale``: pulses per rad or m) or the controller's ``step`` (m, rad; a number is written to within
    it, to half of it in the controller's own number of decimals) of each joint through the TCP's and the
    flange's Jacobians Jp, Jw (N, 3, n); for a pose, a step on each of X, Y, Z (√3 of it) and on each of its
    three angles (3 of it, also swinging the TCP at ``lever`` (N, 3) m from the flange)."""
    length, angle = step
    prismatic = np.array([t == "prismatic" for t in robot.joint_types])
    each = np.where(prismatic, length, angle)
    pulse = each if scale is None else 0.5 / np.abs(scale)
    kind = np.asarray(kinds)
    joint = np.where((kind == "pulses")[:, None], pulse, each)  # (N, n): each joint's rounding, by the target's kind
    pose = kind == "pose"
    tol_p = CHECK_TOL + np.where(pose, 1.01 * (np.sqrt(3) * length + 3 * angle * np.linalg.norm(lever, axis=1)),
                                 np.einsum("nj,nj->n", np.linalg.norm(Jp, axis=1), joint))
    tol_r = CHECK_TOL + np.where(pose, 1.01 * 3 * angle, np.einsum("nj,nj->n", np.linalg.norm(Jw, axis=1), joint))
    return tol_p, tol_r  # all targets at once (a program of 10^4 targets)


def _misses(model: Robot, orientation: Robot, q: np.ndarray, goals, measured: np.ndarray | None = None):
    """How far ``model``'s TCP (m) and ``orientation``'s flange (rad) stand from goals (TCP points (N, 3), flange
    rotations (N, 3, 3), TCPs in the flange (N, 3)) at q (N, n), each (N,), with the TCP's and the flange's joint
    Jacobians (N, 3, n). Where ``orientation`` is another model, the TCP is ``model``'s ``measured`` point (3,) m
    (default the TCP itself) carried on by ``orientation``'s turn (:func:`kincal.compensate.poses.tcp_positions`)."""
    p, R, lever = goals
    pm, Rm, Jp, Jw = model.with_tool_point(np.zeros(3)).pose_and_jacobian(q)
    if orientation is not model:  # from the measured point on, the arm turns with the other model's flange
        point = lever if measured is None else np.broadcast_to(np.asarray(measured, dtype=float), lever.shape)
        at = np.einsum("nij,nj->ni", Rm, point)
        pm, Jp = pm + at, Jp + np.cross(np.swapaxes(Jw, 1, 2), at[:, None, :]).swapaxes(1, 2)
        _, Rm, _, Jw = orientation.with_tool_point(np.zeros(3)).pose_and_jacobian(q)
        lever = lever - point
    arm = np.einsum("nij,nj->ni", Rm, lever)  # the TCP from the flange (or the measured point), in the world
    Jp = Jp + np.cross(np.swapaxes(Jw, 1, 2), arm[:, None, :]).swapaxes(1, 2)  # v = v_point + ω × arm
    miss = np.linalg.norm(pm + arm - p, axis=1)
    return miss, np.linalg.norm(rotation_log(Rm @ np.swapaxes(R, 1, 2)), axis=1), Jp, Jw


def pulse_scale(robot: Robot) -> np.ndarray | None:
    """Pulses per rad (per m for a prismatic joint) of each joint: the robot file's pulses_per_degree; None unless
    every joint gives it (a chain robot's, through the terms wrapped around it)."""
    while isinstance(robot, Wrapped) and robot.inner.joint_names == robot.joint_names:
        robot = robot.inner
    if not isinstance(robot, SerialRobot) or not all(j.pulses for j in robot.moving):
        return None
    return np.array([j.pulses * (180 / np.pi if j.type == "revolute" else 1e3) for j in robot.moving])


def in_joints(program: Program, scale: np.ndarray | None) -> Program:
    """The program with each PULSE target (counts) as a joint target (rad or m) where ``scale`` (pulses per rad
    or m) has its joints; the others as they are (a PULSE target left is refused with the reason)."""
    if scale is None or not any(t.kind == "pulses" for t in program.targets):
        return program
    return dataclasses.replace(program, targets=tuple(
        dataclasses.replace(t, kind="joints", values=t.values / scale)
        if t.kind == "pulses" and t.values.size == scale.size else t for t in program.targets))


def _poses(p: np.ndarray, R: np.ndarray) -> np.ndarray:
    """4x4 poses (N, 4, 4) of positions p (N, 3) and rotations R (N, 3, 3)."""
    T = np.zeros((len(p), 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, p, 1.0
    return T
