"""Errors of the export layer."""

from __future__ import annotations

from collections.abc import Sequence

from geosyn.core.errors import GeosynError, InvalidArgument


class ExportError(GeosynError):
    """Exporting a controller to C failed (unsupported controller, compiler failure, ...).

    Attributes:
        command: the command that failed (compiler, archiver), empty if none ran.
        stderr: what it printed on stderr (empty if none ran).
    """

    def __init__(self, message: str, command: Sequence[str] = (), stderr: str = "") -> None:
        super().__init__(message)
        self.command = list(command)
        self.stderr = str(stderr)


__all__ = ["ExportError", "InvalidArgument"]
