"""Robot models: parameters, serial chains, URDF chains, transmissions, closed loops, error-model
terms, and robot files in and out."""
from .chain import Chain, Op
from .export import FORMATS, export_robot, joint_frames, ur_calibration, urdf_text
from .implicit import ImplicitRobot
from .parameters import Parameters
from .puu3 import PUU3Robot
from .joint_space import JointSpace
from .robot import Robot
from .wrapped import Wrapped
from .serial import ChainRobot, Joint, SerialRobot
from .terms import ErrorModel, ExtendedRobot, extend, parse_model, with_covariates, without_unread_covariates
from .transmission import Map, TransmissionRobot
from .urdf import URDFJoint, URDFRobot, read_urdf
from .yaml_io import bundled_robots, load_calibration_record, load_robot, save_robot

__all__ = ["Chain", "Op", "FORMATS", "export_robot", "joint_frames", "ur_calibration", "urdf_text", "ImplicitRobot",
           "Parameters", "PUU3Robot", "JointSpace", "Robot", "Wrapped", "ChainRobot", "Joint", "SerialRobot",
           "ErrorModel", "ExtendedRobot", "extend", "parse_model", "with_covariates", "without_unread_covariates", "Map",
           "TransmissionRobot",
           "URDFJoint", "URDFRobot",
           "read_urdf", "bundled_robots", "load_calibration_record", "load_robot", "save_robot"]
