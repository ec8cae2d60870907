"""Observation types: what a measurement says about the robot (a point, the joints that reach it, markers, a full
pose, the same point with known distances, plane contacts), each a residual object with its noise σ and the
set-up parameters it brings. The stacked fit is :func:`kincal.identify.fit_observations`."""
from .constraints import PlaneObs, SamePointObs
from .drifting import Drifting
from .files import KINDS, ObservationFormat, describe, read_observations, write_observations
from .joint import JointObs, PoseJointObs, in_cartesian, in_joint_space
from .markers import MarkersObs
from .observations import Observation, PointObs, PoseObs
from .orientation import check_convention, default_columns, from_matrices, to_matrices
from .sessions import InSession

__all__ = ["Observation", "PointObs", "JointObs", "PoseJointObs", "in_joint_space", "in_cartesian", "PoseObs",
           "MarkersObs", "SamePointObs", "PlaneObs", "InSession", "Drifting", "KINDS", "ObservationFormat",
           "read_observations", "write_observations", "describe", "check_convention", "default_columns",
           "from_matrices", "to_matrices"]
