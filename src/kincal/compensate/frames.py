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

from ..models.robot import Robot
from ..ties import first_best
from ..units import MM

TARGET_FRAMES = ("base", "measurement")  # besides the frames a robot file names
MISMATCH_TOL = 0.1e-3  # m: the nominal model at the nominal joints must reach the targets this closely
EXPLAINED = 0.2  # a constant offset explains the gap when it leaves less than this fraction (RMS)
MIN_ROWS = 3  # a constant offset needs this many targets to be told from a row's own miss
LINK_ERROR_MAX = 1e-3  # m: the most a real robot's last link is off; a larger move of the fitted target is its mounting


def command_models(calibrated: Robot, nominal_values: Mapping[str, float] | None = None,
                   tcp: np.ndarray | None = None, frame: str = "base",
                   link_error_max: float = LINK_ERROR_MAX) -> tuple[Robot, Robot]:
    """(model, nominal model) for commands: the calibrated and the nominal parameters (``nominal_values``,
    default the calibrated ones), both in the target ``frame`` ("base": the robot's own base frame;
    "measurement": the calibration's measurement frame; or a frame the robot file names). Without a
    ``tcp`` the targets are for the measured target: the nominal model uses its declared point and the
    calibrated model the fitted one. With the controller's ``tcp`` (m, flange frame) the nominal model
    uses it, and the calibrated model it moved by what :func:`tool_carry` carries over of the
    calibration's move of the declared point (up to ``link_error_max``, m)."""
    nominal = calibrated.with_params(dict(nominal_values)) if nominal_values else calibrated
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
    """What of the calibration's move of the declared target point (fitted − declared, m, flange
    frame) is carried over to the controller's TCP, and a sentence that says so. The data cannot tell
    a target declared in the wrong place from an error of the last link, which the TCP shares: a move
    up to ``limit`` (m) is taken for the link's and carried over; a larger one is the target's
    mounting (declared wrong: no real link is that far off) and is carried over as nothing."""
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


def frame_mismatch(nominal: Robot, q: np.ndarray, targets: np.ndarray, rows: np.ndarray) -> str:
    """The set-up mismatch that keeps the nominal model at the nominal joints q (N, n) from the targets
    (N, 3), or '': a constant offset in the flange frame is a TCP mismatch, one in the base frame a
    frame offset; targets that fit a named frame of the robot file are in that frame. Scattered
    misses are not a set-up mismatch (the per-row checks name them)."""
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
                    f"model's; give the controller's TCP with --tcp. Not corrected: a constant offset is a set-up "
                    f"mismatch, not a robot error")
        return (f"{head}: the targets are in another frame than the model's; say which with --target-frame. Not "
                f"corrected: a constant offset is a set-up mismatch, not a robot error")
    for frame, (R, t) in nominal.named_frames().items():
        there = (reached - t) @ R  # the nominal positions in that frame
        if np.max(np.linalg.norm(targets - there, axis=1)) <= MISMATCH_TOL:
            return (f"the targets are in the robot's '{frame}' frame, not its base frame: give --target-frame {frame}")
    return ""  # no set-up mismatch: the rows that miss are named one by one


def orientation_change(model: Robot, q: np.ndarray, nominal: Robot, q0: np.ndarray) -> np.ndarray:
    """(N,) rad: how far the tool orientation the model predicts at the commands q lies from the one the
    nominal model promises at the nominal joints q0 (position-only compensation leaves it)."""
    Ra, Rb = model.flange_rotation(q), nominal.flange_rotation(q0)
    cos = (np.einsum("nij,nij->n", Ra, Rb) - 1.0) / 2.0
    return np.arccos(np.clip(cos, -1.0, 1.0))
