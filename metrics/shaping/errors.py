"""Errors of the metric-shaping terms (payload, obstacle and joint-limit terms)."""

from __future__ import annotations

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.errors import MetricError


class ShapingError(MetricError):
    """Base class of the errors raised by metric-shaping terms and `ShapedMetric`."""


class InvalidTermArgument(ShapingError, InvalidArgument):
    """An argument of a shaping term is out of range or has the wrong shape.

    The message names the argument, the value given and what is allowed.
    """


class InvalidPayload(InvalidTermArgument):
    """A payload has a non-positive mass, a badly shaped com or a non-SPD inertia."""


class InvalidObstacle(InvalidTermArgument):
    """An obstacle has a bad size or pose (negative radius, non-unit normal, ...)."""


class UnknownObstacleType(InvalidObstacle):
    """An obstacle is not one of the supported shapes (Sphere, Box, Capsule, HalfSpace)."""


class CapacityExceeded(InvalidTermArgument):
    """More obstacles were given than the fixed capacity of an `ObstacleTerm`."""


class TermNotBound(ShapingError):
    """A term was evaluated before being bound to a robot (see `MetricTerm.bind`)."""


class TermAlreadyBound(ShapingError):
    """A term bound to one robot was bound again to a different robot."""


__all__ = [
    "CapacityExceeded",
    "InvalidObstacle",
    "InvalidPayload",
    "InvalidTermArgument",
    "ShapingError",
    "TermAlreadyBound",
    "TermNotBound",
    "UnknownObstacleType",
]
