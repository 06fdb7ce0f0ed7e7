"""The ``geosyn`` command line.

Every subcommand is a function registered in `COMMANDS`; a `GeosynError` raised by any of
them is printed as one line on stderr and exits with code 2 (bad input), never as a
traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from geosyn.core.errors import GeosynError

COMMANDS: dict[str, tuple[Callable[[argparse.Namespace], int], str]] = {}


def command(name: str, help_text: str) -> Callable:
    """Register a subcommand ``name`` implemented by ``fn(args) -> exit code``."""

    def wrap(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        COMMANDS[name] = (fn, help_text)
        return fn

    return wrap


@command("robots", "list the built-in robots with DoF and total mass")
def cmd_robots(args: argparse.Namespace) -> int:
    from geosyn.robots import BUILTINS, load_robot

    print(f"{'robot':<10} {'DoF':>3} {'mass [kg]':>10}  end-effector")
    for name in BUILTINS:
        r = load_robot(name)
        print(f"{name:<10} {r.nv:>3} {r.total_mass:>10.3f}  {r.ee_frame}")
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
ARGUMENTS: dict[str, Callable[[argparse.ArgumentParser], None]] = {}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``geosyn`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    fn, _ = COMMANDS[args.command]
    try:
        return fn(args)
    except GeosynError as err:
        print(f"geosyn {args.command}: error: {type(err).__name__}: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
