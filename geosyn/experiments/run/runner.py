"""Running one experiment into a run directory.

The directory is created only after the config validated, and atomically: everything is
written into a hidden temporary directory next to the target, which is renamed at the
end; on any failure the temporary directory is removed, so a failed run leaves nothing.
The target is claimed first (`geosyn.experiments.run.rundir`: a lock held for the whole run),
so a second writer to the same directory fails at once; an existing run directory is
never overwritten unless ``force=True``, and never while another process writes it.

Files of a run: ``config.yaml`` (the resolved config, after ``--set``), ``results.npz``
(the procedure's arrays), ``data/<run>.csv`` (each closed-loop run with named columns,
`geosyn.experiments.results.data`), ``run.log`` (what happened, warnings included), PNG plots,
optional videos, ``run.json`` (timing, versions, geosyn version and git commit),
``summary.md`` and ``summary.json`` (written last: its presence marks a complete run).
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import sys
import time
import uuid
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np
import pinocchio

from geosyn.experiments.config.loader import dump_config
from geosyn.experiments.errors import OutputNotWritable, RunDirectoryExists
from geosyn.experiments.procedures import PROCEDURES
from geosyn.experiments.procedures.base import Procedure, RunContext, ignored_sections
from geosyn.experiments.results.data import write_csv
from geosyn.experiments.results.parquet import write_parquet
from geosyn.experiments.results.run_video import write_videos
from geosyn.experiments.results.summary import clean_summary, print_summary, write_summary
from geosyn.experiments.run import rundir, termination
from geosyn.experiments.run.progress import progress_bars
from geosyn.experiments.run.runlog import RunLog, geosyn_version, git_commit
from geosyn.experiments.run.scene import build_run_scene
from geosyn.experiments.schema import ExperimentConfig
from geosyn.sim.blocks import save_npz
from geosyn.sim.log import RUN_META
from geosyn.sim.log_spool import spool_directory


class RunOutcome(NamedTuple):
    """Result of `run_experiment`.

    Attributes:
        path: the run directory.
        summary: the flat scalar summary (as in summary.json).
        wall_time: wall time of the run [s].
    """

    path: Path
    summary: dict[str, float]
    wall_time: float


def default_run_dir(cfg: ExperimentConfig, root: str | Path = "runs") -> Path:
    """``<root>/<name>-<UTC timestamp>``, with ``-2``, ``-3``, ... if that exists already."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    path = Path(root) / f"{cfg.name}-{stamp}"
    i = 2
    while path.exists() or rundir.lock_path(path).exists():  # taken, or being written
        path = Path(root) / f"{cfg.name}-{stamp}-{i}"
        i += 1
    return path


def _versions() -> dict[str, str]:
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
        "pinocchio": pinocchio.__version__,
    }


def _run_statuses(results: dict[str, Any]) -> dict[str, str]:
    """Status of each closed-loop run stored in ``results`` (``ok``, ``diverged: ...``)."""
    tail = "__status"
    return {k[: -len(tail)]: str(v) for k, v in results.items() if k.endswith(tail)}


def _run_notes(results: dict[str, Any], run: str) -> list[str]:
    """The notes stored with closed-loop run ``run``: its controller's
    (`SimResult.controller_notes`) and how its exact clearance was measured."""
    meta = results.get(f"{run}{RUN_META}")
    if meta is None:
        return []
    meta = json.loads(str(meta))
    notes = [f"controller note {n}" for n in meta.get("controller_notes", [])]
    mesh = meta.get("mesh_clearance_note", "")
    return notes + ([f"exact clearance on the robot file's geometry: {mesh}"] if mesh else [])


def run_experiment(
    cfg: ExperimentConfig,
    out: str | Path | None = None,
    *,
    force: bool = False,
    video: bool = False,
    progress: bool = True,
    quiet: bool = False,
) -> RunOutcome:
    """Run a validated experiment and write its run directory.

    Args:
        cfg: the validated config (see `geosyn.experiments.config.loader.load_config`).
        out: the run directory; default ``runs/<name>-<timestamp>``.
        force: replace an existing ``out``.
        video: render videos (also on with ``outputs.video``).
        progress: show progress bars.
        quiet: do not print the summary table.

    Returns:
        The `RunOutcome`.

    Raises:
        RunDirectoryExists: ``out`` exists and ``force`` is False, is a file, or another
            process is writing it (see `geosyn.experiments.run.rundir`; ``force`` never
            replaces a directory being written).
        OutputNotWritable: disk full, read-only or no permission (nothing is left on disk).
        GeosynError: the procedure failed (nothing is left on disk).
    """
    if out is not None:
        with rundir.claim(Path(out), force):
            return _run_claimed(cfg, Path(out), video, progress, quiet)
    for _ in range(100):  # default name: the next free one (-2, -3, ...) if two runs race
        path = default_run_dir(cfg)
        try:
            with rundir.claim(path, False):
                return _run_claimed(cfg, path, video, progress, quiet)
        except RunDirectoryExists as err:
            if err.path != path:
                raise
    raise RunDirectoryExists(path, "and 99 other default names are taken; pass --out")


def _run_claimed(
    cfg: ExperimentConfig, out: Path, video: bool, progress: bool, quiet: bool
) -> RunOutcome:
    """`run_experiment` once ``out`` is claimed (see `geosyn.experiments.run.rundir`): run
    into a temporary directory, then commit it as ``out`` (removed on any failure)."""
    tmp = out.parent / f".{out.name}.partial-{uuid.uuid4().hex[:8]}"
    try:
        tmp.mkdir()
    except OSError as err:
        raise OutputNotWritable(out, err) from err
    with termination.guarded(tmp, rundir.lock_path(out)):
        return _run_into(cfg, out, tmp, video, progress, quiet)


def _run_into(
    cfg: ExperimentConfig, out: Path, tmp: Path, video: bool, progress: bool, quiet: bool
) -> RunOutcome:
    """`_run_claimed` once ``tmp`` exists: run into it and commit it as ``out``."""
    t0 = time.perf_counter()
    started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    try:
        if video and not cfg.outputs.video:  # the saved config says what was rendered
            cfg = cfg.model_copy(update={"outputs": cfg.outputs.model_copy(update={"video": True})})
        proc = PROCEDURES[cfg.kind]()
        params = proc.Params.model_validate(cfg.params)
        log = _start_log(cfg, proc, tmp, out)
        with progress_bars(progress) as factory:
            with log.warnings(), spool_directory(tmp):  # long runs' logs: in the run dir
                # the scene inside the log's warnings too (a scene file's enclosed geoms)
                ctx = RunContext(cfg, params, build_run_scene(cfg), tmp, cfg.outputs.video,
                                 factory)  # fmt: skip
                results = proc.run(ctx)
        summary, videos = _write_results(ctx, proc, results, log)
        wall = time.perf_counter() - t0
        _write_run_json(tmp, cfg, started, wall, videos)
        write_summary(tmp, cfg.name, cfg.description, summary, proc.units)
        log.write(f"finished in {wall:.2f} s; {len(summary)} summary values")
        termination.raise_if_terminated()  # never commit a run whose SIGTERM was swallowed
        rundir.commit(tmp, out)
    except OSError as err:
        shutil.rmtree(tmp, ignore_errors=True)
        if err.errno in rundir.WRITE_ERRNOS:  # disk full, read-only, ...: one line
            raise OutputNotWritable(out, err) from err
        raise
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _tell(cfg, proc, summary, results, videos, quiet)
    return RunOutcome(out, summary, wall)


def _start_log(cfg: ExperimentConfig, proc: Procedure, tmp: Path, out: Path) -> RunLog:
    """Write ``config.yaml`` and open ``run.log`` with what runs, where, and the config
    sections the procedure does not read."""
    (tmp / "config.yaml").write_text(dump_config(cfg))
    log = RunLog(tmp / "run.log")
    log.write(f"run {cfg.name!r} (kind {cfg.kind}, robot {cfg.robot.name}, seed {cfg.seed})")
    log.write(f"geosyn {geosyn_version()}; into {out}")
    for section in ignored_sections(cfg, type(proc)):
        log.write(f"note: kind {cfg.kind!r} does not read section {section!r}; it has no effect")
    return log


def _write_results(
    ctx: RunContext, proc: Procedure, results: dict[str, Any], log: RunLog
) -> tuple[dict[str, float], dict[str, Any] | None]:
    """Write ``results.npz``, the CSV tables, the plots and the videos of a run.

    Returns:
        (the clean summary, the video record or None without videos).
    """
    cfg, params, tmp = ctx.config, ctx.params, ctx.out_dir
    arrays: dict[str, Any] = results
    save_npz(tmp / "results.npz", arrays)  # a spooled log a block at a time
    for name, status in _run_statuses(results).items():
        log.write(f"closed-loop run {name}: {status}")
        for note in _run_notes(results, name):
            log.write(f"closed-loop run {name}: {note}")
    if cfg.outputs.csv:
        for path in write_csv(tmp, cfg.controller_labels(), arrays):
            log.write(f"wrote {path.relative_to(tmp)}")
    if cfg.outputs.parquet:
        for path in write_parquet(tmp, cfg.controller_labels(), arrays):
            log.write(f"wrote {path.relative_to(tmp)}")
    summary = clean_summary(proc.full_summary(cfg, params, results))
    if cfg.outputs.plots:
        proc.plot(cfg, params, results, tmp)
    videos = None
    if cfg.outputs.video:  # never raises: a failed video is recorded, the run kept
        videos = write_videos(cfg, ctx.robot, results, tmp, scene=ctx.scene)
        log.write(f"videos: {videos}")
    return summary, videos


def _write_run_json(
    tmp: Path, cfg: ExperimentConfig, started: str, wall: float, videos: dict[str, Any] | None
) -> None:
    """``run.json``: timing, versions, provenance, the videos and the sha256 of the results."""
    meta = {
        "name": cfg.name,
        "kind": cfg.kind,
        "seed": cfg.seed,
        "started": started,
        "finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "finished_ns": time.time_ns(),
        "wall_time": wall,
        "pid": os.getpid(),
        "versions": _versions(),
        "geosyn": geosyn_version(),
        "git": git_commit(),
        **({"video": videos} if videos is not None else {}),
        # checked by `geosyn report` (an altered or damaged results.npz is refused)
        "results_sha256": hashlib.sha256((tmp / "results.npz").read_bytes()).hexdigest(),
    }
    (tmp / "run.json").write_text(json.dumps(meta, indent=1) + "\n")


def _tell(
    cfg: ExperimentConfig,
    proc: Procedure,
    summary: dict[str, float],
    results: dict[str, Any],
    videos: dict[str, Any] | None,
    quiet: bool,
) -> None:
    """After the commit: a failed video on stderr; unless ``quiet``, the summary table and
    the runs that did not complete."""
    if videos is not None and videos["error"]:
        print(f"{cfg.name}: no video: {videos['error']} (run kept)", file=sys.stderr)
    if quiet:
        return
    print_summary(cfg.name, summary, proc.units)
    failed = int(summary.get("failed_runs", 0.0))
    if failed:
        reasons = [
            f"{k[: -len('__status')]}: {v}"
            for k, v in results.items()
            if k.endswith("__status") and str(v) != "ok"
        ]
        print(
            f"{cfg.name}: {failed} run(s) did not complete (their metrics are NaN): "
            + "; ".join(reasons),
            file=sys.stderr,
        )


__all__ = ["RunOutcome", "default_run_dir", "run_experiment"]
