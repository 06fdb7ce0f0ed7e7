"""Recorded trajectories as demonstrations for PGA/PCA: NPZ and CSV files.

- NPZ: with ``key``, that array, (T, n), is one trajectory; without, every 2-D array of
  the file is one (in key order; 1-D arrays such as time stamps are skipped).
- CSV: ``#`` comment lines, then a header of column names, then rows. With
  ``joint_names``, the columns are ``q[<joint>]`` (geosyn's run CSV, `write_csv` of
  ``geosyn.experiments.results.data``) or ``<joint>``, taken in that order; without, every
  ``q[...]`` column, else every column except ``t`` and ``trajectory``. An optional
  ``trajectory`` column splits the rows into trajectories (one per distinct value, in
  order of appearance).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from geosyn.synergies.errors import InvalidSynergyInput


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
    if joint_names is not None:
        cols = []
        for j in joint_names:
            hit = [c for c in (f"q[{j}]", j) if c in header]
            if not hit:
                raise InvalidSynergyInput(
                    f"{path}: no column 'q[{j}]' or '{j}'; columns: {', '.join(header)}", "path"
                )
            cols.append(header.index(hit[0]))
    else:
        cols = [i for i, h in enumerate(header) if h.startswith("q[")] or [
            i for i, h in enumerate(header) if h not in ("t", "trajectory")
        ]
    if "trajectory" not in header:
        return [table[:, cols]]
    ids = table[:, header.index("trajectory")]
    return [table[ids == v][:, cols] for v in dict.fromkeys(ids.tolist())]


def load_demonstrations(
    path: str | Path, joint_names: Sequence[str] | None = None, *, key: str | None = None
) -> list[np.ndarray]:
    """Trajectories recorded in a file (see the module doc).

    Args:
        path: a ``.npz`` or ``.csv`` file.
        joint_names: (n,) joints to read from a CSV (in this order).
        key: the NPZ array to read.

    Returns:
        The trajectories, each (T_i, n) float64 [rad].

    Raises:
        InvalidSynergyInput: missing file, unknown suffix, missing key or column,
            non-numeric or non-finite values, or trajectories of different widths.
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
    else:
        raise InvalidSynergyInput(f"{p}: suffix {suffix!r}; allowed: .npz, .csv", "path")
    if not trajs or any(a.shape[0] == 0 for a in trajs):
        raise InvalidSynergyInput(f"{p}: no (T, n) trajectory with T >= 1", "path")
    if len({a.shape[1] for a in trajs}) != 1:
        raise InvalidSynergyInput(
            f"{p}: trajectories of different widths {[a.shape[1] for a in trajs]}", "path"
        )
    if not all(np.all(np.isfinite(a)) for a in trajs):
        raise InvalidSynergyInput(f"{p}: non-finite values", "path")
    return trajs
