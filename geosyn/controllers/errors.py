"""Errors of the controllers layer."""

from __future__ import annotations

from geosyn.core.errors import GeosynError, InvalidArgument


class ControllerError(GeosynError):
    """Base class of controller-layer errors."""


class NoReference(ControllerError):
    """`Controller.compute` was called before a reference was set."""


class SolverFailed(ControllerError):
    """An optimisation-based controller's solver did not return a usable solution.

    Controllers normally do not raise it (they fall back and flag it in their
    diagnostics); it is raised where no fallback exists.

    Attributes:
        status: solver status string.
        iterations: iterations used.
    """

    def __init__(self, message: str, status: str = "failed", iterations: int = 0) -> None:
        super().__init__(message)
        self.status = str(status)
        self.iterations = int(iterations)


__all__ = ["ControllerError", "InvalidArgument", "NoReference", "SolverFailed"]
