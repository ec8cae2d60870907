"""Measurement-pose design: candidate pools, criteria, exchange algorithms, certified bounds."""
from .bound import Bound, relaxed_bound
from .criteria import CRITERIA, score
from .npose import PoseCountCurve, minimum_poses, pose_count_curve
from .options import DESIGN_CRITERIA, METHODS, DesignOptions
from .problem import UNITS, DesignProblem, design_problem, observation_problem
from .cell import Cell, candidate_pool
from .check import check_poses
from .route import Route, plan_route, travel_order, turned
from .select import Design, select_poses

__all__ = ["UNITS", "Bound", "relaxed_bound", "CRITERIA", "score", "candidate_pool", "DesignProblem", "design_problem",
           "METHODS", "DESIGN_CRITERIA", "Cell", "DesignOptions", "Design", "select_poses", "PoseCountCurve", "minimum_poses",
           "pose_count_curve", "observation_problem", "check_poses", "Route", "plan_route",
           "travel_order", "turned"]
