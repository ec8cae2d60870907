"""Reproducible studies built on the public API: Guo et al. 2024 reproduced (the demonstration) and
its claim as a Monte-Carlo distribution, run in tasks on any executor."""
from .guo2024 import Guo2024Study, guo2024_study

__all__ = ["Guo2024Study", "guo2024_study"]
