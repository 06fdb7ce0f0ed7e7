"""Running one experiment into a run directory.

The directory is created only after the config validated, and atomically: everything is
written into a hidden temporary directory next to the target, which is renamed at the
end; on any failure the temporary directory is removed, so a failed run leaves nothing.
The target is claimed first (`geosyn.experiments.rundir`: a lock held for the whole run),
so a second writer to the same directory fails at once; an existing run directory is
never overwritten unless ``force=True``, and never while another process writes it.

Files of a run: ``config.yaml`` (the resolved config, after ``--set``), ``results.npz``
(the procedure's arrays), ``data/<run>.csv`` (each closed-loop run with named columns,
`geosyn.experiments.data`), ``run.log`` (what happened, warnings included), PNG plots,
optional videos, ``run.json`` (timing, versions, geosyn version and git commit),
``summary.md`` and ``summary.json`` (written last: its presence marks a complete run).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import shutil
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from geosyn.experiments import rundir, termination
from geosyn.experiments.errors import OutputNotWritable, RunDirectoryExists
from geosyn.experiments.loader import dump_config
from geosyn.experiments.report import clean_summary, print_summary, write_summary
from geosyn.experiments.runlog import RunLog, geosyn_version, git_commit
from geosyn.experiments.schema import ExperimentConfig


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


@contextlib.contextmanager
def _progress(enabled: bool) -> Iterator[Callable[[str, int], Callable[[], None]]]:
    if not enabled:
        yield lambda description, total: lambda: None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        transient=True,
    ) as bar:

        def factory(description: str, total: int) -> Callable[[], None]:
            task = bar.add_task(description, total=total)
            return lambda: bar.advance(task)

        yield factory


def _versions() -> dict[str, str]:
    import mujoco
    import pinocchio

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
        cfg: the validated config (see `geosyn.experiments.loader.load_config`).
        out: the run directory; default ``runs/<name>-<timestamp>``.
        force: replace an existing ``out``.
        video: render videos (also on with ``outputs.video``).
        progress: show progress bars.
        quiet: do not print the summary table.

    Returns:
        The `RunOutcome`.

    Raises:
        RunDirectoryExists: ``out`` exists and ``force`` is False, is a file, or another
            process is writing it (see `geosyn.experiments.rundir`; ``force`` never
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
    """`run_experiment` once ``out`` is claimed (see `geosyn.experiments.rundir`)."""
    from geosyn.experiments.build import build_robot
    from geosyn.experiments.procedures import PROCEDURES
    from geosyn.experiments.procedures.base import RunContext

    tmp = out.parent / f".{out.name}.partial-{uuid.uuid4().hex[:8]}"
    try:
        tmp.mkdir()
    except OSError as err:
        raise OutputNotWritable(out, err) from err
    t0 = time.perf_counter()
    started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    try:
        proc = PROCEDURES[cfg.kind]()
        params = proc.Params.model_validate(cfg.params)
        if video and not cfg.outputs.video:  # the saved config says what was rendered
            cfg = cfg.model_copy(update={"outputs": cfg.outputs.model_copy(update={"video": True})})
        (tmp / "config.yaml").write_text(dump_config(cfg))
        log = RunLog(tmp / "run.log")
        log.write(f"run {cfg.name!r} (kind {cfg.kind}, robot {cfg.robot.name}, seed {cfg.seed})")
        log.write(f"geosyn {geosyn_version()}; into {out}")
        from geosyn.experiments.procedures.base import ignored_sections

        for section in ignored_sections(cfg, type(proc)):
            log.write(
                f"note: kind {cfg.kind!r} does not read section {section!r}; it has no effect"
            )
        with _progress(progress) as factory:
            ctx = RunContext(
                config=cfg,
                params=params,
                robot=build_robot(cfg),
                out_dir=tmp,
                video=video or cfg.outputs.video,
                progress=factory,
            )
            with log.warnings():
                results = proc.run(ctx)
        arrays: dict[str, Any] = results  # numpy stubs match **kwds against allow_pickle: bool
        np.savez_compressed(tmp / "results.npz", **arrays)
        for name, status in _run_statuses(results).items():
            log.write(f"closed-loop run {name}: {status}")
        if cfg.outputs.csv:
            from geosyn.experiments.data import write_csv

            for path in write_csv(tmp, cfg.controller_labels()):
                log.write(f"wrote {path.relative_to(tmp)}")
        summary = clean_summary(proc.full_summary(cfg, params, results))
        if cfg.outputs.plots:
            proc.plot(cfg, params, results, tmp)
        videos = None
        if cfg.outputs.video:  # never raises: a failed video is recorded, the run kept
            from geosyn.experiments.video import write_videos

            videos = write_videos(cfg, ctx.robot, results, tmp)
            log.write(f"videos: {videos}")
        wall = time.perf_counter() - t0
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
    if videos is not None and videos["error"]:
        print(f"{cfg.name}: no video: {videos['error']} (run kept)", file=sys.stderr)
    if not quiet:
        print_summary(cfg.name, summary, PROCEDURES[cfg.kind].units)
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
    return RunOutcome(out, summary, wall)


__all__ = ["RunOutcome", "default_run_dir", "run_experiment"]
