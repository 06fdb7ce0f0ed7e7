"""Data out as Parquet: ``data/<run>.parquet`` per closed-loop run, the same named columns
as ``data/<run>.csv`` (`geosyn.experiments.results.data`), float64 throughout.

The CSV's ``# key: value`` lines (run, controller, robot, control period, status) are the
file's key-value metadata. Writing Parquet needs pyarrow, geosyn's ``parquet`` extra
(``pip install 'geosyn[parquet]'``); without it `write_parquet` raises an
`ExperimentError` that says so.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from geosyn.experiments.errors import ExperimentError
from geosyn.experiments.results.data import controller_of, results_file, stored_run_columns
from geosyn.sim.blocks import row_blocks

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


def write_parquet(
    out_dir: Path, labels: list[str], results: Mapping[str, Any] | None = None
) -> list[Path]:
    """Write ``data/<run>.parquet`` for every closed-loop run of ``out_dir/results.npz``.

    A row group per `geosyn.sim.blocks.SCAN_BLOCK` ticks, written one at a time: like the
    CSV, memory does not grow with the runs (beyond one run's arrays when read from the
    file).

    Args:
        out_dir: the run directory (holding results.npz).
        labels: the config's controller labels (for the ``controller`` metadata).
        results: the arrays of ``results.npz`` when the caller holds them (the runner):
            read from memory instead of the file.

    Returns:
        The files written (none when the experiment has no closed-loop run).

    Raises:
        ExperimentError: no results.npz, or pyarrow is not installed.
    """
    if results is None:
        with np.load(results_file(out_dir), allow_pickle=False) as data:
            return _write_runs(out_dir, labels, data)
    return _write_runs(out_dir, labels, results)


def _write_runs(out_dir: Path, labels: list[str], data: Mapping[str, Any]) -> list[Path]:
    written = []
    for run, meta, cols, arrays in stored_run_columns(data):
        pa, pq = _pyarrow()
        folder = out_dir / "data"
        folder.mkdir(exist_ok=True)
        info = {
            "run": run,
            "controller": controller_of(run, labels),
            "robot": meta["robot_name"],
            "control_dt [s]": repr(float(meta["control_dt"])),
            "status": meta["status"],
        }
        schema = pa.schema([(name, pa.float64()) for name in cols], metadata=info)
        path = folder / f"{run}.parquet"
        with pq.ParquetWriter(path, schema) as writer:
            for rows in row_blocks(len(cols["t"]), *arrays):
                block = {k: np.asarray(v[rows], dtype=np.float64) for k, v in cols.items()}
                writer.write_table(pa.table(block, schema=schema))
        written.append(path)
    return written


__all__ = ["PARQUET_EXTRA", "write_parquet"]
