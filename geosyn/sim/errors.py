"""Errors of the simulation layer (scene building, disturbances, log spooling, rendering).

A bad obstacle shape or payload is a `geosyn.world.InvalidGeometry`, raised where shapes
and payloads are validated.
"""

from __future__ import annotations

from geosyn.core.errors import GeosynError, InvalidArgument


class SimError(GeosynError):
    """Base class of simulation-layer errors."""


class UnknownBody(SimError, KeyError):
    """A body, link, frame or payload name does not resolve to a MuJoCo body.

    The message lists the names that are accepted.
    """

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class SpoolError(SimError, OSError):
    """A long run's spool file (`geosyn.sim.log_spool`) could not be created, written or
    mapped: ``errno`` says why (e.g. ``ENOSPC``, no space left), ``filename`` where."""


class RenderError(SimError):
    """A video could not be rendered or written (no OpenGL context, no writer, ...)."""


__all__ = ["InvalidArgument", "RenderError", "SimError", "SpoolError", "UnknownBody"]
