"""Reproducible studies built on the public API (the seed papers' experiments)."""
from .seed1 import Seed1Study, seed1_study

__all__ = ["Seed1Study", "seed1_study"]
