"""Compensation: joint commands that the calibrated model says reach given target positions."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .._frozen import freeze_arrays
from ..analysis.uncertainty import ModelUncertainty, envelope_warning, extrapolation_warning
from ..checks import kind_of, number
from ..units import MM, joint_shown
from ..errors import ModelError
from ..models.robot import Robot
from ..models.terms import without_unread_covariates
from .frames import MISMATCH_TOL, base_mismatch, frame_mismatch, orientation_change, unit_mismatch

IK_TOL = 1e-10  # m
IK_ITER = 100
BRANCH_TOL = {"revolute": np.deg2rad(5.0), "prismatic": 5e-3}  # a correction larger than this changes branch
GIVE_UP = 2.0  # pose solves stop a target this many times branch_tolerance from its nominal command
START_TOL = 50e-3  # m: the model at the nominal command must be this close to the target
POS_TOL = 1e-6  # m: a command must reach its target position this closely
REACH_MARGIN = 1.2  # targets farther from the base than this times the reach bound are out of reach


@dataclass(frozen=True)
class Compensation:
    """Joint commands that the calibrated model says reach given targets, each checked before use.

    ``ok`` says which commands passed every check (reach, joint limits, branch, model residual);
    ``problems`` holds one message per refused target, naming its input row (``rows``).

    Parameters
    ----------
    q : ndarray, shape (N, n)
        The commands, rad (m for a prismatic joint); the nominal commands when nothing was corrected.
    residual : ndarray, shape (N,)
        ``abs(model(q) - target)``, m (inf where no command was found).
    method : str
        How ``q`` was found: "damped least squares", "closed-form inverse", "pose (damped Newton)",
        "closed-form inverse (poses)", or "not corrected" (a set-up mismatch refused every row).
    iterations : int
        Iterations of the solve (0 for a closed form).
    ok : ndarray of bool, shape (N,)
        Which commands passed every check.
    problems : tuple of str
        One message per refused target ("row r: why"), or one for all on a set-up mismatch.
    rows : ndarray, shape (N,)
        The targets' row numbers, as the messages name them.
    predicted_sigma : ndarray, shape (N,), optional
        The model's predicted σ of the position at each accepted command, m (NaN at refused ones), where
        the model's uncertainty is known; None else.
    warnings : tuple of str, optional
        Warnings for accepted commands: where the model extrapolates or leaves the joint envelope of its
        data, rotations a robot with fewer than six joints does not control.
    orientation_change : ndarray, shape (N,), optional
        How far the tool orientation the model predicts at ``q`` lies from the one the nominal model
        promises at the nominal command, rad (position targets compensated with the nominal model).
    rotation_residual : ndarray, shape (N,), optional
        Pose targets: ``abs(log(R_target R(q)ᵀ))``, rad.
    filtered : tuple of ndarray, optional
        Pose targets with the nominal model: the positions (N, 3) m and rotations (N, 3, 3) to send a
        controller moving with the nominal model (:func:`filtered_poses`).

    See Also
    --------
    compensate : Makes it.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q0 = nominal.sample_joints(3, seed=2)
    >>> comp = compensate(real, nominal.forward(q0), q0, nominal=nominal)
    >>> comp.method, comp.all_ok, comp.rows.tolist(), comp.problems
    ('damped least squares', True, [1, 2, 3], ())
    >>> bool(comp.residual.max() < 1e-9)
    True
    >>> np.round(comp.orientation_change * 1e3, 2)  # mrad
    array([3.36, 0.46, 2.78])
    >>> sorted(comp.to_dict())
    ['iterations', 'max_residual', 'method', 'ok', 'orientation_change', 'predicted_sigma', 'problems', 'q',
     'residual', 'rotation_residual', 'warnings']
    """

    q: np.ndarray
    residual: np.ndarray
    method: str
    iterations: int
    ok: np.ndarray
    problems: tuple[str, ...]
    rows: np.ndarray
    predicted_sigma: np.ndarray | None = None  # (N,) m, where the model's uncertainty is known
    warnings: tuple[str, ...] = ()
    orientation_change: np.ndarray | None = None  # (N,) rad: model at q vs the nominal promise at q_start
    rotation_residual: np.ndarray | None = None  # (N,) rad, pose targets: |log(R_target R(q)ᵀ)|
    filtered: tuple[np.ndarray, np.ndarray] | None = None  # poses to send a controller moving with the nominal model

    def __post_init__(self) -> None:
        freeze_arrays(self)

    @property
    def all_ok(self) -> bool:
        """True when every command passed every check."""
        return bool(self.ok.all())

    def to_dict(self) -> dict:
        """The result as plain JSON values (None for the commands and values of refused rows), m and rad."""
        ok = self.ok
        res = np.where(np.isfinite(self.residual), self.residual, np.nan)
        accepted = lambda a: None if a is None else [float(x) if k else None for x, k in zip(a, ok)]  # noqa: E731
        finite = lambda a: None if a is None else [float(x) if np.isfinite(x) else None for x in a]  # noqa: E731
        return {"q": [qi.tolist() if k else None for qi, k in zip(self.q, ok)], "residual": finite(res),
                "max_residual": float(np.nanmax(res[ok])) if ok.any() else None, "method": self.method,
                "iterations": self.iterations, "ok": ok.tolist(), "problems": list(self.problems),
                "predicted_sigma": finite(self.predicted_sigma), "warnings": list(self.warnings),
                "orientation_change": accepted(self.orientation_change),
                "rotation_residual": accepted(self.rotation_residual)}


def compensate(robot: Robot, targets: np.ndarray, q_start: np.ndarray | None = None, *, damping: float = 1e-4,
               rows: np.ndarray | None = None, uncertainty: ModelUncertainty | None = None,
               nominal: Robot | None = None, rotations: np.ndarray | None = None,
               orientation: Robot | None = None, measured: np.ndarray | None = None) -> Compensation:
    """Joint commands that place ``robot``'s tool at the targets, each checked before use.

    Robots with a closed-form inverse (parallel robots) use it. Otherwise (serial robots) a damped
    least-squares iteration on the model, started from ``q_start`` — normally the commands the
    nominal model gives for the targets — converges to the nearest solution; the damping keeps
    steps small near singularities. Every command is then checked: the target must be within reach
    (and plausibly in the declared unit), the command inside the joint limits, on the same branch
    as the nominal command (no joint moving more than :func:`branch_tolerance`), with a model residual under
    1 µm. ``ok`` and ``problems`` report the checks. Every argument is checked before any work.

    Parameters
    ----------
    robot : Robot
        The calibrated model (where the robot really goes), in the targets' frame.
    targets : ndarray, shape (N, 3)
        Target positions of the tool point, m.
    q_start : ndarray, shape (N, n), optional
        The nominal commands of the targets, rad (m for a prismatic joint): the start of the iteration and
        the branch every command must stay on. Required unless the robot has a closed-form inverse.
    damping : float, optional
        Damping of the least-squares steps, m (default 1e-4).
    rows : ndarray, shape (N,), optional
        The row numbers the messages name (default 1, 2, ..., N).
    uncertainty : ModelUncertainty, optional
        The model's uncertainty: the predicted σ at every accepted command is reported, with a warning
        naming the rows where the model extrapolates.
    nominal : Robot, optional
        The nominal (controller's) model, same frame and tool point (:func:`command_models`): a model whose
        base frame is another (a calibrated model as fitted: the instrument's) is refused (ModelError,
        :func:`base_mismatch`). The nominal joints must first reach the targets through it: a TCP or frame
        mismatch refuses every row, named with its size and direction (:func:`frame_mismatch`); the predicted
        change of the tool orientation is reported.
    rotations : ndarray, shape (N, 3, 3), optional
        Target rotations of the flange: the targets are full poses (:func:`compensate_poses`).

    orientation : Robot, optional
        With ``rotations``: the model whose flange is turned to them (:func:`compensate_poses`); the nominal
        model when the calibration measured no orientation.
    measured : ndarray, shape (3,), optional
        With ``orientation``: the point the calibration measured, m, flange frame (:func:`compensate_poses`).

    Returns
    -------
    Compensation
        The commands (N, n), their residuals (N,) m, which passed every check and why the others did not.

    Raises
    ------
    ModelError
        When the robot has covariate terms, is a hexapod given position targets only, has no inverse and
        no ``q_start``, stands in another base frame than ``nominal``, or the targets or start joints are not
        finite or do not match in number.
    ValueError
        When ``rows`` does not give one number per target.
    TypeError
        When ``robot`` or ``nominal`` is not a Robot (a calibration's result: :func:`command_models` gives the pair).

    See Also
    --------
    compensate_poses, path_checked, command_models

    Examples
    --------
    A UR5 whose link lengths and joint zeros are off by up to 1 mm and 1 mrad, sent to three targets that the
    nominal model reaches at ``q0``:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q0 = nominal.sample_joints(3, seed=2)
    >>> targets = nominal.forward(q0)
    >>> comp = compensate(real, targets, q0)
    >>> comp.ok.tolist()
    [True, True, True]
    >>> round(float(np.abs(comp.q - q0).max()) * 1e3, 2)  # the largest correction, mrad
    3.54
    >>> bool(np.linalg.norm(real.forward(comp.q) - targets, axis=1).max() < 1e-9)
    True

    Targets in mm given as m spread a thousand times more than the robot moves at their joints: none is corrected,
    and the unit is named (:func:`unit_mismatch`):

    >>> bad = compensate(real, targets * 1e3, q0)
    >>> bad.ok.tolist(), bad.method
    ([False, False, False], 'not corrected')
    >>> print(bad.problems[0])
    the targets spread ...x more than the model moves at their nominal joints: they look like mm, not m; give them in
    m (x0.001). Not corrected: a unit mistake, not a robot error

    One target (no spread to judge by) is out of reach, and its row says so:

    >>> print(compensate(real, targets[:1] * 1e3, q0[:1], rows=np.array([10])).problems[0])
    row 10: target ... mm from the base, beyond the robot's reach (1225.4 mm): out of reach, or not in the
    declared length unit
    """
    _robots(robot, nominal, orientation)
    refuse_covariates(robot)
    _same_frame(robot, nominal)
    if rotations is not None:
        return compensate_poses(robot, targets, rotations, q_start, rows=rows, uncertainty=uncertainty,
                                nominal=nominal, orientation=orientation, measured=measured)
    if orientation is not None:
        raise ValueError("orientation names the model whose flange is turned to target rotations: it applies to "
                         "pose targets only (give rotations)")
    if robot.has_pose_inverse:
        raise ModelError(f"robot '{robot.name}' ({robot.structure}): its joints are set by the platform's whole pose; "
                         f"give 6-D targets, position and orientation (rotations=; CLI: --pose)")
    targets, q0, rows = _checked_inputs(robot, targets, q_start, damping, rows)
    why = _set_up_mismatch(robot, nominal, q0, targets)
    if why:
        return Compensation(q0.copy(), np.full(len(targets), np.inf), "not corrected", 0, np.zeros(len(targets), bool),
                            (why,), rows)
    if robot.has_inverse:  # (no nominal commands q0 to check against)
        q, method, it = robot.inverse(targets, strict=False), "closed-form inverse", 0
    else:
        q, method, it = q0.copy(), "damped least squares", 0
        for it in range(1, IK_ITER + 1):
            e = targets - robot.forward(q)
            if np.max(np.linalg.norm(e, axis=1)) < IK_TOL:
                break
            Jq = robot.joint_jacobian(q)  # (N, 3, n)
            A = Jq @ np.swapaxes(Jq, 1, 2) + damping**2 * np.eye(3)
            q = q + np.einsum("nji,nj->ni", Jq, np.linalg.solve(A, e[..., None])[..., 0])
    comp = _with_sigma(robot, _checked(robot, q, method, it, targets, q0, rows, nominal), uncertainty)
    if nominal is None or q0 is None or not robot.has_tool_point:
        return comp
    return dataclasses.replace(comp, orientation_change=orientation_change(robot, q, nominal, q0))


def branch_tolerance(robot: Robot) -> np.ndarray:
    """How far each joint's corrected command may move from the nominal one and stay on its branch.

    ``BRANCH_TOL`` of what the joint moves: an angle's (5°) for a revolute joint, a length's (5 mm) for a prismatic
    one and for a motor turning a screw (``robot.motor_leads``), converted through its lead (a screw has no other
    configuration: its turns add up to travel, so 5° of a 10 mm lead would refuse a correction of 0.14 mm).

    Parameters
    ----------
    robot : Robot
        The robot (its joint types and any motors' leads).

    Returns
    -------
    ndarray, shape (n,)
        The tolerances, rad (m for a prismatic joint).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate.commands import branch_tolerance
    >>> np.degrees(branch_tolerance(kincal.load_robot("ur5"))).round(3).tolist()
    [5.0, 5.0, 5.0, 5.0, 5.0, 5.0]
    >>> np.degrees(branch_tolerance(kincal.load_robot("guo3t2r"))).round(3).tolist()  # 10 mm leads: 5 mm of travel
    [360.0, 360.0, 180.0, 5.0, 5.0]
    """
    typed = np.array([BRANCH_TOL[t] for t in robot.joint_types])
    lead = robot.motor_leads
    return np.where(np.isnan(lead), typed, BRANCH_TOL["prismatic"] / np.where(np.isnan(lead), 1.0, lead))


def past_limits(robot: Robot, q: np.ndarray) -> str:
    """Which joint of q breaks the robot's limits and by how much, in kincal's display units; '' when none does.

    Parameters
    ----------
    robot : Robot
        The robot (its joint limits, rad or m).
    q : ndarray, shape (n,)
        The joints, rad (m for a prismatic joint).

    Returns
    -------
    str
        The first joint past a limit: its value, the limit and the excess ('' when every joint is inside).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate.commands import past_limits
    >>> robot = kincal.load_robot("kuka_kr6r900sixx")
    >>> past_limits(robot, np.radians([0, -90, 90, 0, 30, -350.25]))
    'a6 at -350.250 deg, past its limit -350.000 deg by 0.250 deg'
    >>> past_limits(robot, np.radians([0, -90, 90, 0, 30, 0]))
    ''
    """
    q = np.asarray(q, dtype=float)
    excess = np.maximum(robot.lower - q, q - robot.upper)
    off = np.flatnonzero(excess > 1e-12)  # within_limits' own margin
    if not off.size:
        return ""
    j = int(off[0])
    unit, f = joint_shown(robot.joint_types, robot.periodic)[j]
    limit = robot.lower[j] if q[j] < robot.lower[j] else robot.upper[j]
    return (f"{robot.joint_names[j]} at {q[j] * f:.3f} {unit}, past its limit {limit * f:.3f} {unit} by "
            f"{excess[j] * f:.3f} {unit}")


def refuse_covariates(robot: Robot) -> None:
    """ModelError for a robot that reads covariates (a thermal term's temperature): compensation solves for the
    joints alone. One whose covariates no term reads is that model without them
    (:func:`kincal.models.without_unread_covariates`)."""
    read = without_unread_covariates(robot).covariate_names
    if read:
        raise ModelError(f"robot '{robot.name}' has covariate terms ({', '.join(read)}): its "
                         f"commands depend on the covariate's value at each target, which compensation does not take "
                         f"yet; compensate with a calibration without the covariate term")
    if robot.covariate_names:
        raise ModelError(f"robot '{robot.name}' reads the covariate(s) {', '.join(robot.covariate_names)}, which no "
                         f"term uses: compensate without_unread_covariates(robot), the same model without them")


def _robots(robot: Robot, nominal: Robot | None, orientation: Robot | None) -> None:
    """TypeError unless the models given are robots (a calibration's result where its robot belongs: what to give)."""
    pair = "command_models(result.robot, result.nominal.params.as_dict()) gives both in the targets' frame"
    kind_of("robot", robot, Robot, f"the calibrated model; of a calibration: model, nominal = {pair}")
    for name, value in (("nominal", nominal), ("orientation", orientation)):
        if value is not None:
            kind_of(name, value, Robot, f"the nominal model; of a calibration: model, nominal = {pair}"
                    if name == "nominal" else "the model whose flange is turned to the target rotations")


def _same_frame(robot: Robot, nominal: Robot | None) -> None:
    """ModelError when ``robot`` and ``nominal`` stand in different base frames (:func:`base_mismatch`)."""
    why = "" if nominal is None else base_mismatch(robot, nominal)
    if why:
        raise ModelError(why)


def _set_up_mismatch(robot: Robot, nominal: Robot | None, q0: np.ndarray | None, targets: np.ndarray) -> str:
    """Why no target can be corrected, before any is: targets in another length unit than m (judged against the
    nominal model, else ``robot``: :func:`unit_mismatch`), or a TCP or frame mismatch (:func:`frame_mismatch`);
    '' when neither (or no nominal joints to judge by)."""
    if q0 is None:
        return ""
    return unit_mismatch(nominal or robot, q0, targets) or ("" if nominal is None else
                                                             frame_mismatch(nominal, q0, targets))


def _checked_inputs(robot: Robot, targets, q_start, damping: float, rows):
    """Targets (N, 3), the starting joints (N, n) (None with a closed-form inverse) and the rows (N,),
    checked: finite numbers, matching counts, a positive damping."""
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    if targets.ndim != 2 or targets.shape[1] != 3 or not np.all(np.isfinite(targets)):
        raise ModelError(f"targets must be finite positions (N, 3) in m, got shape {targets.shape}")
    number("damping", damping, unit="m")
    rows = np.arange(1, len(targets) + 1) if rows is None else np.asarray(rows)
    if rows.shape != (len(targets),):
        raise ValueError(f"rows: {rows.shape[0] if rows.ndim else 0} row numbers for {len(targets)} targets")
    if robot.has_inverse or robot.has_pose_inverse:
        return targets, None, rows
    if q_start is None:
        raise ModelError(f"robot '{robot.name}' has no closed-form inverse: give the nominal joint values of the "
                         f"targets as the starting point")
    q0 = robot.check_q(q_start)
    if q0.shape[0] != targets.shape[0] or not np.all(np.isfinite(q0)):
        raise ModelError(f"{targets.shape[0]} targets but {q0.shape[0]} starting joint vectors (finite values needed)")
    return targets, q0, rows


def _with_sigma(robot: Robot, comp: Compensation, unc: ModelUncertainty | None) -> Compensation:
    """The compensation with the predicted σ at its accepted commands and an extrapolation warning."""
    if unc is None or not comp.ok.any():
        return comp
    sigma = np.full(len(comp.q), np.nan)
    sigma[comp.ok] = unc.sigma(robot, comp.q[comp.ok])
    ok = comp.ok
    warnings = (extrapolation_warning(comp.rows[ok], sigma[ok], unc, comp.q[ok], robot),
                envelope_warning(comp.rows[ok], comp.q[ok], robot, unc)[1])
    return dataclasses.replace(comp, predicted_sigma=sigma, warnings=tuple(w for w in warnings if w))


def _checked(robot: Robot, q: np.ndarray, method: str, iterations: int, targets: np.ndarray, q0: np.ndarray | None,
             rows: np.ndarray, nominal: Robot | None = None, turn: tuple = (None, None)) -> Compensation:
    """The compensation by commands q (how they were found; their model residuals: inf where q is not
    finite, the TCP where ``turn``, the model whose flange turn is followed and the point the calibration
    measured, puts it: :func:`kincal.compensate.poses.tcp_positions`) with every command checked; the first
    failed check of each row is reported."""
    from .poses import assembled_rows, tcp_positions

    residual = np.full(len(q), np.inf)  # inf also where a closed chain does not assemble: refused by row
    good, at = assembled_rows(lambda i: tcp_positions(robot, q[i], *turn), q)
    if good.size:
        residual[good] = np.linalg.norm(at - targets[good], axis=1)
    why: list[str | None] = [None] * len(targets)
    for bad, message in _checks(robot, q, residual, targets, q0, nominal):
        for k in np.flatnonzero(bad):
            why[k] = why[k] or f"row {rows[k]}: {message(k)}"
    ok = np.array([w is None for w in why])
    return Compensation(q, residual, method, iterations, ok, tuple(w for w in why if w), rows)


def _checks(robot: Robot, q: np.ndarray, residual: np.ndarray, targets: np.ndarray, q0: np.ndarray | None,
            nominal: Robot | None):
    """(mask of failing rows, message for row k) per check, in the order they are reported. With the
    nominal model the nominal command must reach its target within MISMATCH_TOL, else START_TOL (the
    calibrated model is then the only one known)."""
    mm = lambda x: f"{x * MM:.1f} mm"  # noqa: E731
    finite = np.all(np.isfinite(q), axis=1)
    dist, reach = _reach(robot, targets)
    yield dist > REACH_MARGIN * reach, lambda k: (f"target {mm(dist[k])} from the base, beyond the robot's reach "
                                                  f"({mm(reach)}): out of reach, or not in the declared length unit")
    yield ~finite, lambda k: "out of reach of the calibrated model (no inverse kinematics solution)"
    if q0 is not None:
        gap = np.linalg.norm((nominal or robot).forward(q0) - targets, axis=1)
        tol = START_TOL if nominal is None else MISMATCH_TOL
        yield gap > tol, lambda k: (f"the nominal command lands {gap[k] * MM:.3f} mm from the target"
                                    f"{' through the nominal model' if nominal else ''}: the joint values and the "
                                    f"target do not belong together (units, column order, TCP or frame?)")
        jump = np.where(finite[:, None], np.abs(q - q0), 0.0) > branch_tolerance(robot)
        names = robot.joint_names
        yield jump.any(axis=1), lambda k: (f"the corrected command moves joint(s) "
                                           f"{', '.join(n for n, j in zip(names, jump[k]) if j)} away from the nominal "
                                           f"one (another arm configuration); refused")
    lim = finite & ~robot.within_limits(np.where(finite[:, None], q, 0.0))
    yield lim, lambda k: f"the command breaks the joint limits: {past_limits(robot, q[k])}"
    yield finite & np.isinf(residual), lambda k: ("the calibrated model does not assemble at the command (its forward "
                                                  "kinematics find no pose there): out of reach, or at a singularity")
    few = (f"; a robot of {robot.n_joints} joint{'s' if robot.n_joints > 1 else ''} reaches a "
           f"{'surface' if robot.n_joints == 2 else 'curve'} of points only: a target off it cannot be reached; give "
           f"points it reaches, such as the nominal model's at the commands") if robot.n_joints < 3 else ""
    yield finite & (residual > POS_TOL), lambda k: (f"the model misses the target by {residual[k] * MM:.3f} mm (a "
                                                    f"command must reach it within {POS_TOL * MM:g} mm{few})")


def _reach(robot: Robot, targets: np.ndarray) -> tuple[np.ndarray, float]:
    """Distance of each target from the robot's base origin, and an upper bound on the reach (m): the
    sum of every length parameter but the base frame's and of the prismatic joints' travel. No
    reachable target exceeds it; a target in the wrong unit (mm read as m) lies far beyond."""
    t = robot.base_transform()[1] if robot.base_params() else np.zeros(3)
    p = robot.params
    base = set(robot.base_params())
    links = sum(abs(v) for n, k, v in zip(p.names, p.kinds, p.values) if k == "length" and n not in base)
    travel = sum(max(abs(lo), abs(hi)) for t_, lo, hi in zip(robot.joint_types, robot.lower, robot.upper)
                 if t_ == "prismatic" and np.isfinite(lo) and np.isfinite(hi))
    return np.linalg.norm(targets - t, axis=1), float(links + travel)


ROT_TOL = 1e-6  # rad: a pose command must reproduce the target orientation this closely (6 joints or more)
ORIENT_MISMATCH = 1e-3  # rad: the nominal command's orientation must match the target's this closely


def compensate_poses(robot: Robot, targets: np.ndarray, rotations: np.ndarray, q_start: np.ndarray | None, *,
                     rows: np.ndarray | None = None, uncertainty: ModelUncertainty | None = None,
                     nominal: Robot | None = None, orientation: Robot | None = None,
                     measured: np.ndarray | None = None) -> Compensation:
    """Joint commands that put ``robot``'s tool point at target poses, each checked before use.

    Each command is checked like a position command (:func:`compensate`) and, with six joints or more,
    for the orientation too (to 1 µrad); with fewer joints the rotation they cannot control is reported
    (``rotation_residual`` and a warning). A hexapod's legs follow from the poses in closed form.

    Parameters
    ----------
    robot : Robot
        The calibrated model, with a tool point and flange frame, in the targets' frame.
    targets : ndarray, shape (N, 3)
        Target positions of the tool point, m.
    rotations : ndarray, shape (N, 3, 3)
        Target rotations of the flange.
    q_start : ndarray, shape (N, n) or None
        The nominal commands of the targets, rad (m for a prismatic joint): the start of the solve and the
        branch every command must stay on (None for a robot with a closed-form inverse).
    rows : ndarray, shape (N,), optional
        The row numbers the messages name (default 1, 2, ..., N).
    uncertainty : ModelUncertainty, optional
        The model's uncertainty: the predicted σ at every accepted command.
    nominal : Robot, optional
        The nominal (controller's) model: the set-up is checked first (a TCP, frame or orientation
        mismatch refuses every row), and the filtered poses are given: what to send that controller so
        that its inverse kinematics give these commands.

    orientation : Robot, optional
        The model whose flange the commands turn to the target rotations (default: ``robot``). Give the nominal
        model when the calibration measured no orientation (points, sockets, planes): its parameters are then
        fitted to positions alone, and the turns of the flange they imply are not seen by the data (a UR5
        calibrated from a reflector on the flange's axis turned the true flange 0.17° from its targets, against
        0.10° for the nominal commands); the positions still come from ``robot``.
    measured : ndarray, shape (3,), optional
        With ``orientation``: the point the calibration measured, m in the flange frame (the calibrated file's tool
        point; default: ``robot``'s tool point, the TCP). ``robot``'s position is trusted there, and a TCP beyond
        it is carried on by ``orientation``'s turn (:func:`kincal.compensate.poses.tcp_positions`), not by
        ``robot``'s, which the data did not determine: the lever would carry that turn's error to the TCP.

    Returns
    -------
    Compensation
        The commands (N, n) with ``rotation_residual`` (N,) rad and, with ``nominal``, ``filtered``.

    Raises
    ------
    ModelError
        When the rotations are not finite right-handed rotation matrices (N, 3, 3), the robot has no tool
        point, or the targets or start joints are not finite or do not match in number.
    TypeError
        When ``robot``, ``nominal`` or ``orientation`` is not a Robot (a calibration's result: :func:`command_models`
        gives the pair).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate_poses
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q0 = nominal.sample_joints(3, seed=2)
    >>> p, R, _, _ = nominal.pose_and_jacobian(q0)  # the poses the controller means at q0
    >>> comp = compensate_poses(real, p, R, q0, nominal=nominal)
    >>> comp.method, comp.all_ok
    ('pose (damped Newton)', True)
    >>> bool(comp.rotation_residual.max() < 1e-9)
    True
    >>> p_send, R_send = comp.filtered
    >>> p_send.shape, R_send.shape
    ((3, 3), (3, 3, 3))
    """
    from .poses import at_measured, filtered_poses, model_turn, solve_poses

    _robots(robot, nominal, orientation)
    _same_frame(robot, nominal)
    targets, q0, rows = _checked_inputs(robot, targets, q_start, 1e-4, rows)
    rotations = _checked_rotations(rotations, len(targets))
    if robot.has_pose_inverse:  # a hexapod: the legs of each pose in closed form, checked through the forward model
        point, at = (robot, targets) if orientation is None else at_measured(robot, targets, rotations, measured)
        goal = rotations if orientation is None else _closed_form_goal(orientation, point, at, rotations)
        comp = _closed_form_poses(point, at, goal, rows, nominal)
        if orientation is not None:
            comp = dataclasses.replace(comp, rotation_residual=model_turn(orientation, comp.q, rotations))
        return _with_sigma(robot, comp, uncertainty)
    why = _set_up_mismatch(robot, nominal, q0, targets) or (
        "" if nominal is None else _orientation_mismatch(nominal, q0, rotations))
    if why:
        none = np.zeros(len(targets), bool)
        return Compensation(q0.copy(), np.full(len(targets), np.inf), "not corrected", 0, none, (why,), rows)
    give_up = GIVE_UP * branch_tolerance(robot)  # refused by the branch check anyway
    sol = solve_poses(robot, targets, rotations, q0, give_up=give_up, turned_as=orientation, measured=measured)
    comp = _checked(robot, sol.q, "pose (damped Newton)", sol.iterations, targets, q0, rows, nominal,
                    (orientation, measured))
    if robot.n_joints >= 6:
        bad = comp.ok & (sol.rotation_error > ROT_TOL)
        problems = comp.problems + tuple(f"row {r}: the model misses the target orientation by "
                                         f"{e * 1e3:.4f} mrad" for r, e in zip(rows[bad], sol.rotation_error[bad]))
        comp = dataclasses.replace(comp, ok=comp.ok & ~bad, problems=problems)
    comp = dataclasses.replace(_with_sigma(robot, comp, uncertainty), rotation_residual=sol.rotation_error)
    if robot.n_joints < 6 and comp.ok.any():
        comp = dataclasses.replace(comp, warnings=comp.warnings + (
            uncontrolled_warning(robot, float(sol.rotation_error[comp.ok].max())),))
    return comp if nominal is None else dataclasses.replace(comp, filtered=filtered_poses(nominal, sol.q))


def _closed_form_goal(model: Robot, robot: Robot, targets: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """The rotations of :func:`kincal.compensate.poses.turn_goal` for a robot whose joints follow from the pose in
    closed form (a hexapod's legs)."""
    from .poses import TURN_ROUNDS, turn_goal

    goal = rotations
    for _ in range(TURN_ROUNDS):
        with np.errstate(invalid="ignore"):
            q = robot.inverse_pose(goal, targets, strict=False)
        goal = turn_goal(model, robot, q, rotations)
    return goal


def _closed_form_poses(robot: Robot, targets: np.ndarray, rotations: np.ndarray, rows: np.ndarray,
                       nominal: Robot | None) -> Compensation:
    """Commands of a robot whose joints follow from the pose in closed form (its legs), checked like
    every command: limits, and the calibrated forward kinematics back at the target (position and
    orientation); with the ``nominal`` model, the filtered poses (what its inverse turns into them)."""
    from ..models.transforms import rotation_log
    from .poses import filtered_poses

    with np.errstate(invalid="ignore"):
        q = robot.inverse_pose(rotations, targets, strict=False)
    comp = _checked(robot, q, "closed-form inverse (poses)", 0, targets, None, rows, nominal)
    finite = np.isfinite(comp.residual)  # the legs are finite and the model assembles there
    turn = np.full(len(q), np.inf)
    if finite.any():
        R = robot.frame_and_rates(q[finite])[2]
        turn[finite] = np.linalg.norm(rotation_log(R @ np.swapaxes(rotations[finite], 1, 2)), axis=1)
    bad = comp.ok & (turn > ROT_TOL)
    comp = dataclasses.replace(comp, ok=comp.ok & ~bad, rotation_residual=turn, problems=comp.problems + tuple(
        f"row {r}: the model misses the target orientation by {e * 1e3:.4f} mrad"
        for r, e in zip(rows[bad], turn[bad])))
    if nominal is None or not finite.all():
        return comp
    return dataclasses.replace(comp, filtered=filtered_poses(nominal, q))


def uncontrolled_warning(robot: Robot, left: float) -> str:
    """What pose targets leave to a robot with fewer than six joints: ``left`` (rad) the largest
    rotation error at accepted commands."""
    return (f"{robot.n_joints} joints control the position and {robot.n_joints - 3} rotation(s): the rest of the "
            f"target orientation is not controlled, up to {left * 1e3:.3f} mrad left (rotation_residual)")


def _checked_rotations(rotations, n: int) -> np.ndarray:
    R = np.asarray(rotations, dtype=float)
    if R.shape != (n, 3, 3) or not np.all(np.isfinite(R)):
        raise ModelError(f"rotations must be finite (N, 3, 3) matrices for the {n} targets, got shape {R.shape}")
    dev = np.abs(np.einsum("nki,nkj->nij", R, R) - np.eye(3)).max(axis=(1, 2))  # columns unit and orthogonal
    bad = (dev > 1e-6) | (np.linalg.det(R) < 0)  # right-handed (det is ±1 within 1e-5 where dev passes)
    if bad.any():
        raise ModelError(f"target {int(np.flatnonzero(bad)[0]) + 1}: the orientation is not a rotation")
    return R


def _orientation_mismatch(nominal: Robot, q0: np.ndarray, rotations: np.ndarray) -> str:
    """A constant rotation between the nominal flange at the nominal joints and the targets' orientation
    (in the flange frame): the TCP's orientation or the convention differs; '' when they match."""
    from ..models.transforms import rotation_log

    Rn = nominal.flange_rotation(q0)
    local = rotation_log(np.swapaxes(Rn, 1, 2) @ rotations)  # target in the nominal flange frame
    if np.median(np.linalg.norm(local, axis=1)) <= ORIENT_MISMATCH:
        return ""
    c = np.median(local, axis=0)
    axis = ", ".join(f"{round(float(x), 2) + 0.0:.2f}" for x in c / max(float(np.linalg.norm(c)), 1e-300))
    return (f"the targets' orientation differs from the nominal flange at the nominal joints by "
            f"{np.linalg.norm(c) * 1e3:.1f} mrad about the flange axis ({axis}): a TCP orientation or an "
            f"orientation convention that differs from the model's; not corrected")


PATH_TOL = {"revolute": np.deg2rad(0.5), "prismatic": 0.5e-3}  # a step the correction may add between rows
PATH_RATIO = 3.0  # ... or this many times the nominal step, whichever is larger


def path_checked(robot: Robot, comp: Compensation, q_start: np.ndarray) -> Compensation:
    """Check a compensation as a path, whose consecutive rows are consecutive targets.

    A row whose corrected command steps from the previous row's much more than the nominal commands do
    (more than ``PATH_RATIO`` times the nominal step and more than ``PATH_TOL``: 0.5 deg, 0.5 mm) loses
    continuity: it is refused and named, with the joint and both steps. Rows refused already keep their
    first reason.

    Parameters
    ----------
    robot : Robot
        The calibrated model the commands are for (its joint types and names).
    comp : Compensation
        The compensation of the path's targets, in order.
    q_start : ndarray, shape (N, n)
        The nominal commands of the path, rad (m for a prismatic joint).

    Returns
    -------
    Compensation
        ``comp`` with the rows that lose continuity refused and named in ``problems``.

    Examples
    --------
    >>> import dataclasses
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate, path_checked
    >>> nominal = kincal.load_robot("ur5")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> q_start = np.array([0.3, -1.2, 1.5, -1.9, 1.2, 0.4]) + np.linspace(0.0, 0.02, 5)[:, None]
    >>> comp = compensate(real, nominal.forward(q_start), q_start)
    >>> path_checked(real, comp, q_start).ok.tolist()
    [True, True, True, True, True]

    A command that jumps (here made up: 50 mrad more on the first joint at row 3) is refused, and so is the
    step back at row 4:

    >>> q = comp.q.copy()
    >>> q[2, 0] += 0.05
    >>> jumped = path_checked(real, dataclasses.replace(comp, q=q), q_start)
    >>> jumped.ok.tolist()
    [True, True, False, False, True]
    >>> print(jumped.problems[0])
    row 3: the corrected command jumps 3.15 deg on j1 from the previous row where the nominal path moves 0.29 deg:
    continuity of the path is lost here (near a singularity?)
    """
    q, q0 = comp.q, np.asarray(q_start, dtype=float)
    d_cor, d_nom = np.abs(np.diff(q, axis=0)), np.abs(np.diff(q0, axis=0))
    tol = np.array([PATH_TOL[t] for t in robot.joint_types])
    over = (d_cor > np.maximum(PATH_RATIO * d_nom, tol)) & np.all(np.isfinite(q[1:]), axis=1)[:, None]
    bad = np.flatnonzero(over.any(axis=1) & comp.ok[1:]) + 1  # rows refused already keep their first reason
    fmt = lambda j, v: (f"{np.rad2deg(v):.2f} deg" if robot.joint_types[j] == "revolute"  # noqa: E731
                        else f"{v * 1e3:.2f} mm")
    problems = []
    for k in bad:
        j = int(np.argmax(np.where(over[k - 1], d_cor[k - 1] - d_nom[k - 1], -np.inf)))
        problems.append(f"row {comp.rows[k]}: the corrected command jumps {fmt(j, d_cor[k - 1, j])} on "
                        f"{robot.joint_names[j]} from the previous row where the nominal path moves "
                        f"{fmt(j, d_nom[k - 1, j])}: continuity of the path is lost here (near a singularity?)")
    ok = comp.ok.copy()
    ok[bad] = False
    return dataclasses.replace(comp, ok=ok, problems=comp.problems + tuple(problems))
