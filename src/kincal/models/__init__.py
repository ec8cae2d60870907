"""Robot models: parameters, serial chains, URDF chains, robot files in and out."""
from .chain import Chain, Op
from .export import FORMATS, export_robot, joint_frames, ur_calibration, urdf_text
from .parameters import Parameters
from .robot import Robot
from .serial import ChainRobot, Joint, SerialRobot
from .transmission import Map, TransmissionRobot
from .urdf import URDFJoint, URDFRobot, read_urdf
from .yaml_io import bundled_robots, load_calibration_record, load_robot, save_robot

__all__ = ["Chain", "Op", "Parameters", "Robot", "ChainRobot", "Joint", "SerialRobot", "Map", "TransmissionRobot",
           "URDFJoint", "URDFRobot", "read_urdf", "bundled_robots", "load_robot", "save_robot", "load_calibration_record", "joint_frames",
           "ur_calibration", "urdf_text", "FORMATS", "export_robot"]
