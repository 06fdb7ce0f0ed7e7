"""The run log (``run.log`` in each run directory) and the provenance of a run (geosyn
version, git commit) written to ``run.json``.

The log says, with UTC time stamps, what a run did: its config, each closed-loop run's
status, every warning raised while it ran (solver fallbacks, dropped model properties,
...), the files it wrote. Warnings are recorded with `warnings.catch_warnings`, which puts
the previous filters back on exit.
"""

from __future__ import annotations

import contextlib
import subprocess
import time
import warnings
from collections.abc import Iterator
from pathlib import Path

from geosyn import __version__


class RunLog:
    """Lines of a run's ``run.log``, written as they come.

    Args:
        path: the log file (created, or appended to).
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.touch()

    def write(self, message: str) -> None:
        """Append one time-stamped line (newlines in ``message`` become spaces)."""
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        with self.path.open("a", encoding="utf-8") as f:
            f.write(f"{stamp} {' '.join(str(message).split())}\n")

    @contextlib.contextmanager
    def warnings(self) -> Iterator[None]:
        """Record every warning raised inside the block (and show it as usual after)."""
        caught: list[warnings.WarningMessage] = []
        try:
            with warnings.catch_warnings(record=True) as recorder:
                warnings.simplefilter("always")
                try:
                    yield
                finally:
                    caught = list(recorder)
        finally:
            for w in caught:
                self.write(f"warning: {w.category.__name__}: {w.message}")
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def geosyn_version() -> str:
    """The installed geosyn version."""
    return str(__version__)


def git_commit() -> dict[str, str | bool | None]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the geosyn source tree.

    None when geosyn does not run from a git checkout (an installed wheel) or git is
    missing.
    """
    root = Path(__file__).resolve().parent.parent
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10
        )
        if sha.returncode != 0:
            return {"commit": None, "dirty": None}
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}
    dirty = bool(status.stdout.strip()) if status.returncode == 0 else None
    return {"commit": sha.stdout.strip(), "dirty": dirty}


__all__ = ["RunLog", "geosyn_version", "git_commit"]
