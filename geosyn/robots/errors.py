"""Errors raised while loading or querying robot descriptions."""

from __future__ import annotations

from collections.abc import Iterable

from geosyn.core.errors import GeosynError, InvalidArgument


class RobotError(GeosynError):
    """Base class of robot-layer errors."""


class RobotFileError(RobotError):
    """A robot file is missing, unreadable or malformed, or holds an unsupported model.

    Attributes:
        path: the file concerned, or None (e.g. an unsupported joint in a model).
    """

    def __init__(self, message: str, path: object = None) -> None:
        super().__init__(message)
        self.path = None if path is None else str(path)


class FloatingBaseError(RobotError):
    """A floating-base robot (configuration on SE(3) x R^n) where geosyn supports only a
    fixed base, or a floating-base configuration that is not on the group (a quaternion
    that is not unit); the message names the robot and what to do instead."""


class RobotWarning(UserWarning):
    """A robot file was loaded with something assumed or changed (a default torque limit,
    a welded floating base, an ignored property); the message says what."""


class _UnknownName(RobotError, KeyError):
    """A name that is not among the available ones; the message lists them.

    Attributes:
        name: the name given.
        available: the names that would have been accepted.
    """

    def __init__(self, message: str, name: object = None, available: Iterable[str] = ()) -> None:
        super().__init__(message)
        self.name = name
        self.available = tuple(available)

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class UnknownRobot(_UnknownName):
    """A robot name is neither a built-in nor a path with a robot-file suffix."""


class UnknownFrame(_UnknownName):
    """A frame or joint name is not in the model."""


__all__ = [
    "FloatingBaseError",
    "InvalidArgument",
    "RobotError",
    "RobotFileError",
    "RobotWarning",
    "UnknownFrame",
    "UnknownRobot",
]
