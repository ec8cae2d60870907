"""The calibration report (HTML with inline SVG plots, JSON, terminal summary) and its figures."""
from .build import Report, build_report, evaluation_figures, figure_set, json_path_for
from .figures import save as save_figure

__all__ = ["Report", "build_report", "figure_set", "evaluation_figures", "json_path_for", "save_figure"]
