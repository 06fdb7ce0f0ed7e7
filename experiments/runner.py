"""Running one experiment into a run directory.

The directory is created only after the config validated, and atomically: everything is
written into a hidden temporary directory next to the target, which is renamed at the
end; on any failure the temporary directory is removed, so a failed run leaves nothing.
An existing run directory is never overwritten unless ``force=True``.

Files of a run: ``config.yaml`` (the resolved config, after ``--set``), ``results.npz``
(the procedure's arrays), PNG plots, optional videos, ``run.json`` (timing, versions),
``summary.md`` and ``summary.json`` (written last: its presence marks a complete run).
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import shutil
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from geosyn.experiments import termination
from geosyn.experiments.errors import RunDirectoryExists
from geosyn.experiments.loader import dump_config
from geosyn.experiments.report import clean_summary, print_summary, write_summary
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
    while path.exists():
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
        RunDirectoryExists: ``out`` exists and ``force`` is False.
        GeosynError: the procedure failed (nothing is left on disk).
    """
    from geosyn.experiments.build import build_robot
    from geosyn.experiments.procedures import PROCEDURES
    from geosyn.experiments.procedures.base import RunContext

    out = default_run_dir(cfg) if out is None else Path(out)
    if out.exists() and not force:
        raise RunDirectoryExists(
            out, "already exists; choose another --out or pass --force to replace it"
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{uuid.uuid4().hex[:8]}"
    tmp.mkdir()
    t0 = time.perf_counter()
    started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    try:
        proc = PROCEDURES[cfg.kind]()
        params = proc.Params.model_validate(cfg.params)
        (tmp / "config.yaml").write_text(dump_config(cfg))
        with _progress(progress) as factory:
            ctx = RunContext(
                config=cfg,
                params=params,
                robot=build_robot(cfg),
                out_dir=tmp,
                video=video or cfg.outputs.video,
                progress=factory,
            )
            results = proc.run(ctx)
        arrays: dict[str, Any] = results  # numpy stubs match **kwds against allow_pickle: bool
        np.savez_compressed(tmp / "results.npz", **arrays)
        summary = clean_summary(proc.summarize(cfg, params, results))
        if cfg.outputs.plots:
            proc.plot(cfg, params, results, tmp)
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
        }
        (tmp / "run.json").write_text(json.dumps(meta, indent=1) + "\n")
        write_summary(tmp, cfg.name, cfg.description, summary, proc.units)
        termination.raise_if_terminated()  # never commit a run whose SIGTERM was swallowed
        if out.exists():  # force=True
            shutil.rmtree(out)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if not quiet:
        print_summary(cfg.name, summary, PROCEDURES[cfg.kind].units)
    return RunOutcome(out, summary, wall)


__all__ = ["RunOutcome", "default_run_dir", "run_experiment"]
