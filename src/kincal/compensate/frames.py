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
TOOL_CORRECTION_MAX = 50e-3  # m: the verdict's tool_suspect; beyond it the fitted point is the mounting


def command_models(calibrated: Robot, nominal_values: Mapping[str, float] | None = None,
                   tcp: np.ndarray | None = None, frame: str = "base") -> tuple[Robot, Robot]:
    """(model, nominal model) for commands: the calibrated and the nominal parameters (``nominal_values``,
    default the calibrated ones), both in the target ``frame`` ("base": the robot's own base frame;
    "measurement": the calibration's measurement frame; or a frame the robot file names). Without a
    ``tcp`` the targets are for the measured target: the nominal model uses its declared point and the
    calibrated model the fitted one. With the controller's ``tcp`` (m, flange frame) the nominal model
    uses it, and the calibrated model it moved as the calibration moved the declared point."""
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
        model = model.with_tool_point(tcp + _tool_correction(model.tool_point(), nominal.tool_point()))
        nominal = nominal.with_tool_point(tcp)
    return model, nominal


def _tool_correction(fitted: np.ndarray, declared: np.ndarray) -> np.ndarray:
    """What the calibration moved the declared tool point by, carried over to the TCP: along the flange
    it also holds kinematic errors (e.g. the last link's length) that the TCP shares. A move beyond
    TOOL_CORRECTION_MAX is the target's mounting (a tool point not declared), carried over as nothing."""
    shift = fitted - declared
    return shift if np.linalg.norm(shift) <= TOOL_CORRECTION_MAX else np.zeros(3)


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
