"""Errors raised while loading or querying robot descriptions."""

from __future__ import annotations

from geosyn.core.errors import GeosynError, InvalidArgument


class RobotError(GeosynError):
    """Base class of robot-layer errors."""


class UnknownRobot(RobotError, KeyError):
    """A robot name is neither a built-in nor an existing file."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class RobotFileError(RobotError):
    """A robot file is missing, unreadable or malformed."""


class UnknownFrame(RobotError, KeyError):
    """A frame or joint name is not in the model; the message lists the available ones."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


__all__ = ["InvalidArgument", "RobotError", "RobotFileError", "UnknownFrame", "UnknownRobot"]
