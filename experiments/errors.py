"""Errors of the experiments layer (configs, runner, CLI)."""

from __future__ import annotations

from geosyn.core.errors import GeosynError


class ExperimentError(GeosynError):
    """Base class of experiment-layer errors."""
