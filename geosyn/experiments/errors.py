"""Errors of the experiments layer (configs, runs, sweeps, the CLI).

Three coarse kinds, by what the user does about them: fix the input (`ConfigError`),
choose another output directory (`RunDirectoryExists`), or look at the run that failed
(`ProcedureFailed`). Argument checks of the library functions raise
`geosyn.core.InvalidArgument` (from `geosyn.core.validation`).
"""

from __future__ import annotations

from pathlib import Path

from geosyn.core.errors import GeosynError


class ExperimentError(GeosynError):
    """Base class of experiment-layer errors (also raised for a path that is not a run
    directory)."""


class ConfigError(ExperimentError):
    """Malformed input: a config file, its YAML, a field value, a ``--set`` override or a
    sweep's ``--grid``.

    The message reads ``<file>: <field path>: <what is wrong>``, e.g.
    ``panda.yaml: controllers.1.kp: Input should be greater than or equal to 0``.

    Attributes:
        file: the config file (or built-in name, ``--set`` or ``--grid``) the error is about.
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
    """The output directory of a run or sweep exists and may not be written into.

    Attributes:
        path: the directory.
        reason: why it may not be used (and what to do instead).
    """

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path = Path(path)
        self.reason = reason
        super().__init__(f"out {str(path)!r} {reason}")


class OutputNotWritable(ExperimentError):
    """A run or sweep directory could not be written (disk full, read-only, no permission).

    Attributes:
        path: the directory.
        errno: the operating system's error number (e.g. ``errno.ENOSPC``), if known.
    """

    def __init__(self, path: str | Path, err: OSError) -> None:
        self.path = Path(path)
        self.errno = err.errno
        what = err.strerror or str(err)
        where = f" ({err.filename})" if err.filename else ""
        super().__init__(
            f"out {str(path)!r} cannot be written: {what}{where}; free disk space, fix the"
            " permissions or choose another --out"
        )


class ProcedureFailed(ExperimentError):
    """A procedure could not produce its results (a solver failed, a run diverged, a
    sweep's run failed, ...)."""


__all__ = [
    "ConfigError",
    "ExperimentError",
    "OutputNotWritable",
    "ProcedureFailed",
    "RunDirectoryExists",
]
