"""Sensitivity analysis (the 3-PUU error-model verification paper, §3.4): the position error a unit error of
each parameter causes."""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..models.robot import Robot
from ..units import MM, MRAD, fine

UNIT = {"length": 1.0 / MM, "angle": 1.0 / MRAD, "ratio": 1e-3}  # one unit error: 1 mm, 1 mrad, 1 ‰ (SI)


@dataclass(frozen=True, eq=False)
class Sensitivity:
    """deltas (P, N, 3): position change (m) at each sample for a unit error of each parameter
    (1 mm or 1 mrad), from the exact model; ``linear`` the same from the Jacobian."""

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    units: tuple[float, ...]
    q: np.ndarray
    deltas: np.ndarray
    linear: np.ndarray

    def to_dict(self) -> dict:
        return {"names": list(self.names), "units": list(self.units), "q": self.q.tolist(),
                "deltas": self.deltas.tolist(), "mean_abs": self.mean_abs().tolist()}

    def mean_abs(self) -> np.ndarray:
        """(P, 3) mean |Δx|, |Δy|, |Δz| over the samples (m)."""
        return np.abs(self.deltas).mean(axis=1)

    def table(self) -> str:
        out = [f"{'parameter':<12} {'unit':>6} {'mean|dx| mm':>12} {'mean|dy| mm':>12} {'mean|dz| mm':>12} "
               f"{'max|dp| mm':>11}"]
        for n, kind, m, d in zip(self.names, self.kinds, self.mean_abs(), self.deltas):
            unit = fine(UNIT[kind], kind, "g")
            out.append(f"{n:<12} {unit:>6} {m[0] * MM:12.4f} {m[1] * MM:12.4f} {m[2] * MM:12.4f} "
                       f"{np.linalg.norm(d, axis=1).max() * MM:11.4f}")
        return "\n".join(out)

    def plot(self, path: str | os.PathLike) -> None:
        """Δx, Δy, Δz against the sample for each parameter (Figs. 8–9), as PNG or SVG by extension."""
        from matplotlib.figure import Figure

        P = len(self.names)
        cols = min(P, 3)
        rows = -(-P // cols)
        fig = Figure(figsize=(4.2 * cols, 3.0 * rows))
        axes = fig.subplots(rows, cols, squeeze=False)
        x = np.arange(1, self.q.shape[0] + 1)
        for ax in axes.flat[P:]:
            ax.axis("off")
        for k, ax in enumerate(axes.flat[:P]):
            for a, label in enumerate("xyz"):
                ax.plot(x, self.deltas[k, :, a] * MM, marker="o", ms=3, label=f"Δ{label}")
            ax.set(title=self.names[k], xlabel="sample", ylabel="mm")
            ax.grid(alpha=0.3)
        axes.flat[0].legend()
        fig.tight_layout()
        fig.savefig(path)


def sensitivity(robot: Robot, q: np.ndarray, names: Sequence[str] | None = None) -> Sensitivity:
    """Position changes at joint values q (N, n) for a unit error (1 mm, 1 mrad) of each parameter
    (default: all but the base frame)."""
    q = robot.check_q(q)
    names = tuple(names) if names is not None else tuple(
        n for n in robot.params.names if n not in set(robot.base_params()))
    idx = robot.params.indices(names)
    units = tuple(UNIT[robot.params.kinds[i]] for i in idx)
    p0, J = robot.forward_and_jacobian(q)
    step = np.eye(len(robot.params.values))  # a unit error of parameter i: u * step[i]
    deltas = [robot.forward(q, robot.params.values + u * step[i]) - p0 for i, u in zip(idx, units)]
    kinds = tuple(robot.params.kinds[i] for i in idx)
    return Sensitivity(names, kinds, units, q, np.array(deltas), np.moveaxis(J[:, :, idx] * np.array(units), 2, 0))
