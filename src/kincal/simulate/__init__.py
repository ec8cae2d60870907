"""Simulation: a "true" robot and tracker noise stand in for the real robot and its measurements.

:func:`perturb` makes the "true" robot (random errors in the nominal parameters), :func:`simulate` its tracker
measurements; :mod:`kincal.simulate.observations` simulates the other kinds of observation (6-D poses, markers,
sockets, planes) and :mod:`kincal.simulate.thermal` a robot that warms up. The defaults: ``DEFAULT_NOISE`` (m per
axis, a laser tracker's typical 1σ), ``DEFAULT_LENGTH_ERROR`` (m) and ``DEFAULT_ANGLE_ERROR`` (rad).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..checks import number
from ..io.measurements import Measurements
from ..models.unit_checks import joints_in_radians
from ..models.robot import Robot
from .observations import (plane_plan, reach, simulate_markers, simulate_planes, simulate_poses, simulate_same_point,
                           socket_plan)
from .thermal import ALUMINIUM, STEEL, link_growth, simulate_thermal, warm_up

DEFAULT_NOISE = 15e-6  # m, per axis: a laser tracker's typical 1-sigma
DEFAULT_LENGTH_ERROR = 0.5e-3  # m
DEFAULT_ANGLE_ERROR = np.deg2rad(0.05)  # rad


def simulate(true_robot: Robot, q: np.ndarray, noise: float = DEFAULT_NOISE, seed: int | None = 0) -> Measurements:
    """Simulate tracker measurements of a robot's tool point.

    The tool point of ``true_robot`` at each configuration, plus independent Gaussian noise of σ = ``noise`` on
    each axis: the measurements a laser tracker would report of the real robot that ``true_robot`` stands for.

    Parameters
    ----------
    true_robot : Robot
        The robot that stands in for the real one (e.g. a nominal model with errors from :func:`perturb`).
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint); a single (n,) vector is one configuration.
    noise : float, optional
        σ per axis of the measurement noise, m (default ``DEFAULT_NOISE``, 15e-6: a laser tracker's typical
        1σ); 0 gives the exact positions.
    seed : int or None, optional
        Seed of the noise's random generator (default 0); None draws different noise at every call.

    Returns
    -------
    Measurements
        The joint values q (N, n) and the measured positions xyz (N, 3) in m, in the base (world) frame, with
        ``true_robot``'s joint names and the source "simulated <robot name>".

    Raises
    ------
    ValueError
        When ``noise`` is negative or not a finite number.
    ModelError
        When q does not have one column per joint of ``true_robot``.

    See Also
    --------
    perturb : A "true" robot with random errors in its parameters.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(20, seed=1)
    >>> meas = kincal.simulate(robot, q, noise=15e-6, seed=0)
    >>> meas.q.shape, meas.xyz.shape, meas.source
    ((20, 6), (20, 3), 'simulated ur5')
    >>> err = np.linalg.norm(meas.xyz - robot.forward(q), axis=1)
    >>> bool(err.max() < 6 * 15e-6)
    True
    >>> exact = kincal.simulate(robot, q, noise=0.0)
    >>> bool(np.array_equal(exact.xyz, robot.forward(q)))
    True
    """
    number("noise", noise, positive=False, unit="m per axis")
    q = true_robot.check_q(q)
    joints_in_radians("q", q, true_robot)
    rng = np.random.default_rng(seed)
    xyz = true_robot.forward(q) + noise * rng.standard_normal((q.shape[0], 3))
    return Measurements(q, xyz, true_robot.joint_names, source=f"simulated {true_robot.name}")


def perturb(robot: Robot, length: float = DEFAULT_LENGTH_ERROR, angle: float = DEFAULT_ANGLE_ERROR,
            seed: int | None = 0, names: Sequence[str] | None = None, include_base: bool = False) -> Robot:
    """Add uniform random errors to a robot's parameters: a "true" robot for a simulation.

    Each chosen parameter of kind "length" moves by a value drawn uniformly in [-``length``, ``length``] m, each
    other one (angles, dimensionless ratios) by a value in [-``angle``, ``angle``]; the others keep their values.

    Parameters
    ----------
    robot : Robot
        The nominal robot.
    length : float, optional
        Largest error of a length parameter, m (default ``DEFAULT_LENGTH_ERROR``, 0.5e-3).
    angle : float, optional
        Largest error of an angle parameter, rad (default ``DEFAULT_ANGLE_ERROR``, 0.05° = 8.7e-4 rad); it
        also bounds the errors of dimensionless (ratio) parameters.
    seed : int or None, optional
        Seed of the random generator (default 0); None draws different errors at every call.
    names : sequence of str, optional
        The parameters to perturb (default: all of them, the base frame's left out unless ``include_base``).
    include_base : bool, optional
        With the default ``names``, perturb the base frame parameters too (default False: where the tracker
        stands is not a robot error).

    Returns
    -------
    Robot
        A copy of ``robot`` (same type, names and kinds) with the perturbed values.

    Raises
    ------
    ValueError
        When ``length`` or ``angle`` is negative or not a finite number.
    ModelError
        When a name in ``names`` is not a parameter of ``robot``, or the new values are not valid for it.

    See Also
    --------
    simulate : Measurements of the perturbed robot.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> error = true.params.values - robot.params.values
    >>> lengths = robot.params.is_length()
    >>> bool(np.all(np.abs(error[lengths]) <= 0.5e-3)), bool(np.all(np.abs(error[~lengths]) <= np.deg2rad(0.05)))
    (True, True)
    >>> all(true.params[n] == robot.params[n] for n in robot.base_params())
    True

    Only two link lengths, by up to 1 mm:

    >>> true = kincal.perturb(robot, length=1e-3, names=["j2.a", "j3.a"], seed=3)
    >>> [n for n in robot.params.names if true.params[n] != robot.params[n]]
    ['j2.a', 'j3.a']
    """
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
