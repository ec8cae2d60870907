"""The calibration report (HTML with inline SVG plots, JSON, terminal summary) and the figures of
calibrations and studies. Importing this room loads matplotlib and Jinja2."""
from .._atomic import json_path_for
from .build import Report, build_report, evaluation_figures, figure_set
from .figures import save as save_figure
from .observations import observation_figures
from .study_figures import guo2024_figures

__all__ = ["Report", "build_report", "figure_set", "evaluation_figures", "json_path_for", "save_figure",
           "guo2024_figures", "observation_figures"]
