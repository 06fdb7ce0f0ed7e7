"""A subcommand of the ``geosyn`` command line: its name, function, help and arguments.

Each command module lists its commands in a module-level ``COMMANDS`` tuple;
`geosyn.experiments.cli.main` assembles the parser from those tuples (no registration by
import side effect).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import NamedTuple


class Command(NamedTuple):
    """One subcommand.

    Attributes:
        name: the subcommand (``geosyn <name>``).
        run: ``run(args) -> exit code``.
        help: one line for ``geosyn --help``.
        arguments: adds the subcommand's arguments to its parser (None: it takes none).
    """

    name: str
    run: Callable[[argparse.Namespace], int]
    help: str
    arguments: Callable[[argparse.ArgumentParser], None] | None = None


__all__ = ["Command"]
