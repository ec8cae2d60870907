"""Compensation: joint commands that the calibrated model says reach given targets (checked before
use), and error-model verification plans (the 3-PUU paper of 2024,
"Error analysis model of parallel robot based on parameters identification")."""
from .commands import Compensation, compensate, compensate_poses, path_checked
from .poses import PoseSolution, filtered_poses, solve_poses
from .program import ProgramCompensation, compensate_program
from .branch import compensate_branches
from .frames import (LINK_ERROR_MAX, TARGET_FRAMES, base_mismatch, base_note, command_models, frame_mismatch,
                     tool_carry, unit_mismatch, unseen_at_flange, unseen_in_base)
from .stream import StreamJob, StreamResult, TargetsFormat, compensate_file
from .frames_only import FramesOnly, fit_frames_only
from .taught import resolve_taught
from .turn import FlangeTurn, flange_turn
from .folder import FolderCompensation, check_folder_output, compensate_folder, write_folder
from .verify import Verification, VerificationPlan, commandable, verification_plan

__all__ = ["Compensation", "compensate", "compensate_poses", "path_checked", "ProgramCompensation",
           "compensate_program", "compensate_branches", "PoseSolution", "solve_poses", "filtered_poses",
           "TARGET_FRAMES", "LINK_ERROR_MAX", "command_models", "frame_mismatch", "tool_carry", "StreamJob",
           "StreamResult", "TargetsFormat", "compensate_file", "Verification", "VerificationPlan", "verification_plan", "commandable",
           "FramesOnly", "fit_frames_only", "resolve_taught", "FolderCompensation", "check_folder_output",
           "compensate_folder", "write_folder", "FlangeTurn", "flange_turn", "unseen_in_base", "unseen_at_flange",
           "base_note", "unit_mismatch",
           "base_mismatch"]
