"""Simulation: a "true" robot and tracker noise stand in for the real robot and its measurements."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..checks import number
from ..io.measurements import Measurements
from ..models.robot import Robot
from .observations import (plane_plan, reach, simulate_markers, simulate_planes, simulate_poses, simulate_same_point,
                           socket_plan)
from .thermal import ALUMINIUM, STEEL, link_growth, simulate_thermal, warm_up

DEFAULT_NOISE = 15e-6  # m, per axis: a laser tracker's typical 1-sigma
DEFAULT_LENGTH_ERROR = 0.5e-3  # m
DEFAULT_ANGLE_ERROR = np.deg2rad(0.05)  # rad


def simulate(true_robot: Robot, q: np.ndarray, noise: float = DEFAULT_NOISE, seed: int | None = 0) -> Measurements:
    """Measurements of ``true_robot`` at joint values q (N, n) with Gaussian noise of ``noise`` m per axis."""
    number("noise", noise, positive=False, unit="m per axis")
    q = true_robot.check_q(q)
    rng = np.random.default_rng(seed)
    xyz = true_robot.forward(q) + noise * rng.standard_normal((q.shape[0], 3))
    return Measurements(q, xyz, true_robot.joint_names, source=f"simulated {true_robot.name}")


def perturb(robot: Robot, length: float = DEFAULT_LENGTH_ERROR, angle: float = DEFAULT_ANGLE_ERROR,
            seed: int | None = 0, names: Sequence[str] | None = None, include_base: bool = False) -> Robot:
    """A copy of ``robot`` with uniform random errors in ±length (m) / ±angle (rad) on the parameters ``names``
    (default: all except the base frame unless ``include_base``)."""
    number("length", length, positive=False, unit="m")
    number("angle", angle, positive=False, unit="rad")
    rng = np.random.default_rng(seed)
    if names is None:
        names = [n for n in robot.params.names if include_base or n not in robot.base_params()]
    idx = robot.params.indices(names)
    mag = np.where(robot.params.is_length()[idx], length, angle)
    values = robot.params.values.copy()
    values[idx] += rng.uniform(-1.0, 1.0, size=idx.size) * mag
    return robot.with_params(values)


__all__ = ["simulate", "perturb", "simulate_poses", "simulate_markers", "simulate_same_point", "simulate_planes",
           "reach", "socket_plan", "plane_plan", "simulate_thermal", "warm_up", "link_growth", "ALUMINIUM", "STEEL",
           "DEFAULT_NOISE", "DEFAULT_LENGTH_ERROR", "DEFAULT_ANGLE_ERROR"]
