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
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import ExperimentError
from geosyn.sim import log_spool
from geosyn.sim.blocks import row_blocks
from geosyn.sim.log import RUN_META, SimResult, saved_runs
from geosyn.sim.log_spool import row_bytes

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


class LogSize(NamedTuple):
    """What one closed-loop run's per-tick log takes [bytes] (`log_size`).

    Attributes:
        memory: the log rows the simulation holds in memory: the whole run up to
            ``SPOOL_CHUNK`` ticks, one chunk of them for a longer run.
        spool: the spool file of a longer run on disk (0 for a short one), held while the
            run's results are (the file is unlinked when the run ends).
        csv: ``data/<run>.csv``, at most `CSV_BYTES_PER_VALUE` per value.
    """

    memory: int
    spool: int
    csv: int


def log_size(nq: int, nv: int, payloads: int, ticks: int) -> LogSize:
    """The size of one closed-loop run's per-tick log [bytes]: in memory, and on disk.

    The rows are the tick and derived fields of `geosyn.sim.log.LOG_FIELDS`
    (`geosyn.sim.log_spool.row_bytes`): 219 B per tick on planar2, 584 B on a 7-DoF arm. A
    run of at most ``SPOOL_CHUNK`` (8,192) ticks holds them in memory; a longer one holds
    one chunk (1.8 MB on planar2, 4.8 MB on a 7-DoF arm) and spools the rest to disk at the
    same bytes per tick, and every writer of its outputs reads it a block at a time.
    Measured (issue 23, ``geosyn run``, planar2, computed torque at 1 kHz; kernel peak
    RSS): 259 MB for 60 s and 259 MB for 600 s (before spooling: 270 and 394 MB, 229 B per
    tick of resident memory), so memory no longer grows with the run; the spool takes
    219 B per tick of disk while the run's results are held. The CSV: measured 324 B per
    tick for planar2's 19 columns (17 B per value); ``results.npz`` is compressed and far
    smaller (3 B per tick there).

    Args:
        nq: joint positions of the robot.
        nv: joint velocities.
        payloads: payloads of the scene.
        ticks: control ticks of the run.

    Returns:
        ``(memory, spool, csv)`` upper estimates [bytes].
    """
    per_tick = row_bytes({"nq": nq, "nv": nv, "P": payloads})
    columns = 1 + len(JOINT_COLUMNS) * nv + len(TICK_COLUMNS) + payloads
    spooled = ticks > log_spool.SPOOL_CHUNK
    return LogSize(
        memory=per_tick * min(ticks, log_spool.SPOOL_CHUNK),
        spool=per_tick * ticks if spooled else 0,
        csv=columns * CSV_BYTES_PER_VALUE * ticks,
    )


def results_file(run_dir: str | Path) -> Path:
    """The ``results.npz`` of a run directory (or the file itself).

    Raises:
        ExperimentError: there is none.
    """
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
    path = results_file(run_dir)
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
    with the length of the runs (beyond one run's arrays when read from the file; a
    spooled run's arrays held by the caller are read a block at a time, their pages
    released after each, `geosyn.sim.blocks.row_blocks`).

    Args:
        out_dir: the run directory (holding results.npz).
        labels: the config's controller labels (for the ``controller`` comment).
        results: the arrays of ``results.npz`` when the caller holds them (the runner):
            read from memory instead of the file (no second copy).

    Returns:
        The files written (none when the experiment has no closed-loop run).
    """
    if results is None:
        with np.load(results_file(out_dir), allow_pickle=False) as data:
            return _write_runs(out_dir, labels, data)
    return _write_runs(out_dir, labels, results)


def stored_run_columns(
    data: Mapping[str, Any],
) -> Iterator[tuple[str, dict[str, Any], dict[str, np.ndarray], list[Any]]]:
    """Each closed-loop run stored in ``data`` (the arrays of a ``results.npz``): its
    prefix, metadata (`geosyn.sim.SimResult.metadata_json`), named columns (views, see
    the module doc) and the arrays they view (to `geosyn.sim.blocks.release`)."""
    runs = [k[: -len(RUN_META)] for k in data if k.endswith(RUN_META) and k != "__meta__"]
    for run in runs:
        meta = json.loads(str(data[f"{run}{RUN_META}"]))
        keys = {name: f"{run}__{name}" for name in _CSV_FIELDS}
        arrays = {name: data[key] for name, key in keys.items() if key in data}  # one run
        yield run, meta, _columns(arrays, meta["joint_names"]), list(arrays.values())


def _write_runs(out_dir: Path, labels: list[str], data: Mapping[str, Any]) -> list[Path]:
    written = []
    for run, meta, cols, arrays in stored_run_columns(data):
        folder = out_dir / "data"
        folder.mkdir(exist_ok=True)
        header = [
            f"# run: {run}",
            f"# controller: {controller_of(run, labels)}",
            f"# robot: {meta['robot_name']}",
            f"# control_dt [s]: {float(meta['control_dt'])!r}",
            f"# status: {meta['status']}",
            ",".join(cols),
        ]
        path = folder / f"{run}.csv"
        line = ",".join(["%.17g"] * len(cols)) + "\n"  # round-trips float64
        with path.open("w", encoding="utf-8") as f:
            f.write("\n".join(header) + "\n")
            # a spooled log's pages are released after each block (geosyn.sim.blocks)
            for rows in row_blocks(len(cols["t"]), *arrays, size=CSV_BLOCK):
                block = np.column_stack([np.asarray(c[rows], np.float64) for c in cols.values()])
                # np.savetxt's text, formatted from Python floats: ~25 % less time
                f.write("".join(line % tuple(r) for r in block.tolist()))
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
    "LogSize",
    "TICK_COLUMNS",
    "controller_of",
    "load_runs",
    "load_table",
    "log_size",
    "results_file",
    "run_columns",
    "stored_run_columns",
    "write_csv",
]
