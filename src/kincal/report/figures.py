"""The report's figures (matplotlib, no pyplot state), shared by ``kincal report`` and ``--plot``.

Every figure takes :class:`PoseSet` values: one data set's poses, with the errors before and after
calibration (m). SVG output is deterministic (fixed hash salt, no date, text as paths), so a report
has the same bytes for the same input.
"""
from __future__ import annotations

import io
import os
import re
import textwrap
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter, MaxNLocator

from .._frozen import freeze_arrays
from ..ties import order_with_ties
from ..units import MM, joint_shown

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

RC: dict[RcKeyType, Any] = {"svg.hashsalt": "kincal", "svg.fonttype": "none", "font.size": 9, "axes.titlesize": 10,
      "axes.grid": True, "grid.alpha": 0.3, "font.family": "DejaVu Sans"}
SVG_DPI = 110  # point clouds are embedded as images at this resolution (thousands of markers stay small)
COLOURS = {"training": "#1f77b4", "held-out": "#d62728", "before": "#9a9a9a"}


@dataclass(frozen=True, eq=False)
class PoseSet:
    """One data set: label ("training" / "held-out"), input rows (N,), joints q (N, n) SI, measured
    positions xyz (N, 3) m, errors before/after (N, 3) m (measured − model; ``before`` None when
    only one model is evaluated), outlier flags (N,)."""

    label: str
    rows: np.ndarray
    q: np.ndarray
    xyz: np.ndarray
    before: np.ndarray | None
    after: np.ndarray
    outliers: np.ndarray
    name: str = ""  # the session (file) of a held-out set
    registration: str = ""  # how the models' measurement frame was set for these data
    colour: str = ""  # default: by label
    key: str = ""  # the set's key in the report's numbers (default: the label)
    rot_before: np.ndarray | None = None  # 6-D data: the rotation error per sample (N,) rad, before calibration
    rot_after: np.ndarray | None = None  # and after (None: no rotation measured)

    def __post_init__(self) -> None:
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @property
    def after_norm(self) -> np.ndarray:
        return np.linalg.norm(self.after, axis=1)

    @property
    def title(self) -> str:
        return f"{self.label} {self.name}" if self.name else self.label

    @property
    def color(self) -> str:
        return self.colour or COLOURS[self.label]


SESSION_COLOURS = ("#d62728", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")  # held-out sessions in turn
TRAINING_COLOURS = ("#1f77b4", "#2ca02c", "#bcbd22", "#393b79", "#637939", "#843c39")  # training sessions in turn


def colour(label: str, k: int) -> str:
    """The colour of the ``k``-th (0-based) set labelled ``label`` ("training" or "held-out"): each session its own,
    training sessions in blues and greens, held-out ones in reds and oranges, none the grey of "before"."""
    palette = TRAINING_COLOURS if label == "training" else SESSION_COLOURS
    return palette[k % len(palette)]


_styled = matplotlib.rc_context(RC)  # a decorator: figures built and saved in the report's style, whatever rcParams


@_styled
def svg(fig: Figure) -> str:
    """The figure as an inline SVG string (no XML header, deterministic)."""
    buf = io.StringIO()
    fig.savefig(buf, format="svg", dpi=SVG_DPI, metadata={"Date": None, "Creator": None})
    text = re.sub(r"\s*<metadata>.*?</metadata>", "", buf.getvalue(), flags=re.S)  # creator/format RDF: noise in a page
    return text[text.index("<svg"):]


@_styled
def save(fig: Figure, path: str | os.PathLike) -> None:
    """Save a figure as PNG or SVG by the file's extension, in the report's style.

    PNG at 130 dpi; SVG without a date, so the same figure gives the same bytes.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, e.g. one of :func:`kincal.report.figure_set`'s.
    path : str or os.PathLike
        The file (.png or .svg; another extension is left to matplotlib).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from matplotlib.figure import Figure
    >>> from kincal.report import save_figure
    >>> fig = Figure(figsize=(3.0, 2.0))
    >>> _ = fig.add_subplot().plot([0.0, 1.0], [0.0, 0.2])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     save_figure(fig, Path(folder) / "errors.svg")
    ...     text = (Path(folder) / "errors.svg").read_text()
    >>> "<svg" in text, "dc:date" in text
    (True, False)
    """
    fig.savefig(path, dpi=130, metadata={"Date": None} if str(path).lower().endswith(".svg") else None)


def _figure(width: float, height: float) -> Figure:
    return Figure(figsize=(width, height), layout="constrained")


def _axes(width: float, height: float, **kw) -> tuple[Figure, Any]:
    """A figure with one axes (``kw``: for ``add_subplot``, e.g. a projection)."""
    fig = _figure(width, height)
    return fig, fig.add_subplot(**kw)


def legend_below(fig: Figure, handles: list | None = None, labels: list | None = None, ncols: int = 3) -> None:
    """The figure's one legend, below its axes: outside every axes, so it covers no plotted point or bar.

    ``handles`` and ``labels`` default to the labelled artists of all its axes, a label once (the first
    artist that has it). The figure must use the constrained layout, which makes room for it.
    """
    if handles is None or labels is None:
        found: dict[str, Any] = {}
        for ax in fig.axes:
            for handle, label in zip(*ax.get_legend_handles_labels()):
                found.setdefault(label, handle)
        handles, labels = list(found.values()), list(found)
    if labels:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(ncols, len(labels)), fontsize=8,
                   frameon=False)


def error_of(sets: list[PoseSet], model: str = "the model") -> str:
    """What the sets' ``after`` errors are, for the figures' titles: "after calibration" when some set has the
    nominal model's errors beside them (a calibration), else "of <model>" (one model evaluated: nothing says it
    was calibrated)."""
    return "after calibration" if any(s.before is not None for s in sets) else f"of {model}"


class _PlainLog(LogFormatter):
    """A log axis's labels as plain numbers (0.06, 1), on the ticks matplotlib's log formatter labels."""

    def _num_to_string(self, x, vmin, vmax):
        return f"{x:g}"


@_styled
def per_pose(sets: list[PoseSet], what: str = "after calibration",
             before: str = "frame and target point registered", rotation: bool = False) -> Figure:
    """Error norm of every pose in file order (log scale: mm to µm): before and after calibration (``before``: how
    the nominal model was registered), or of the one model evaluated (``what``: :func:`error_of`); with
    ``rotation`` the rotation error (mrad) of the sets that measured one."""
    sets = [s for s in sets if s.rot_after is not None] if rotation else sets
    fig = _figure(9.0, 2.6 * len(sets))
    quantity, unit = ("rotation error", "mrad") if rotation else ("position error", "mm")
    for k, s in enumerate(sets):
        ax = fig.add_subplot(len(sets), 1, k + 1)
        x = np.arange(1, len(s.rows) + 1)
        ref = s.rot_before if rotation else None if s.before is None else np.linalg.norm(s.before, axis=1)
        err = s.rot_after if rotation and s.rot_after is not None else s.after_norm
        if ref is not None:
            ax.semilogy(x, ref * MM, ".", ms=3, color=COLOURS["before"],  # (mm per m, mrad per rad: 1000)
                        label=f"before (nominal model, {before})", rasterized=True)
        ax.semilogy(x, err * MM, ".", ms=3, color=s.color, rasterized=True,
                    label=f"{s.title}: {what}" if ref is not None else None)
        circle(ax, x[s.outliers], err[s.outliers] * MM)
        error = quantity if ref is not None else f"{quantity} {what}"
        ax.set(title=f"{s.title} poses ({len(x)}): {error} per pose", xlabel="pose (file order)",
               ylabel=f"error ({unit})")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True, steps=[1, 2, 5, 10]))  # poses are counted
        ax.yaxis.set_major_formatter(_PlainLog())  # mm as numbers (0.6, not 6×10⁻¹)
        ax.yaxis.set_minor_formatter(_PlainLog(labelOnlyBase=False, minor_thresholds=(2, 0.4)))
    legend_below(fig)
    return fig


@_styled
def histogram(sets: list[PoseSet], what: str = "after calibration") -> Figure:
    """The distribution of the position error (``what``: :func:`error_of`), a set's share of poses per bin."""
    fig, ax = _axes(4.6, 3.0)
    top = max(float(s.after_norm.max()) for s in sets) * MM
    bins = np.linspace(0.0, top * 1.02 if top > 0 else 1.0, 31)
    for s in sets:
        ax.hist(s.after_norm * MM, bins=bins.tolist(), alpha=0.6, color=s.color, label=s.title,
                weights=np.full(len(s.rows), 100.0 / len(s.rows)))
    ax.set(title=f"distribution of the error {what}", xlabel="position error (mm)", ylabel="poses (%)")
    legend_below(fig)
    return fig


@_styled
def per_axis(sets: list[PoseSet], what: str = "after calibration") -> Figure:
    """Box plots of the error per axis (``what``: :func:`error_of`): one box per set (its colour, named in the
    legend) beside each other at x, y and z."""
    fig, ax = _axes(4.6, 3.0)
    k = len(sets)
    data = [s.after[:, a] * MM for a in range(3) for s in sets]
    where = [a * (k + 1) + j + 1 for a in range(3) for j in range(k)]
    parts = ax.boxplot(data, positions=where, patch_artist=True, widths=0.6, flierprops={"markersize": 2})
    for patch, s in zip(parts["boxes"], [s for _ in range(3) for s in sets]):
        patch.set(facecolor=s.color, alpha=0.5)
    ax.set_xticks([a * (k + 1) + (k + 1) / 2 for a in range(3)], ["x", "y", "z"])
    if k > 1:
        legend_below(fig, parts["boxes"][:k], [s.title for s in sets])
    ax.set(title=f"error per axis {what}", ylabel="measured − model (mm)")
    return fig


@_styled
def vs_joints(sets: list[PoseSet], joint_names, units, what: str = "after calibration") -> Figure:
    """The error (``what``: :func:`error_of`) against each joint value, in the joint's ``units`` ((unit, factor
    from SI) per joint, :func:`kincal.units.joint_shown`: deg, mm, rev for a leg's motor): gravity sag, gear and
    encoder errors show here."""
    n = len(joint_names)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig = _figure(3.2 * cols, 2.4 * rows)
    for j in range(n):
        ax = fig.add_subplot(rows, cols, j + 1)
        unit, scale = units[j]
        for s in sets:
            ax.plot(s.q[:, j] * scale, s.after_norm * MM, ".", ms=3, color=s.color, label=s.title,
                    rasterized=True)
            circle(ax, s.q[s.outliers, j] * scale, s.after_norm[s.outliers] * MM)
        ax.set(xlabel=f"{joint_names[j]} ({unit})", ylabel="error (mm)")
    legend_below(fig)
    fig.suptitle(f"error {what} against each joint")
    return fig


@_styled
def workspace(sets: list[PoseSet], frame: str = "the training data's frame", what: str = "after calibration") -> Figure:
    """Measured positions in three projections (in ``frame``, for the title), coloured by the error (``what``:
    :func:`error_of`); outliers circled, the ``NAMED`` largest named by input row inside the axes, and all
    listed under the figure. The title keys the markers of training and held-out data when both are shown."""
    fig = _figure(11.0, 3.6)
    all_err = np.concatenate([s.after_norm for s in sets]) * MM
    vmax = float(np.percentile(all_err, 99)) if all_err.size else 1.0
    where, names = _outliers(sets)
    everything = np.concatenate([s.xyz for s in sets]) * MM
    for k, (a, b) in enumerate(((0, 1), (0, 2), (1, 2))):
        ax = fig.add_subplot(1, 3, k + 1)
        for s in sets:
            sc = ax.scatter(s.xyz[:, a] * MM, s.xyz[:, b] * MM, c=s.after_norm * MM, s=8, cmap="viridis",
                            vmin=0.0, vmax=vmax, marker="o" if s.label == "training" else "^", rasterized=True)
        circle(ax, where[:, a], where[:, b])
        _name_outliers(ax, everything[:, [a, b]], where[:NAMED][:, [a, b]], names[:NAMED])
        ax.set(xlabel=f"{'xyz'[a]} (mm)", ylabel=f"{'xyz'[b]} (mm)", aspect="equal", adjustable="datalim")
    fig.colorbar(sc, ax=fig.axes, label=f"error {what} (mm)", shrink=0.9)
    kinds = {s.label == "training" for s in sets}
    key = ["o training, ^ held-out"] if len(kinds) == 2 else []
    key += [f"red circles: {len(names)} outlier{'s' if len(names) > 1 else ''}"] if names else []
    fig.suptitle(f"workspace ({frame})" + (": " + "; ".join(key) if key else ""))
    if len(names) > NAMED:
        listed = ", ".join(names[:LISTED]) + (f" and {len(names) - LISTED} more" if len(names) > LISTED else "")
        fig.supxlabel(textwrap.fill(f"outliers by error, largest first (the first {NAMED} named): {listed}", 190),
                      fontsize=8)
    _merge_names(fig)  # once laid out with the caption
    return fig


def circle(ax: Any, x: np.ndarray, y: np.ndarray) -> None:
    """Circle the outliers at ``x``, ``y`` (K,) in ``ax`` (red rings, vector: one ``<use>`` each in the SVG's group
    "outliers"), as every error figure marks them; nothing for none."""
    if len(x):
        ax.scatter(x, y, s=80, facecolors="none", edgecolors="red", linewidths=1.2, label="outlier (red circle)",
                   gid="outliers", zorder=3)


NAMED = 3  # outliers the workspace names by row beside their circle (the largest errors)
LISTED = 60  # outliers its caption lists


def _outliers(sets: list[PoseSet]) -> tuple[np.ndarray, list[str]]:
    """The outliers of all sets, largest error first (ties: in the sets' order): positions (K, 3) mm and names
    ("row 86"; a held-out set's with its file or label)."""
    where = np.concatenate([s.xyz[s.outliers] for s in sets]) * MM
    error = np.concatenate([s.after_norm[s.outliers] for s in sets])
    names = [f"row {r}" if s.label == "training" else f"{s.name or s.label} row {r}" for s in sets
             for r in s.rows[s.outliers]]
    order = order_with_ties(error) if len(error) else []
    return where[order].reshape(-1, 3), [names[i] for i in order]


def _name_outliers(ax: Any, points: np.ndarray, where: np.ndarray, names: list[str]) -> None:
    """Name outliers at ``where`` (K, 2) in a panel of ``points`` (N, 2), each name written from its point towards
    the points' middle, so that it stays inside the axes; :func:`_merge_names` joins names that overlap."""
    middle = (points.min(axis=0) + points.max(axis=0)) / 2.0 if len(points) else np.zeros(2)
    for p, name in zip(where, names):
        right, up = p[0] <= middle[0], p[1] <= middle[1]
        ax.annotate(name, tuple(p), xytext=(5 if right else -5, 5 if up else -5), textcoords="offset points",
                    ha="left" if right else "right", va="bottom" if up else "top", color="red", fontsize=8,
                    gid="outlier", bbox={"boxstyle": "square,pad=0.1", "facecolor": "white", "alpha": 0.7,
                                         "edgecolor": "none"})  # legible over the points


def _merge_names(fig: Figure) -> None:
    """Join outlier names that overlap as drawn into the first one's ("rows 86, 91"), in each axes: the layout
    is drawn once (text sizes do not depend on the resolution it is saved at)."""
    fig.draw_without_rendering()
    for ax in fig.axes:
        kept: list[tuple[Any, list[str]]] = []
        for label in [t for t in ax.texts if t.get_gid() == "outlier"]:
            box = label.get_window_extent()
            home = next((k for k in kept if k[0].get_window_extent().overlaps(box)), None)
            if home is None:
                kept.append((label, [label.get_text()]))
                continue
            home[1].append(label.get_text())
            label.remove()
            rows = all(n.startswith("row ") for n in home[1])
            home[0].set_text("rows " + ", ".join(n[4:] for n in home[1]) if rows else "; ".join(home[1]))


@_styled
def correlation(names, corr: np.ndarray) -> Figure:
    k = len(names)
    size = max(4.0, min(10.0, 0.28 * k + 2.0))
    fig, ax = _axes(size + 1.0, size)
    im = ax.imshow(corr, vmin=-1.0, vmax=1.0, cmap="RdBu_r")
    ax.set_xticks(range(k), names, rotation=90, fontsize=7)
    ax.set_yticks(range(k), names, fontsize=7)
    ax.grid(False)
    fig.colorbar(im, ax=ax, label="correlation", shrink=0.8)
    ax.set_title("correlation of the estimated parameters")
    return fig


def pose_figures(sets: list[PoseSet], robot, frame: str = "the training data's frame",
                 before: str = "frame and target point registered") -> dict:
    """The figures of pose sets by name: errors per pose (and rotation errors per pose, "rotation", of 6-D data),
    distribution, per axis, against the
    joints of ``robot``, in the workspace (``frame``, for its title); ``before``: how the nominal model was
    registered to the data, in the CLI's words."""
    what = error_of(sets, robot.name)
    rotation = {"rotation": per_pose(sets, what, before, rotation=True)} if any(
        s.rot_after is not None for s in sets) else {}
    return {"per_pose": per_pose(sets, what, before), **rotation, "histogram": histogram(sets, what), "per_axis": per_axis(sets, what),
            "vs_joints": vs_joints(sets, robot.joint_names, joint_shown(robot.joint_types, robot.periodic), what),
            "workspace": workspace(sets, frame, what)}
