"""The commands that list, run, sweep, report and clean up experiments: ``robots``,
``list``, ``run``, ``sweep``, ``report``, ``clean``.

The library is imported inside each command, not here: ``geosyn --help`` and ``geosyn
list`` must answer without importing MuJoCo, CasADi or Matplotlib (`tests/test_cli.py`).
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from geosyn.core.errors import GeosynError
from geosyn.experiments.cli import exit_codes
from geosyn.experiments.cli.registry import Command
from geosyn.experiments.config import chatter
from geosyn.experiments.errors import ConfigError


def cmd_robots(args: argparse.Namespace) -> int:
    # deferred (as in every command): loading the robots imports Pinocchio and MuJoCo
    from geosyn.robots import BUILTINS, load_robot
    from geosyn.robots.catalog import catalog
    from geosyn.sim.floating_scene import STANDING

    entries = catalog()
    print(f"{'robot':<28} {'DoF':>3} {'mass [kg]':>10}  {'end-effector':<30} source")
    for name in BUILTINS:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            welded = False
            try:
                try:
                    r = load_robot(name)
                except GeosynError:  # e.g. couplings on a floating base: welded it loads
                    if not (entries.get(name) and entries[name].floating):
                        raise
                    r, welded = load_robot(name, fixed_base=True), True
            except GeosynError as err:
                print(f"{name:<28}   -          -  {'-':<30} cannot load: {err}")
                continue
        source = "built-in" if r.source_file is None else Path(r.source_file).name
        notes = ["floating base: loads with fixed_base=True only"] if welded else []
        if r.floating:  # DoF counts the base's 6
            stands = "stands in kind tracking" if name in STANDING else "fixed_base: true to run it"
            notes.append(f"floating base, DoF with the base's 6: {stands}")
        notes += [f"{len(caught)} warning(s) on loading"] if caught else []
        extra = f" ({'; '.join(notes)})" if notes else ""
        print(f"{name:<28} {r.nv:>3} {r.total_mass:>10.3f}  {r.ee_frame:<30} {source}{extra}")
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    # The descriptions are read from the YAML files without validating them: validation
    # imports the whole library (MuJoCo, CasADi), and `geosyn list` must answer at once.
    from geosyn.experiments import configs
    from geosyn.robots.builtins import BUILTINS

    print("experiments:")
    for path in sorted(Path(configs.__file__).parent.glob("*.yaml")):
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        text = data.get("description", "") if isinstance(data, dict) else ""
        first = re.split(r"(?<=\.)\s", " ".join(str(text).split()), maxsplit=1)[0]
        print(f"  {path.stem:<31} {first}")
    print("robots:")
    print("  " + ", ".join(BUILTINS))
    return 0


def _experiment_arguments(p: argparse.ArgumentParser, out_help: str, set_help: str) -> None:
    """Arguments of every command that runs an experiment (``run``, ``sweep``)."""
    p.add_argument(
        "experiment", metavar="NAME|FILE.yaml", help="built-in experiment name or YAML file"
    )
    p.add_argument("--out", metavar="DIR", help=out_help)
    p.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=set_help
    )
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bars")
    p.add_argument(
        "--allow-unused",
        dest="allow_unused",
        action="store_true",
        help="run even if the config sets sections its kind does not read (refused by"
        " default: they would have no effect; the run log names them)",
    )


def _keywords(args: argparse.Namespace, fn: Callable[..., Any]) -> dict[str, Any]:
    """The parsed arguments named like keyword parameters of ``fn``."""
    params = inspect.signature(fn).parameters
    return {k: v for k, v in vars(args).items() if k in params}


def _run_arguments(p: argparse.ArgumentParser) -> None:
    _experiment_arguments(
        p,
        "run directory (default runs/<name>-<timestamp>)",
        "override a config field, e.g. --set simulation.duration=1.0; KEY+=VALUE appends"
        " to a list, e.g. --set 'controllers+={type: qp}' (repeatable)",
    )
    p.add_argument("--video", action="store_true", help="also render videos")
    p.add_argument("--force", action="store_true", help="replace an existing run directory")
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = exit_codes.epilog()


def cmd_run(args: argparse.Namespace) -> int:
    # deferred: the runner imports the whole library (MuJoCo, CasADi, Matplotlib)
    from geosyn.experiments.config.loader import load_config
    from geosyn.experiments.run.runner import run_experiment

    with chatter.quiet() as loading:  # the robot file's parser and compiler print
        try:
            cfg, _ = load_config(args.experiment, args.overrides, allow_unused=args.allow_unused)
        except ConfigError as err:
            failure: ConfigError | None = err
        else:
            failure = None
    if failure is not None:
        raise ConfigError(failure.file, failure.field, failure.reason + loading.reason()) from (
            failure
        )
    loading.show_own_warnings()
    with chatter.mujoco_warnings() as mujoco_texts, chatter.own_warnings_shown():
        outcome = run_experiment(cfg, **_keywords(args, run_experiment))
    _keep_chatter(outcome.path, loading, mujoco_texts)
    print(f"run directory: {outcome.path}  ({outcome.wall_time:.1f} s)")
    code = exit_codes.run_exit_code(outcome.summary)
    if code == exit_codes.NO_RUN_SUCCEEDED:
        print(
            f"geosyn run: no closed-loop run completed (exit {code}); see {outcome.path / 'run.log'}",
            file=sys.stderr,
        )
    return code


def _keep_chatter(run_dir: Path, loading: chatter.Quiet, mujoco_texts: list[str]) -> None:
    """Third-party output of the loading into ``run.log``, MuJoCo's warnings (of the
    loading and the run) into the run directory's ``MUJOCO_LOG.TXT``."""
    lines = loading.log_lines()
    if lines:
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        with (run_dir / "run.log").open("a", encoding="utf-8") as f:
            for line in lines:
                f.write(f"{stamp} while loading the config: {' '.join(line.split())}\n")
    chatter.append_mujoco_log(run_dir, loading.mujoco + mujoco_texts)


def _sweep_arguments(p: argparse.ArgumentParser) -> None:
    _experiment_arguments(
        p,
        "sweep directory (default runs/sweep-<name>-<timestamp>)",
        "override a config field for every run (repeatable)",
    )
    p.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="KEY=V1,V2",
        help="a swept field and its values (repeatable; the grid is the product)",
    )
    p.add_argument(
        "--seeds", type=int, default=1, metavar="N", help="seeds per grid point (seed, seed+1, ...)"
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="K",
        help="local worker processes (default 1); with --ray local, Ray CPUs (default all)",
    )
    p.add_argument(
        "--ray",
        dest="ray_address",
        metavar="ADDRESS",
        help="run on Ray: a cluster address, or 'local'",
    )
    p.add_argument(
        "--max-runs",
        dest="max_runs",
        type=int,
        default=1000,
        metavar="N",
        help="refuse a sweep of more runs (grid points x seeds) than N (default 1000)",
    )


def cmd_sweep(args: argparse.Namespace) -> int:
    from geosyn.experiments.sweep import parse_grid, sweep

    options = _keywords(args, sweep)
    grid = parse_grid(options.pop("grid"))
    # each run keeps its MuJoCo warnings in its own directory (`run_job`); the loading's
    # go to the sweep directory
    with chatter.mujoco_warnings() as texts:
        result = sweep(args.experiment, grid, **options)
    chatter.append_mujoco_log(result.path, texts)
    print(
        f"sweep directory: {result.path}  ({result.ran} run(s) done now,"
        f" {result.skipped} already complete)"
    )
    return 0


def _report_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "run_dir",
        metavar="RUN_DIR",
        help="a run directory (geosyn run) or sweep directory (geosyn sweep)",
    )


def cmd_report(args: argparse.Namespace) -> int:
    from geosyn.experiments.results.report import report

    folder = Path(args.run_dir)  # MuJoCo's warnings to its MUJOCO_LOG.TXT, never the cwd's
    with chatter.mujoco_log(folder) if folder.is_dir() else chatter.mujoco_warnings():
        report(args.run_dir)
    print(f"report regenerated in {args.run_dir}")
    return 0


def _clean_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "folder",
        nargs="?",
        default="runs",
        metavar="FOLDER",
        help="folder of run and sweep directories (default runs)",
    )


def cmd_clean(args: argparse.Namespace) -> int:
    from geosyn.experiments.run import rundir

    folder = Path(args.folder)
    if not folder.is_dir():
        raise ConfigError(str(folder), None, "is not a folder (geosyn clean FOLDER)")
    removed, kept = rundir.clean(folder)
    for path in removed:
        print(f"removed {path}")
    for path in kept:
        print(f"kept {path} (a live process is writing it)")
    print(f"geosyn clean: {len(removed)} removed, {len(kept)} kept in {folder}")
    return 0


COMMANDS = (
    Command(
        "robots",
        cmd_robots,
        "list the robots known by name: DoF, mass, end-effector, source",
    ),
    Command(
        "list",
        cmd_list,
        "list the built-in experiments and robots",
    ),
    Command(
        "run",
        cmd_run,
        "run an experiment (built-in name or YAML file)",
        _run_arguments,
    ),
    Command(
        "sweep",
        cmd_sweep,
        "run an experiment over a grid of settings and seeds",
        _sweep_arguments,
    ),
    Command(
        "report",
        cmd_report,
        "regenerate summary.md, summary.json and plots of a run directory (of a sweep"
        " directory: its tables and a plot per grid axis)",
        _report_arguments,
    ),
    Command(
        "clean",
        cmd_clean,
        "remove what killed runs and sweeps left under a folder (partial directories of"
        " dead writers, lock files nobody holds); never a complete run",
        _clean_arguments,
    ),
)

__all__ = ["COMMANDS"]
