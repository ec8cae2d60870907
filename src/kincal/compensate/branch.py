"""Programs whose targets state their branch (KUKA S/T, ABB confdata, FANUC CONFIG, Yaskawa RCONF),
compensated on that branch.

A controller turns a Cartesian target into joints with its own (nominal) model, on the branch the
target's configuration bits name. For each literal target of such a program:

* a joint target q₀ means the pose the nominal model reaches there; the corrected joints q reach that
  pose on the calibrated model (Newton from q₀) and are written as they are;
* a pose target T (the TCP in the program's base frame B, with the program's tool frame U) is turned
  into the controller's joints q₀: of the nominal model's inverse-kinematics solutions within the joint
  limits (Newton from the previous target's joints, then from spread starts, each with the whole turns
  the limits allow), those whose bits equal the target's, the one nearest the previous joints. The
  corrected joints q reach T on the calibrated model; the target is replaced by the filtered pose, the
  one the nominal model reaches at q, which the controller turns back into q.

The bits are derived again from q (``config_of``): they must equal the target's, else the target is
refused with its line (as when the correction does not converge, leaves the nominal branch or breaks
a joint limit). Frames are the program's own names (``Target.frames``): each must be given in
``frames`` (name -> 4x4 pose, m) unless the language defines it as the identity (RAPID's tool0 and
wobj0); a frame that is missing is refused, never taken as the identity; where the program names none, the frames'
``default tool`` and ``default base`` are the ones in force. The written program is read
again and every compensated target checked end to end: the controller's joints of the text as written
reach the intended pose on the calibrated model (``CHECK_TOL``).
"""
from __future__ import annotations

import itertools
from typing import Callable, Mapping

import numpy as np

from ..io.programs import Program, Target, dialects
from ..models.robot import Robot
from ..models.transforms import rotation_log, rotvec_matrix
from ..ties import first_best
from .poses import solve_poses
from .program import SEARCH, STARTS, ProgramCompensation, corrected

CHECK_TOL = 1e-9  # m and rad: a written target must reproduce its intended pose this closely
SINGULAR = 1e3  # condition number of the pose Jacobian (m, rad) beyond which a failed correction is named as such
IDENTITY_FRAMES = {"rapid": (("tool0",), ("wobj0", ""))}  # (tools, bases) a language defines as the identity
# (RAPID: tool0 is the flange, wobj0 the world frame, and a move without \WObj is in wobj0)
Config = Callable[[Robot, np.ndarray], tuple]


def compensate_branches(model: Robot, nominal: Robot, program: Program, config_of: Config,
                        frames: Mapping[str, np.ndarray] | None = None,
                        q_start: np.ndarray | None = None) -> ProgramCompensation:
    """Compensate every literal target of ``program`` on the branch it states (module docstring);
    ``config_of(robot, q) -> bits`` as the language writes them (:data:`kincal.io.branches.BITS`); ``frames``:
    the program's tool and base frames by name (4x4, m), beside those it declares itself (RAPID's tooldata and
    wobjdata; a given one wins); ``q_start``: the joints before the first move (default: the first joint
    target's, else the zero pose: the bits choose the branch). The replacement texts are checked end to end
    (:func:`check_written`)."""
    dialect = dialects()[program.dialect]
    frames = {**dialect.frames(program), **(frames or {})}  # the program's declared frames, unless given
    model, nominal = model.with_tool_point(np.zeros(3)), nominal.with_tool_point(np.zeros(3))  # flange poses
    q_prev = (next((t.values for t in program.targets if t.kind == "joints"), np.clip(0.0, model.lower, model.upper))
              if q_start is None else np.asarray(q_start, dtype=float))
    texts, refused, qs = {}, {}, np.full((len(program.targets), model.n_joints), np.nan)
    for k, t in enumerate(program.targets):
        found = _target(model, nominal, t, _frames(program.dialect, t, frames), config_of, q_prev)
        if isinstance(found, str):
            refused[k] = found
            continue
        qs[k], q_prev, values = found
        texts[k] = dialect.write(program.text, t, values)
    for k, why in check_written(model, nominal, program, texts, qs, config_of, frames).items():
        texts.pop(k)
        refused[k] = why
    problems = tuple(f"{program.source}: line {program.targets[k].line} ({program.targets[k].move}"
                     f"{' ' + program.targets[k].variable if program.targets[k].variable else ''}): {why}; left as is"
                     for k, why in sorted(refused.items()))
    return ProgramCompensation(texts, qs, problems, program.not_literal, refused)


def _frames(dialect: str, t: Target, frames: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray] | str:
    """The target's tool and base frames (4x4 each; names in any case), or why they are not known."""
    given = {k.lower(): np.asarray(v, dtype=float) for k, v in frames.items()}
    out = []
    for what, name, identity in zip(("tool", "base"), t.frames, IDENTITY_FRAMES.get(dialect, ((), ()))):
        key = name.lower() or f"default {what}"  # the frame in force where the program names none
        if name.lower() in identity:
            out.append(np.eye(4))
        elif key in given:
            out.append(given[key])
        else:
            return (f"its {what} frame {name!r} is not given (give it with the frames; it is not taken as the "
                    f"identity)" if name else f"the program names no {what} frame here: give the one in force "
                    f"(frames: 'default {what}')")
    return out[0], out[1]


def _target(model: Robot, nominal: Robot, t: Target, frames, config_of: Config, q_prev: np.ndarray):
    """(corrected joints, the joints the next target starts from, new SI values) or why not."""
    if t.kind == "joints":  # (joints need no frame)
        if t.values.size != model.n_joints:
            return f"{t.values.size} joint values for a {model.n_joints}-joint robot"
        q_nom = t.values
        p, R, _, _ = nominal.pose_and_jacobian(q_nom[None])
    else:
        if isinstance(frames, str):
            return frames
        tool, base = frames
        p, R = _flange(base @ _pose(t.values) @ np.linalg.inv(tool))
        found = controller_inverse(nominal, p, R, q_prev, t.config, config_of)
        if isinstance(found, str):
            return found
        q_nom = found
    q, why = corrected(model, p, R, q_nom)
    why = why or _bits_kept(model, q, t.config, config_of)
    if why:
        return why + _singular(nominal, q_nom)
    if t.kind == "joints":
        return q, q, q
    pf, Rf, _, _ = nominal.pose_and_jacobian(q[None])
    target = np.linalg.inv(base) @ _pose_of(pf[0], Rf[0]) @ tool
    return q, q, np.concatenate([target[:3, 3], rotation_log(target[None, :3, :3])[0]])


def _singular(robot: Robot, q: np.ndarray) -> str:
    """A note when the arm is near a singularity at q (its pose Jacobian's condition number above SINGULAR):
    there the pose does not fix every joint, the usual cause of a correction that fails; else ''."""
    _, _, Jp, Jw = robot.pose_and_jacobian(q[None])
    s = np.linalg.svd(np.concatenate([Jp[0], Jw[0]]), compute_uv=False)
    cond = s[0] / max(s[-1], 1e-300)
    return f" (the arm is at or near a singularity here: condition number {cond:.1e}; move the target off it)" \
        if cond > SINGULAR else ""


def _bits_kept(model: Robot, q: np.ndarray, config: tuple, config_of: Config) -> str:
    if not config:
        return ""
    again = tuple(config_of(model, q))
    return "" if again == tuple(config) else (f"the corrected joints' configuration bits {again} differ from the "
                                             f"target's {tuple(config)}")


def controller_inverse(robot: Robot, p: np.ndarray, R: np.ndarray, near: np.ndarray, config: tuple,
                       config_of: Config) -> np.ndarray | str:
    """The joints (n,) a controller moving with ``robot`` takes for the tool point at p (1, 3) m with the
    flange at R (1, 3, 3) on the branch ``config`` (all branches for ()): of the solutions within the joint
    limits whose bits equal it, the one nearest ``near`` (ties: the first in the order found); or why none."""
    cand: list[np.ndarray] = []
    reached = False
    for starts in (near[None], robot.sample_joints(STARTS, seed=0)):  # the spread starts only when needed
        sol = solve_poses(robot, np.repeat(p, len(starts), 0), np.repeat(R, len(starts), 0), starts,
                          max_iter=SEARCH[0], max_travel=SEARCH[1])
        every = [c for q in sol.q[sol.converged] for c in _turns(robot, q)]
        reached |= bool(every)
        cand += [c for c in every if not config or tuple(config_of(robot, c)) == tuple(config)]
        if cand:
            break
    if not cand:
        return (f"the nominal model reaches this pose, but on no branch with the target's bits {tuple(config)} "
                f"within the joint limits" if reached else "the nominal model does not reach this pose within the "
                f"joint limits (out of reach, or the wrong robot or frames)")
    c = np.array(cand)
    return c[first_best(np.linalg.norm(c - near, axis=1), maximize=False)]


def _turns(robot: Robot, q: np.ndarray) -> list[np.ndarray]:
    """q with every combination of whole turns of its revolute joints that stays within the limits."""
    options = [[q[j] + 2 * np.pi * k for k in (0, -1, 1) if robot.lower[j] <= q[j] + 2 * np.pi * k <= robot.upper[j]]
               if periodic else ([q[j]] if robot.lower[j] <= q[j] <= robot.upper[j] else [])
               for j, periodic in enumerate(robot.periodic)]
    return [np.array(c) for c in itertools.product(*options)]


def check_written(model: Robot, nominal: Robot, program: Program, texts: dict, qs: np.ndarray, config_of: Config,
                  frames: Mapping[str, np.ndarray]) -> dict[int, str]:
    """The compensated targets whose text, read again, does not bring the robot where the program meant:
    for each, why (the controller's joints of the written target, on its bits from the corrected joints,
    must reach the intended pose on the calibrated model to ``CHECK_TOL``)."""
    if not texts:
        return {}
    model, nominal = model.with_tool_point(np.zeros(3)), nominal.with_tool_point(np.zeros(3))  # flange poses
    again = dialects()[program.dialect].parse(program.source, program.with_targets(texts))
    bad = {}
    for k in texts:
        old, new = program.targets[k], again.targets[k]
        known = _frames(program.dialect, old, frames)
        if old.kind == "joints":
            p, R, _, _ = nominal.pose_and_jacobian(old.values[None])
            q = new.values
        elif isinstance(known, str):  # (it was solved, so its frames are known)
            bad[k] = known
            continue
        else:
            tool, base = known
            p, R = _flange(base @ _pose(old.values) @ np.linalg.inv(tool))
            found = controller_inverse(nominal, *_flange(base @ _pose(new.values) @ np.linalg.inv(tool)), qs[k],
                                       new.config, config_of)
            if isinstance(found, str):
                bad[k] = f"the written target does not come back: {found}"
                continue
            q = found
        pm, Rm, _, _ = model.pose_and_jacobian(q[None])
        miss, turn = np.linalg.norm(pm - p), np.linalg.norm(rotation_log(Rm @ np.swapaxes(R, 1, 2)))
        if miss > CHECK_TOL or turn > CHECK_TOL:
            bad[k] = f"the written target misses by {miss * 1e3:.2e} mm / {turn:.2e} rad (checked as read again)"
    return bad


def _pose(values: np.ndarray) -> np.ndarray:
    """A 4x4 pose of x, y, z (m) and a rotation vector (rad)."""
    return _pose_of(values[:3], rotvec_matrix(values[3:6]))


def _pose_of(p: np.ndarray, R: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def _flange(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The flange's position (1, 3) and rotation (1, 3, 3) of a 4x4 flange pose."""
    return T[None, :3, 3], T[None, :3, :3]
