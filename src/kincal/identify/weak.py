"""Parameters the data hardly determine: kept at their nominal values, in every fit.

A parameter whose σ from the data exceeds the largest correction a real robot plausibly needs (the
verdict's "large correction" limits, 10 mm and 2 deg) is noise: fitted, it extrapolates wildly
outside the measured region (one marker on a small region: 4.17 mm held out where the fit that holds
such parameters reaches 3.14 mm). The worst one is kept nominal and the fit repeated, until none is.
The one fit (:mod:`kincal.identify.stacked`) applies it to every kind, with σ judged by the stated
σ and the model error the data show.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..models.robot import Robot
from ..ties import first_best
from ..units import fine
from .covariance import normal_inverse
from .verdict import Thresholds


def weakest(robot: Robot, free: Sequence[str], jacobian: np.ndarray, noise: float,
            scales: Mapping[str, tuple[float, str]] | None = None) -> tuple[str, float] | None:
    """The robot parameter among ``free`` (the columns of ``jacobian``) the data determine worst, with
    its σ (m or rad), when that σ exceeds the plausible correction limits; None when none does. The
    base frame (a set-up) is never held. σ from ``noise`` (the instrument's, in the Jacobian's units)
    and the poses alone, not from the residual's scale: so data that do not fit the robot (swapped
    joints) keep their implausible corrections in view instead of hiding them as weak. A parameter with
    a scale in ``scales`` (:meth:`kincal.Robot.correction_scales` at the data's poses: a compliance) is
    judged by the correction σ × scale makes there, not by its value."""
    sd = noise * np.sqrt(np.maximum(np.diag(normal_inverse(jacobian)), 0.0))
    th, scales = Thresholds(), scales or {}
    kinds = dict(zip(robot.params.names, robot.params.kinds))
    over = [(float(s * scales.get(n, (1.0, ""))[0] / th.suspect(kinds[n])), n, float(s))
            for n, s in zip(free, sd) if n in kinds and n not in robot.base_params()]
    over = [r for r in over if r[0] > 1.0]
    return None if not over else over[first_best([r[0] for r in over])][1:]


def weak_note(robot: Robot, weak: dict[str, float], scales: Mapping[str, tuple[float, str]] | None = None) -> str:
    """The parameters held, with the σ the data gave them, in one line ('' when none); one with a scale in
    ``scales`` (a compliance) by the σ of the correction it makes at the data's poses, and where."""
    if not weak:
        return ""
    kinds, scales = dict(zip(robot.params.names, robot.params.kinds)), scales or {}
    shown = [f"{n} ±{fine(v * scales.get(n, (1.0, ''))[0], kinds[n], '.1f' if kinds[n] == 'length' else '.0f')}"
             + (f" {scales[n][1]}" if n in scales else "") for n, v in weak.items()]
    return f"kept at nominal, determined worse than a real robot's error (10 mm, 2 deg): {', '.join(shown)}"
