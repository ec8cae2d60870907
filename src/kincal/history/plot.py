"""The history plot: the parameters the history lists as the steps' largest differences (against the first
calibration, with their ±σ bands), the position error of every calibration, evaluation and check, and the
events, on one time axis. matplotlib is loaded when a plot is drawn."""
from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from .._atomic import write_text_atomic
from ..units import MM, SHOWN
from .changes import calibrations, changed_parameters
from .records import Record, parse_time

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from matplotlib.typing import RcKeyType

STYLE: dict[RcKeyType, Any] = {
    "font.size": 9, "axes.titlesize": 9, "axes.grid": True, "grid.alpha": 0.3, "font.family": "DejaVu Sans",
    "svg.hashsalt": "kincal", "svg.fonttype": "none"}
ERRORS = (  # (kind, figure, label, marker, filled): the series of the error panel
    ("calibration", "heldout_mean", "calibration, held-out data", "o", True),
    ("calibration", "training_mean", "calibration, training data", "s", False),
    ("evaluation", "heldout_mean", "evaluation", "^", True),
    ("check", "heldout_mean", "check", "D", True))
COLOUR = {"calibration": "#1f77b4", "evaluation": "#2ca02c", "check": "#9467bd", "event": "#d62728"}


def _grid(n: int) -> int:
    """Columns of parameter panels for ``n`` parameters."""
    return 1 if n <= 3 else 2 if n <= 10 else 3


def history_figure(records: Sequence[tuple[int, Record]], parameters: Sequence[str] | None = None) -> "Figure":
    """The history plot of one robot: its parameters, position errors and events on one time axis.

    A panel per parameter shows its value minus the first calibration's (mm, deg or %, as ``kincal history``
    lists the differences) with the ±σ band
    (no band where σ is unknown: the value was held); a panel of the mean position errors (mm) shows
    each calibration's training mean and held-out mean (where it had held-out data) as two series, each
    evaluation's and check's; events are dashed vertical lines, with their note on the error panel. matplotlib is
    loaded when the plot is drawn.

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order (:meth:`Store.records`).
    parameters : sequence of str, optional
        The parameters to show (each in some calibration); default: those the steps list as their largest
        differences (:func:`changed_parameters`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (not attached to pyplot); save it with :func:`save_history_figure`.

    Raises
    ------
    ValueError
        When a given parameter is in no calibration of the records.
    """
    import matplotlib
    from matplotlib.figure import Figure

    names = changed_parameters(records, parameters)
    cols = _grid(len(names))
    rows = -(-len(names) // cols)
    with matplotlib.rc_context(STYLE):
        fig = Figure(figsize=(max(7.0, 4.6 * cols + 1.0), 1.9 * rows + 3.0), layout="constrained")
        grid = fig.add_gridspec(rows + 1, cols, height_ratios=[1.0] * rows + [1.5])
        errors = fig.add_subplot(grid[rows, :])
        panels = [fig.add_subplot(grid[k // cols, k % cols], sharex=errors) for k in range(len(names))]
        for ax, name in zip(panels, names):
            _parameter_panel(ax, records, name)
        _error_panel(errors, records)
        for ax in [*panels, errors]:
            _events(ax, records, label=ax is errors)
            ax.margins(x=0.05)
            _dates(ax)
            ax.tick_params(labelbottom=True)  # each panel its dates (shared axes hide all but the last's)
        name = records[0][1].identity.name if records else ""
        fig.suptitle(f"history of {name}\neach parameter minus its first calibrated value (band ±1σ); position "
                     f"errors; events (dashed)", fontsize=10)
    return fig


def _parameter_panel(ax: Any, records: Sequence[tuple[int, Record]], name: str) -> None:
    """One parameter over the calibrations that have it: value − the first one's, its ±σ band (no band where σ
    is unknown: the value was held)."""
    cals = [r for _, r in calibrations(records) if name in r.parameters]
    kind = cals[0].kinds[name] if cals else "length"
    unit, factor = SHOWN[kind]  # the unit kincal history lists the differences in
    x = [parse_time(r.time) for r in cals]
    y = [(r.parameters[name] - cals[0].parameters[name]) * factor for r in cals]
    s = [(r.sigmas.get(name) or 0.0) * factor for r in cals]
    ax.fill_between(x, [a - b for a, b in zip(y, s)], [a + b for a, b in zip(y, s)], color=COLOUR["calibration"],
                    alpha=0.2, linewidth=0, label="±1σ")
    ax.plot(x, y, "o-", color=COLOUR["calibration"], ms=4, label=name)
    ax.axhline(0.0, color="#555555", linewidth=0.6)
    ax.set_title(name, loc="left")
    ax.set_ylabel(f"Δ ({unit})")


def _error_panel(ax: Any, records: Sequence[tuple[int, Record]]) -> None:
    """Each calibration's training mean error and, where it had held-out data, its held-out mean, as two series;
    each evaluation's and check's held-out mean; in mm. One quantity per series: a training mean never stands in
    a held-out series."""
    for kind, figure, label, marker, filled in ERRORS:
        chosen = [r for _, r in records if r.kind == kind and figure in r.figures]
        if chosen:
            colour = COLOUR[kind]
            ax.plot([parse_time(r.time) for r in chosen], [r.figures[figure] * MM for r in chosen], marker,
                    color=colour, mfc=colour if filled else "white", ms=6, linestyle="none", label=label)
    ax.set_ylabel("mean position error (mm)")
    ax.set_ylim(0.0, ax.get_ylim()[1] * 1.1)  # from zero, the highest point clear of the frame
    ax.set_title("position error", loc="left")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=8)


def _events(ax: Any, records: Sequence[tuple[int, Record]], label: bool) -> None:
    """Events as dashed vertical lines; on the error panel (``label``) with their note."""
    for _, r in records:
        if r.kind == "event":
            when = parse_time(r.time)
            ax.axvline(when, color=COLOUR["event"], linestyle="--", linewidth=1.0)
            if label:
                ax.annotate(r.note[:40], (when, 1.0), xycoords=("data", "axes fraction"), xytext=(3, -3),
                            textcoords="offset points", rotation=90, va="top", ha="left", fontsize=8,
                            color=COLOUR["event"])


def _dates(ax: Any) -> None:
    import matplotlib.dates as mdates

    locator = mdates.AutoDateLocator()
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))


def save_history_figure(fig: "Figure", path: str | Path) -> None:
    """Save a history plot as PNG or SVG by the file's extension, atomically (a temporary file, then a rename).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure (:func:`history_figure`).
    path : str or Path
        The file: .png (130 dpi) or .svg; its folder must exist.

    Raises
    ------
    ValueError
        When the extension is neither .png nor .svg, or the folder does not exist.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".png", ".svg"):
        raise ValueError(f"--plot {path}: give a .png or .svg file")
    if not path.parent.is_dir():
        raise ValueError(f"--plot {path}: the folder {path.parent} does not exist; create it or choose another path")
    import matplotlib

    buf = io.BytesIO()
    with matplotlib.rc_context(STYLE):
        fig.savefig(buf, format=ext[1:], dpi=130, metadata={"Date": None} if ext == ".svg" else None)
    # latin-1 maps each byte to one character and back: the text writer writes the image's bytes as they are
    write_text_atomic(path, buf.getvalue().decode("latin-1"), encoding="latin-1")
