"""Commands in the user's frames: targets in the robot's base frame (or a frame the robot file names,
such as ROS ``base_link``), for the controller's TCP, wherever the tracker stood during calibration.

A calibrated model's base frame is the measurement frame (where the tracker stood). Commands are
computed with the calibrated kinematics in the robot's own base frame instead (the nominal one: the
part of the base frame the tracker saw is where it stood, not the robot), composed with the named
target frame, and with the controller's TCP as tool point. Before any correction the nominal model at
the nominal joints must reach the targets: a constant offset between them is a TCP or frame mismatch
(a set-up error), refused with its size and direction, never "corrected" by moving joints.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import ModelError
from ..models.robot import TOOL_NAMES, Robot
from ..models.transforms import rotation_log
from ..models.unit_checks import MIN_SPREAD, SPREAD_RATIO, _times, _unit_of
from ..ties import first_best
from ..units import LENGTH_UNITS, MM, OTHER_LENGTHS

TARGET_FRAMES = ("base", "measurement")  # besides the frames a robot file names
MISMATCH_TOL = 0.1e-3  # m: the nominal model at the nominal joints must reach the targets this closely
EXPLAINED = 0.2  # a constant offset explains the gap when it leaves less than this fraction (RMS)
MIN_ROWS = 3  # a constant offset needs this many targets to be told from a row's own miss
LINK_ERROR_MAX = 1e-3  # m: the most a real robot's last link is off; a larger move of the fitted target is its mounting
BASE_TOL = 1e-9  # m and rad: a model and its nominal for commands stand in one base frame this closely


def command_models(calibrated: Robot, nominal_values: Mapping[str, float] | None = None,
                   tcp: np.ndarray | None = None, frame: str = "base",
                   link_error_max: float = LINK_ERROR_MAX) -> tuple[Robot, Robot]:
    """Return the calibrated and the nominal model for commands, both in the targets' frame and for their TCP.

    Commands are computed with the calibrated kinematics in the robot's own base frame (the nominal one: the
    part of the base frame the tracker saw is where it stood, not the robot) unless the targets are in the
    measurement frame, composed with a named target frame (module docstring).

    Parameters
    ----------
    calibrated : Robot
        The calibrated model (its base frame: the measurement frame).
    nominal_values : mapping of str to float, optional
        The nominal parameters by name, m and rad (default: the calibrated ones).
    tcp : ndarray, shape (3,), optional
        The controller's TCP in the flange frame, m. The nominal model uses it, and the calibrated model it
        moved by what :func:`tool_carry` carries over of the calibration's move of the declared point.
        Without it the targets are for the measured target: the nominal model uses its declared point and
        the calibrated model the fitted one.
    frame : str, optional
        The targets' frame: "base" (the robot's own base frame, the default), "measurement" (the
        calibration's measurement frame) or a frame the robot file names (such as ROS ``base_link``).
    link_error_max : float, optional
        The largest move of the declared target point carried over to the TCP, m (default
        ``LINK_ERROR_MAX``, 1e-3).

    Returns
    -------
    model : Robot
        The calibrated model in the target frame, with the TCP.
    nominal : Robot
        The nominal model in the target frame, with the TCP.

    Raises
    ------
    ValueError
        When ``frame`` is none of the target frames.
    ModelError
        When a ``tcp`` is given for a robot without a tool point, or ``nominal_values`` lacks some of the
        calibrated model's parameters (an error model's terms) or names others.

    Examples
    --------
    A UR5 calibrated with the tracker 1.2 m in front of it: in the robot's base frame both models agree to
    the robot's errors, in the measurement frame both stand where the tracker saw the robot:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import command_models
    >>> nominal = kincal.load_robot("ur5")
    >>> calibrated = kincal.perturb(nominal, seed=1).with_params({"base.x": 1.2, "base.y": -0.3})
    >>> q = nominal.sample_joints(3, seed=2)
    >>> model, nom = command_models(calibrated, nominal.params.as_dict())
    >>> np.round(np.linalg.norm(model.forward(q) - nom.forward(q), axis=1) * 1e3, 2)  # mm
    array([1.42, 1.26, 0.86])
    >>> model, nom = command_models(calibrated, nominal.params.as_dict(), frame="measurement")
    >>> np.round(nom.forward(q) - nominal.forward(q), 6)[:, :2]  # x and y, m (z: 0)
    array([[ 1.2, -0.3],
           [ 1.2, -0.3],
           [ 1.2, -0.3]])

    With the controller's TCP, the calibrated model's is moved as the calibration moved the declared point:

    >>> model, nom = command_models(calibrated, nominal.params.as_dict(), tcp=[0.0, 0.0, 0.15])
    >>> nom.tool_point().tolist()
    [0.0, 0.0, 0.15]
    >>> np.round((model.tool_point() - nom.tool_point()) * 1e3, 3)  # mm
    array([ 0.041, -0.223, -0.339])
    """
    nominal = calibrated.with_params(_every_nominal(calibrated, nominal_values)) if nominal_values else calibrated
    named = calibrated.named_frames()
    if frame not in TARGET_FRAMES and frame not in named:
        raise ValueError(f"target frame '{frame}': use one of {', '.join((*TARGET_FRAMES, *named))}")
    model = calibrated
    if calibrated.base_params():
        R, t = (calibrated if frame == "measurement" else nominal).base_transform()
        if frame in named:
            Rf, tf = named[frame]
            R, t = Rf.T @ R, Rf.T @ (t - tf)
        model, nominal = model.with_base_transform(R, t), nominal.with_base_transform(R, t)
    if tcp is not None:  # a robot without a tool point says so (ModelError)
        tcp = np.asarray(tcp, dtype=float)
        model = model.with_tool_point(tcp + tool_carry(model.tool_point(), nominal.tool_point(), link_error_max)[0])
        nominal = nominal.with_tool_point(tcp)
    return model, nominal


def tool_carry(fitted: np.ndarray, declared: np.ndarray, limit: float = LINK_ERROR_MAX) -> tuple[np.ndarray, str]:
    """Return what of the calibration's move of the declared target point is carried over to the controller's TCP.

    The data cannot tell a target declared in the wrong place from an error of the last link, which the TCP
    shares: a move up to ``limit`` is taken for the link's and carried over; a larger one is the target's
    mounting (declared wrong: no real link is that far off) and is carried over as nothing.

    Parameters
    ----------
    fitted : ndarray, shape (3,)
        The target point the calibration fitted, m, flange frame.
    declared : ndarray, shape (3,)
        The target point as declared (the nominal one), m, flange frame.
    limit : float, optional
        The largest move taken for the last link's error, m (default ``LINK_ERROR_MAX``, 1e-3).

    Returns
    -------
    shift : ndarray, shape (3,)
        What is added to the TCP, m, flange frame: ``fitted - declared``, or zeros.
    why : str
        A sentence that says so.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.compensate import tool_carry
    >>> shift, why = tool_carry(np.array([0.0002, 0.0, 0.1503]), np.array([0.0, 0.0, 0.15]))
    >>> np.round(shift * 1e3, 3)  # mm
    array([0.2, 0. , 0.3])
    >>> print(why)
    the calibration moved the declared target point by 0.361 mm: taken as the last link's error and carried
    over to the TCP (up to 1 mm, --link-error-max)
    >>> shift, why = tool_carry(np.array([0.0, 0.0, 0.16]), np.array([0.0, 0.0, 0.15]))
    >>> shift.tolist()
    [0.0, 0.0, 0.0]
    >>> print(why)
    the calibration moved the declared target point by 10.00 mm, more than a link's error (1 mm,
    --link-error-max): taken as the target's mounting (declared wrong), not carried over to the TCP
    """
    shift = fitted - declared
    size = float(np.linalg.norm(shift))
    if size <= limit:
        return shift, (f"the calibration moved the declared target point by {size * MM:.3f} mm: taken as the last "
                       f"link's error and carried over to the TCP (up to {limit * MM:g} mm, --link-error-max)")
    return np.zeros(3), (f"the calibration moved the declared target point by {size * MM:.2f} mm, more than a link's "
                         f"error ({limit * MM:g} mm, --link-error-max): taken as the target's mounting (declared "
                         f"wrong), not carried over to the TCP")


def _direction(v: np.ndarray, frame: str) -> str:
    """'the flange +z' for a unit vector along an axis, else 'the flange direction (0.60, 0.80, 0.00)'."""
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) > 0.98:
        return f"the {frame} {'+' if v[k] > 0 else '-'}{'xyz'[k]}"
    return f"the {frame} direction ({', '.join(f'{c:.2f}' for c in v)})"


def base_mismatch(model: Robot, nominal: Robot) -> str:
    """Say why a model and the nominal model given with it for commands are not in one frame, if they are not.

    Commands need both in the targets' frame (:func:`command_models`); a calibrated model's base frame is
    the measurement frame (where the instrument saw the robot), so given as it is beside the nominal model, its
    commands are off by that frame's move (1.1 mm on the real UR5's tracker frame) while every other check
    passes.

    Parameters
    ----------
    model : Robot
        The model the commands are computed with.
    nominal : Robot
        The nominal (controller's) model.

    Returns
    -------
    str
        How far the base frames are apart and what to do; '' when they agree to ``BASE_TOL`` (or a model has
        no base frame).

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import base_mismatch, command_models
    >>> nominal = kincal.load_robot("ur5")
    >>> calibrated = nominal.with_params({"base.x": 0.0004, "base.ry": 0.002})
    >>> print(base_mismatch(calibrated, nominal))
    the model's base frame stands 0.400 mm and 2.000 mrad from the nominal model's: ...
    >>> base_mismatch(*command_models(calibrated, nominal.params.as_dict()))
    ''
    """
    if not (model.base_params() and nominal.base_params()):
        return ""
    (Rm, tm), (Rn, tn) = model.base_transform(), nominal.base_transform()
    move, turn = float(np.linalg.norm(tm - tn)), float(np.linalg.norm(rotation_log((Rm @ Rn.T)[None])[0]))
    if move <= BASE_TOL and turn <= BASE_TOL:
        return ""
    return (f"the model's base frame stands {move * MM:.3f} mm and {turn * 1e3:.3f} mrad from the nominal model's: "
            f"the two are in different frames (a calibrated model's base frame is the measurement frame, where the "
            f"instrument saw the robot), and its commands would miss by that move; put both in the targets' frame "
            f"with command_models(calibrated, nominal.params.as_dict()) (frame='measurement' for targets in the "
            f"instrument's frame)")


def frame_mismatch(nominal: Robot, q: np.ndarray, targets: np.ndarray) -> str:
    """Name the set-up mismatch that keeps the nominal model at the nominal joints from the targets, if any.

    A constant offset in the flange frame is a TCP mismatch, one in the base frame a frame offset (each
    must explain the misses to ``EXPLAINED`` of their RMS); targets that fit a named frame of the robot file
    are in that frame. Scattered misses are not a set-up mismatch (the per-row checks name them), nor are
    misses of fewer than ``MIN_ROWS`` (3) targets or a median miss within ``MISMATCH_TOL`` (0.1 mm).

    Parameters
    ----------
    nominal : Robot
        The nominal (controller's) model, with the TCP, in the frame the targets should be in.
    q : ndarray, shape (N, n)
        The nominal joints of the targets, rad (m for a prismatic joint).
    targets : ndarray, shape (N, 3)
        The target positions, m.

    Returns
    -------
    str
        The mismatch, its size and direction and what to give instead; '' when there is none.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import frame_mismatch
    >>> nominal = kincal.load_robot("ur5")
    >>> q = nominal.sample_joints(5, seed=2)
    >>> frame_mismatch(nominal, q, nominal.forward(q))
    ''
    >>> print(frame_mismatch(nominal, q, nominal.forward(q) + [0.0, 0.002, 0.0]))
    TCP/frame mismatch of 2.0 mm along the base frame +y: the targets are in another frame than the model's;
    say which (command_models' frame=; CLI: --target-frame). Not corrected: a constant offset is a set-up
    mismatch, not a robot error
    >>> longer = nominal.forward(q) + nominal.flange_rotation(q) @ np.array([0.0, 0.0, 0.01])
    >>> print(frame_mismatch(nominal, q, longer))
    TCP/frame mismatch of 10.0 mm along the flange +z: the targets were computed for a tool point at (0.00, 0.09,
    41.00) mm in the flange frame, not the model's; give the controller's TCP (command_models' tcp=; CLI: --tcp).
    Not corrected: a constant offset is a set-up mismatch, not a robot error
    >>> print(frame_mismatch(nominal, q, nominal.forward(q) * [-1.0, -1.0, 1.0]))
    the targets are in the robot's 'base_link' frame, not its base frame: give it (command_models'
    frame='base_link'; CLI: --target-frame base_link)
    """
    reached = nominal.forward(q)
    e = targets - reached
    norms = np.linalg.norm(e, axis=1)
    if len(e) < MIN_ROWS or np.median(norms) <= MISMATCH_TOL:  # too few to tell, or most fine: misses are the rows' own
        return ""
    rms = float(np.sqrt(np.mean(norms**2)))
    fits = [("base frame", e.mean(axis=0), e - e.mean(axis=0))]
    if nominal.has_tool_point:
        Rf = nominal.flange_rotation(q)
        c = np.einsum("nji,nj->i", Rf, e) / len(e)
        fits.append(("flange", c, e - Rf @ c))
    name, c, rest = fits[first_best([float(np.sum(f[2] ** 2)) for f in fits], maximize=False)]  # ties: base frame
    size = float(np.linalg.norm(c))
    if np.sqrt(np.mean(np.sum(rest**2, axis=1))) < EXPLAINED * rms:
        head = f"TCP/frame mismatch of {size * MM:.1f} mm along {_direction(c / size, name)}"
        if name == "flange":
            where = ", ".join(f"{x * MM:.2f}" for x in nominal.tool_point() + c)
            return (f"{head}: the targets were computed for a tool point at ({where}) mm in the flange frame, not the "
                    f"model's; give the controller's TCP (command_models' tcp=; CLI: --tcp). Not corrected: a "
                    f"constant offset is a set-up mismatch, not a robot error")
        return (f"{head}: the targets are in another frame than the model's; say which (command_models' frame=; "
                f"CLI: --target-frame). Not corrected: a constant offset is a set-up mismatch, not a robot error")
    for frame, (R, t) in nominal.named_frames().items():
        there = (reached - t) @ R  # the nominal positions in that frame
        if np.max(np.linalg.norm(targets - there, axis=1)) <= MISMATCH_TOL:
            return (f"the targets are in the robot's '{frame}' frame, not its base frame: give it (command_models' "
                    f"frame='{frame}'; CLI: --target-frame {frame})")
    return ""  # no set-up mismatch: the rows that miss are named one by one


def unit_mismatch(nominal: Robot, q: np.ndarray, targets: np.ndarray) -> str:
    """Name the length unit the targets are really in when they are not in m: their spread against the nominal model's
    at the nominal joints, off by the factor of a length unit (a set-up mismatch moves them, it does not scale them).

    The spread is the median distance from the median position, so a few rows far off are named by row, not taken for a
    unit. Fewer than ``MIN_ROWS`` (3) targets, a robot that moves less than ``MIN_SPREAD`` (1 mm) at the joints, a
    spread within ``SPREAD_RATIO`` (2x) of the robot's or a factor no length unit explains (within 30 %) say nothing.

    Parameters
    ----------
    nominal : Robot
        The nominal (controller's) model, in the targets' frame.
    q : ndarray, shape (N, n)
        The nominal joints of the targets, rad (m for a prismatic joint).
    targets : ndarray, shape (N, 3)
        The target positions, m.

    Returns
    -------
    str
        The factor, the unit the targets look like and what to do; '' when they are plausibly in m.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import unit_mismatch
    >>> nominal = kincal.load_robot("ur5")
    >>> q = nominal.sample_joints(5, seed=2)
    >>> unit_mismatch(nominal, q, nominal.forward(q))
    ''
    >>> print(unit_mismatch(nominal, q, nominal.forward(q) * 1e3))
    the targets spread 1e+03x more than the model moves at their nominal joints: they look like mm, not m; give
    them in m (x0.001). Not corrected: a unit mistake, not a robot error
    """
    if len(targets) < MIN_ROWS:
        return ""
    try:
        moved = _median_spread(nominal.forward(q))
    except ModelError:  # a closed chain that does not assemble at these joints: the rows' own checks name it
        return ""
    ratio = _median_spread(targets) / moved if moved > MIN_SPREAD else 1.0
    name = "" if 1 / SPREAD_RATIO < ratio < SPREAD_RATIO else _unit_of(ratio, "m")
    if not name:
        return ""
    return (f"the targets spread {_times(ratio)} than the model moves at their nominal joints: they look like {name}, "
            f"not m; give them in m (x{({**LENGTH_UNITS, **OTHER_LENGTHS})[name]:g}). Not corrected: a unit mistake, "
            f"not a robot error")


def _median_spread(x: np.ndarray) -> float:
    """m: the median distance of the positions x (N, 3) from their median (a few rows far off do not move it)."""
    return float(np.median(np.linalg.norm(x - np.median(x, axis=0), axis=1)))


def orientation_change(model: Robot, q: np.ndarray, nominal: Robot, q0: np.ndarray) -> np.ndarray:
    """(N,) rad: how far the tool orientation the model predicts at the commands q lies from the one the
    nominal model promises at the nominal joints q0 (position-only compensation leaves it)."""
    Ra, Rb = model.flange_rotation(q), nominal.flange_rotation(q0)
    cos = (np.einsum("nij,nij->n", Ra, Rb) - 1.0) / 2.0
    return np.arccos(np.clip(cos, -1.0, 1.0))


def unseen_in_base(calibrated: Robot, q: np.ndarray) -> tuple[str, ...]:
    """The robot parameters a calibration that fitted its measurement frame cannot tell from that frame (a tracker's or
    a camera's).

    Their effect on every position is a move of the frame (a DH arm's joint 1 zero and height: ``j1.theta`` acts
    like ``base.rz``, ``j1.d`` like ``base.z``), so the fit keeps them nominal and the frame takes their real
    values. Commands in the robot's base frame (the nominal one) therefore keep them as the controller has them.

    Parameters
    ----------
    calibrated : Robot
        The calibrated model, with a base frame.
    q : ndarray, shape (N, n)
        Poses of the calibration's joint ranges, rad (m for a prismatic joint).

    Returns
    -------
    tuple of str
        The names, in the robot's order; () for a robot without a base frame.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import unseen_in_base
    >>> robot = kincal.load_robot("ur5")
    >>> unseen_in_base(robot, robot.sample_joints(100, seed=1))
    ('j1.theta', 'j1.d')
    """
    from ..analysis.identifiability import free_parameters

    if not calibrated.base_params():
        return ()
    ident = free_parameters(calibrated, q)
    base = set(calibrated.base_params())
    return tuple(n for n in ident.dropped if ident.confounds.get(n) and all(k in base for k, _ in ident.confounds[n]))


def unseen_at_flange(calibrated: Robot, q: np.ndarray) -> tuple[str, ...]:
    """The robot parameters a body fitted on the flange (a nest of markers) takes up: their effect at every pose
    is a rigid move of everything on the flange.

    A calibration that fits where its markers sit on the flange cannot tell these from the nest's own pose (a
    DH arm's last link: ``j6.d``, ``j6.a``, its twist and zero), so it keeps them nominal and the markers'
    positions take their real values: the flange itself, and a TCP on it, keep them as the controller has them.
    A parameter is taken up when its position Jacobian at three points of the flange lies, over the poses, in the
    span of the flange's own six motions (to 1e-6 of its size).

    Parameters
    ----------
    calibrated : Robot
        The calibrated model, with a tool point.
    q : ndarray, shape (N, n)
        Poses of the calibration's joint ranges, rad (m for a prismatic joint).

    Returns
    -------
    tuple of str
        The names, in the robot's order (the base frame's and the tool point's left out); () for a robot
        without a tool point.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import unseen_at_flange
    >>> robot = kincal.load_robot("ur10")
    >>> unseen_at_flange(robot, robot.sample_joints(50, seed=1))
    ('j6.theta', 'j6.d', 'j6.a', 'j6.alpha')
    """
    if not calibrated.has_tool_point:
        return ()
    flange = calibrated.with_tool_point(np.zeros(3))
    _, R, _, _ = flange.pose_and_jacobian(q)
    blocks, motions = [], []
    for v in 0.1 * np.eye(3):  # three points of the flange, 0.1 m out along its axes
        blocks.append(calibrated.with_tool_point(v).param_jacobian(q).reshape(-1, calibrated.n_params))
        arm = np.einsum("nij,j->ni", R, v)
        turn = np.cross(R, arm[:, :, None], axis=1)  # a turn about each flange axis: ω × arm, (N, 3, 3)
        motions.append(np.concatenate([R, turn], axis=2).reshape(-1, 6))
    A, T = np.vstack(blocks), np.vstack(motions)
    left = A - T @ np.linalg.lstsq(T, A, rcond=None)[0]
    size = np.linalg.norm(A, axis=0)
    skip = set(calibrated.base_params()) | set(TOOL_NAMES)
    return tuple(n for n, a, r in zip(calibrated.params.names, size, np.linalg.norm(left, axis=0))
                 if n not in skip and a > 0 and r <= 1e-6 * a)


def base_note(names: tuple[str, ...], measurement_frame: bool = True) -> str:
    """Say what commands in the robot's base frame leave as the controller has it.

    Parameters
    ----------
    names : tuple of str
        The parameters :func:`unseen_in_base` names.
    measurement_frame : bool, optional
        Say that targets in the tracker's frame (``--target-frame measurement``) are not affected (default True;
        False for programs, whose frames are their own).

    Returns
    -------
    str
        One line for the user; '' for no names.

    Examples
    --------
    >>> from kincal.compensate import base_note
    >>> print(base_note(("j1.theta", "j1.d"), measurement_frame=False))
    base frame: j1.theta, j1.d not corrected: the measurements cannot tell them from where the instrument stood, so
    in the robot's base frame they stay as the controller has them; targets located on the robot's mounting can miss
    by their real errors, targets in frames taught with this robot do not
    """
    if not names:
        return ""
    return (f"base frame: {', '.join(names)} not corrected: the measurements cannot tell them from where the "
            f"instrument stood, so in the robot's base frame they stay as the controller has them; targets located on "
            f"the robot's mounting can miss by their real errors, targets "
            + ("in the instrument's frame (--target-frame measurement) or " if measurement_frame else "")
            + "in frames taught with this robot do not")


def _every_nominal(calibrated: Robot, nominal_values: Mapping[str, float]) -> dict[str, float]:
    """``nominal_values`` when it gives every parameter of ``calibrated`` and no other (ModelError otherwise: a
    parameter left out would keep its calibrated value in the "nominal" model, the controller's)."""
    names = calibrated.params.names
    missing = [n for n in names if n not in nominal_values]
    unknown = [n for n in nominal_values if n not in set(names)]
    if missing or unknown:
        what = (f"lack {len(missing)} of the calibrated model's parameters ({', '.join(missing[:4])}"
                f"{', ...' if len(missing) > 4 else ''}), which would keep their calibrated values in the controller's "
                f"model" if missing else f"name {', '.join(unknown[:4])}, which the calibrated model does not have")
        raise ModelError(f"the nominal values {what}; give the calibration's own nominal, with its error model's "
                         f"terms at their nominal values (from Python: the result's nominal.params.as_dict(); a "
                         f"calibrated file's record: its 'nominal')")
    return dict(nominal_values)
