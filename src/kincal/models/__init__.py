"""Robot models: parameters, serial chains, robot files."""
from .chain import Chain, Op
from .parameters import Parameters
from .robot import Robot
from .serial import Joint, SerialRobot
from .transmission import Map, TransmissionRobot
from .yaml_io import bundled_robots, load_robot, save_robot

__all__ = ["Chain", "Op", "Parameters", "Robot", "Joint", "SerialRobot", "Map", "TransmissionRobot", "bundled_robots",
           "load_robot", "save_robot"]
