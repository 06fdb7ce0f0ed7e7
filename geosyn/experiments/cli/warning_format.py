"""How the command line shows geosyn's own warnings: one line each, once per command.

A command can meet the same warning several times (the robot is loaded when the config is
validated and again when the run builds it; recorded warnings are replayed after a run), and
Python's default format adds the file and source line that raised it, which tell a user of
the command line nothing. Inside `geosyn_warnings_once`, a warning whose class is geosyn's
(`geosyn.robots.errors.RobotWarning`, `geosyn.experiments.config.chatter.MuJoCoWarning`, any
class defined in a ``geosyn`` module) prints as ``warning: <Class>: <message>`` on stderr the
first time its class and message are seen and not again; any other warning goes to the
handler that was installed before, which is restored on exit.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO


def is_geosyn_warning(category: type[Warning]) -> bool:
    """Whether ``category`` is one of geosyn's warning classes (defined in a geosyn module)."""
    return any(k.__module__.split(".")[0] == "geosyn" for k in category.__mro__)


@contextmanager
def geosyn_warnings_once() -> Iterator[set[tuple[str, str]]]:
    """Show geosyn's warnings once each, one line without a source line (see the module doc).

    Yields:
        The set of ``(class name, message)`` pairs shown so far.
    """
    previous = warnings.showwarning
    shown: set[tuple[str, str]] = set()

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if not is_geosyn_warning(category):
            previous(message, category, filename, lineno, file, line)
            return
        text = " ".join(str(message).split())
        key = (category.__name__, text)
        if key in shown:
            return
        shown.add(key)
        stream: Any = sys.stderr if file is None else file
        try:
            stream.write(f"warning: {category.__name__}: {text}\n")
        except OSError:  # stderr closed: nothing to tell
            pass

    warnings.showwarning = show
    try:
        yield shown
    finally:
        warnings.showwarning = previous


__all__ = ["geosyn_warnings_once", "is_geosyn_warning"]
