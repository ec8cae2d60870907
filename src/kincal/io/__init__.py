"""Measurement data in and out (CSV)."""
from .measurements import Measurements, read_joints, read_measurements, read_positions, write_joints, write_measurements

__all__ = ["Measurements", "read_joints", "read_measurements", "read_positions", "write_joints", "write_measurements"]
