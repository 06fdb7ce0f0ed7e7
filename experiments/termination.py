"""SIGTERM handling for `geosyn run` and `geosyn sweep`.

The handler raises ``SystemExit(143)`` so that a killed run removes its temporary
directory. Python discards an exception raised while a finaliser or ``__del__`` runs (it
prints "Exception ignored"), and geosyn's caches use finalisers, so the handler also
records the signal: `raise_if_terminated` re-raises it at safe points (between sweep runs,
before a run directory is committed), and a swallowed signal still ends the process.
"""

from __future__ import annotations

import signal
import threading

_received: int | None = None  # the signal number once SIGTERM arrived (process state)


def _handler(signum: int, frame: object) -> None:
    global _received
    _received = signum
    raise SystemExit(128 + signum)


def install() -> None:
    """Route SIGTERM to `SystemExit(143)` (main thread only; no-op elsewhere)."""
    global _received
    if threading.current_thread() is threading.main_thread():
        _received = None
        signal.signal(signal.SIGTERM, _handler)


def raise_if_terminated() -> None:
    """Raise ``SystemExit(128 + signal)`` if a SIGTERM arrived, even one that was swallowed."""
    if _received is not None:
        raise SystemExit(128 + _received)
