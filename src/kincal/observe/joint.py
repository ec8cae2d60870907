"""The joint-space residual as an observation type: measured positions against commanded joints.

The 3-PUU paper of 2024 ("Error analysis model of parallel robot based on parameters identification", eq. 4/11)
compares the joint values that reach each measured point, by the model's closed-form inverse kinematics, with the commanded ones. The data are a :class:`~kincal.observe.PointObs`'s
(joint values and measured positions); only the residual differs: robots with a closed-form inverse (``has_inverse``).
Also the rows a set's measured positions cannot be judged at: out of the starting model's reach, or joint values a
closed chain does not assemble at (two columns swapped named as such).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from .._csv import listed
from .._stats import spread
from ..errors import MeasurementError, ModelError
from ..models.robot import Robot
from ..models.transforms import kabsch
from ..ties import first_best
from ..units import ANGLE_UNITS, LENGTH_UNITS, joint_shown, joint_units, length_mistakes
from .observations import MeasuredPositions, PointObs, PoseObs, Wrapper, component_major, mean_square, so3_right


class InJoints:
    """What a residual in joint space is, whatever was measured: one row per sample and joint, each with
    the joints' reading noise ``std`` (rad or m) as its σ; and each sample's noise as a whole, the joints' reading
    noise and the measurement's noise through the inverse kinematics (:meth:`covariance`), which the verdict
    judges it by."""

    kind = "joint"
    q: np.ndarray
    std: float

    def sample_rows(self) -> np.ndarray:
        return np.tile(np.arange(len(self.q)), self.q.shape[1])

    def sigma(self) -> np.ndarray:
        return np.full(self.q.size, float(self.std))

    def measured_noise(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How the measurement's noise reaches the joints: the inverse's derivatives by the measured quantity at
        each sample (N, n, d) and that quantity's noise variances (N, d) (m², rad²); each type declares them."""
        raise NotImplementedError

    def covariance(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> np.ndarray:
        """(N, n, n) each sample's residual covariance, (rad or m)²: C = σ² I + D Σ Dᵀ, σ the joints' reading noise,
        D the inverse's derivatives by the measured position or pose and Σ its noise (:meth:`measured_noise`): the
        noise of one measured pose reaches every joint, the more where the inverse kinematics amplify it."""
        D, var = self.measured_noise(robot, values, nuis)
        return float(self.std) ** 2 * np.eye(D.shape[1]) + np.einsum("nid,nd,njd->nij", D, var, D)


@dataclass(frozen=True, eq=False)
class JointObs(InJoints, MeasuredPositions):
    """Measured positions at commanded joints, with the residual in joint space.

    The residual is the inverse kinematics of xyz − q, (N, n) rad or m: robots with a closed-form inverse
    (``has_inverse``). Its σ is the joints' reading noise, stated; its statistics are the position errors (m).

    Parameters
    ----------
    q : ndarray, shape (N, n)
        The commanded joint values, rad (m for a prismatic joint).
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    xyz : ndarray, shape (N, 3)
        The measured positions of the tool point, m.
    std : float, optional
        σ of every joint's reading, rad or m (default 1e-4).
    std_pos : ndarray, shape (N, 3), or float, optional
        σ of the measured positions per axis, m, as for :class:`PointObs` (default 15e-6): it reaches the joints
        through the inverse kinematics (:meth:`covariance`).

    See Also
    --------
    in_joint_space : A set of points or poses with its residual in joint space.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import JointObs
    >>> robot = kincal.load_robot("puu3")
    >>> meas = kincal.simulate(robot, robot.sample_joints(5, seed=1), noise=0.0)
    >>> obs = JointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz, std=1e-5)
    >>> r, Jr, _ = obs.evaluate(robot, robot.params.values, np.zeros(0))
    >>> obs.kind, r.shape, bool(np.abs(r).max() < 1e-9), obs.sigma()[:3].tolist()
    ('joint', (15,), True, [1e-05, 1e-05, 1e-05])
    """

    std: float = 1e-4
    std_pos: np.ndarray | float = 15e-6

    def measured_noise(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        var = np.broadcast_to(np.asarray(self.std_pos, float) ** 2, self.xyz.shape)
        return robot.inverse_rates(self.xyz, values), var

    def evaluate_cols(self, robot: Robot, values: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        try:
            qh, J = robot.inverse_and_jacobian(self.xyz, values)
        except ModelError:  # a trial step where some measured position is out of reach: reject it
            return np.full(self.q.size, np.inf), np.zeros((self.q.size, len(cols)))
        return component_major(qh - self.q, J, cols)

    def batch_cost(self, robot: Robot, values: np.ndarray) -> np.ndarray:
        return mean_square(robot.inverse_batch(self.xyz, values) - self.q)

    def check(self, robot: Robot, values: np.ndarray) -> None:
        reach = lambda k: np.all(np.isfinite(robot.inverse(self.xyz * k, values, strict=False)), axis=1)  # noqa: E731
        out_of_reach(self, robot, values, ~reach(1.0), "positions", lambda k: bool(np.all(reach(k))))


MOST = 0.5  # more than this share of the samples out of reach: not a few bad poses, the whole file
UNIT_MATCH = 1.3  # a length unit mistake explains a spread ratio within this factor of its own


def out_of_reach(obs: MeasuredPositions, robot: Robot, values: np.ndarray, bad: np.ndarray, what: str, reach) -> None:
    """Refuse the samples of ``obs`` whose measured positions the starting model (``values``) cannot reach (``bad``
    (N,) bool): how many and which, and what to do. When most are out of reach, a length unit mistake is named if one
    explains the positions' spread (RMS distance from their centroid) against the robot's own at the same joints
    and brings every one within reach (``reach(k)``: whether all the positions multiplied by k are)."""
    n, k, rows = len(bad), int(np.count_nonzero(bad)), obs.rows
    if not k:
        return
    head = (f"{obs.source}: the {what} in {f'all {n} rows' if k == n else f'{k} of {n} rows ({listed(rows[bad])})'} "
            f"are out of reach of the starting model, so the joint-space residual is undefined there")
    cartesian = "fit the positions instead (residual='cartesian'; CLI: --residual cartesian)"
    if k <= MOST * n:
        raise MeasurementError(f"{head}: leave those rows out (CLI: --exclude {','.join(map(str, rows[bad]))}) or "
                               f"{cartesian}")
    try:
        ratio = spread(obs.xyz) / max(spread(robot.forward(obs.q, values)), 1e-300)
    except ModelError:  # the joints do not assemble the robot either: their own check names why
        ratio = np.nan
    fits = lambda f: 1 / UNIT_MATCH < f * ratio < UNIT_MATCH and reach(f)  # noqa: E731  (False for nan)
    factor = next((f for f in length_mistakes() if fits(f)), None)
    if factor is None:
        raise MeasurementError(f"{head}: that many rows are not a few bad poses: check the position columns, their unit "
                               f"and their frame against the robot file (CLI: --xyz-cols, --length-unit, --base "
                               f"estimate), or {cartesian}")
    pairs = " or ".join(f"{real} read as {read}" for real, read in length_mistakes()[factor])
    raise MeasurementError(f"{head}: they spread {ratio:.4g}x as far as the robot moves at the same joint values, and "
                           f"multiplied by {factor:g} they are all within reach: a length unit mistake ({pairs}); read "
                           f"them in the unit they are in (CLI: --length-unit)")


SWAP_CLEAR = 0.5  # a swap of two joint columns explains the data when its rigid fit's mean miss is at most this share
# of the next swap's (the Jugglebot's legs 2 and 3: 4.68 mm, the next 77 mm)


def unassembled_rows(source: str, q: np.ndarray, xyz: np.ndarray, robot: Robot, rows: np.ndarray | None = None,
                units: tuple[str, str] | None = None) -> tuple[MeasurementError, bool] | None:
    """The error for joint values at which ``robot`` (a closed chain) does not assemble, and whether two joint
    columns swapped explain it (:func:`swap_explains`); None when it assembles at every row.

    Parameters
    ----------
    source : str
        Where the values come from (a file's path), named in the message.
    q : ndarray, shape (N, n)
        Joint values, rad or m.
    xyz : ndarray, shape (N, 3)
        The measured positions at them, m (to judge a swap by).
    robot : Robot
        The robot, at its own parameter values.
    rows : ndarray of int, shape (N,), optional
        Each row's 1-based line number in ``source`` (default: 2, 3, …, after a header line).
    units : (str, str), optional
        The length and angle unit the joint values were written in, to show them so (default: kincal's own,
        :func:`kincal.units.joint_shown`).

    Returns
    -------
    (MeasurementError, bool) or None
        The error naming the rows, the first one's joint values and what to do, and whether a swap explains it.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe.joint import unassembled_rows
    >>> robot = kincal.load_robot("hexapod")
    >>> q = robot.sample_joints(20, seed=1)
    >>> unassembled_rows("legs.csv", q, robot.forward(q), robot) is None
    True
    """
    p = robot.forward_batch(q, robot.params.values[None])[0]
    bad = np.flatnonzero(~np.all(np.isfinite(p), axis=1))
    if not bad.size:
        return None
    rows = np.arange(2, len(q) + 2) if rows is None else np.asarray(rows)
    shown = joint_shown(robot.joint_types, robot.periodic) if units is None else [
        (u or "", 1.0 / {**LENGTH_UNITS, **ANGLE_UNITS}.get(u or "", 1.0)) for u in joint_units(robot.joint_types,
                                                                                                 *units)]
    first = ", ".join(f"{n} {v * f:.6g} {u}" for n, v, (u, f) in zip(robot.joint_names, q[bad[0]], shown))
    head = (f"{source}: {robot.name} does not assemble at the joint values of {bad.size} row(s) (its forward "
            f"kinematics finds no pose there): row(s) {listed(rows[bad])}; row {rows[bad[0]]}: {first}"
            f"{' as written' if units else ''}")
    swap = swap_explains(q, xyz, robot)
    if swap is not None:
        a, b = (robot.joint_names[k] for k in swap[:2])
        return MeasurementError(
            f"{head}; with the columns of {a} and {b} swapped it assembles at every row and the positions fit it "
            f"rigidly to {swap[2] * 1e3:.3g} mm mean (the next swap {swap[3] * 1e3:.3g} mm): the columns of {a} and "
            f"{b} are swapped; swap them (CLI: give --joint-cols in the robot's joint order)"), True
    return MeasurementError(f"{head}: outside the workspace or at a singularity; check those rows' joint values and "
                            f"their unit, or leave them out (CLI: --exclude {','.join(map(str, rows[bad]))})"), False


def swap_explains(q: np.ndarray, xyz: np.ndarray, robot: Robot) -> tuple[int, int, float, float] | None:
    """The two joint columns (i, j) of one type whose swap makes ``robot`` assemble at every row of q (N, n) and fits
    the positions xyz (N, 3) m best rigidly (Kabsch), with its mean miss and the next swap's (m; inf when no other
    assembles); None unless that miss is at most SWAP_CLEAR of the next one's."""
    tried = []
    for i, j in combinations(range(robot.n_joints), 2):
        if robot.joint_types[i] != robot.joint_types[j]:
            continue
        swapped = q.copy()
        swapped[:, [i, j]] = swapped[:, [j, i]]
        p = robot.forward_batch(swapped, robot.params.values[None])[0]
        if np.all(np.isfinite(p)) and len(q) >= 3:
            R, t = kabsch(p, xyz)
            tried.append((float(np.mean(np.linalg.norm(p @ R.T + t - xyz, axis=1))), i, j))
    if not tried:
        return None
    best = first_best([e for e, _, _ in tried], maximize=False)
    others = [e for k, (e, _, _) in enumerate(tried) if k != best]
    miss, i, j = tried[best]
    after = min(others, default=np.inf)
    return (i, j, miss, after) if miss <= SWAP_CLEAR * after else None

@dataclass(frozen=True, eq=False)
class PoseJointObs(InJoints, PoseObs):
    """Measured 6-D poses at read joints, with the residual in joint space.

    The residual is the joints that put the platform at the measured pose by the model's closed-form inverse
    (a hexapod's legs from its pose, no forward solve: ``has_pose_inverse``) − q, (N, n) m or rad. The
    platform's frame is the measured one turned back by the target's rotation (a set-up parameter, as for
    :class:`PoseObs`). Its σ is the joints' reading noise, stated; its statistics are the pose errors
    (forward kinematics).

    Parameters
    ----------
    q : ndarray, shape (N, n)
        The read joint values, m or rad.
    rows : ndarray of int, shape (N,)
        Each sample's 1-based line number in ``source`` (header = line 1).
    source : str
        Where the data come from (a file's path), named in messages.
    xyz : ndarray, shape (N, 3)
        The measured positions of the target's origin, m.
    R : ndarray, shape (N, 3, 3)
        The measured rotations of the target (columns: its axes in the measurement frame).
    target_rotation : ndarray, shape (3, 3), optional
        The target's orientation on the platform that the fitted rotation vector starts from (default
        identity).
    std_pos : ndarray, shape (N,), or float, optional
        σ of the positions per axis, m, as for :class:`PoseObs` (default 0.1e-3); with ``std_rot`` it reaches the
        joints through the inverse kinematics (:meth:`covariance`).
    std_rot : ndarray, shape (N,), or float, optional
        σ of the rotations per axis, rad, as for :class:`PoseObs` (default 1e-3).
    anchored : bool, optional
        The target rotation was given: :meth:`prepare` keeps it (default False).
    own_target : bool, optional
        Held out: the target's point and rotation are re-fitted (default False).
    std : float, optional
        σ of every joint's reading, m or rad (default 1e-4).

    See Also
    --------
    in_joint_space : A set of poses with its residual in joint space.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import PoseJointObs
    >>> robot = kincal.load_robot("hexapod")
    >>> q = robot.sample_joints(4, seed=1)
    >>> p, R, _, _ = robot.pose_and_jacobian(q)
    >>> obs = PoseJointObs(q, np.arange(2, 6), "platform.csv", xyz=p, R=R, std=1e-5)
    >>> obs.kind, obs.sigma().shape, obs.nuisance(robot)[0]
    ('joint', (24,), ('target.rx', 'target.ry', 'target.rz'))
    """

    std: float = 1e-4

    def position_axes(self) -> np.ndarray:
        return np.full(self.q.size, -1)

    def measured_noise(self, robot: Robot, values: np.ndarray, nuis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Rm = self.R @ self.target(nuis).transpose()  # the platform frame the measurement implies
        var = [np.broadcast_to(np.asarray(s, float) ** 2, len(self.q)) for s in (self.std_pos, self.std_rot)]
        return robot.inverse_rates(self.xyz, values, Rm), np.repeat(np.column_stack(var), 3, axis=1)

    def evaluate(self, robot: Robot, values: np.ndarray, nuis: np.ndarray):
        Rm = self.R @ self.target(nuis).transpose()  # the platform frame the measurement implies
        try:
            qh, Js, Jw = robot.inverse_pose_and_jacobian(Rm, self.xyz, values)
        except ModelError:  # a trial step where some measured pose is out of reach: reject it
            return np.full(self.q.size, np.inf), np.zeros((self.q.size, robot.n_params)), np.zeros((self.q.size, 3))
        # a turn dn of the target turns the platform frame by −R J_r(n) dn (world axes)
        Jn = -Jw @ (self.R @ so3_right(nuis[:3]))
        r, J = component_major(qh - self.q, Js, np.arange(robot.n_params))
        return r, J, Jn.transpose(1, 0, 2).reshape(-1, 3)

    def check(self, robot: Robot, values: np.ndarray) -> None:
        R = self.R @ self.target(np.zeros(3)).T
        reach = lambda k: np.all(np.isfinite(robot.inverse_pose(R, self.xyz * k, values, strict=False)),  # noqa: E731
                                 axis=1)
        out_of_reach(self, robot, values, ~reach(1.0), "poses", lambda k: bool(np.all(reach(k))))


def in_joint_space(obs, std: float | None = None):
    """A set with its residual in joint space (``residual='joint'``).

    Points become a :class:`JointObs`, 6-D poses a :class:`PoseJointObs` (σ: the joints' reading noise,
    their default ``std``; the positions' and rotations' σ kept, which reach the joints through the inverse
    kinematics), a session's or a drifting instrument's set is converted inside its wrapper; a
    set already in joint space is returned as it is.

    Parameters
    ----------
    obs : Observation
        The set (points, poses, or a wrapper of them).
    std : float, optional
        The joints' reading noise σ, rad or m (default: the types' own, 1e-4).

    Returns
    -------
    Observation
        The same samples with the joint-space residual.

    Raises
    ------
    ValueError
        For the kinds that measure no position or pose to invert (markers, same-point, plane).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.observe import PointObs, in_joint_space
    >>> robot = kincal.load_robot("puu3")
    >>> meas = kincal.simulate(robot, robot.sample_joints(4, seed=1))
    >>> obs = in_joint_space(PointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz))
    >>> type(obs).__name__, obs.kind, in_joint_space(obs) is obs
    ('JointObs', 'joint', True)
    """
    if obs.kind == "joint":
        return obs if std is None else dataclasses.replace(obs, std=std)
    if isinstance(obs, Wrapper):
        return dataclasses.replace(obs, inner=in_joint_space(obs.inner, std))
    sigma = {} if std is None else {"std": std}
    if isinstance(obs, PoseObs):
        return PoseJointObs(q=obs.q, rows=obs.rows, source=obs.source, xyz=obs.xyz, R=obs.R, **sigma,
                            std_pos=obs.std_pos, std_rot=obs.std_rot, target_rotation=obs.target_rotation,
                            anchored=obs.anchored, own_target=obs.own_target)
    if isinstance(obs, PointObs):
        return JointObs(q=obs.q, rows=obs.rows, source=obs.source, xyz=obs.xyz, std_pos=obs.std, **sigma)
    raise ValueError(f"residual='joint' inverts measured positions or poses; {obs.kind} data ({obs.source}) have "
                     f"none to invert: use residual='cartesian'")


def in_cartesian(obs):
    """The set ``obs`` with its residual in the measurement's own space: the inverse of :func:`in_joint_space` (a
    :class:`JointObs` becomes the :class:`PointObs`, a :class:`PoseJointObs` the :class:`PoseObs` it was made of;
    a wrapper keeps its wrapping); any other set as it is. What a figure of the nominal model is judged on
    whatever residual the fit used: the position and rotation errors it reports.

    Parameters
    ----------
    obs : Observation
        A set of any type, its residual in joint space or not.

    Returns
    -------
    Observation
        The same samples, σ and target, with the residual of their measurement (positions in m, rotations in
        rad).

    Examples
    --------
    >>> import kincal
    >>> from kincal.observe import PointObs, in_cartesian, in_joint_space
    >>> robot = kincal.load_robot("puu3")
    >>> meas = kincal.simulate(robot, robot.sample_joints(4, seed=1))
    >>> obs = PointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz, std=20e-6)
    >>> back = in_cartesian(in_joint_space(obs))
    >>> type(back).__name__, back.kind, back.std, bool((back.xyz == obs.xyz).all()), in_cartesian(obs) is obs
    ('PointObs', 'point', 2e-05, True, True)
    """
    if isinstance(obs, Wrapper):
        return dataclasses.replace(obs, inner=in_cartesian(obs.inner))
    if isinstance(obs, PoseJointObs):
        return PoseObs(q=obs.q, rows=obs.rows, source=obs.source, xyz=obs.xyz, R=obs.R, std_pos=obs.std_pos,
                       std_rot=obs.std_rot, target_rotation=obs.target_rotation, anchored=obs.anchored,
                       own_target=obs.own_target)
    if isinstance(obs, JointObs):
        return PointObs(q=obs.q, rows=obs.rows, source=obs.source, xyz=obs.xyz, std=obs.std_pos)
    return obs
