"""Error-model verification (the 3-PUU paper of 2024,
"Error analysis model of parallel robot based on parameters identification", §3.5, Table 5).

With an identified ("actual") model s′ and sample joint inputs q′: for each parameter error Δs (unit
error) the error model predicts the position p + Δp = FK(q′; s′ + Δs). The inverse of the actual
model maps that position onto commands q″ = IK(p + Δp; s′). Commanding q″ on the robot and measuring
p″ tests the error model: p″ should equal p + Δp up to the measurement noise.
"""
from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .._csv import read_text
from .._frozen import freeze_arrays
from ..analysis.sensitivity import UNIT
from ..errors import MeasurementError, ModelError
from ..io.measurements import write_csv
from ..units import MM, joint_factors, unit_factor
from ..models.robot import Robot
from ..models.transmission import TransmissionRobot
from .commands import compensate

WHY_TOLERANCE = ("  (the tolerance is how far a measured position may deviate and still count as the prediction come "
                 "true: the default 0.05 mm is about 3 σ of a 15 µm tracker, which noise alone exceeds in a few per "
                 "cent of cases; the 3-PUU paper of 2024 accepted its model with deviations up to about 0.45 mm, which "
                 "--tolerance 0.5 judges alike)")


@dataclass(frozen=True, eq=False)
class VerificationPlan:
    """Commands that test an error model, with the positions it predicts, case (parameter) by case.

    Parameters
    ----------
    cases : tuple of str
        The C parameters, each given a unit error (1 mm or 1 mrad) in turn.
    q_samples : ndarray, shape (N, n) or None
        The sample inputs the commands were made from, rad (m for a prismatic joint); None in a plan file
        written before kincal kept them.
    predicted : ndarray, shape (C, N, 3)
        The positions the error model predicts for each case at each sample, m.
    commands : ndarray, shape (C, N, n)
        The commands that realise them on the actual robot, rad (m for a prismatic joint).
    units : tuple of str, optional
        The unit error of each case as the tables name it ("mm", "mrad", "‰"; default: not named).

    See Also
    --------
    verification_plan : Makes it.

    Examples
    --------
    A plan written in mm and read back, then the positions measured at its commands compared with the
    predictions:

    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import VerificationPlan, verification_plan
    >>> robot = kincal.load_robot("puu3")
    >>> plan = verification_plan(robot, robot.sample_joints(4, seed=1), names=["L1", "L2"])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "plan.csv")
    ...     plan.write_csv(path, robot, length_unit="mm")
    ...     with open(path) as f:
    ...         print(f.readline() + f.readline(), end="")
    ...     again = VerificationPlan.read_csv(path, robot)
    # kincal verification plan for puu3; units: length=mm angle=rad
    case,sample,h1,h2,h3,x_pred,y_pred,z_pred,input_h1,input_h2,input_h3
    >>> again.cases, again.commands.shape
    (('L1', 'L2'), (2, 4, 3))
    >>> bool(np.abs(again.commands - plan.commands).max() < 1e-12)
    True
    >>> measured = robot.forward(plan.commands.reshape(-1, 3))  # a robot with no noise at all
    >>> plan.compare(measured).passed.tolist()
    [True, True]
    """

    cases: tuple[str, ...]
    q_samples: np.ndarray | None
    predicted: np.ndarray
    commands: np.ndarray
    units: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        freeze_arrays(self)  # the arrays it hands out: what it prints cannot drift from what it computed

    def compare(self, measured: np.ndarray, tolerance: float = 50e-6) -> "Verification":
        """Compare the positions measured at the commands with the predictions.

        Parameters
        ----------
        measured : ndarray, shape (C, N, 3)
            The positions measured at the commands, m (any shape with C·N·3 values, in that order).
        tolerance : float, optional
            The largest deviation per axis of a case that passes, m (default 50e-6).

        Returns
        -------
        Verification
            The deviations (C, N, 3) m, judged against ``tolerance``.
        """
        dev = np.asarray(measured, float).reshape(self.predicted.shape) - self.predicted
        return Verification(self.cases, dev, tolerance, self.units)

    def write_csv(self, path: str | os.PathLike, robot: Robot, joint_cols: Sequence[str] | None = None,
                  length_unit: str = "m", angle_unit: str = "rad") -> None:
        """Write the commands to run, case by case, with the predicted positions, in the given units (atomically).

        A first comment line records the units; columns: case, sample, one per joint, x_pred, y_pred, z_pred,
        then the sample inputs the commands were made from (``input_<joint>``). :meth:`read_csv` reads it
        back.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write.
        robot : Robot
            The robot of the plan (its name, joint names and types).
        joint_cols : sequence of str, optional
            The joint columns, one per joint (default: the robot's joint names).
        length_unit : str, optional
            The unit of the positions and prismatic joints: "m" (the default), "mm" or "um".
        angle_unit : str, optional
            The unit of the revolute joints: "rad" (the default), "deg" or "rev".

        Raises
        ------
        MeasurementError
            When ``joint_cols`` does not give one column per joint.
        """
        cols = list(joint_cols) if joint_cols else list(robot.joint_names)
        if len(cols) != robot.n_joints:
            raise MeasurementError(f"{path}: {len(cols)} joint columns given for {robot.n_joints} joints")
        qs, lf = np.array(joint_factors(robot.joint_types, length_unit, angle_unit)), unit_factor(length_unit, "length")
        known = self.q_samples is not None
        inputs = self.q_samples / qs if known else np.zeros(self.commands.shape[1:2] + (0,))
        rows = ([case, k + 1, *(repr(float(v)) for v in (*qc, *pc, *qi))]
                for case, cmds, pred in zip(self.cases, self.commands / qs, self.predicted / lf)
                for k, (qc, pc, qi) in enumerate(zip(cmds, pred, inputs)))
        write_csv(path, ["case", "sample", *cols, "x_pred", "y_pred", "z_pred", *(f"input_{c}" for c in cols if known)],
                  rows, first=f"# kincal verification plan for {robot.name}; units: length={length_unit} "
                              f"angle={angle_unit}\n")

    @classmethod
    def read_csv(cls, path: str | os.PathLike, robot: Robot) -> "VerificationPlan":
        """Read a plan written by :meth:`write_csv` (its units line says how to read it).

        Parameters
        ----------
        path : str or os.PathLike
            The plan file.
        robot : Robot
            The robot of the plan.

        Returns
        -------
        VerificationPlan
            The plan, in m and rad.

        Raises
        ------
        MeasurementError
            When the file is not a plan written by kincal, has the wrong number of columns, a value that
            is no number, or cases of different sizes.
        """
        lines = read_text(str(path)).splitlines()
        m = re.match(r"# kincal verification plan .*units: length=(\w+) angle=(\w+)", lines[0] if lines else "")
        if not m:
            raise MeasurementError(f"{path}: not a verification plan written by 'kincal verify -o' (its first line "
                                   f"names the units); write the plan with -o and pass that file")
        qs, lf = np.array(joint_factors(robot.joint_types, m.group(1), m.group(2))), unit_factor(m.group(1), "length")
        rows = list(csv.reader(lines[1:]))
        n = robot.n_joints
        width = len(rows[0]) if rows else 0
        if len(rows) < 2 or width not in (n + 5, 2 * n + 5) or any(len(r) != width for r in rows):
            raise MeasurementError(f"{path}: a plan for {robot.name} has {2 * n + 5} columns per row (commands, "
                                   f"predictions and sample inputs; {n + 5} in plans of older versions)")
        cases = tuple(dict.fromkeys(r[0] for r in rows[1:]))
        try:
            vals = np.array([[float(x) for x in r[2:]] for r in rows[1:]])
        except ValueError as exc:
            raise MeasurementError(f"{path}: {exc}") from None
        per = len(rows[1:]) // len(cases)
        if per * len(cases) != len(rows) - 1:
            raise MeasurementError(f"{path}: every case needs the same number of samples")
        cmds = (vals[:, :n] * qs).reshape(len(cases), per, n)
        inputs = (vals[:per, n + 3:] * qs) if width == 2 * n + 5 else None  # the same for every case
        if inputs is not None and not (vals[:, n + 3:].reshape(len(cases), per, n) == vals[:per, n + 3:]).all():
            raise MeasurementError(f"{path}: the sample inputs differ between cases; write the plan again with -o")
        return cls(cases, inputs, (vals[:, n:n + 3] * lf).reshape(len(cases), per, 3), cmds, _units(robot, cases))


@dataclass(frozen=True, eq=False)
class Verification:
    """Measured positions against an error model's predictions: a case passes when no axis deviates by more
    than the tolerance.

    Parameters
    ----------
    cases : tuple of str
        The C parameters of the plan.
    deviations : ndarray, shape (C, N, 3)
        Measured minus predicted positions, m.
    tolerance : float, optional
        The largest deviation per axis of a case that passes, m (default 50e-6).
    units : tuple of str, optional
        The unit error of each case as the table names it ("mm", "mrad", "‰"; default: not named).

    See Also
    --------
    VerificationPlan.compare : Makes it.

    Examples
    --------
    Positions measured with 5 µm of noise at the commands of a plan, judged against 50 µm, then 1 µm:

    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import verification_plan
    >>> robot = kincal.load_robot("puu3")
    >>> plan = verification_plan(robot, robot.sample_joints(4, seed=1), names=["L1", "L2"])
    >>> noise = np.random.default_rng(0).normal(0.0, 5e-6, (8, 3))
    >>> measured = robot.forward(plan.commands.reshape(-1, 3)) + noise
    >>> result = plan.compare(measured)
    >>> result.passed.tolist(), result.to_dict()["pass"]
    ([True, True], True)
    >>> print(result.table())
    case           axis     max mm   mean mm  verdict (tolerance 0.05 mm)
    ΔL1 = 1 mm     x        0.0065    0.0035  PASS
                   y        0.0047    0.0028
                   z        0.0035    0.0022
    ΔL2 = 1 mm     x        0.0116    0.0060  PASS
                   y        0.0052    0.0031
                   z        0.0062    0.0026
    error model confirmed: 2 of 2 cases within 0.05 mm
    >>> print(plan.compare(measured, tolerance=1e-6).table().splitlines()[-2])
    error model NOT confirmed: 0 of 2 cases within 0.001 mm
    """

    cases: tuple[str, ...]
    deviations: np.ndarray
    tolerance: float = 50e-6
    units: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        freeze_arrays(self)  # the arrays it hands out: what it prints cannot drift from what it computed

    @property
    def passed(self) -> np.ndarray:
        """Which cases pass, (C,) bool."""
        return np.abs(self.deviations).max(axis=(1, 2)) <= self.tolerance

    def to_dict(self) -> dict:
        """The verdict and, per case, the largest and mean deviation per axis (m) as plain JSON values."""
        a = np.abs(self.deviations)
        return {"units": "m", "tolerance": self.tolerance, "pass": bool(self.passed.all()),
                "cases": {c: {"max": a[k].max(axis=0).tolist(), "mean": a[k].mean(axis=0).tolist(),
                              "pass": bool(self.passed[k])} for k, c in enumerate(self.cases)}}

    def table(self) -> str:
        """Table 5: per case and axis, maximum and mean deviation (mm), and the verdict."""
        units = [*self.units, *[""] * len(self.cases)]
        labels = [f"Δ{c} = 1" + (f" {u}" if u else "") for c, u in zip(self.cases, units)]
        w = max([14, *map(len, labels)])
        out = [f"{'case':<{w}} {'axis':<5} {'max mm':>9} {'mean mm':>9}  verdict (tolerance {self.tolerance * MM:g} mm)"]
        a = np.abs(self.deviations) * MM
        tol = self.tolerance * MM
        for k, label in enumerate(labels):
            d = 4 if self.passed[k] or round(float(a[k].max()), 4) > tol else 6  # a FAIL never reads as the tolerance
            for j, axis in enumerate("xyz"):
                verdict = ("PASS" if self.passed[k] else "FAIL") if j == 0 else ""
                out.append(f"{label if j == 0 else '':<{w}} {axis:<5} {a[k, :, j].max():9.{d}f} "
                           f"{a[k, :, j].mean():9.{d}f}  {verdict}")
        out.append(f"error model {'confirmed' if self.passed.all() else 'NOT confirmed'}: "
                   f"{int(self.passed.sum())} of {len(self.cases)} cases within {self.tolerance * MM:g} mm")
        if not self.passed.all():
            out.append(WHY_TOLERANCE)
        return "\n".join(out)


def verification_plan(robot: Robot, q_samples: np.ndarray, names: Sequence[str] | None = None) -> VerificationPlan:
    """Plan the commands that realise, on the actual robot, the error model's prediction for a unit error.

    For each parameter error Δs (one unit: 1 mm or 1 mrad) the error model predicts the position
    p + Δp = FK(q′; s′ + Δs) at each sample input q′; the actual model's inverse maps it onto the commands
    q″ = IK(p + Δp; s′) (module docstring).

    Parameters
    ----------
    robot : Robot
        The identified ("actual") model s′.
    q_samples : ndarray, shape (N, n)
        The sample inputs q′, rad (m for a prismatic joint).
    names : sequence of str, optional
        The parameters to test (default: all but the base frame's and a transmission's own).

    Returns
    -------
    VerificationPlan
        The cases, the sample inputs, the predicted positions (C, N, 3) m and the commands (C, N, n).

    Raises
    ------
    ModelError
        When a name is not a parameter of the robot or the sample inputs do not fit it, or a case's command for
        a sample is refused (:func:`compensate`: beyond a joint limit, off the branch, not reached).

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import verification_plan
    >>> robot = kincal.load_robot("puu3")
    >>> q = robot.sample_joints(4, seed=1)
    >>> plan = verification_plan(robot, q)
    >>> plan.cases
    ('r', 'R', 'L1', 'L2', 'L3')
    >>> plan.predicted.shape, plan.commands.shape
    ((5, 4, 3), (5, 4, 3))

    At its commands the actual model reaches the predicted positions:

    >>> bool(np.abs(robot.forward(plan.commands[2]) - plan.predicted[2]).max() < 1e-9)
    True
    """
    _positions_only(robot)
    q = robot.check_q(q_samples)
    names = _cases(robot, names)
    predicted, commands = [], []
    for name in names:
        i = robot.params.index(name)
        v = robot.params.values.copy()
        v[i] += UNIT[robot.params.kinds[i]]
        target = robot.forward(q, v)
        comp = compensate(robot, target, q)
        if not comp.ok.all():  # a command no robot should be sent: beyond a limit, off the branch, unreachable
            raise ModelError(f"verification case {name}: the commands of sample(s) "
                             f"{', '.join(str(int(r)) for r in comp.rows[~comp.ok][:10])} were refused "
                             f"({comp.problems[0]}); choose sample inputs away from the joint limits and "
                             f"singularities")
        predicted.append(target)
        commands.append(comp.q)
    return VerificationPlan(names, q, np.array(predicted), np.array(commands), _units(robot, names))


def _positions_only(robot: Robot) -> None:
    """ModelError for a robot whose joints its platform's whole pose sets: the cases are positions."""
    if robot.has_pose_inverse:
        raise ModelError(f"robot '{robot.name}' ({robot.structure}): its joints are set by the platform's whole pose, "
                         f"and the error-model verification's cases are positions (the 3-PUU paper of 2024's, for a "
                         f"translational robot): it has no cases of 6-D poses; judge this robot with calibrate --test "
                         f"or evaluate on poses it did not see")


def _units(robot: Robot, cases: Sequence[str]) -> tuple[str, ...]:
    """Each case's unit error as a table names it: "mm", "mrad" or "‰" ('' for a name the robot does not have)."""
    shown = {"length": "mm", "angle": "mrad", "ratio": "‰"}
    names = robot.params.names
    return tuple(shown.get(robot.params.kinds[names.index(c)], "") if c in names else "" for c in cases)


def _cases(robot: Robot, names: Sequence[str] | None) -> tuple[str, ...]:
    """The parameters to test, checked to be the robot's (default: the structure's, all but the base frame's and a
    transmission's own: 1 mm on a 10 mm screw lead is a 10 % error that moves the tool by centimetres)."""
    skip = set(robot.base_params()) | (set(robot.drive.names) if isinstance(robot, TransmissionRobot) else set())
    names = tuple(names) if names is not None else tuple(n for n in robot.params.names if n not in skip)
    robot.params.indices(names)
    return names


def commandable(robot: Robot, q_samples: np.ndarray, names: Sequence[str] | None = None) -> np.ndarray:
    """Which sample inputs q′ (N, n) have a command the robot may be sent for every case (unit error) of
    :func:`verification_plan`: none beyond a joint limit, off the branch or unreachable.

    Parameters
    ----------
    robot : Robot
        The identified ("actual") model s′.
    q_samples : ndarray, shape (N, n)
        Candidate sample inputs, rad (m for a prismatic joint).
    names : sequence of str, optional
        The parameters to test (default: all but the base frame's and a transmission's own).

    Returns
    -------
    ndarray of bool, shape (N,)
        True where every case's command is accepted.

    Examples
    --------
    >>> import kincal
    >>> from kincal.compensate import commandable
    >>> robot = kincal.load_robot("puu3")
    >>> commandable(robot, robot.sample_joints(4, seed=1)).tolist()
    [True, True, True, True]
    """
    _positions_only(robot)
    q = robot.check_q(q_samples)
    ok = np.ones(len(q), bool)
    for name in _cases(robot, names):
        v = robot.params.values.copy()
        v[robot.params.index(name)] += UNIT[robot.params.kinds[robot.params.index(name)]]
        ok &= compensate(robot, robot.forward(q, v), q).ok
    return ok

