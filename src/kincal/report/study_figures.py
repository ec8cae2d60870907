"""Figures of the papers' studies: Guo et al. 2024's Figs. 5-8, 10 and 12-13 from a
:class:`~kincal.studies.Guo2024Study`, and the 3-PUU paper of 2024's Fig. 7
("Error analysis model of parallel robot based on parameters identification")
(particle-swarm fitness) from a calibration's history."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.patches import Patch

from ..identify.positions import EXACT, e_statistics
from ..units import MM
from .figures import _axes, _figure, _styled, legend_below

DESIGN_COLOURS = {"random": "#9a9a9a", "full-parameter optimised": "#1f77b4",
                  "separated-parameter optimised": "#d62728", "before calibration": "#555555"}


@_styled
def ide_convergence(histories: dict) -> Figure:
    """Fig. 6: the comprehensive index of the best design per IDE generation, one panel per model
    (generation 0: the DETMAX design IDE starts from)."""
    runs = {k: h for k, h in histories.items() if len(h)}
    fig = _figure(6.0, 1.6 + 1.6 * len(runs))
    axes = fig.subplots(len(runs), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (name, h) in zip(axes, runs.items()):
        ax.plot(np.arange(len(h)), h, color=DESIGN_COLOURS.get(name))
        ax.set(ylabel="index", title=f"{name}: {h[0]:.4f} -> {h[-1]:.4f}")
    axes[-1].set_xlabel("IDE generation")
    fig.suptitle("DETMAX-IDE convergence (Fig. 6)")
    return fig


@_styled
def pose_count(curve: dict, m: int) -> Figure:
    """Fig. 7: the comprehensive index against the number of poses (separated model)."""
    fig, ax = _axes(6.0, 3.2)
    ax.plot(curve["m"], curve["values"], color=DESIGN_COLOURS["separated-parameter optimised"])
    ax.axvline(m, color="k", lw=0.8, ls="--")
    ax.annotate(f"{m} poses", (m, np.nanmin(curve["values"])), xytext=(4, 4), textcoords="offset points")
    ax.set(xlabel="number of poses", ylabel="comprehensive index", title="Index against the number of poses (Fig. 7)")
    return fig


def eta_range(values, clip: float = -100.0) -> tuple[float, float]:
    """The η axis (%) for ``values`` (NaN: not identifiable): from a little below the lowest (at most down to
    ``clip`` less a margin) to a little above the highest or 100 %, so that η of 97-100 % differ visibly.

    >>> eta_range([97.02, 99.5, 100.0])
    (96.57, 100.3)
    >>> eta_range([-250.0, 90.0])  # cut at -100 %: the cut bars are marked
    (-130.0, 120.0)
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    low = max(float(v.min()), clip) if v.size else 0.0
    high = max(float(v.max()), 100.0) if v.size else 100.0
    span = max(high - low, 1.0)
    return round(low - 0.15 * span, 2), round(high + 0.1 * span, 2)


@_styled
def eta_bars(eta: dict, names: list[str], stand_ins=(), clip: float = -100.0) -> Figure:
    """Fig. 8: identification accuracy η per parameter and design, the axis from the values (:func:`eta_range`:
    bars below ``clip`` are cut and marked; ``stand_ins``, kept parameters that carry dependent ones, are hatched:
    their η against their own error alone is not their accuracy)."""
    fig, ax = _axes(max(6.0, 0.38 * len(names)), 3.6)
    designs = list(eta)
    width = 0.8 / len(designs)
    x = np.arange(len(names))
    for k, d in enumerate(designs):
        v = np.array([eta[d].get(n, np.nan) for n in names])
        pos = x + (k - (len(designs) - 1) / 2) * width
        bars = ax.bar(pos, np.maximum(v, clip), width, label=d, color=DESIGN_COLOURS.get(d))
        for bar, n in zip(bars, names):
            if n in stand_ins:
                bar.set_hatch("///")
        for i in np.flatnonzero(v < clip):
            ax.annotate(f"{v[i]:.0f}", (pos[i], clip), fontsize=6, rotation=90, va="bottom", ha="center")
    ax.set_xticks(x, names, rotation=60, ha="right", fontsize=7)
    ax.set(ylabel="η (%)", ylim=eta_range([eta[d].get(n, np.nan) for d in designs for n in names], clip),
           title="Identification accuracy η per parameter (Fig. 8)\nhatched: stands for a combination; "
                 "no bar: not identifiable")
    legend_below(fig)
    return fig


@_styled
def validation_points(errors: dict) -> Figure:
    """Fig. 12: the error e (average of the three axis errors) at each validation point: before
    calibration (top) and after, per model (bottom)."""
    fig = _figure(6.4, 4.6)
    top, bottom = fig.subplots(2, 1, sharex=True)
    exact = []
    for name, err in errors.items():
        e = np.asarray(err).mean(axis=1) * MM
        if name != "before calibration" and np.max(np.abs(e)) < EXACT * MM:
            exact.append(name)  # round-off (no noise, exact model): named, not plotted as a ranking
            continue
        ax = top if name == "before calibration" else bottom
        ax.plot(np.arange(1, len(e) + 1), e, marker="o", ms=2.5, lw=0.8, label=name, color=DESIGN_COLOURS.get(name))
    if exact:
        bottom.text(0.5, 0.5, "every point < 1 nm (round-off, not shown):\n" + "\n".join(exact),
                    transform=bottom.transAxes, ha="center", va="center", fontsize=7)
    top.set(ylabel="e (mm)", title="Error at the validation points (Fig. 12): before calibration")
    bottom.set(xlabel="validation point", ylabel="e (mm)", title="after calibration")
    if len(exact) < len(errors) - 1:
        legend_below(fig, *bottom.get_legend_handles_labels())
    return fig


def _note(fig: Figure, text: str) -> None:
    """A note under the figure: the title of its legend below the axes (:func:`legend_below`), else its x label
    (the two would share the bottom margin and overlap)."""
    if fig.legends:
        fig.legends[0].set_title(text, prop=FontProperties(size=6))
    elif text:
        fig.supxlabel(text, fontsize=6)


@_styled
def validation_summary(errors: dict, note: str = "") -> Figure:
    """Fig. 13: max |e|, mean |e| and std e over the validation points, before calibration and per
    model after; values below 1 nm (no noise, exact model) are round-off, drawn as a note, not bars. ``note``:
    under the figure (the protocol), set before the top of the axes leaves room for the bars' labels."""
    fig, ax = _axes(6.4, 3.4)
    stats = e_statistics(errors)
    x = np.arange(3)
    shown: list[float] = []
    width = 0.8 / len(stats)
    for k, (name, row) in enumerate(stats.items()):
        pos = x + (k - (len(stats) - 1) / 2) * width
        v = np.array(row) * MM
        exact = np.array(row) < EXACT
        ax.bar(pos[~exact], v[~exact], width, label=name, color=DESIGN_COLOURS.get(name, "#999999"))
        shown.extend(v[~exact])
        for p, val, ex in zip(pos, v, exact):  # the table's numbers on the bars; round-off is named, not drawn
            ax.annotate("< 1 nm" if ex else f"{val:.3g}", (p, 0.02 if ex else val), fontsize=6, rotation=90,
                        va="bottom", ha="center", xycoords=ax.get_xaxis_transform() if ex else "data")
    ax.set(yscale="log", xlim=(-0.5, 2.5), ylim=(min(shown) / 4, max(shown) * 2.5))
    ax.set_xticks(x, ["max |e|", "mean |e|", "std e"])
    ax.set(ylabel="mm (log scale)", title="Validation on the 60-point grid, before and after calibration (Fig. 13)")
    legend_below(fig, [Patch(color=DESIGN_COLOURS.get(n, "#999999")) for n in stats], list(stats), ncols=2)
    _note(fig, note)
    _room_above(ax, [t for t in ax.texts if t.get_text() != "< 1 nm"])
    return fig


def _room_above(ax, labels: list) -> None:
    """Raise the top of a log axes until the labels written upwards from their data points (va "bottom") end
    below it: the labels' heights do not depend on the limits, so the top follows in closed form from them
    and the axes' height (as laid out) with one layout."""
    fig = ax.figure
    fig.draw_without_rendering()
    height = ax.get_window_extent().height
    low, high = (np.log10(v) for v in ax.get_ylim())
    need = high - low
    for label in labels:
        share = (label.get_window_extent().height + 5.0 * fig.dpi / 72.0) / height  # 5 pt clear of the frame
        need = max(need, (np.log10(label.xy[1]) - low) / (1.0 - share))
    ax.set_ylim(10.0 ** low, 10.0 ** (low + need))


@_styled
def gcn_against_poses(curve: dict) -> Figure:
    """Fig. 5: the GCN of the separated model's Jacobian against the number of measurement poses.

    The Jacobian is raw, in mm and rad (as the paper's Fig. 5), where the separation's tables (kincal
    tables S1, S2, …) give the GCN of scaled columns: the figure says so in its legend and axis label.
    """
    fig, ax = _axes(6.0, 3.2)
    ax.semilogy(curve["m"], curve["gcn"], marker="o", ms=2, lw=0.8, color="#1f77b4",
                label="raw Jacobian in mm and rad (columns not scaled,\nunlike the separation tables S1, S2, ...)")
    ax.set(xlabel="number of poses", ylabel="GCN (cond / m), mm and rad",
           title=f"GCN of the separated model ({len(curve['parameters'])} parameters) against the poses (Fig. 5)")
    legend_below(fig)
    return fig


@_styled
def design_positions(positions: dict) -> Figure:
    """Fig. 10: where the designs put the tool in the workspace (mm)."""
    fig, ax = _axes(6.4, 4.8, projection="3d")
    for name, p in positions.items():
        ax.scatter(*(np.asarray(p) * MM).T, s=10, label=name, color=DESIGN_COLOURS.get(name),
                   alpha=1.0 if "separated" in name else 0.45)
    ax.set(xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)", title="Tool positions of the designs (Fig. 10)")
    ax.legend(fontsize=7, loc="upper left")
    return fig


def guo2024_figures(study) -> dict:
    """The figures of Guo et al. 2024's study, by name.

    "ide-convergence" (Fig. 6), "pose-count" (Fig. 7), "eta" (Fig. 8: random and separated-parameter
    designs), "validation-points" (Fig. 12), "validation-summary" (Fig. 13), "gcn" (Fig. 5: raw Jacobian
    in mm and rad, not the scaled columns of the separation's tables) and "design-positions" (Fig. 10).
    The identification and validation figures (8, 12, 13) show the first repetition under the study's
    protocol (``study.protocol``).

    Parameters
    ----------
    study : Guo2024Study
        The study's results (:func:`kincal.studies.guo2024_study`).

    Returns
    -------
    dict
        name -> matplotlib Figure.
    """
    chosen = {d: study.eta[d] for d in ("random", "separated-parameter optimised")}
    stand_ins = {label.split()[0] for combos in study.combinations.values() for label in combos}
    figs = {"ide-convergence": ide_convergence(study.histories), "pose-count": pose_count(study.curve, study.m),
            "eta": eta_bars(chosen, list(study.true_errors), stand_ins),
            "validation-points": validation_points(study.point_errors),
            "validation-summary": validation_summary(study.point_errors, f"first repetition; {study.protocol_text()}"),
            "gcn": gcn_against_poses(study.gcn_curve),
            "design-positions": design_positions(study.positions)}
    index = "the raw Jacobian in mm and rad" if study.units == "paper" else "scaled columns"
    for name in ("ide-convergence", "pose-count", "design-positions"):  # each figure states its protocol
        _note(figs[name], f"{study.m}-pose designs, comprehensive index on {index}")
    for name in ("eta", "validation-points"):
        _note(figs[name], f"first repetition; {study.protocol_text()}")
    return figs


@_styled
def pso_fitness(history) -> Figure:
    """The 3-PUU paper of 2024's Fig. 7: the swarm's best mean squared residual per iteration."""
    fig, ax = _axes(6.0, 3.2)
    h = np.asarray(history, dtype=float)
    ax.semilogy(np.arange(1, len(h) + 1), np.sqrt(h) * MM, color="#1f77b4")
    ax.set(xlabel="iteration", ylabel="best RMS residual (mm)",
           title="Particle swarm fitness (3-PUU paper of 2024, Fig. 7)")
    return fig
