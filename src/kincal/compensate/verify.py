"""Error-model verification (seed 2, §3.5, Table 5).

With an identified ("actual") model s′ and sample joint inputs q′: for each parameter error Δs (unit
error) the error model predicts the position p + Δp = FK(q′; s′ + Δs). The inverse of the actual
model maps that position onto commands q″ = IK(p + Δp; s′). Commanding q″ on the robot and measuring
p″ tests the error model: p″ should equal p + Δp up to the measurement noise.
"""
from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .._atomic import write_text_atomic
from ..analysis.sensitivity import UNIT
from ..models.robot import Robot
from . import compensate


@dataclass(frozen=True, eq=False)
class VerificationPlan:
    """For each case (parameter) and sample: the predicted position (C, N, 3) and commands (C, N, n)."""

    cases: tuple[str, ...]
    q_samples: np.ndarray
    predicted: np.ndarray
    commands: np.ndarray

    def compare(self, measured: np.ndarray) -> "Verification":
        """Deviations of the measured positions (C, N, 3) from the predictions."""
        dev = np.asarray(measured, float).reshape(self.predicted.shape) - self.predicted
        return Verification(self.cases, dev)

    def write_csv(self, path: str | os.PathLike, joint_names: Sequence[str]) -> None:
        """The commands to run, case by case (SI units), with the predicted positions; written
        atomically. Columns: case, sample, one per joint, x_pred, y_pred, z_pred."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["case", "sample", *joint_names, "x_pred", "y_pred", "z_pred"])
        for case, cmds, pred in zip(self.cases, self.commands, self.predicted):
            for k, (qc, pc) in enumerate(zip(cmds, pred)):
                w.writerow([case, k + 1, *(repr(float(v)) for v in qc), *(repr(float(v)) for v in pc)])
        write_text_atomic(path, buf.getvalue())


@dataclass(frozen=True, eq=False)
class Verification:
    cases: tuple[str, ...]
    deviations: np.ndarray  # (C, N, 3) measured − predicted, m

    def to_dict(self) -> dict:
        a = np.abs(self.deviations)
        return {c: {"max": a[k].max(axis=0).tolist(), "mean": a[k].mean(axis=0).tolist()}
                for k, c in enumerate(self.cases)}

    def table(self) -> str:
        """Table 5: per case and axis, maximum and mean deviation (mm)."""
        out = [f"{'case':<14} {'axis':<5} {'max mm':>9} {'mean mm':>9}"]
        a = np.abs(self.deviations) * 1e3
        for k, c in enumerate(self.cases):
            for j, axis in enumerate("xyz"):
                out.append(f"{('Δ' + c + ' = 1') if j == 0 else '':<14} {axis:<5} {a[k, :, j].max():9.4f} "
                           f"{a[k, :, j].mean():9.4f}")
        return "\n".join(out)


def verification_plan(model: Robot, q_samples: np.ndarray, params: Sequence[str] | None = None) -> VerificationPlan:
    """Commands that realise, on the actual robot, the error model's prediction for a unit error of
    each parameter (default: all but the base frame) at the sample inputs (N, n)."""
    q = model.check_q(q_samples)
    names = tuple(params) if params is not None else tuple(
        n for n in model.params.names if n not in set(model.base_params()))
    predicted, commands = [], []
    for name in names:
        i = model.params.index(name)
        v = model.params.values.copy()
        v[i] += UNIT[model.params.kinds[i]]
        target = model.forward(q, v)
        predicted.append(target)
        commands.append(compensate(model, target, q).q)
    return VerificationPlan(names, q, np.array(predicted), np.array(commands))
