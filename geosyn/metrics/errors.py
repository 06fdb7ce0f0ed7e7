"""Errors of the metrics layer (metrics, geodesics)."""

from __future__ import annotations

from geosyn.core.errors import GeosynError


class MetricError(GeosynError):
    """Base class of metric-layer errors."""


class NoSymbolicForm(MetricError):
    """A metric has no CasADi symbolic form, so symbolic derivatives are unavailable."""


class FloatingBaseUnsupported(MetricError):
    """An operation that treats configurations as vectors in R^n was given a metric on a
    floating base's group SE(3) x R^n (nq != nv); the message names what works there."""


class StanceError(MetricError):
    """A stance (contact frames held fixed) that cannot be used: no frames, one that
    over-constrains the robot, or a start off the stance; the message gives the values."""


class GeodesicNotFound(MetricError):
    """The log map (boundary-value problem) did not converge.

    Attributes:
        residual: final endpoint error ||exp(q0, v0)(1) - q1|| [rad].
        v0: (n,) best initial velocity found [rad/s].
    """

    def __init__(self, message: str, residual: float, v0: object = None) -> None:
        super().__init__(message)
        self.residual = float(residual)
        self.v0 = v0


class NonFiniteResult(MetricError):
    """A computation on finite inputs left the float64 range (inf or NaN): e.g. a geodesic
    shot with a huge velocity, or a Coriolis term of velocities near 1e154.

    Attributes:
        quantity: what became non-finite (``"geodesic_acceleration"``, ``"exp"``, ...).
    """

    def __init__(self, message: str, quantity: str) -> None:
        super().__init__(message)
        self.quantity = quantity
