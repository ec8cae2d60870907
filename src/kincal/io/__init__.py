"""Measurement data in and out (CSV), and robot programs read and written again (one dialect per vendor language)."""
from .measurements import (Measurements, read_joints, read_measurements, read_positions, write_joints,
                           write_measurements, write_residuals, write_selected_rows)
from .programs import DIALECT_NAMES, Dialect, Program, Target, dialect_of, dialects, read_program, write_program
from .frames_file import TaughtFrame, read_frames
from .branches import BITS, ROWS
from .frames_data import FRAMES_FORMATS, check_frames_output, frame_numbers, write_frames_data
from ..models.unit_checks import check_degrees, check_joints, check_limits, check_radians, check_spread, joints_in_radians

__all__ = ["Measurements", "read_joints", "read_measurements", "read_positions", "write_joints", "write_measurements",
           "write_residuals", "write_selected_rows", "check_degrees", "check_joints", "check_limits", "check_radians",
           "check_spread", "joints_in_radians",
           "Program", "Target", "Dialect", "DIALECT_NAMES", "dialect_of", "dialects", "read_frames", "TaughtFrame",
           "read_program", "BITS", "ROWS", "write_program", "FRAMES_FORMATS", "check_frames_output", "frame_numbers",
           "write_frames_data"]
