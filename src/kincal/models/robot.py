"""The `Robot` interface every model (serial, hybrid, parallel) implements.

A robot is an immutable value (a frozen dataclass) with a ``name``, a ``description``, its named
parameters ``params`` and its ``joint_space`` (joint names, types and read-only limits). Everything a
robot can do is declared here, so callers never probe for an attribute; a robot that lacks an
ability says so with a :class:`~kincal.errors.ModelError` through the same method:

* kinematics (batched: the first axis of ``q`` is the configuration; a single (n,) vector gives
  unbatched results): ``forward``, ``forward_and_jacobian``, ``param_jacobian``, ``joint_jacobian``,
  ``forward_jacobians``, ``forward_batch``. A subclass implements the batched hooks
  ``_forward_and_jacobian`` and ``_joint_jacobian``; shapes are handled here, once;
* joints (:class:`~kincal.models.joint_space.Joints`): ``joint_names``, ``joint_types``, ``lower``,
  ``upper``, ``check_q``, ``within_limits``, ``feasible`` (coupled constraints too), ``sample_joints``
  (feasible poses only);
* parameters: ``with_params`` (one implementation: a copy with new values, re-validated),
  ``param_values``, ``preferred_params`` (kept first among confounded ones), ``structure_notes``;
* the base frame: ``base_params``, ``base_transform``, ``with_base_transform``;
* inverse kinematics (``has_inverse``): ``inverse``, ``inverse_and_jacobian``, ``inverse_batch``,
  ``inverse_rates``;
* the error model beyond geometry: ``error_model``, ``term_names``, ``corrected``, ``compliances``;
* gravity loads of link masses (``has_gravity``): ``gravity``; Hayati's β tilts (``has_beta``):
  ``without_beta``.

A robot built on another one is a :class:`~kincal.models.wrapped.Wrapped` robot; the robot it wraps
is ``inner``.
"""
from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from contextlib import suppress
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Literal, Mapping, Sequence, TypeVar, overload

import numpy as np

from ..errors import ModelError
from .joint_space import Joints, JointSpace
from .parameters import Parameters
from .transforms import rot_zyx, zyx_from_matrix

if TYPE_CHECKING:
    from .gravity import GravityModel

TOOL_NAMES = ("tool.x", "tool.y", "tool.z")  # the measured point in the flange frame (m), where a model has one
R = TypeVar("R", bound="Robot")
ParamValues = Mapping[str, float] | Sequence[float] | np.ndarray | Parameters


class Robot(Joints, ABC):
    """A robot with named joints, joint limits and a named parameter vector: the interface of every model.

    Everything a robot can do is declared here (see the module docstring for the whole interface), so callers
    never probe for an attribute; a model that lacks an ability says so with a ModelError. Subclasses are frozen
    dataclasses that set ``name``, ``description``, ``params`` and ``joint_space`` and implement the two batched
    kinematic hooks ``_forward_and_jacobian`` and ``_joint_jacobian``. Units are SI (m, rad).

    Attributes
    ----------
    name : str
        The robot's name (e.g. "ur5").
    description : str
        Free text from the robot file.
    params : Parameters
        The named parameters (P,), SI units.
    joint_space : JointSpace
        Names, types and read-only limits of the n joints (and any covariate inputs after them).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> robot = kincal.load_robot("ur5")
    >>> robot.name, robot.n_joints, robot.n_params, robot.structure
    ('ur5', 6, 35, 'dh')
    >>> robot.joint_names
    ('j1', 'j2', 'j3', 'j4', 'j5', 'j6')
    >>> q = robot.sample_joints(10, seed=1)
    >>> robot.forward(q).shape, robot.param_jacobian(q).shape, robot.joint_jacobian(q).shape
    ((10, 3), (10, 3, 35), (10, 3, 6))
    >>> bool(robot.feasible(q).all())
    True
    """

    name: str
    description: str
    params: Parameters
    joint_space: JointSpace

    has_inverse: ClassVar[bool] = False  # closed-form inverse kinematics of positions
    has_pose_inverse: ClassVar[bool] = False  # closed-form inverse kinematics of whole poses (a hexapod's legs)
    has_gravity: ClassVar[bool] = False  # a chain whose links can carry masses (gravity terms)
    has_load_compliance: ClassVar[bool] = False  # its own model of giving under its load (a hexapod's legs)

    # ---- what a model implements (batched: q (N, n), values (P,)) -------------------------------
    @abstractmethod
    def _forward_and_jacobian(self, q: np.ndarray, values: np.ndarray,
                              jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Tool positions (N, 3) and parameter Jacobian (N, 3, P) (None unless ``jacobian``)."""

    @abstractmethod
    def _joint_jacobian(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """d position / d joint values, (N, 3, n)."""

    def _forward_jacobians(self, q: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, J = self._forward_and_jacobian(q, values, True)
        assert J is not None  # asked for
        return p, J, self._joint_jacobian(q, values)

    def _pose_and_jacobian(self, q: np.ndarray, values: np.ndarray):
        """Generic: the flange axes are where a unit step of the tool point along each moves it, and
        the angular velocity ω follows from those axes' rates, ω = ½ Σₖ aₖ × ȧₖ (exact)."""
        steps = self._tool_steps(values)
        p0, J0 = self._forward_and_jacobian(q, values, False)[0], self._joint_jacobian(q, values)
        R = np.stack([self._forward_and_jacobian(q, v, False)[0] - p0 for v in steps], axis=2)
        Jw = sum(0.5 * np.cross(R[:, :, k, None], self._joint_jacobian(q, v) - J0, axis=1) for k, v in enumerate(steps))
        return p0, R, J0, Jw

    def _frame_and_rates(self, q: np.ndarray, values: np.ndarray):
        """Generic: the flange axes aₖ are the tool point's Jacobian columns (a translation in the
        flange frame), their rates the Jacobian's change for a unit step of the tool point along each,
        and the rotation rate is ½ Σₖ aₖ × d aₖ (exact: positions are linear in the tool point)."""
        p, J = self._forward_and_jacobian(q, values, True)
        assert J is not None  # asked for
        R = J[:, :, self.params.indices(TOOL_NAMES)]
        Jw = sum(0.5 * np.cross(R[:, :, k, None], self._forward_and_jacobian(q, v, True)[1] - J, axis=1)
                 for k, v in enumerate(self._tool_steps(values)))
        return p, J, R, Jw

    # ---- kinematics ------------------------------------------------------------------------------
    def _batched(self, hook: Callable[..., Any], q, values, *args):
        """``hook`` on q as (N, n) and values as (P,); a single (n,) q gives unbatched results."""
        out = hook(self.check_q(q), self.param_values(values), *args)
        if np.ndim(q) != 1:
            return out
        return tuple(None if a is None else a[0] for a in out) if isinstance(out, tuple) else out[0]

    @overload
    def forward_and_jacobian(self, q: np.ndarray, values: np.ndarray | None = None,
                             jacobian: Literal[True] = True) -> tuple[np.ndarray, np.ndarray]: ...
    @overload
    def forward_and_jacobian(self, q: np.ndarray, values: np.ndarray | None = None, *,
                             jacobian: Literal[False]) -> tuple[np.ndarray, None]: ...

    def forward_and_jacobian(self, q: np.ndarray, values: np.ndarray | None = None,
                             jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Tool positions and their parameter Jacobian in one pass.

        Parameters
        ----------
        q : ndarray, shape (N, n)
            Joint values, rad (m for a prismatic joint); a single (n,) vector gives unbatched results.
        values : ndarray, shape (P,), optional
            Parameter values, SI units (default: the robot's own).
        jacobian : bool, optional
            Compute the Jacobian too (default True).

        Returns
        -------
        p : ndarray, shape (N, 3)
            Positions of the tool point in the world frame, m.
        J : ndarray, shape (N, 3, P), or None
            ∂p/∂parameters (m per parameter unit), columns in the order of ``params.names``; None unless
            ``jacobian``.
        """
        return self._batched(self._forward_and_jacobian, q, values, jacobian)

    def frame_and_rates(self, q: np.ndarray, values: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Tool positions (N, 3) m, their parameter Jacobian (N, 3, P), the flange rotation (N, 3, 3:
        columns are its axes in the world) and its rotation rate per parameter (N, 3, P) (rad per
        parameter unit, world frame): what a full 6-D pose measurement needs, in one call."""
        return self._batched(self._frame_and_rates, q, values)

    def forward(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """Forward kinematics: the tool point's position in the world frame.

        Parameters
        ----------
        q : ndarray, shape (N, n)
            Joint values, rad (m for a prismatic joint); a single (n,) vector gives one (3,) position.
        values : ndarray, shape (P,), optional
            Parameter values, SI units (default: the robot's own).

        Returns
        -------
        ndarray, shape (N, 3)
            Positions of the tool point in the world frame, m.

        Raises
        ------
        ModelError
            When q does not have one column per joint, ``values`` has the wrong size, or (a closed chain) a
            configuration does not assemble.

        Examples
        --------
        >>> import numpy as np
        >>> import kincal
        >>> robot = kincal.load_robot("ur5")
        >>> np.round(robot.forward(np.zeros(6)), 6).tolist()
        [-0.81725, -0.22245, -0.005401]
        >>> robot.forward(np.zeros((4, 6))).shape
        (4, 3)
        """
        return self.forward_and_jacobian(q, values, jacobian=False)[0]

    def param_jacobian(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """The parameter Jacobian: derivatives of the tool point's position by every parameter.

        Parameters
        ----------
        q : ndarray, shape (N, n)
            Joint values, rad (m for a prismatic joint); a single (n,) vector gives one (3, P) Jacobian.
        values : ndarray, shape (P,), optional
            Parameter values at which to differentiate, SI units (default: the robot's own).

        Returns
        -------
        ndarray, shape (N, 3, P)
            ∂p/∂parameters: m/m for a length, m/rad for an angle; columns in the order of ``params.names``.

        Examples
        --------
        >>> import numpy as np
        >>> import kincal
        >>> robot = kincal.load_robot("ur5")
        >>> q = robot.sample_joints(3, seed=1)
        >>> J = robot.param_jacobian(q)
        >>> J.shape
        (3, 3, 35)
        >>> J[:, :, robot.params.index("base.x")].tolist()  # the base frame's x moves every pose along x
        [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]

        A column against a finite difference:

        >>> k, h = robot.params.index("j2.a"), 1e-7
        >>> v = robot.params.values.copy()
        >>> v[k] += h
        >>> bool(np.allclose((robot.forward(q, v) - robot.forward(q)) / h, J[:, :, k], atol=1e-6))
        True
        """
        return self.forward_and_jacobian(q, values)[1]

    def joint_jacobian(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """The joint Jacobian: derivatives of the tool point's position by the joint values.

        Parameters
        ----------
        q : ndarray, shape (N, n)
            Joint values, rad (m for a prismatic joint); a single (n,) vector gives one (3, n) Jacobian.
        values : ndarray, shape (P,), optional
            Parameter values, SI units (default: the robot's own).

        Returns
        -------
        ndarray, shape (N, 3, n)
            ∂p/∂q: m/rad for a revolute joint, m/m for a prismatic one.
        """
        return self._batched(self._joint_jacobian, q, values)

    def forward_jacobians(self, q: np.ndarray, values: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (N, 3), parameter Jacobian (N, 3, P) and joint Jacobian (N, 3, n); chains give
        all three from one pass."""
        return self._batched(self._forward_jacobians, q, values)

    def pose_and_jacobian(self, q: np.ndarray, values: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Tool point (N, 3) m, flange orientation (N, 3, 3) (columns: its axes in the world) and the
        joint Jacobians of the tool point and of the flange's angular velocity, (N, 3, n) each."""
        return self._batched(self._pose_and_jacobian, q, values)

    def forward_batch(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Positions (S, N, 3) m for S parameter vectors ``values`` (S, P) at the same joints q (N, n),
        as a particle swarm needs; rows that cannot be computed are NaN. This default calls
        ``forward`` once per vector; models with a batched path override it."""
        q = self.check_q(q)
        out = np.full((len(values), q.shape[0], 3), np.nan)
        for k, v in enumerate(np.asarray(values, dtype=float)):
            with suppress(ModelError):
                out[k] = self.forward(q, v)
        return out

    # ---- inverse kinematics (has_inverse) --------------------------------------------------------
    def _no_inverse(self) -> ModelError:
        return ModelError(f"robot '{self.name}' ({self.structure}) has no closed-form inverse kinematics; give "
                          f"nominal joint values to start from, or use residual='cartesian'")

    def inverse(self, p: np.ndarray, values: np.ndarray | None = None, strict: bool = True) -> np.ndarray:
        """Joint values (N, n) that place the tool at world positions p (N, 3); unreachable positions
        raise a ModelError, or give NaN rows when not ``strict``."""
        raise self._no_inverse()

    def inverse_and_jacobian(self, p: np.ndarray, values: np.ndarray | None = None
                             ) -> tuple[np.ndarray, np.ndarray]:
        """Joint values (N, n) for positions p (N, 3) and their parameter derivatives at fixed p, (N, n, P)."""
        raise self._no_inverse()

    def inverse_batch(self, p: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Joint values (S, N, n) for positions p (N, 3) and S parameter vectors (S, P); NaN where out of reach."""
        raise self._no_inverse()

    def inverse_rates(self, p: np.ndarray, values: np.ndarray | None = None,
                      R: np.ndarray | None = None) -> np.ndarray:
        """The closed-form inverse's derivatives by what it starts from, at tool points p (N, 3) m: by a world
        translation of p, (N, n, 3) rad or m per m; with the flange's world rotations R (N, 3, 3) (a pose inverse),
        by that translation and then by a turn of the pose about world axes through p, (N, n, 6) (per m, then per
        rad): how the noise of a measured position or pose reaches the joints."""
        raise self._no_inverse()

    def inverse_pose(self, R: np.ndarray, p: np.ndarray, values: np.ndarray | None = None,
                     strict: bool = True) -> np.ndarray:
        """Joint values (N, n) that put the flange frame at world rotations R (N, 3, 3) with the tool point at
        world positions p (N, 3) m, in closed form (a hexapod's legs from its platform pose)."""
        raise self._no_inverse()

    def inverse_pose_and_jacobian(self, R: np.ndarray, p: np.ndarray, values: np.ndarray | None = None
                                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint values (N, n) for flange poses (R (N, 3, 3), tool points p (N, 3)), their parameter
        derivatives at the fixed pose (N, n, P) and their derivatives by a turn of the pose about world
        axes through the tool point (N, n, 3)."""
        raise self._no_inverse()

    # ---- parameters ------------------------------------------------------------------------------
    @property
    def n_params(self) -> int:
        return len(self.params)

    @property
    def structure(self) -> str:
        """The kinematic structure in a few words (e.g. 'dh', 'mdh', 'urdf', 'puu3 (implicit)')."""
        return type(self).__name__

    def param_values(self, values: np.ndarray | None) -> np.ndarray:
        """``values`` as a (P,) array (the robot's own when None); ModelError for another size."""
        if values is None:
            return self.params.values
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.size != self.n_params:
            raise ModelError(f"{self.name}: expected {self.n_params} parameter values, got {v.size}")
        return v

    def with_params(self: R, values: ParamValues) -> R:
        """A copy of the robot with changed parameter values (the robot itself is never changed).

        Parameters
        ----------
        values : mapping of str to float, ndarray of shape (P,), or Parameters
            New values by name (the others keep theirs), a full vector, or Parameters of the same names and
            kinds; SI units.

        Returns
        -------
        Robot
            A robot of the same type and structure with the new values.

        Raises
        ------
        ModelError
            When a name is unknown, the vector has the wrong size, the Parameters' names or kinds differ, or
            the model refuses the values.

        Examples
        --------
        >>> import kincal
        >>> robot = kincal.load_robot("ur5")
        >>> longer = robot.with_params({"j2.a": -0.426})
        >>> longer.params["j2.a"], robot.params["j2.a"], type(longer).__name__
        (-0.426, -0.425, 'SerialRobot')
        """
        new = values if isinstance(values, Parameters) else self.params.replace(values)
        if (new.names, new.kinds) != (self.params.names, self.params.kinds):
            raise ModelError(f"robot '{self.name}': the new parameters must have the same names and kinds")
        return self._rebuild(new)

    def _rebuild(self: R, params: Parameters) -> R:
        """A copy with ``params`` (a frozen dataclass is re-validated by its __post_init__)."""
        if not dataclasses.is_dataclass(self):
            raise ModelError(f"robot '{self.name}': a robot that is not a dataclass must override _rebuild")
        return dataclasses.replace(self, params=params)

    def reading_terms(self) -> str:
        """What of the model acts on the joint readings themselves, in words ('the terms (compliance)',
        'the legs' zeros and scales'): fitted on the training joint ranges, it extrapolates beyond them;
        '' for none (a geometric serial chain)."""
        return "" if self.error_model == "geometric" else f"the terms ({self.error_model})"

    def frame_freedoms(self) -> tuple[tuple[str, tuple[str, ...], int], ...]:
        """Gauge freedoms of design frames: (what they are, the parameters among which they lie, how
        many), e.g. where a hexapod's robot frame stands among its base points (6); the rank rule holds
        that many of those parameters at their values, which changes no prediction. None by default."""
        return ()

    def mounting_params(self) -> tuple[str, ...]:
        """Parameters whose design frame is not the frame they are measured in (a hexapod's base and
        platform points, its legs' zero lengths): judged by the verdict's mounting limits, not a serial
        arm's; none by default."""
        return ()

    def preferred_params(self) -> tuple[str, ...]:
        """Names to keep first when parameters are confounded (after any the user lists)."""
        return ()

    def correction_hint(self, calibrated: "Robot") -> str:
        """The cause large corrections from this (nominal) model to ``calibrated`` (the same structure) reveal that
        makes the calibrated file wrong to use as it is, in words (a hexapod's legs relabelled: its joint columns
        read in another order, so each leg would be commanded by another's column); the verdict refuses with it.
        '' by default."""
        return ""

    def structure_notes(self) -> list[str]:
        """Warnings about the model's structure (e.g. parallel axes without β); none by default."""
        return []

    # ---- base frame ------------------------------------------------------------------------------
    def base_params(self) -> tuple[str, ...]:
        """Names of the 6 base-frame parameters (x y z rx ry rz), or () if the model has no base frame."""
        return ()

    def base_transform(self) -> tuple[np.ndarray, np.ndarray]:
        """The base frame: where the robot stands in the world (measurement) frame.

        From the base parameters x y z (m) and rx ry rz (rad): R = Rz(rz) Ry(ry) Rx(rx), and a point p in the
        robot's frame is R @ p + t in the world frame.

        Returns
        -------
        R : ndarray, shape (3, 3)
            The base frame's rotation.
        t : ndarray, shape (3,)
            The base frame's origin in the world frame, m.

        Raises
        ------
        ModelError
            When the model has no base frame.
        """
        x, y, z, rx, ry, rz = (self.params[n] for n in self._base_names())
        return rot_zyx(rz, ry, rx), np.array([x, y, z])

    def with_base_transform(self: R, R_: np.ndarray, t: np.ndarray) -> R:
        """A copy of the robot standing at another base frame.

        Parameters
        ----------
        R_ : ndarray, shape (3, 3)
            The new base frame's rotation (a point p in the robot's frame is ``R_ @ p + t`` in the world).
        t : ndarray, shape (3,)
            The new base frame's origin in the world frame, m.

        Returns
        -------
        Robot
            The copy, its base parameters x y z rx ry rz set from ``R_`` and ``t``.

        Raises
        ------
        ModelError
            When the model has no base frame.

        Examples
        --------
        >>> import numpy as np
        >>> import kincal
        >>> robot = kincal.load_robot("ur5")
        >>> turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90° about z
        >>> moved = robot.with_base_transform(turn, [1.0, 2.0, 0.5])
        >>> [round(moved.params[n], 6) for n in ("base.x", "base.y", "base.z", "base.rz")]
        [1.0, 2.0, 0.5, 1.570796]
        >>> q = robot.sample_joints(3, seed=1)
        >>> bool(np.allclose(moved.forward(q), robot.forward(q) @ turn.T + [1.0, 2.0, 0.5]))
        True
        """
        names = self._base_names()
        rz, ry, rx = zyx_from_matrix(np.asarray(R_, dtype=float))
        x, y, z = (float(c) for c in t)
        return self.with_params(dict(zip(names, (x, y, z, rx, ry, rz))))

    def _base_names(self) -> tuple[str, ...]:
        """:meth:`base_params`; ModelError when the model has no base frame."""
        names = self.base_params()
        if not names:
            raise ModelError(f"robot '{self.name}' has no base frame")
        return names

    def program_language(self) -> str:
        """The language of its controller's programs ("ur", "krl", "rapid", "fanuc", "inform"), as its robot file
        states it; '' when it does not (the default)."""
        return ""

    def named_frames(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Frames the robot file names (e.g. ROS ``base_link``): name -> (R, t), the frame's pose in the
        robot's base frame (a point p in it is R @ p + t in the base frame); none by default."""
        return {}

    # ---- the tool point (the measured target on the flange) ---------------------------------------
    @property
    def has_tool_point(self) -> bool:
        """Whether the model ends with a tool point ``tool.x/y/z`` (m, in the flange frame)."""
        return all(n in self.params.names for n in TOOL_NAMES)

    def _tool_indices(self) -> np.ndarray:
        """The positions of ``tool.x/y/z`` among the parameters; ModelError for a model without them."""
        if not self.has_tool_point:
            raise ModelError(f"robot '{self.name}' ({self.structure}) has no tool point (tool.x, tool.y, tool.z): its "
                             f"measured point is part of its structure")
        return self.params.indices(TOOL_NAMES)

    def tool_point(self) -> np.ndarray:
        """The tool point (3,) in m in the flange frame."""
        return self.params.values[self._tool_indices()]

    def with_tool_point(self: R, xyz) -> R:
        """A copy whose tool point is ``xyz`` (3,) m in the flange frame."""
        t = np.asarray(xyz, dtype=float).reshape(-1)
        self._tool_indices()
        if t.size != 3 or not np.all(np.isfinite(t)):
            raise ModelError(f"robot '{self.name}': a tool point is three finite numbers (m), got {xyz!r}")
        return self.with_params(dict(zip(TOOL_NAMES, map(float, t))))

    def flange_rotation(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """(N, 3, 3) orientation of the flange frame in the world frame at q (N, n): column k is where
        a unit step of the tool point along flange axis k moves it (the tool point is a translation)."""
        v, q = self.param_values(values), self.check_q(q)
        p0 = self.forward(q, v)
        return np.stack([self.forward(q, vk) - p0 for vk in self._tool_steps(v)], axis=2)

    def _tool_steps(self, values: np.ndarray) -> np.ndarray:
        """(3, P): ``values`` with the tool point moved 1 m along each flange axis."""
        steps = np.repeat(np.asarray(values, dtype=float)[None], 3, axis=0)
        steps[np.arange(3), self._tool_indices()] += 1.0
        return steps

    # ---- the error model beyond geometry ---------------------------------------------------------
    @property
    def error_model(self) -> str:
        """The joint-value terms on top of the geometry ('geometric': none; e.g. 'compliance+harmonics:2')."""
        return "geometric"

    @property
    def term_names(self) -> tuple[str, ...]:
        """The parameters of the error-model terms (none for a geometric model)."""
        return ()

    def corrected(self, q: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """The joint values (N, n) the geometry uses for commanded/read values q (the same without terms)."""
        return self.check_q(q)

    def compliances(self) -> dict[str, float]:
        """Per joint with a compliance term its compliance in rad/(N·m); none by default."""
        return {}

    def value_units(self) -> dict[str, str]:
        """Parameters whose value is per something beyond its kind's unit (m, rad, 1), and what, in words: a
        compliance is the deflection 'at 100 N·m', a thermal growth rate 'per unit of temperature' (its
        covariate's unit). The parameter tables say it beside such a value. None by default."""
        return {}

    def correction_scales(self, q: np.ndarray) -> dict[str, tuple[float, str]]:
        """Parameters whose value is not the correction it makes at the poses q (N, n): per name, the largest
        correction (m or rad, of the parameter's kind) one unit of it makes there, and where, in words (a
        compliance, the deflection at 100 N·m, deflects its joint by value × its largest load in q / 100 N·m).
        The verdict's plausible-correction limits and the hold of weakly determined parameters judge value ×
        scale. None by default: a value is its correction."""
        return {}

    def with_load_compliance(self: R) -> R:
        """The robot with its own compliance under its load as parameters (``has_load_compliance``: the
        error model ``compliance`` of a model that is not a chain; a chain's is a term on its joints)."""
        raise ModelError(f"robot '{self.name}' ({self.structure}) has no compliance of its own")

    # ---- gravity and β ---------------------------------------------------------------------------
    def gravity(self, payload: float = 0.0) -> "GravityModel":
        """The gravity loads of the link masses (and ``payload`` kg at the tool point)."""
        raise ModelError(f"robot '{self.name}' ({self.structure}): gravity terms need a serial chain whose links "
                         f"carry masses")

    @property
    def has_beta(self) -> bool:
        """Whether the model carries Hayati β tilts that ``without_beta`` can switch off."""
        return False

    def without_beta(self: R) -> R:
        """The model without its β tilts (their values dropped)."""
        raise ModelError(f"robot '{self.name}' ({self.structure}): 'nobeta' applies to DH/MDH chains with β tilts")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, joints={self.n_joints}, params={self.n_params})"
