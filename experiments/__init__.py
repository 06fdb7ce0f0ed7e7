"""Experiments: typed YAML configs, the runner, built-in procedures, sweeps and reports.

The functions ``sweep`` and ``report`` live in the submodules of the same names
(`geosyn.experiments.sweep.sweep`, `geosyn.experiments.report.report`); they are not
re-exported here so that the submodules stay importable under their names.
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.experiments, not {__name__}: one module, one name")


from geosyn.experiments.errors import (
    ConfigError,
    ExperimentError,
    ProcedureFailed,
    RunDirectoryExists,
)
from geosyn.experiments.loader import builtin_names, load_config, validate_config
from geosyn.experiments.procedures import PROCEDURES, Procedure, RunContext, register
from geosyn.experiments.runner import RunOutcome, run_experiment
from geosyn.experiments.schema import ExperimentConfig
from geosyn.experiments.sweep import SweepResult, parse_grid

__all__ = [
    "PROCEDURES",
    "ConfigError",
    "ExperimentConfig",
    "ExperimentError",
    "Procedure",
    "ProcedureFailed",
    "RunContext",
    "RunDirectoryExists",
    "RunOutcome",
    "SweepResult",
    "builtin_names",
    "load_config",
    "parse_grid",
    "register",
    "run_experiment",
    "validate_config",
]
