"""A robot that warms up: a temperature column over a session and the links' thermal growth.

The "true" robot's links (every parameter of kind "length" but the base frame and the tool point)
grow by α·(T − T_ref) at each sample's temperature T, each sample measured on its own grown copy of
the robot — the growth itself, not the linear model of it that
:mod:`kincal.models.covariates` fits, so a test of the term against these data is a test against an
independent reference. Aluminium arms (UR) grow by 23e-6 per K, steel by 12e-6: 0.9 m of links and
15 K move the tool point by about 0.3 mm.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..checks import number
from ..io.measurements import Measurements
from ..models.robot import Robot

ALUMINIUM = 23e-6  # 1/K
STEEL = 12e-6  # 1/K


def warm_up(n: int, start: float = 20.0, rise: float = 15.0, tau: float | None = None) -> np.ndarray:
    """Temperatures of a session that warms up: start + rise·(1 − exp(−k/τ)) at sample k.

    Parameters
    ----------
    n : int
        Number of samples.
    start : float, optional
        Temperature at the first sample, K or °C (default 20.0); the result is in the same unit.
    rise : float, optional
        How far the temperature rises in the end, in the unit of ``start`` (default 15.0).
    tau : float, optional
        Time constant τ in samples (default n / 3).

    Returns
    -------
    ndarray, shape (n,)
        The temperature at each sample, in the unit of ``start``.

    Raises
    ------
    ValueError
        When ``tau`` is not a finite number > 0 (also for n = 0 with the default).

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.simulate import warm_up
    >>> np.round(warm_up(4, start=20.0, rise=15.0), 3)
    array([20.   , 27.915, 31.653, 33.419])
    >>> np.round(warm_up(4, tau=1.0), 3)
    array([20.   , 29.482, 32.97 , 34.253])
    """
    tau = number("tau", n / 3.0 if tau is None else tau, unit="samples")
    return start + rise * (1.0 - np.exp(-np.arange(int(n)) / tau))


def link_growth(robot: Robot, alpha: float | Mapping[str, float]) -> np.ndarray:
    """Thermal growth of each parameter per kelvin: α·L for every link length.

    A link length is a parameter of kind "length" that is neither a base frame parameter nor a tool point
    coordinate; every other parameter does not grow.

    Parameters
    ----------
    robot : Robot
        The robot whose links grow.
    alpha : float or mapping of str to float
        Coefficient of thermal expansion α, 1/K: one rate for all links (``ALUMINIUM``, ``STEEL``), or a rate
        per link, keyed by the part of the parameter name before the dot (``{"j1": 30e-6}``: a warmer base
        column; links not named do not grow).

    Returns
    -------
    ndarray, shape (P,)
        Growth of each parameter per kelvin, m/K (0 for the parameters that do not grow), in the order of
        ``robot.params.names``.

    Examples
    --------
    >>> import kincal
    >>> from kincal.simulate import ALUMINIUM, link_growth
    >>> robot = kincal.load_robot("ur5")
    >>> growth = link_growth(robot, ALUMINIUM)
    >>> growth.shape
    (35,)
    >>> [n for n, g in zip(robot.params.names, growth) if g != 0]
    ['j1.d', 'j2.a', 'j3.a', 'j4.d', 'j5.d', 'j6.d']
    >>> f"{growth[robot.params.index('j2.a')] * 1e6:.3f} um/K"  # j2.a = -0.425 m
    '-9.775 um/K'
    >>> growth = link_growth(robot, {"j2": 30e-6})
    >>> [n for n, g in zip(robot.params.names, growth) if g != 0]
    ['j2.a']
    """
    skip = set(robot.base_params())
    rates = np.zeros(robot.n_params)
    for k, (name, kind) in enumerate(zip(robot.params.names, robot.params.kinds)):
        if kind == "length" and name not in skip and not name.startswith("tool."):
            link = name.split(".")[0]
            rates[k] = alpha if not isinstance(alpha, Mapping) else alpha.get(link, 0.0)
    return rates * robot.params.values


def simulate_thermal(true_robot: Robot, q: np.ndarray, temperature: np.ndarray,
                     alpha: float | Mapping[str, float] = ALUMINIUM, reference: float = 20.0, noise: float = 15e-6,
                     seed: int | None = 0, column: str = "temperature") -> Measurements:
    """Simulate tracker measurements of a robot whose links grow with the temperature.

    Each sample is measured on its own copy of ``true_robot``, its links grown by α·(T − ``reference``) at the
    sample's temperature T (:func:`link_growth`), with Gaussian noise of σ = ``noise`` per axis.

    Parameters
    ----------
    true_robot : Robot
        The robot that stands in for the real one, at the reference temperature.
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    temperature : array_like, shape (N,)
        The temperature at each sample, K or °C (as ``reference``), e.g. from :func:`warm_up`.
    alpha : float or mapping of str to float, optional
        Coefficient of thermal expansion, 1/K, for all links or per link (see :func:`link_growth`; default
        ``ALUMINIUM``, 23e-6).
    reference : float, optional
        The temperature at which the links have ``true_robot``'s lengths (default 20.0).
    noise : float, optional
        σ per axis of the measurement noise, m (default 15e-6).
    seed : int or None, optional
        Seed of the noise's random generator (default 0); None draws different noise at every call.
    column : str, optional
        Name of the temperature column (default "temperature").

    Returns
    -------
    Measurements
        Positions xyz (N, 3) m, and q (N, n + 1): the joint values, then the temperature in a column named
        ``column``.

    Raises
    ------
    ValueError
        When ``noise`` is negative or not finite, or ``temperature`` is not one finite value per sample.
    ModelError
        When q does not have one column per joint.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.simulate import simulate_thermal, warm_up
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(5, seed=1)
    >>> meas = simulate_thermal(robot, q, warm_up(5), noise=0.0)
    >>> meas.q.shape, meas.joint_names[-1]
    ((5, 7), 'temperature')
    >>> moved = np.linalg.norm(meas.xyz - robot.forward(q), axis=1)  # m
    >>> [f"{d * 1e6:.0f} um" for d in moved]
    ['0 um', '130 um', '188 um', '221 um', '243 um']
    """
    number("noise", noise, positive=False, unit="m per axis")
    q = true_robot.check_q(q)
    T = np.asarray(temperature, dtype=float).reshape(-1)
    if T.shape != (len(q),) or not np.all(np.isfinite(T)):
        raise ValueError(f"temperature: one finite value per pose ({len(q)}), got shape {T.shape}")
    growth, values = link_growth(true_robot, alpha), true_robot.params.values
    xyz = np.empty((len(q), 3))
    for k in range(len(q)):  # each sample on its own grown robot
        xyz[k] = true_robot.forward(q[k:k + 1], values + growth * (T[k] - reference))[0]
    xyz += noise * np.random.default_rng(seed).standard_normal(xyz.shape)
    return Measurements(np.column_stack([q, T]), xyz, (*true_robot.joint_names, column),
                        source=f"simulated {true_robot.name} warming up")
