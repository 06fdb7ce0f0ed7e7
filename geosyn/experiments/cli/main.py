"""The ``geosyn`` command line.

Every subcommand is a `Command` listed by its module (`experiment_commands`,
`schema_commands`, `viewer_commands`) and assembled in `COMMANDS`; a `GeosynError` raised by any of
them is printed as one line on stderr and exits with code 2 (bad input), never as a
traceback; ``--help`` lists every exit code (`exit_codes`). geosyn's own warnings print
once each, on one line without a source line (`warning_format`).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from geosyn.core.errors import GeosynError
from geosyn.experiments.cli import (
    exit_codes,
    experiment_commands,
    export_commands,
    schema_commands,
    viewer_commands,
)
from geosyn.experiments.cli.registry import Command
from geosyn.experiments.cli.warning_format import geosyn_warnings_once
from geosyn.experiments.run import termination

#: Every subcommand, by name, in ``--help`` order.
COMMANDS: dict[str, Command] = {
    c.name: c
    for c in (
        *experiment_commands.COMMANDS,
        *schema_commands.COMMANDS,
        *viewer_commands.COMMANDS,
        *export_commands.COMMANDS,
    )
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one sub-parser per registered command."""
    parser = argparse.ArgumentParser(
        prog="geosyn",
        description="Geodesic synergies, shaped metrics and torque controllers.",
        epilog=exit_codes.epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, cmd in COMMANDS.items():
        p = sub.add_parser(name, help=cmd.help)
        if cmd.arguments is not None:
            cmd.arguments(p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``geosyn`` console script; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: usage errors exit 2, --help exits 0
        return int(exc.code) if isinstance(exc.code, int) else 2
    fn = COMMANDS[args.command].run
    try:
        # the previous signal handler and warnings display are back when main returns
        with termination.sigterm_exits(), geosyn_warnings_once():
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
