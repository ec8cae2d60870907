"""Serial chains in standard DH (Craig's ``Rz(θ) Tz(d) Tx(a) Rx(α)``) or modified DH
(``Rx(α) Tx(a) Rz(θ) Tz(d)``), with Hayati's β, a 6-parameter base frame and a tool point.

Parameter names (stable): ``base.x base.y base.z base.rx base.ry base.rz``, then per joint
``<joint>.theta <joint>.d <joint>.a <joint>.alpha [<joint>.beta]``, then ``tool.x tool.y tool.z``.

* base frame: ``Tx(x) Ty(y) Tz(z) Rz(rz) Ry(ry) Rx(rx)`` (fixed-axis roll/pitch/yaw).
* standard DH joint i: ``Rz(θ_i + q_i) Tz(d_i) Tx(a_i) Rx(α_i) [Ry(β_i)]``; β_i goes on the link whose
  two joint axes (i and i+1) are parallel (α_i ≈ 0 or π), where the common normal is undefined.
* modified DH joint i: ``Rx(α_i) Tx(a_i) [Ry(β_i)] Rz(θ_i + q_i) Tz(d_i)``; β_i goes on joint i when its
  axis is parallel to joint i-1's.
* prismatic joints add q to d instead of θ; θ (or d) is then the joint's zero offset.
"""
from __future__ import annotations

import copy
import dataclasses
from abc import abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar, Iterable, Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .chain import AXES, ROT, TRANS, Chain, Op, compiled
from .gravity import GravityModel
from .parameters import Parameters
from .joint_space import JOINT_TYPES, JointSpace
from .robot import TOOL_NAMES, Robot
from .transforms import rot_zyx

CONVENTIONS = ("dh", "mdh")
ROW_TYPES = (*JOINT_TYPES, "fixed")  # a fixed row: a DH row without a joint (e.g. a tool row)
BASE_NAMES = ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz")
POSE_KINDS = ("length",) * 3 + ("angle",) * 3  # of x y z rx ry rz (the base frame's, a URDF origin's)
PARALLEL_TOL = 1e-6  # |sin α| below this: consecutive axes are parallel
ROW_PARAMS = (("theta", "angle"), ("d", "length"), ("a", "length"), ("alpha", "angle"), ("beta", "angle"))


@dataclass(frozen=True)
class Joint:
    """The structure of one joint (one row) of a DH/MDH chain; its geometry is in the robot's parameters.

    Parameters
    ----------
    name : str
        The joint's name, non-empty and without a dot (parameter names are ``<name>.theta`` …).
    type : str, optional
        "revolute" (default), "prismatic", or "fixed" (a row without a joint, e.g. a tool row).
    beta : bool, optional
        Whether the row carries Hayati's β tilt ``<name>.beta`` (default False).
    lower : float, optional
        Lower joint limit, rad (m for a prismatic joint), finite (default -π).
    upper : float, optional
        Upper joint limit in the same unit, above ``lower`` (default π).
    mass : float, optional
        Mass of the link the joint moves, kg, 0 or more (default 0: no gravity load).
    com : tuple of 3 float, optional
        Centre of mass of that link in the link frame at the end of the joint's row, m (default the origin).
    velocity : float or None, optional
        Velocity limit, rad/s (m/s), 0 or more (default None: not given).
    effort : float or None, optional
        Effort limit, N·m (N), 0 or more (default None: not given; 0 is a value, as ROS-Industrial's
        descriptions write it where the maker publishes none).
    export_name : str, optional
        The joint's name in the robot stack (URDF, ROS), e.g. "shoulder_pan_joint" (default "": its own name).
    pulses : float, optional
        The controller's encoder pulses per degree (per mm for a prismatic joint), signed by its counting
        direction (default 0: not given).

    Raises
    ------
    ModelError
        When the name is empty or has a dot, the type is unknown, the limits are not finite with lower < upper,
        or a mass, centre of mass, velocity, effort or pulse count is not valid.

    Examples
    --------
    >>> from kincal.models import Joint
    >>> j = Joint("j1")
    >>> j.type, j.beta, round(j.lower, 6), round(j.upper, 6), j.mass
    ('revolute', False, -3.141593, 3.141593, 0.0)
    >>> slide = Joint("z", type="prismatic", lower=0.0, upper=0.2)
    >>> slide.type, slide.upper
    ('prismatic', 0.2)
    """

    name: str
    type: str = "revolute"
    beta: bool = False
    lower: float = -np.pi
    upper: float = np.pi
    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: float | None = None  # rad/s or m/s; None: not given
    effort: float | None = None  # N·m or N; None: not given
    export_name: str = ""  # the joint's name in the robot stack (URDF, ROS); default its own name
    pulses: float = 0.0  # the controller's encoder pulses per degree (per mm), signed by its counting; 0: not given

    def __post_init__(self) -> None:
        object.__setattr__(self, "com", check_mass(self.mass, self.com, f"joint '{self.name}'"))
        if not np.isfinite(self.pulses):
            raise ModelError(f"joint '{self.name}': pulses_per_degree {self.pulses} must be a finite number (0: not "
                             f"given)")
        for key in ("velocity", "effort"):
            value = self.__dict__[key]
            if value is not None and not (np.isfinite(value) and value >= 0.0):
                raise ModelError(f"joint '{self.name}': {key} limit {value} must be a finite number, 0 or more")
        if self.type not in ROW_TYPES:
            raise ModelError(f"joint '{self.name}': type '{self.type}' is not one of {ROW_TYPES}")
        if not (np.isfinite(self.lower) and np.isfinite(self.upper) and self.lower < self.upper):
            raise ModelError(f"joint '{self.name}': limits [{self.lower}, {self.upper}] must be finite with "
                             f"lower < upper")
        if "." in self.name or not self.name:
            raise ModelError(f"joint name '{self.name}' must be non-empty and contain no '.'")


def check_mass(mass: float, com, where: str) -> tuple[float, float, float]:
    """The centre of mass as a tuple of floats (m), after checking: a link mass must be finite and
    ≥ 0 kg, its centre of mass three finite numbers."""
    if not (np.isfinite(mass) and mass >= 0.0):
        raise ModelError(f"{where}: mass {mass} must be a finite number of kg, 0 or more")
    if len(com) != 3 or not np.all(np.isfinite(np.asarray(com, dtype=float))):
        raise ModelError(f"{where}: com {list(com)} must be three finite numbers (x, y, z)")
    return (float(com[0]), float(com[1]), float(com[2]))


def check_frames(frames, where: str) -> tuple[tuple[str, tuple[float, ...]], ...]:
    """Named frames as ((name, (x, y, z, rx, ry, rz)), ...) after checking: distinct non-empty names,
    six finite numbers each (m, rad: the frame's pose in the robot's base frame)."""
    out = []
    for name, pose in frames:
        pose = tuple(float(v) for v in pose)
        if not str(name) or len(pose) != 6 or not np.all(np.isfinite(pose)):
            raise ModelError(f"{where}: frame '{name}' needs a name and six finite numbers x, y, z, rx, ry, rz")
        out.append((str(name), pose))
    names = [n for n, _ in out]
    if len(set(names)) != len(names) or "base" in names:
        raise ModelError(f"{where}: frame names {names} must be distinct and not 'base' (the robot's own frame)")
    return tuple(out)


def chain_layout(rows: Iterable[tuple[str, str]]) -> tuple[list[str], list[str]]:
    """Parameter names and kinds of a chain: the base frame, the ``rows`` (name, kind), the tool point."""
    pairs = list(rows)
    names = [*BASE_NAMES, *(n for n, _ in pairs), *TOOL_NAMES]
    return names, [*POSE_KINDS, *(k for _, k in pairs), *("length",) * 3]


def _param_names(joints: Sequence[Joint]) -> tuple[list[str], list[str]]:
    return chain_layout((f"{jt.name}.{s}", kind) for jt in joints for s, kind in ROW_PARAMS if s != "beta" or jt.beta)


class ChainRobot(Robot):
    """A robot computed by a :class:`~kincal.models.chain.Chain` of elementary motions.

    The chain starts with the standard base frame (``base.x`` … ``base.rz``) and ends with the tool point
    (``tool.x/y/z``): DH/MDH chains (:class:`SerialRobot`) and URDF chains (:class:`URDFRobot`) share their
    kinematics, base handling and gravity loads. Not built directly: a subclass is a frozen dataclass that sets
    ``joints`` and compiles its ``chain``.

    Attributes
    ----------
    joints : tuple
        The chain's rows (DH) or joints (URDF): name, type, limits, mass and centre of mass each.
    chain : Chain
        The compiled op sequence (read-only: exports walk it).
    """

    joints: tuple  # the chain's rows (DH) or joints (URDF): name, type, limits, mass and com each
    chain: Chain  # the compiled op sequence (read-only use: exports walk it)
    has_gravity: ClassVar[bool] = True

    def _rebuild(self, params: Parameters):
        """A copy with ``params``: their names and kinds are this chain's (checked by
        :meth:`with_params`), so its structure, already validated and compiled, is kept (a fit
        rebuilds the robot several times; validating and compiling again cost 0.5 ms each)."""
        new = copy.copy(self)
        object.__setattr__(new, "params", params)
        return new

    @property
    def moving(self) -> tuple:
        """The joints with a joint variable (``joints`` less the fixed ones)."""
        return tuple(j for j in self.joints if j.type != "fixed")

    def _compile(self, types: Sequence[str], columns: int) -> None:
        """Set ``joint_space`` (the moving joints, of ``types``) and the chain compiled for ``columns`` values."""
        moving = self.moving
        object.__setattr__(self, "joint_space", JointSpace([j.name for j in moving], types, [j.lower for j in moving],
                                                           [j.upper for j in moving]))
        object.__setattr__(self, "chain", compiled(self._build_ops(), columns, len(moving)))

    @abstractmethod
    def _joint_ops(self, joint, k: int) -> list[Op]:
        """The ops of one row (k: its joint's index among the moving ones); they end in its link's frame."""

    def _rows(self) -> list[tuple[str, float, tuple[float, float, float], list[Op]]]:
        """Per row (joint) of the chain, in order: its name, the mass (kg) and centre of mass (m) of
        the link it moves (link k is the frame at the end of row k), and its ops."""
        moving = np.cumsum([j.type != "fixed" for j in self.joints]) - 1  # each row's joint index (unused if fixed)
        return [(j.name, j.mass, j.com, self._joint_ops(j, int(k))) for k, j in zip(moving, self.joints)]

    def _build_ops(self) -> tuple[Op, ...]:
        """The base frame's six ops Tx Ty Tz Rz Ry Rx, the rows' ops, the tool point's Tx Ty Tz."""
        idx = self.params.index
        base = [Op(TRANS, AXES[a], idx(f"base.{a}")) for a in "xyz"]
        base += [Op(ROT, AXES[a], idx(f"base.r{a}")) for a in "zyx"]
        tool = [Op(TRANS, AXES[a], idx(f"tool.{a}")) for a in "xyz"]
        return tuple(base + [op for *_, ops in self._rows() for op in ops] + tool)

    def link_frames(self) -> list[tuple[str, int, int, float, tuple[float, float, float]]]:
        """Per link of the chain (the frame at the end of each row): (name, number of chain ops up to
        its frame, number of joints before it, mass kg, centre of mass m in its frame). Gravity terms
        place masses with this."""
        out, end, moving = [], len(BASE_NAMES), 0  # the chain starts with the base frame's six ops
        for name, mass, com, ops in self._rows():
            end += len(ops)
            moving += any(op.joint >= 0 for op in ops)
            out.append((name, end, moving, mass, com))
        return out

    def chain_values(self, values: np.ndarray | None = None) -> np.ndarray:
        """The values the compiled chain reads (the parameters, and any extra columns)."""
        return self.param_values(values)

    def _forward_and_jacobian(self, q, values, jacobian):
        values = self.chain_values(values)
        if not jacobian:
            return self.chain.forward(values, q), None
        p, J = self.chain.forward_and_jacobian(values, q)
        return p, J[:, :, :self.n_params]  # extra chain columns (URDF joint motions) left out

    def _forward_jacobians(self, q, values):
        p, J = self.chain.forward_and_jacobian(self.chain_values(values), q)
        # ∂p/∂qⱼ is the column of the parameter joint j's value adds to (θ or d; a URDF joint motion's own)
        return p, J[:, :, :self.n_params], J[:, :, self.chain.joint_param]

    def _joint_jacobian(self, q, values):
        return self._forward_jacobians(q, values)[2]

    def _pose_and_jacobian(self, q, values):
        return self.chain.pose_jacobian(self.chain_values(values), q)[:4]

    def link_points(self, q: np.ndarray) -> np.ndarray | None:
        return self.chain.pose_jacobian(self.chain_values(), self.check_q(q))[4]

    def _frame_and_rates(self, q, values):
        p, J, R, Jw = self.chain.frame_and_rates(self.chain_values(values), q)
        return p, J[:, :, :self.n_params], R, Jw[:, :, :self.n_params]

    def gravity(self, payload: float = 0.0) -> GravityModel:
        return GravityModel(self, float(payload))

    def preferred_params(self) -> tuple[str, ...]:
        """The tool point, then the base frame: well-conditioned, physical stand-ins for joint terms."""
        return TOOL_NAMES + BASE_NAMES

    def base_params(self) -> tuple[str, ...]:
        return BASE_NAMES


@dataclass(frozen=True, eq=False, repr=False)
class SerialRobot(ChainRobot):
    """An open serial chain in standard or modified DH, with Hayati's β, a base frame and a tool point.

    Build one with :meth:`SerialRobot.build` or load it from a robot file (:func:`load_robot`); the constructor
    takes Parameters already laid out as the joints ask (see the module docstring for the names).

    Parameters
    ----------
    name : str
        The robot's name.
    convention : str
        "dh" (Craig's Rz(θ) Tz(d) Tx(a) Rx(α)) or "mdh" (Rx(α) Tx(a) Rz(θ) Tz(d)).
    joints : tuple of Joint
        The rows of the chain, base to tip, with distinct names; at least one is not fixed.
    params : Parameters
        The base frame, each row's θ d a α [β] and the tool point, in that order, SI units (m, rad).
    description : str, optional
        Free text (default "").
    frames : tuple of (str, tuple of 6 float), optional
        Named frames of the robot description (e.g. ROS ``base_link``): (name, (x, y, z m, rx, ry, rz rad)),
        the frame's pose in the robot's base frame (default none).
    language : str, optional
        The language of its controller's programs, one of ``LANGUAGES`` ("ur", "krl", "rapid", "fanuc",
        "inform"); '' (default) when not known. ``compensate`` refuses a program of another language.

    Attributes
    ----------
    joint_space : JointSpace
        The moving joints' names, types and limits (set from ``joints``).
    chain : Chain
        The compiled op sequence.

    Raises
    ------
    ModelError
        When the convention is unknown, there is no joint or no moving joint, joint names repeat, the parameter
        names do not match the joints, or a named frame is not valid.

    Examples
    --------
    A planar arm of two links, 0.4 m and 0.3 m, with a tool point 0.05 m along the last link:

    >>> import numpy as np
    >>> from kincal.models import Joint, SerialRobot
    >>> arm = SerialRobot.build("planar", "dh", [Joint("j1"), Joint("j2")], [{"a": 0.4}, {"a": 0.3}],
    ...                         tool={"x": 0.05})
    >>> arm
    SerialRobot(name='planar', joints=2, params=17)
    >>> arm.params.names[6:10]
    ('j1.theta', 'j1.d', 'j1.a', 'j1.alpha')
    >>> np.round(arm.forward([0.0, np.pi / 2]), 6).tolist()
    [0.4, 0.35, 0.0]
    >>> arm.parallel_pairs()  # the two axes are parallel: a β on j1 would model their tilt
    [(0, 1)]
    """

    name: str
    convention: str
    joints: tuple[Joint, ...]
    params: Parameters
    description: str = ""
    frames: tuple[tuple[str, tuple[float, ...]], ...] = ()  # named frames: (name, (x y z m, rx ry rz rad) in base)
    language: str = ""  # the language of its controller's programs (LANGUAGES); '' not known
    joint_space: JointSpace = field(init=False, repr=False)
    chain: Chain = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise ModelError(f"robot '{self.name}': convention '{self.convention}' is not one of {CONVENTIONS}")
        joints = tuple(self.joints)
        if not joints:
            raise ModelError(f"robot '{self.name}': a serial robot needs at least one joint")
        jn = [j.name for j in joints]
        if len(set(jn)) != len(jn):
            raise ModelError(f"robot '{self.name}': duplicate joint names {jn}")
        if all(j.type == "fixed" for j in joints):
            raise ModelError(f"robot '{self.name}': every row is fixed; a robot needs a moving joint")
        names, kinds = _param_names(joints)
        if tuple(names) != self.params.names or tuple(kinds) != self.params.kinds:
            raise ModelError(f"robot '{self.name}': parameter names do not match the joint structure")
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "frames", check_frames(self.frames, f"robot '{self.name}'"))
        self._compile([j.type for j in self.moving], len(self.params))

    # ---- construction --------------------------------------------------------------------------
    @classmethod
    def build(cls, name: str, convention: str, joints: Sequence[Joint], dh: Sequence[Mapping[str, float]],
              base: Mapping[str, float] | None = None, tool: Mapping[str, float] | None = None, description: str = "",
              frames: Sequence[tuple[str, Sequence[float]]] = (), language: str = "") -> "SerialRobot":
        """Build a robot from joint structures and per-joint DH values.

        Parameters
        ----------
        name : str
            The robot's name.
        convention : str
            "dh" or "mdh".
        joints : sequence of Joint
            The rows of the chain, base to tip.
        dh : sequence of mapping of str to float
            One mapping per joint with keys among "theta", "d", "a", "alpha" and (a joint with β) "beta";
            m and rad; missing keys are 0.
        base : mapping of str to float, optional
            The base frame, keys among x y z (m) and rx ry rz (rad); missing keys are 0.
        tool : mapping of str to float, optional
            The tool point in the flange frame, keys among x y z (m); missing keys are 0.
        description : str, optional
            Free text (default "").
        frames : sequence of (str, sequence of 6 float), optional
            Named frames: (name, (x, y, z m, rx, ry, rz rad)) in the robot's base frame (default none).
        language : str, optional
            The language of its controller's programs (default '': not known).

        Returns
        -------
        SerialRobot
            The robot.

        Raises
        ------
        ModelError
            When ``dh`` does not have one row per joint, a key is not a parameter, or the robot is not valid.
        """
        if len(dh) != len(joints):
            raise ModelError(f"robot '{name}': {len(joints)} joints but {len(dh)} DH rows")
        names, kinds = _param_names(joints)
        vals = dict.fromkeys(names, 0.0)
        given = [(f"{f}.{k}", v) for f, kv in (("base", base), ("tool", tool)) for k, v in (kv or {}).items()]
        for key, v in given + [(f"{jt.name}.{k}", v) for jt, row in zip(joints, dh) for k, v in row.items()]:
            if key not in vals:
                raise ModelError(f"robot '{name}': unknown parameter '{key}'; known: {', '.join(vals)}")
            vals[key] = float(v)
        return cls(name, convention, tuple(joints), Parameters(names, [vals[n] for n in names], kinds), description,
                   tuple((n, tuple(p)) for n, p in frames), language)

    def _joint_ops(self, jt: Joint, k: int) -> list[Op]:
        p = lambda s: self.params.index(f"{jt.name}.{s}")  # noqa: E731
        x, y, z = AXES["x"], AXES["y"], AXES["z"]
        rz = Op(ROT, z, p("theta"), k if jt.type == "revolute" else -1)
        tz = Op(TRANS, z, p("d"), k if jt.type == "prismatic" else -1)
        beta = [Op(ROT, y, p("beta"))] if jt.beta else []
        if self.convention == "dh":
            return [rz, tz, Op(TRANS, x, p("a")), Op(ROT, x, p("alpha"))] + beta
        return [Op(ROT, x, p("alpha")), Op(TRANS, x, p("a"))] + beta + [rz, tz]

    @property
    def structure(self) -> str:
        return self.convention

    def with_joints(self, joints: Sequence[Joint], name: str | None = None) -> "SerialRobot":
        """Same values, new joint structures (e.g. β switched on/off); new β values start at 0."""
        old = self.params.as_dict()
        names, kinds = _param_names(joints)
        vals = [old.get(n, 0.0) for n in names]
        return SerialRobot(name or self.name, self.convention, tuple(joints), Parameters(names, vals, kinds),
                           self.description, self.frames, self.language)

    def program_language(self) -> str:
        return self.language

    def named_frames(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        return {n: (rot_zyx(v[5], v[4], v[3]), np.array(v[:3])) for n, v in self.frames}

    @property
    def stack_names(self) -> tuple[str, ...]:
        return tuple(j.export_name or j.name for j in self.moving)

    @property
    def has_beta(self) -> bool:
        return any(j.beta for j in self.joints)

    def without_beta(self) -> "SerialRobot":
        return self.with_joints([dataclasses.replace(j, beta=False) for j in self.joints])

    # ---- structure -----------------------------------------------------------------------------
    def parallel_pairs(self) -> list[tuple[int, int]]:
        """Index pairs (i, i+1) of consecutive revolute joints whose nominal axes are parallel."""
        pairs = [(i, i + 1) for i in range(len(self.joints) - 1)
                 if self.joints[i].type == self.joints[i + 1].type == "revolute"]
        alpha = [self.params[f"{self.joints[self.beta_joint(p)].name}.alpha"] for p in pairs]  # between the two axes
        return [p for p, a in zip(pairs, alpha) if abs(np.sin(a)) < PARALLEL_TOL]

    def beta_joint(self, pair: tuple[int, int]) -> int:
        """The joint that carries β for a parallel pair: the first in DH, the second in MDH."""
        return pair[0] if self.convention == "dh" else pair[1]

    def structure_notes(self) -> list[str]:
        """Human-readable warnings about the model structure (parallel axes without β)."""
        notes = []
        for pair in self.parallel_pairs():
            jb = self.joints[self.beta_joint(pair)]
            if not jb.beta:
                a, b = (self.joints[k].name for k in pair)
                notes.append(
                    f"axes of {a} and {b} are parallel and {jb.name} has no beta: a tilt of {b}'s axis "
                    f"about the common normal cannot be represented and the d offsets along the parallel "
                    f"axes only act through their sum; set 'beta' on {jb.name} (Hayati) to model it"
                )
        return notes

