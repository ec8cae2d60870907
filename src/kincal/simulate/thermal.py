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
    """(n,) temperatures (K or °C, as ``start``) of a session warming up from ``start`` by ``rise`` with
    time constant ``tau`` samples (default n/3): start + rise·(1 − exp(−k/τ)) at sample k."""
    tau = number("tau", n / 3.0 if tau is None else tau, unit="samples")
    return start + rise * (1.0 - np.exp(-np.arange(int(n)) / tau))


def link_growth(robot: Robot, alpha: float | Mapping[str, float]) -> np.ndarray:
    """(P,) the growth of each parameter per kelvin (m/K): α·L for every link length (kind "length",
    neither base frame nor tool point); ``alpha`` one rate for all links or one per link name prefix
    (``{"j1": 30e-6}``: a warmer base column; links not named do not grow)."""
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
    """Measurements of ``true_robot`` at joints q (N, n) and temperatures (N,): each sample's links
    grown by α·(T − ``reference``) (:func:`link_growth`), Gaussian noise ``noise`` m per axis. The
    result's q is (N, n + 1): the joints, then the temperature in a column named ``column``."""
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
