"""Helpers of the fuzz suites (tests/test_fuzz_*.py): run a hostile case in-process with a
time bound and check that it ends in exit code 2 with one line (CLI) or in a geosyn error
(API), without a traceback and without leaving files behind."""

from __future__ import annotations

import contextlib
import io
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from geosyn.core.errors import GeosynError
from geosyn.experiments.cli import main

#: Wall-time bound of one fuzz case [s] (a case is a hang if it takes longer; the bound
#: is generous because CI machines are shared; a healthy case takes well under 1 s).
CASE_SECONDS = 60.0


class CaseTimeout(Exception):
    """A fuzz case ran past `CASE_SECONDS` (a hang)."""


@contextlib.contextmanager
def time_bound(seconds: float = CASE_SECONDS) -> Iterator[None]:
    """Raise `CaseTimeout` in the main thread if the block runs longer than ``seconds``."""
    if threading.current_thread() is not threading.main_thread():  # pragma: no cover
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise CaseTimeout(f"case ran longer than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def run_cli(argv: Sequence[str]) -> tuple[int, str, str]:
    """``geosyn ARGV`` in-process, time-bounded: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with time_bound(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def assert_clean_cli_error(code: int, out: str, err: str, *, command: str) -> str:
    """Exit 2, one ``geosyn COMMAND: error: ...`` line on stderr, no traceback; its text."""
    lines = err.strip().splitlines()
    assert code == 2, (code, out[-500:], err[-2000:])
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    assert lines[0].startswith(f"geosyn {command}: error: "), err
    return lines[0]


def files_under(folder: Path, keep: Sequence[str] = ()) -> list[str]:
    """Every path below ``folder`` (relative), except those named in ``keep``."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.name not in keep)


def call_api(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> BaseException | Any:
    """Call ``fn`` time-bounded; returns the exception raised, or the result."""
    try:
        with time_bound():
            return fn(*args, **kwargs)
    except CaseTimeout:
        raise
    except Exception as exc:  # noqa: BLE001 - the caller checks the type
        return exc


def assert_geosyn_error(result: Any, what: str) -> None:
    """``result`` (from `call_api`) is a GeosynError with a one-line-able message."""
    assert isinstance(result, GeosynError), f"{what}: expected a GeosynError, got {result!r}"
    assert str(result).strip(), f"{what}: empty message"
