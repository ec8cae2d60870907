"""The calibration problem: a robot to start from, measurements, the free parameters and the
observation set they are fitted to.

A problem is a frozen value; solvers take one and return a fit. The measured positions become an
observation set of :mod:`kincal.observe` (``RESIDUALS``: a :class:`~kincal.observe.PointObs` for
"cartesian", a :class:`~kincal.observe.JointObs` for "joint"), so the residual, its Jacobian, the
swarm's batched cost and the check that the residual is defined are the observation protocol's.
``build_problem`` registers the measurement frame when the base is estimated, chooses the free
parameters by the base-mode rule of :func:`kincal.analysis.free_parameters`, and checks that the
residual is defined and that there are more equations than unknowns, all before any solver runs.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..analysis.identifiability import Identifiability, free_parameters
from ..errors import IdentifiabilityError, MeasurementError
from ..io.measurements import Measurements
from ..models.robot import Robot
from ..observe import JointObs, Observation, PointObs
from .options import RESIDUAL_NAMES, FitOptions
from .registration import register_base
from .verdict import duplicate_groups, repeat_tolerance



@dataclass(frozen=True, eq=False)
class CalibrationProblem:
    """Fit ``names`` of ``start`` (all other parameters stay at ``values0``) to the observation set
    ``obs`` made of ``meas``.

    ident -- identifiability of the candidates at these poses (``ident.dropped``: not determined)
    """

    start: Robot
    meas: Measurements
    names: tuple[str, ...]
    obs: Observation
    ident: Identifiability
    base: str
    values0: np.ndarray
    repeated_poses: tuple[np.ndarray, ...] = ()  # groups of poses with the same commanded joints (indices)
    weights: np.ndarray | None = None  # (M,) relative weights (σ_median/σ)² of the residual rows from the σ, if given
    evaluated: tuple[np.ndarray, np.ndarray] | None = None  # (r, J over all parameters) at values0, if known

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
        """x -> (r, J): the residual and Jacobian for LM, weighted by the rows' ``weights`` and by
        per-sample ``weights`` (N,) (robust reweighting), if given."""
        cols, rows = self.cols, self.obs.sample_rows()
        sw = None if weights is None else np.sqrt(weights)[rows]
        if self.weights is not None:
            sw = np.sqrt(self.weights) if sw is None else sw * np.sqrt(self.weights)
        x0 = self.x0

        def f(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            if self.evaluated is not None and np.array_equal(x, x0):  # the start, evaluated once
                r, J = self.evaluated[0], self.evaluated[1][:, cols]
            else:
                r, J = self.obs.evaluate_cols(self.start, self.embed(x), cols)
            return (r, J) if sw is None else (r * sw, J * sw[:, None])
        return f

    @property
    def components(self) -> int:
        """Residual rows per pose (3 for positions, n for joints)."""
        return self.obs.sample_rows().size // max(len(self.obs), 1)

    def pose_norms(self, x: np.ndarray) -> np.ndarray:
        """(N,) 3-D position error of every pose at x (m)."""
        return np.linalg.norm(self.meas.xyz - self.start.forward(self.meas.q, self.embed(x)), axis=1)

    def restrict(self, names: Sequence[str], values0: np.ndarray) -> "CalibrationProblem":
        """The same problem with fewer free parameters, the others held at ``values0``."""
        return dataclasses.replace(self, names=tuple(names), values0=np.asarray(values0, float).copy(), evaluated=None)


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
    obs = RESIDUALS[options.residual](meas.q, meas.rows, meas.source, xyz=meas.xyz)
    evaluated = obs.evaluate_cols(start, start.params.values, np.arange(start.n_params)) if obs.kind == "point" \
        else None  # the position Jacobian at the start: the identifiability rule's and the solver's first
    say("checking identifiability")
    auto = options.names == "auto"
    ident = free_parameters(start, meas.q, base, None if auto else options.names, options.keep, options.rank_tol,
                            None if evaluated is None else evaluated[1])
    if not auto and ident.dropped and strict:
        raise IdentifiabilityError(f"these parameters cannot all be identified from the {len(meas)} poses; leave "
                                   f"out the dropped ones or estimate names='auto':\n{ident}")
    names = ident.identifiable if auto or strict else ident.candidates
    rows = obs.sample_rows().size // max(len(obs), 1)
    equations = rows * distinct
    if equations <= len(names):
        raise MeasurementError(
            f"{meas.source}: {distinct} poses give {equations} equations for {len(names)} parameters"
            f"{'' if distinct == len(meas) else f' ({len(meas)} rows, some repeating the same joint values)'}; "
            f"measure at least {len(names) // rows + 1} poses (3-5 times as many is advisable)")
    obs.check(start, start.params.values)
    weights = None if meas.std is None or obs.kind != "point" else (float(np.median(meas.std)) / meas.std).T.ravel() ** 2
    return CalibrationProblem(start, meas, tuple(names), obs, ident, base, start.params.values.copy(), repeated,
                              weights, evaluated)


RESIDUALS = dict(zip(RESIDUAL_NAMES, (PointObs, JointObs)))  # FitOptions.residual -> the observation type fitted
