"""Third-party output kept off the terminal: what native libraries (the URDF parser,
MuJoCo's compiler) print on the process's stderr, and MuJoCo's warnings (which MuJoCo
would print and append to ``MUJOCO_LOG.TXT`` in the current directory).

`captured_stderr` redirects file descriptor 2 (C++ and Python writers alike) into a
temporary file for the duration of a block; `mujoco_warnings` routes MuJoCo's warnings
into Python warnings (recorded in the run log by the runner) and a list that the CLI
writes to the run directory's ``MUJOCO_LOG.TXT`` (`append_mujoco_log`; `mujoco_log` for
commands that know their directory up front: sweep runs, report, view);
`own_warnings_shown` keeps other
libraries' warnings (recorded in the run log) off the terminal. Each restores what it
replaced.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

_SOURCE_LOCATION = re.compile(r"^at line \d+ in \S+$")


class Captured:
    """What a `captured_stderr` block printed (``text`` is set when the block ends)."""

    def __init__(self) -> None:
        self.text = ""

    def lines(self, limit: int = 3) -> list[str]:
        """The first ``limit`` non-empty lines, each stripped, without the C++ source
        locations (``at line 607 in .../joint.cpp``) some parsers print after a line."""
        kept = [s.strip() for s in self.text.splitlines() if s.strip()]
        return [s for s in kept if not _SOURCE_LOCATION.match(s)][:limit]

    def said(self) -> str:
        """The first lines, to append to geosyn's error ('' if nothing was printed)."""
        lines = self.lines()
        return f" (third-party output: {' | '.join(lines)})" if lines else ""


@contextlib.contextmanager
def captured_stderr() -> Iterator[Captured]:
    """Redirect file descriptor 2 into a temporary file inside the block.

    Yields:
        A `Captured` whose ``text`` holds the output once the block has ended.
    """
    out = Captured()
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            out.text = tmp.read(1 << 16).decode("utf-8", "replace")


class MuJoCoWarning(UserWarning):
    """A warning MuJoCo raised while a run simulated (its text is MuJoCo's)."""


@contextlib.contextmanager
def mujoco_warnings() -> Iterator[list[str]]:
    """MuJoCo's warnings as `MuJoCoWarning` (never printed by MuJoCo nor written to the
    current directory's ``MUJOCO_LOG.TXT``); the previous handler is back after.

    Yields:
        The list of warning texts, filled while the block runs.
    """
    import mujoco  # deferred: the CLI answers --help without MuJoCo

    texts: list[str] = []

    def handler(message: Any) -> None:
        text = " ".join(str(message).split())
        texts.append(text)
        warnings.warn(f"MuJoCo: {text}", MuJoCoWarning, stacklevel=1)

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(handler)
    try:
        yield texts
    finally:
        mujoco.set_mju_user_warning(previous)


#: MuJoCo's log file name, kept in the run (or sweep) directory instead of the current one.
MUJOCO_LOG = "MUJOCO_LOG.TXT"


def append_mujoco_log(folder: Path, texts: Sequence[str]) -> None:
    """Append MuJoCo warning texts to ``folder/MUJOCO_LOG.TXT`` (nothing without texts)."""
    if texts:
        with (Path(folder) / MUJOCO_LOG).open("a", encoding="utf-8") as f:
            f.writelines(f"WARNING: {text}\n" for text in texts)


@contextlib.contextmanager
def mujoco_log(folder: Path) -> Iterator[list[str]]:
    """`mujoco_warnings`, each text also appended to ``folder/MUJOCO_LOG.TXT`` when the
    block ends (even by an exception), never to the current directory."""
    with mujoco_warnings() as texts:
        try:
            yield texts
        finally:
            with contextlib.suppress(OSError):  # an unwritable folder: the warnings were shown
                append_mujoco_log(folder, texts)


class Quiet:
    """What a `quiet` block left: third-party lines and MuJoCo warnings (for the run
    log and ``MUJOCO_LOG.TXT``), Python warnings (geosyn's are shown, others logged)."""

    def __init__(self) -> None:
        self.stderr = Captured()
        self.mujoco: list[str] = []
        self.warnings: list[warnings.WarningMessage] = []

    def log_lines(self) -> list[str]:
        """Every captured item as one run-log line."""
        lines = [f"third-party stderr: {line}" for line in self.stderr.lines(limit=200)]
        lines += [f"MuJoCo warning: {text}" for text in self.mujoco]
        lines += [f"warning: {w.category.__name__}: {w.message}" for w in self.warnings]
        return lines

    def reason(self) -> str:
        """The first third-party lines, to append to geosyn's error ('' if none)."""
        lines = self.stderr.lines() + self.mujoco[:2]
        return f" (third-party output: {' | '.join(lines)})" if lines else ""

    def show_own_warnings(self) -> None:
        """Show geosyn's own warnings as usual (the others stay in the run log)."""
        for w in self.warnings:
            if _is_geosyn(w):
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _is_geosyn(w: warnings.WarningMessage) -> bool:
    return _own_category(w.category)


def _own_category(category: type[Warning]) -> bool:
    module = getattr(category, "__module__", "")
    return module.startswith("geosyn.") and category is not MuJoCoWarning


@contextlib.contextmanager
def own_warnings_shown() -> Iterator[None]:
    """Inside the block, only geosyn's own warnings reach the terminal; the others
    (numpy's, MuJoCo's) are shown nowhere but the run log, which records every warning
    (`geosyn.experiments.run.runlog.RunLog.warnings`). ``warnings.showwarning`` is
    restored after."""
    previous = warnings.showwarning

    def show(message: Any, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        if _own_category(category):
            previous(message, category, *args, **kwargs)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = previous


@contextlib.contextmanager
def quiet() -> Iterator[Quiet]:
    """`captured_stderr`, `mujoco_warnings` and recorded Python warnings in one block."""
    out = Quiet()
    with contextlib.ExitStack() as stack:
        out.stderr = stack.enter_context(captured_stderr())
        out.mujoco = stack.enter_context(mujoco_warnings())
        out.warnings = stack.enter_context(warnings.catch_warnings(record=True))
        warnings.simplefilter("always")
        yield out


__all__ = [
    "MUJOCO_LOG",
    "Captured",
    "MuJoCoWarning",
    "Quiet",
    "append_mujoco_log",
    "captured_stderr",
    "mujoco_log",
    "mujoco_warnings",
    "own_warnings_shown",
    "quiet",
]
