"""The ``geosyn`` command line.

Every subcommand is a function registered in `COMMANDS`; a `GeosynError` raised by any of
them is printed as one line on stderr and exits with code 2 (bad input), never as a
traceback.
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

from geosyn.core.errors import GeosynError
from geosyn.experiments import termination

COMMANDS: dict[str, tuple[Callable[[argparse.Namespace], int], str]] = {}


def command(name: str, help_text: str) -> Callable:
    """Register a subcommand ``name`` implemented by ``fn(args) -> exit code``."""

    def wrap(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        COMMANDS[name] = (fn, help_text)
        return fn

    return wrap


@command("robots", "list the robots known by name: DoF, mass, end-effector, source")
def cmd_robots(args: argparse.Namespace) -> int:
    from pathlib import Path

    from geosyn.robots import BUILTINS, load_robot
    from geosyn.robots.catalog import catalog

    entries = catalog()
    print(f"{'robot':<28} {'DoF':>3} {'mass [kg]':>10}  {'end-effector':<30} source")
    for name in BUILTINS:
        entry = entries.get(name)
        floating = entry is not None and entry.floating
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                r = load_robot(name, fixed_base=True) if floating else load_robot(name)
            except GeosynError as err:
                print(f"{name:<28}   -          -  {'-':<30} cannot load: {err}")
                continue
        source = "built-in" if r.source_file is None else Path(r.source_file).name
        notes = ["floating base: needs fixed_base=True"] if floating else []
        notes += [f"{len(caught)} warning(s) on loading"] if caught else []
        extra = f" ({'; '.join(notes)})" if notes else ""
        print(f"{name:<28} {r.nv:>3} {r.total_mass:>10.3f}  {r.ee_frame:<30} {source}{extra}")
    return 0


@command("list", "list the built-in experiments and robots")
def cmd_list(args: argparse.Namespace) -> int:
    # The descriptions are read from the YAML files without validating them: validation
    # imports the whole library (MuJoCo, CasADi), and `geosyn list` must answer at once.
    from pathlib import Path

    import yaml

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


@command("run", "run an experiment (built-in name or YAML file)")
def cmd_run(args: argparse.Namespace) -> int:
    from geosyn.experiments.loader import load_config
    from geosyn.experiments.runner import run_experiment

    cfg, _ = load_config(args.experiment, args.overrides)
    outcome = run_experiment(cfg, **_keywords(args, run_experiment))
    print(f"run directory: {outcome.path}  ({outcome.wall_time:.1f} s)")
    return 0


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


@command("sweep", "run an experiment over a grid of settings and seeds")
def cmd_sweep(args: argparse.Namespace) -> int:
    from geosyn.experiments.sweep import parse_grid, sweep

    options = _keywords(args, sweep)
    grid = parse_grid(options.pop("grid"))
    result = sweep(args.experiment, grid, **options)
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


@command(
    "report",
    "regenerate summary.md, summary.json and plots of a run directory (of a sweep"
    " directory: its tables and a plot per grid axis)",
)
def cmd_report(args: argparse.Namespace) -> int:
    from geosyn.experiments.report import report

    report(args.run_dir)
    print(f"report regenerated in {args.run_dir}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one sub-parser per registered command."""
    parser = argparse.ArgumentParser(
        prog="geosyn",
        description="Geodesic synergies, shaped metrics and torque controllers.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (_fn, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text)
        configure = ARGUMENTS.get(name)
        if configure is not None:
            configure(p)
    return parser


#: Per-command argument set-up, filled by modules that add commands.
ARGUMENTS: dict[str, Callable[[argparse.ArgumentParser], None]] = {
    "run": _run_arguments,
    "sweep": _sweep_arguments,
    "report": _report_arguments,
}


# The browser viewers register `view` and `explore` (viser is imported only when they run);
# `cli_schema` registers `schema` and `init` (the schema is imported only when they run).
from geosyn.experiments import cli_schema, viewer_cli  # noqa: E402, F401


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``geosyn`` console script; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: usage errors exit 2, --help exits 0
        return int(exc.code) if isinstance(exc.code, int) else 2
    fn, _ = COMMANDS[args.command]
    try:
        with termination.sigterm_exits():  # the previous handler is back when main returns
            return fn(args)
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except GeosynError as err:
        message = " ".join(str(err).split())  # one line, always
        print(f"geosyn {args.command}: error: {type(err).__name__}: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
