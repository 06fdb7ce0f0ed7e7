"""Experiments: typed YAML configs, the runner, built-in procedures, sweeps and reports.

The rooms follow a run's stages: `schema` (typed YAML sections), `config` (loading a
file: every problem at once, resource limits), `run` (build the parts, claim the run
directory, run a procedure, log), `procedures` (the built-in experiments, registered by
``kind``), `results` (summaries, reports, tables, plots, videos), `sweep` (grids x seeds
on local workers or Ray), `cli` (the ``geosyn`` command) and `viewer` (browser viewers).
The functions `geosyn.experiments.sweep.sweep` and
`geosyn.experiments.results.report.report` are not re-exported here.

Names load on first use (PEP 562), so importing this package (as the ``geosyn`` command
line does for ``--help`` and ``list``) imports neither MuJoCo, CasADi nor Pinocchio;
``from geosyn.experiments import load_config`` works as usual.
"""

from __future__ import annotations

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.experiments, not {__name__}: one module, one name")

import importlib
from typing import TYPE_CHECKING, Any

#: Public name -> the submodule that defines it.
_NAMES = {
    "ConfigError": "geosyn.experiments.errors",
    "ExperimentError": "geosyn.experiments.errors",
    "OutputNotWritable": "geosyn.experiments.errors",
    "ProcedureFailed": "geosyn.experiments.errors",
    "RunDirectoryExists": "geosyn.experiments.errors",
    "builtin_names": "geosyn.experiments.config.loader",
    "load_config": "geosyn.experiments.config.loader",
    "validate_config": "geosyn.experiments.config.loader",
    "PROCEDURES": "geosyn.experiments.procedures",
    "Procedure": "geosyn.experiments.procedures",
    "RunContext": "geosyn.experiments.procedures",
    "register": "geosyn.experiments.procedures",
    "RunOutcome": "geosyn.experiments.run.runner",
    "run_experiment": "geosyn.experiments.run.runner",
    "ExperimentConfig": "geosyn.experiments.schema",
    "SweepResult": "geosyn.experiments.sweep",
    "parse_grid": "geosyn.experiments.sweep",
}

__all__ = [
    "PROCEDURES",
    "ConfigError",
    "ExperimentConfig",
    "ExperimentError",
    "OutputNotWritable",
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

if TYPE_CHECKING:
    from geosyn.experiments.config.loader import builtin_names, load_config, validate_config
    from geosyn.experiments.errors import (
        ConfigError,
        ExperimentError,
        OutputNotWritable,
        ProcedureFailed,
        RunDirectoryExists,
    )
    from geosyn.experiments.procedures import PROCEDURES, Procedure, RunContext, register
    from geosyn.experiments.run.runner import RunOutcome, run_experiment
    from geosyn.experiments.schema import ExperimentConfig
    from geosyn.experiments.sweep import SweepResult, parse_grid


def __getattr__(name: str) -> Any:
    """Load a public name from its submodule on first use (PEP 562)."""
    module = _NAMES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
