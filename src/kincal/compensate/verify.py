"""Error-model verification (the 3-PUU error-model verification paper, §3.5, Table 5).

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
from pathlib import Path
from typing import Sequence

import numpy as np

from ..analysis.sensitivity import UNIT
from ..errors import MeasurementError
from ..io.measurements import write_csv
from ..units import MM, joint_factors, unit_factor
from ..models.robot import Robot
from .commands import compensate


@dataclass(frozen=True, eq=False)
class VerificationPlan:
    """For each case (parameter) and sample: the predicted position (C, N, 3) and commands (C, N, n),
    from the sample inputs q_samples (N, n) (None in a plan file written before kincal kept them)."""

    cases: tuple[str, ...]
    q_samples: np.ndarray | None
    predicted: np.ndarray
    commands: np.ndarray

    def compare(self, measured: np.ndarray, tolerance: float = 50e-6) -> "Verification":
        """Deviations of the measured positions (C, N, 3) from the predictions, judged against
        ``tolerance`` (m, per axis)."""
        dev = np.asarray(measured, float).reshape(self.predicted.shape) - self.predicted
        return Verification(self.cases, dev, tolerance)

    def write_csv(self, path: str | os.PathLike, robot: Robot, joint_cols: Sequence[str] | None = None,
                  length_unit: str = "m", angle_unit: str = "rad") -> None:
        """The commands to run, case by case, with the predicted positions, in the given units
        (atomically). A first comment line records the units; columns: case, sample, one per joint,
        x_pred, y_pred, z_pred, then the sample inputs the commands were made from (``input_<joint>``).
        :meth:`read_csv` reads it back."""
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
        """A plan written by :meth:`write_csv` (its units line says how to read it)."""
        lines = Path(path).read_text(encoding="utf-8-sig").splitlines()
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
        return cls(cases, inputs, (vals[:, n:n + 3] * lf).reshape(len(cases), per, 3), cmds)


@dataclass(frozen=True, eq=False)
class Verification:
    """Deviations (C, N, 3) of measured − predicted positions (m), judged against ``tolerance`` (m):
    a case passes when no axis deviates by more than the tolerance."""

    cases: tuple[str, ...]
    deviations: np.ndarray
    tolerance: float = 50e-6

    @property
    def passed(self) -> np.ndarray:
        return np.abs(self.deviations).max(axis=(1, 2)) <= self.tolerance

    def to_dict(self) -> dict:
        a = np.abs(self.deviations)
        return {"units": "m", "tolerance": self.tolerance, "pass": bool(self.passed.all()),
                "cases": {c: {"max": a[k].max(axis=0).tolist(), "mean": a[k].mean(axis=0).tolist(),
                              "pass": bool(self.passed[k])} for k, c in enumerate(self.cases)}}

    def table(self) -> str:
        """Table 5: per case and axis, maximum and mean deviation (mm), and the verdict."""
        out = [f"{'case':<14} {'axis':<5} {'max mm':>9} {'mean mm':>9}  verdict (tolerance {self.tolerance * MM:g} mm)"]
        a = np.abs(self.deviations) * MM
        for k, c in enumerate(self.cases):
            for j, axis in enumerate("xyz"):
                verdict = ("PASS" if self.passed[k] else "FAIL") if j == 0 else ""
                out.append(f"{('Δ' + c + ' = 1') if j == 0 else '':<14} {axis:<5} {a[k, :, j].max():9.4f} "
                           f"{a[k, :, j].mean():9.4f}  {verdict}")
        out.append(f"error model {'confirmed' if self.passed.all() else 'NOT confirmed'}: "
                   f"{int(self.passed.sum())} of {len(self.cases)} cases within {self.tolerance * MM:g} mm")
        return "\n".join(out)


def verification_plan(robot: Robot, q_samples: np.ndarray, names: Sequence[str] | None = None) -> VerificationPlan:
    """Commands that realise, on the actual robot (``robot``: the identified model), the error
    model's prediction for a unit error of each parameter (default: all but the base frame) at the
    sample inputs (N, n)."""
    q = robot.check_q(q_samples)
    names = tuple(names) if names is not None else tuple(
        n for n in robot.params.names if n not in set(robot.base_params()))
    robot.params.indices(names)
    predicted, commands = [], []
    for name in names:
        i = robot.params.index(name)
        v = robot.params.values.copy()
        v[i] += UNIT[robot.params.kinds[i]]
        target = robot.forward(q, v)
        predicted.append(target)
        commands.append(compensate(robot, target, q).q)
    return VerificationPlan(names, q, np.array(predicted), np.array(commands))
