"""Errors of the world layer (shapes, poses, payloads)."""

from __future__ import annotations

from geosyn.core.errors import GeosynError, InvalidArgument


class WorldError(GeosynError):
    """Base class of world-layer errors."""


class InvalidGeometry(WorldError, InvalidArgument):
    """A shape, pose or payload has a bad value, or an object is not a supported shape.

    The message names the field, the value given and what is allowed.

    Attributes:
        name: the field or argument concerned, e.g. ``"Sphere.radius"`` or ``"obstacles[2]"``.
        value: the value given.
    """

    def __init__(self, message: str, name: str = "", value: object = None) -> None:
        super().__init__(message)
        self.name = name
        self.value = value


__all__ = ["InvalidGeometry", "WorldError"]
