"""SIGTERM handling for `geosyn run` and `geosyn sweep`.

While `sigterm_exits` is active, SIGTERM raises ``SystemExit(143)`` so that a killed run
removes its temporary directory; on leaving it the previous handler is back (importing
this module, or returning from the CLI, leaves the process's handlers as they were).

Python discards an exception raised while a finaliser or ``__del__`` runs (it prints
"Exception ignored"), and geosyn's caches use finalisers, so the handler also records the
signal: `raise_if_terminated` re-raises it at safe points (between sweep runs, before a
run directory is committed), and a swallowed signal still ends the process.

Native code can swallow it too: CasADi runs pending signal handlers inside its own calls
on the main thread and turns their exception into its interrupt, which a solver may take
as a stop request and return from. So a run writing a partial directory registers it
(`guarded`); a SIGTERM then also starts a watchdog which, if the process is still alive
`EXIT_GRACE` seconds later, removes the registered partial directories and lock files and
ends the process with the same code (``os._exit``).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType
from typing import Any

#: What `signal.getsignal` returns: a handler, SIG_DFL/SIG_IGN, or None (not set from Python).
Handler = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None

_received: int | None = None  # the signal number once SIGTERM arrived (process state)

#: Seconds after SIGTERM by which a process writing a run is gone, whatever it is doing.
EXIT_GRACE = 1.5

_guarded: dict[int, tuple[Path, Path]] = {}  # partial directories and lock files written
_watchdog: threading.Timer | None = None


def _handler(signum: int, frame: object) -> None:
    global _received, _watchdog
    _received = signum
    if _guarded and _watchdog is None:
        _watchdog = threading.Timer(EXIT_GRACE, _force_exit, args=(128 + signum,))
        _watchdog.daemon = True
        _watchdog.start()
    raise SystemExit(128 + signum)


def _force_exit(code: int) -> None:
    """The watchdog: the process outlived `EXIT_GRACE` after SIGTERM (the signal's exit
    was swallowed): remove what it was writing and end it."""
    for tmp, lock in list(_guarded.values()):
        shutil.rmtree(tmp, ignore_errors=True)
        with contextlib.suppress(OSError):
            os.unlink(lock)
    os._exit(code)


@contextlib.contextmanager
def guarded(tmp: Path, lock: Path) -> Iterator[None]:
    """While the block runs, a SIGTERM whose exit is swallowed still ends the process
    within `EXIT_GRACE` seconds, ``tmp`` (a partial run directory) and ``lock`` (its lock
    file) removed."""
    key = object()
    _guarded[id(key)] = (Path(tmp), Path(lock))
    try:
        yield
    finally:
        _guarded.pop(id(key), None)


def install() -> Handler:
    """Route SIGTERM to `SystemExit(143)` and forget an earlier SIGTERM.

    Main thread only (signal handlers can only be set there); a no-op elsewhere.

    Returns:
        The handler it replaced, for `restore` (None off the main thread).
    """
    global _received, _watchdog
    if threading.current_thread() is not threading.main_thread():
        return None
    _received = None
    if _watchdog is not None:
        _watchdog.cancel()
        _watchdog = None
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


__all__ = [
    "EXIT_GRACE",
    "Handler",
    "guarded",
    "install",
    "raise_if_terminated",
    "restore",
    "sigterm_exits",
]
