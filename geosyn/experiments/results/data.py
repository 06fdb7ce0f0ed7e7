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

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import ExperimentError
from geosyn.sim.log import SimResult, saved_runs

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


def run_columns(res: SimResult) -> dict[str, np.ndarray]:
    """The named columns of one run (see the module doc), each (T,)."""
    cols: dict[str, np.ndarray] = {"t": np.asarray(res.t)}
    for name, _unit in JOINT_COLUMNS:
        arr = np.asarray(getattr(res, name))
        for j, joint in enumerate(res.joint_names[: arr.shape[1]]):
            cols[f"{name}[{joint}]"] = arr[:, j]
    for name, _unit in TICK_COLUMNS:
        if getattr(res, name, None) is not None:
            cols[name] = np.asarray(getattr(res, name))
    mass = np.asarray(res.payload_mass)
    for i in range(mass.shape[1] if mass.ndim == 2 else 0):
        cols[f"payload_mass[{i}]"] = mass[:, i]
    return cols


def write_csv(out_dir: Path, labels: list[str]) -> list[Path]:
    """Write ``data/<run>.csv`` for every closed-loop run of ``out_dir/results.npz``.

    Args:
        out_dir: the run directory (holding results.npz).
        labels: the config's controller labels (for the ``controller`` comment).

    Returns:
        The files written (none when the experiment has no closed-loop run).
    """
    runs = load_runs(out_dir)
    if not runs:
        return []
    folder = out_dir / "data"
    folder.mkdir(exist_ok=True)
    written = []
    for run, res in runs.items():
        cols = run_columns(res)
        header = [
            f"# run: {run}",
            f"# controller: {controller_of(run, labels)}",
            f"# robot: {res.robot_name}",
            f"# control_dt [s]: {res.control_dt!r}",
            f"# status: {res.status}",
            ",".join(cols),
        ]
        table = np.column_stack([np.asarray(c, dtype=np.float64) for c in cols.values()])
        path = folder / f"{run}.csv"
        with path.open("w", encoding="utf-8") as f:
            f.write("\n".join(header) + "\n")
            np.savetxt(f, table, delimiter=",", fmt="%.17g")  # round-trips float64
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
    "JOINT_COLUMNS",
    "TICK_COLUMNS",
    "controller_of",
    "load_runs",
    "load_table",
    "run_columns",
    "write_csv",
]
