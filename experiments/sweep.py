"""Sweeps: one experiment over the product of a grid of settings and a number of seeds.

Each run (grid point x seed) writes its own run directory ``<out>/<point>/seed<i>``
through `run_experiment`, atomically, as soon as it finishes; a run directory holding
``summary.json`` is complete. Re-running a sweep into the same directory (an interrupted
one) skips the complete runs and does only the missing ones. Runs execute in-process
(``workers=1``), on local processes (``concurrent.futures.ProcessPoolExecutor``) or on Ray
(``ray_address``: a cluster address, or ``"local"`` to start a local instance; the
``distributed`` extra). At the end ``sweep_summary.json`` and ``sweep_summary.md`` give,
per grid point, the mean and standard deviation over seeds of every scalar of the runs'
``summary.json``.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shutil
import sys
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml

from geosyn.core.errors import GeosynError
from geosyn.core.validation import check_int
from geosyn.experiments import termination
from geosyn.experiments.errors import ConfigError, ProcedureFailed, RunDirectoryExists
from geosyn.experiments.loader import load_config
from geosyn.experiments.report import fmt


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


def _run_local(jobs: Sequence[SweepJob], workers: int, advance: Any) -> None:
    if workers == 1:
        for job in jobs:
            termination.raise_if_terminated()
            _job_by_name(job)
            advance()
        return
    import multiprocessing

    # Linux: fork, so workers inherit the already imported pinocchio/casadi/mujoco (a
    # forkserver re-imports them in every sweep; the speed-ups are in benchmarks/RESULTS.md).
    # Workers only run experiments and never use the parent's progress thread. Elsewhere:
    # a forkserver that preloads geosyn.
    if sys.platform.startswith("linux"):
        ctx = multiprocessing.get_context("fork")
    else:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["geosyn.experiments.sweep", "geosyn.experiments.procedures"])
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        pending = {pool.submit(run_job, job): job for job in jobs}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                termination.raise_if_terminated()
                for fut in done:
                    job = pending.pop(fut)
                    try:
                        fut.result()
                    except GeosynError as err:
                        raise ProcedureFailed(
                            f"run {job.out!r} failed: {type(err).__name__}: {err}"
                        ) from err
                    advance()
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise


def _run_ray(jobs: Sequence[SweepJob], address: str, workers: int, advance: Any) -> None:
    try:
        import ray
    except ImportError as err:
        raise ConfigError(
            "--ray", address, "needs the 'distributed' extra: pip install 'geosyn[distributed]'"
        ) from err
    started = False
    if not ray.is_initialized():
        if address == "local":
            ray.init(num_cpus=max(workers, 1), include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_job)
        refs = {remote.remote(job): job for job in jobs}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    ray.get(ref)
                except Exception as err:
                    for p in pending:
                        ray.cancel(p)
                    raise ProcedureFailed(
                        f"run {refs[ref].out!r} failed on Ray: {err}".splitlines()[0]
                    ) from err
                advance()
    finally:
        if started:
            ray.shutdown()


def aggregate(out: Path, points: Sequence[dict[str, str]], seeds: int) -> list[dict[str, Any]]:
    """Mean and std (over seeds) of each summary scalar, per grid point."""
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
            with np.errstate(invalid="ignore"):  # inf values (never recovered): std is nan
                metrics[k] = {"mean": float(np.mean(vals)), "std": float(np.std(vals))}
        rows.append({"point": point, "n_runs": len(summaries), "metrics": metrics})
    return rows


def _write_aggregate(out: Path, name: str, rows: list[dict[str, Any]]) -> None:
    (out / "sweep_summary.json").write_text(json.dumps(rows, indent=1, allow_nan=True) + "\n")
    keys = list(dict.fromkeys(k for r in rows for k in r["metrics"]))
    lines = [f"# sweep: {name}", "", "mean ± std over seeds per grid point", ""]
    lines.append(
        "| metric | "
        + " | ".join(point_name(r["point"]) + f" (n={r['n_runs']})" for r in rows)
        + " |"
    )
    lines.append("|---|" + "---|" * len(rows))
    for k in keys:
        cells = []
        for r in rows:
            m = r["metrics"].get(k)
            cells.append("" if m is None else f"{fmt(m['mean'])} ± {fmt(m['std'])}")
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
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

    Returns:
        The `SweepResult`.

    Raises:
        InvalidArgument: ``seeds`` or ``workers`` is not an integer >= 1.
        ConfigError: a grid point's config does not validate (checked before any run).
        RunDirectoryExists: ``out`` holds another sweep or is not a sweep directory.
        ProcedureFailed: a run failed.
    """
    seeds = check_int(seeds, "seeds", low=1)
    if workers is None:
        workers = (os.cpu_count() or 1) if ray_address == "local" else 1
    workers = check_int(workers, "workers", low=1)
    base_cfg, path = load_config(source, overrides)
    path = path.resolve()  # workers (Ray) may run in another directory
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
        for stale in run_dir.parent.glob(f".{run_dir.name}.partial-*"):
            shutil.rmtree(stale, ignore_errors=True)  # left by a killed run
        if not _is_complete(run_dir):
            if run_dir.exists():
                shutil.rmtree(run_dir)
            todo.append(job)
    from geosyn.experiments.runner import _progress

    with _progress(progress) as factory:
        advance = factory(f"sweep {base_cfg.name}", len(todo))
        if ray_address is not None:
            _run_ray(todo, ray_address, workers, advance)
        else:
            _run_local(todo, workers, advance)
    rows = aggregate(out, points, seeds)
    _write_aggregate(out, base_cfg.name, rows)
    return SweepResult(out, len(todo), len(jobs_all) - len(todo), rows)


__all__ = ["SweepJob", "SweepResult", "aggregate", "parse_grid", "point_name", "run_job", "sweep"]
