"""Errors of the synergies layer (geodesic synergies, bases, PGA, reaching)."""

from __future__ import annotations

from geosyn.core.errors import GeosynError, InvalidArgument
from geosyn.metrics.errors import GeodesicNotFound


class SynergyError(GeosynError):
    """Base class of synergy-layer errors."""


class InvalidSynergyInput(SynergyError, InvalidArgument):
    """An argument of a synergy function has the wrong shape, size or value.

    The message names the argument, the value given and what is allowed.
    """


class DimensionMismatch(InvalidSynergyInput):
    """Arrays or synergies whose dimensions disagree (e.g. a (3,) vector for a 2-DoF metric)."""


class EmptyDemonstrations(InvalidSynergyInput):
    """No demonstrations, or a demonstration with no samples."""


class WeightCountMismatch(InvalidSynergyInput):
    """The number of weights differs from the number of synergies."""


class LinearlyDependentDirections(InvalidSynergyInput):
    """Directions to orthonormalize are linearly dependent (under the metric).

    Attributes:
        index: column of the first direction found dependent on the previous ones.
    """

    def __init__(self, message: str, index: int) -> None:
        super().__init__(message)
        self.index = int(index)


class LogMapFailed(SynergyError, GeodesicNotFound):
    """The log map needed by a synergy operation did not converge.

    Wraps `geosyn.metrics.GeodesicNotFound` (and is one, so code catching that keeps
    working), adding which configurations were being connected.

    Attributes:
        residual: final endpoint error of the shooting [rad].
        v0: (n,) best initial velocity found [rad/s], or None.
        q_from: (n,) start configuration [rad].
        q_to: (n,) target configuration [rad].
    """

    def __init__(self, message: str, residual: float, v0: object, q_from: object, q_to: object):
        super().__init__(message, residual, v0)
        self.q_from = q_from
        self.q_to = q_to


class MeanNotConverged(SynergyError):
    """The Fréchet (Karcher) mean iteration did not converge.

    Attributes:
        iterations: iterations done.
        step_norm: Riemannian norm of the last mean update [rad, G-norm].
    """

    def __init__(self, message: str, iterations: int, step_norm: float) -> None:
        super().__init__(message)
        self.iterations = int(iterations)
        self.step_norm = float(step_norm)
