"""Data out as Parquet: ``data/<run>.parquet`` per closed-loop run, the same named columns
as ``data/<run>.csv`` (`geosyn.experiments.results.data`), float64 throughout.

The CSV's ``# key: value`` lines (run, controller, robot, control period, status) are the
file's key-value metadata. Writing Parquet needs pyarrow, geosyn's ``parquet`` extra
(``pip install 'geosyn[parquet]'``); without it `write_parquet` raises an
`ExperimentError` that says so.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np

from geosyn.experiments.errors import ExperimentError
from geosyn.experiments.results.data import controller_of, load_runs, run_columns

PARQUET_EXTRA = "parquet"
"""The optional-dependency group that brings pyarrow."""


def _pyarrow() -> tuple[ModuleType, ModuleType]:
    """``pyarrow`` and ``pyarrow.parquet``, imported on first use."""
    try:  # deferred: pyarrow is optional and heavy
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as err:
        raise ExperimentError(
            f"writing Parquet needs pyarrow, geosyn's {PARQUET_EXTRA!r} extra:"
            f" pip install 'geosyn[{PARQUET_EXTRA}]' (the CSV files hold the same columns)"
        ) from err
    return pa, pq


def write_parquet(out_dir: Path, labels: list[str]) -> list[Path]:
    """Write ``data/<run>.parquet`` for every closed-loop run of ``out_dir/results.npz``.

    Args:
        out_dir: the run directory (holding results.npz).
        labels: the config's controller labels (for the ``controller`` metadata).

    Returns:
        The files written (none when the experiment has no closed-loop run).

    Raises:
        ExperimentError: no results.npz, or pyarrow is not installed.
    """
    runs = load_runs(out_dir)
    if not runs:
        return []
    pa, pq = _pyarrow()
    folder = out_dir / "data"
    folder.mkdir(exist_ok=True)
    written = []
    for run, res in runs.items():
        cols = run_columns(res)
        table = pa.table({k: pa.array(np.asarray(v, dtype=np.float64)) for k, v in cols.items()})
        meta = {
            "run": run,
            "controller": controller_of(run, labels),
            "robot": res.robot_name,
            "control_dt [s]": repr(res.control_dt),
            "status": res.status,
        }
        table = table.replace_schema_metadata({k: str(v) for k, v in meta.items()})
        path = folder / f"{run}.parquet"
        pq.write_table(table, path)
        written.append(path)
    return written


__all__ = ["PARQUET_EXTRA", "write_parquet"]
