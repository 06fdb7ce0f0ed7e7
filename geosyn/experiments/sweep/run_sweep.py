"""Sweeps: one experiment over the product of a grid of settings and a number of seeds.

Each run (grid point x seed) writes its own run directory ``<out>/<point>/seed<i>``
through `run_experiment`, atomically, as soon as it finishes; a run directory holding
``summary.json`` is complete. Re-running a sweep into the same directory (an interrupted
one) skips the complete runs and does only the missing ones. Runs execute in-process
(``workers=1``), on local processes (``concurrent.futures.ProcessPoolExecutor``) or on Ray
(``ray_address``: a cluster address, or ``"local"`` to start a local instance; the
``distributed`` extra); see `geosyn.experiments.sweep.executors` (workers die with the sweep).
At the end ``sweep_summary.json`` and ``sweep_summary.md`` give, per grid point, the mean
and standard deviation over seeds of every scalar of the runs' ``summary.json`` (metrics
of failed runs, NaN, left out and counted).

Bounds: a sweep of more than ``max_runs`` runs (default `MAX_RUNS`; ``--max-runs``) is
refused before anything runs; the size is announced before the runs start. One sweep at a
time writes a sweep directory (a lock, `geosyn.experiments.run.rundir`).
"""

from __future__ import annotations

import itertools
import math
import os
import shutil
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import yaml

from geosyn.core.validation import check_int
from geosyn.experiments.config import chatter
from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import (
    ConfigError,
    OutputNotWritable,
    RunDirectoryExists,
)
from geosyn.experiments.results.aggregate import aggregate, point_name, write_aggregate
from geosyn.experiments.run import rundir
from geosyn.experiments.run.progress import progress_bars
from geosyn.experiments.run.runner import run_experiment
from geosyn.experiments.sweep.executors import check_ray_address, run_local, run_ray

#: Default largest number of runs (grid points x seeds) of a sweep; raise with ``max_runs``.
MAX_RUNS = 1000
#: Largest number of local worker processes (or local Ray CPUs).
MAX_WORKERS = 256


class SweepJob(NamedTuple):
    """One run of a sweep: the config source, its overrides, its run directory, and
    whether sections its kind does not read are allowed (``--allow-unused``)."""

    source: str
    overrides: tuple[str, ...]
    out: str
    allow_unused: bool = False


class SweepResult(NamedTuple):
    """Result of `sweep`.

    Attributes:
        path: the sweep directory.
        ran: runs executed by this call.
        skipped: runs already complete before this call.
        aggregate: per grid point ``{"point": {...}, "n_runs": int, "metrics": {key:
            {"mean": float, "std": float}}}``.
    """

    path: Path
    ran: int
    skipped: int
    aggregate: list[dict[str, Any]]


def _split_values(text: str) -> list[str]:
    """Split ``v1,v2`` at top-level commas (``[1,2],[3,4]`` gives two values)."""
    out, depth, cur = [], 0, ""
    for ch in text:
        if ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    out.append(cur)
    return [v.strip() for v in out]


def parse_grid(items: Iterable[str]) -> dict[str, list[str]]:
    """``["key=v1,v2", ...]`` to ``{key: [v1, v2]}`` (values stay text; YAML-parsed later).

    Raises:
        ConfigError: no ``=``, an empty key or value, or a key given twice (file
            ``--grid``, field the item).
    """
    grid: dict[str, list[str]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        key = key.strip()
        vals = _split_values(values) if sep else []
        if not sep or not key or not vals or any(v == "" for v in vals):
            raise ConfigError(
                "--grid", item, "expected key.path=v1,v2,... (e.g. controllers.0.kp=100,400)"
            )
        if key in grid:
            raise ConfigError("--grid", key, "is given twice")
        grid[key] = vals
    return grid


def run_job(job: SweepJob) -> tuple[str, dict[str, float]]:
    """Run one sweep job (in this process); returns (run dir, summary). MuJoCo's warnings
    go to the run directory's ``MUJOCO_LOG.TXT`` (never the worker's current directory)."""
    with chatter.mujoco_warnings() as texts:
        cfg, _ = load_config(job.source, job.overrides, allow_unused=job.allow_unused)
        outcome = run_experiment(cfg, job.out, progress=False, quiet=True)
    chatter.append_mujoco_log(outcome.path, texts)
    return str(outcome.path), outcome.summary


def _job_by_name(job: SweepJob) -> tuple[str, dict[str, float]]:
    # Looked up at call time so tests can substitute `run_job` (in-process executor).
    return globals()["run_job"](job)


def _is_complete(run_dir: Path) -> bool:
    return (run_dir / "summary.json").is_file()


def sweep(
    source: str | Path,
    grid: dict[str, list[str]],
    *,
    seeds: int = 1,
    out: str | Path | None = None,
    workers: int | None = None,
    ray_address: str | None = None,
    overrides: Sequence[str] = (),
    progress: bool = True,
    max_runs: int = MAX_RUNS,
    allow_unused: bool = False,
) -> SweepResult:
    """Run (or complete) a sweep; see the module doc.

    Args:
        source: built-in experiment name or YAML file.
        grid: swept field paths and their values (text, parsed as YAML like ``--set``).
        seeds: runs per grid point, with seeds ``seed, seed + 1, ...`` (config seed first).
        out: sweep directory; default ``runs/sweep-<name>-<timestamp>``. An existing sweep
            directory of the same sweep is completed; of another sweep, refused.
        workers: local worker processes, >= 1 (default 1: in this process); with
            ``ray_address="local"`` the CPUs of the local Ray instance (default: all).
        ray_address: run on Ray at this address (``"local"``: start one here).
        overrides: ``key=value`` overrides applied to every run before the grid values.
        progress: show a progress bar.
        allow_unused: run even if the config sets sections its kind does not read.
        max_runs: refuse a sweep of more runs (grid points x seeds) than this, before
            anything runs; default `MAX_RUNS`.

    Returns:
        The `SweepResult`.

    Raises:
        InvalidArgument: ``seeds``, ``max_runs`` or ``workers`` is not an integer >= 1
            (``workers`` <= `MAX_WORKERS`).
        ConfigError: a grid point's config does not validate (checked before any run),
            more than ``max_runs`` runs, or a malformed or unreachable ``ray_address``.
        RunDirectoryExists: ``out`` holds another sweep, is not a sweep directory, or
            another process is running a sweep into it.
        OutputNotWritable: ``out`` cannot be written (disk full, read-only, ...).
        ProcedureFailed: a run failed.
    """
    seeds = check_int(seeds, "seeds", low=1)
    max_runs = check_int(max_runs, "max_runs", low=1)
    if workers is None:
        workers = (os.cpu_count() or 1) if ray_address == "local" else 1
    workers = check_int(workers, "workers", low=1, high=MAX_WORKERS)
    _check_size(grid, seeds, max_runs)
    if ray_address is not None:
        ray_address = check_ray_address(ray_address)
    base_cfg, path = load_config(source, overrides, allow_unused=allow_unused)
    path = path.resolve()  # workers (Ray) may run in another directory
    keys = list(grid)
    points = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
        out = Path("runs") / f"sweep-{base_cfg.name}-{stamp}"
    out = Path(out).resolve()
    jobs_all = _validated_jobs(
        path, base_cfg.name, base_cfg.seed, points, seeds, overrides, out, allow_unused
    )
    spec = {"source": str(path), "grid": grid, "seeds": seeds, "overrides": list(overrides)}
    if allow_unused:  # (only when set: older sweep directories stay the same sweep)
        spec["allow_unused"] = True
    created = not out.exists()
    try:
        with rundir.claim(out, force=True):  # one sweep at a time into ``out``
            try:
                return _sweep_claimed(
                    out,
                    spec,
                    points,
                    seeds,
                    jobs_all,
                    base_cfg.name,
                    workers,
                    ray_address,
                    progress,
                )
            except OSError as err:
                if err.errno in rundir.WRITE_ERRNOS:
                    raise OutputNotWritable(out, err) from err
                raise
    except BaseException:
        if created:  # a failed precondition (Ray unreachable, ...) leaves no empty directory
            _remove_if_empty(out)
        raise


def _check_size(grid: dict[str, list[str]], seeds: int, max_runs: int) -> None:
    """Refuse a sweep of more than ``max_runs`` runs (`ConfigError` naming ``--max-runs``)."""
    n_runs = math.prod(len(v) for v in grid.values()) * seeds
    if n_runs > max_runs:
        raise ConfigError(
            "--grid",
            None,
            f"the sweep has {n_runs} runs ({n_runs // seeds} grid point(s) x {seeds} seed(s)),"
            f" more than the limit of {max_runs}; raise it with --max-runs {n_runs}"
            " (max_runs=) if that is what you want",
        )


def _validated_jobs(
    path: Path,
    name: str,
    seed: int,
    points: list[dict[str, str]],
    seeds: int,
    overrides: Sequence[str],
    out: Path,
    allow_unused: bool = False,
) -> list[SweepJob]:
    """One `SweepJob` per grid point and seed, each config validated before any runs.

    Raises:
        ConfigError: a run's config does not validate (the grid point named).
    """
    n_runs = len(points) * seeds
    if n_runs > 50:  # validation takes a while: say what is going on
        print(
            f"sweep {name}: {n_runs} run(s) ({len(points)} grid point(s) x"
            f" {seeds} seed(s)); validating their configs",
            file=sys.stderr,
            flush=True,
        )
    jobs: list[SweepJob] = []
    for point in points:
        for s in range(seeds):
            ov = (*overrides, *(f"{k}={v}" for k, v in point.items()), f"seed={seed + s}")
            try:
                load_config(path, ov, allow_unused=allow_unused)  # validate all before any
            except ConfigError as err:
                raise ConfigError(
                    err.file, err.field, f"{err.reason} (grid point {point_name(point)})"
                ) from None
            run_dir = str(out / point_name(point) / f"seed{s}")
            jobs.append(SweepJob(str(path), ov, run_dir, allow_unused))
    return jobs


def _remove_if_empty(out: Path) -> None:
    """Remove a sweep directory this call created when no run completed in it and no run
    (e.g. a Ray task) still writes into it."""
    if (
        out.is_dir()
        and not any(out.rglob("summary.json"))
        and not any(rundir.is_locked(p.with_name(p.name[1:-5])) for p in out.rglob(".*.lock"))
    ):
        shutil.rmtree(out, ignore_errors=True)


def _remove_partials(run_dir: Path) -> None:
    """Remove the temporary directories a killed writer left for ``run_dir``."""
    for stale in run_dir.parent.glob(f".{run_dir.name}.partial-*"):
        shutil.rmtree(stale, ignore_errors=True)


def _sweep_claimed(
    out: Path,
    spec: dict[str, Any],
    points: list[dict[str, str]],
    seeds: int,
    jobs_all: list[SweepJob],
    name: str,
    workers: int,
    ray_address: str | None,
    progress: bool,
) -> SweepResult:
    """`sweep` once ``out`` is claimed: check it, run the missing runs, aggregate."""
    spec_file = out / "sweep.yaml"
    if spec_file.is_file():
        old = yaml.safe_load(spec_file.read_text())
        if old != spec:
            raise RunDirectoryExists(
                out, "holds a different sweep (see its sweep.yaml); choose another --out"
            )
    elif out.exists() and any(out.iterdir()):
        raise RunDirectoryExists(out, "exists and is not a sweep directory; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    spec_file.write_text(yaml.safe_dump(spec, sort_keys=False))
    todo = []
    for job in jobs_all:
        run_dir = Path(job.out)
        if rundir.is_locked(run_dir):  # e.g. a worker of a killed sweep still running
            raise RunDirectoryExists(
                run_dir, "is still being written by another process; wait for it and re-run"
            )
        _remove_partials(run_dir)
        if not _is_complete(run_dir):
            if run_dir.exists():
                shutil.rmtree(run_dir)
            todo.append(job)
    if progress or todo:
        print(
            f"sweep {name}: running {len(todo)} of {len(jobs_all)} run(s) ({len(points)} grid"
            f" point(s) x {seeds} seed(s); {len(jobs_all) - len(todo)} already complete)",
            file=sys.stderr,
            flush=True,
        )
    with progress_bars(progress) as factory:
        advance = factory(f"sweep {name}", len(todo))
        try:
            if ray_address is not None:
                run_ray(todo, ray_address, workers, advance, run_job)
            else:
                run_local(todo, workers, advance, _job_by_name)
        except BaseException:
            # a stopped sweep's workers are dead by now (SIGTERM, then SIGKILL after a
            # grace); one killed inside a native call could not remove its partial run
            if ray_address is None:
                for job in todo:
                    if not rundir.is_locked(Path(job.out)):
                        _remove_partials(Path(job.out))
            raise
    rows = aggregate(out, points, seeds)
    write_aggregate(out, name, rows)
    return SweepResult(out, len(todo), len(jobs_all) - len(todo), rows)


__all__ = ["MAX_RUNS", "MAX_WORKERS", "SweepJob", "SweepResult", "parse_grid", "run_job", "sweep"]
