"""Observation types: what one kind of measurement says about the robot, each a residual object (its interface:
:class:`Observation`). Points on the flange need only the robot's position Jacobian: the tool point is a translation
in the flange frame, so d p / d tool = R (the flange rotation). A full pose also needs the flange's rotation rate per
parameter, :meth:`kincal.models.Robot.frame_and_rates` (a chain reads it off its ops' world axes; any other robot
with a tool point derives it from unit steps of the tool point), so every robot with a tool point gets full poses
and markers."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .._frozen import freeze_arrays
from ..errors import MeasurementError
from ..models.robot import TOOL_NAMES, Robot
from ..models.transforms import skew
from ..models.unit_checks import Framed
from .orientation import nearest_rotation


def so3_left_inverse(phi: np.ndarray) -> np.ndarray:
    """(N, 3, 3) inverse left Jacobian of SO(3) at rotation vectors phi (N, 3): d log(R) = J⁻¹ δθ."""
    th = np.linalg.norm(phi, axis=-1)
    small = th < 1e-6
    ts = np.where(small, 1.0, th)
    c = np.where(small, 1.0 / 12.0, 1.0 / ts**2 - (1 + np.cos(ts)) / (2 * ts * np.sin(ts)))
    K = skew(phi)
    return np.eye(3) - 0.5 * K + c[:, None, None] * (K @ K)


def so3_right(omega: np.ndarray) -> np.ndarray:
    """(3, 3) right Jacobian of SO(3) at the rotation vector omega (3,): R Exp(ω + δ) ≈ R Exp(ω) Exp(Jr δ)."""
    th = float(np.linalg.norm(omega))
    K = skew(omega)
    if th < 1e-6:
        return np.eye(3) - 0.5 * K + K @ K / 6.0
    return np.eye(3) - (1 - np.cos(th)) / th**2 * K + (th - np.sin(th)) / th**3 * (K @ K)


def component_major(r: np.ndarray, J: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, c) residuals and (N, c, P) derivatives -> (N·c,) and (N·c, K) for the columns ``cols``, every sample's
    first component, then the second, …: J is a transposed view of one copy (the kinematics are parameter-major)."""
    return r.T.ravel(), J.transpose(2, 1, 0)[cols].reshape(len(cols), -1).T


def mean_square(r: np.ndarray) -> np.ndarray:
    """(S,) mean of r² over every axis but the first; non-finite rows give inf."""
    with np.errstate(invalid="ignore", over="ignore"):
        val = np.mean(r.reshape(r.shape[0], -1) ** 2, axis=1)
    return np.where(np.isfinite(val), val, np.inf)


def flange_point(robot: Robot, q: np.ndarray, values: np.ndarray, point: np.ndarray):
    """Positions (N, 3) of ``point`` (3,) m in the flange frame, their parameter Jacobian (N, 3, P)
    and the flange rotation (N, 3, 3), which is the Jacobian's tool columns (d p / d point = R)."""
    v, tool = values.copy(), robot.params.indices(TOOL_NAMES)
    v[tool] = point
    p, J = robot.forward_and_jacobian(q, v)
    return p, J, J[:, :, tool]


@dataclass(frozen=True, eq=False)
class Observation:
    """What one kind of measurement says about the robot: the interface of every observation type.

    A set of N samples with their joint values; each type adds what was measured and declares its residual
    (:meth:`evaluate`: predicted − measured, with its derivatives by the robot's parameters and by the set's
    own set-up parameters, :meth:`nuisance`), the noise σ of every residual component (:meth:`sigma`) and
    its statistics. The stacked fit is :func:`kincal.identify.fit_observations`.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        The input rows: each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.

    See Also
    --------
    PointObs, PoseObs, JointObs, MarkersObs, SamePointObs, PlaneObs : The observation types.
    read_observations : A set read from its file.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.observe import Observation
    >>> obs = Observation(np.zeros((3, 6)), np.array([2, 3, 4]), "poses.csv")
    >>> len(obs), obs.kind, obs.reference
    (3, 'observation', True)
    >>> obs.without_rows([3]).rows.tolist()
    [2, 4]
    >>> obs.sigma()
    Traceback (most recent call last):
    ...
    NotImplementedError: observation data declare no σ
    """

    q: np.ndarray
    rows: np.ndarray
    source: str

    kind = "observation"

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @property
    def reference(self) -> bool:
        """Whether the data fix the length scale (absolute positions do)."""
        return True

    def __len__(self) -> int:
        return self.q.shape[0]

    def subset(self, idx: np.ndarray) -> "Observation":
        """The samples ``idx`` (every per-sample array indexed; distances, planes and frames kept)."""
        per_sample = {f.name: v[idx] for f in dataclasses.fields(self)
                      if isinstance(v := vars(self)[f.name], np.ndarray) and v.shape[:1] == (len(self),)}
        return dataclasses.replace(self, **per_sample)

    def without_rows(self, rows) -> "Observation":
        """The set less the samples of the given input rows (file line numbers, header = 1)."""
        unknown = sorted(set(int(r) for r in rows) - set(self.rows.tolist()))
        if unknown:
            raise MeasurementError(f"{self.source}: row(s) {', '.join(map(str, unknown[:10]))} to exclude are not "
                                   f"data rows of the file (data rows are {self.rows.min()}..{self.rows.max()})")
        return self.subset(np.flatnonzero(~np.isin(self.rows, [int(r) for r in rows])))

    def nuisance(self, robot: Robot) -> tuple[tuple[str, ...], np.ndarray, tuple[str, ...]]:
        """Names, start values (at ``robot``) and kinds ('length'/'angle') of the set-up parameters it
        brings (target frame, marker points, socket points, planes)."""
        return (), np.zeros(0), ()

    def gauge_params(self, robot: Robot) -> tuple[str, ...]:
        """Robot parameters these data cannot see (left at their values, named as gauge freedoms): a
        plate's sockets do not see where the robot stands (the base frame)."""
        return ()

    def prepare(self, robot: Robot) -> "Observation":
        """The set ready to fit from ``robot`` (types whose parametrisation depends on the start override)."""
        return self

    def check_known_lengths(self, robot: Robot) -> None:
        """Refuses (MeasurementError) a known length of the set that ``robot`` sees 10-1000x off, naming the unit it
        looks like (types that state lengths, such as a step between known planes, override; also before data
        without a length scale are refused: a step read in another unit may be why there is none)."""

    def positions(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(q, xyz) of the tool point measured in the measurement frame, to register that frame before
        the fit; None for data that see no absolute position."""
        return None

    def flange_positions(self) -> dict:
        """The absolute positions it measured of points on the flange, in the measurement frame, per point: the
        point's name (``tool``: the robot's tool point; ``marker[m1]``: a marker's set-up point) -> (q (N, n),
        xyz (N, 3) m) of the samples that saw it; {} for data that see none: what a "before" model is registered
        to."""
        found = self.positions()
        return {} if found is None else {"tool": found}

    def position_rows(self) -> np.ndarray:
        """(n,) the input rows of the samples :meth:`positions` gives (every sample's by default)."""
        return self.rows

    def positions_point(self, setup: dict) -> np.ndarray | None:
        """The point on the flange (3,) m whose positions :meth:`positions` gives, from the set-up parameters'
        values ``setup`` (name -> m or rad); None for the robot's own tool point (points, poses)."""
        return None

    def framed(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> Framed | None:
        """What a rigid change of its measurement frame moves, sample by sample in the set's order (the measured
        points and rotations against ``robot``'s at ``values`` and ``nuis``): what the frame-jump test judges
        (:func:`kincal.models.unit_checks.frame_jump_test`); None for data that see no absolute position."""
        return None

    def sample_rows(self) -> np.ndarray:
        """The sample each residual row belongs to, (M,); -1 for rows of no one sample (a known
        distance): what a pose design needs to group the rows into per-candidate blocks."""
        raise NotImplementedError(f"{self.kind} data cannot be grouped by sample")

    def sigma(self) -> np.ndarray:
        """(M,) the noise σ of every residual component (m or rad); every type declares it. It whitens the
        problem: mm and mrad are combined by the instrument's noise, never by an arbitrary "1 mm weighs like x mrad"."""
        raise NotImplementedError(f"{self.kind} data declare no σ")

    def covariance(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> np.ndarray | None:
        """(N, c, c) each sample's noise covariance, (m or rad)², its c residual rows in their order, at ``values``
        and ``nuis``, for a type whose sample's components share noise (the joints that reach one measured pose);
        None (the default) where every component's noise is its own, σ (:meth:`sigma`)."""
        return None

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted − measured r (M,), its derivatives by the robot's parameters Jr (M, P) and by the set's
        own nuisance parameters Jn (M, K), at ``values`` and ``nuis``; every type declares it."""
        raise NotImplementedError(f"{self.kind} data declare no residual")

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        """Per-type figures (m, rad) at ``values`` and ``nuis``; every type declares them."""
        raise NotImplementedError(f"{self.kind} data declare no statistics")

    def sample_errors(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple | None:
        """Each sample's errors as :meth:`stats` judges them at ``values`` and ``nuis``, for the report's figures:
        the measured − the model's position (N, 3) m in the measurement frame, and for 6-D data the rotation error
        (N,) rad (else None); None for data without one measured position per sample."""
        return None

    def evaluate_cols(self, robot: Robot, values: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """r (M,) and its derivatives by the robot parameters ``cols`` only (M, K), set-up parameters at their
        starts: the position fit's view (types whose Jacobian is parameter-major override it, saving a copy)."""
        r, Jr, _ = self.evaluate(robot, values, self.nuisance(robot)[1])
        return r, Jr[:, cols]

    def batch_cost(self, robot: Robot, values: np.ndarray) -> np.ndarray:
        """(S,) mean squared residual for S parameter vectors (S, P) at once, inf where one cannot be
        evaluated: what a particle swarm minimises; types that have batched kinematics declare it."""
        raise NotImplementedError(f"a particle swarm cannot fit {self.kind} data")

    def check(self, robot: Robot, values: np.ndarray) -> None:
        """A MeasurementError, before any work, where the residual is undefined (none by default)."""

    def position_axes(self) -> np.ndarray:
        """(M,) the axis (0, 1, 2) of each residual row that is a component of a measured position, −1
        for the others: what a drifting instrument moves; types that measure positions declare it."""
        raise NotImplementedError(f"{self.kind} data measure no position in an instrument's frame")

    def shifted(self, offset: np.ndarray) -> "Observation":
        """The set with each sample's measured positions moved by ``offset`` (N, 3) m (as above)."""
        raise NotImplementedError(f"{self.kind} data measure no position in an instrument's frame")

    def refitted(self, robot: Robot) -> tuple[str, ...]:
        """Robot and set-up parameters the set re-fits as its own when it is held out, beside its
        measurement frame (a 6-D target defined anew: its point and rotation); none by default."""
        return ()

    def anchors(self) -> dict:
        """Start values its set-up parameters are measured from, which every set sharing them must share (a
        pose target's start rotation); none by default."""
        return {}

    def with_anchors(self, anchors: dict) -> "Observation":
        """The set measured from the given anchors (the first set's, when several share a target)."""
        return self


def error_stats(obs: Observation, e: np.ndarray, **counts) -> dict:
    """The summary of an observation's errors ``e`` (m, one per sample or per observed point): its type,
    source and samples, then ``counts`` (e.g. markers=4), then the mean, RMS and largest error (m;
    :func:`kincal.units.in_display` shows them in mm)."""
    return {"type": obs.kind, "source": obs.source, "samples": len(obs), **counts, "mean": float(e.mean()),
            "rms": float(np.sqrt(np.mean(e**2))), "max": float(e.max())}


@dataclass(frozen=True, eq=False)
class Wrapper(Observation):
    """A set built on another, ``inner`` (a session's own frame, a drifting instrument): its type, σ,
    rows, positions, anchors and set-up start are the inner set's unless the wrapper says otherwise."""

    inner: Observation

    def __post_init__(self) -> None:  # the inner set's type (frozen: it cannot be assigned afterwards)
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place
        object.__setattr__(self, "kind", self.inner.kind)

    @classmethod
    def of(cls, inner: Observation, *fields) -> "Wrapper":
        """``inner`` wrapped (its samples, rows and source); ``fields``: the wrapper's own, in order."""
        return cls(inner.q, inner.rows, inner.source, inner, *fields)

    @property
    def reference(self) -> bool:
        return self.inner.reference

    def subset(self, idx: np.ndarray) -> "Wrapper":
        return dataclasses.replace(self, q=self.q[idx], rows=self.rows[idx], inner=self.inner.subset(idx))

    def positions(self):
        return self.inner.positions()

    def flange_positions(self) -> dict:
        return self.inner.flange_positions()

    def position_rows(self) -> np.ndarray:
        return self.inner.position_rows()

    def positions_point(self, setup: dict) -> np.ndarray | None:
        return self.inner.positions_point(setup)

    def framed(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> Framed | None:
        """The inner set's, its own set-up parameters first in ``nuis`` (the measurements as given: a session's frame
        is one more rigid frame, which the test fits; a drift, which it weighs the jump against)."""
        return self.inner.framed(robot, values, nuis[:len(self.inner.nuisance(robot)[1])])

    def prepare(self, robot: Robot) -> "Wrapper":
        return dataclasses.replace(self, inner=self.inner.prepare(robot))

    def check_known_lengths(self, robot: Robot) -> None:
        self.inner.check_known_lengths(robot)

    def anchors(self) -> dict:
        return self.inner.anchors()

    def refitted(self, robot: Robot) -> tuple[str, ...]:
        return self.inner.refitted(robot)

    def with_anchors(self, anchors: dict) -> "Wrapper":
        return dataclasses.replace(self, inner=self.inner.with_anchors(anchors))

    def gauge_params(self, robot: Robot) -> tuple[str, ...]:
        return self.inner.gauge_params(robot)

    def sigma(self) -> np.ndarray:
        return self.inner.sigma()

    def sample_rows(self) -> np.ndarray:
        return self.inner.sample_rows()

    def position_axes(self) -> np.ndarray:
        return self.inner.position_axes()

    def shifted(self, offset: np.ndarray) -> "Wrapper":
        return dataclasses.replace(self, inner=self.inner.shifted(offset))


@dataclass(frozen=True, eq=False)
class MeasuredPositions(Observation):
    """A set with one measured tool position per sample, xyz (N, 3) m in the measurement frame: its
    positions, the set with them moved, the statistics of their errors (types with more override them) and, for
    types without set-up parameters, the residual of :meth:`evaluate_cols` over every robot parameter."""

    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        r, J = self.evaluate_cols(robot, values, np.arange(robot.n_params))
        return r, J, np.zeros((r.size, 0))

    def positions(self):
        return self.q, self.xyz

    def framed(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> Framed:
        return Framed.of(self.xyz, robot.forward(self.q, values))

    def shifted(self, offset: np.ndarray) -> "MeasuredPositions":
        return dataclasses.replace(self, xyz=self.xyz + offset)

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        return error_stats(self, np.linalg.norm(robot.forward(self.q, values) - self.xyz, axis=1))

    def sample_errors(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple | None:
        return self.xyz - robot.forward(self.q, values), None


@dataclass(frozen=True, eq=False)
class PointObs(MeasuredPositions):
    """One 3-D point per sample (a tracker's reflector), measured in the measurement frame.

    The measurement frame is given by the robot's base frame parameters. The residual is the tool point's
    predicted − measured position, component by component: the x of every sample, then y, then z.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    xyz : ndarray, shape (N, 3)
        The measured points, m.
    std : ndarray, shape (N, 3), or float, optional
        σ per sample and axis, or one number for all, m (default 15e-6: a laser tracker's).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import PointObs
    >>> robot = kincal.load_robot("ur5")
    >>> meas = kincal.simulate(robot, robot.sample_joints(6, seed=1), noise=15e-6, seed=0)
    >>> obs = PointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz, std=15e-6)
    >>> obs.kind, len(obs), obs.reference, obs.positions() is not None
    ('point', 6, True, True)
    >>> r, Jr, Jn = obs.evaluate(robot, robot.params.values, np.zeros(0))
    >>> r.shape, Jr.shape == (18, robot.n_params), Jn.shape, obs.sigma().shape
    ((18,), True, (18, 0), (18,))
    >>> bool(np.abs(r).max() < 6 * 15e-6)
    True
    """

    std: np.ndarray | float = 15e-6
    kind = "point"

    def sample_rows(self) -> np.ndarray:
        return np.tile(np.arange(len(self)), 3)

    def sigma(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.std, float), self.xyz.shape).T.ravel()

    def evaluate_cols(self, robot: Robot, values: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, J = robot.forward_and_jacobian(self.q, values)
        return component_major(p - self.xyz, J, cols)

    def batch_cost(self, robot: Robot, values: np.ndarray) -> np.ndarray:
        return mean_square(robot.forward_batch(self.q, values) - self.xyz)

    def position_axes(self) -> np.ndarray:
        return np.repeat(np.arange(3), len(self))


@dataclass(frozen=True, eq=False)
class PoseObs(MeasuredPositions):
    """Full 6-D poses of a target frame on the flange, measured in the measurement frame.

    The target's origin is the tool point; its orientation on the flange is ``target_rotation`` times a fitted
    rotation vector (the set-up parameters ``target.rx/ry/rz``, rad). The residual is the position error (m)
    and the rotation error (rad: the world-frame rotation vector of predicted·measuredᵀ) of every sample.

    Parameters
    ----------
    q : ndarray, shape (N, n)
        Joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    xyz : ndarray, shape (N, 3)
        The measured positions of the target's origin, m.
    R : ndarray, shape (N, 3, 3)
        The measured rotations of the target (columns: its axes in the measurement frame).
    target_rotation : ndarray, shape (3, 3), optional
        The target's orientation on the flange that the fitted rotation vector starts from (default identity;
        :meth:`prepare` sets it from the data unless ``anchored``).
    std_pos : ndarray, shape (N,), or float, optional
        σ of the positions per axis, per sample or one number, m (default 0.1e-3).
    std_rot : ndarray, shape (N,), or float, optional
        σ of the rotations per axis, per sample or one number, rad (default 1e-3).
    anchored : bool, optional
        The target rotation was given (another set's, a training file's): :meth:`prepare` keeps it (default
        False).
    own_target : bool, optional
        Held out: the target's point and rotation are re-fitted, a rigid body defined anew (default False).

    Examples
    --------
    Poses of the nominal "ur5", with a target turned 90° about the flange's z axis:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import PoseObs
    >>> robot = kincal.load_robot("ur5")
    >>> q = robot.sample_joints(5, seed=1)
    >>> p, R, _, _ = robot.pose_and_jacobian(q)  # the tool point and the flange's rotation
    >>> turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    >>> obs = PoseObs(q, np.arange(2, 7), "poses.csv", xyz=p, R=R @ turn, std_pos=50e-6, std_rot=0.5e-3)
    >>> obs.kind, obs.sigma().shape, obs.nuisance(robot)[0]
    ('pose', (30,), ('target.rx', 'target.ry', 'target.rz'))
    >>> bool(np.allclose(obs.prepare(robot).target_rotation, turn))
    True
    """

    R: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    target_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    std_pos: np.ndarray | float = 0.1e-3
    std_rot: np.ndarray | float = 1e-3
    anchored: bool = False  # the target rotation given (another set's, a training file's): prepare keeps it
    own_target: bool = False  # held out: the target's point and rotation are re-fitted (a rigid body defined anew)
    kind = "pose"

    def prepare(self, robot: Robot) -> "PoseObs":
        """A copy whose target rotation starts at the chordal mean of flangeᵀ·measured over the samples
        (unless one was given: ``with_anchors``)."""
        if self.anchored:
            return self
        _, _, Rf = flange_point(robot, self.q, robot.params.values, robot.tool_point())
        return dataclasses.replace(self, target_rotation=nearest_rotation(np.sum(Rf.transpose(0, 2, 1) @ self.R, 0)))

    def nuisance(self, robot: Robot):
        return ("target.rx", "target.ry", "target.rz"), np.zeros(3), ("angle",) * 3

    def registered_turn(self, robot: Robot) -> np.ndarray:
        """The target's turn (3,) rad (``target.rx/ry/rz``, from ``target_rotation``) that best fits the measured
        rotations with ``robot`` as it is (the chordal mean of flangeᵀ·measured): the target registered to these
        data, as a "before" figure takes it."""
        from ..models.transforms import rotation_log

        _, _, Rf = flange_point(robot, self.q, robot.params.values, robot.tool_point())
        best = nearest_rotation(np.sum(Rf.transpose(0, 2, 1) @ self.R, 0))
        return rotation_log((self.target_rotation.T @ best)[None])[0]

    def anchors(self) -> dict:
        return {"target_rotation": self.target_rotation}

    def refitted(self, robot: Robot) -> tuple[str, ...]:
        return (*TOOL_NAMES, *self.nuisance(robot)[0]) if self.own_target else ()

    def sample_rows(self) -> np.ndarray:
        return np.tile(np.arange(len(self)), 6)

    def position_axes(self) -> np.ndarray:
        return np.concatenate([np.repeat(np.arange(3), len(self)), np.full(3 * len(self), -1)])

    def with_anchors(self, anchors: dict) -> "PoseObs":
        if "target_rotation" not in anchors:
            return self
        return dataclasses.replace(self, target_rotation=anchors["target_rotation"], anchored=True)

    def sigma(self) -> np.ndarray:
        sp, sr = (np.broadcast_to(np.asarray(s, float), (len(self),)) for s in (self.std_pos, self.std_rot))
        return np.concatenate([sp, sp, sp, sr, sr, sr])

    def framed(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> Framed:
        """The positions and the rotations, a rotation's σ weighed as its position's (:class:`Framed`)."""
        v = robot.param_values(values)
        p, _, Rf = flange_point(robot, self.q, v, v[robot.params.indices(TOOL_NAMES)])
        sp, sr = (np.broadcast_to(np.asarray(s, float), (len(self),)) for s in (self.std_pos, self.std_rot))
        return Framed.of(self.xyz, p, self.R, Rf @ self.target(nuis), sp / (np.sqrt(2.0) * sr))

    def target(self, nuis: np.ndarray) -> np.ndarray:
        from scipy.spatial.transform import Rotation
        return self.target_rotation @ Rotation.from_rotvec(nuis[:3]).as_matrix()

    def errors(self, robot: Robot, values: np.ndarray, nuis: np.ndarray, jacobian: bool = True):
        """Position errors (N, 3) m, rotation errors (N, 3) rad (world-frame rotation vectors of
        predicted·measuredᵀ) and, with ``jacobian``, their derivatives."""
        from scipy.spatial.transform import Rotation
        v = robot.param_values(values)
        if jacobian:  # the flange's rotation rate per parameter: Robot.frame_and_rates
            p, J, Rf, Jw = robot.frame_and_rates(self.q, v)
        else:
            p, J, Rf = flange_point(robot, self.q, v, v[robot.params.indices(TOOL_NAMES)])
        Rt = self.target(nuis)
        phi = Rotation.from_matrix(Rf @ Rt @ self.R.transpose(0, 2, 1)).as_rotvec()
        if not jacobian:
            return p - self.xyz, phi, None
        Linv = so3_left_inverse(phi)
        return p - self.xyz, phi, (J, Linv @ Jw, Linv @ (Rf @ (Rt @ so3_right(nuis[:3]))))

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        dp, phi, (J, Jrot, Jn) = self.errors(robot, values, nuis)  # rows: x, y, z, then the 3 rotation components
        return (np.concatenate([dp, phi], axis=1).T.ravel(),
                np.concatenate([J, Jrot], axis=1).transpose(1, 0, 2).reshape(-1, J.shape[2]),
                np.concatenate([np.zeros_like(Jn), Jn], axis=1).transpose(1, 0, 2).reshape(-1, 3))

    def sample_errors(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple | None:
        dp, phi, _ = self.errors(robot, values, nuis, jacobian=False)
        return -dp, np.linalg.norm(phi, axis=1)

    def stats(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> dict:
        dp, phi, _ = self.errors(robot, values, nuis, jacobian=False)
        rot = error_stats(self, np.linalg.norm(phi, axis=1))
        return error_stats(self, np.linalg.norm(dp, axis=1)) | {f"{k}_rotation": rot[k] for k in ("mean", "rms", "max")}
