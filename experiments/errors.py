"""Errors of the experiments layer (configs, runner, CLI)."""

from __future__ import annotations

from geosyn.core.errors import GeosynError


class ExperimentError(GeosynError):
    """Base class of experiment-layer errors."""


class ConfigError(ExperimentError):
    """A malformed experiment configuration (file, YAML syntax, field value or override).

    The message reads ``<file>: <field path>: <what is wrong>``, e.g.
    ``panda.yaml: controllers.1.kp: Input should be greater than or equal to 0``.

    Attributes:
        file: the config file (or built-in name, or ``--set``) the error is about.
        field: dotted field path (``controllers.1.kp``), or None for file-level errors.
        reason: the reason alone, without file and field.
    """

    def __init__(self, file: str, field: str | None, reason: str) -> None:
        self.file = str(file)
        self.field = field
        self.reason = reason
        where = f"{self.file}: {field}: " if field else f"{self.file}: "
        super().__init__(where + reason)


class RunDirectoryExists(ExperimentError):
    """The output directory of a run already exists and ``--force`` was not given."""


class ProcedureFailed(ExperimentError):
    """A procedure could not produce its results (a solver failed, a run diverged, ...)."""


class SweepError(ExperimentError):
    """A malformed sweep (bad ``--grid``, seeds, workers) or a failed sweep run."""
