"""Sensitivity analysis (the 3-PUU paper of 2024,
"Error analysis model of parallel robot based on parameters identification", §3.4): the position error a unit
error of each parameter causes."""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from .._frozen import freeze_arrays
from ..models.robot import Robot
from ..units import FINE, MM, MRAD, fine

if TYPE_CHECKING:
    from matplotlib.figure import Figure

UNIT = {"length": 1.0 / MM, "angle": 1.0 / MRAD, "ratio": 1e-3}  # one unit error: 1 mm, 1 mrad, 1 ‰ (SI)
STYLES = ({"marker": "o", "ms": 5, "linestyle": "-", "mfc": "none"},  # Δx, Δy, Δz: told apart where they coincide
          {"marker": "s", "ms": 3, "linestyle": "--"}, {"marker": "^", "ms": 3, "linestyle": ":"})


@dataclass(frozen=True, eq=False)
class Sensitivity:
    """Position changes a unit error of each parameter causes at each sample.

    Built by :func:`sensitivity`; a unit error is 1 mm for a length, 1 mrad for an angle and 1 ‰ for a
    ratio (:data:`UNIT`).

    Parameters
    ----------
    names : tuple of str
        The P parameters, in the order of the first axis of ``deltas``.
    kinds : tuple of str
        ``"length"``, ``"angle"`` or ``"ratio"`` per parameter.
    units : tuple of float
        The unit error applied per parameter, SI (1e-3 m, 1e-3 rad or 1e-3).
    q : ndarray, shape (N, n)
        Joint values of the samples, rad (m for a prismatic joint).
    deltas : ndarray, shape (P, N, 3)
        Position change at each sample for a unit error of each parameter, m, from the exact model.
    linear : ndarray, shape (P, N, 3)
        The same from the parameter Jacobian (first order), m.

    Examples
    --------
    >>> import kincal
    >>> from kincal.analysis import sensitivity
    >>> robot = kincal.load_robot("ur5")
    >>> sens = sensitivity(robot, robot.sample_joints(5, seed=2), names=["j1.d", "j2.a", "j2.theta"])
    >>> print(sens.table())
    parameter      unit  mean|dx| mm  mean|dy| mm  mean|dz| mm  max|dp| mm
    j1.d           1 mm       0.0000       0.0000       1.0000      1.0000
    j2.a           1 mm       0.4468       0.4368       0.7169      1.0000
    j2.theta     1 mrad       0.2656       0.3252       0.2893      0.6937
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    units: tuple[float, ...]
    q: np.ndarray
    deltas: np.ndarray
    linear: np.ndarray

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    def to_dict(self) -> dict:
        return {"names": list(self.names), "units": list(self.units), "q": self.q.tolist(),
                "deltas": self.deltas.tolist(), "mean_abs": self.mean_abs().tolist()}

    def mean_abs(self) -> np.ndarray:
        """(P, 3) mean abs(Δx), abs(Δy), abs(Δz) over the samples (m)."""
        return np.abs(self.deltas).mean(axis=1)

    def table(self) -> str:
        out = [f"{'parameter':<12} {'unit':>6} {'mean|dx| mm':>12} {'mean|dy| mm':>12} {'mean|dz| mm':>12} "
               f"{'max|dp| mm':>11}"]
        for n, kind, m, d in zip(self.names, self.kinds, self.mean_abs(), self.deltas):
            unit = fine(UNIT[kind], kind, "g")
            out.append(f"{n:<12} {unit:>6} {m[0] * MM:12.4f} {m[1] * MM:12.4f} {m[2] * MM:12.4f} "
                       f"{np.linalg.norm(d, axis=1).max() * MM:11.4f}")
        return "\n".join(out)

    def figure(self) -> "Figure":
        """Δx, Δy, Δz against the sample for each parameter (Figs. 8–9).

        Each panel's axis is mm per unit error (mm per mm, mm per mrad, mm per ‰: :data:`UNIT`); each of x, y, z
        has its marker and line style, so equal curves stay visible (j1.d's Δx and Δy, both 0); one legend above
        the panels.

        Returns
        -------
        matplotlib.figure.Figure
            One panel per parameter (not attached to pyplot).

        Examples
        --------
        >>> import kincal
        >>> from kincal.analysis import sensitivity
        >>> robot = kincal.load_robot("ur5")
        >>> fig = sensitivity(robot, robot.sample_joints(5, seed=2), names=["j1.d", "j2.theta"]).figure()
        >>> [ax.get_ylabel() for ax in fig.axes[:2]]
        ['Δ (mm per mm)', 'Δ (mm per mrad)']
        """
        from matplotlib.figure import Figure

        P = len(self.names)
        cols = min(P, 3)
        rows = -(-P // cols)
        fig = Figure(figsize=(4.2 * cols, 3.0 * rows + 0.4), layout="constrained")
        axes = fig.subplots(rows, cols, squeeze=False)
        x = np.arange(1, self.q.shape[0] + 1)
        for ax in axes.flat[P:]:
            ax.axis("off")
        for k, ax in enumerate(axes.flat[:P]):
            for a, (label, style) in enumerate(zip("xyz", STYLES)):
                ax.plot(x, self.deltas[k, :, a] * MM, label=f"Δ{label}", **style)
            ax.set(title=self.names[k], xlabel="sample", ylabel=f"Δ (mm per {FINE[self.kinds[k]][0]})")
            ax.grid(alpha=0.3)
        fig.legend(*axes.flat[0].get_legend_handles_labels(), loc="outside upper center", ncols=3)
        return fig

    def plot(self, path: str | os.PathLike) -> None:
        """Save :meth:`figure` as PNG or SVG by the file's extension.

        Parameters
        ----------
        path : str or os.PathLike
            The file (.png or .svg).
        """
        self.figure().savefig(path)


def sensitivity(robot: Robot, q: np.ndarray, names: Sequence[str] | None = None) -> Sensitivity:
    """Position changes at joint values ``q`` for a unit error of each parameter.

    A unit error is 1 mm for a length, 1 mrad for an angle and 1 ‰ for a ratio (the 3-PUU error-model
    verification paper's sensitivity analysis, §3.4); each change is computed from the exact model and,
    to first order, from the Jacobian.

    Parameters
    ----------
    robot : Robot
        The robot model.
    q : ndarray, shape (N, n)
        Joint values of the samples, rad (m for a prismatic joint).
    names : sequence of str, optional
        The parameters (default: all but the base frame).

    Returns
    -------
    Sensitivity
        ``deltas`` and ``linear`` (P, N, 3) m, with the names, kinds and unit errors.

    Raises
    ------
    ModelError
        For an unknown parameter name or ``q`` of the wrong shape.

    Examples
    --------
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.analysis import sensitivity
    >>> robot = kincal.load_robot("ur5")
    >>> sens = sensitivity(robot, robot.sample_joints(5, seed=2), names=["j1.d", "j2.a", "j2.theta"])
    >>> sens.deltas.shape, sens.kinds
    ((3, 5, 3), ('length', 'length', 'angle'))
    >>> np.round(sens.mean_abs() * 1e3, 4)  # mm per unit error
    array([[0.    , 0.    , 1.    ],
           [0.4468, 0.4368, 0.7169],
           [0.2656, 0.3252, 0.2893]])
    >>> bool(np.abs(sens.deltas - sens.linear).max() < 1e-6)  # first order holds to below a micrometre
    True
    """
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
