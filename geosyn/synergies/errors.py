"""Errors of the synergies layer (geodesic synergies, bases, PGA, reaching).

Two kinds: bad input (`InvalidSynergyInput`, also a `geosyn.core.InvalidArgument`) and a
numerical iteration that did not converge (`SynergyNotConverged`), both a `SynergyError`.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from geosyn.core.errors import GeosynError, InvalidArgument


class SynergyError(GeosynError):
    """Base class of synergy-layer errors."""


class InvalidSynergyInput(SynergyError, InvalidArgument):
    """An argument of a synergy function has the wrong type, shape, size or value.

    The message names the argument, the value given and what is allowed.

    Attributes:
        argument: name of the offending argument, or None.
        index: for linearly dependent directions, the column found dependent on the
            previous ones; otherwise None.
    """

    def __init__(self, message: str, argument: str | None = None, index: int | None = None) -> None:
        super().__init__(message)
        self.argument = argument
        self.index = None if index is None else int(index)


class SynergyNotConverged(SynergyError):
    """A numerical iteration inside a synergy operation did not converge.

    Raised when the log map joining two configurations fails (chained from
    `geosyn.metrics.GeodesicNotFound`) and when the Fréchet mean iteration stops at its
    limit.

    Attributes:
        residual: final residual: the log map's endpoint error [rad], or the G-norm of
            the mean's last update [rad].
        iterations: iterations done (Fréchet mean), or None.
        q_from: (n,) start configuration of the failed log map [rad], or None.
        q_to: (n,) target configuration of the failed log map [rad], or None.
        v0: (n,) best initial velocity the log map found [rad/s], or None.
    """

    def __init__(
        self,
        message: str,
        residual: float,
        iterations: int | None = None,
        *,
        q_from: object = None,
        q_to: object = None,
        v0: object = None,
    ) -> None:
        super().__init__(message)
        self.residual = float(residual)
        self.iterations = None if iterations is None else int(iterations)
        self.q_from = q_from
        self.q_to = q_to
        self.v0 = v0


@contextmanager
def synergy_input(argument: str | None = None) -> Iterator[None]:
    """Report a `geosyn.core.InvalidArgument` raised inside as `InvalidSynergyInput`.

    Lets synergy functions use the shared checks of `geosyn.core.validation` while
    every bad input they refuse stays a `SynergyError`; the message is kept.

    Args:
        argument: name of the argument checked inside, for `InvalidSynergyInput.argument`.
    """
    try:
        yield
    except InvalidSynergyInput:
        raise
    except InvalidArgument as err:
        raise InvalidSynergyInput(str(err), argument) from err


__all__ = ["InvalidSynergyInput", "SynergyError", "SynergyNotConverged", "synergy_input"]
