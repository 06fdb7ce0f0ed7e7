"""Recorded trajectories as demonstrations for PGA/PCA: NPZ, CSV and Parquet files.

- NPZ: with ``key``, that array, (T, n), is one trajectory; without, every 2-D array of
  the file is one (in key order; 1-D arrays such as time stamps are skipped).
- CSV: ``#`` comment lines, then a header of column names, then rows. With
  ``joint_names``, the columns are ``q[<joint>]`` (geosyn's run CSV, `write_csv` of
  ``geosyn.experiments.results.data``) or ``<joint>``, taken in that order; without, every
  ``q[...]`` column, else every column except ``t`` and ``trajectory``. An optional
  ``trajectory`` column splits the rows into trajectories (one per distinct value, in
  order of appearance).
- Parquet: the same columns and rules as the CSV (the ``trajectory`` column may hold
  numbers or strings). Reading and writing Parquet needs pyarrow, the ``parquet`` extra
  (``pip install 'geosyn[parquet]'``); without it a clear error says so.

`write_demonstrations` writes trajectories in any of the three formats with the named
columns ``trajectory``, ``q[<joint>]`` (CSV, Parquet) or arrays ``trajectory_<i>`` (NPZ),
which `load_demonstrations` reads back unchanged (float64 round trip).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from geosyn.synergies.errors import InvalidSynergyInput

PARQUET_EXTRA = "parquet"
"""The optional-dependency group that brings pyarrow."""


def parquet_module() -> ModuleType:
    """``pyarrow.parquet``, imported on first use (pyarrow is the ``parquet`` extra).

    Raises:
        InvalidSynergyInput: pyarrow is not installed (the message names the extra).
    """
    try:  # deferred: pyarrow is optional and heavy
        import pyarrow.parquet as pq
    except ImportError as err:
        raise InvalidSynergyInput(
            f"reading or writing Parquet needs pyarrow, geosyn's {PARQUET_EXTRA!r} extra:"
            f" pip install 'geosyn[{PARQUET_EXTRA}]' (or use .npz / .csv)",
            "path",
        ) from err
    return pq


def _select(path: Path, header: list[str], joint_names: Sequence[str] | None) -> list[int]:
    """Indices of the joint columns in ``header`` (the module doc's rules)."""
    if joint_names is None:
        return [i for i, h in enumerate(header) if h.startswith("q[")] or [
            i for i, h in enumerate(header) if h not in ("t", "trajectory")
        ]
    cols = []
    for j in joint_names:
        hit = [c for c in (f"q[{j}]", j) if c in header]
        if not hit:
            raise InvalidSynergyInput(
                f"{path}: no column 'q[{j}]' or '{j}'; columns: {', '.join(header)}", "path"
            )
        cols.append(header.index(hit[0]))
    return cols


def _split(table: np.ndarray, ids: Sequence[object] | None) -> list[np.ndarray]:
    """Rows of ``table`` grouped by ``ids`` in order of first appearance."""
    if ids is None:
        return [table]
    keys = np.asarray(list(ids), dtype=object)
    return [table[keys == v] for v in dict.fromkeys(keys.tolist())]


def _csv(path: Path, joint_names: Sequence[str] | None) -> list[np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    if len(lines) < 2:
        raise InvalidSynergyInput(f"{path}: needs a header line and at least one row", "path")
    header = [h.strip() for h in lines[0].split(",")]
    try:
        table = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    except ValueError as err:
        raise InvalidSynergyInput(f"{path}: a row is not numeric ({err})", "path") from err
    if table.shape[1] != len(header):
        raise InvalidSynergyInput(
            f"{path}: {table.shape[1]} values per row, {len(header)} column names", "path"
        )
    cols = _select(path, header, joint_names)
    ids = table[:, header.index("trajectory")].tolist() if "trajectory" in header else None
    return _split(table[:, cols], ids)


def _parquet(path: Path, joint_names: Sequence[str] | None) -> list[np.ndarray]:
    pq = parquet_module()
    try:
        data = pq.read_table(path)
    except Exception as err:  # pyarrow raises its own ArrowInvalid / OSError variants
        raise InvalidSynergyInput(f"{path}: not a readable Parquet file ({err})", "path") from err
    header = list(data.column_names)
    cols = _select(path, header, joint_names)
    try:
        table = (
            np.column_stack([np.asarray(data.column(i).to_numpy(), dtype=np.float64) for i in cols])
            if cols
            else np.zeros((data.num_rows, 0))
        )
    except (TypeError, ValueError) as err:
        raise InvalidSynergyInput(f"{path}: a joint column is not numeric ({err})", "path") from err
    ids = data.column("trajectory").to_pylist() if "trajectory" in header else None
    return _split(table, ids)


def write_demonstrations(
    path: str | Path, trajectories: Sequence[np.ndarray], joint_names: Sequence[str]
) -> Path:
    """Write trajectories as ``.npz``, ``.csv`` or ``.parquet`` (see the module doc).

    Args:
        path: the file (its suffix picks the format; an existing file is replaced).
        trajectories: each (T_i, n) [rad].
        joint_names: (n,) joint names (the ``q[<joint>]`` columns).

    Returns:
        The path written.

    Raises:
        InvalidSynergyInput: unknown suffix, no trajectory, widths differing from
            ``len(joint_names)``, or pyarrow missing for Parquet.
    """
    p = Path(path)
    trajs = [np.asarray(a, dtype=np.float64) for a in trajectories]
    n = len(joint_names)
    if not trajs or any(a.ndim != 2 or a.shape[1] != n for a in trajs):
        raise InvalidSynergyInput(
            f"trajectories must be (T_i, {n}) arrays for {n} joint names, got"
            f" {[a.shape for a in trajs]}",
            "trajectories",
        )
    suffix = p.suffix.lower()
    ids = np.concatenate([np.full(len(a), i) for i, a in enumerate(trajs)])
    table = np.vstack(trajs)
    names = [f"q[{j}]" for j in joint_names]
    if suffix == ".npz":
        width = len(str(len(trajs) - 1))
        arrays: dict[str, Any] = {f"trajectory_{i:0{width}d}": a for i, a in enumerate(trajs)}
        np.savez(p, **arrays)
    elif suffix == ".csv":
        with p.open("w", encoding="utf-8") as f:
            f.write(",".join(["trajectory", *names]) + "\n")
            np.savetxt(f, np.column_stack([ids, table]), delimiter=",", fmt="%.17g")
    elif suffix == ".parquet":
        pq = parquet_module()
        import pyarrow as pa

        columns = {"trajectory": pa.array(ids.astype(np.int64))}
        columns.update({c: pa.array(table[:, i]) for i, c in enumerate(names)})
        pq.write_table(pa.table(columns), p)
    else:
        raise InvalidSynergyInput(f"{p}: suffix {suffix!r}; allowed: .npz, .csv, .parquet", "path")
    return p


def load_demonstrations(
    path: str | Path, joint_names: Sequence[str] | None = None, *, key: str | None = None
) -> list[np.ndarray]:
    """Trajectories recorded in a file (see the module doc).

    Args:
        path: a ``.npz``, ``.csv`` or ``.parquet`` file.
        joint_names: (n,) joints to read from a CSV or Parquet file (in this order).
        key: the NPZ array to read.

    Returns:
        The trajectories, each (T_i, n) float64 [rad].

    Raises:
        InvalidSynergyInput: missing file, unknown suffix, missing key or column,
            non-numeric or non-finite values, trajectories of different widths, or a
            Parquet file without pyarrow installed (the ``parquet`` extra).
    """
    p = Path(path)
    if not p.is_file():
        raise InvalidSynergyInput(f"demonstrations file {str(p)!r} does not exist", "path")
    suffix = p.suffix.lower()
    if suffix == ".npz":
        with np.load(p) as data:
            if key is not None and key not in data.files:
                raise InvalidSynergyInput(
                    f"{p}: no array {key!r}; arrays: {', '.join(data.files)}", "key"
                )
            names = [key] if key is not None else sorted(data.files)
            trajs = [np.asarray(data[k], dtype=np.float64) for k in names]
        if key is not None and trajs[0].ndim != 2:
            raise InvalidSynergyInput(f"{p}: array {key!r} has shape {trajs[0].shape}", "key")
        trajs = [a for a in trajs if a.ndim == 2]
    elif suffix == ".csv":
        trajs = _csv(p, joint_names)
    elif suffix == ".parquet":
        trajs = _parquet(p, joint_names)
    else:
        raise InvalidSynergyInput(f"{p}: suffix {suffix!r}; allowed: .npz, .csv, .parquet", "path")
    if not trajs or any(a.shape[0] == 0 for a in trajs):
        raise InvalidSynergyInput(f"{p}: no (T, n) trajectory with T >= 1", "path")
    if len({a.shape[1] for a in trajs}) != 1:
        raise InvalidSynergyInput(
            f"{p}: trajectories of different widths {[a.shape[1] for a in trajs]}", "path"
        )
    if not all(np.all(np.isfinite(a)) for a in trajs):
        raise InvalidSynergyInput(f"{p}: non-finite values", "path")
    return trajs
