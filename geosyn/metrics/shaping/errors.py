"""Errors of the metric-shaping terms and `ShapedMetric`.

A bad obstacle shape or payload is a `geosyn.world.InvalidGeometry`, raised by the world
layer where shapes and payloads are validated.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.errors import MetricError


class ShapingError(MetricError):
    """Base class of the errors raised by metric-shaping terms and `ShapedMetric`."""


class InvalidTermArgument(ShapingError, InvalidArgument):
    """An argument of a shaping term is out of range or has the wrong shape.

    The message names the argument, the value given and what is allowed.
    """


class CapacityExceeded(InvalidTermArgument):
    """More obstacles were given than the fixed capacity of an `ObstacleTerm`.

    Attributes:
        capacity: the term's number of obstacle slots.
        requested: the number of obstacles asked for.
    """

    def __init__(self, message: str, capacity: int = 0, requested: int = 0) -> None:
        super().__init__(message)
        self.capacity = capacity
        self.requested = requested


class TermNotBound(ShapingError):
    """A term was evaluated before being bound to a robot (see `MetricTerm.bind`)."""


class TermAlreadyBound(ShapingError):
    """A term bound to one robot was bound again to a different robot."""


@contextmanager
def term_arguments() -> Iterator[None]:
    """Report a failed `geosyn.core.validation` check inside the block as `InvalidTermArgument`."""
    try:
        yield
    except InvalidArgument as err:
        if type(err) is not InvalidArgument:  # already a more specific error
            raise
        raise InvalidTermArgument(str(err)) from err


__all__ = [
    "CapacityExceeded",
    "InvalidTermArgument",
    "ShapingError",
    "TermAlreadyBound",
    "TermNotBound",
    "term_arguments",
]
