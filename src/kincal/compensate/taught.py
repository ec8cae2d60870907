"""Frames taught on the robot, corrected as the measurements they are.

A controller computes a taught base from the TCP positions its nominal model gives at the teach poses, and a
taught tool from the flange poses its nominal model gives; the TCP and the flange were really where the
calibrated model puts them at those joints. So each taught frame (:class:`kincal.io.TaughtFrame`) gives two
frames: the controller's (the nominal model at the teach poses: what the controller holds and turns written
targets with) and the physical one (the calibrated model at the same poses: where the fixture or the tool
really is, which the program's targets mean). A frame written in the file as well is the controller's (a
tool always is: the controller's fit of disagreeing nominal poses is its own); it must agree with the one its
joints give to ``TAUGHT_TOL`` (a tool: plus three times how far its nominal poses disagree), else it is refused
with the sizes (wrong joints, tool, rule or robot). A base taught with a tool takes that tool's TCP as the
program's targets do (:func:`tool_pair`: a tool given by its values with the calibration's move of the measured
point carried over, :func:`kincal.compensate.tool_carry`; a taught tool as the calibrated model gives it, that
move held already). Rules: :data:`kincal.io.frames_file.RULES`.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import ModelError
from ..io import TaughtFrame
from ..models.robot import Robot
from ..models.transforms import rotation_log

TAUGHT_TOL = (1e-4, 5e-4)  # m, rad: a written taught frame and the one its joints give on the nominal model
Pair = tuple[np.ndarray, np.ndarray]  # (controller, physical) 4x4 frames


def base_of_points(rule: str, P: np.ndarray) -> np.ndarray:
    """The base (4x4) that ``rule`` builds from three TCP positions P (3, 3) m: origin-x-xy (origin P0, +x toward
    P1, P2 in the xy plane on the +y side) or x1-x2-y1 (x from P0 to P1, P2 on +y, the origin its foot on x)."""
    x = (P[1] - P[0]) / np.linalg.norm(P[1] - P[0])
    origin = P[0] if rule == "origin-x-xy" else P[0] + ((P[2] - P[0]) @ x) * x
    z = np.cross(x, P[2] - P[0])
    z /= np.linalg.norm(z)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.column_stack([x, np.cross(z, x), z]), origin
    return T


def tool_of_poses(p: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, float]:
    """The TCP (4x4 in the flange, the flange's axes) that flange poses p (K, 3), R (K, 3, 3) all put on one
    fixed point: R_k t + p_k = c, by least squares over t and c; and the RMS distance (m) of the K TCP positions
    from that point (how far the poses disagree)."""
    A = np.concatenate([R, -np.broadcast_to(np.eye(3), R.shape)], axis=2).reshape(-1, 6)
    x = np.linalg.lstsq(A, -p.reshape(-1), rcond=None)[0]
    T = np.eye(4)
    T[:3, 3] = x[:3]
    spread = np.linalg.norm(np.einsum("kij,j->ki", R, x[:3]) + p - x[3:], axis=1)
    return T, float(np.sqrt(np.mean(spread**2)))


def tool_pair(tool: object, carry: np.ndarray | None = None) -> Pair:
    """A tool frame as the controller holds it and as it is on the calibrated model (4x4 each, m).

    A tool given by its values (or None: the flange) is the controller's; on the calibrated model its TCP is moved
    by ``carry``, what of the calibration's move of the declared target point is the last link's error, which the
    TCP shares (:func:`kincal.compensate.tool_carry`). A (controller, physical) pair, a taught tool's, is kept: its
    physical frame is computed on the calibrated model, which holds that error already.

    Parameters
    ----------
    tool : ndarray, shape (4, 4), None or tuple of two ndarrays
        The tool frame in the flange (m), None for the flange itself, or its (controller, physical) pair.
    carry : ndarray, shape (3,), optional
        What is added to the TCP on the calibrated model, m, flange frame (default zeros).

    Returns
    -------
    tuple of two ndarrays, shape (4, 4)
        The controller's tool frame and the physical one, m.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.compensate.taught import tool_pair
    >>> tcp = np.eye(4)
    >>> tcp[:3, 3] = [0.0, 0.0, 0.15]
    >>> controller, physical = tool_pair(tcp, np.array([0.0002, 0.0, 0.0003]))
    >>> controller[:3, 3].tolist(), np.round(physical[:3, 3] * 1e3, 3).tolist()  # m; mm
    ([0.0, 0.0, 0.15], [0.2, 0.0, 150.3])
    """
    if isinstance(tool, tuple):
        return tool
    controller = np.eye(4) if tool is None else np.asarray(tool, dtype=float)
    physical = controller.copy()
    physical[:3, 3] += np.zeros(3) if carry is None else carry
    return controller, physical


def _flange_poses(robot: Robot, q: np.ndarray, orientation: Robot | None) -> tuple[np.ndarray, np.ndarray]:
    """The flange poses p (K, 3) m, R (K, 3, 3) at q (K, n): ``robot``'s tool point where ``robot`` puts it, the
    flange turned as ``orientation``'s (default ``robot``'s) about it; the flange's origin follows from both."""
    robot = robot if robot.has_tool_point else robot.with_tool_point(np.zeros(3))
    P, R, _, _ = robot.pose_and_jacobian(robot.check_q(q))
    if orientation is not None:
        R = orientation.flange_rotation(q)
    return P - R @ robot.tool_point(), R


def _taught(f: TaughtFrame, robot: Robot, tool: np.ndarray,
            orientation: Robot | None = None) -> tuple[np.ndarray, float]:
    """The frame ``f``'s teach poses give on ``robot`` (its flange poses, :func:`_flange_poses`), a base with the
    TCP of ``tool`` (4x4); and for a tool how far its poses disagree (m; 0 for a base, whose rule is an exact
    construction)."""
    p, R = _flange_poses(robot, f.joints, orientation)
    if f.kind == "tool":
        return tool_of_poses(p, R)
    return base_of_points(f.rule, p + np.einsum("kij,j->ki", R, tool[:3, 3])), 0.0


def resolve_taught(frames: Mapping[str, object], nominal: Robot, calibrated: Robot,
                   orientation: Robot | None = None, carry: np.ndarray | None = None) -> dict[str, object]:
    """Replace every taught frame by the frame the controller holds and the one that is physically there.

    The controller's frame is what its nominal model gives at the teach poses (what it turns written targets
    with); the physical frame is what the calibrated model gives at the same poses (where the fixture or the
    tool really is, which the program's targets mean). A frame written in the file as well is the
    controller's; it must agree with the one its joints give to ``TAUGHT_TOL`` (0.1 mm, 0.5 mrad; a tool:
    plus three times how far its nominal poses disagree), else it is refused with the sizes. Tools are
    resolved first: a base uses the tool it was taught with, on the calibrated model as the program's targets use
    it (:func:`tool_pair`: a tool given by its values with its TCP moved by ``carry``, a taught one as it is).

    Parameters
    ----------
    frames : mapping of str to ndarray, str or TaughtFrame
        Frames by name: 4x4 poses (m, kept as they are), why a frame is not known (kept), or taught frames
        (:class:`kincal.io.TaughtFrame`).
    nominal : Robot
        The controller's (nominal) model, a flange model (no tool point).
    calibrated : Robot
        The calibrated model, with the point the calibration measured as its tool point (or a flange model).
    orientation : Robot, optional
        The model whose flange turn the physical frames take (default: the calibrated model's): give the nominal
        model where the calibration's data do not determine the turn (:func:`flange_turn`). The flange then
        stands where the calibrated model puts the measured point, turned as this model's about it.
    carry : ndarray, shape (3,), optional
        What of the calibration's move of the declared target point is carried over to a TCP, m, flange frame
        (:func:`kincal.compensate.tool_carry`; default zeros): a base taught with a tool given by its values
        takes that tool's TCP so moved on the calibrated model, as the program's targets do.

    Returns
    -------
    dict of str to object
        ``frames`` with every taught frame replaced by its (controller, physical) pair of 4x4 frames (m), or
        by why it cannot be used (str).

    Examples
    --------
    A base taught by three TCP positions (origin, a point on +x, a point in the xy plane) on a perturbed arm:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import resolve_taught
    >>> from kincal.io import TaughtFrame
    >>> nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point(np.zeros(3))
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q = np.radians([[0, -90, 90, 0, 45, 0], [15, -90, 90, 0, 45, 0], [0, -70, 80, 0, 45, 0]])
    >>> frames = resolve_taught({"table": TaughtFrame("table", "origin-x-xy", q, "", None)}, nominal, real)
    >>> controller, physical = frames["table"]
    >>> np.round(controller[[0, 2], 3], 4)  # the origin the controller holds: x and z, m (y is 0)
    array([0.5016, 0.8334])
    >>> np.round((physical[:3, 3] - controller[:3, 3]) * 1e3, 3)  # where it really is, mm from there
    array([ 0.413, -1.881,  0.002])

    A frame written beside its taught joints must be the one they give:

    >>> written = controller.copy()
    >>> written[0, 3] += 0.002
    >>> print(resolve_taught({"table": TaughtFrame("table", "origin-x-xy", q, "", written)}, nominal, real)["table"])
    as written it is 2.000 mm and 0.000 mrad from the frame its taught joints give on the nominal model
    (origin-x-xy): not the joints, tool, rule or robot it was taught with
    """
    out = dict(frames)
    taught = {n: f for n, f in frames.items() if isinstance(f, TaughtFrame)}
    for name in sorted(taught, key=lambda n: (taught[n].kind != "tool", n)):  # tools first: bases use them
        out[name] = _pair(taught[name], out, nominal, calibrated, orientation, carry)
    return out


def _pair(f: TaughtFrame, known: Mapping[str, object], nominal: Robot, calibrated: Robot,
          orientation: Robot | None, carry: np.ndarray | None) -> Pair | str:
    """The (controller, physical) frames of ``f`` (``orientation`` and ``carry`` as for :func:`resolve_taught`),
    or why it cannot be used."""
    tool = known.get(f.tool) if f.kind == "base" else None
    if isinstance(tool, str):
        return f"it was taught with tool {f.tool!r}, which is not known: {tool}"
    pair = tool_pair(tool, carry)  # the base's TCP on each model, as the program's targets take it
    try:
        (controller, spread) = _taught(f, nominal, pair[0])
        physical, _ = _taught(f, calibrated, pair[1], orientation)
    except ModelError as exc:  # teach poses of another joint count
        return f"its teach poses do not fit this robot ({exc})"
    if f.declared is None:
        return controller, physical
    off = np.linalg.norm(f.declared[:3, 3] - controller[:3, 3])
    turn = np.linalg.norm(rotation_log((f.declared[:3, :3] @ controller[:3, :3].T)[None])[0])
    if off > TAUGHT_TOL[0] + 3 * spread or turn > TAUGHT_TOL[1]:
        return (f"as written it is {off * 1e3:.3f} mm and {turn * 1e3:.3f} mrad from the frame its taught joints give "
                f"on the nominal model ({f.rule}): not the joints, tool, rule or robot it was taught with")
    return f.declared, physical  # the controller's frame as it holds it; the real one, from the calibrated model
