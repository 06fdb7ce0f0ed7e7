"""Robot files: URDF and MJCF loading, and the example-robot-data folder."""

from __future__ import annotations

from pathlib import Path

import pinocchio as pin

from geosyn.robots.errors import RobotFileError
from geosyn.robots.from_model import robot_from_model
from geosyn.robots.robot import Robot

ROBOT_FILE_SUFFIXES = (".urdf", ".xml", ".mjcf")
"""File suffixes `load_file` reads (case-insensitive)."""


def example_robot_data_dir() -> Path:
    """Folder of the URDFs shipped by the `example-robot-data` PyPI package.

    Raises:
        RobotFileError: the package is not installed.
    """
    site = Path(pin.__file__).resolve().parents[1]
    for base in (site, *Path(pin.__file__).resolve().parents):
        cand = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if cand.is_dir():
            return cand
    raise RobotFileError(
        "example-robot-data is not installed (looked for cmeel.prefix/share/example-robot-data"
        f" under {site}); install it with `pip install example-robot-data`"
    )


def _read_model(path: Path) -> pin.Model:
    """The Pinocchio model of a URDF or MJCF file."""
    if not path.is_file():
        raise RobotFileError(f"robot file {str(path)!r} does not exist", path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".urdf":
            return pin.buildModelFromUrdf(str(path))
        if suffix in (".xml", ".mjcf"):
            return pin.buildModelFromMJCF(str(path))
    except (RuntimeError, ValueError) as err:
        raise RobotFileError(f"could not parse robot file {str(path)!r}: {err}", path) from err
    raise RobotFileError(
        f"robot file {str(path)!r} has suffix {suffix!r}; allowed: {', '.join(ROBOT_FILE_SUFFIXES)}",
        path,
    )


def load_file(path: str | Path, **options: object) -> Robot:
    """Load a robot from a URDF (``.urdf``) or MJCF (``.xml``/``.mjcf``) file.

    Args:
        path: file path.
        **options: forwarded to `robot_from_model` (``keep_joints``, ``lock_q``,
            ``ee_frame``, ``armature``, ``gravity``, ...).

    Raises:
        RobotFileError: missing, unreadable or malformed file.
    """
    p = Path(path)
    model = _read_model(p)
    options.setdefault("name", p.stem)
    return robot_from_model(model, **options)  # type: ignore[arg-type]
