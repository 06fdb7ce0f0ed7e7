"""Sweeps: one experiment over a grid of settings x seeds, resumable, on local workers or Ray.

`run_sweep` holds `sweep` and the grid parsing, `executors` the local process pool (its
workers die with the sweep) and Ray; the aggregate of a sweep directory is
`geosyn.experiments.results.aggregate`.
"""

from geosyn.experiments.results.aggregate import aggregate, point_name
from geosyn.experiments.sweep.run_sweep import (
    MAX_RUNS,
    MAX_WORKERS,
    SweepJob,
    SweepResult,
    parse_grid,
    run_job,
    sweep,
)

__all__ = [
    "MAX_RUNS",
    "MAX_WORKERS",
    "SweepJob",
    "SweepResult",
    "aggregate",
    "parse_grid",
    "point_name",
    "run_job",
    "sweep",
]
