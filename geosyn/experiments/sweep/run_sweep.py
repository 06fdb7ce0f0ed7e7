"""Sweeps: one experiment over the product of a grid of settings and a number of seeds.

Each run (grid point x seed) writes its own run directory ``<out>/<point>/seed<i>``
through `run_experiment`, atomically, as soon as it finishes; a run directory holding
``summary.json`` is complete. Re-running a sweep into the same directory (an interrupted
one) skips the complete runs and does only the missing ones. Runs execute in-process
(``workers=1``), on local processes (``concurrent.futures.ProcessPoolExecutor``) or on Ray
(``ray_address``: a cluster address, or ``"local"`` to start a local instance; the
``distributed`` extra); see `geosyn.experiments.executors` (workers die with the sweep).
At the end ``sweep_summary.json`` and ``sweep_summary.md`` give, per grid point, the mean
and standard deviation over seeds of every scalar of the runs' ``summary.json`` (metrics
of failed runs, NaN, left out and counted).

Bounds: a sweep of more than ``max_runs`` runs (default `MAX_RUNS`; ``--max-runs``) is
refused before anything runs; the size is announced before the runs start. One sweep at a
time writes a sweep directory (a lock, `geosyn.experiments.rundir`).
"""

from __future__ import annotations

import itertools
import json
import math
import os
import re
import shutil
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml

from geosyn.core.validation import check_int
from geosyn.experiments import rundir
from geosyn.experiments.errors import (
    ConfigError,
    OutputNotWritable,
    RunDirectoryExists,
)
from geosyn.experiments.executors import check_ray_address, run_local, run_ray
from geosyn.experiments.loader import load_config
from geosyn.experiments.report import fmt

#: Default largest number of runs (grid points x seeds) of a sweep; raise with ``max_runs``.
MAX_RUNS = 1000
#: Largest number of local worker processes (or local Ray CPUs).
MAX_WORKERS = 256


class SweepJob(NamedTuple):
    """One run of a sweep: the config source, its overrides, its run directory."""

    source: str
    overrides: tuple[str, ...]
    out: str


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


def point_name(point: dict[str, str]) -> str:
    """Directory name of a grid point, ``key=value__key=value`` with unsafe characters replaced."""
    if not point:
        return "base"
    text = "__".join(f"{k}={v}" for k, v in point.items())
    return re.sub(r"[^A-Za-z0-9_.=,\-]", "_", text)[:200]


def run_job(job: SweepJob) -> tuple[str, dict[str, float]]:
    """Run one sweep job (in this process); returns (run dir, summary)."""
    from geosyn.experiments.runner import run_experiment

    cfg, _ = load_config(job.source, job.overrides)
    outcome = run_experiment(cfg, job.out, progress=False, quiet=True)
    return str(outcome.path), outcome.summary


def _job_by_name(job: SweepJob) -> tuple[str, dict[str, float]]:
    # Looked up at call time so tests can substitute `run_job` (in-process executor).
    return globals()["run_job"](job)


def _is_complete(run_dir: Path) -> bool:
    return (run_dir / "summary.json").is_file()


def aggregate(out: Path, points: Sequence[dict[str, str]], seeds: int) -> list[dict[str, Any]]:
    """Mean and std (over seeds) of each summary scalar, per grid point.

    NaN values (metrics of runs that did not complete, see
    `geosyn.experiments.report.clean_summary`) are left out of the mean and std; ``n`` per
    metric says how many runs entered them, ``n_failed`` per point how many runs had a
    failed (diverged, stopped) controller run.
    """
    rows = []
    for point in points:
        summaries = []
        for s in range(seeds):
            path = out / point_name(point) / f"seed{s}" / "summary.json"
            if path.is_file():
                summaries.append(json.loads(path.read_text()))
        keys = list(dict.fromkeys(k for summ in summaries for k in summ))
        metrics = {}
        for k in keys:
            vals = np.array([float(summ[k]) for summ in summaries if k in summ])
            vals = vals[~np.isnan(vals)]  # NaN: not measured (a failed run), left out
            with np.errstate(invalid="ignore"):  # inf values (never recovered): std is nan
                metrics[k] = {
                    "mean": float(np.mean(vals)) if vals.size else math.nan,
                    "std": float(np.std(vals)) if vals.size else math.nan,
                    "n": int(vals.size),
                }
        n_failed = sum(1 for summ in summaries if float(summ.get("failed_runs", 0.0)) > 0)
        rows.append(
            {"point": point, "n_runs": len(summaries), "n_failed": n_failed, "metrics": metrics}
        )
    return rows


def _write_aggregate(out: Path, name: str, rows: list[dict[str, Any]]) -> None:
    from geosyn.experiments.metrics import unit_of

    (out / "sweep_summary.json").write_text(json.dumps(rows, indent=1, allow_nan=True) + "\n")
    keys = list(dict.fromkeys(k for r in rows for k in r["metrics"]))
    lines = [
        f"# sweep: {name}",
        "",
        "mean ± std over seeds per grid point; runs that failed (diverged, stopped) do not"
        " enter the metrics they did not measure",
        "",
    ]
    lines.append(
        "| metric | "
        + " | ".join(
            point_name(r["point"]) + f" (n={r['n_runs']}, failed={r.get('n_failed', 0)})"
            for r in rows
        )
        + " |"
    )
    lines.append("|---|" + "---|" * len(rows))
    for k in keys:
        cells = []
        for r in rows:
            m = r["metrics"].get(k)
            cells.append("" if m is None else f"{fmt(m['mean'])} ± {fmt(m['std'])}")
        unit = unit_of(k.rsplit(".", 1)[-1])
        lines.append(f"| {k} [{unit}] | " if unit else f"| {k} | ")
        lines[-1] += " | ".join(cells) + " |"
    (out / "sweep_summary.md").write_text("\n".join(lines) + "\n")


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
    n_runs = math.prod(len(v) for v in grid.values()) * seeds
    if n_runs > max_runs:
        raise ConfigError(
            "--grid",
            None,
            f"the sweep has {n_runs} runs ({n_runs // seeds} grid point(s) x {seeds} seed(s)),"
            f" more than the limit of {max_runs}; raise it with --max-runs {n_runs}"
            " (max_runs=) if that is what you want",
        )
    if ray_address is not None:
        ray_address = check_ray_address(ray_address)
    base_cfg, path = load_config(source, overrides)
    path = path.resolve()  # workers (Ray) may run in another directory
    if n_runs > 50:  # validation takes a while: say what is going on
        print(
            f"sweep {base_cfg.name}: {n_runs} run(s) ({n_runs // seeds} grid point(s) x"
            f" {seeds} seed(s)); validating their configs",
            file=sys.stderr,
            flush=True,
        )
    keys = list(grid)
    points = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]
    jobs_all: list[SweepJob] = []
    out = (
        Path(out)
        if out is not None
        else Path("runs") / f"sweep-{base_cfg.name}-{time.strftime('%Y%m%d-%H%M%S', time.gmtime())}"
    )
    out = out.resolve()
    for point in points:
        for s in range(seeds):
            ov = (*overrides, *(f"{k}={v}" for k, v in point.items()), f"seed={base_cfg.seed + s}")
            try:
                load_config(path, ov)  # validate every run before running any
            except ConfigError as err:
                raise ConfigError(
                    err.file, err.field, f"{err.reason} (grid point {point_name(point)})"
                ) from None
            jobs_all.append(SweepJob(str(path), ov, str(out / point_name(point) / f"seed{s}")))
    spec = {
        "source": str(path.resolve()),
        "grid": grid,
        "seeds": seeds,
        "overrides": list(overrides),
    }
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
        # a failed precondition (Ray unreachable, ...) leaves no empty sweep directory
        if (
            created
            and out.is_dir()
            and not any(out.rglob("summary.json"))
            and not any(rundir.is_locked(p.with_name(p.name[1:-5])) for p in out.rglob(".*.lock"))
        ):  # (never while a run, e.g. a Ray task, still writes into it)
            shutil.rmtree(out, ignore_errors=True)
        raise


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
    from geosyn.experiments.runner import _progress

    with _progress(progress) as factory:
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
    _write_aggregate(out, name, rows)
    return SweepResult(out, len(todo), len(jobs_all) - len(todo), rows)


__all__ = ["SweepJob", "SweepResult", "aggregate", "parse_grid", "point_name", "run_job", "sweep"]
