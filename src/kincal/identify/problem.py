"""The calibration problem: a robot to start from, measurements, the free parameters and a residual.

A problem is a frozen value; solvers take one and return a fit. ``build_problem`` registers the
measurement frame when the base is estimated, chooses the free parameters by the base-mode rule of
:func:`kincal.analysis.free_parameters`, and checks that the residual is defined and that there are
more equations than unknowns, all before any solver runs.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from ..analysis.identifiability import Identifiability, free_parameters
from ..errors import IdentifiabilityError, MeasurementError
from ..io.measurements import Measurements
from ..models.robot import Robot
from .registration import register_base
from .residuals import RESIDUALS, CartesianResidual, JointResidual
from .verdict import duplicate_groups, repeat_tolerance

if TYPE_CHECKING:
    from .options import FitOptions


@dataclass(frozen=True, eq=False)
class CalibrationProblem:
    """Fit ``names`` of ``start`` (all other parameters stay at ``values0``) to ``residual``.

    ident -- identifiability of the candidates at these poses (``ident.dropped``: not determined)
    """

    start: Robot
    meas: Measurements
    names: tuple[str, ...]
    residual: CartesianResidual | JointResidual
    ident: Identifiability
    base: str
    values0: np.ndarray
    repeated_poses: tuple[np.ndarray, ...] = ()  # groups of poses with the same commanded joints (indices)
    weights: np.ndarray | None = None  # (N, 3) relative weights (σ_median/σ)² from the measurement σ, if given

    @property
    def cols(self) -> np.ndarray:
        return self.start.params.indices(self.names)

    @property
    def x0(self) -> np.ndarray:
        return self.values0[self.cols]

    def embed(self, x: np.ndarray) -> np.ndarray:
        """The full parameter vector (P,) with the free parameters set to x (K,)."""
        v = self.values0.copy()
        v[self.cols] = x
        return v

    def embed_many(self, X: np.ndarray) -> np.ndarray:
        """(S, P) parameter vectors for S vectors of free parameters (S, K)."""
        V = np.tile(self.values0, (X.shape[0], 1))
        V[:, self.cols] = X
        return V

    def fun(self, weights: np.ndarray | None = None) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """x -> (r, J): the (optionally per-pose weighted) stacked residual and Jacobian for LM."""
        cols = self.cols
        sw = None if weights is None else np.tile(np.sqrt(weights), self.residual.components)
        if self.weights is not None and self.residual.components == 3:  # component-major, as the residual
            base = np.sqrt(self.weights).T.ravel()
            sw = base if sw is None else sw * base

        def f(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r, J = self.residual.evaluate(self.embed(x), cols)
            return (r, J) if sw is None else (r * sw, J * sw[:, None])
        return f

    def pose_norms(self, x: np.ndarray) -> np.ndarray:
        """(N,) 3-D position error of every pose at x (m)."""
        return np.linalg.norm(self.residual.pose_errors(self.embed(x)), axis=1)

    def restrict(self, names: Sequence[str], values0: np.ndarray) -> "CalibrationProblem":
        """The same problem with fewer free parameters, the others held at ``values0``."""
        return dataclasses.replace(self, names=tuple(names), values0=np.asarray(values0, float).copy())


def build_problem(robot: Robot, meas: Measurements, options: FitOptions,
                  say: Callable[[str], None] = lambda msg: None) -> CalibrationProblem:
    """Register, choose the free parameters, check the data. With Levenberg–Marquardt an explicit
    list of ``options.names`` must be identifiable; a particle swarm (a global search) keeps the
    undetermined ones free."""
    base, strict = options.base, options.method == "lm"
    meas.check_robot(robot)
    start = robot
    repeated = tuple(duplicate_groups(meas.q, repeat_tolerance(robot.joint_types, options.thresholds)))
    distinct = len(meas) - sum(len(g) - 1 for g in repeated)
    if base == "estimate":
        if distinct < 3:
            raise MeasurementError(f"{meas.source}: registering the base frame needs at least 3 distinct poses, got "
                                   f"{distinct} ({len(meas)} rows); measure poses spread over the workspace")
        say("registering the measurement frame")
        start = register_base(robot, meas.q, meas.xyz)
    say("checking identifiability")
    auto = options.names == "auto"
    ident = free_parameters(start, meas.q, base, None if auto else options.names, options.keep, options.rank_tol)
    if not auto and ident.dropped and strict:
        raise IdentifiabilityError(f"these parameters cannot all be identified from the {len(meas)} poses; leave "
                                   f"out the dropped ones or estimate names='auto':\n{ident}")
    names = ident.identifiable if auto or strict else ident.candidates
    res = RESIDUALS[options.residual](start, meas)
    equations = res.components * distinct
    if equations <= len(names):
        raise MeasurementError(
            f"{meas.source}: {distinct} poses give {equations} equations for {len(names)} parameters"
            f"{'' if distinct == len(meas) else f' ({len(meas)} rows, some repeating the same joint values)'}; "
            f"measure at least {len(names) // res.components + 1} poses (3-5 times as many is advisable)")
    res.check(start.params.values)
    weights = None if meas.std is None else (float(np.median(meas.std)) / meas.std) ** 2
    return CalibrationProblem(start, meas, tuple(names), res, ident, base, start.params.values.copy(), repeated,
                              weights)
