"""Robot descriptions: one description gives a Pinocchio model and a MuJoCo model with
identical dynamics."""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.robots, not {__name__}: one module, one name")


from geosyn.robots.builtins import BUILTINS
from geosyn.robots.couplings import Coupling
from geosyn.robots.errors import (
    FloatingBaseError,
    RobotError,
    RobotFileError,
    RobotWarning,
    UnknownFrame,
    UnknownRobot,
)
from geosyn.robots.files import load_file
from geosyn.robots.from_model import robot_from_model
from geosyn.robots.loading import load_robot
from geosyn.robots.mjcf import robot_to_mjcf
from geosyn.robots.robot import CollisionCapsule, CollisionSphere, Robot

__all__ = [
    "BUILTINS",
    "Coupling",
    "CollisionCapsule",
    "CollisionSphere",
    "FloatingBaseError",
    "Robot",
    "RobotError",
    "RobotFileError",
    "RobotWarning",
    "UnknownFrame",
    "UnknownRobot",
    "load_file",
    "load_robot",
    "robot_from_model",
    "robot_to_mjcf",
]
