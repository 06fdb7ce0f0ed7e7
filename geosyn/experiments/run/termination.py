"""SIGTERM handling for `geosyn run` and `geosyn sweep`.

While `sigterm_exits` is active, SIGTERM raises ``SystemExit(143)`` so that a killed run
removes its temporary directory; on leaving it the previous handler is back (importing
this module, or returning from the CLI, leaves the process's handlers as they were).

Python discards an exception raised while a finaliser or ``__del__`` runs (it prints
"Exception ignored"), and geosyn's caches use finalisers, so the handler also records the
signal: `raise_if_terminated` re-raises it at safe points (between sweep runs, before a
run directory is committed), and a swallowed signal still ends the process.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any

#: What `signal.getsignal` returns: a handler, SIG_DFL/SIG_IGN, or None (not set from Python).
Handler = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None

_received: int | None = None  # the signal number once SIGTERM arrived (process state)


def _handler(signum: int, frame: object) -> None:
    global _received
    _received = signum
    raise SystemExit(128 + signum)


def install() -> Handler:
    """Route SIGTERM to `SystemExit(143)` and forget an earlier SIGTERM.

    Main thread only (signal handlers can only be set there); a no-op elsewhere.

    Returns:
        The handler it replaced, for `restore` (None off the main thread).
    """
    global _received
    if threading.current_thread() is not threading.main_thread():
        return None
    _received = None
    return signal.signal(signal.SIGTERM, _handler)


def restore(previous: Handler) -> None:
    """Put back the SIGTERM handler `install` returned (None: the default action).

    Main thread only; a no-op elsewhere.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


@contextlib.contextmanager
def sigterm_exits() -> Iterator[None]:
    """Within the block SIGTERM raises ``SystemExit(143)``; the previous handler after it."""
    previous = install()
    try:
        yield
    finally:
        restore(previous)


def raise_if_terminated() -> None:
    """Raise ``SystemExit(128 + signal)`` if a SIGTERM arrived, even one that was swallowed."""
    if _received is not None:
        raise SystemExit(128 + _received)


__all__ = ["Handler", "install", "raise_if_terminated", "restore", "sigterm_exits"]
