"""Data out: the closed-loop runs of a run directory as tables with named columns.

Every closed-loop run an experiment stores in ``results.npz`` (under a prefix: the
controller label, or ``{path}_{label}``) is read back as a `geosyn.sim.SimResult` by
`load_runs` (the same loader as `SimResult.load(path, run)`), and written as one CSV per
run, ``data/<run>.csv``, by `write_csv`. Its columns:

- ``t`` [s]; per joint ``q[<joint>]`` [rad], ``v[<joint>]`` [rad/s], ``q_ref[<joint>]``
  [rad], ``tracking_error[<joint>]`` [rad], ``tau_applied[<joint>]`` [N m],
  ``saturated[<joint>]`` (0/1);
- per tick ``kinetic_energy`` [J], ``power`` [W], ``effort`` [N^2 m^2 s] (cumulative),
  ``clearance`` [m], ``contact_force`` [N], ``fallback_used`` (0/1),
  ``payload_mass[<i>]`` [kg];

and its first lines are ``# key: value`` comments: the run, the controller, the robot,
the control period, the status. `load_table` returns every run of a directory as one
tidy pandas table (the ``data`` extra: ``pip install geosyn[data]``): one row per run,
tick and joint, with the run and controller as columns.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import ExperimentError
from geosyn.sim.log import LOG_FIELDS, RUN_META, SimResult, saved_runs

if TYPE_CHECKING:
    import pandas

#: Per-joint columns, (SimResult field, unit).
JOINT_COLUMNS = (
    ("q", "rad"),
    ("v", "rad/s"),
    ("q_ref", "rad"),
    ("tracking_error", "rad"),
    ("tau_applied", "N m"),
    ("saturated", ""),
)
#: Per-tick columns, (SimResult field, unit).
TICK_COLUMNS = (
    ("kinetic_energy", "J"),
    ("power", "W"),
    ("effort", "N^2 m^2 s"),
    ("clearance", "m"),
    ("contact_force", "N"),
    ("fallback_used", ""),
)


#: Most characters of one CSV value: ``%.17g`` of a float64 (``-1.2345678901234567e-308``)
#: and its separator.
CSV_BYTES_PER_VALUE = 25


def log_size(nq: int, nv: int, payloads: int, ticks: int) -> tuple[int, int]:
    """The size of one closed-loop run's per-tick log [bytes]: in memory, and on disk.

    In memory: the simulation's rows (`geosyn.sim.log.LOG_FIELDS`, ``"tick"`` and
    ``"derived"`` fields): 219 B per tick on planar2, 584 B on a 7-DoF arm. Measured (issue
    23, planar2, computed torque, 600 s at 1 kHz): 229 B per tick of resident memory, the
    run's peak 394 MB against 247 MB before it simulates; the CSV is written in blocks and
    adds nothing that grows with the run. On disk: ``data/<run>.csv``, at most
    `CSV_BYTES_PER_VALUE` per value (measured 324 B per tick for planar2's 19 columns,
    17 B per value); ``results.npz`` is compressed and far smaller (3 B per tick there).

    Args:
        nq: joint positions of the robot.
        nv: joint velocities.
        payloads: payloads of the scene.
        ticks: control ticks of the run.

    Returns:
        ``(memory, disk)`` upper estimates [bytes].
    """
    dims = {"nq": nq, "nv": nv, "P": payloads}
    per_tick = 0
    for f in LOG_FIELDS:
        if f.source in ("tick", "derived"):
            n = math.prod(dims[d] for d in f.shape if d != "T")
            per_tick += n * np.dtype(f.dtype).itemsize
    columns = 1 + len(JOINT_COLUMNS) * nv + len(TICK_COLUMNS) + payloads
    return per_tick * ticks, columns * CSV_BYTES_PER_VALUE * ticks


def _results_file(run_dir: str | Path) -> Path:
    path = Path(run_dir)
    path = path / "results.npz" if path.is_dir() else path
    if not path.is_file():
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no results.npz; is it a run directory?"
        )
    return path


def load_runs(run_dir: str | Path) -> dict[str, SimResult]:
    """Every closed-loop run of a run directory (or of its ``results.npz``), by prefix.

    Raises:
        ExperimentError: no results.npz there.
    """
    path = _results_file(run_dir)
    return {run: SimResult.load(path, run) for run in saved_runs(path)}


def controller_of(run: str, labels: list[str]) -> str:
    """The controller label a run prefix ends with (``shaped_qp`` -> ``qp``); the
    longest match wins; the prefix itself when none matches."""
    matches = [lab for lab in labels if run == lab or run.endswith(f"_{lab}")]
    return max(matches, key=len) if matches else run


#: Rows formatted at a time by `write_csv`: a long run's CSV costs this many rows of
#: memory, not a second copy of the run.
CSV_BLOCK = 10_000


def run_columns(res: SimResult) -> dict[str, np.ndarray]:
    """The named columns of one run (see the module doc), each (T,)."""
    arrays = {name: getattr(res, name, None) for name in _CSV_FIELDS}
    return _columns(arrays, res.joint_names)


_CSV_FIELDS = ("t", *(n for n, _ in JOINT_COLUMNS), *(n for n, _ in TICK_COLUMNS), "payload_mass")


def _columns(arrays: Mapping[str, Any], joint_names: Sequence[str]) -> dict[str, np.ndarray]:
    """The named columns (views, no copies) of one run's arrays by `SimResult` field."""
    cols: dict[str, np.ndarray] = {"t": np.asarray(arrays["t"])}
    for name, _unit in JOINT_COLUMNS:
        arr = np.asarray(arrays[name])
        for j, joint in enumerate(joint_names[: arr.shape[1]]):
            cols[f"{name}[{joint}]"] = arr[:, j]
    for name, _unit in TICK_COLUMNS:
        if arrays.get(name) is not None:
            cols[name] = np.asarray(arrays[name])
    mass = np.asarray(arrays.get("payload_mass", np.zeros((0, 0))))
    for i in range(mass.shape[1] if mass.ndim == 2 else 0):
        cols[f"payload_mass[{i}]"] = mass[:, i]
    return cols


def write_csv(
    out_dir: Path, labels: list[str], results: Mapping[str, np.ndarray] | None = None
) -> list[Path]:
    """Write ``data/<run>.csv`` for every closed-loop run of ``out_dir/results.npz``.

    One run at a time, `CSV_BLOCK` rows at a time: the memory it takes does not grow
    with the length of the runs (beyond one run's arrays when read from the file).

    Args:
        out_dir: the run directory (holding results.npz).
        labels: the config's controller labels (for the ``controller`` comment).
        results: the arrays of ``results.npz`` when the caller holds them (the runner):
            read from memory instead of the file (no second copy).

    Returns:
        The files written (none when the experiment has no closed-loop run).
    """
    if results is None:
        with np.load(_results_file(out_dir), allow_pickle=False) as data:
            return _write_runs(out_dir, labels, data)
    return _write_runs(out_dir, labels, results)


def _write_runs(out_dir: Path, labels: list[str], data: Mapping[str, Any]) -> list[Path]:
    runs = [k[: -len(RUN_META)] for k in data if k.endswith(RUN_META) and k != "__meta__"]
    if not runs:
        return []
    folder = out_dir / "data"
    folder.mkdir(exist_ok=True)
    written = []
    for run in runs:
        meta = json.loads(str(data[f"{run}{RUN_META}"]))
        keys = {name: f"{run}__{name}" for name in _CSV_FIELDS}
        arrays = {name: data[key] for name, key in keys.items() if key in data}  # one run
        cols = _columns(arrays, meta["joint_names"])
        header = [
            f"# run: {run}",
            f"# controller: {controller_of(run, labels)}",
            f"# robot: {meta['robot_name']}",
            f"# control_dt [s]: {float(meta['control_dt'])!r}",
            f"# status: {meta['status']}",
            ",".join(cols),
        ]
        path = folder / f"{run}.csv"
        n = len(cols["t"])
        with path.open("w", encoding="utf-8") as f:
            f.write("\n".join(header) + "\n")
            for start in range(0, n, CSV_BLOCK):
                block = [
                    np.asarray(c[start : start + CSV_BLOCK], np.float64) for c in cols.values()
                ]
                np.savetxt(f, np.column_stack(block), delimiter=",", fmt="%.17g")  # round-trips
        written.append(path)
    return written


def load_table(run_dir: str | Path) -> pandas.DataFrame:
    """Every closed-loop run of a run directory as one tidy pandas table.

    One row per (run, tick, joint), columns ``run``, ``controller``, ``t`` [s],
    ``joint``, ``q`` [rad], ``v`` [rad/s], ``q_ref`` [rad], ``tracking_error`` [rad],
    ``tau_applied`` [N m], ``saturated`` (bool), then the per-tick quantities
    ``kinetic_energy`` [J], ``power`` [W], ``effort`` [N^2 m^2 s], ``clearance`` [m],
    ``contact_force`` [N], ``fallback_used`` (bool), repeated on each joint's row.

    Raises:
        ExperimentError: no results.npz, or pandas is not installed.
    """
    try:  # deferred: pandas is the optional 'data' extra
        import pandas as pd
    except ImportError as err:
        raise ExperimentError(
            "load_table needs pandas: pip install 'geosyn[data]' (or read data/*.csv)"
        ) from err
    run_dir = Path(run_dir)
    labels: list[str] = []
    if (run_dir / "config.yaml").is_file():
        labels = load_config(run_dir / "config.yaml", allow_unused=True)[0].controller_labels()
    frames = []
    for run, res in load_runs(run_dir).items():
        T, nv = res.q.shape[0], len(res.joint_names)
        data: dict[str, Any] = {
            "run": np.repeat(run, T * nv),
            "controller": np.repeat(controller_of(run, labels), T * nv),
            "t": np.repeat(res.t, nv),
            "joint": np.tile(np.array(res.joint_names), T),
        }
        for name, _unit in JOINT_COLUMNS:
            data[name] = np.asarray(getattr(res, name))[:, :nv].reshape(-1)
        for name, _unit in TICK_COLUMNS:
            data[name] = np.repeat(np.asarray(getattr(res, name)), nv)
        frames.append(pd.DataFrame(data))
    columns = ["run", "controller", "t", "joint", *(n for n, _ in JOINT_COLUMNS + TICK_COLUMNS)]
    if not frames:
        return pd.DataFrame({c: [] for c in columns})
    return pd.concat(frames, ignore_index=True)


__all__ = [
    "CSV_BLOCK",
    "CSV_BYTES_PER_VALUE",
    "JOINT_COLUMNS",
    "TICK_COLUMNS",
    "controller_of",
    "load_runs",
    "load_table",
    "log_size",
    "run_columns",
    "write_csv",
]
