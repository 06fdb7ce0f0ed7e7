"""Loading robots by name or path: a built-in robot, or any URDF or MJCF file.

The pieces live by concept: `geosyn.robots.builtins` (the built-in robots),
`geosyn.robots.catalog` (example-robot-data by name), `geosyn.robots.files` (URDF/MJCF
files), `geosyn.robots.from_mjcf` (MJCF through MuJoCo's compiler) and
`geosyn.robots.from_model` (a `Robot` from a Pinocchio model).
"""

from __future__ import annotations

from pathlib import Path

from geosyn.core.errors import InvalidArgument
from geosyn.robots.builtins import BUILTINS
from geosyn.robots.errors import UnknownRobot
from geosyn.robots.files import ROBOT_FILE_SUFFIXES, load_file
from geosyn.robots.robot import Robot


def load_robot(name_or_path: str | Path, **options: object) -> Robot:
    """Load a built-in robot by name, or any URDF/MJCF file by path.

    Args:
        name_or_path: one of ``BUILTINS`` (planar2, planar3, panda, talos_arm, ur5, and
            every URDF of example-robot-data by name, e.g. ``xarm7``; see `geosyn robots`)
            or a path to a ``.urdf`` / ``.xml`` / ``.mjcf`` file.
        **options: forwarded to the builder (e.g. ``m1=2.0`` for planar2; for files and
            catalog robots ``fixed_base``, ``armature``, ``gravity``, ``keep_joints``,
            ``ee_frame``, ``tau_max``, see `geosyn.robots.files.load_file`).

    Raises:
        UnknownRobot: neither a built-in name nor a path with a robot-file suffix.
        RobotFileError: the file is missing or malformed.
    """
    key = str(name_or_path)
    if key in BUILTINS:
        try:
            return BUILTINS[key](**options)
        except TypeError as err:
            raise InvalidArgument(f"bad option for robot {key!r}: {err}") from err
    if Path(key).suffix.lower() in ROBOT_FILE_SUFFIXES:
        return load_file(key, **options)
    available = sorted(BUILTINS)
    raise UnknownRobot(
        f"{key!r} is not a built-in robot; available: {', '.join(available)}"
        " (or give a path to a .urdf/.xml/.mjcf file)",
        key,
        available,
    )
